//! The floor every friction law stands on (issue 58): what the laws share
//! and neither owns. Its files are written for a scalar `Real`, as the
//! laws' integrators are, and compiled once per precision: [`double`]
//! (f64, SI units) and [`single`] (f32, the f32 shader's mirror's units).
//!
//! * `vec2.rs`: [`Vec2`], one value per axis (WGSL's `vec2<Real>`).
//! * `measure.rs`: the steady measurement (docs/model.md section 4), the
//!   CPU mirror of `shaders/shared/measure.wgsl`, read through two traits
//!   a law implements: [`measure::Gauge`] (its per-instance constants) and
//!   [`measure::Slider`] (its state).
//! * `phase.rs`: the phase ladder, the mirror of
//!   `shaders/shared/phase.wgsl`.
//! * `kinds.rs`: the kinds of work a lane counts (the engine's tallies).
//! * `setup.rs`: [`Setup`], the measurement's constants of an instance,
//!   computed from the instance alone.
//! * `units.rs`: the unit systems of the precisions (SI for f64,
//!   micrometres and milliseconds for f32).
//! * `check.rs` (f64 host code): f32's check of its heaviest window runs,
//!   the rule both f32 paths follow, whatever the law.
//! * `record.rs` (f64 only): [`Record`] and [`Run`], where a run of any
//!   law stands, as everything above the laws reads it.
//! * `variation.rs` (f64 only): the slider's total variation, the
//!   backward travel's position, measured beside the step.
//! * `drive/` (f64 host code): a waveform's corners over one cycle and
//!   the slew-limited follower's periodic orbit (issue 59), which
//!   both laws read.
//!
//! The run's settings are [`crate::laws::settings`], its status codes
//! [`crate::laws::status`]. Laws import the floor; the floor imports no law.
//! The f64 instance is re-exported here.

pub mod check;
pub mod double;
pub mod drive;
pub mod kinds;
pub mod record;
pub mod single;
pub mod units;
pub mod variation;

pub use double::{Setup, Vec2, measure, phase, setup, vec2};
pub use record::{Record, Run};
