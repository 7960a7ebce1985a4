//! `pidm merge`: shard files joined into one map file
//! ([`crate::run::shard::merge`]).

use std::path::{Path, PathBuf};

use anyhow::Result;

/// `pidm merge`: joins shard files into one map file.
pub fn merge(out: &Path, shards: &[PathBuf]) -> Result<()> {
    let merged = crate::run::shard::merge(out, shards)?;
    println!(
        "wrote {} ({} instances from {} shards)",
        merged.path.display(),
        merged.instances,
        merged.shards
    );
    Ok(())
}
