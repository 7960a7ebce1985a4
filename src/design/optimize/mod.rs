//! `pidm optimize` (docs/design.md): the best drive or mechanism under
//! constraints, or the front between two objectives, measured rather
//! than lucky: the optimum is steady, its value and each constraint's
//! margin carry standard errors, and its neighbourhood is probed for a
//! cliff.

pub mod report;
pub mod search;
pub mod spec;

use anyhow::Result;

use self::search::{PROBE, SCAN_POINTS, Search};
use self::spec::OptimizeScene;
use crate::design::model::{Evaluation, Model};
use crate::model::AXES;

/// One probe of the optimum's neighbourhood, and what changed there.
pub struct Probe {
    /// The key moved and the way (-1 or +1).
    pub key: usize,
    pub direction: f64,
    pub index: usize,
    /// What differs from the optimum: a status, a kind of motion, a
    /// step's sign; empty where nothing does.
    pub changes: Vec<String>,
}

/// What the search found.
pub struct Found {
    /// The optimum's index in the archive (the first objective's best,
    /// feasibility first), `None` where no run finished.
    pub optimum: Option<usize>,
    pub probes: Vec<Probe>,
    /// Per free key, its scan through the optimum: archive indices.
    pub scans: Vec<Vec<usize>>,
    /// The front's archive indices (two objectives only).
    pub front: Vec<usize>,
}

/// Runs the whole search of `spec` on `model`, from `seed`.
pub fn optimize(search: &mut Search) -> Result<Found> {
    let spec: &OptimizeScene = search.spec;
    let p = spec.free.len();
    let probes = 2 * p;
    if spec.front() {
        search.front_search(spec.budget - probes)?;
    } else {
        search.minimise(0, spec.budget - probes - SCAN_POINTS * p)?;
    }
    let optimum = search.best(0);
    let mut found = Found {
        optimum,
        probes: Vec::new(),
        scans: Vec::new(),
        front: if spec.front() {
            search.front()
        } else {
            Vec::new()
        },
    };
    if let Some(best) = optimum {
        found.probes = probe(search, best)?;
        if !spec.front() {
            found.scans = scans(search, best)?;
        }
    }
    Ok(found)
}

/// The optimum's coordinates.
fn coordinates(search: &Search, index: usize) -> Vec<f64> {
    search
        .spec
        .free
        .iter()
        .zip(&search.archive.values[index])
        .map(|(f, &v)| f.coordinate(v))
        .collect()
}

/// Runs the optimum's neighbours at ±[`PROBE`] of each key's range
/// (clipped to the bounds) and says what changed there.
fn probe(search: &mut Search, best: usize) -> Result<Vec<Probe>> {
    let (lo, hi) = search.bounds();
    let at = coordinates(search, best);
    let mut points = Vec::new();
    let mut moves = Vec::new();
    for j in 0..at.len() {
        for direction in [-1.0, 1.0] {
            let mut u = at.clone();
            u[j] = (u[j] + direction * PROBE * (hi[j] - lo[j])).clamp(lo[j], hi[j]);
            points.push(u);
            moves.push((j, direction));
        }
    }
    let first = search.archive.runs.len();
    search.run(&points)?;
    let centre = search.archive.runs[best].clone();
    Ok(moves
        .into_iter()
        .enumerate()
        .map(|(k, (key, direction))| Probe {
            key,
            direction,
            index: first + k,
            changes: changes(&centre, &search.archive.runs[first + k]),
        })
        .collect())
}

/// What differs between the optimum's run and a neighbour's.
fn changes(centre: &Evaluation, other: &Evaluation) -> Vec<String> {
    let (Ok(c), Ok(o)) = (centre, other) else {
        return vec![match other {
            Err(why) => format!("the neighbour is {why}"),
            Ok(_) => "the optimum did not run".to_owned(),
        }];
    };
    let (c, o) = (&c.record, &o.record);
    let mut out = Vec::new();
    if c.status != o.status {
        out.push(format!("status {} becomes {}", c.status, o.status));
    }
    if c.motion != o.motion {
        out.push(format!(
            "motion {} becomes {}",
            c.motion.name(),
            o.motion.name()
        ));
    }
    for a in 0..AXES {
        if c.step[a].signum() * o.step[a].signum() < 0.0 {
            out.push(format!(
                "step_{} changes sign ({:.4e} to {:.4e} m)",
                crate::model::AXIS_NAMES[a],
                c.step[a],
                o.step[a]
            ));
        }
    }
    out
}

/// Each free key across its bounds ([`SCAN_POINTS`]) with the others at
/// the optimum, for OPT.png.
fn scans(search: &mut Search, best: usize) -> Result<Vec<Vec<usize>>> {
    let (lo, hi) = search.bounds();
    let at = coordinates(search, best);
    let mut points = Vec::new();
    for j in 0..at.len() {
        for k in 0..SCAN_POINTS {
            let mut u = at.clone();
            u[j] = lo[j] + (hi[j] - lo[j]) * k as f64 / (SCAN_POINTS - 1) as f64;
            points.push(u);
        }
    }
    let first = search.archive.runs.len();
    search.run(&points)?;
    Ok((0..at.len())
        .map(|j| {
            (0..SCAN_POINTS)
                .map(|k| first + j * SCAN_POINTS + k)
                .collect()
        })
        .collect())
}

/// Starts a search of `spec` over `model`.
pub fn new_search<'s, 'm, 'a>(
    spec: &'s OptimizeScene,
    model: &'m mut Model<'a>,
    seed: u64,
    done: &'s (dyn Fn(u64) + Sync),
) -> Search<'s, 'm, 'a> {
    Search {
        spec,
        model,
        archive: search::Archive::default(),
        seed,
        done,
    }
}
