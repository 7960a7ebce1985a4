//! What the engine needs of a law's lanes (`Lanes`): the structs a batch
//! keeps on the device per instance, how many steps a state has taken and
//! whether it is done, and a bound on the slices one instance can need.
//! The queue, packing, time slices, readback and the CPU tail's size
//! (`slices.rs`, `readback.rs`, `warps.rs`) see a law only through it.
//! Karnopp's lanes are `precision::Single` and `precision::Double`
//! (whose `Layout` adds packing, outcomes, replicas and continuation),
//! LuGre's are `lugre::Lugre`.

use super::*;

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
    /// Whether the instance's run has ended on the device.
    fn finished(inst: &Instance, st: &Self::State) -> bool;
    /// An upper bound on the slices one of `instances` can need on a lane
    /// of its own: every slice advances the instance a lane holds by one
    /// unit of work or more (an iteration, a step attempt, a period end)
    /// or finishes it. The engine multiplies it by the rounds of lanes.
    fn slice_bound(instances: &[Instance], settings: &Settings) -> u64;
}

/// Every state of a batch and, for a batch with a steady instance, every
/// measurement, as read back from the device.
pub(super) type Readback<L> = (Vec<<L as Lanes>::State>, Vec<<L as Lanes>::Measure>);
