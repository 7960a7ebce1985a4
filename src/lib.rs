//! pidm: maps of how two-axis piezoelectric impact drives move.
//!
//! See ARCHITECTURE.md for the bird's-eye view.

pub mod cpu;
pub mod gpu;
pub mod model;
