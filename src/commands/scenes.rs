//! The scenes the commands load: the default scene, shipped scenes from
//! the binary when their path is not there, and every distinct
//! integration of a scene.

use std::path::{Path, PathBuf};

use anyhow::Result;

use crate::model::Instance;
use crate::scene::Scene;
use crate::sweep;

/// The default scene of `pidm accuracy` and `pidm bench`.
pub const DEFAULT_SCENE: &str = "sweeps/paper.toml";

/// Loads a scene file; a shipped scene named by its path in the checkout
/// (`sweeps/paper.toml`, the commands' defaults) that is not there, as
/// from another directory, is the copy built into the binary.
pub fn load_scene(path: &Path) -> Result<Scene> {
    if !path.exists()
        && let Some(scene) = path.to_str().and_then(Scene::shipped)
    {
        return Ok(scene?);
    }
    Ok(Scene::load(path)?)
}

/// [`load_scene`] for each path.
pub(super) fn load_scenes(paths: &[PathBuf]) -> Result<Vec<Scene>> {
    paths.iter().map(|p| load_scene(p)).collect()
}

/// Every distinct integration a whole scene asks for.
pub(super) fn scene_integrations(scene: &Scene) -> Vec<Instance> {
    let instances: Vec<Instance> = (0..scene.instance_count())
        .map(|i| scene.instance(i))
        .collect();
    sweep::distinct_integrations(&instances, scene.baselines)
}
