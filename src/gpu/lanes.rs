//! What the engine needs of a law's lanes (`Lanes`): the structs a batch
//! keeps on the device per instance, how many steps a state has taken and
//! whether it is done, and a bound on the slices one instance can need;
//! what a law hands the engine with a batch (`Kernel`, `Work`) and gets
//! back (`Sliced`).
//! The queue, packing, time slices, readback and the CPU tail's size
//! (`slices.rs`, `readback.rs`, `warps.rs`) see a law only through it.
//! Karnopp's lanes are `karnopp::runner`'s `Single` and `Double`
//! (whose `Layout` adds packing, outcomes, replicas and continuation),
//! LuGre's are `lugre::Lugre`.

use super::*;
use layout::control::Tally;

/// One law's lanes, in one precision, as the engine sees them.
pub(super) trait Lanes {
    const PRECISION: Precision;

    /// Per instance, read only: what the steady measurement reads
    /// (binding 0).
    type Coefficients: HostLayout + Send + Sync;
    /// Per instance, between dispatches (binding 1).
    type State: HostLayout + Send + Sync;
    /// A steady measurement's accumulators (binding 5).
    type Measure: HostLayout + Send + Sync;
    /// What the host reads of every finished steady measurement (binding
    /// 6).
    type Head: HostLayout + Send + Sync;
    /// Whether a measurement with this head ended with a verdict whose
    /// reduction reads only the head (periodic or phase-resolved).
    fn head_suffices(h: &Self::Head) -> bool;
    /// The accumulators that the reduction of such a head reads.
    fn from_head(h: &Self::Head) -> Self::Measure;
    /// The steps a state has taken.
    fn steps(st: &Self::State) -> u32;
    /// What a round's pilot keeps of a run on the CPU: the law's host
    /// result (Karnopp's outcome, LuGre's run).
    type Pilot: Send;
    /// `inst`'s whole run on the CPU in f64, as the CPU tail's results
    /// are, where the law's lanes park an instance at the round's cap on
    /// its steps (`control.cap`), so that a batch can run in rounds
    /// (`rounds::first_cap`); `None` where they don't (the clock then
    /// decides the batch's tail).
    fn pilot(inst: &Instance, settings: &Settings) -> Option<Self::Pilot>;
    /// The steps a pilot's run took.
    fn pilot_steps(p: &Self::Pilot) -> u32;
    /// Whether the instance's run has ended on the device.
    fn finished(inst: &Instance, st: &Self::State) -> bool;
    /// An upper bound on the slices one of `instances` can need on a lane
    /// of its own: every slice advances the instance a lane holds by one
    /// unit of work or more (an iteration, a step attempt, a period end)
    /// or finishes it. The engine multiplies it by the rounds of lanes.
    fn slice_bound(instances: &[Instance], settings: &Settings) -> u64;
}

/// Every state of a batch; for a batch with a steady instance, every
/// measurement; and for a kernel that measures the backward travel
/// ([`Kernel::backward`]), every instance's variation entry (empty
/// otherwise), as read back from the device.
pub(super) type Readback<L> = (
    Vec<<L as Lanes>::State>,
    Vec<<L as Lanes>::Measure>,
    Vec<<L as Lanes>::Measure>,
);

/// A law's compiled pipeline, and what the engine binds and sizes for it.
#[derive(Clone, Copy)]
pub(super) struct Kernel<'p> {
    pub(super) pipeline: &'p wgpu::ComputePipeline,
    /// It measures steady runs: it binds the accumulators and heads (5
    /// and 6).
    pub(super) steady: bool,
    /// Its adapter's loop limiter cuts iterations short (Karnopp on
    /// llvmpipe): the accumulators end with a scratch entry per lane.
    pub(super) loop_limiter: bool,
    /// It measures the backward travel (Karnopp's `variation.wgsl`, with
    /// `steady`): the accumulators' buffer has a second half of as many
    /// entries, each instance's variation, which every instance uses.
    pub(super) backward: bool,
    /// Invocations per workgroup, as its source declares them.
    pub(super) workgroup_size: u32,
    /// The law's own buffers and their bindings, after the engine's 0 to
    /// 8 (LuGre's parameters and recurrence snapshots).
    pub(super) extra: &'p [(u32, &'p wgpu::Buffer)],
    /// Buffers the engine gives each lane an entry of, with their
    /// bindings and bytes per entry (Karnopp's f64 hardware lanes hold a
    /// step's flow, samples and propagators there).
    pub(super) per_lane: &'p [(u32, u64)],
}

impl<'p> Kernel<'p> {
    /// `n` lanes rounded up to whole workgroups.
    pub(super) fn whole_workgroups(&self, n: usize) -> usize {
        n.div_ceil(self.workgroup_size as usize) * self.workgroup_size as usize
    }
}

/// A batch's instances, their coefficients and, where the law's host sets
/// them up, the states its lanes start from (else zeroed: the first
/// dispatch starts every instance, `control.initialize`).
pub(super) struct Work<'w, L: Lanes> {
    pub(super) instances: &'w [Instance],
    pub(super) coefficients: &'w [L::Coefficients],
    pub(super) states: Option<&'w [L::State]>,
}

/// What `Runner::slices` leaves of a batch.
pub(super) struct Sliced<L: Lanes> {
    /// Every state and, for a batch with a steady instance, every
    /// measurement.
    pub(super) readback: Readback<L>,
    /// The tallies of the first dispatch (instance k's on lane k).
    pub(super) probe_tallies: Vec<Tally>,
    /// The instances a round's pilot ran whole on the CPU, and their
    /// outcomes, which stand: the queue left them out
    /// (`rounds::first_cap`).
    pub(super) pilot: Vec<(usize, L::Pilot)>,
    /// Dispatches, each followed by a readback of the counters.
    pub(super) dispatches: u64,
    /// Iterations the dispatches offered the lanes that held an
    /// unfinished instance at their start (per dispatch, those lanes times
    /// its iterations): the slots the lanes' work filled.
    pub(super) offered: u64,
}
