//! Reading the stored trajectories (`/trajectories/<k>/`, laid out by
//! `crate::trajectory`), checked: every series of a run has the length of
//! its `time`, times are finite (within ±1e100) and never decrease, and the
//! run attributes the figure uses exist and are finite.

use super::checked::{Checked, ResultFile, is_plausible, join};
use super::error::Problem;
use crate::model::AXIS_NAMES;
use crate::output::schema;

/// One stored run in time: the point's, or a 1-DOF run beside it (which
/// holds only its driven axis' series).
pub(super) struct RunData {
    /// Sample times [s].
    pub(super) time: Vec<f64>,
    /// Stage and slider displacement per axis [m].
    pub(super) stage: [Vec<f64>; 2],
    pub(super) slider: [Vec<f64>; 2],
    /// Drive amplitude [V], frequency [Hz], rise fraction and phase
    /// [cycles] per axis.
    pub(super) voltage: [f64; 2],
    pub(super) frequency: [f64; 2],
    pub(super) duty: [f64; 2],
    pub(super) phase: [f64; 2],
    /// Scene period and the end of the settle periods [s].
    pub(super) period_s: f64,
    pub(super) settle_s: f64,
    /// End of the measured periods [s].
    pub(super) measured_end_s: f64,
    /// Integrator status at the end of the run (0 = ok).
    pub(super) status: u64,
}

impl RunData {
    /// The slider's step per own drive cycle of axis `a` over the measured
    /// periods, from the samples [um]; `None` when they do not cover them.
    pub(super) fn step_um(&self, a: usize) -> Option<f64> {
        let at = |t: f64| {
            self.time
                .iter()
                .position(|&s| s >= t - 1e-9 * self.period_s)
        };
        let (i, j) = (at(self.settle_s)?, at(self.measured_end_s)?);
        let kept = self.time[j] - self.time[i];
        (kept > 0.0 && self.frequency[a] > 0.0 && self.status == 0)
            .then(|| (self.slider[a][j] - self.slider[a][i]) / kept / self.frequency[a] * 1e6)
    }

    /// Whether every stored displacement is finite and within ±1e100.
    fn is_plausible(&self) -> bool {
        self.stage
            .iter()
            .chain(&self.slider)
            .flatten()
            .all(|&v| is_plausible(v))
    }
}

/// A stored trajectory.
pub(super) struct TrajectoryData {
    pub(super) point: String,
    /// The point's label in a points scene, else "".
    pub(super) label: String,
    /// The flat instance index.
    pub(super) index: u64,
    pub(super) run: RunData,
    /// The 1-DOF runs, x driven alone and y driven alone.
    pub(super) baselines: Option<[RunData; 2]>,
    /// Why the trajectory cannot be drawn (too few samples, non-finite
    /// displacements), if it cannot.
    pub(super) not_drawn: Option<String>,
}

/// Reads every stored trajectory, in the order of their numbers; none when
/// the file has no `/trajectories` group.
pub(super) fn read_trajectories(file: &ResultFile) -> Checked<Vec<TrajectoryData>> {
    if !file.exists(schema::TRAJECTORIES) {
        return Ok(Vec::new());
    }
    let mut names = file.members(schema::TRAJECTORIES)?;
    names.sort_by_key(|n| n.parse::<u64>().unwrap_or(u64::MAX));
    names
        .iter()
        .map(|name| read_trajectory(file, &join(schema::TRAJECTORIES, name), name))
        .collect()
}

/// Reads the trajectory group at `at`, named `name`.
fn read_trajectory(file: &ResultFile, at: &str, name: &str) -> Checked<TrajectoryData> {
    let g = file.group(at)?;
    let mut run = read_run(file, at, false)?;
    for a in 0..2 {
        run.stage[a] = read_series(file, at, schema::STAGE[a], run.time.len())?;
        run.slider[a] = read_series(file, at, schema::SLIDER[a], run.time.len())?;
    }
    let [x, y] = schema::BASELINE_RUN.map(|b| join(at, b));
    let baselines = match (file.exists(&x), file.exists(&y)) {
        (false, false) => None,
        (true, true) => {
            let mut pair = [read_run(file, &x, true)?, read_run(file, &y, true)?];
            for (a, (base, path)) in pair.iter_mut().zip([&x, &y]).enumerate() {
                let n = base.time.len();
                base.stage[a] = read_series(file, path, schema::BASELINE_STAGE, n)?;
                base.slider[a] = read_series(file, path, schema::BASELINE_SLIDER, n)?;
            }
            Some(pair)
        }
        (has_x, _) => {
            let (missing, present) = if has_x { (&y, &x) } else { (&x, &y) };
            return Err(file.error(
                format!("group /{missing}"),
                Problem::Invalid(format!(
                    "is missing while /{present} exists: the 1-DOF runs come in pairs"
                )),
            ));
        }
    };
    let not_drawn = if run.time.len() < 2 {
        Some("has fewer than two samples".to_owned())
    } else if !run.is_plausible() || baselines.iter().flatten().any(|b| !b.is_plausible()) {
        Some(
            "holds displacements that are not finite or beyond ±1e100 (the run diverged)"
                .to_owned(),
        )
    } else {
        None
    };
    Ok(TrajectoryData {
        point: file
            .text_attr(&g, at, schema::POINT)?
            .unwrap_or_else(|| format!("trajectory {name}")),
        label: file.text_attr(&g, at, schema::LABEL)?.unwrap_or_default(),
        index: file
            .integer_attr(&g, at, schema::INDEX)?
            .unwrap_or(u64::MAX),
        run,
        baselines,
        not_drawn,
    })
}

/// Reads the 1-D series `name` of the run group at `at`, which must hold
/// `len` samples (the length of the group's `time`).
fn read_series(file: &ResultFile, at: &str, name: &str, len: usize) -> Checked<Vec<f64>> {
    let series = file.floats(&join(at, name))?;
    file.expect_shape(
        &series,
        &[len],
        format!("the length of /{}", join(at, schema::TIME)),
    )?;
    Ok(series.values)
}

/// Reads the sample times and the attributes of the run group at `at`; a
/// 1-DOF run (`baseline`) also needs its `measured_cycles`.
fn read_run(file: &ResultFile, at: &str, baseline: bool) -> Checked<RunData> {
    let g = file.group(at)?;
    let time_path = join(at, schema::TIME);
    let time = file.floats(&time_path)?;
    file.expect_list(&time)?;
    file.expect_plausible(&time, "sample times place the curves on the page")?;
    if let Some(i) = time.values.windows(2).position(|w| w[1] < w[0]) {
        return Err(file.dataset_error(
            &time_path,
            Problem::Invalid(format!(
                "decreases after index {i} (from {} s to {} s); sample times must not decrease",
                time.values[i],
                time.values[i + 1]
            )),
        ));
    }
    let number = |name: &str| file.number_attr(&g, at, name);
    let per_axis = |what: &str| -> Checked<[f64; 2]> {
        Ok([
            number(&format!("{what}_{}", AXIS_NAMES[0]))?,
            number(&format!("{what}_{}", AXIS_NAMES[1]))?,
        ])
    };
    let period_s = number(schema::PERIOD_S)?;
    let measured_end_s = if baseline {
        let cycles = file
            .integer_attr(&g, at, schema::MEASURED_CYCLES)?
            .ok_or_else(|| {
                file.error(
                    format!("attribute {} of /{at}", schema::MEASURED_CYCLES),
                    Problem::Missing,
                )
            })?;
        cycles as f64 * period_s
    } else {
        number(schema::DURATION_S)?
    };
    let status = file
        .integer_attr(&g, at, schema::RUN_STATUS)?
        .ok_or_else(|| {
            file.error(
                format!("attribute {} of /{at}", schema::RUN_STATUS),
                Problem::Missing,
            )
        })?;
    Ok(RunData {
        time: time.values,
        stage: [Vec::new(), Vec::new()],
        slider: [Vec::new(), Vec::new()],
        voltage: per_axis(schema::VOLTAGE)?,
        frequency: per_axis(schema::FREQUENCY)?,
        duty: per_axis(schema::DUTY)?,
        phase: per_axis(schema::PHASE)?,
        period_s,
        settle_s: number(schema::SETTLE_S)?,
        measured_end_s,
        status,
    })
}
