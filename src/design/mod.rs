//! The design commands (issue 61, docs/design.md): `pidm optimize` finds
//! the best drive or mechanism under constraints, `pidm sensitivity` says
//! which parameters a quantity's spread comes from. Both run a scene's
//! one instance at candidates chosen by `crate::search`.
//!
//! * `quantity.rs`: what they measure (maps, `abs`, `hypot`, constraints)
//!   with standard errors by the delta method.
//! * `model.rs`: candidates as scenes, run in batches on a backend.
//! * `sensitivity/`: `[sensitivity]`, Saltelli's sample, Sobol' indices,
//!   SENS.json, SENS.png and the samples' CSV.
//! * `optimize/`: `[optimize]`, the search, OPT.json, OPT.toml, OPT.png.

pub mod model;
pub mod optimize;
pub mod quantity;
pub mod sensitivity;
