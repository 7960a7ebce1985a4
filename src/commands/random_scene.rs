//! `pidm random-scene`: a points scene of seeded random instances, as TOML
//! text that reads back bit for bit.

use anyhow::{Context, Result, bail};

use crate::model::AXIS_NAMES;
use crate::scene::Scene;

/// `pidm random-scene`: a points scene of seeded random instances (see
/// `random.rs` for the ranges), as TOML on stdout, measured over a fixed
/// window (`measure = "window"`, `cycles` periods of which `settle` are
/// discarded) so that backends can be compared on it exactly. Refuses
/// `count` 0: a scene without points is one default instance, not none.
pub fn random_scene(seed: u64, count: usize, cycles: u32, settle: u32) -> Result<String> {
    use std::fmt::Write as _;
    if count == 0 {
        bail!(
            "random-scene --count 0: expected at least 1 instance (a scene without points would \
             run one default instance)"
        );
    }
    let mut toml = String::new();
    let _ = writeln!(
        toml,
        "# {count} seeded random 2-DOF instances (seed {seed}): written by\n\
         # `pidm random-scene --seed {seed} --count {count} --cycles {cycles} --settle {settle}`.\n\
         name = \"random\"\n\n[simulation]\nmeasure = \"window\"\ncycles = {cycles}\nsettle = {settle}\n"
    );
    for (k, inst) in crate::model::random::random_instances(seed, count, cycles, settle)
        .iter()
        .enumerate()
    {
        let _ = writeln!(toml, "[[points]]\nlabel = \"random {k}\"");
        // Loads only where set (never, today): the text of unloaded
        // instances is what it was before the load existed.
        let mechanism: Vec<(&str, f64)> = inst
            .mechanism
            .parameters()
            .into_iter()
            .filter(|&(key, value)| !(key.starts_with("load_") && value == 0.0))
            .collect();
        let _ = writeln!(toml, "mechanism = {}", inline_table(&mechanism));
        for (name, a) in AXIS_NAMES.iter().zip(&inst.axes) {
            let _ = writeln!(toml, "axis.{name} = {}", inline_table(&a.parameters()));
        }
        toml.push('\n');
    }
    // What is written must be a scene that runs: its own validation
    // refuses flags it cannot hold (`--cycles 0`, `--settle` >= `--cycles`).
    Scene::from_toml(&toml, None).context("random-scene: the flags do not make a valid scene")?;
    Ok(toml)
}

/// [`random_scene`]'s instances as a `[random]` table: the same scene in a
/// few lines, whatever the count.
pub fn random_scene_compact(seed: u64, count: usize, cycles: u32, settle: u32) -> Result<String> {
    if count == 0 {
        bail!("random-scene --count 0: expected at least 1 instance");
    }
    let toml = format!(
        "# {count} seeded random 2-DOF instances (seed {seed}): written by\n\
         # `pidm random-scene --seed {seed} --count {count} --cycles {cycles} --settle {settle} \
         --compact`.\n\
         name = \"random\"\n\n[simulation]\nmeasure = \"window\"\ncycles = {cycles}\n\
         settle = {settle}\n\n[random]\nseed = {seed}\ncount = {count}\n"
    );
    Scene::from_toml(&toml, None).context("random-scene: the flags do not make a valid scene")?;
    Ok(toml)
}

/// A TOML inline table of named values, each written so that it reads back
/// bit for bit.
fn inline_table(entries: &[(&str, f64)]) -> String {
    let fields: Vec<String> = entries
        .iter()
        .map(|(k, v)| format!("{k} = {v:?}"))
        .collect();
    format!("{{ {} }}", fields.join(", "))
}
