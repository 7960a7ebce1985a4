//! Derivative-free searches over a box of parameters, shared by the
//! commands that look for a best point: `pidm fit`'s global stage today
//! (issue 61: `pidm optimize` is to share it). They know nothing of the
//! engine: a candidate is scored by a batch callback.

pub mod evolution;
