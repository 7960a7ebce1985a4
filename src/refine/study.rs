//! `pidm refine-study`: how the refinement rule does on a map whose every
//! point is known, a uniform run of the finest grid. The waves run with the
//! uniform file's records as their integration (the refined run integrates
//! exactly those instances, bit for bit), so a rule variant costs no
//! integration; the inferred raster is then compared with the uniform one.

use std::path::Path;

use anyhow::{Context, Result, bail};
use hdf5::File;

use super::grid::FineGrid;
use super::interpolate;
use super::rule::{self, Sample, within};
use super::waves::{self, Options, Refinement};
use crate::model::AXES;
use crate::output::schema;
use crate::plot::{Regime, ZERO_STEP_M};
use crate::sweep::Record;

/// How a rule variant did against the uniform map.
#[derive(Clone, Debug)]
pub struct Metrics {
    /// Points integrated, of the finest grid's.
    pub integrated: u64,
    pub points: u64,
    /// Share of points whose sign labels (dead zone: the tolerance) differ.
    pub sign_mismatch: f64,
    /// Share of points whose sign of a step (dead zone 0.001 um, the
    /// plots' zero) differs.
    pub zero_sign_mismatch: f64,
    /// Share of points whose coupling regime (`pidm plot`'s) differs, when
    /// the map has baselines.
    pub regime_mismatch: Option<f64>,
    /// The same with the tolerance as the regimes' zero.
    pub regime_tol_mismatch: Option<f64>,
    /// Share of the step values (both axes) within the tolerance + 1 %.
    pub within: f64,
    /// The largest step difference [m].
    pub worst: f64,
}

/// Reads the records of a uniform map file (its maps and baselines).
pub fn read_records(path: &Path) -> Result<(Vec<usize>, Vec<Record>, bool)> {
    let file = File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    let f64s = |name: &str| -> Result<Vec<f64>> {
        Ok(file
            .dataset(name)
            .with_context(|| format!("{}: no /{name}", path.display()))?
            .read_raw::<f64>()?)
    };
    let u32s = |name: &str| -> Result<Vec<u32>> {
        Ok(file
            .dataset(name)
            .with_context(|| format!("{}: no /{name}", path.display()))?
            .read_raw::<u32>()?)
    };
    let shape = file.dataset(schema::STATUS)?.shape();
    let step = [f64s(schema::STEP[0])?, f64s(schema::STEP[1])?];
    let velocity = [f64s("maps/velocity_x")?, f64s("maps/velocity_y")?];
    let se = [f64s(schema::STEP_SE[0])?, f64s(schema::STEP_SE[1])?];
    let status = u32s(schema::STATUS)?;
    let baselines = file.group(schema::BASELINE).is_ok();
    let (base, base_status) = if baselines {
        (
            [
                f64s(schema::BASELINE_STEP[0])?,
                f64s(schema::BASELINE_STEP[1])?,
            ],
            u32s(schema::BASELINE_STATUS)?,
        )
    } else {
        (
            [vec![0.0; status.len()], vec![0.0; status.len()]],
            vec![0; status.len()],
        )
    };
    let records = (0..status.len())
        .map(|k| Record {
            step: [step[0][k], step[1][k]],
            velocity: [velocity[0][k], velocity[1][k]],
            step_se: [se[0][k], se[1][k]],
            baseline_step: [base[0][k], base[1][k]],
            baseline_status: base_status[k],
            status: status[k],
            ..Record::default()
        })
        .collect();
    Ok((shape, records, baselines))
}

/// Runs the waves of `opts` with `uniform` as the integration.
pub fn replay(grid: FineGrid, opts: &Options, uniform: &[Record]) -> Result<Refinement> {
    let baselines = opts.baselines;
    let mut integrate = |indices: &[u64]| -> Result<Vec<Sample>> {
        Ok(indices
            .iter()
            .map(|&i| Sample::of_record(&uniform[i as usize], baselines))
            .collect())
    };
    waves::refine(grid, opts, vec![None; grid.len()], &mut integrate)
}

/// Compares a raster with the uniform records at `tolerance` [m].
pub fn compare(raster: &[Record], uniform: &[Record], tolerance: f64, baselines: bool) -> Metrics {
    let n = uniform.len();
    let (mut sign, mut zero, mut regime, mut regime_tol, mut inside) =
        (0u64, 0u64, 0u64, 0u64, 0u64);
    let mut worst: f64 = 0.0;
    for (a, b) in raster.iter().zip(uniform) {
        let (sa, sb) = (
            Sample::of_record(a, baselines),
            Sample::of_record(b, baselines),
        );
        sign += (rule::label(&sa, tolerance, None).sign != rule::label(&sb, tolerance, None).sign)
            as u64;
        zero += (rule::label(&sa, ZERO_STEP_M, None).sign
            != rule::label(&sb, ZERO_STEP_M, None).sign) as u64;
        if baselines {
            let class = |r: &Record, k: usize| {
                Regime::classify(
                    r.step[k],
                    r.baseline_step[k],
                    r.status == 0 && r.baseline_status == 0,
                )
            };
            regime += (0..AXES).any(|k| class(a, k) != class(b, k)) as u64;
            let class_tol = |r: &Record, k: usize| {
                Regime::classify_within(
                    r.step[k],
                    r.baseline_step[k],
                    r.status == 0 && r.baseline_status == 0,
                    tolerance,
                )
            };
            regime_tol += (0..AXES).any(|k| class_tol(a, k) != class_tol(b, k)) as u64;
        }
        for k in 0..AXES {
            inside += within(a.step[k], b.step[k], tolerance) as u64;
            worst = worst.max((a.step[k] - b.step[k]).abs());
        }
    }
    let share = |x: u64, of: usize| x as f64 / of.max(1) as f64;
    Metrics {
        integrated: 0,
        points: n as u64,
        sign_mismatch: share(sign, n),
        zero_sign_mismatch: share(zero, n),
        regime_mismatch: baselines.then(|| share(regime, n)),
        regime_tol_mismatch: baselines.then(|| share(regime_tol, n)),
        within: share(inside, 2 * n),
        worst,
    }
}

/// One variant of the rule, named for the table.
pub fn variants(tolerance: f64, baselines: bool) -> Vec<(&'static str, Options)> {
    let standard = Options::standard(tolerance, baselines);
    let corners = Options {
        probe_labels_last: 0,
        ..standard
    };
    let coupling = Options {
        coupling_labels: true,
        ..standard
    };
    vec![
        (
            "corner labels, centre probe",
            Options {
                neighbour_checks: false,
                ..corners
            },
        ),
        ("corner labels, centre probe + neighbour checks", corners),
        (
            "corner labels, centre + edge probes",
            Options {
                edge_probes: true,
                neighbour_checks: false,
                ..corners
            },
        ),
        (
            "corner labels, centre probe + buffer",
            Options {
                buffer: true,
                neighbour_checks: false,
                ..corners
            },
        ),
        ("standard (probe labels on the last level)", standard),
        (
            "standard + buffer beside misses > 10 tol",
            Options {
                miss_buffer: Some(10.0),
                ..standard
            },
        ),
        (
            "standard + buffer beside misses > 25 tol",
            Options {
                miss_buffer: Some(25.0),
                ..standard
            },
        ),
        (
            "standard + buffer beside misses > 50 tol",
            Options {
                miss_buffer: Some(50.0),
                ..standard
            },
        ),
        (
            "standard, no audit",
            Options {
                audit_fraction: 0.0,
                ..standard
            },
        ),
        (
            "standard, no neighbour checks",
            Options {
                neighbour_checks: false,
                ..standard
            },
        ),
        (
            "probe labels on the last 2 levels",
            Options {
                probe_labels_last: 2,
                ..standard
            },
        ),
        (
            "probe labels everywhere",
            Options {
                corner_labels: false,
                ..standard
            },
        ),
        (
            "with coupling labels, corner labels",
            Options {
                probe_labels_last: 0,
                ..coupling
            },
        ),
        ("with coupling labels (standard otherwise)", coupling),
        (
            "with coupling labels, probe labels on the last 2 levels",
            Options {
                probe_labels_last: 2,
                ..coupling
            },
        ),
    ]
}

/// Runs every variant on a uniform file of a refined scene's finest grid.
pub fn study(
    uniform_path: &Path,
    coarse: [usize; 2],
    levels: u32,
    tolerance: f64,
) -> Result<Vec<(&'static str, Metrics, Refinement)>> {
    let (shape, uniform, baselines) = read_records(uniform_path)?;
    let grid = FineGrid::new(coarse, levels);
    if shape != grid.n {
        bail!(
            "{} is a {:?} map; the refined scene's finest grid is {:?}",
            uniform_path.display(),
            shape,
            grid.n
        );
    }
    let mut out = Vec::new();
    for (name, opts) in variants(tolerance, baselines) {
        let r = replay(grid, &opts, &uniform)?;
        let records: Vec<Option<Record>> = r
            .level_of
            .iter()
            .zip(&uniform)
            .map(|(&l, rec)| (l != waves::INFERRED).then_some(*rec))
            .collect();
        let (raster, inferred) = interpolate::raster(&r, &records);
        let mut m = compare(&raster, &uniform, tolerance, baselines);
        m.integrated = inferred.iter().filter(|&&x| x == 0).count() as u64;
        out.push((name, m, r));
    }
    Ok(out)
}
