//! The subcommands behind the `pidm` binary. `main.rs` only parses the
//! command line and prints errors; everything a command does is here, so
//! tests can call it.
//!
//! One file per subcommand, as cargo's `commands/`: `run.rs`, `merge.rs`,
//! `check.rs`, `fit.rs`, `sensitivity.rs`, `optimize.rs`, `info.rs`, `report.rs`, `accuracy.rs`, `random_scene.rs`,
//! `bench.rs` and `refine_study.rs`. `summary.rs` is the one home of the
//! run summary `pidm run` prints, `format.rs` of the numbers and words the
//! commands write for people, and `scenes.rs` of how the commands load
//! scenes.

mod accuracy;
mod bench;
mod check;
mod check_design;
mod design_args;
mod fit;
mod format;
mod info;
mod merge;
mod optimize;
mod random_scene;
mod refine_study;
mod report;
mod run;
mod scenes;
mod sensitivity;
mod summary;

pub use crate::run::estimate::NOMINAL_SIMULATED_PER_CORE;
pub use accuracy::accuracy;
pub use bench::bench;
pub use check::{CheckReport, check_json, check_report};
pub use check_design::check;
pub use fit::{FitCommand, fit};
pub use format::{human_duration, instance_name, plural, um};
pub use info::{info, registers, shader_info};
pub use merge::merge;
pub use optimize::{OptimizeCommand, optimize};
pub use random_scene::{random_scene, random_scene_compact};
pub use refine_study::refine_study;
pub use report::report;
pub use run::{RunOptions, run};
pub use scenes::{DEFAULT_SCENE, load_scene};
pub use sensitivity::{SensitivityCommand, sensitivity};
