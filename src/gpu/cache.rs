//! The driver's compiled pipelines, kept on disk between runs
//! (`wgpu::PipelineCache`, Vulkan only), so only the first run on a machine
//! pays the driver's compile.
//!
//! The file lives in `$PIDM_CACHE_DIR`, else `$XDG_CACHE_HOME/pidm`, else
//! `~/.cache/pidm`, named by the adapter (wgpu's `pipeline_cache_key`).
//! `PIDM_CACHE_DIR=off` disables it. The driver checks the data it is given
//! and ignores what does not fit it, so a stale or foreign file costs a
//! compile, never a wrong pipeline; the file is replaced atomically.

use std::path::{Path, PathBuf};

/// A pipeline cache and the file it is saved to.
pub struct DiskCache {
    cache: wgpu::PipelineCache,
    path: PathBuf,
    /// The cache was filled from its file (else it starts empty).
    loaded: bool,
}

/// The folder pipeline caches are kept in, or `None` when disabled or no
/// home is known.
pub fn folder() -> Option<PathBuf> {
    if let Some(dir) = std::env::var_os("PIDM_CACHE_DIR") {
        if dir == "off" {
            return None;
        }
        return Some(PathBuf::from(dir));
    }
    if let Some(dir) = std::env::var_os("XDG_CACHE_HOME").filter(|d| !d.is_empty()) {
        return Some(PathBuf::from(dir).join("pidm"));
    }
    std::env::var_os("HOME")
        .filter(|d| !d.is_empty())
        .map(|home| PathBuf::from(home).join(".cache").join("pidm"))
}

impl DiskCache {
    /// The cache of an adapter, filled from its file when there is one;
    /// `None` where the backend has no pipeline cache or caching is off.
    pub fn open(device: &wgpu::Device, info: &wgpu::AdapterInfo) -> Option<DiskCache> {
        let key = wgpu::util::pipeline_cache_key(info)?;
        let path = folder()?.join(format!("{key}.bin"));
        let data = std::fs::read(&path).ok();
        // SAFETY: the data was written by `save` from `get_data` of a cache
        // for an adapter with the same key; the driver validates it and
        // falls back to an empty cache when it does not fit.
        let cache = unsafe {
            device.create_pipeline_cache(&wgpu::PipelineCacheDescriptor {
                label: Some("pidm pipelines"),
                data: data.as_deref(),
                fallback: true,
            })
        };
        Some(DiskCache {
            cache,
            path,
            loaded: data.is_some(),
        })
    }

    pub fn cache(&self) -> &wgpu::PipelineCache {
        &self.cache
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Whether the cache was filled from its file: the driver then takes
    /// the pipelines it holds from there (unless the file is stale or
    /// foreign) instead of compiling them.
    pub fn loaded(&self) -> bool {
        self.loaded
    }

    /// Writes the cache to its file (to a temporary name, then renamed).
    /// A cache that cannot be written only costs the next run a compile,
    /// so failures are reported on stderr, not returned.
    pub fn save(&self) {
        let Some(data) = self.cache.get_data() else {
            return;
        };
        let result = (|| -> std::io::Result<()> {
            if let Some(dir) = self.path.parent() {
                std::fs::create_dir_all(dir)?;
            }
            let tmp = self
                .path
                .with_extension(format!("tmp{}", std::process::id()));
            std::fs::write(&tmp, &data)?;
            std::fs::rename(&tmp, &self.path)
        })();
        if let Err(e) = result {
            eprintln!(
                "pidm: could not save the pipeline cache to {}: {e}",
                self.path.display()
            );
        }
    }
}
