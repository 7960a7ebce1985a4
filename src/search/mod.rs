//! Derivative-free searches and samplings of a box of parameters, shared
//! by the commands that look for a best point or for what matters:
//! `pidm fit`'s global stage today (issue 61: `pidm optimize` and `pidm
//! sensitivity` are to share them). They know nothing of the engine: a
//! candidate is scored by a batch callback, a sample by its output.
//!
//! * `evolution.rs`: differential evolution, feasibility first.
//! * `front.rs`: GDE3, a front between two costs, feasibility first.
//! * `pattern.rs`: a compass search, the local stage for a noisy cost.
//! * `sobol.rs`: Saltelli's sample and the Sobol' indices SALib reports.
//! * `distributions.rs`: a key's value from a point of the unit cube, and
//!   an output's spread.
//! * `rng.rs`: the seeded generator both draw from.

pub mod distributions;
pub mod evolution;
pub mod front;
pub mod pattern;
pub mod rng;
pub mod sobol;
