//! HDF5 output: step-displacement maps written chunk by chunk into a
//! temporary file that is renamed into place only once it is complete.
//!
//! Layout (a contract):
//! - root attributes `scene` (TOML text), `pidm_version`, `backend`,
//!   `precision`, `wall_time_s`, `variant`, `tolerance`;
//! - `/axes/<key>`: one 1-D dataset per grid axis, in grid order, with a
//!   `units` attribute (a points scene has `/axes/point` and `/labels`);
//! - `/maps/step_x`, `/maps/step_y` [m per own drive cycle],
//!   `/maps/velocity_x`, `/maps/velocity_y` [m/s], `/maps/status`,
//!   `/maps/steps`, `/maps/step_x_se`, `/maps/step_y_se` [m per own drive
//!   cycle], `/maps/periods`, `/maps/period_lag`, and `/maps/motion` (u8,
//!   the codes of `crate::model::motion::Motion`, with CF `flag_values` and
//!   `flag_meanings`), each shaped like the grid;
//! - `/baseline/step_x`, `/baseline/step_y`, `/baseline/status` when
//!   baselines are asked for;
//! - `/maps/stall_load_x` [N], `/maps/stall_step_near_x`,
//!   `/maps/stall_step_far_x` [m per own drive cycle], `/maps/stall_waves_x`
//!   and `/maps/stall_status_x` (or `_y`) for a scene with `[stall]`
//!   (`crate::stall`), shaped like the grid;
//! - `/trajectories/<k>/` when the scene asks for trajectories (written by
//!   `crate::trajectory`, which documents its layout).
//!
//! The file also follows the netCDF-4 conventions, so netCDF tools and
//! `xarray.open_dataset(file, engine="h5netcdf")` see labelled arrays: each
//! `/axes` dataset is an HDF5 dimension scale named by its key and attached
//! to every map, and the root group holds hard links (the same objects, not
//! copies) named `step_x`, ..., `baseline_step_x`, ... and one per axis key.
//! Every map has `units` and `long_name` attributes.
//!
//! A shard file (`pidm run --shard K/N`) holds only its own instances: its
//! maps are 1-D in ascending flat-index order, `/shard/instance` lists those
//! indices, and root attributes `shard_index`, `shard_count` and
//! `instance_count` say which part of the scene it is. `pidm merge` turns
//! shards back into one map file.
//!
//! The files, one concern each: `writer.rs` ([`MapWriter`]), `blocks.rs`
//! (flat ranges as hyperslabs), `attributes.rs` (attributes written and
//! read), `dimension_scales.rs` (the netCDF-4 dimensions), `compare.rs`
//! ([`compare_contents`]), `schema.rs` (the file's names and types),
//! `claim.rs` ([`OutputClaim`]) and `shard_spec.rs` ([`ShardSpec`]); here
//! is what the file describes ([`FileInfo`]).

use std::ops::Range;

mod attributes;
mod blocks;
pub mod claim;
mod compare;
pub(crate) mod dimension_scales;
pub mod schema;
pub mod shard_spec;
mod writer;

pub(crate) use attributes::{read_str_attr, write_f64_attr, write_str_attr, write_u64_attr};
pub use blocks::flat_to_blocks;
pub use claim::OutputClaim;
pub use compare::compare_contents;
pub use shard_spec::ShardSpec;
pub use writer::{MapWriter, StallColumns, root_name};

/// Where a shard file's instances sit in the scene.
#[derive(Clone, Debug)]
pub struct ShardInfo {
    pub spec: ShardSpec,
    /// Instances in the whole scene.
    pub total: u64,
    /// The flat indices this shard holds, ascending and disjoint.
    pub ranges: Vec<Range<u64>>,
}

impl ShardInfo {
    pub fn new(spec: ShardSpec, total: u64) -> ShardInfo {
        ShardInfo {
            spec,
            total,
            ranges: spec.ranges(total),
        }
    }

    /// Instances the shard holds.
    pub fn len(&self) -> u64 {
        self.ranges.iter().map(|r| r.end - r.start).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// One grid axis as it is written to `/axes`.
#[derive(Clone, Debug)]
pub struct AxisInfo {
    pub key: String,
    pub values: Vec<f64>,
    pub units: String,
}

/// What the file describes, known before the run starts.
#[derive(Clone, Debug)]
pub struct FileInfo {
    pub name: String,
    pub scene_text: String,
    /// Grid shape; empty for a single instance.
    pub shape: Vec<usize>,
    pub axes: Vec<AxisInfo>,
    /// Point labels of a points scene.
    pub labels: Option<Vec<String>>,
    pub baselines: bool,
    pub backend: String,
    pub precision: String,
    /// Which integrator variant ran (for example "2-DOF" or "1-DOF").
    pub variant: String,
    pub tolerance: f64,
    /// The friction law, "karnopp" or "lugre" (`mechanism.friction`), and
    /// LuGre's parameters as instance 0 has them (grid axes and points may
    /// vary them; their coordinates then say so).
    pub friction: String,
    pub friction_parameters: Option<String>,
    /// The tolerance of the `--verify` reruns, when the run was verified.
    pub verify_tolerance: Option<f64>,
    /// Set for a shard file: which part of the scene it holds.
    pub shard: Option<ShardInfo>,
    /// The stalled axis of a scene with `[stall]`: its stall maps are
    /// written too (`schema::STALL_DATASETS`).
    pub stall: Option<usize>,
    /// The scene asks for the backward-travel maps (`[output] backward`,
    /// `schema::BACKWARD_DATASETS`).
    pub backward: bool,
}
