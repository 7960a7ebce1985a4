//! The GPU path's tuning constants and the environment knobs that override
//! them for measurements. A knob read once per process; a value it refuses
//! is reported on stderr and the default stands.

use std::str::FromStr;
use std::sync::OnceLock;

use super::warps::Order;
use super::{F32Check, Route};
use crate::knob::{knob, parse_knob};

/// Invocations per workgroup; the shader reads it from its prelude. A warp
/// on NVIDIA, and small enough that lavapipe spreads a batch of 64 over two
/// CPU threads.
pub const WORKGROUP_SIZE: u32 = 32;

/// Iterations of `iterate` per instance and dispatch: a dispatch then takes
/// milliseconds on a GPU, far from any watchdog.
pub const SLICE_ITERATIONS: u32 = 1024;

/// Lanes (invocations) that work through a batch's instances at once on a
/// hardware adapter: enough to fill an H100 (132 multiprocessors x 2048
/// threads) about once. A lane that finishes an instance takes the next
/// one, so a batch of more instances than lanes keeps every lane busy
/// until the last few.
pub const LANES: usize = 1 << 18;

/// Lanes per CPU thread on a software adapter (lavapipe runs a workgroup
/// of 32 on one thread, 8 lanes to a SIMD register): four workgroups a
/// thread, so threads share the work evenly and a dispatch of 1,024
/// iterations still takes tens of milliseconds, while the queue keeps
/// every lane of a workgroup busy. More lanes only make each dispatch
/// longer; the instances' cost is the same.
pub const SOFTWARE_LANES_PER_THREAD: usize = 128;

/// Iterations of a batch's first dispatch, which starts every instance and
/// whose tallies rank the rest of the queue (`warps::queue_order`): short,
/// since every instance is on a lane of its own there (and lanes whose
/// instance finishes sit idle), yet enough to see how fast each one
/// advances.
pub const PROBE_ITERATIONS: u32 = 128;

/// Lane-fulls a sweep chunk holds on a hardware device: four, so that
/// lanes take instances from the queue for most of a chunk and only its
/// last quarter or so can leave lanes idle.
pub const CHUNK_ROUNDS: usize = 4;

/// Lane-fulls a sweep chunk holds on a software adapter: sixteen (4,096
/// instances on two cores, the CPU path's chunk), so that a chunk is large
/// enough to hand its slow tail to the CPU
/// ([`super::CPU_TAIL_MIN_BATCH`]).
pub const SOFTWARE_CHUNK_ROUNDS: usize = 16;

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

/// The lanes `PIDM_GPU_LANES` asks for (at least 1), if set.
pub(super) fn lanes_knob() -> Option<usize> {
    static LANE_COUNT: OnceLock<Option<usize>> = OnceLock::new();
    *LANE_COUNT.get_or_init(|| {
        let text = std::env::var("PIDM_GPU_LANES").ok();
        match parse_knob(text.as_deref(), |n: &usize| *n >= 1) {
            Ok(lanes) => lanes,
            Err(text) => {
                eprintln!(
                    "pidm: ignoring PIDM_GPU_LANES = {text:?}: expected an integer of at least 1; \
                     using the adapter's default"
                );
                None
            }
        }
    })
}

/// The lanes a batch keeps busy at once on a hardware adapter: [`LANES`],
/// or `PIDM_GPU_LANES`.
pub fn lanes() -> usize {
    lanes_for(true)
}

/// The lanes a batch keeps busy at once: `PIDM_GPU_LANES` where set, else
/// [`LANES`] on a hardware adapter and [`SOFTWARE_LANES_PER_THREAD`] per
/// core on a software one (whose "GPU" is this machine's cores).
pub fn lanes_for(hardware: bool) -> usize {
    lanes_knob().unwrap_or_else(|| {
        if hardware {
            LANES
        } else {
            let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
            SOFTWARE_LANES_PER_THREAD * cores
        }
    })
}

/// Whether busy lanes are packed once a batch's queue is empty: yes, or
/// `PIDM_GPU_COMPACT=0`.
pub fn compact() -> bool {
    static COMPACT: OnceLock<bool> = OnceLock::new();
    *COMPACT.get_or_init(|| knob("PIDM_GPU_COMPACT", 1u8, |n| *n <= 1, "0 or 1") == 1)
}

/// How a batch's queue is ordered: [`Order::Cost`], or `PIDM_GPU_ORDER` =
/// `cost` or `index` (for measuring what the order is worth).
pub fn order() -> Order {
    static ORDER: OnceLock<Order> = OnceLock::new();
    *ORDER.get_or_init(|| knob("PIDM_GPU_ORDER", Order::Cost, |_| true, "cost or index"))
}

impl FromStr for Order {
    type Err = ();
    fn from_str(text: &str) -> Result<Order, ()> {
        match text {
            "cost" => Ok(Order::Cost),
            "index" => Ok(Order::Index),
            _ => Err(()),
        }
    }
}

impl std::fmt::Display for Order {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Order::Cost => "cost",
            Order::Index => "index",
        })
    }
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

/// The CPU tail of this process's batches ([`BatchOptions::cpu_tail`]):
/// the default rule, or `PIDM_GPU_TAIL` = `auto` or a count of instances
/// (`0`: none, so that a map is the device's alone, the same bits however
/// it is split into batches; tests/golden/house.sh).
///
/// [`BatchOptions::cpu_tail`]: super::BatchOptions::cpu_tail
pub fn cpu_tail() -> Tail {
    static TAIL: OnceLock<Tail> = OnceLock::new();
    *TAIL.get_or_init(|| {
        knob(
            "PIDM_GPU_TAIL",
            Tail(None),
            |_| true,
            "auto or a count of instances",
        )
    })
}

/// A CPU tail's size: `None` for the default rule.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tail(pub Option<usize>);

impl FromStr for Tail {
    type Err = ();
    fn from_str(text: &str) -> Result<Tail, ()> {
        match text {
            "auto" => Ok(Tail(None)),
            n => n.parse().map(|n| Tail(Some(n))).map_err(|_| ()),
        }
    }
}

impl std::fmt::Display for Tail {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.0 {
            None => f.write_str("auto"),
            Some(n) => write!(f, "{n}"),
        }
    }
}
