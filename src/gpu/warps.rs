//! What the lanes did, read without a GPU's clock: every dispatch, each
//! lane returns a [`Tally`] of its iterations by kind, and these figures
//! follow from them (issue 38). They are properties of the algorithm and of
//! the order instances are dispatched in, not of the adapter: the same
//! tallies describe an NVIDIA warp of 32 on lavapipe and on an H100.
//!
//! * *Warp efficiency*: the lanes grouped 32 to a warp in dispatch order,
//!   a warp runs each dispatch as many passes of the lane's loop as its
//!   busiest lane (an iteration of `iterate`, or a steady measurement's
//!   period end); the share of its 32 lanes' slots in those passes that did
//!   work, overall and by kind of pass. A kind's own figure is the share
//!   its lanes would fill if they all did that kind together (its passes
//!   over 32 times the busiest lane's of that kind): an upper bound on how
//!   well the warp shares that kind's code.
//! * *Critical path*: a batch's passes in lockstep (each dispatch as long
//!   as its busiest lane) against its mean lane's, and its longest
//!   instance's iterations against the mean instance's.
//! * *Bytes*: what a lane keeps in device memory and moves per dispatch.
//!
//! Also the queue's order: the first dispatch of a batch runs every
//! instance a short way ([`crate::gpu::BatchOptions::probe_iterations`]),
//! and [`queue_order`] ranks the unfinished ones by the cost their own
//! first iterations predict, so that the dearest start first and lanes of
//! one warp take instances alike in cost and in mode mix.

use std::fmt::Write;
use std::sync::Mutex;

use super::layout::control::Tally;
pub use crate::laws::floor::kinds::KIND_NAMES;
use crate::laws::floor::kinds::{
    ITERATION_KINDS, ITERATION_REJECTED, ITERATION_SLIP, rejected_share,
};

/// Lanes per warp in the figures: NVIDIA's warp.
pub const WARP: usize = 32;

/// The lane held no instance at the end of the dispatch.
pub const NO_INSTANCE: u32 = u32::MAX;

impl Tally {
    /// Passes by kind ([`KIND_NAMES`]).
    pub fn by_kind(&self) -> [u64; ITERATION_KINDS] {
        let k = self.kinds;
        let m = self.more;
        [k[0], k[1], k[2], k[3], m[0], m[1]].map(u64::from)
    }

    /// Every pass of the lane's loop in the dispatch.
    pub fn passes(&self) -> u64 {
        self.by_kind().iter().sum()
    }

    /// Instances the lane took from the queue.
    pub fn taken(&self) -> u64 {
        self.more[2] as u64
    }

    /// The instance the lane held at the end, if any.
    pub fn held(&self) -> Option<u32> {
        (self.more[3] != NO_INSTANCE).then_some(self.more[3])
    }
}

/// The warp figures of a run's dispatches, added up.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Warps {
    /// Dispatches counted.
    pub dispatches: u64,
    /// Lanes dispatched, over all dispatches (a warp's 32 each, the last
    /// warp's too).
    pub lane_slots: u64,
    /// Per warp and dispatch, its busiest lane's passes, added up.
    pub warp_passes: u64,
    /// Passes by kind, every lane's.
    pub passes: [u64; ITERATION_KINDS],
    /// Per kind: per warp and dispatch, its busiest lane's passes of that
    /// kind, added up.
    pub kind_warp_passes: [u64; ITERATION_KINDS],
    /// Instances lanes took from the queue.
    pub taken: u64,
    /// Emulated f64 divisions and roots, every lane's.
    pub emulated: u64,
}

impl Warps {
    /// Adds one dispatch's tallies, in lane order.
    pub fn add_dispatch(&mut self, tallies: &[Tally]) {
        self.dispatches += 1;
        for warp in tallies.chunks(WARP) {
            self.lane_slots += WARP as u64;
            self.warp_passes += warp.iter().map(Tally::passes).max().unwrap_or(0);
            let mut most = [0u64; ITERATION_KINDS];
            for lane in warp {
                let kinds = lane.by_kind();
                for k in 0..ITERATION_KINDS {
                    self.passes[k] += kinds[k];
                    most[k] = most[k].max(kinds[k]);
                }
                self.taken += lane.taken();
                self.emulated += lane.emulated as u64;
            }
            for (sum, most) in self.kind_warp_passes.iter_mut().zip(most) {
                *sum += most;
            }
        }
    }

    /// Adds another run's figures.
    pub fn merge(&mut self, other: &Warps) {
        self.dispatches += other.dispatches;
        self.lane_slots += other.lane_slots;
        self.warp_passes += other.warp_passes;
        self.taken += other.taken;
        self.emulated += other.emulated;
        for k in 0..ITERATION_KINDS {
            self.passes[k] += other.passes[k];
            self.kind_warp_passes[k] += other.kind_warp_passes[k];
        }
    }

    /// Every lane's passes.
    pub fn lane_passes(&self) -> u64 {
        self.passes.iter().sum()
    }

    /// The share of the warps' lane slots that did work: lane passes over
    /// 32 times the warps' passes.
    pub fn efficiency(&self) -> f64 {
        share(self.lane_passes(), WARP as u64 * self.warp_passes)
    }

    /// Each kind's share of the warps' lane slots (adding up, with the
    /// idle slots, to 1).
    pub fn kind_shares(&self) -> [f64; ITERATION_KINDS] {
        self.passes
            .map(|p| share(p, WARP as u64 * self.warp_passes))
    }

    /// Each kind's efficiency if its lanes did it together: its passes
    /// over 32 times the warps' busiest lanes' of that kind.
    pub fn kind_efficiency(&self) -> [f64; ITERATION_KINDS] {
        let mut out = [0.0; ITERATION_KINDS];
        for (k, e) in out.iter_mut().enumerate() {
            *e = share(self.passes[k], WARP as u64 * self.kind_warp_passes[k]);
        }
        out
    }

    /// The table's lines.
    pub fn describe(&self) -> String {
        let mut out = String::new();
        let percent = |x: f64| format!("{:.1} %", 100.0 * x);
        let _ = writeln!(
            out,
            "pidm: phase warps of {WARP} lanes in dispatch order: {} of their lane slots did \
             work ({} lane passes in {} warp passes, {} dispatches)",
            percent(self.efficiency()),
            self.lane_passes(),
            self.warp_passes,
            self.dispatches
        );
        let shares = self.kind_shares();
        let together = self.kind_efficiency();
        let mut by_kind: Vec<String> = KIND_NAMES
            .iter()
            .enumerate()
            .filter(|(k, _)| self.passes[*k] > 0)
            .map(|(k, name)| format!("{name} {}", percent(shares[k])))
            .collect();
        by_kind.push(format!("idle {}", percent(1.0 - self.efficiency())));
        let _ = writeln!(out, "pidm: phase   slots by kind: {}", by_kind.join(", "));
        let _ = writeln!(
            out,
            "pidm: phase   rejected trials: {} of slip trials (slip steps and rejected trials)",
            percent(rejected_share(&self.passes))
        );
        if self.emulated > 0 {
            let trials =
                self.passes[ITERATION_SLIP as usize] + self.passes[ITERATION_REJECTED as usize];
            let _ = writeln!(
                out,
                "pidm: phase   emulated f64 divisions and roots: {} ({:.1} per slip trial, every kind of iteration's counted)",
                self.emulated,
                self.emulated as f64 / trials.max(1) as f64
            );
        }
        let alike: Vec<String> = KIND_NAMES
            .iter()
            .enumerate()
            .filter(|(k, _)| self.passes[*k] > 0)
            .map(|(k, name)| format!("{name} {}", percent(together[k])))
            .collect();
        let _ = writeln!(
            out,
            "pidm: phase   a kind's lanes together (at most): {}",
            alike.join(", ")
        );
        out
    }
}

/// A fraction that is 0 where the whole is.
fn share(part: u64, whole: u64) -> f64 {
    if whole == 0 {
        0.0
    } else {
        part as f64 / whole as f64
    }
}

/// One batch's critical path.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CriticalPath {
    /// Instances in the batch.
    pub instances: usize,
    /// Lanes that worked through its queue (after the first dispatch,
    /// which has a lane per instance).
    pub lanes: usize,
    /// Its dispatches, each as long as its busiest lane, added up [passes].
    pub lockstep: u64,
    /// Its dispatches, each as long as its lanes' passes spread evenly
    /// over them (the first's over a lane per instance, the others' over
    /// [`CriticalPath::lanes`]), added up [passes].
    pub even: f64,
    /// Its longest instance's iterations, and the mean instance's.
    pub longest_instance: u64,
    pub mean_instance: f64,
    /// How well the first dispatch ranked the queue: the rank correlation
    /// of the iterations it predicted for the queued instances with those
    /// they took (of those the device finished), where there were two or
    /// more.
    pub ranking: Option<f64>,
}

impl CriticalPath {
    /// Counts one dispatch of `lanes` lanes with these tallies.
    pub fn add_dispatch(&mut self, tallies: &[Tally], lanes: usize) {
        self.lockstep += tallies.iter().map(Tally::passes).max().unwrap_or(0);
        self.even += tallies.iter().map(Tally::passes).sum::<u64>() as f64 / lanes.max(1) as f64;
    }

    /// The lockstep length over the even one: 1 where every lane is busy
    /// until the batch ends.
    pub fn stretch(&self) -> f64 {
        if self.even > 0.0 {
            self.lockstep as f64 / self.even
        } else {
            0.0
        }
    }

    /// One line of the table.
    pub fn describe(&self, batch: usize) -> String {
        format!(
            "pidm: phase critical path of batch {batch} ({} instances, then {} lanes): {} passes \
             in lockstep against {:.0} with its work spread evenly ({:.2}x); longest instance {} \
             iterations, mean {:.0} ({:.1}x)\n",
            self.instances,
            self.lanes,
            self.lockstep,
            self.even,
            self.stretch(),
            self.longest_instance,
            self.mean_instance,
            self.longest_instance as f64 / self.mean_instance.max(1.0)
        ) + &match self.ranking {
            Some(r) => format!(
                "pidm: phase   the first dispatch's prediction ranks the queued instances' \
                 iterations with rank correlation {r:.2}\n"
            ),
            None => String::new(),
        }
    }
}

/// Spearman's rank correlation of two equally long series (ties share
/// their mean rank); `None` for fewer than two pairs or a constant series.
pub fn rank_correlation(a: &[f64], b: &[f64]) -> Option<f64> {
    fn ranks(x: &[f64]) -> Vec<f64> {
        let mut order: Vec<usize> = (0..x.len()).collect();
        order.sort_by(|&i, &j| x[i].total_cmp(&x[j]));
        let mut out = vec![0.0; x.len()];
        let mut k = 0;
        while k < order.len() {
            let mut end = k;
            while end + 1 < order.len() && x[order[end + 1]] == x[order[k]] {
                end += 1;
            }
            let rank = (k + end) as f64 / 2.0;
            for &i in &order[k..=end] {
                out[i] = rank;
            }
            k = end + 1;
        }
        out
    }
    if a.len() != b.len() || a.len() < 2 {
        return None;
    }
    let (ra, rb) = (ranks(a), ranks(b));
    let mean = (a.len() - 1) as f64 / 2.0;
    let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
    for (x, y) in ra.iter().zip(&rb) {
        ab += (x - mean) * (y - mean);
        aa += (x - mean) * (x - mean);
        bb += (y - mean) * (y - mean);
    }
    (aa > 0.0 && bb > 0.0).then(|| ab / (aa * bb).sqrt())
}

/// What a lane keeps and moves: the sizes of a precision's structs [bytes].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LaneBytes {
    pub coefficients: usize,
    pub state: usize,
    /// The accumulators of a steady instance (0 for a batch of windows).
    pub measure: usize,
}

impl LaneBytes {
    /// The bytes a run's dispatches moved, from their figures: every lane
    /// of a dispatch reads its instance's coefficients and state and
    /// writes the state, its lane index and its tally; every instance
    /// taken from the queue reads its coefficients and state (and the
    /// finished one's state is written); every period end reads and
    /// writes the accumulators.
    pub fn moved(&self, warps: &Warps) -> u64 {
        let tally = size_of::<Tally>() as u64;
        let per_lane = (self.coefficients + 2 * self.state) as u64 + 8 + tally;
        let per_take = (self.coefficients + 2 * self.state) as u64;
        let period_ends = warps.passes[crate::laws::floor::kinds::ITERATION_PERIOD_END as usize];
        warps.lane_slots * per_lane + warps.taken * per_take + period_ends * 2 * self.measure as u64
    }

    /// One line of the table.
    pub fn describe(&self, warps: &Warps) -> String {
        let per_dispatch = self.moved(warps) as f64 / warps.lane_slots.max(1) as f64;
        format!(
            "pidm: phase a lane keeps {} B of state{} and {} B of coefficients in device memory, \
             and moves about {:.0} B per dispatch (reads, writes, its queue's and measurement's)\n",
            self.state,
            if self.measure > 0 {
                format!(" and {} B of steady accumulators", self.measure)
            } else {
                String::new()
            },
            self.coefficients,
            per_dispatch
        )
    }
}

/// How a batch's queue is ordered after its first dispatch.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Order {
    /// By the cost each instance's first iterations predict, dearest first,
    /// and within a quarter-octave of cost by the share of slip in them.
    Cost,
    /// By index (for measuring what the order is worth:
    /// `PIDM_GPU_ORDER=index`).
    Index,
}

/// The lane figures of a run's GPU batches, for the phase table.
#[derive(Default)]
struct Run {
    warps: Warps,
    paths: Vec<CriticalPath>,
    bytes: LaneBytes,
}

static RUN: Mutex<Option<Run>> = Mutex::new(None);

/// Counts one GPU batch's lane figures into the run's (only inside the
/// integrator's work, not the self-test's: `profile::integrating`).
pub fn record(warps: &Warps, path: CriticalPath, bytes: LaneBytes) {
    if !crate::profile::integrating() {
        return;
    }
    let mut run = RUN.lock().unwrap_or_else(|e| e.into_inner());
    let run = run.get_or_insert_with(Run::default);
    run.warps.merge(warps);
    run.paths.push(path);
    run.bytes = bytes;
}

/// The phase table's lines of the run's lanes: its warps, the critical
/// paths of its batches (the first few and the longest stretch), what a
/// lane keeps and moves; empty where no GPU batch ran.
pub fn table_lines() -> String {
    let run = RUN.lock().unwrap_or_else(|e| e.into_inner());
    let Some(run) = run.as_ref() else {
        return String::new();
    };
    let mut out = run.warps.describe();
    let shown = 4;
    for (k, path) in run.paths.iter().enumerate().take(shown) {
        out += &path.describe(k);
    }
    if run.paths.len() > shown {
        let (k, worst) = run
            .paths
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.stretch().total_cmp(&b.1.stretch()))
            .expect("some batches");
        out += &format!(
            "pidm: phase ({} batches in all; the longest stretch:)\n{}",
            run.paths.len(),
            worst.describe(k)
        );
    }
    out += &run.bytes.describe(&run.warps);
    out
}

/// The run's emulated f64 divisions and roots and their number per slip
/// trial (slip steps and rejected trials), where its GPU batches took any
/// slip trial.
pub fn emulated_per_slip_trial() -> Option<(u64, f64)> {
    let run = RUN.lock().unwrap_or_else(|e| e.into_inner());
    let warps = &run.as_ref()?.warps;
    let trials = warps.passes[ITERATION_SLIP as usize] + warps.passes[ITERATION_REJECTED as usize];
    (trials > 0).then(|| (warps.emulated, warps.emulated as f64 / trials as f64))
}

/// An unfinished instance after the first dispatch: its index, the passes
/// it ran there, and the periods it covered of the `expected` it will run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Probed {
    pub index: u32,
    pub tally: Tally,
    pub expected_periods: f64,
}

/// The passes still to come that an instance's first ones predict: its
/// passes per period so far times the periods left. One that covered no
/// time yet is ranked dearest.
pub fn predicted_passes(p: &Probed) -> f64 {
    let done = p.tally.progress as f64;
    let passes = p.tally.passes() as f64;
    if done <= 0.0 || !done.is_finite() {
        return f64::INFINITY;
    }
    passes / done * (p.expected_periods - done).max(0.0)
}

/// The queue of a batch: the unfinished instances' indices in the order
/// lanes take them.
pub fn queue_order(probed: &[Probed], order: Order) -> Vec<u32> {
    let mut keyed: Vec<(u64, u64, u32)> = probed
        .iter()
        .map(|p| {
            let (cost, mix) = match order {
                Order::Index => (0, 0),
                Order::Cost => {
                    let predicted = predicted_passes(p);
                    // Quarter octaves of cost, dearest first.
                    let cost = if predicted.is_finite() {
                        (4.0 * (1.0 + predicted).log2()) as u64
                    } else {
                        u64::MAX
                    };
                    let kinds = p.tally.by_kind();
                    let slip = kinds[2] + kinds[3] + kinds[4];
                    let mix = (10 * slip / p.tally.passes().max(1)).min(10);
                    (u64::MAX - cost, mix)
                }
            };
            (cost, mix, p.index)
        })
        .collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|(_, _, index)| index).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tally of `stick` stick steps and `slip` slip steps, holding
    /// `held`.
    fn tally(stick: u32, slip: u32, held: u32) -> Tally {
        Tally {
            kinds: [0, stick, slip, 0],
            more: [0, 0, 0, held],
            ..Tally::default()
        }
    }

    /// One warp of 32 lanes, half of them doing 10 stick steps and half 10
    /// slip steps, and one of them 30 more: 32 x 40 slots, 640 + 30 of
    /// them used.
    #[test]
    fn warp_efficiency_of_a_hand_made_dispatch() {
        let mut lanes: Vec<Tally> = (0..32)
            .map(|k| {
                if k < 16 {
                    tally(10, 0, 0)
                } else {
                    tally(0, 10, 0)
                }
            })
            .collect();
        lanes[31].kinds[2] += 30;
        let mut warps = Warps::default();
        warps.add_dispatch(&lanes);
        assert_eq!(warps.warp_passes, 40);
        assert_eq!(warps.lane_passes(), 350);
        assert_eq!(warps.efficiency(), 350.0 / (32.0 * 40.0));
        let shares = warps.kind_shares();
        assert_eq!(shares[1], 160.0 / 1280.0);
        assert_eq!(shares[2], 190.0 / 1280.0);
        // Stick: 160 passes, the busiest lane 10: half the lanes do it.
        let together = warps.kind_efficiency();
        assert_eq!(together[1], 0.5);
        assert_eq!(together[2], 190.0 / (32.0 * 40.0));
        let text = warps.describe();
        assert!(text.contains("27.3 %"), "{text}");
    }

    /// A dispatch of 40 lanes is two warps, the second with 8 lanes: its
    /// 24 missing lanes count as idle slots.
    #[test]
    fn a_partial_warp_counts_its_missing_lanes_idle() {
        let lanes = vec![tally(5, 0, 0); 40];
        let mut warps = Warps::default();
        warps.add_dispatch(&lanes);
        assert_eq!(warps.lane_slots, 64);
        assert_eq!(warps.warp_passes, 10);
        assert_eq!(warps.efficiency(), 200.0 / 320.0);
    }

    #[test]
    fn rank_correlation_is_one_for_a_monotone_map_and_minus_one_reversed() {
        let a = [1.0, 5.0, 2.0, 9.0];
        let up = [10.0, 50.0, 20.0, 1e9];
        let down = [4.0, 2.0, 3.0, 1.0];
        assert_eq!(rank_correlation(&a, &up), Some(1.0));
        assert_eq!(rank_correlation(&a, &down), Some(-1.0));
        assert_eq!(rank_correlation(&a, &[1.0; 4]), None);
        assert_eq!(rank_correlation(&a[..1], &up[..1]), None);
        // Ties share their mean rank: ranks (0.5, 0.5, 2) and (0, 1, 2).
        let r = rank_correlation(&[1.0, 1.0, 3.0], &[1.0, 2.0, 3.0]).unwrap();
        assert!((r - 0.75f64.sqrt()).abs() < 1e-12, "{r}");
    }

    #[test]
    fn the_critical_path_compares_lockstep_with_the_mean_lane() {
        let mut path = CriticalPath {
            instances: 10,
            lanes: 4,
            longest_instance: 150,
            mean_instance: 80.0,
            ..CriticalPath::default()
        };
        // The first dispatch, a lane per instance: 10 passes each but one
        // lane's 40; then two dispatches on 4 lanes, 100 passes each and
        // one lane 30 fewer.
        let tally = |passes: u32| Tally {
            kinds: [0, passes, 0, 0],
            ..Tally::default()
        };
        let mut first = vec![tally(10); 10];
        first[3] = tally(40);
        path.add_dispatch(&first, 10);
        let later = [tally(100), tally(100), tally(100), tally(70)];
        path.add_dispatch(&later, 4);
        path.add_dispatch(&later, 4);
        assert_eq!(path.lockstep, 240);
        assert_eq!(path.even, 13.0 + 2.0 * 92.5);
        assert_eq!(path.stretch(), 240.0 / 198.0);
        assert!(path.describe(0).contains("(1.21x)"), "{}", path.describe(0));
    }

    /// Dearest first by the probe's prediction; an instance that covered
    /// no time is dearest of all; the index order keeps indices.
    #[test]
    fn the_queue_starts_with_the_dearest() {
        let probe = |index: u32, passes: u32, progress: f32| Probed {
            index,
            tally: Tally {
                progress,
                ..tally(passes, 0, index)
            },
            expected_periods: 4.0,
        };
        let probed = [
            probe(0, 100, 2.0), // 100 passes to come
            probe(1, 100, 0.1), // 3,900
            probe(2, 100, 0.0), // unknown
            probe(3, 100, 1.0), // 300
        ];
        assert_eq!(queue_order(&probed, Order::Cost), vec![2, 1, 3, 0]);
        assert_eq!(queue_order(&probed, Order::Index), vec![0, 1, 2, 3]);
    }
}
