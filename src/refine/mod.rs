//! Adaptive regime maps (issue 22): a grid scene with `[refine]` is
//! integrated on a coarse grid first and refined, level by level, only
//! where the regimes change or the bilinear interpolant misses, while the
//! result file stays a map of the finest grid like a uniform run's.
//!
//! The scene's grid is the finest grid (`crate::scene` expands it), so
//! every integrated point is a flat index of that grid, bit-identical to
//! the same instance of a uniform run; the waves hand each level's new
//! points to `crate::sweep` as large batches.
//!
//! Split by concern: `grid` (the finest grid, cells and index math),
//! `rule` (labels and the accuracy rule, on plain values), `waves` (which
//! points each level integrates, over an integration closure),
//! `interpolate` (the finest raster), `output` (the `/refine` group) and
//! `run` (a refined run into its file, with checkpoint and resume).

pub mod grid;
pub mod interpolate;
pub mod output;
pub mod rule;
pub mod run;
pub mod study;
pub mod waves;

pub use run::{Outcome, Report, Scope};
pub use waves::{LevelStats, Options, Refinement};
