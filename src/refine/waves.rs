//! The waves of a refinement: which points are integrated, level by level,
//! each level's new points as few large batches. The integration itself
//! is a closure, so the rule runs on synthetic maps in tests and on the
//! records of a uniform run in the study (`pidm refine-study`).
//!
//! Level 0 integrates the coarse grid; every coarse cell is a candidate.
//! At each level `l = 1..=levels` the candidates (cells of side
//! `2^(levels - l + 1)` finest steps) are judged:
//! 1. a cell whose corners carry different labels, or a corner that did not
//!    finish normally, is flagged ([`rule::corners_agree`]);
//! 2. one batch integrates the probe of every candidate (its centre; with
//!    [`Options::edge_probes`] also its edge midpoints) and the audit point
//!    of a deterministic random [`Options::audit_fraction`] of the unflagged
//!    ones (an interior point off the cell's midlines, where no probe looks);
//! 3. a cell is flagged where the bilinear interpolant of its corners
//!    misses a probe or audit point ([`rule::judge`]: beyond the tolerance
//!    plus 1 %, or another label);
//! 4. one batch integrates the new points of every flagged cell (its centre
//!    and edge midpoints: the corners of its children); with
//!    [`Options::neighbour_checks`], an unflagged candidate whose edge
//!    midpoints a flagged neighbour integrated is judged on them too, and a
//!    miss flags it for another batch, until no cell is newly flagged;
//! 5. the children of the flagged cells are the next level's candidates; an
//!    unflagged candidate is a leaf, inferred from its corners.
//!
//! A point is integrated once, at the first level that asks for it; points
//! already known (from the checkpoint of an interrupted run) are not handed
//! to the closure again, and the waves come out the same.

use std::collections::HashSet;

use anyhow::Result;

use super::grid::{Cell, FineGrid, Point};
use super::rule::{self, Sample};
use crate::model::random::Rng;

/// The choices of the rule; [`Options::standard`] is what `pidm run` uses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// The step tolerance [m per own drive cycle]: the labels' dead zone and
    /// the absolute part of the accuracy rule.
    pub tolerance: f64,
    /// Whether the samples carry baselines (coupling labels, compared
    /// baseline steps).
    pub baselines: bool,
    /// Whether the labels include the coupling regime (2-DOF against 1-DOF
    /// step, `pidm plot`'s classes) when the samples carry baselines, and
    /// the probes compare the baseline steps too. Off
    /// in the standard rule: on the coupling map its class boundaries
    /// (where 2-DOF and 1-DOF steps differ by a few nm) cover so much of
    /// the map that following them integrates 28-36 % of it
    /// (results/refine.md).
    pub coupling_labels: bool,
    /// The coupling regime's zero [m]: steps, and differences between the
    /// 2-DOF and 1-DOF step, smaller than it count as none.
    pub coupling_zero: f64,
    /// Probe the edge midpoints of every candidate too, not only its centre.
    pub edge_probes: bool,
    /// Judge unflagged candidates on the edge midpoints their flagged
    /// neighbours integrated, again until nothing changes.
    pub neighbour_checks: bool,
    /// Refine every cell whose corners carry different labels (the issue's
    /// rule); when false such a cell is refined only where its probes miss
    /// the interpolant or its label there (a smooth crossing of a label's
    /// threshold is left to the interpolant, which places it within the
    /// tolerance). Corners that did not finish normally always refine.
    pub corner_labels: bool,
    /// Levels at the fine end (the last ones) where [`Options::corner_labels`]
    /// does not apply: their label-boundary cells are judged on probes only.
    pub probe_labels_last: u32,
    /// Also refine the same-size candidates beside every flagged cell.
    pub buffer: bool,
    /// Also refine the same-size candidates beside every cell whose probes
    /// missed the interpolant by more than this many tolerances: a miss far
    /// beyond the tolerance is structure the cell size does not resolve,
    /// which may reach into the neighbours unseen by their probes.
    pub miss_buffer: Option<f64>,
    /// Share of the unflagged candidates of each level that get an audit
    /// point.
    pub audit_fraction: f64,
    /// Seed of the audit's choice of cells and points.
    pub seed: u64,
}

/// Share of unflagged cells audited per level: 2 %, a few dozen points on
/// a 17 x 17 grid refined 4 times, a fraction of a percent of its points.
pub const AUDIT_FRACTION: f64 = 0.02;
/// The audit's seed: fixed, so a run and its resumption choose alike.
pub const AUDIT_SEED: u64 = 0x5eed_0022;

impl Options {
    /// The coupling regime's zero, when the samples carry baselines.
    pub fn coupling(&self) -> Option<f64> {
        (self.baselines && self.coupling_labels).then_some(self.coupling_zero)
    }

    /// The rule `pidm run` uses: sign labels at the corners of every level
    /// but the last (where labels are judged at the probes), centre probes,
    /// neighbour checks, no buffer, a 2 % audit (the choices measured in
    /// results/refine.md).
    pub fn standard(tolerance: f64, baselines: bool) -> Options {
        Options {
            tolerance,
            baselines,
            coupling_labels: false,
            coupling_zero: tolerance,
            corner_labels: true,
            probe_labels_last: 1,
            edge_probes: false,
            neighbour_checks: true,
            buffer: false,
            miss_buffer: None,
            audit_fraction: AUDIT_FRACTION,
            seed: AUDIT_SEED,
        }
    }
}

/// What one level did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LevelStats {
    /// Points first asked for at this level (coarse grid at level 0).
    pub integrated: u64,
    /// Cells judged.
    pub candidates: u64,
    /// Cells refined.
    pub flagged: u64,
    /// Of those, the cells whose corners disagreed, those a probe flagged,
    /// and those a neighbour's edge midpoints flagged.
    pub by_label: u64,
    pub by_probe: u64,
    pub by_neighbours: u64,
    /// The largest difference between the interpolant and an integrated
    /// probe, audit or neighbour point of the level [m].
    pub largest_miss: f64,
    /// Cells that got an audit point.
    pub audited: u64,
    /// Cells only their audit point flagged.
    pub audit_finds: u64,
    /// Batches handed to the integration.
    pub batches: u64,
}

/// The outcome of the waves.
#[derive(Clone, Debug)]
pub struct Refinement {
    pub grid: FineGrid,
    /// The level that integrated each point, or [`INFERRED`].
    pub level_of: Vec<u8>,
    /// Every sample, `None` where inferred.
    pub samples: Vec<Option<Sample>>,
    /// The unrefined cells, largest first: every inferred point lies in one.
    pub leaves: Vec<Cell>,
    /// Per level, from 0.
    pub stats: Vec<LevelStats>,
}

/// [`Refinement::level_of`] of a point that was not integrated.
pub const INFERRED: u8 = u8::MAX;

/// The integration the waves ask for: the samples of the given flat
/// indices (ascending, none known yet), in that order.
pub type Integrate<'a> = dyn FnMut(&[u64]) -> Result<Vec<Sample>> + 'a;

struct Waves<'a, 'b> {
    grid: FineGrid,
    opts: Options,
    level_of: Vec<u8>,
    samples: Vec<Option<Sample>>,
    integrate: &'a mut Integrate<'b>,
}

impl Waves<'_, '_> {
    /// Integrates the points not yet asked for, as one batch; returns how
    /// many were new.
    fn ask(
        &mut self,
        points: impl IntoIterator<Item = Point>,
        level: u8,
        stats: &mut LevelStats,
    ) -> Result<()> {
        let mut indices: Vec<usize> = points
            .into_iter()
            .map(|p| self.grid.index(p))
            .filter(|&k| self.level_of[k] == INFERRED)
            .collect();
        indices.sort_unstable();
        indices.dedup();
        if indices.is_empty() {
            return Ok(());
        }
        for &k in &indices {
            self.level_of[k] = level;
        }
        stats.integrated += indices.len() as u64;
        let unknown: Vec<u64> = indices
            .iter()
            .filter(|&&k| self.samples[k].is_none())
            .map(|&k| k as u64)
            .collect();
        if !unknown.is_empty() {
            stats.batches += 1;
            let got = (self.integrate)(&unknown)?;
            anyhow::ensure!(
                got.len() == unknown.len(),
                "internal: the integration returned {} samples for {} points",
                got.len(),
                unknown.len()
            );
            for (k, s) in unknown.iter().zip(got) {
                self.samples[*k as usize] = Some(s);
            }
        }
        Ok(())
    }

    fn sample(&self, p: Point) -> Option<Sample> {
        self.samples[self.grid.index(p)].filter(|_| self.level_of[self.grid.index(p)] != INFERRED)
    }

    fn corners(&self, cell: &Cell) -> [Sample; 4] {
        cell.corners().map(|p| {
            self.sample(p)
                .expect("a candidate's corners are integrated")
        })
    }

    /// Judges the interpolant of a cell at those of `points` that are
    /// integrated: (largest miss, whether any is off).
    fn judge(&self, cell: &Cell, points: &[Point]) -> (f64, bool) {
        let corners = self.corners(cell);
        let mut worst = (0.0f64, false);
        for &p in points {
            if let Some(exact) = self.sample(p) {
                let (u, v) = cell.local(p);
                let j = rule::judge(
                    &Sample::bilinear(&corners, u, v),
                    &exact,
                    self.opts.tolerance,
                    self.opts.coupling(),
                    self.opts.coupling().is_some(),
                );
                worst = (worst.0.max(j.miss), worst.1 || j.off);
            }
        }
        worst
    }
}

/// The audit point of a cell, if it is audited: an interior point off its
/// midlines, chosen by a hash of the seed, the level and the cell.
pub fn audit_point(cell: &Cell, level: u32, opts: &Options) -> Option<Point> {
    let h = cell.size / 2;
    if h < 2 || opts.audit_fraction <= 0.0 {
        return None;
    }
    // One generator per (level, cell), so the choice does not depend on
    // the order cells are judged in.
    let key = (level as u64) << 56 ^ (cell.i as u64) << 28 ^ cell.j as u64;
    let mut rng = Rng::new(opts.seed ^ key.wrapping_mul(0x9e37_79b9_7f4a_7c15));
    if rng.unit() >= opts.audit_fraction {
        return None;
    }
    let a = rng.next_u64() as usize;
    let b = rng.next_u64() as usize;
    // An offset in 1..size, not h: off the midlines.
    let off = |r: usize| {
        let k = 1 + r % (cell.size - 2);
        if k >= h { k + 1 } else { k }
    };
    Some((cell.i + off(a), cell.j + off(b)))
}

/// Runs the waves over `grid`. `known` holds samples already integrated
/// (a resumed run's checkpoint), `None` elsewhere; `integrate` computes the
/// others.
pub fn refine(
    grid: FineGrid,
    opts: &Options,
    known: Vec<Option<Sample>>,
    integrate: &mut Integrate<'_>,
) -> Result<Refinement> {
    assert_eq!(known.len(), grid.len());
    let mut w = Waves {
        grid,
        opts: *opts,
        level_of: vec![INFERRED; grid.len()],
        samples: known,
        integrate,
    };
    let mut stats = vec![LevelStats::default(); grid.levels as usize + 1];
    let mut candidates = grid.coarse_cells();
    let coarse: Vec<Point> = candidates.iter().flat_map(|c| c.corners()).collect();
    w.ask(coarse, 0, &mut stats[0])?;
    let mut leaves = Vec::new();
    for level in 1..=grid.levels {
        candidates = w.level(&candidates, level, &mut stats[level as usize], &mut leaves)?;
    }
    let samples = w
        .samples
        .iter()
        .zip(&w.level_of)
        .map(|(s, &l)| s.filter(|_| l != INFERRED))
        .collect();
    Ok(Refinement {
        grid,
        level_of: w.level_of,
        samples,
        leaves,
        stats,
    })
}

impl Waves<'_, '_> {
    /// Runs one level `1..=levels` over its candidates (steps 1-5 of the
    /// module's rule), adding its unflagged candidates to `leaves`;
    /// returns the next level's candidates.
    fn level(
        &mut self,
        candidates: &[Cell],
        level: u32,
        st: &mut LevelStats,
        leaves: &mut Vec<Cell>,
    ) -> Result<Vec<Cell>> {
        let lv = level as u8;
        st.candidates = candidates.len() as u64;
        // 1. Labels.
        let mut flagged = self.label_flags(candidates, level);
        st.by_label = flagged.iter().filter(|f| **f).count() as u64;
        // 2. Probes and audit points, one batch.
        let audits = self.ask_probes(candidates, &flagged, level, st)?;
        // 3. Judge the probes, then the audit points.
        let big_miss = self.judge_probes(candidates, &audits, &mut flagged, st);
        self.flag_buffer(candidates, &mut flagged, big_miss);
        // 4. The new points of the flagged cells, then the neighbours'
        // checks, until nothing more is flagged.
        self.refine_flagged(candidates, &mut flagged, lv, st)?;
        st.flagged = flagged.iter().filter(|f| **f).count() as u64;
        Ok(next_candidates(candidates, &flagged, leaves))
    }

    /// Step 1: whether each candidate is flagged by its corners' labels (or,
    /// where labels do not apply at this level, by a corner that did not
    /// finish normally).
    fn label_flags(&self, candidates: &[Cell], level: u32) -> Vec<bool> {
        let opts = &self.opts;
        candidates
            .iter()
            .map(|c| {
                let corners = self.corners(c);
                if opts.corner_labels && level + opts.probe_labels_last <= self.grid.levels {
                    !rule::corners_agree(&corners, opts.tolerance, opts.coupling())
                } else {
                    corners.iter().any(|s| !s.ok)
                }
            })
            .collect()
    }

    /// Step 2: chooses the audit points of the unflagged candidates and
    /// integrates every candidate's probes and audit point as one batch;
    /// returns the audit point of each candidate.
    fn ask_probes(
        &mut self,
        candidates: &[Cell],
        flagged: &[bool],
        level: u32,
        st: &mut LevelStats,
    ) -> Result<Vec<Option<Point>>> {
        let opts = self.opts;
        let audits: Vec<Option<Point>> = candidates
            .iter()
            .zip(flagged)
            .map(|(c, &f)| {
                if f {
                    None
                } else {
                    audit_point(c, level, &opts)
                }
            })
            .collect();
        st.audited = audits.iter().flatten().count() as u64;
        let mut batch: Vec<Point> = Vec::new();
        for (c, a) in candidates.iter().zip(&audits) {
            batch.push(c.centre());
            if opts.edge_probes {
                batch.extend(c.edge_midpoints());
            }
            batch.extend(*a);
        }
        self.ask(batch, level as u8, st)?;
        Ok(audits)
    }

    /// Step 3: judges each candidate's probes, then its audit point,
    /// flagging the cells they miss; returns the cells whose probes missed
    /// by more than [`Options::miss_buffer`] tolerances.
    fn judge_probes(
        &self,
        candidates: &[Cell],
        audits: &[Option<Point>],
        flagged: &mut [bool],
        st: &mut LevelStats,
    ) -> HashSet<Cell> {
        let opts = &self.opts;
        let mut big_miss: HashSet<Cell> = HashSet::new();
        for (k, c) in candidates.iter().enumerate() {
            let mut probes = vec![c.centre()];
            probes.extend(c.edge_midpoints());
            let (miss, off) = self.judge(c, &probes);
            st.largest_miss = st.largest_miss.max(miss);
            if opts.miss_buffer.is_some_and(|f| miss > f * opts.tolerance) {
                big_miss.insert(*c);
            }
            if !flagged[k] && off {
                flagged[k] = true;
                st.by_probe += 1;
            }
            if let Some(a) = audits[k] {
                let (miss, off) = self.judge(c, &[a]);
                st.largest_miss = st.largest_miss.max(miss);
                if off && !flagged[k] {
                    flagged[k] = true;
                    st.audit_finds += 1;
                }
            }
        }
        big_miss
    }

    /// Flags the candidates beside a flagged cell ([`Options::buffer`]) or,
    /// without the buffer, beside a cell of `big_miss`.
    fn flag_buffer(&self, candidates: &[Cell], flagged: &mut [bool], big_miss: HashSet<Cell>) {
        if self.opts.buffer || !big_miss.is_empty() {
            let set: HashSet<Cell> = if self.opts.buffer {
                candidates
                    .iter()
                    .zip(flagged.iter())
                    .filter(|(_, f)| **f)
                    .map(|(c, _)| *c)
                    .collect()
            } else {
                big_miss
            };
            for (k, c) in candidates.iter().enumerate() {
                if !flagged[k] && c.neighbours().iter().any(|n| set.contains(n)) {
                    flagged[k] = true;
                }
            }
        }
    }

    /// Step 4: integrates the new points of the flagged cells, one batch
    /// per round; with [`Options::neighbour_checks`] judges the unflagged
    /// candidates on their edge midpoints after each round, and flags a
    /// miss for the next, until no cell is newly flagged.
    fn refine_flagged(
        &mut self,
        candidates: &[Cell],
        flagged: &mut [bool],
        lv: u8,
        st: &mut LevelStats,
    ) -> Result<()> {
        let mut newly: Vec<usize> = (0..candidates.len()).filter(|&k| flagged[k]).collect();
        while !newly.is_empty() {
            let points: Vec<Point> = newly
                .iter()
                .flat_map(|&k| {
                    let c = candidates[k];
                    std::iter::once(c.centre()).chain(c.edge_midpoints())
                })
                .collect();
            self.ask(points, lv, st)?;
            newly.clear();
            if self.opts.neighbour_checks {
                for (k, c) in candidates.iter().enumerate() {
                    if !flagged[k] {
                        let (miss, off) = self.judge(c, &c.edge_midpoints());
                        st.largest_miss = st.largest_miss.max(miss);
                        if off {
                            flagged[k] = true;
                            st.by_neighbours += 1;
                            newly.push(k);
                        }
                    }
                }
            }
        }
        Ok(())
    }
}

/// Step 5: the children of the flagged candidates (cells larger than 2
/// finest steps), the next level's candidates; the unflagged ones are
/// added to `leaves`.
fn next_candidates(candidates: &[Cell], flagged: &[bool], leaves: &mut Vec<Cell>) -> Vec<Cell> {
    let mut next = Vec::new();
    for (c, f) in candidates.iter().zip(flagged) {
        if *f {
            if c.size > 2 {
                next.extend(c.children());
            }
        } else {
            leaves.push(*c);
        }
    }
    next
}
