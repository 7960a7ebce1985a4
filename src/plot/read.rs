//! Reading a result file into [`Data`], checked whole before any picture
//! is drawn: the maps, their status, the baselines, the axes or labels and
//! the trajectories must exist with the right type, and every shape must
//! agree with the others, so drawing never indexes past the end of a list.
//!
//! Every number drawn must be finite and within ±1e100 ([`PLAUSIBLE`]), so
//! that nothing derived from it overflows. Coordinates (axis values, sample
//! times, run attributes) beyond that are an error. Values (steps,
//! displacements) can be so only where a run failed: such a step with
//! status 0 is drawn as not computed, and a trajectory with such samples
//! is left out, each with a note.
//!
//! [`PLAUSIBLE`]: super::checked::PLAUSIBLE

use std::path::Path;

use super::checked::{Array, Checked, ResultFile, is_plausible, join};
use super::error::{Problem, ResultFileError};
use super::read_trajectories::{TrajectoryData, read_trajectories};
use crate::model::Measure;
use crate::model::motion::Motion;
use crate::output::schema;
use crate::scene::{Layout, Scene};

/// The status given to instances whose step is not finite although their
/// status is 0; like every non-zero status, it is drawn as not computed.
const NOT_FINITE: u32 = u32::MAX;

/// One grid axis as stored in `/axes`.
#[derive(Clone, Debug)]
pub(super) struct AxisData {
    pub(super) key: String,
    pub(super) units: String,
    pub(super) values: Vec<f64>,
}

/// What kind of instances the file holds.
pub(super) enum Kind {
    /// A grid, its axes in grid order (none for a single instance).
    Grid(Vec<AxisData>),
    /// A points scene, one label per point.
    Points(Vec<String>),
}

/// Everything `pidm plot` reads.
pub(super) struct Data {
    pub(super) name: String,
    pub(super) kind: Kind,
    /// The shape of the maps: the grid's, `[points]` for a points scene,
    /// `[]` for a single instance.
    pub(super) shape: Vec<usize>,
    /// Steps per axis [m per own drive cycle], row-major.
    pub(super) step: [Vec<f64>; 2],
    pub(super) status: Vec<u32>,
    /// The 1-DOF steps per axis and their status, when stored.
    pub(super) baseline: Option<([Vec<f64>; 2], Vec<u32>)>,
    /// The standard errors of the steps per axis [m per own drive cycle],
    /// when stored (files of the steady measurement).
    pub(super) step_se: Option<[Vec<f64>; 2]>,
    /// The backward ratios per axis (`[output] backward`), when stored.
    pub(super) backward_ratio: Option<[Vec<f64>; 2]>,
    /// 1 where a refined map's value was interpolated (`/maps/inferred`),
    /// when stored.
    pub(super) inferred: Option<Vec<u32>>,
    /// The kind of motion per instance (`/maps/motion`), when stored (files
    /// written before it existed have none).
    pub(super) motion: Option<Vec<Motion>>,
    pub(super) trajectories: Vec<TrajectoryData>,
    /// Things the reader should know (guessed axis order, values left out).
    pub(super) notes: Vec<String>,
    /// The drive parameters that no grid axis changes, for map titles
    /// ("fixed: x 100 V, 10 Hz, ..."), when the scene parses.
    pub(super) fixed: Option<String>,
    /// The stall maps of a scene with `[stall]`, when stored.
    pub(super) stall: Option<StallData>,
    /// The file's scene, when it parses.
    pub(super) scene: Option<Scene>,
}

/// The stall maps of one axis (`crate::stall`), row-major like the maps.
pub(super) struct StallData {
    /// The stalled axis (0 = x).
    pub(super) axis: usize,
    /// The stall load [N].
    pub(super) load: Vec<f64>,
    /// The stall search's status (0 found, 6 with a probe not steady, 8 no
    /// stall load, 1-5 a probe failed).
    pub(super) status: Vec<u32>,
}

impl Data {
    /// Reads and checks the result file at `path`.
    pub(super) fn read(path: &Path) -> Checked<Data> {
        let file = ResultFile::open(path)?;
        let root = file.root();
        if file.has_attr(root, schema::SHARD_INDEX) {
            return Err(ResultFileError::Shard {
                file: path.to_path_buf(),
            });
        }
        let mut notes = Vec::new();
        let stem = path
            .file_stem()
            .map_or_else(|| "result".to_owned(), |s| s.to_string_lossy().into_owned());
        let name = file.text_attr(root, "", schema::NAME)?.unwrap_or(stem);
        // A scene that no longer parses (written by another version) only
        // loses the grid order, which is then guessed with a note.
        let scene = file
            .text_attr(root, "", schema::SCENE)?
            .and_then(|text| Scene::from_toml(&text, Some(&name)).ok());
        if !file.exists(schema::MAPS) {
            return Err(file.error(
                format!("group /{}", schema::MAPS),
                Problem::Invalid("is missing: not a pidm result file".to_owned()),
            ));
        }
        file.group(schema::MAPS)?;
        let (step, status) = read_maps(&file, schema::STEP, schema::STATUS, None, &mut notes)?;
        let shape = step[0].shape.clone();
        let baseline = read_baseline(&file, &shape, &mut notes)?;
        let step_se = read_step_se(&file, &shape)?;
        let backward_ratio = read_backward_ratio(&file, &shape)?;
        let inferred = read_inferred(&file, &shape)?;
        let motion = read_motion(&file, &shape)?;
        note_no_verdict(motion.as_deref(), scene.as_ref(), &mut notes);
        let kind = read_kind(&file, &shape, scene.as_ref(), &mut notes)?;
        let trajectories = read_trajectories(&file)?;
        let fixed = scene.as_ref().and_then(super::maps::fixed_drive);
        let stall = read_stall(&file, &shape)?;
        Ok(Data {
            name,
            kind,
            shape,
            step: step.map(|a| a.values),
            status,
            baseline,
            step_se,
            backward_ratio,
            inferred,
            motion,
            trajectories,
            notes,
            fixed,
            stall,
            scene,
        })
    }
}

/// The 1-DOF steps per axis [m per own drive cycle] and their status.
type BaselineMaps = ([Vec<f64>; 2], Vec<u32>);

/// Reads the 1-DOF baselines' steps and status when the file has them,
/// shaped `shape` like the 2-DOF maps.
fn read_baseline(
    file: &ResultFile,
    shape: &[usize],
    notes: &mut Vec<String>,
) -> Checked<Option<BaselineMaps>> {
    if !file.exists(schema::BASELINE) {
        return Ok(None);
    }
    file.group(schema::BASELINE)?;
    let (b, s) = read_maps(
        file,
        schema::BASELINE_STEP,
        schema::BASELINE_STATUS,
        Some(shape),
        notes,
    )?;
    Ok(Some((b.map(|a| a.values), s)))
}

/// Reads the standard errors of the steps per axis [m per own drive
/// cycle] when the file has both, shaped `shape`, each finite and >= 0.
fn read_step_se(file: &ResultFile, shape: &[usize]) -> Checked<Option<[Vec<f64>; 2]>> {
    let paths = schema::STEP_SE.map(String::from);
    let rule = "a standard error is finite and >= 0";
    read_pair(file, &paths, shape, &|v| v.is_finite() && v >= 0.0, rule)
}

/// Reads the backward ratios per axis (`[output] backward`) when the file
/// has both, shaped `shape`, each in [0, 1].
fn read_backward_ratio(file: &ResultFile, shape: &[usize]) -> Checked<Option<[Vec<f64>; 2]>> {
    let paths = [0, 1].map(|axis| schema::backward_path(axis, 2));
    let rule = "a backward ratio is in [0, 1]";
    read_pair(file, &paths, shape, &|v| (0.0..=1.0).contains(&v), rule)
}

/// Reads one f64 map per axis at `paths` when the file has both, shaped
/// `shape`, each value passing `valid` (else an error naming the dataset,
/// the value and the `rule`).
fn read_pair(
    file: &ResultFile,
    paths: &[String; 2],
    shape: &[usize],
    valid: &dyn Fn(f64) -> bool,
    rule: &str,
) -> Checked<Option<[Vec<f64>; 2]>> {
    if !paths.iter().all(|path| file.exists(path)) {
        return Ok(None);
    }
    let mut read = Vec::new();
    for path in paths {
        let map = file.floats(path)?;
        file.expect_shape(&map, shape, format!("the shape of /{}", schema::STEP[0]))?;
        if let Some(v) = map.values.iter().find(|v| !valid(**v)) {
            return Err(file.dataset_error(path, Problem::Invalid(format!("holds {v}: {rule}"))));
        }
        read.push(map.values);
    }
    let y = read.pop().expect("two axes");
    let x = read.pop().expect("two axes");
    Ok(Some([x, y]))
}

/// Reads `/maps/inferred` when the file has it: 0 or 1 per instance,
/// shaped `shape`.
fn read_inferred(file: &ResultFile, shape: &[usize]) -> Checked<Option<Vec<u32>>> {
    if !file.exists(schema::INFERRED) {
        return Ok(None);
    }
    let mask = file.integers(schema::INFERRED)?;
    file.expect_shape(&mask, shape, format!("the shape of /{}", schema::STEP[0]))?;
    if let Some(v) = mask.values.iter().find(|v| **v > 1) {
        return Err(file.dataset_error(
            schema::INFERRED,
            Problem::Invalid(format!("holds {v}: expected 0 or 1")),
        ));
    }
    Ok(Some(mask.values))
}

/// Adds a note when a steady measurement's `motion` is undetermined for
/// every instance: no picture of the kinds of motion is drawn then.
fn note_no_verdict(motion: Option<&[Motion]>, scene: Option<&Scene>, notes: &mut Vec<String>) {
    if motion.is_some_and(|m| m.iter().all(|&k| k == Motion::Undetermined))
        && scene.is_some_and(|s| matches!(s.instance(0).measure, Measure::Steady { .. }))
    {
        notes.push(format!(
            "every instance's /{} is {}: the steady measurement reached no verdict \
             (see /{}); no picture of the kinds of motion is drawn",
            schema::MOTION,
            Motion::Undetermined.name(),
            schema::STATUS
        ));
    }
}

/// What kind of instances the file holds: a points scene's labels (one
/// per instance, shaped `shape`) when the scene is one or the file has
/// labels, else the grid axes in grid order.
fn read_kind(
    file: &ResultFile,
    shape: &[usize],
    scene: Option<&Scene>,
    notes: &mut Vec<String>,
) -> Checked<Kind> {
    let points = matches!(
        scene,
        Some(Scene {
            layout: Layout::Points { .. },
            ..
        })
    );
    if points || file.exists(schema::LABELS) {
        let labels = file.texts(schema::LABELS)?;
        file.expect_shape(
            &labels,
            shape,
            format!("one label per instance: the shape of /{}", schema::STEP[0]),
        )?;
        Ok(Kind::Points(labels.values))
    } else {
        Ok(Kind::Grid(read_axes(file, shape, scene, notes)?))
    }
}

/// Reads the stall maps when the file has them (`/maps/stall_load_x` or
/// `_y`): the load, finite and within ±1e100, and the status, each a known
/// code, both shaped like the maps; a value only where the status keeps
/// one.
fn read_stall(file: &ResultFile, shape: &[usize]) -> Checked<Option<StallData>> {
    let Some(axis) = (0..2).find(|&a| file.exists(&schema::stall_path(a, 0))) else {
        return Ok(None);
    };
    let (load_path, status_path) = (schema::stall_path(axis, 0), schema::stall_path(axis, 4));
    let reason = || format!("the shape of /{}", schema::STEP[0]);
    let load = file.floats(&load_path)?;
    file.expect_shape(&load, shape, reason())?;
    file.expect_plausible(&load, "a stall load is a force below the kinetic friction")?;
    let status = file.integers(&status_path)?;
    file.expect_shape(&status, shape, reason())?;
    if let Some(v) = status
        .values
        .iter()
        .find(|&&v| crate::measurement::status::Status::from_code(v).is_none())
    {
        return Err(file.dataset_error(
            &status_path,
            Problem::Invalid(format!("holds {v}, which is no status code")),
        ));
    }
    Ok(Some(StallData {
        axis,
        load: load.values,
        status: status.values,
    }))
}

impl Data {
    /// The kinds of motion to draw: `/maps/motion` when the file has it
    /// and some instance has a kind (a window measurement has none, so its
    /// pictures are those of files without the map).
    pub(super) fn motion_shown(&self) -> Option<&[Motion]> {
        self.motion
            .as_deref()
            .filter(|m| m.iter().any(|&k| k != Motion::Undetermined))
    }
}

/// Reads `/maps/motion` when the file has it: integer codes shaped like
/// the maps, each one of [`Motion`]'s.
fn read_motion(file: &ResultFile, shape: &[usize]) -> Checked<Option<Vec<Motion>>> {
    if !file.exists(schema::MOTION) {
        return Ok(None);
    }
    let codes = file.integers(schema::MOTION)?;
    file.expect_shape(&codes, shape, format!("the shape of /{}", schema::STEP[0]))?;
    let kinds = codes
        .values
        .iter()
        .map(|&v| {
            u8::try_from(v)
                .ok()
                .and_then(Motion::from_code)
                .ok_or_else(|| {
                    file.dataset_error(
                        schema::MOTION,
                        Problem::Invalid(format!(
                            "holds {v}: expected one of the motion codes {:?} ({})",
                            Motion::flag_values(),
                            Motion::flag_meanings()
                        )),
                    )
                })
        })
        .collect::<Checked<_>>()?;
    Ok(Some(kinds))
}

/// Reads the step maps `step` and the status map `status`, checks that
/// they share one shape (`shape`, when given: that of the 2-DOF maps) with
/// no empty dimension, and marks non-finite steps with status 0 as not
/// computed.
fn read_maps(
    file: &ResultFile,
    step: [&str; 2],
    status: &str,
    shape: Option<&[usize]>,
    notes: &mut Vec<String>,
) -> Checked<([Array<f64>; 2], Vec<u32>)> {
    let x = file.floats(step[0])?;
    let (shape, reason) = match shape {
        Some(shape) => (shape.to_vec(), format!("the shape of /{}", schema::STEP[0])),
        None => (x.shape.clone(), format!("the shape of /{}", step[0])),
    };
    file.expect_shape(&x, &shape, &reason)?;
    if let Some(d) = shape.iter().position(|&n| n == 0) {
        return Err(file.dataset_error(
            step[0],
            Problem::Invalid(format!(
                "has shape {shape:?}: dimension {d} is empty, so there is nothing to draw"
            )),
        ));
    }
    let y = file.floats(step[1])?;
    file.expect_shape(&y, &shape, &reason)?;
    let status_map = file.integers(status)?;
    file.expect_shape(&status_map, &shape, &reason)?;
    let mut status_values = status_map.values;
    let mut marked = 0;
    for (k, s) in status_values.iter_mut().enumerate() {
        if *s == 0 && !(is_plausible(x.values[k]) && is_plausible(y.values[k])) {
            *s = NOT_FINITE;
            marked += 1;
        }
    }
    if marked > 0 {
        notes.push(format!(
            "{marked} instances have status 0 in /{status} but a value in /{} or /{} that is not \
             finite or beyond ±1e100; they are drawn as not computed",
            step[0], step[1]
        ));
    }
    Ok(([x, y], status_values))
}

/// Reads the 1-D, finite axis dataset `/axes/<key>` and its unit.
fn read_axis(file: &ResultFile, key: &str) -> Checked<AxisData> {
    let path = join(schema::AXES, key);
    let values = file.floats(&path)?;
    file.expect_list(&values)?;
    file.expect_plausible(&values, "axis values place the cells on the page")?;
    let units = match file.root().dataset(&path) {
        Ok(ds) => file.text_attr(&ds, &path, schema::UNITS)?,
        Err(_) => None,
    };
    Ok(AxisData {
        key: key.to_owned(),
        units: units.unwrap_or_else(|| "1".to_owned()),
        values: values.values,
    })
}

/// The grid axes in grid order. HDF5 lists `/axes` alphabetically, so the
/// order comes from the stored scene when it parses, and then every axis it
/// names must be stored with the length of its dimension of the maps;
/// otherwise each dimension takes the first unused axis of its length, or
/// its indices when there is none.
fn read_axes(
    file: &ResultFile,
    shape: &[usize],
    scene: Option<&Scene>,
    notes: &mut Vec<String>,
) -> Checked<Vec<AxisData>> {
    if let Some(Scene {
        layout: Layout::Grid { axes },
        ..
    }) = scene
    {
        let out: Vec<AxisData> = axes
            .iter()
            .map(|a| read_axis(file, &a.key))
            .collect::<Checked<_>>()?;
        let lengths: Vec<usize> = out.iter().map(|a| a.values.len()).collect();
        if lengths != shape {
            let names: Vec<String> = out
                .iter()
                .map(|a| format!("/{}", join(schema::AXES, &a.key)))
                .collect();
            return Err(file.dataset_error(
                schema::STEP[0],
                Problem::WrongShape {
                    found: shape.to_vec(),
                    expected: lengths,
                    reason: format!(
                        "the lengths of the stored scene's grid axes {}",
                        if names.is_empty() {
                            "(none: a single instance)".to_owned()
                        } else {
                            names.join(", ")
                        }
                    ),
                },
            ));
        }
        return Ok(out);
    }
    let names = if file.exists(schema::AXES) {
        file.members(schema::AXES)?
    } else {
        Vec::new()
    };
    let mut all: Vec<AxisData> = names
        .iter()
        .map(|n| read_axis(file, n))
        .collect::<Checked<_>>()?;
    let mut out = Vec::with_capacity(shape.len());
    for (d, &n) in shape.iter().enumerate() {
        match all.iter().position(|a| a.values.len() == n) {
            Some(i) => out.push(all.remove(i)),
            None => out.push(AxisData {
                key: format!("dimension {d}"),
                units: "1".to_owned(),
                values: (0..n).map(|v| v as f64).collect(),
            }),
        }
    }
    if !shape.is_empty() {
        notes.push(
            "the stored scene did not give the grid order; axes were matched to dimensions \
             by length"
                .to_owned(),
        );
    }
    Ok(out)
}
