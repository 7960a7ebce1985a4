//! pidm: maps of how two-axis piezoelectric impact drives move.
//!
//! See ARCHITECTURE.md for the bird's-eye view.

pub mod accuracy;
pub mod backend;
pub mod checkpoint;
pub mod commands;
pub mod design;
pub mod fit;
pub mod gpu;
pub mod interrupt;
pub mod knob;
pub mod laws;
pub mod measurement;
pub mod model;
pub mod output;
pub mod plot;
pub mod profile;
pub mod progress;
pub mod refine;
pub mod replicas;
pub mod run;
pub mod scene;
pub mod scope;
pub mod search;
pub mod stall;
pub mod sweep;
pub mod trajectory;
