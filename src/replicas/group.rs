//! One instance's replicas as a group: what the backends read of each
//! replica ([`Member`]), and what the group does next ([`Group::step`]):
//! wait, let every replica go on, stop with the merged estimate (a phase
//! split) or the joined pieces (a cycle split, `Group::join`), or give up
//! the split. Plain values: the backends run the replicas (`super::cpu`
//! on the CPU's threads, `gpu::slices` on lanes) and ask here.
//!
//! **The merge.** At a ladder level that may stop the run, every replica
//! has kept its sums of that level's windows (`phase::LevelSums`); their
//! sums are the virtual run's, and `phase::evaluate_sums` judges them as
//! it judges one run's: the one home of the rule. The group stops where
//! the merged standard error is within the step tolerance on both axes.
//!
//! **Never two attractors.** Each replica's own estimate is its sums, each
//! over its share of its window's virtual weights ([`replica_weight`]),
//! judged by the ladder's rule as one run's (Richardson, halves,
//! quarters): a coarser estimate with its own standard error. A replica
//! whose estimate differs from the merged one by more than
//! [`DISAGREEMENT_Z`] times their combined standard errors plus
//! [`DISAGREEMENT_FLOOR`] on either axis sits on another attractor: the
//! group is not merged.

use crate::laws::floor::Setup;
use crate::laws::floor::Vec2;
use crate::laws::floor::measure::Measure;
use crate::laws::floor::measure::initial_measure;
use crate::laws::floor::measure::{
    Snapshot, VERDICT_PERIODIC, VERDICT_PHASE, VERDICT_RUNNING, repeats,
};
use crate::laws::floor::phase::{
    Gaps, LevelSums, PhaseEstimate, evaluate_sums, ladder_length, window_weight,
};
use crate::laws::floor::variation::Variation;
use crate::laws::status::STATUS_OK;
use crate::laws::{Record, Run};
use crate::laws::{Replica, Settings};
use crate::measurement::{Measured, reduce, reduce_variation};
use crate::model::AXES;
use crate::model::Instance;

/// How many of their combined errors a replica's estimate may differ from
/// the merged one before the two count as different attractors. Measured
/// on the 36 instances of `results/pipeline/twofreq6.toml` with 8
/// replicas (64 merges, every replica on one attractor): at most 4.5
/// (`examples/replicas_validate.rs`); twice that leaves room for what the
/// 36 did not show. A replica's own estimate is a coarse quadrature (its
/// points weighted by the virtual run's gaps), so an attractor closer
/// than this many of its errors (about 0.2 um per cycle at the default
/// tolerance) is not told apart (docs/steady.md, "Replicas").
pub const DISAGREEMENT_Z: f64 = 9.0;

/// What a replica's estimate may differ from the merged one besides
/// [`DISAGREEMENT_Z`] of their errors [m per own drive cycle]: the maps'
/// own allowance (0.002 um, issue 39's), so that estimates that agree to
/// it are never called different attractors.
pub const DISAGREEMENT_FLOOR: f64 = 0.002e-6;

/// What a backend reads of one replica, in SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Member {
    /// The replica's status (`STATUS_OK` while it runs).
    pub status: u32,
    /// `Record::measured`: 0 running, 1 finished, 2 waiting for the merge.
    pub measured: u32,
    /// It ran to its `max_cycles` without a verdict.
    pub at_max: bool,
    /// Scene periods it has run.
    pub periods: u32,
    /// The level it waits at and its sums there (while waiting).
    pub level: u32,
    pub sums: LevelSums,
    /// A cycle split's piece: the states where its piece starts and ends,
    /// once it has run it.
    pub ends: Option<(Snapshot, Snapshot)>,
    /// The slider's total variation as it follows the step, where the run
    /// keeps it (`Settings::backward`): merged or joined as the step is,
    /// never deciding ([`Group::followed`]).
    pub followed: Option<Followed>,
}

/// What a group reads of a replica's variation (`laws::floor::variation`):
/// its sums at the level it waits at, and a piece's variation over its
/// measured periods.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Followed {
    pub sums: LevelSums,
    pub piece: Option<Vec2>,
}

impl Member {
    /// What a CPU run of replica `inst` (`Group::replicas`) holds.
    pub fn of(inst: &Instance, run: &Run) -> Member {
        let m = &run.measure;
        Member {
            status: run.record.status,
            measured: run.record.measured,
            at_max: run.record.period >= inst.cycles,
            periods: m.next_end,
            level: m.pending_level,
            sums: m.phase.pending,
            ends: piece_ends(m),
            followed: None,
        }
    }

    /// [`Member::of`] with the replica's variation, where its run keeps
    /// one (`laws::law::Resumable::variation`).
    pub fn following(self, v: Option<&Variation>) -> Member {
        Member {
            followed: v.map(|v| Followed {
                sums: v.measure.phase.pending,
                piece: v.piece_travel(),
            }),
            ..self
        }
    }
}

/// Where a cycle split's piece started and ended: its recurrence test's
/// first two states (a piece's "common period" is its length), or, where
/// that test found the end repeating the start, the start moved by the
/// travel between them.
fn piece_ends(m: &Measure) -> Option<(Snapshot, Snapshot)> {
    let start = m.snaps[0];
    match (m.verdict, m.snapshots) {
        (VERDICT_PERIODIC, _) => Some((
            start,
            Snapshot {
                x_s: start.x_s + m.travel,
                ..start
            },
        )),
        (_, 2..) => Some((start, m.snaps[1])),
        _ => None,
    }
}

/// What a group does next.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step {
    /// Some replicas still run to the level the others wait at.
    Wait,
    /// The merged level did not stop the run: every replica goes on.
    Continue,
    /// The merged window stopped the run: the instance's result.
    Merged(Measured),
    /// No merge: the instance runs again as one run of its own, its motion
    /// labelled multistable where replicas disagreed.
    Alone { multistable: bool },
}

/// One instance split into replicas.
#[derive(Clone, Debug)]
pub struct Group {
    inst: Instance,
    /// The split: `index` unused.
    split: Replica,
    /// Replica 0's measurement constants (the virtual run's ladder: every
    /// replica's is the same but for the index).
    c: Setup,
    /// Each axis' drive cycles per scene period.
    cycles_per_period: Vec2,
}

impl Group {
    /// `inst` split as `split` says (`super::split`: its count >= 2 and
    /// virtual run) under `settings`.
    pub fn new(inst: &Instance, settings: &Settings, split: Replica) -> Group {
        let split = Replica { index: 0, ..split };
        let c = match split.cycle {
            0 => Setup::new(inst, settings, split),
            // The instance's own: its recurrence test's tolerances.
            _ => Setup::new(inst, settings, Replica::NONE),
        };
        let period = inst.period();
        let [ax, ay] = &inst.axes;
        Group {
            inst: *inst,
            split,
            c,
            cycles_per_period: Vec2::new(ax.frequency * period, ay.frequency * period),
        }
    }

    /// The replicas: each one's instance and index.
    pub fn replicas(&self) -> Vec<(Instance, Replica)> {
        (0..self.split.count)
            .map(|index| {
                let r = Replica {
                    index,
                    ..self.split
                };
                (super::replica_instance(&self.inst, r), r)
            })
            .collect()
    }

    pub fn count(&self) -> u32 {
        self.split.count
    }

    /// What the group does after its members (in replica order) did what
    /// they could.
    pub fn step(&self, members: &[Member]) -> Step {
        if self.split.cycle > 0 {
            return self.join(members);
        }
        if members
            .iter()
            .any(|m| ended(m.status, m.measured, m.at_max))
        {
            return Step::Alone { multistable: false };
        }
        if members.iter().any(|m| m.measured != 2) {
            return Step::Wait;
        }
        let Some(level) = common_level(members) else {
            return Step::Alone { multistable: false };
        };
        let merged = self.merge(members, level);
        if self.disagreement_of(members, level, &merged) > DISAGREEMENT_Z {
            return Step::Alone { multistable: true };
        }
        let limit = self.c.se_limit2;
        if merged.se2.x <= limit.x && merged.se2.y <= limit.y {
            let periods = members.iter().map(|m| m.periods).max().unwrap_or(0);
            return Step::Merged(self.measured(&merged, periods));
        }
        Step::Continue
    }

    /// Whether this is a cycle split (`Replica::cycle`), whose pieces run
    /// to their ends and are joined once, rather than a phase split.
    pub fn is_cycle(&self) -> bool {
        self.split.cycle > 0
    }

    /// Whether replica `r`, with this status, `Record::measured` and
    /// period, keeps its group waiting: it still runs, and has neither
    /// reached what its group waits for (a phase split's level, a piece's
    /// end) nor ended the split ([`Group::gives_up`]).
    pub fn runs(&self, r: u32, status: u32, measured: u32, period: u32) -> bool {
        status == STATUS_OK && measured == 0 && period < self.cycles_of(r)
    }

    /// Whether a replica in this state makes its group give up the
    /// split: it failed, or (a phase split's replica) was measured by a
    /// rule of its own or ran out ([`ended`]). A piece of a cycle split
    /// ends at its `cycles`, as it should.
    pub fn gives_up(&self, status: u32, measured: u32, period: u32) -> bool {
        match self.split.cycle {
            0 => ended(status, measured, period >= self.inst.cycles),
            _ => status != STATUS_OK,
        }
    }

    /// The periods replica `r` runs at most.
    fn cycles_of(&self, r: u32) -> u32 {
        match self.split.cycle {
            0 => self.inst.cycles,
            _ => {
                let piece = Replica {
                    index: r,
                    ..self.split
                };
                self.inst.settle + piece.cycle_segment().1
            }
        }
    }

    /// A cycle split's step: once every piece has run to its end, the
    /// pieces joined end to start within the recurrence test's tolerances
    /// ([`repeats`]), the last one's end to the first one's start, are one
    /// trajectory that repeats after the common period q: the instance's
    /// motion is periodic and its travel over q is the pieces' travels
    /// added. A piece that failed, or one join that does not hold (a motion
    /// that does not repeat after q, a piece not yet settled, or pieces on
    /// different attractors), gives up the split, unlabelled: the joins
    /// cannot tell those apart.
    fn join(&self, members: &[Member]) -> Step {
        let count = members.len();
        if members.iter().any(|m| m.status != STATUS_OK) {
            return Step::Alone { multistable: false };
        }
        if members.iter().any(|m| m.measured == 0 && !m.at_max) {
            return Step::Wait;
        }
        let ends: Option<Vec<(Snapshot, Snapshot)>> = members.iter().map(|m| m.ends).collect();
        let Some(ends) = ends else {
            return Step::Alone { multistable: false };
        };
        let joined = (0..count).all(|r| repeats(&self.c, &ends[r].1, &ends[(r + 1) % count].0));
        if !joined {
            return Step::Alone { multistable: false };
        }
        let travel = ends
            .iter()
            .fold(Vec2::ZERO, |sum, (start, end)| sum + (end.x_s - start.x_s));
        let periods = members.iter().map(|m| m.periods).max().unwrap_or(0);
        Step::Merged(self.finished(periods, self.periodic(travel)))
    }

    /// The accumulators of a merged window's estimate (a phase-resolved
    /// verdict).
    fn phase_measure(&self, merged: &PhaseEstimate) -> Measure {
        Measure {
            verdict: VERDICT_PHASE,
            travel: merged.value * merged.span as f64,
            span: merged.span,
            se2: merged.se2,
            ..initial_measure(&self.c)
        }
    }

    /// The accumulators of a joined cycle split whose position travelled
    /// `travel` over the common period.
    fn periodic(&self, travel: Vec2) -> Measure {
        Measure {
            verdict: VERDICT_PERIODIC,
            travel,
            lag: self.split.cycle,
            ..initial_measure(&self.c)
        }
    }

    /// How far the replicas' own estimates lie from the merged one where
    /// every member waits at one level (else `None`): the largest over
    /// replicas and axes of the distance beyond [`DISAGREEMENT_FLOOR`] in
    /// combined errors; the group takes them for different attractors
    /// beyond [`DISAGREEMENT_Z`]. For studies of the rule (the examples).
    pub fn disagreement(&self, members: &[Member]) -> Option<f64> {
        if members.iter().any(|m| m.measured != 2) {
            return None;
        }
        let level = common_level(members)?;
        let merged = self.merge(members, level);
        Some(self.disagreement_of(members, level, &merged))
    }

    /// The virtual run's estimate of `level` from the replicas' sums.
    fn merge(&self, members: &[Member], level: u32) -> PhaseEstimate {
        self.merge_sums(members.iter().map(|m| &m.sums), level)
    }

    /// The virtual run's estimate of `level` from the replicas' sums of a
    /// position (the slider's, or its total variation's).
    fn merge_sums<'a>(
        &self,
        sums: impl Iterator<Item = &'a LevelSums>,
        level: u32,
    ) -> PhaseEstimate {
        let mut total = LevelSums::ZERO;
        for s in sums {
            total.whole = total.whole + s.whole;
            total.half = total.half + s.half;
            total.second = total.second + s.second;
            for (t, q) in total.quarters.iter_mut().zip(s.quarters) {
                *t = *t + q;
            }
        }
        let lattice = (self.c.phase_lattice >> level) & 1 == 1;
        evaluate_sums(&total, level, lattice)
    }

    /// The backward travel's values (`measurement::reduce_variation`: the
    /// variation per axis and its standard error) of a group whose
    /// [`Group::step`] merged its `members`, where every member keeps its
    /// variation: the variation's sums merged at the step's level, or its
    /// pieces' variations added over the joined cycle, reduced with the
    /// step's verdict, as one run's variation follows its step. `None`
    /// where a member keeps none or the group did not merge.
    pub fn followed(&self, members: &[Member]) -> Option<([f64; AXES], [f64; AXES])> {
        let parts: Vec<Followed> = members.iter().map(|m| m.followed).collect::<Option<_>>()?;
        let periods = members.iter().map(|m| m.periods).max().unwrap_or(0);
        let (step, followed) = if self.split.cycle > 0 {
            let Step::Merged(_) = self.join(members) else {
                return None;
            };
            let travel = parts
                .iter()
                .try_fold(Vec2::ZERO, |sum, p| p.piece.map(|t| sum + t))?;
            (self.periodic(Vec2::ZERO), self.periodic(travel))
        } else {
            let level = common_level(members)?;
            let step = self.merge(members, level);
            let followed = self.merge_sums(parts.iter().map(|p| &p.sums), level);
            (self.phase_measure(&step), self.phase_measure(&followed))
        };
        let mut v = Variation::new(&self.c);
        v.measure = followed;
        Some(reduce_variation(&self.inst, &self.run(periods, step), &v))
    }

    /// [`Self::disagreement`] against `merged`. A replica's error is the
    /// larger of its own and the replicas' pooled one (the root mean of
    /// their squares): the replicas' estimates are alike in length and
    /// phases, and one replica's halves and quarters may agree by chance
    /// (measured: a tenth of the pooled error), which alone would call
    /// one attractor two.
    fn disagreement_of(&self, members: &[Member], level: u32, merged: &PhaseEstimate) -> f64 {
        let floor = self.cycles_per_period * DISAGREEMENT_FLOOR;
        let own: Vec<PhaseEstimate> = members
            .iter()
            .enumerate()
            .map(|(r, m)| self.own_estimate(r as u32, &m.sums, level))
            .collect();
        let pooled = own.iter().fold(Vec2::ZERO, |s, e| s + e.se2) * (1.0 / own.len() as f64);
        let mut most: f64 = 0.0;
        for e in &own {
            for i in 0..2 {
                let beyond = (e.value[i] - merged.value[i]).abs() - floor[i].abs();
                let error = (e.se2[i].max(pooled[i]) + merged.se2[i]).sqrt();
                if beyond > 0.0 {
                    // A zero error with a distance beyond the floor is
                    // infinitely far.
                    most = most.max(beyond / error);
                }
            }
        }
        most
    }

    /// Replica `r`'s own estimate of `level` and its error: each of its
    /// sums over its share of its window's virtual weights
    /// ([`replica_weight`]), judged as one run's sums are.
    fn own_estimate(&self, r: u32, sums: &LevelSums, level: u32) -> PhaseEstimate {
        let count = self.split.count;
        let share = |j: u32, start: u32, sum: Vec2| {
            let length = ladder_length(j);
            sum * (1.0 / replica_weight(&self.c.gaps[j as usize], start, length, r, count))
        };
        let (j, half, quarter) = (level, ladder_length(level - 2), ladder_length(level - 4));
        let own = LevelSums {
            whole: share(j, 0, sums.whole),
            half: share(j - 2, 0, sums.half),
            second: share(j - 2, half, sums.second),
            quarters: [
                share(j - 4, 0, sums.quarters[0]),
                share(j - 4, quarter, sums.quarters[1]),
                share(j - 4, 2 * quarter, sums.quarters[2]),
                share(j - 4, 3 * quarter, sums.quarters[3]),
            ],
        };
        let lattice = (self.c.phase_lattice >> level) & 1 == 1;
        evaluate_sums(&own, level, lattice)
    }

    /// The map's values of a merged window, through the one reduction
    /// every run's results pass through: a phase-resolved verdict.
    fn measured(&self, merged: &PhaseEstimate, periods: u32) -> Measured {
        self.finished(periods, self.phase_measure(merged))
    }

    /// The map's values of a group that ended after `periods` with the
    /// verdict and travel `measure` holds, through [`reduce`] as any
    /// finished run's.
    fn finished(&self, periods: u32, measure: Measure) -> Measured {
        reduce(&self.inst, &self.run(periods, measure))
    }

    /// The run of the instance a group that ended after `periods` with
    /// `measure` stands for.
    fn run(&self, periods: u32, measure: Measure) -> Run {
        let record = Record {
            period: periods,
            measured: 1,
            ..Record::at_rest()
        };
        let measure = Measure {
            next_end: periods,
            ..measure
        };
        debug_assert_ne!(measure.verdict, VERDICT_RUNNING);
        Run { record, measure }
    }
}

/// Whether a replica with this status, `Record::measured` and `at_max`
/// (it ran to its `max_cycles`) has ended: it failed, was measured by a
/// rule of its own (a recurrence, batch means) or ran out; the group then
/// gives up the split.
pub fn ended(status: u32, measured: u32, at_max: bool) -> bool {
    status != STATUS_OK || measured == 1 || at_max
}

/// The level every member waits at, if they wait at one.
fn common_level(members: &[Member]) -> Option<u32> {
    let level = members.first()?.level;
    members.iter().all(|m| m.level == level).then_some(level)
}

/// Replica `index`'s share of the trapezoid weights of the virtual window
/// [`start`, `start + length`) (`g` its table): the weights at its periods,
/// the virtual periods `count k + index` in the window. Its own estimate
/// is its sums over this share.
pub fn replica_weight(g: &Gaps, start: u32, length: u32, index: u32, count: u32) -> f64 {
    let first = start + (index + count - start % count) % count;
    (first..start + length)
        .step_by(count as usize)
        .map(|v| window_weight(g, length, v - start))
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::laws::floor::phase::gaps;

    /// The replicas' shares of a window's weights add up to the whole
    /// circle, and each is about its fraction of it, wherever the window
    /// starts.
    #[test]
    fn the_replicas_share_the_weights() {
        let rho = 2f64.sqrt() - 1.0;
        for count in [2, 3, 8] {
            for (start, length) in [(0, 1360), (680, 680), (1020, 340), (7, 85)] {
                let g = gaps((rho + 1.0) / count as f64, length);
                let shares: Vec<f64> = (0..count)
                    .map(|r| replica_weight(&g, start, length, r, count))
                    .collect();
                let total: f64 = shares.iter().sum();
                assert!((total - 1.0).abs() < 1e-9, "{total}");
                for s in &shares {
                    assert!(
                        (s * count as f64 - 1.0).abs() < 0.35,
                        "{count} {start}: {shares:?}"
                    );
                }
            }
        }
    }
}
