//! The rounds in which a batch's CPU tail is taken (`super::slices`): a
//! CPU pilot sets the first cap on an instance's steps, the lanes park
//! instances at the cap (`shaders/engine/queue.wgsl`'s `park`), and each
//! round's end decides by the count of the parked.

use super::*;
use layout::control::NO_CAP;

/// A round's pilot: each instance's index and its run's result.
pub(super) type Piloted<L> = Vec<(usize, <L as Lanes>::Pilot)>;

/// Where a batch runs in rounds (a law whose lanes park, a CPU tail, no
/// replica groups), the first round's cap on an instance's steps: the most
/// steps of a pilot of up to `tail_size` of the unfinished instances in
/// `order`, spread over them by index, each run whole on the CPU in f64,
/// times 1.5 ([`PILOT_QUARTERS`]), at least [`MIN_CAP`]; and the pilot's
/// outcomes, which stand (the CPU tail's own), taken out of `order`.
///
/// Why rounds: the CPU integrates an instance with other roundings than
/// the shader (a fused multiply-add, an emulated division), so a run the
/// CPU finishes differs from the device's by the tolerance's scatter. Were
/// the tail the instances left when the clock says so, which ones those
/// are, and where the CPU takes them over, would change from run to run.
/// In rounds, the lanes park every instance at its first iteration
/// boundary at or past the round's cap (steps, which only the run's own
/// arithmetic sets); a round ends once every instance has finished or
/// parked, and the count of the parked decides: at most the tail's size
/// ([`HAND_OVER`]), and the CPU continues them from there; more, and they
/// go on in a round of a cap 1.125 times higher ([`ROUND_GROWTH_EIGHTHS`]). Both depend on the runs alone, so the same command
/// writes the same bits. (The first dispatch's own prediction of the cost,
/// which ranks the queue, overestimates a window run's steps about
/// sixtyfold: its 128 iterations see the start from rest.)
pub(super) fn first_cap<L: Lanes>(
    instances: &[Instance],
    settings: &Settings,
    order: &mut Vec<u32>,
    tail_size: u64,
) -> Option<(u32, Piloted<L>)> {
    let mut unfinished = order.clone();
    unfinished.sort_unstable();
    let count = unfinished.len();
    let m = (tail_size as usize)
        .min(PILOT_PER_THREAD * rayon::current_num_threads())
        .clamp(1, count);
    let pilot = (0..m)
        .into_par_iter()
        .map(|k| {
            let index = unfinished[k * count / m] as usize;
            L::pilot(&instances[index], settings).map(|outcome| (index, outcome))
        })
        .collect::<Option<Vec<(usize, L::Pilot)>>>()?;
    let piloted: std::collections::HashSet<u32> = pilot.iter().map(|(k, _)| *k as u32).collect();
    order.retain(|k| !piloted.contains(k));
    let most = pilot
        .iter()
        .map(|(_, p)| L::pilot_steps(p))
        .max()
        .unwrap_or(0);
    let cap = most as u64 * PILOT_QUARTERS / 4;
    Some((cap.clamp(MIN_CAP as u64, NO_CAP as u64 - 1) as u32, pilot))
}

/// Pilot instances per CPU thread at most ([`first_cap`]): the pilot's
/// largest steps then stand for the batch's upper thousandth or so.
const PILOT_PER_THREAD: usize = 64;

/// The first round's cap over the pilot's most steps ([`first_cap`]), in
/// quarters: 1.5. On random 2,000 on lavapipe f64 (its pilot's most, 4,156
/// steps; results/house.md) 1 and 1.25 take more rounds; 1.5 parks 51,
/// which the CPU takes ([`HAND_OVER`]) as fast as the clock's tail; a
/// higher cap makes every lane wait longer for the instances that started
/// last.
const PILOT_QUARTERS: u64 = 6;

/// Each round's cap over the last one's, in eighths: 1.125. Fine steps,
/// since the parked instances go on together and a round costs little
/// more than its steps, and a coarse one overshoots the tail: on random
/// 2,000, 1.25 and 2 ended with 21 and 12 parked of the 32 and 64 the CPU
/// would take, after longer rounds.
pub(super) const ROUND_GROWTH_EIGHTHS: u64 = 9;

/// The parked instances, over the default tail's size, that the CPU
/// takes at a round's end ([`Queue::hand_over`]; a tail's size set by
/// `PIDM_GPU_TAIL` is taken as it is). The clock's tail takes the last
/// ones whenever few are left, the instances that started last among
/// them; a round waits for those to reach its cap, so it lets the CPU take
/// more.
pub(super) const HAND_OVER: u64 = 2;

/// The smallest first round's cap [steps]: four first dispatches' worth.
const MIN_CAP: u32 = 4 * PROBE_ITERATIONS;
