//! Where a run's wall time goes: `--profile` or `PIDM_GPU_PHASES=1` prints
//! one table per `pidm run` (issue 32), every second of the process
//! accounted for.
//!
//! Three threads do a run's work ([`crate::sweep::run_chunks`]): the
//! *driver* (the main thread) starts the process, opens the backend,
//! expands each chunk's instances into jobs, makes records and finishes
//! the file; the *integrator* runs the backend on one chunk and the
//! *writer* hands another's records to the HDF5 file and the checkpoint,
//! both beside the driver. The driver's phases ([`Phase::DRIVER`]) follow
//! one another, so with its waits for the integrator and the writer they
//! add up to the wall time, and what they leave is the "left over" line:
//! time no phase claims. The integrator's phases ([`Phase::INTEGRATOR`])
//! split its time on the backend (on the GPU: packing, uploads,
//! dispatches, readback, reduction, the CPU's part).
//!
//! Spans are always timed (two clock reads and an atomic add each, a few
//! per chunk and batch); only the table is optional.

use std::sync::OnceLock;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// A timed part of a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// From the process's start to the backend's choice: arguments, the
    /// scene, the output's claim.
    Start,
    /// Choosing and opening the backend: on the GPU the adapter, the
    /// device, the pipeline (from the cache) and its self-test.
    Backend,
    /// Opening the output: the temporary HDF5 file and the checkpoint.
    Open,
    /// Expanding a chunk's instances and their distinct integrations.
    Expand,
    /// The driver waiting for the integrator (or integrating itself, where
    /// chunks do not overlap): integration that nothing beside it hid.
    Wait,
    /// Records of finished integrations: baselines joined, the summary.
    Records,
    /// The driver waiting for the writer thread (or writing itself, where
    /// chunks do not overlap): writing that nothing beside it hid.
    WaitWriter,
    /// After the last chunk: trajectories, closing and renaming the file.
    Finish,
    /// The integrator thread on the backend, each chunk's whole call.
    Integrate,
    /// GPU: each instance's coefficients packed on the host.
    Pack,
    /// GPU: buffers made and the coefficients uploaded.
    Upload,
    /// GPU: the time-sliced dispatches, until a batch is done.
    Dispatch,
    /// GPU: states, heads and accumulators mapped and read.
    Readback,
    /// GPU: read-back states and accumulators reduced to outcomes.
    Reduce,
    /// GPU: the CPU's part, the slow tail of a batch continued, loop-limited
    /// and f32 fallbacks integrated, f32's check (twins or reference).
    CpuPart,
    /// The writer thread: records into the HDF5 file and the checkpoint.
    Write,
}

impl Phase {
    /// The driver's phases, in the order of a run.
    pub const DRIVER: [Phase; 8] = [
        Phase::Start,
        Phase::Backend,
        Phase::Open,
        Phase::Expand,
        Phase::Records,
        Phase::Wait,
        Phase::WaitWriter,
        Phase::Finish,
    ];

    /// The integrator's parts of [`Phase::Integrate`].
    pub const INTEGRATOR: [Phase; 6] = [
        Phase::Pack,
        Phase::Upload,
        Phase::Dispatch,
        Phase::Readback,
        Phase::Reduce,
        Phase::CpuPart,
    ];

    const COUNT: usize = 16;

    fn index(self) -> usize {
        self as usize
    }

    /// The table's words for the phase.
    pub fn label(self) -> &'static str {
        match self {
            Phase::Start => "start (arguments, scene, claim)",
            Phase::Backend => "backend (probe, device, pipeline, self-test)",
            Phase::Open => "opening the output and checkpoint",
            Phase::Expand => "expanding instances into jobs",
            Phase::Wait => "integration not hidden (waited for)",
            Phase::Records => "records and summary",
            Phase::WaitWriter => "writing not hidden (waited for)",
            Phase::Write => "writer thread: HDF5 file and checkpoint",
            Phase::Finish => "finishing (trajectories, closing, rename)",
            Phase::Integrate => "integrator thread, whole",
            Phase::Pack => "packing coefficients",
            Phase::Upload => "buffers and uploads",
            Phase::Dispatch => "dispatches",
            Phase::Readback => "readback",
            Phase::Reduce => "reduction to outcomes",
            Phase::CpuPart => "CPU tail, fallbacks and check",
        }
    }
}

static TOTALS: [AtomicU64; Phase::COUNT] = [const { AtomicU64::new(0) }; Phase::COUNT];
static BYTES_READ: AtomicU64 = AtomicU64::new(0);
/// Lane-nanoseconds of dispatches: every lane's, and those of lanes that
/// held an instance; nanoseconds of slices with idle lanes; most lanes.
static LANE_NS: AtomicU64 = AtomicU64::new(0);
static BUSY_LANE_NS: AtomicU64 = AtomicU64::new(0);
static TAIL_NS: AtomicU64 = AtomicU64::new(0);
static MOST_LANES: AtomicU64 = AtomicU64::new(0);
static FORCED: AtomicBool = AtomicBool::new(false);

/// The process's start, as [`start`] marked it (or the first use).
fn origin() -> Instant {
    static ORIGIN: OnceLock<Instant> = OnceLock::new();
    *ORIGIN.get_or_init(Instant::now)
}

/// Marks the process's start: call first thing in `main`.
pub fn start() {
    origin();
}

/// Seconds since [`start`].
pub fn elapsed() -> Duration {
    origin().elapsed()
}

/// Turns the table on (`--profile`).
pub fn enable() {
    FORCED.store(true, Ordering::Relaxed);
}

/// Whether the run prints its table: `--profile`, or `PIDM_GPU_PHASES` =
/// 1.
pub fn enabled() -> bool {
    static ASKED: OnceLock<bool> = OnceLock::new();
    FORCED.load(Ordering::Relaxed)
        || *ASKED
            .get_or_init(|| crate::knob::knob("PIDM_GPU_PHASES", 0u8, |n| *n <= 1, "0 or 1") == 1)
}

thread_local! {
    /// Whether this thread is inside a [`Phase::Integrate`] span: the
    /// integrator's parts count only there, not in the self-test batch
    /// that opening a GPU runs (part of [`Phase::Backend`]).
    static INTEGRATING: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Adds `time` to `phase`.
pub fn add(phase: Phase, time: Duration) {
    if Phase::INTEGRATOR.contains(&phase) && !INTEGRATING.with(|i| i.get()) {
        return;
    }
    TOTALS[phase.index()].fetch_add(time.as_nanos() as u64, Ordering::Relaxed);
}

/// Counts bytes read back from a device.
pub fn add_bytes_read(bytes: u64) {
    BYTES_READ.fetch_add(bytes, Ordering::Relaxed);
}

/// Counts one slice of `time` on a device with `lanes` lanes of which
/// `busy` held an instance (at the slice's start: an upper bound, as
/// lanes finish during the slice).
pub fn add_lanes(lanes: u64, busy: u64, time: Duration) {
    if !INTEGRATING.with(|i| i.get()) {
        return;
    }
    let ns = time.as_nanos() as u64;
    LANE_NS.fetch_add(lanes.saturating_mul(ns), Ordering::Relaxed);
    BUSY_LANE_NS.fetch_add(busy.saturating_mul(ns), Ordering::Relaxed);
    if busy < lanes {
        TAIL_NS.fetch_add(ns, Ordering::Relaxed);
    }
    MOST_LANES.fetch_max(lanes, Ordering::Relaxed);
}

/// Whether this thread is inside a [`Phase::Integrate`] span (the
/// integrator's work, not the self-test batch that opening a GPU runs).
pub fn integrating() -> bool {
    INTEGRATING.with(|i| i.get())
}

/// Runs `f` outside the integrator's counts: a pipeline's self-test
/// batch, compiled on a batch's first use inside an integration span
/// (`gpu::lugre`), adds nothing to the integrator's parts.
pub fn outside_integration<T>(f: impl FnOnce() -> T) -> T {
    let was = INTEGRATING.with(|i| i.replace(false));
    let out = f();
    INTEGRATING.with(|i| i.set(was));
    out
}

/// Times a phase until dropped.
#[must_use = "a span times until it is dropped"]
pub struct Span {
    phase: Phase,
    since: Instant,
    /// For a [`Phase::Integrate`] span: whether the thread was already in
    /// one.
    was_integrating: bool,
}

impl Drop for Span {
    fn drop(&mut self) {
        add(self.phase, self.since.elapsed());
        if self.phase == Phase::Integrate {
            INTEGRATING.with(|i| i.set(self.was_integrating));
        }
    }
}

/// A [`Span`] of `phase` from now.
pub fn span(phase: Phase) -> Span {
    let was_integrating = INTEGRATING.with(|i| {
        let was = i.get();
        if phase == Phase::Integrate {
            i.set(true);
        }
        was
    });
    Span {
        phase,
        since: Instant::now(),
        was_integrating,
    }
}

/// Runs `f` as a span of `phase`.
pub fn time<T>(phase: Phase, f: impl FnOnce() -> T) -> T {
    let _span = span(phase);
    f()
}

/// Seconds spent in `phase` so far.
pub fn seconds(phase: Phase) -> f64 {
    TOTALS[phase.index()].load(Ordering::Relaxed) as f64 * 1e-9
}

/// Marks everything from the process's start to now that no driver phase
/// claimed as [`Phase::Start`]: called once the backend is chosen, so the
/// start is what came before it.
pub fn close_start() {
    let claimed: f64 = Phase::DRIVER.iter().map(|&p| seconds(p)).sum();
    let start = elapsed().as_secs_f64() - claimed;
    if start > 0.0 {
        add(Phase::Start, Duration::from_secs_f64(start));
    }
}

/// The table for a run that ends now: each driver phase with its share of
/// the wall time and what is left over, then the integrator's.
pub fn table() -> String {
    render(
        elapsed().as_secs_f64(),
        &|p| seconds(p),
        BYTES_READ.load(Ordering::Relaxed),
    )
}

fn render(wall: f64, seconds: &dyn Fn(Phase) -> f64, bytes_read: u64) -> String {
    use std::fmt::Write;
    let share = |s: f64| 100.0 * s / wall.max(1e-12);
    let mut out = String::new();
    let line = |out: &mut String, label: &str, s: f64| {
        let _ = writeln!(
            out,
            "pidm: phase {label:<48} {s:>9.3} s {:>6.1} %",
            share(s)
        );
    };
    let _ = writeln!(
        out,
        "pidm: phase table (driver thread; its phases add up to the wall time)"
    );
    let mut claimed = 0.0;
    for p in Phase::DRIVER {
        let s = seconds(p);
        claimed += s;
        line(&mut out, p.label(), s);
    }
    // A refined or stall run plans its waves between sweeps: that time is
    // here too.
    line(
        &mut out,
        "left over (no phase; refine and stall plans)",
        (wall - claimed).max(0.0),
    );
    line(&mut out, "wall time of the process", wall);
    let integrate = seconds(Phase::Integrate);
    let _ = writeln!(
        out,
        "pidm: phase table (integrator and writer threads, beside the driver; % of the wall time)"
    );
    line(&mut out, Phase::Integrate.label(), integrate);
    let mut parts = 0.0;
    for p in Phase::INTEGRATOR {
        let s = seconds(p);
        parts += s;
        if s > 0.0 {
            line(&mut out, &format!("  {}", p.label()), s);
        }
    }
    if parts > 0.0 {
        line(
            &mut out,
            "  rest of the backend's calls",
            (integrate - parts).max(0.0),
        );
    }
    line(
        &mut out,
        "integration hidden behind the driver's work",
        (integrate - seconds(Phase::Wait)).max(0.0),
    );
    let write = seconds(Phase::Write);
    line(&mut out, Phase::Write.label(), write);
    line(
        &mut out,
        "writing hidden behind the driver's work",
        (write - seconds(Phase::WaitWriter)).max(0.0),
    );
    if bytes_read > 0 {
        let _ = writeln!(
            out,
            "pidm: phase read back from the device: {:.1} MB",
            bytes_read as f64 / 1e6
        );
    }
    let lane_ns = LANE_NS.load(Ordering::Relaxed);
    if lane_ns > 0 {
        let _ = writeln!(
            out,
            "pidm: phase lanes: up to {}; at most {:.1} % of the dispatches' lane-time held an \
             instance; {:.3} s of dispatches had idle lanes (batch tails)",
            MOST_LANES.load(Ordering::Relaxed),
            100.0 * BUSY_LANE_NS.load(Ordering::Relaxed) as f64 / lane_ns as f64,
            TAIL_NS.load(Ordering::Relaxed) as f64 * 1e-9
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_left_over_is_the_wall_time_no_driver_phase_claims() {
        let seconds = |p: Phase| match p {
            Phase::Start => 0.1,
            Phase::Backend => 0.2,
            Phase::Wait => 0.3,
            Phase::WaitWriter => 0.25,
            Phase::Write => 0.3,
            Phase::Integrate => 0.5,
            Phase::Dispatch => 0.4,
            _ => 0.0,
        };
        let table = render(1.0, &seconds, 0);
        let left = table
            .lines()
            .find(|l| l.contains("left over"))
            .expect("a left-over line");
        assert!(left.contains("0.150 s"), "{table}");
        assert!(left.contains("15.0 %"), "{table}");
        // Integration not waited for was hidden behind the driver.
        let hidden = table
            .lines()
            .find(|l| l.contains("integration hidden"))
            .expect("an integration-hidden line");
        assert!(hidden.contains("0.200 s"), "{table}");
        let hidden = table
            .lines()
            .find(|l| l.contains("writing hidden"))
            .expect("a writing-hidden line");
        assert!(hidden.contains("0.050 s"), "{table}");
        let rest = table.lines().find(|l| l.contains("rest of")).unwrap();
        assert!(rest.contains("0.100 s"), "{table}");
    }

    #[test]
    fn every_phase_has_a_distinct_index_and_one_table() {
        let all: Vec<Phase> = Phase::DRIVER
            .iter()
            .chain(&[Phase::Integrate])
            .chain(&Phase::INTEGRATOR)
            .chain(&[Phase::Write])
            .copied()
            .collect();
        assert_eq!(all.len(), Phase::COUNT);
        let mut seen = [false; Phase::COUNT];
        for p in all {
            assert!(!seen[p.index()], "{p:?} twice");
            seen[p.index()] = true;
        }
    }
}
