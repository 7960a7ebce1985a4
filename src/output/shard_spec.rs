//! `ShardSpec`: the deterministic K/N split of a scene's instances that
//! `--shard K/N` names (the merge is `crate::run::shard`). It lives with the
//! output because every file a shard writes records it.

use std::fmt;
use std::ops::Range;
use std::path::PathBuf;
use std::str::FromStr;

/// Shard `index` of `count` (1-based, as `--shard 2/4` reads).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShardSpec {
    pub index: u32,
    pub count: u32,
}

/// Most blocks per shard the split aims for: enough that cost differences
/// across the grid average out between shards.
const BLOCKS_PER_SHARD: u64 = 16;

/// Largest block [instances]: long enough for efficient writes and GPU
/// batches, short enough to balance big grids.
const MAX_BLOCK: u64 = 4096;

impl ShardSpec {
    /// Instances per block for a scene of `total` instances.
    pub fn block_size(self, total: u64) -> u64 {
        (total / (self.count as u64 * BLOCKS_PER_SHARD)).clamp(1, MAX_BLOCK)
    }

    /// The flat indices of this shard: every `count`-th block, starting at
    /// block `index - 1`.
    pub fn ranges(self, total: u64) -> Vec<Range<u64>> {
        if self.count == 1 {
            return crate::sweep::Plan::everything(total);
        }
        let block = self.block_size(total);
        let stride = block * self.count as u64;
        let mut out = Vec::new();
        let mut start = block * (self.index as u64 - 1);
        while start < total {
            out.push(start..(start + block).min(total));
            start += stride;
        }
        out
    }

    /// The default output file of this shard of a scene.
    pub fn default_output(self, scene_name: &str) -> PathBuf {
        PathBuf::from("results").join(format!(
            "{scene_name}.shard-{}-of-{}.h5",
            self.index, self.count
        ))
    }
}

impl fmt::Display for ShardSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl FromStr for ShardSpec {
    type Err = String;

    fn from_str(text: &str) -> Result<ShardSpec, String> {
        let expected = "expected K/N with 1 <= K <= N, for example 2/4";
        let (k, n) = text
            .split_once('/')
            .ok_or_else(|| format!("{text:?}: {expected}"))?;
        let index: u32 = k
            .trim()
            .parse()
            .map_err(|_| format!("{text:?}: {expected}"))?;
        let count: u32 = n
            .trim()
            .parse()
            .map_err(|_| format!("{text:?}: {expected}"))?;
        if count == 0 || index == 0 || index > count {
            return Err(format!("{text:?}: {expected}"));
        }
        Ok(ShardSpec { index, count })
    }
}
