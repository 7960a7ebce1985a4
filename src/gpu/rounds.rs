//! The rounds in which a batch's CPU tail is taken (`super::slices`): a
//! CPU pilot sets the first cap on an instance's steps, the lanes park
//! instances at the cap (`shaders/engine/queue.wgsl`'s `park`), and each
//! round's end decides by the count of the parked.

use super::*;
use layout::control::NO_CAP;

/// A round's pilot: each instance's index and its run's result.
pub(super) type Piloted<L> = Vec<(usize, <L as Lanes>::Pilot)>;

/// Where a batch runs in rounds (a law whose lanes park, a CPU tail, no
/// replica groups), the first round's cap on an instance's steps: a pilot
/// of up to `tail_size` of the unfinished instances in `order`, spread
/// over them by index, each run whole on the CPU in f64, gives the steps
/// above which about the tail's share of the batch lies ([`pilot_cap`]),
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
    let mut steps: Vec<u32> = pilot.iter().map(|(_, p)| L::pilot_steps(p)).collect();
    let cap = pilot_cap(&mut steps, tail_size, count as u64);
    Some((cap, pilot))
}

/// The first round's cap from a pilot's `steps` (its runs' step counts,
/// sorted here) drawn evenly from `count` unfinished instances: the
/// pilot's (k+1)-th most steps, k = its size times `tail_size` / `count`
/// (the pilot's count above the step that about the tail's share of the
/// batch exceeds), times [`PILOT_QUARTERS`] / 4, within [[`MIN_CAP`],
/// `NO_CAP`). A small batch's pilot (k = 0) gives its most, as before
/// this rule. The most of a large pilot stands for the batch's heaviest
/// instances, which on heavy-tailed batches are far heavier than its tail:
/// random 100,000's 1,000 pilots put the cap at 33,180 steps by their
/// most, where its 1,000th heaviest instance takes 9,653 (the CPU's step
/// counts), and on an H200 its first round ran 176,316 passes; its tail
/// quantile gives 11,514 (results/gpu.md).
pub(super) fn pilot_cap(steps: &mut [u32], tail_size: u64, count: u64) -> u32 {
    steps.sort_unstable_by(|a, b| b.cmp(a));
    let k = (steps.len() as u64 * tail_size / count.max(1)) as usize;
    let steps_at = steps.get(k.min(steps.len().saturating_sub(1)));
    let cap = *steps_at.unwrap_or(&0) as u64 * PILOT_QUARTERS / 4;
    cap.clamp(MIN_CAP as u64, NO_CAP as u64 - 1) as u32
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The cap is the pilot's most steps times 1.5 where the pilot is
    /// small against the tail's share, and a quantile of its steps where
    /// it is large: an outlier among a large pilot no longer sets it.
    #[test]
    fn the_first_cap_stands_for_the_tail_not_the_heaviest() {
        // (pilot steps, tail size, unfinished, cap).
        let check = |steps: &[u32], tail: u64, count: u64, cap: u32| {
            let mut s = steps.to_vec();
            assert_eq!(
                pilot_cap(&mut s, tail, count),
                cap,
                "{steps:?} {tail} {count}"
            );
        };
        let big = 4 * MIN_CAP;
        // 32 of 2,000 with a tail of 32: k = 0, the most.
        check(&[big, 2 * big, big], 32, 2000, 3 * big);
        // 4 of 100 with a tail of 25: k = 1, the second most.
        check(&[big, 100 * big, 2 * big, big], 25, 100, 3 * big);
        // Never below the smallest cap, and empty pilots give it.
        check(&[1, 2], 1, 1000, MIN_CAP);
        check(&[], 1, 1000, MIN_CAP);
        // k past the pilot's end: its least.
        check(&[2 * big, 4 * big], 10, 10, 3 * big);
    }
}
