//! Trajectories: the stage and slider motion of chosen instances over the
//! whole run (settle included), on a uniform time grid, for pictures such as
//! the paper's Figs. 5-8.
//!
//! A trajectory is always computed by the f64 CPU integrator. Its steps can
//! be long (a stick phase may be crossed in one closed-form step), so the
//! samples are not step ends: an observer ([`StepObserver`]) sees the
//! closed-form motion of every step and evaluates it at each sample time
//! the step covers, the same dense output that event location uses. The
//! observer never changes the state, so a recorded run ends in the same
//! state, bit for bit, as the map run of the same instance.
//!
//! Stored in the result file as `/trajectories/<k>/` (k = 0, 1, ... in the
//! order of `output.trajectories`):
//! - `time` [s], a netCDF dimension scale that every other series of the
//!   group is attached to (so the group opens in xarray with `time` as its
//!   dimension); `stage_x`, `stage_y`, `slider_x`, `slider_y` [m];
//!   `voltage_x`, `voltage_y` [V] (the drive);
//! - every dataset has `units` and `long_name` attributes; the group has
//!   `point` (a human name), `label` (a points scene's label, or ""),
//!   `index` (flat instance index), `status`, `samples_per_cycle`,
//!   `period_s`, `settle_s`, `duration_s` and the drive of each axis
//!   (`voltage_x` [V], `frequency_x` [Hz], `duty_x`, `phase_x` [cycles],
//!   and the same for y);
//! - with baselines, subgroups `baseline_x` and `baseline_y`: the 1-DOF run
//!   with only that axis driven, as `time` [s], `stage`, `slider` [m] and
//!   `voltage` [V] along that axis, with the same attributes plus
//!   `measured_cycles`. A 1-DOF run at a higher frequency than the point's
//!   scene period has a shorter period, so it is recorded for more periods
//!   to cover the point's whole run, with as many samples per second as
//!   the point; its first `measured_cycles` periods are the map's baseline
//!   run, bit for bit.

use anyhow::{Context, Result};
use rayon::prelude::*;

use crate::laws::Record;
use crate::laws::floor::drive::{Corners, axis_corners};
use crate::laws::observe::{Observer, Positions};
use crate::laws::{Law, Settings};
use crate::model::{AXES, AXIS_NAMES, Instance};
use crate::output::schema;
use crate::output::{dimension_scales, write_f64_attr, write_str_attr, write_u64_attr};
use crate::scene::{Scene, TrajectoryPoint};

/// The motion of one instance on a uniform time grid.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    /// Sample times from the start of the run [s].
    pub time: Vec<f64>,
    /// Stage displacement per axis [m].
    pub stage: [Vec<f64>; AXES],
    /// Slider displacement per axis [m].
    pub slider: [Vec<f64>; AXES],
    /// Drive voltage per axis [V].
    pub voltage: [Vec<f64>; AXES],
    /// The state the run ended in (the same as [`integrate::run_instance`]'s).
    pub state: Record,
    /// Samples per scene period.
    pub samples_per_cycle: u32,
}

/// Collects samples as the integrator's steps go by.
struct Sampler<'a> {
    inst: &'a Instance,
    /// Each axis' drive over a cycle (`floor::drive::axis_corners`).
    drives: [Corners; AXES],
    period: f64,
    per: u64,
    /// Index of the next sample to take; sample k is at k T / per.
    next: u64,
    /// Samples in a complete run.
    total: u64,
    out: Series,
}

/// A trajectory's series, as the sampler fills them.
struct Series {
    time: Vec<f64>,
    stage: [Vec<f64>; AXES],
    slider: [Vec<f64>; AXES],
    voltage: [Vec<f64>; AXES],
}

impl Sampler<'_> {
    fn push(&mut self, x_p: [f64; AXES], x_s: [f64; AXES]) {
        let t = self.next as f64 * self.period / self.per as f64;
        self.out.time.push(t);
        for i in 0..AXES {
            self.out.stage[i].push(x_p[i]);
            self.out.slider[i].push(x_s[i]);
            let axis = &self.inst.axes[i];
            let v = if axis.is_driven() {
                axis.voltage * self.drives[i].level(axis.frequency * t + axis.phase)
            } else {
                0.0
            };
            self.out.voltage[i].push(v);
        }
        self.next += 1;
    }
}

impl Observer for Sampler<'_> {
    fn step(
        &mut self,
        period: u32,
        _start: f64,
        end: f64,
        positions_at: &dyn Fn(f64) -> Positions,
    ) {
        let first = period as u64 * self.per;
        while self.next < self.total {
            // Local time of the next sample within this period; the sample
            // at the period's end (j = per) lands exactly on the step end.
            let j = self.next.saturating_sub(first);
            let local = j as f64 / self.per as f64 * self.period;
            if local > end {
                break;
            }
            let (x_p, x_s) = positions_at(local);
            self.push(x_p, x_s);
        }
    }
}

/// Integrates `inst` with its law's f64 CPU integrator and samples its motion
/// `samples_per_cycle` times per scene period, from t = 0 to the end of the
/// run (or to where it stopped, when it ended with a non-zero status).
pub fn record(inst: &Instance, settings: &Settings, samples_per_cycle: u32) -> Trajectory {
    let per = samples_per_cycle.max(1) as u64;
    let total = inst.cycles as u64 * per + 1;
    let capacity = total.min(1 << 24) as usize;
    let series = || std::array::from_fn(|_| Vec::with_capacity(capacity));
    let mut sampler = Sampler {
        inst,
        drives: inst.axes.map(|a| axis_corners(&a)),
        period: inst.period(),
        per,
        next: 0,
        total,
        out: Series {
            time: Vec::with_capacity(capacity),
            stage: series(),
            slider: series(),
            voltage: series(),
        },
    };
    // Every law's run starts at rest at the origin (docs/model.md).
    sampler.push([0.0; AXES], [0.0; AXES]);
    let state = Law::run_observed(inst, settings, &mut sampler);
    let Series {
        time,
        stage,
        slider,
        voltage,
    } = sampler.out;
    Trajectory {
        time,
        stage,
        slider,
        voltage,
        state,
        samples_per_cycle: per as u32,
    }
}

/// A 1-DOF run beside a recorded point: one axis driven alone.
#[derive(Clone, Debug)]
pub struct Baseline {
    /// The instance recorded: the map's baseline instance with its cycles
    /// raised, when its period is shorter than the point's, so that it
    /// covers the point's whole run. Its first `measured_cycles` periods are
    /// the map's baseline run itself (the integration does not depend on
    /// how many periods follow).
    pub instance: Instance,
    /// The cycles of the map's baseline run.
    pub measured_cycles: u32,
    pub trajectory: Trajectory,
}

/// One recorded point of a scene: the instance and, with baselines, its two
/// 1-DOF runs (x driven alone, y driven alone).
#[derive(Clone, Debug)]
pub struct Recorded {
    pub point: TrajectoryPoint,
    pub instance: Instance,
    pub main: Trajectory,
    pub baselines: Option<[Baseline; AXES]>,
}

/// The baseline of `instance` with only axis `axis` driven, extended to
/// cover the instance's run.
pub fn baseline_instance(instance: &Instance, axis: usize) -> (Instance, u32) {
    let mut base = instance.baseline(axis);
    let measured = base.cycles;
    let cover = (instance.duration() / base.period() - 1e-9).ceil();
    if cover.is_finite() && cover > measured as f64 && cover < u32::MAX as f64 {
        base.cycles = cover as u32;
    }
    (base, measured)
}

/// Records every trajectory a scene asks for, in parallel.
pub fn record_scene(scene: &Scene) -> Vec<Recorded> {
    let per = scene.trajectory_samples_per_cycle;
    scene
        .trajectories
        .par_iter()
        .map(|point| {
            let instance = scene.instance(point.index);
            let main = record(&instance, &scene.settings, per);
            let baselines = scene.baselines.then(|| {
                std::array::from_fn(|axis| {
                    let (base, measured_cycles) = baseline_instance(&instance, axis);
                    // The same density in time as the point's samples.
                    let base_per = (per as f64 * base.period() / instance.period())
                        .round()
                        .max(1.0) as u32;
                    let trajectory = if base == instance {
                        main.clone()
                    } else {
                        record(&base, &scene.settings, base_per)
                    };
                    Baseline {
                        instance: base,
                        measured_cycles,
                        trajectory,
                    }
                })
            });
            Recorded {
                point: point.clone(),
                instance,
                main,
                baselines,
            }
        })
        .collect()
}

/// Writes one series of a trajectory group, attached to the group's `time`
/// scale (so netCDF readers such as xarray see `time` as its dimension).
fn series(
    group: &hdf5::Group,
    time: &hdf5::Dataset,
    name: &str,
    data: &[f64],
    units: &str,
    long_name: &str,
) -> Result<()> {
    let ds = dataset(group, name, data, units, long_name)?;
    dimension_scales::attach(&ds, time, 0)
}

/// A dataset of `data` with its units and long name.
fn dataset(
    group: &hdf5::Group,
    name: &str,
    data: &[f64],
    units: &str,
    long_name: &str,
) -> Result<hdf5::Dataset> {
    let ds = group
        .new_dataset_builder()
        .with_data(data)
        .create(name)
        .with_context(|| format!("cannot write trajectory dataset {name}"))?;
    write_str_attr(&ds, schema::UNITS, units)?;
    write_str_attr(&ds, schema::LONG_NAME, long_name)?;
    Ok(ds)
}

/// The attributes every trajectory group carries: run timing, status and
/// drive per axis; and its `time`, a dimension scale the group's series are
/// attached to (returned).
fn run_attrs(g: &hdf5::Group, inst: &Instance, t: &Trajectory) -> Result<hdf5::Dataset> {
    write_u64_attr(g, schema::RUN_STATUS, t.state.status as u64)?;
    write_u64_attr(g, "samples_per_cycle", t.samples_per_cycle as u64)?;
    write_f64_attr(g, schema::PERIOD_S, inst.period())?;
    write_f64_attr(g, schema::SETTLE_S, inst.settle as f64 * inst.period())?;
    write_f64_attr(g, schema::DURATION_S, inst.duration())?;
    for (i, name) in AXIS_NAMES.iter().enumerate() {
        let axis = &inst.axes[i];
        let attr = |what: &str| format!("{what}_{name}");
        write_f64_attr(g, &attr(schema::VOLTAGE), axis.voltage)?;
        write_f64_attr(g, &attr(schema::FREQUENCY), axis.frequency)?;
        write_f64_attr(g, &attr(schema::DUTY), axis.duty)?;
        write_f64_attr(g, &attr(schema::PHASE), axis.phase)?;
        write_str_attr(g, &attr(schema::DRIVE), &crate::scene::drive_words(axis))?;
    }
    let time = dataset(
        g,
        schema::TIME,
        &t.time,
        "s",
        "time from the start of the run",
    )?;
    dimension_scales::set_scale(&time, schema::TIME)?;
    Ok(time)
}

/// Writes `recorded` as `/trajectories/0`, `/1`, ... under `parent` (the
/// result file's root). Writes nothing when the list is empty.
pub fn write(parent: &hdf5::Group, recorded: &[Recorded]) -> Result<()> {
    if recorded.is_empty() {
        return Ok(());
    }
    let root = parent.create_group(schema::TRAJECTORIES)?;
    for (k, rec) in recorded.iter().enumerate() {
        let g = root.create_group(&k.to_string())?;
        let main = &rec.main;
        write_str_attr(&g, schema::POINT, &rec.point.name)?;
        write_str_attr(&g, schema::LABEL, &rec.point.label)?;
        write_u64_attr(&g, schema::INDEX, rec.point.index)?;
        let time = run_attrs(&g, &rec.instance, main)?;
        for (i, name) in AXIS_NAMES.iter().enumerate() {
            series(
                &g,
                &time,
                schema::STAGE[i],
                &main.stage[i],
                "m",
                &format!("stage displacement along {name}"),
            )?;
            series(
                &g,
                &time,
                schema::SLIDER[i],
                &main.slider[i],
                "m",
                &format!("slider displacement along {name}"),
            )?;
            series(
                &g,
                &time,
                &format!("voltage_{name}"),
                &main.voltage[i],
                "V",
                &format!("drive voltage of axis {name}"),
            )?;
        }
        let Some(bases) = &rec.baselines else {
            continue;
        };
        for (i, name) in AXIS_NAMES.iter().enumerate() {
            let base = &bases[i];
            let b = g.create_group(schema::BASELINE_RUN[i])?;
            write_str_attr(
                &b,
                "description",
                &format!(
                    "1-DOF run: axis {name} driven alone; its first measured_cycles periods are \
                     the map's baseline run"
                ),
            )?;
            let time = run_attrs(&b, &base.instance, &base.trajectory)?;
            write_u64_attr(&b, schema::MEASURED_CYCLES, base.measured_cycles as u64)?;
            let t = &base.trajectory;
            series(
                &b,
                &time,
                schema::BASELINE_STAGE,
                &t.stage[i],
                "m",
                &format!("1-DOF stage displacement along {name}"),
            )?;
            series(
                &b,
                &time,
                schema::BASELINE_SLIDER,
                &t.slider[i],
                "m",
                &format!("1-DOF slider displacement along {name}"),
            )?;
            series(
                &b,
                &time,
                "voltage",
                &t.voltage[i],
                "V",
                &format!("drive voltage of axis {name}"),
            )?;
        }
    }
    Ok(())
}

/// Records a scene's trajectories and writes them under `parent`; a no-op
/// for a scene without `output.trajectories`.
pub fn record_and_write(parent: &hdf5::Group, scene: &Scene) -> Result<()> {
    if scene.trajectories.is_empty() {
        return Ok(());
    }
    write(parent, &record_scene(scene))
}

/// The slider displacement over periods `settle .. cycles` [m] from a
/// trajectory's samples: the sample at the end of period `cycles` minus the
/// sample at the end of the settle periods. `None` when the run did not
/// finish or has fewer periods.
pub fn measured_displacement(t: &Trajectory, settle: u32, cycles: u32) -> Option<[f64; AXES]> {
    let per = t.samples_per_cycle as usize;
    let end = cycles as usize * per;
    let start = settle as usize * per;
    if t.state.status != crate::laws::status::STATUS_OK || t.time.len() <= end {
        return None;
    }
    Some(std::array::from_fn(|i| {
        t.slider[i][end] - t.slider[i][start]
    }))
}
