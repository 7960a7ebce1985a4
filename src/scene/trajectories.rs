//! `[output] trajectories`: the instances whose motion is recorded over
//! time (stored under `/trajectories/` by `crate::trajectory`).
//!
//! Each entry names one instance of the scene in one of three ways:
//!
//! - a string: the `label` of a `[[points]]` entry (points scenes only; the
//!   label must name exactly one point);
//! - an integer: the flat instance index, row-major over the grid axes with
//!   the last axis fastest (the point index in a points scene), from 0;
//! - a table of grid coordinates (grid scenes only): every grid axis' full
//!   key with one of its values, e.g.
//!   `{ "axis.x.voltage" = 100.0, "axis.y.voltage" = -50.0 }` (dotted keys
//!   without quotes, `{ axis.x.voltage = 100.0, ... }`, mean the same).
//!   A value matches a grid value within 1e-9 of the axis' largest
//!   magnitude.
//!
//! `trajectory_samples_per_cycle` sets how densely each trajectory is
//! sampled in time.

use toml::de::{DeTable, DeValue};

use super::describe::describe_values;
use super::format::{fmt_num, fmt_short};
use super::parser::{Parser, Value, join};
use super::{GridAxis, Layout, Scene, SceneError};
use crate::model::Measure;

/// Default samples per scene period of a recorded trajectory. At Table 1's
/// 10 Hz drive and 3.2 kHz stage resonance, 2000 samples per 0.1 s period
/// are one every 50 us: about 40 across the 2 ms fast fall of the sawtooth
/// (duty 0.98) and 6 per period of the stage's ringing, enough to draw the
/// curves of the paper's Figs. 5-8 over whole runs; raise it to resolve
/// faster motion.
pub const DEFAULT_SAMPLES_PER_CYCLE: u32 = 2000;

/// Largest number of samples one trajectory may hold (samples per cycle
/// times cycles). A sample takes 56 bytes in memory per recorded run (time,
/// and stage, slider and voltage per axis), and with baselines a point is
/// recorded three times, so this caps one trajectory at about 340 MB while
/// it is recorded.
pub const MAX_TRAJECTORY_SAMPLES: u64 = 2_000_000;

/// Largest accepted `trajectory_samples_per_cycle`.
const MAX_SAMPLES_PER_CYCLE: u32 = 1_000_000;

/// One instance whose motion is recorded over time.
#[derive(Clone, Debug, PartialEq)]
pub struct TrajectoryPoint {
    /// Flat row-major instance index (the point index in a points scene).
    pub index: u64,
    /// The point's label, or "" in a grid scene or for an unlabelled point.
    pub label: String,
    /// A human name: the label, or "instance 17 (axis.x.voltage = 100 V,
    /// ...)" in a grid scene, or "point 3" for an unlabelled point.
    pub name: String,
}

/// An entry of `output.trajectories` as written, before the layout is known.
#[derive(Clone, Debug)]
pub(super) enum Spec {
    Label(String),
    Index(i128),
    /// Full dotted key paths and values, in the order given.
    Coordinates(Vec<(String, f64)>),
}

/// An entry and where it is in the text.
#[derive(Clone, Debug)]
pub(super) struct SpecAt {
    spec: Spec,
    span: std::ops::Range<usize>,
    /// The entry as written, for messages.
    source: String,
}

/// What an entry may be, for messages.
const ENTRY_KINDS: &str = "a point label (string), a flat instance index (integer >= 0) or a \
     table of grid coordinates ({ \"axis.x.voltage\" = 100.0, ... })";

impl Parser<'_> {
    /// `output.trajectories`: a list of entries.
    pub(super) fn trajectories(&self, value: &Value<'_>) -> Result<Vec<SpecAt>, SceneError> {
        let DeValue::Array(items) = value.get_ref() else {
            return Err(self.wrong_type(
                "output.trajectories",
                &format!("expected a list, each entry {ENTRY_KINDS}"),
                value,
            ));
        };
        let mut specs = Vec::with_capacity(items.len());
        for (k, item) in items.iter().enumerate() {
            let path = format!("output.trajectories[{k}]");
            let spec = match item.get_ref() {
                DeValue::String(s) => Spec::Label(s.to_string()),
                DeValue::Integer(i) => {
                    let n = i128::from_str_radix(i.as_str(), i.radix()).unwrap_or(-1);
                    Spec::Index(n)
                }
                DeValue::Table(table) => {
                    let mut coordinates = Vec::new();
                    self.flatten_coordinates(&path, "", table, &mut coordinates)?;
                    Spec::Coordinates(coordinates)
                }
                _ => {
                    return Err(self.wrong_type(&path, &format!("expected {ENTRY_KINDS}"), item));
                }
            };
            specs.push(SpecAt {
                spec,
                span: item.span(),
                source: self.source(item.span()),
            });
        }
        Ok(specs)
    }

    /// Collects `{ axis = { x = { voltage = 1 } } }` and
    /// `{ "axis.x.voltage" = 1 }` alike as ("axis.x.voltage", 1).
    fn flatten_coordinates(
        &self,
        path: &str,
        prefix: &str,
        table: &DeTable<'_>,
        out: &mut Vec<(String, f64)>,
    ) -> Result<(), SceneError> {
        for (key, value) in table.iter() {
            let name = join(prefix, key.get_ref());
            match value.get_ref() {
                DeValue::Table(inner) => self.flatten_coordinates(path, &name, inner, out)?,
                _ => {
                    let number = self.finite(&format!("{path}.{name}"), value)?;
                    out.push((name, number));
                }
            }
        }
        Ok(())
    }

    /// `output.trajectory_samples_per_cycle`: an integer from 1 to 1e6.
    pub(super) fn samples_per_cycle(&self, value: &Value<'_>) -> Result<u32, SceneError> {
        let path = "output.trajectory_samples_per_cycle";
        let expected = format!("expected an integer from 1 to {MAX_SAMPLES_PER_CYCLE}");
        let DeValue::Integer(_) = value.get_ref() else {
            return Err(self.wrong_type(path, &expected, value));
        };
        let number = Parser::number(value.get_ref()).unwrap_or(f64::NAN);
        if !(number >= 1.0 && number <= MAX_SAMPLES_PER_CYCLE as f64) {
            return Err(self.invalid(
                value.span(),
                format!("{path} = {}: {expected}", fmt_num(number)),
            ));
        }
        Ok(number as u32)
    }

    /// Resolves the entries against the scene's layout and checks the
    /// sample budget of each.
    pub(super) fn resolve_trajectories(
        &self,
        specs: &[SpecAt],
        scene: &Scene,
    ) -> Result<Vec<TrajectoryPoint>, SceneError> {
        let count = scene.instance_count();
        let mut out: Vec<TrajectoryPoint> = Vec::with_capacity(specs.len());
        for (k, at) in specs.iter().enumerate() {
            let path = format!("output.trajectories[{k}] = {}", at.source);
            let fail =
                |message: String| self.invalid(at.span.clone(), format!("{path}: {message}"));
            let index = match (&at.spec, &scene.layout) {
                (Spec::Label(label), Layout::Points { labels }) => {
                    label_index(label, labels).map_err(&fail)?
                }
                (Spec::Label(_), Layout::Grid { .. }) => {
                    return Err(fail(
                        "a grid scene has no point labels; expected a flat instance index or a \
                         table of grid coordinates"
                            .to_owned(),
                    ));
                }
                (Spec::Index(i), _) => {
                    if *i < 0 || *i >= count as i128 {
                        return Err(fail(format!(
                            "expected an instance index from 0 to {} (the scene has {count} \
                             instances)",
                            count - 1
                        )));
                    }
                    *i as u64
                }
                (Spec::Coordinates(_), Layout::Points { .. }) => {
                    return Err(fail(
                        "a points scene has no grid coordinates; expected a point label or index"
                            .to_owned(),
                    ));
                }
                (Spec::Coordinates(coordinates), Layout::Grid { axes }) => {
                    coordinates_index(coordinates, axes).map_err(&fail)?
                }
            };
            if let Some(previous) = out.iter().position(|t| t.index == index) {
                return Err(fail(format!(
                    "names the same instance as output.trajectories[{previous}]; expected each \
                     instance once"
                )));
            }
            check_samples(scene, index).map_err(&fail)?;
            out.push(trajectory_point(scene, index));
        }
        Ok(out)
    }
}

/// The index of the one point labelled `label`, or why there is none:
/// no point has that label, or several have it.
fn label_index(label: &str, labels: &[String]) -> Result<u64, String> {
    let hits: Vec<usize> = labels
        .iter()
        .enumerate()
        .filter(|(_, l)| *l == label)
        .map(|(i, _)| i)
        .collect();
    match hits.as_slice() {
        [i] => Ok(*i as u64),
        [] => {
            let known: Vec<String> = labels
                .iter()
                .filter(|l| !l.is_empty())
                .map(|l| format!("{l:?}"))
                .collect();
            Err(if known.is_empty() {
                "expected the label of a point, but no point has a label; \
                 give the point's index instead"
                    .to_owned()
            } else {
                format!("expected the label of a point: {}", known.join(", "))
            })
        }
        many => Err(format!(
            "the label names {} points (indices {:?}); expected exactly one: \
             give the index instead",
            many.len(),
            many
        )),
    }
}

/// The flat row-major index of the grid point at `coordinates`, or why
/// there is none: an axis without a value, a value not on its axis, or a
/// key that is no grid axis.
fn coordinates_index(coordinates: &[(String, f64)], axes: &[GridAxis]) -> Result<u64, String> {
    let mut index = 0u64;
    for axis in axes {
        let Some(&(_, value)) = coordinates.iter().find(|(key, _)| *key == axis.key) else {
            return Err(format!(
                "expected a value for every grid axis, but `{}` is missing",
                axis.key
            ));
        };
        let scale = axis.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let Some(i) = axis
            .values
            .iter()
            .position(|v| (v - value).abs() <= 1e-9 * scale)
        else {
            return Err(format!(
                "{} = {}: expected one of the axis' values, {}",
                axis.key,
                fmt_num(value),
                describe_values(&axis.values, axis.units)
            ));
        };
        index = index * axis.values.len() as u64 + i as u64;
    }
    if let Some((key, _)) = coordinates
        .iter()
        .find(|(key, _)| !axes.iter().any(|a| a.key == *key))
    {
        let keys: Vec<&str> = axes.iter().map(|a| a.key.as_str()).collect();
        return Err(format!(
            "`{key}` is not a grid axis; expected the keys {}",
            if keys.is_empty() {
                "of no axis (a single-instance scene: use index 0)".to_owned()
            } else {
                keys.join(", ")
            }
        ));
    }
    Ok(index)
}

/// Checks that instance `index`'s trajectory fits [`MAX_TRAJECTORY_SAMPLES`];
/// a steady run may last its max_cycles, and the bound holds for that.
fn check_samples(scene: &Scene, index: u64) -> Result<(), String> {
    let instance = scene.instance(index);
    let cycles = instance.cycles as u64;
    let samples = cycles * scene.trajectory_samples_per_cycle as u64;
    if samples > MAX_TRAJECTORY_SAMPLES {
        let (why, key) = match instance.measure {
            Measure::Window => ("", "simulation.cycles"),
            Measure::Steady { .. } => (
                " (a steady run may last its simulation.max_cycles periods)",
                "simulation.max_cycles",
            ),
        };
        return Err(format!(
            "{} samples per cycle x {cycles} cycles = {samples} samples{why}: expected \
             at most {MAX_TRAJECTORY_SAMPLES} per trajectory; lower \
             output.trajectory_samples_per_cycle or {key}",
            scene.trajectory_samples_per_cycle
        ));
    }
    Ok(())
}

/// Names instance `index` of a scene.
fn trajectory_point(scene: &Scene, index: u64) -> TrajectoryPoint {
    match &scene.layout {
        Layout::Points { labels } => {
            let label = labels[index as usize].clone();
            let name = if label.is_empty() {
                format!("point {index}")
            } else {
                label.clone()
            };
            TrajectoryPoint { index, label, name }
        }
        Layout::Grid { axes } => {
            let mut rest = index;
            let mut parts = Vec::with_capacity(axes.len());
            for axis in axes.iter().rev() {
                let n = axis.values.len() as u64;
                let value = axis.values[(rest % n) as usize];
                rest /= n;
                let unit = if axis.units == "1" {
                    String::new()
                } else {
                    format!(" {}", axis.units)
                };
                parts.push(format!("{} = {}{unit}", axis.key, fmt_short(value)));
            }
            parts.reverse();
            let name = if parts.is_empty() {
                format!("instance {index}")
            } else {
                format!("instance {index} ({})", parts.join(", "))
            };
            TrajectoryPoint {
                index,
                label: String::new(),
                name,
            }
        }
    }
}
