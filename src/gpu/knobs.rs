//! The GPU path's tuning constants and the environment knobs that override
//! them for measurements. A knob read once per process; a value it refuses
//! is reported on stderr and the default stands.

use std::str::FromStr;
use std::sync::OnceLock;

use super::{F32Check, Route};
use crate::knob::knob;

/// Invocations per workgroup; the shader reads it from its prelude. A warp
/// on NVIDIA, and small enough that lavapipe spreads a batch of 64 over two
/// CPU threads.
pub const WORKGROUP_SIZE: u32 = 32;

/// Iterations of `iterate` per instance and dispatch: a dispatch then takes
/// milliseconds on a GPU, far from any watchdog.
pub const SLICE_ITERATIONS: u32 = 1024;

/// Lanes (invocations) that work through a batch's instances, at most:
/// enough to fill an H100 (132 multiprocessors x 2048 threads) about once.
/// A lane that finishes an instance takes the next one, so a batch of more
/// instances than lanes keeps every lane busy until the last few.
pub const LANES: usize = 1 << 18;

/// The invocations per workgroup this process uses: [`WORKGROUP_SIZE`], or
/// `PIDM_GPU_WORKGROUP` (a power of two from 1 to 256).
pub fn workgroup_size() -> u32 {
    static SIZE: OnceLock<u32> = OnceLock::new();
    *SIZE.get_or_init(|| {
        knob(
            "PIDM_GPU_WORKGROUP",
            WORKGROUP_SIZE,
            |n: &u32| n.is_power_of_two() && *n <= 256,
            "a power of two from 1 to 256",
        )
    })
}

/// The lanes this process uses: [`LANES`], or `PIDM_GPU_LANES` (at least 1).
pub fn lanes() -> usize {
    static LANE_COUNT: OnceLock<usize> = OnceLock::new();
    *LANE_COUNT.get_or_init(|| {
        knob(
            "PIDM_GPU_LANES",
            LANES,
            |n| *n >= 1,
            "an integer of at least 1",
        )
    })
}

/// The iterations per dispatch this process uses: [`SLICE_ITERATIONS`], or
/// `PIDM_GPU_SLICE` (at least 1).
pub fn slice_iterations() -> u32 {
    static SLICE: OnceLock<u32> = OnceLock::new();
    *SLICE.get_or_init(|| {
        knob(
            "PIDM_GPU_SLICE",
            SLICE_ITERATIONS,
            |n| *n >= 1,
            "an integer of at least 1",
        )
    })
}

/// How f32 batches check their heaviest runs: [`F32Check::Auto`], or
/// `PIDM_F32_CHECK` = `auto`, `twins`, `reference` or `off` (for
/// measuring the check's cost and what it catches; `off` leaves f32's
/// chaotic misses in the maps, results/gpu.md).
pub fn f32_check() -> F32Check {
    static CHECK: OnceLock<F32Check> = OnceLock::new();
    *CHECK.get_or_init(|| {
        knob(
            "PIDM_F32_CHECK",
            F32Check::Auto,
            |_| true,
            "auto, twins, reference or off",
        )
    })
}

impl FromStr for F32Check {
    type Err = ();
    fn from_str(text: &str) -> Result<F32Check, ()> {
        match text {
            "auto" => Ok(F32Check::Auto),
            "twins" => Ok(F32Check::Route(Route::Twins)),
            "reference" => Ok(F32Check::Route(Route::Reference)),
            "off" => Ok(F32Check::Off),
            _ => Err(()),
        }
    }
}

impl std::fmt::Display for F32Check {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            F32Check::Auto => "auto",
            F32Check::Route(Route::Twins) => "twins",
            F32Check::Route(Route::Reference) => "reference",
            F32Check::Off => "off",
        })
    }
}
