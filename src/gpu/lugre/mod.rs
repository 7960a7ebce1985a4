//! The LuGre integrator on the GPU (docs/model.md section 8) in f64: the WGSL
//! in `shaders/lugre/`, a function-for-function mirror of
//! [`crate::laws::lugre`] (`model.wgsl` of `model.rs`, `rodas.wgsl` of
//! `rodas.rs`: Rodas4 on the reduced 6 x 6 system), and its host, which
//! runs a batch on the engine's queue (`gpu::slices`, with LuGre's lanes
//! as `runner::Lugre`).
//!
//! * Lanes as Karnopp's: the first dispatch runs every instance on a lane
//!   of its own, then a few lanes ([`LugreGpu::lanes`]) take the queued
//!   ones in turn, and the busy ones are packed once the queue is empty.
//!   Each dispatch a lane makes at most [`LugreGpu::attempts`] Rodas4 step
//!   attempts on the instances it holds. A run (the 11 numbers, the step
//!   size, the budget, the segment in hand and its `rejected` flag, the
//!   period count and the period's start) stays in the engine's `states`
//!   buffer between dispatches ([`Lane`]), so that a run cut into
//!   dispatches anywhere, on any lane, gives the same bits; the
//!   per-instance parameters are packed once ([`Params`], binding 9).
//! * A lane measures its period ends itself (`shaders/lugre/measure.wgsl`):
//!   the floor's measurement files (`setup.wgsl`, `measure.wgsl`, `phase.wgsl`,
//!   [`MEASUREMENT_FILES`]) on its own accumulators, then the recurrence
//!   test that compares z, as the CPU run's `Periods::period_end` does,
//!   and starts its next period; a finished run leaves the engine's head.
//!   The host reads the engine's two counters after each dispatch, and
//!   the runs, their heads (and the accumulators the reductions need), and
//!   the recurrence snapshots of runs still going once, at the batch's
//!   end. The result is a
//!   floor `Run` per instance (`Periods::resume`), which
//!   `measurement::reduce` turns into the record the CPU gives.
//! * The batch's slow tail goes to the CPU by the Karnopp batches' rule
//!   ([`crate::gpu::tail_size`], [`LugreGpu::cpu_tail`]): once no more
//!   runs than that are going, the CPU continues each from the start of
//!   its current period (`laws::lugre::run::continue_until`), whose state,
//!   step, budget and measurement its lane keeps.
//! * llvmpipe (lavapipe) ends every loop of an invocation once all its
//!   loops together have run 65,535 passes, silently, counting the passes
//!   of a SIMD group's lanes together. The attempts' loop makes at most one
//!   attempt per pass (no loop of attempts inside a loop of segments,
//!   which would count the lanes' attempts one after the other), one
//!   attempt has at most [`LOOP_PASSES_PER_ATTEMPT`] loop passes in the
//!   source and a period end at most [`PERIOD_END_PASSES`]; a lane
//!   measures at most [`SOFTWARE_PERIOD_ENDS`] per dispatch there, and a
//!   software adapter gets [`SOFTWARE_ATTEMPTS`] attempts per dispatch:
//!   the source's count within a third of the limit. `tests/it/gpu_lugre.rs`
//!   checks that a batch gives the same bits at 3 attempts per dispatch (an
//!   attempt cut short changes the numbers).
//! * Arithmetic ([`Arithmetic`]): on llvmpipe WGSL's own f64 division and
//!   square root, which are IEEE's, as the CPU's; on hardware the floor
//!   prelude's `div` and `root` ([`crate::gpu::prelude`]), as
//!   NVIDIA's compiler requires. llvmpipe's f64 `fma` is not fused (a
//!   rounded product and a sum), and its compiler rewrites a + b - a to b
//!   where it may reassociate: the shader uses no fma, and `keep` guards
//!   the two-part sums. [`LugreGpu::hardware_variant`] gives the hardware's
//!   shader on any adapter, so the tests run it on lavapipe too.
//! * WGSL's f64 has no exp or pow: the CPU's LuGre integrator computes
//!   exp, hypot and the step control's fourth root with algorithms the
//!   shader can run ([`crate::laws::lugre::libm`]: [`exp_nonpositive`],
//!   [`hypot`], [`fourth_root`]), and the shader runs them. So on llvmpipe
//!   the shader's right-hand side, Jacobian and Rodas4 step are the CPU's
//!   to the last bit ([`LugreGpu::mirror_check`]), and whole runs are too
//!   (`tests/it/gpu_lugre.rs`). On hardware, division and square root go
//!   through the floor prelude's helpers and may round otherwise; the
//!   step control is chaotic at the tolerance's scale (one unit in the
//!   last place of the tolerance moves the CPU's own results by up to
//!   8.5e-6 um per cycle at the default 1e-4, 2.3e-7 um at 1e-6).
//!
//! `crate::backend::gpu` hands a batch of LuGre instances to
//! [`LugreGpu::run_until`].
//!
//! The files, named as `gpu::karnopp`'s: `shader.rs` (the prelude
//! generated from the Rust constants, the LU factorisation and solve
//! written out, the source with the shared measurement files),
//! `footprint.rs` (what a lane carries), `layout.rs` (the structs shared
//! with WGSL), `runner.rs` (LuGre's lanes for the
//! engine, and a batch on the pipeline the context compiles once:
//! `GpuContext::law_pipeline`, sized by the engine's `batch_limit`) and `probes.rs`
//! (the function-by-function comparisons the tests run on a device). The
//! shader's exp, hypot and fourth root are mirrored in
//! [`crate::laws::lugre::libm`].

mod footprint;
mod layout;
mod probes;
mod runner;
mod selftest;
mod shader;

pub use crate::laws::lugre::libm::{exp_nonpositive, fourth_root, hypot, split, two_prod, two_sum};
pub use footprint::{
    PIPELINE_NAME, footprint, footprints, hardware_lanes, lane_spirv, write_sources,
};
pub use layout::{Lane, MirrorCheck, Params, Probe, Probed};
pub use runner::{BatchReport, Followed, LugreGpu, table_lines};
pub use selftest::BACKWARD_ALLOWANCE_M;
pub use shader::{Arithmetic, Form, parse_and_validate, prelude, source};

/// The shader files, in the order they are concatenated after the prelude.
pub const FILES: [(&str, &str); 4] = [
    (
        "lugre/model.wgsl",
        include_str!("../../../shaders/lugre/model.wgsl"),
    ),
    (
        "lugre/rodas.wgsl",
        include_str!("../../../shaders/lugre/rodas.wgsl"),
    ),
    (
        "lugre/measure.wgsl",
        include_str!("../../../shaders/lugre/measure.wgsl"),
    ),
    (
        "lugre/entry.wgsl",
        include_str!("../../../shaders/lugre/entry.wgsl"),
    ),
];

/// The drive over an axis' corners (waveform variants: `WAVEFORM`),
/// included after the engine's queue, or its stand-ins
/// (`shader::SAWTOOTH_ONLY`) in a sawtooth variant.
pub const CORNER_FILE: (&str, &str) = (
    "lugre/corners.wgsl",
    include_str!("../../../shaders/lugre/corners.wgsl"),
);

/// Where a lane holds its parameters, Rodas4 stages and W: in device
/// memory on hardware (`Arithmetic::Fused`'s adapters), in private
/// variables on llvmpipe (`Arithmetic::Native`), each file defining the
/// same functions ([`holder`]).
pub const HOLDERS: [(&str, &str); 2] = [
    (
        "lugre/hold_memory.wgsl",
        include_str!("../../../shaders/lugre/hold_memory.wgsl"),
    ),
    (
        "lugre/hold_registers.wgsl",
        include_str!("../../../shaders/lugre/hold_registers.wgsl"),
    ),
];

/// The holder of `arithmetic`'s adapters ([`HOLDERS`]): device memory on
/// hardware, where registers are few (issue 57: 237 VGPRs on RADV's
/// compiler, none spilled, against 479 asked and 271 spilled), private
/// variables on llvmpipe, where device memory ran the 61 x 61 LuGre map
/// 2.9 times slower.
pub fn holder(arithmetic: Arithmetic) -> (&'static str, &'static str) {
    match arithmetic {
        Arithmetic::Fused => HOLDERS[0],
        Arithmetic::Native => HOLDERS[1],
    }
}

/// The floor's measurement files, which every LuGre shader includes as
/// they are after [`FILES`] (`measure.wgsl` says how they fit).
pub const MEASUREMENT_FILES: [(&str, &str); 3] = [
    (
        "shared/setup.wgsl",
        include_str!("../../../shaders/shared/setup.wgsl"),
    ),
    (
        "shared/measure.wgsl",
        include_str!("../../../shaders/shared/measure.wgsl"),
    ),
    (
        "shared/phase.wgsl",
        include_str!("../../../shaders/shared/phase.wgsl"),
    ),
];

/// The backward travel's files (issue 59), which a backward variant
/// ([`Form::Backward`]) includes after [`MEASUREMENT_FILES`]: the floor's
/// `follow`, then LuGre's step variation and hooks.
pub const VARIATION_FILES: [(&str, &str); 2] = [
    (
        "shared/variation.wgsl",
        include_str!("../../../shaders/shared/variation.wgsl"),
    ),
    (
        "lugre/variation.wgsl",
        include_str!("../../../shaders/lugre/variation.wgsl"),
    ),
];

/// The compute entry point of the integrator.
pub const ENTRY_POINT: &str = "lugre_advance";

/// The compute entry point that evaluates the shader-only functions
/// `exp_nonpositive`, `hypot` and `fourth_root` (tests).
pub const FUNCTIONS_ENTRY_POINT: &str = "lugre_functions";

/// The compute entry point that evaluates `rhs`, `jacobian` and `rodas4`
/// at given states (tests).
pub const MIRROR_ENTRY_POINT: &str = "lugre_mirror";

/// llvmpipe's limit on the loop passes of one invocation (all its loops
/// together, a SIMD group's lanes counted together).
pub const LOOP_LIMIT: u32 = 65_535;

/// The loop passes of one step attempt, counted in the shader's source as
/// llvmpipe counts them (a loop's iterations and one more per entry): the
/// attempts' loop 1, a segment's start at most 10 (two corners' searches
/// of [`CORNER_RETRIES`]; a waveform variant's lookups of the piece are
/// written out, [`CORNER_SEARCH`]), Rodas4's stage loop 7 and its sums over the
/// earlier stages 14 and 20. The Jacobian, W, its factorisation and solve,
/// the right-hand side, the vector sums and the error norm have no loops:
/// they are written out. Measured on llvmpipe 15: a lone lane of a 1 Hz
/// instance is cut between 1,200 and 1,400 attempts in one dispatch, 47 to
/// 55 passes each (`tests/it/gpu_lugre.rs`, `dispatches_cut_nothing_short`).
pub const LOOP_PASSES_PER_ATTEMPT: u32 =
    1 + 2 * (CORNER_RETRIES + 1) + (6 + 1) + (10 + 4) + (15 + 5);

/// The loop passes of one period end, counted as [`LOOP_PASSES_PER_ATTEMPT`]
/// (iterations and entries): the phase ladder's 18 levels 19, a batch's
/// halving 17, the batch estimate's MSER cut 885 (17 cuts of two passes
/// over up to 32 batches each) and statistics 134, and the recurrence
/// test's 8 snapshots 9.
pub const PERIOD_END_PASSES: u32 = 19 + 17 + 885 + 134 + 9;

/// The period ends a lane measures in one dispatch on a software adapter.
/// With one, a SIMD group's lanes make their attempts in at most two runs
/// of the attempts' loop (before and after its period end, which lanes
/// that reach theirs in different passes take one after the other) and
/// measure period ends in at most two passes of the entry's loop.
pub const SOFTWARE_PERIOD_ENDS: u32 = 1;

/// Step attempts per dispatch on a software adapter: two runs of the
/// attempts' loop and two period ends stay within a third of
/// [`LOOP_LIMIT`] as counted in the source.
pub const SOFTWARE_ATTEMPTS: u32 =
    (LOOP_LIMIT / 3 - 2 * PERIOD_END_PASSES) / (2 * LOOP_PASSES_PER_ATTEMPT);

/// The loop passes the backward travel adds to a period end: `follow`'s
/// phase ladder 19 and batch halving 17, as the step's.
pub const FOLLOW_PASSES: u32 = 19 + 17;

/// [`SOFTWARE_ATTEMPTS`] of a backward variant ([`Form::Backward`]): an
/// accepted attempt's variation (`variation.wgsl`) is written out, with
/// no loop passes, so only `follow`'s at the period ends count.
pub const SOFTWARE_BACKWARD_ATTEMPTS: u32 =
    (LOOP_LIMIT / 3 - 2 * (PERIOD_END_PASSES + FOLLOW_PASSES)) / (2 * LOOP_PASSES_PER_ATTEMPT);

/// The lanes a LuGre batch keeps busy after its first dispatch on a
/// software adapter (the engine's queue; Karnopp's take
/// [`crate::gpu::SOFTWARE_LANES_PER_THREAD`] per core). A LuGre dispatch
/// is [`SOFTWARE_ATTEMPTS`] attempts long, and llvmpipe's cost per
/// dispatch outweighs fewer lanes' shorter tails: on this project's
/// 2-core machine the 61 x 61 LuGre coupling map took 9.2 s with 256 lanes,
/// 8.2 s with 1,024 and 7.4 s with 4,096 (medians of three, whole
/// processes in turn; results/house.md).
pub const SOFTWARE_LANES: usize = 4096;

/// Step attempts per dispatch on a hardware adapter (no loop limit; a few
/// milliseconds of work per lane, not measured yet).
pub const HARDWARE_ATTEMPTS: u32 = 1024;

/// Invocations per workgroup on a software adapter (llvmpipe spreads
/// workgroups over its threads: small groups share a small batch among
/// the cores) and on a hardware one.
pub const SOFTWARE_WORKGROUP_SIZE: u32 = 4;
pub const HARDWARE_WORKGROUP_SIZE: u32 = 64;

/// The attempts a next corner's search makes before it takes what it has
/// (the CPU recurses; a corner rounded onto t once is already rare).
pub const CORNER_RETRIES: u32 = 4;

/// The halvings of a waveform variant's search for the piece that holds
/// a phase (`corners.wgsl`'s `piece_at`, its `search_corners` written out
/// by `shader::corner_search_source`): an axis' corners are at most
/// [`MAX_CORNERS`], which a table of `floor::drive::MAX_TABLE_ENTRIES`
/// keeps under its amplifier's slew limit (a corner where the follower
/// meets each flank, at most; tested).
pub const CORNER_SEARCH: u32 = 8;

/// The most corners an axis may have in a waveform variant.
pub const MAX_CORNERS: usize = 1 << CORNER_SEARCH;

/// What `segment` returns after a step attempt that leaves the run going,
/// and once the segment is complete (the other values are statuses).
pub const SEGMENT_GOING: u32 = u32::MAX;
pub const SEGMENT_DONE: u32 = u32::MAX - 1;

/// The flags of a [`Lane`] (`entry.wgsl`'s LANE_*): set up by the host at
/// its run's start, running, or stopped (failed or finished).
pub const LANE_FRESH: u32 = 0;
pub const LANE_RUNNING: u32 = 1;
pub const LANE_STOPPED: u32 = 2;
