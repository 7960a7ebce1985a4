//! The kinds of work a lane counts (the engine's tallies,
//! `pidm::gpu::warps`, and the profile's table), one vocabulary for every
//! law: Karnopp's `iterate` returns one of them per iteration; LuGre's
//! lanes count an accepted step attempt as a slip step, a rejected one as
//! a rejected trial, and their period ends. The shader reads them through
//! its prelude.

/// What one iteration did, for the lanes' counts the shader keeps: lanes
/// of one warp that do different kinds of iteration run each other's
/// code. Karnopp's `iterate` passed drive corners or period ends and took
/// no step (or finished there).
pub const ITERATION_BOUNDARY: u32 = 0;
/// A step in stick that located no event.
pub const ITERATION_STICK: u32 = 1;
/// A step in slip (in or outside the band) that located no event.
pub const ITERATION_SLIP: u32 = 2;
/// A slip trial rejected: only the step length changed.
pub const ITERATION_REJECTED: u32 = 3;
/// A step that located an event and moved to it.
pub const ITERATION_EVENT: u32 = 4;
/// Not an iteration of `iterate`: a steady measurement's bookkeeping at a
/// period end (`measure::period_end`), which the lane's loop runs between
/// iterations. The lanes' counts keep it beside the kinds above.
pub const ITERATION_PERIOD_END: u32 = 5;
/// The kinds of iteration a lane counts.
pub const ITERATION_KINDS: usize = 6;
/// The kinds' names in the profile table (`ITERATION_*` order).
pub const KIND_NAMES: [&str; ITERATION_KINDS] = [
    "boundary",
    "stick step",
    "slip step",
    "rejected trial",
    "event location",
    "period end",
];

/// Rejected slip trials as a share of all slip trials (slip steps and
/// rejected trials) in counts by kind: the work the step-size controller
/// throws away (issue 47 holds it to 12 %).
pub fn rejected_share(kinds: &[u64; ITERATION_KINDS]) -> f64 {
    let rejected = kinds[ITERATION_REJECTED as usize];
    let trials = rejected + kinds[ITERATION_SLIP as usize];
    if trials == 0 {
        0.0
    } else {
        rejected as f64 / trials as f64
    }
}

/// The kinds as WGSL constants, for every law's shader prelude
/// (`crate::gpu::prelude`).
pub fn wgsl_constants() -> String {
    [
        ("ITERATION_BOUNDARY", ITERATION_BOUNDARY),
        ("ITERATION_STICK", ITERATION_STICK),
        ("ITERATION_SLIP", ITERATION_SLIP),
        ("ITERATION_REJECTED", ITERATION_REJECTED),
        ("ITERATION_EVENT", ITERATION_EVENT),
        ("ITERATION_PERIOD_END", ITERATION_PERIOD_END),
    ]
    .map(|(name, v)| format!("const {name}: u32 = {v}u;\n"))
    .concat()
}
