//! pidm: maps of how two-axis piezoelectric impact drives move.
//!
//! See ARCHITECTURE.md for the bird's-eye view.

pub mod accuracy;
pub mod backend;
pub mod checkpoint;
pub mod commands;
pub mod estimate;
pub mod gpu;
pub mod interrupt;
pub mod knob;
pub mod laws;
pub mod measurement;
pub mod model;
pub mod motion;
pub mod output;
pub mod plot;
pub mod probe;
pub mod profile;
pub mod progress;
pub mod random;
pub mod refine;
pub mod replicas;
pub mod report;
pub mod run;
pub mod scene;
pub mod scope;
pub mod shard;
pub mod stall;
pub mod status;
pub mod sweep;
pub mod trajectory;
