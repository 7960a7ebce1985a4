//! The parser: reads a TOML document into layers of keys, checking every
//! key, type and value on the way, with errors located in the text. A
//! numeric key's values are read in `numbers.rs`.

use std::ops::Range;

use toml::Spanned;

use crate::laws::settings::Replicas;
use toml::de::{DeTable, DeValue};

use super::error::{Location, SceneError};
use super::format::{fmt_num, fmt_short};
use super::keys::{
    DAMPING, FIT_SCENE, FRICTION_KEY, Field, Law, MAX_REPLICAS, MEASURE_KEY, MECHANISM_FIELDS,
    Mode, OPTIMIZE_SCENE, OUTPUT_KEYS, PHASE, PHASE_UNITS_KEY, POINT_KEYS, QUALITY, REPLICAS_KEY,
    RESONANCE, ROOT_KEYS, SAME_AS_KEY, SENSITIVITY_SCENE, SIMULATION_FIELDS, SIMULATION_KEYS,
    SIMULATION_SLOTS, STAGE_MASS, STIFFNESS, axis_slot, expected_law, slot_field, slot_path,
};
use super::layer::{Layer, PointSpec, Tie};
use super::name::check_name;
use super::refine::RefineSpec;
use super::stall::Stall;
use super::suggest::{home_of, suggest};
use super::trajectories::SpecAt;
use super::values::Entry;
use crate::model::AXIS_NAMES;

/// The key of `layer` that comes first in the text among those whose field
/// `refused` picks, with its slot.
fn first_given(layer: &Layer, refused: impl Fn(Field) -> bool) -> Option<(usize, &Entry)> {
    layer
        .entries
        .iter()
        .enumerate()
        .filter_map(|(slot, entry)| entry.as_ref().map(|e| (slot, e)))
        .filter(|&(slot, _)| refused(slot_field(slot)))
        .min_by_key(|(_, entry)| entry.span.start)
}

/// The document, parsed but not yet checked as a whole.
#[derive(Debug, Default)]
pub(super) struct Parsed {
    /// `name`, already checked to be a plain file name.
    pub(super) name: Option<String>,
    /// `description`.
    pub(super) description: Option<String>,
    /// The keys of the base scene.
    pub(super) base: Layer,
    /// `simulation.measure`, when given (the default is [`Mode::Steady`]).
    pub(super) measure: Option<Mode>,
    /// `mechanism.friction`, when given (the default is Karnopp's), and
    /// where.
    pub(super) friction: Option<(Law, Range<usize>)>,
    /// `simulation.replicas`, when given (the default is
    /// `Replicas::Auto`), and where.
    pub(super) replicas: Option<(Replicas, Range<usize>)>,
    /// `phase_units = "cycles"`: phases beyond one whole cycle are meant.
    pub(super) whole_cycles: bool,
    /// `output.baselines`.
    pub(super) baselines: bool,
    /// `output.backward`: the backward-travel maps.
    pub(super) backward: bool,
    /// `output.trajectories`, not yet resolved against the layout.
    pub(super) trajectories: Vec<SpecAt>,
    /// `output.trajectory_samples_per_cycle`.
    pub(super) samples_per_cycle: Option<u32>,
    /// The `[[points]]`, when given.
    pub(super) points: Option<Vec<PointSpec>>,
    /// `[refine]`, when given.
    pub(super) refine: Option<RefineSpec>,
    /// `[stall]`, when given.
    pub(super) stall: Option<Stall>,
    /// `[random]`, when given.
    pub(super) random: Option<RandomSpec>,
}

/// Whether keys are read for the base scene or for one point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Context {
    /// The base scene: grid axes and scene-wide keys allowed.
    Base,
    /// One `[[points]]` entry: single values of per-instance keys only.
    Point,
}

/// Reads a parsed TOML document into layers, checking every key and value.
pub(super) struct Parser<'t> {
    /// The scene's TOML text, for locations and quoting values.
    pub(super) text: &'t str,
}

/// A TOML value and where it is in the text.
pub(super) type Value<'a> = Spanned<DeValue<'a>>;
/// A TOML key and where it is in the text.
pub(super) type Key<'a> = Spanned<std::borrow::Cow<'a, str>>;

/// `[random]` as read (`random.rs` reads it).
#[derive(Clone, Debug)]
pub(super) struct RandomSpec {
    pub(super) seed: u64,
    pub(super) count: u64,
    /// Where the table is, for errors about the rest of the scene.
    pub(super) span: Range<usize>,
}

impl Parser<'_> {
    /// The line and column of a byte offset.
    pub(super) fn locate(&self, offset: usize) -> Location {
        let before = self.text.get(..offset).unwrap_or(self.text);
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        Location {
            line: before.matches('\n').count() + 1,
            column: before[line_start..].chars().count() + 1,
        }
    }

    /// An [`SceneError::Invalid`] located at `span`.
    pub(super) fn invalid(&self, span: Range<usize>, message: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            message: message.into(),
            location: Some(self.locate(span.start)),
        }
    }

    /// The source text of a value, shortened for messages.
    pub(super) fn source(&self, span: Range<usize>) -> String {
        let text = self.text.get(span).unwrap_or("").trim();
        let text = text.split_whitespace().collect::<Vec<_>>().join(" ");
        if text.chars().count() > 60 {
            let short: String = text.chars().take(57).collect();
            format!("{short}...")
        } else {
            text
        }
    }

    /// Describes a value of the wrong type: "a string \"abc\"".
    pub(super) fn found(&self, value: &Value<'_>) -> String {
        match value.get_ref() {
            DeValue::String(s) => format!("a string {:?}", s.as_ref()),
            DeValue::Integer(_) => format!("an integer {}", self.source(value.span())),
            DeValue::Float(_) => format!("a float {}", self.source(value.span())),
            DeValue::Boolean(b) => format!("a boolean {b}"),
            DeValue::Datetime(d) => format!("a date-time {d}"),
            DeValue::Array(_) => format!("a list {}", self.source(value.span())),
            DeValue::Table(_) => "a table".to_owned(),
        }
    }

    /// A wrong-type error.
    pub(super) fn wrong_type(&self, path: &str, expected: &str, value: &Value<'_>) -> SceneError {
        self.invalid(
            value.span(),
            format!("{path}: {expected}, found {}", self.found(value)),
        )
    }

    /// An unknown-key error, with the closest valid key or the table the key
    /// belongs to.
    pub(super) fn unknown_key(
        &self,
        key: &Key<'_>,
        prefix: &str,
        candidates: &[&str],
    ) -> SceneError {
        let name = key.get_ref().as_ref();
        let path = join(prefix, name);
        let hint = match home_of(name) {
            Some(home) => format!(" (`{name}` belongs in {home})"),
            None => match suggest(name, candidates) {
                Some(best) => format!(" (did you mean `{best}`?)"),
                None => format!(" (expected one of: {})", candidates.join(", ")),
            },
        };
        self.invalid(key.span(), format!("unknown key `{path}`{hint}"))
    }

    /// A table value.
    pub(super) fn table<'v, 'a>(
        &self,
        path: &str,
        expected: &str,
        value: &'v Value<'a>,
    ) -> Result<&'v DeTable<'a>, SceneError> {
        match value.get_ref() {
            DeValue::Table(table) => Ok(table),
            _ => Err(self.wrong_type(path, expected, value)),
        }
    }

    /// A string value.
    pub(super) fn string(&self, path: &str, value: &Value<'_>) -> Result<String, SceneError> {
        match value.get_ref() {
            DeValue::String(s) => Ok(s.to_string()),
            _ => Err(self.wrong_type(path, "expected a string", value)),
        }
    }

    /// The document root.
    pub(super) fn root(&self, table: &DeTable<'_>) -> Result<Parsed, SceneError> {
        let mut parsed = Parsed::default();
        for (key, value) in table.iter() {
            match key.get_ref().as_ref() {
                "name" => {
                    let name = self.string("name", value)?;
                    check_name(&name).map_err(|expected| {
                        self.invalid(value.span(), format!("name = {expected}"))
                    })?;
                    parsed.name = Some(name);
                }
                "description" => parsed.description = Some(self.string("description", value)?),
                PHASE_UNITS_KEY => {
                    let units = self.string(PHASE_UNITS_KEY, value)?;
                    if units != "cycles" {
                        return Err(self.invalid(
                            value.span(),
                            format!(
                                "{PHASE_UNITS_KEY} = {units:?}: expected \"cycles\" (a phase is \
                                 always in cycles of its axis' drive, 1 = one period; write \
                                 degrees / 360, so 90 degrees is 0.25)"
                            ),
                        ));
                    }
                    parsed.whole_cycles = true;
                }
                "mechanism" => {
                    self.mechanism(value, &mut parsed.base, Context::Base, &mut parsed.friction)?
                }
                "axis" => self.axes(value, &mut parsed.base, Context::Base)?,
                "simulation" => self.simulation(
                    value,
                    &mut parsed.base,
                    Context::Base,
                    (&mut parsed.measure, &mut parsed.replicas),
                )?,
                "output" => self.output(value, &mut parsed)?,
                "points" => parsed.points = Some(self.points(value)?),
                "refine" => parsed.refine = Some(self.refine(value)?),
                "stall" => parsed.stall = Some(self.stall(value)?),
                "random" => parsed.random = Some(self.random(value)?),
                "fit" => return Err(self.invalid(key.span(), FIT_SCENE)),
                "optimize" => return Err(self.invalid(key.span(), OPTIMIZE_SCENE)),
                "sensitivity" => return Err(self.invalid(key.span(), SENSITIVITY_SCENE)),
                _ => return Err(self.unknown_key(key, "", &ROOT_KEYS)),
            }
        }
        self.check_stage_keys(&parsed.base)?;
        self.check_ties(&parsed.base)?;
        for (index, point) in parsed.points.iter().flatten().enumerate() {
            self.check_frequency_keys(&point.layer)
                .map_err(|e| e.in_point(index, &point.label))?;
        }
        if !parsed.whole_cycles {
            self.check_phases(&parsed.base)?;
            for (index, point) in parsed.points.iter().flatten().enumerate() {
                self.check_phases(&point.layer)
                    .map_err(|e| e.in_point(index, &point.label))?;
            }
        }
        let mode = parsed.measure.unwrap_or_default();
        self.check_mode_keys(&parsed.base, mode, parsed.measure.is_none())?;
        let law = parsed.friction.as_ref().map(|(law, _)| *law);
        self.check_friction_keys(&parsed.base, law)?;
        for (index, point) in parsed.points.iter().flatten().enumerate() {
            self.check_friction_keys(&point.layer, law)
                .map_err(|e| e.in_point(index, &point.label))?;
        }
        if let Some((_, span)) = &parsed.replicas
            && mode == Mode::Window
        {
            return Err(self.invalid(
                span.clone(),
                "simulation.replicas applies to measure = \"steady\" (replicas split a steady \
                 measurement); a fixed window runs every instance once. This scene sets \
                 measure = \"window\": remove it, or set measure = \"steady\"",
            ));
        }
        for (index, point) in parsed.points.iter().flatten().enumerate() {
            self.check_mode_keys(&point.layer, mode, parsed.measure.is_none())
                .map_err(|e| e.in_point(index, &point.label))?;
        }
        if let Some(stall) = &parsed.stall {
            if let Some(refine) = &parsed.refine {
                return Err(self.invalid(
                    refine.span.clone(),
                    "refine: a scene with [stall] cannot be refined (the refinement chooses \
                     which points to integrate, the stall search needs every instance's step); \
                     expected one of [refine] and [stall]",
                ));
            }
            self.check_stall_load(stall, &parsed.base, "")?;
            for (index, point) in parsed.points.iter().flatten().enumerate() {
                self.check_stall_load(stall, &point.layer, "")
                    .map_err(|e| e.in_point(index, &point.label))?;
            }
        }
        Ok(parsed)
    }

    /// Refuses a phase beyond one whole cycle: a phase is in cycles, so
    /// `phase = 90` is almost surely 90 degrees (0.25 cycles), which would
    /// run as 90 whole periods, the same as 0. One cycle itself is
    /// accepted (the end of a sweep over a whole period). A scene that
    /// means whole cycles says so with `phase_units = "cycles"`.
    pub(super) fn check_phases(&self, layer: &Layer) -> Result<(), SceneError> {
        for (axis, name) in AXIS_NAMES.iter().enumerate() {
            let Some(entry) = &layer.entries[axis_slot(axis, PHASE)] else {
                continue;
            };
            let Some((_, phase)) = entry
                .values
                .extremes()
                .into_iter()
                .find(|&(_, v)| v.abs() > 1.0)
            else {
                continue;
            };
            let cycles = phase / 360.0;
            return Err(self.invalid(
                entry.span.clone(),
                format!(
                    "axis.{name}.phase = {}: a phase is in cycles of the drive (1 = one \
                     period), so this is {} periods, which runs like {}; if it is in \
                     degrees, write {} ({} degrees / 360). To mean whole cycles, set \
                     {PHASE_UNITS_KEY} = \"cycles\" at the top of the scene",
                    fmt_num(phase),
                    fmt_num(phase),
                    fmt_short(phase - phase.floor()),
                    fmt_short(cycles),
                    fmt_num(phase)
                ),
            ));
        }
        Ok(())
    }

    /// Refuses a key of `layer` that applies to the other measurement mode
    /// than the scene's: never silently ignored. `default` says the mode was
    /// not given.
    pub(super) fn check_mode_keys(
        &self,
        layer: &Layer,
        mode: Mode,
        default: bool,
    ) -> Result<(), SceneError> {
        let Some((slot, entry)) =
            first_given(layer, |field| field.mode().is_some_and(|m| m != mode))
        else {
            return Ok(());
        };
        let key_mode = slot_field(slot).mode().unwrap_or(mode);
        let scene = if default {
            format!(
                "This scene measures {:?} (the default, as no simulation.measure is given)",
                mode.name()
            )
        } else {
            format!("This scene sets measure = {:?}", mode.name())
        };
        let todo = match mode {
            Mode::Steady => {
                "set measure = \"window\" for the paper's fixed window of cycles periods"
            }
            Mode::Window => "remove it, or set measure = \"steady\"",
        };
        Err(self.invalid(
            entry.span.clone(),
            format!(
                "{} applies to measure = {:?}; {}. {scene}: {todo}",
                slot_path(slot),
                key_mode.name(),
                mode.instead()
            ),
        ))
    }

    /// Refuses a key of `layer` that applies to the other friction law
    /// than the scene's (`law`, `None` where Karnopp's is the default):
    /// `velocity_band` under LuGre, the bristle keys under Karnopp. Never
    /// silently ignored.
    pub(super) fn check_friction_keys(
        &self,
        layer: &Layer,
        law: Option<Law>,
    ) -> Result<(), SceneError> {
        let scene_law = law.unwrap_or_default();
        let Some((slot, entry)) = first_given(layer, |field| {
            field.friction().is_some_and(|l| l != scene_law)
        }) else {
            return Ok(());
        };
        let key_law = slot_field(slot).friction().expect("filtered on a law");
        let todo = if law.is_none() {
            format!(
                "This scene uses {} friction (the default, as no mechanism.friction is given): \
                 set mechanism.friction = {:?}, or remove the key",
                scene_law.name(),
                key_law.name()
            )
        } else {
            format!(
                "This scene sets friction = {:?}: set it to {:?}, or remove the key",
                scene_law.name(),
                key_law.name()
            )
        };
        Err(self.invalid(
            entry.span.clone(),
            format!(
                "{} applies to mechanism.friction = {:?} only; {}. {todo}",
                slot_path(slot),
                key_law.name(),
                key_law.keys_why(),
            ),
        ))
    }

    /// `[mechanism]`: its numeric keys and `friction`, which only the base
    /// may set.
    pub(super) fn mechanism(
        &self,
        value: &Value<'_>,
        layer: &mut Layer,
        context: Context,
        friction: &mut Option<(Law, Range<usize>)>,
    ) -> Result<(), SceneError> {
        let table = self.table("mechanism", "expected a table", value)?;
        let names: Vec<&str> = MECHANISM_FIELDS
            .iter()
            .map(|f| f.name())
            .chain([FRICTION_KEY])
            .collect();
        for (key, value) in table.iter() {
            if key.get_ref().as_ref() != FRICTION_KEY {
                self.field(
                    key,
                    value,
                    "mechanism",
                    &MECHANISM_FIELDS,
                    &names,
                    0,
                    layer,
                    context,
                )?;
                continue;
            }
            if context == Context::Point {
                return Err(self.invalid(
                    key.span(),
                    "mechanism.friction cannot be set per point: it applies to the whole scene \
                     (set it in the base [mechanism])",
                ));
            }
            let expected = expected_law();
            let DeValue::String(name) = value.get_ref() else {
                return Err(self.wrong_type("mechanism.friction", &expected, value));
            };
            let Some(law) = Law::from_name(name) else {
                return Err(self.invalid(
                    value.span(),
                    format!("mechanism.friction = {:?}: {expected}", name.as_ref()),
                ));
            };
            *friction = Some((law, value.span()));
        }
        Ok(())
    }

    /// `[axis]`: the tables `x` and `y`.
    pub(super) fn axes(
        &self,
        value: &Value<'_>,
        layer: &mut Layer,
        context: Context,
    ) -> Result<(), SceneError> {
        let table = self.table(
            "axis",
            "expected a table of axes ([axis.x], [axis.y])",
            value,
        )?;
        for (key, value) in table.iter() {
            let name = key.get_ref().as_ref();
            let Some(axis) = AXIS_NAMES.iter().position(|&n| n == name) else {
                return Err(self.unknown_key(key, "axis", &AXIS_NAMES));
            };
            self.axis(value, axis, layer, context)?;
        }
        Ok(())
    }

    /// `[simulation]`: its numeric keys, `measure` and `replicas`, which
    /// only the base may set.
    pub(super) fn simulation(
        &self,
        value: &Value<'_>,
        layer: &mut Layer,
        context: Context,
        (measure, replicas): (&mut Option<Mode>, &mut Option<(Replicas, Range<usize>)>),
    ) -> Result<(), SceneError> {
        let table = self.table("simulation", "expected a table", value)?;
        for (key, value) in table.iter() {
            if key.get_ref().as_ref() == REPLICAS_KEY {
                if context == Context::Point {
                    return Err(self.invalid(
                        key.span(),
                        "simulation.replicas cannot be set per point: it applies to the whole \
                         scene (set it in the base [simulation])",
                    ));
                }
                *replicas = Some((self.replicas(value)?, value.span()));
                continue;
            }
            if key.get_ref().as_ref() != MEASURE_KEY {
                self.field(
                    key,
                    value,
                    "simulation",
                    &SIMULATION_FIELDS,
                    &SIMULATION_KEYS,
                    SIMULATION_SLOTS,
                    layer,
                    context,
                )?;
                continue;
            }
            if context == Context::Point {
                return Err(self.invalid(
                    key.span(),
                    "simulation.measure cannot be set per point: it applies to the whole scene \
                     (set it in the base [simulation])",
                ));
            }
            let names: Vec<String> = Mode::ALL
                .iter()
                .map(|mode| format!("{:?}", mode.name()))
                .collect();
            let expected = format!("expected {}", names.join(" or "));
            let DeValue::String(name) = value.get_ref() else {
                return Err(self.wrong_type("simulation.measure", &expected, value));
            };
            let Some(mode) = Mode::from_name(name) else {
                return Err(self.invalid(
                    value.span(),
                    format!(
                        "simulation.measure = {:?}: {expected} (the steady step, the default, \
                         or the paper's fixed window)",
                        name.as_ref()
                    ),
                ));
            };
            *measure = Some(mode);
        }
        Ok(())
    }

    /// `simulation.replicas`: "auto" or a whole number of replicas from 1
    /// to [`MAX_REPLICAS`].
    fn replicas(&self, value: &Value<'_>) -> Result<Replicas, SceneError> {
        let expected = format!(
            "expected \"auto\" (as many replicas as idle threads or lanes allow, the \
             default) or a whole number from 1 (no replicas) to {MAX_REPLICAS}"
        );
        match value.get_ref() {
            DeValue::String(text) if text.as_ref() == "auto" => Ok(Replicas::Auto),
            DeValue::Integer(n) => match n.to_string().parse::<u32>() {
                Ok(n) if (1..=MAX_REPLICAS).contains(&n) => Ok(Replicas::Count(n)),
                _ => Err(self.invalid(
                    value.span(),
                    format!(
                        "simulation.replicas = {}: {expected}",
                        self.source(value.span())
                    ),
                )),
            },
            DeValue::String(text) => Err(self.invalid(
                value.span(),
                format!("simulation.replicas = {:?}: {expected}", text.as_ref()),
            )),
            _ => Err(self.wrong_type("simulation.replicas", &expected, value)),
        }
    }

    /// One numeric key of a table: its values, checked, into `layer`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn field(
        &self,
        key: &Key<'_>,
        value: &Value<'_>,
        path: &str,
        fields: &[Field],
        candidates: &[&str],
        slot_base: usize,
        layer: &mut Layer,
        context: Context,
    ) -> Result<(), SceneError> {
        let name = key.get_ref().as_ref();
        let Some(index) = fields.iter().position(|f| f.name() == name) else {
            return Err(self.unknown_key(key, path, candidates));
        };
        let field = fields[index];
        let key_path = format!("{path}.{name}");
        if field.scene_wide() && context == Context::Point {
            return Err(self.invalid(
                key.span(),
                format!(
                    "{key_path} cannot be set per point: the integrator settings apply to \
                     the whole scene (set them in the base [simulation])"
                ),
            ));
        }
        if field == Field::FrequencyRatio && slot_base == axis_slot(0, 0) {
            return Err(self.invalid(
                key.span(),
                "axis.x.frequency_ratio: only axis.y takes a frequency ratio (axis.y's frequency \
                 is frequency_ratio x axis.x.frequency); give axis.x a frequency",
            ));
        }
        if let DeValue::Table(table) = value.get_ref()
            && table.iter().any(|(k, _)| k.get_ref() == SAME_AS_KEY)
        {
            let slot = slot_base + index;
            let target = self.tie(&key_path, slot, table, value, context)?;
            layer.ties[slot] = Some(Tie {
                target,
                span: value.span(),
            });
            return Ok(());
        }
        let values = self.values(&key_path, field, value)?;
        if values.len() > 1 && (field.scene_wide() || context == Context::Point) {
            let why = if context == Context::Point {
                "a point's values must be single numbers (points give a list of instances, \
                 not a grid)"
            } else {
                "it applies to the whole scene and cannot be a grid axis"
            };
            return Err(self.invalid(
                value.span(),
                format!(
                    "{key_path} = {}: expected a single value, found {} values; {why}",
                    self.source(value.span()),
                    values.len()
                ),
            ));
        }
        layer.entries[slot_base + index] = Some(Entry {
            values,
            span: value.span(),
        });
        Ok(())
    }

    /// `[output]`.
    pub(super) fn output(&self, value: &Value<'_>, parsed: &mut Parsed) -> Result<(), SceneError> {
        let table = self.table("output", "expected a table", value)?;
        for (key, value) in table.iter() {
            match key.get_ref().as_ref() {
                "trajectories" => parsed.trajectories = self.trajectories(value)?,
                "trajectory_samples_per_cycle" => {
                    parsed.samples_per_cycle = Some(self.samples_per_cycle(value)?);
                }
                "baselines" => parsed.baselines = self.boolean("output.baselines", value)?,
                "backward" => parsed.backward = self.boolean("output.backward", value)?,
                _ => return Err(self.unknown_key(key, "output", &OUTPUT_KEYS)),
            }
        }
        Ok(())
    }

    /// A boolean key's value.
    fn boolean(&self, path: &str, value: &Value<'_>) -> Result<bool, SceneError> {
        match value.get_ref() {
            DeValue::Boolean(b) => Ok(*b),
            _ => Err(self.wrong_type(path, "expected a boolean (true or false)", value)),
        }
    }

    /// `[[points]]`.
    pub(super) fn points(&self, value: &Value<'_>) -> Result<Vec<PointSpec>, SceneError> {
        let DeValue::Array(items) = value.get_ref() else {
            return Err(self.wrong_type("points", "expected a list of tables ([[points]])", value));
        };
        if items.is_empty() {
            return Err(self.invalid(value.span(), "points = []: expected at least one point"));
        }
        let mut points = Vec::with_capacity(items.len());
        for (index, item) in items.iter().enumerate() {
            let DeValue::Table(table) = item.get_ref() else {
                return Err(self.wrong_type(&format!("points[{index}]"), "expected a table", item));
            };
            let label = match table.get("label") {
                Some(label) => self
                    .string("label", label)
                    .map_err(|e| e.in_point(index, ""))?,
                None => String::new(),
            };
            let layer = self.point(table).map_err(|e| e.in_point(index, &label))?;
            points.push(PointSpec { label, layer });
        }
        Ok(points)
    }

    /// One point's keys.
    pub(super) fn point(&self, table: &DeTable<'_>) -> Result<Layer, SceneError> {
        let mut layer = Layer::default();
        for (key, value) in table.iter() {
            match key.get_ref().as_ref() {
                "label" => {}
                "mechanism" => self.mechanism(value, &mut layer, Context::Point, &mut None)?,
                "axis" => self.axes(value, &mut layer, Context::Point)?,
                "simulation" => {
                    self.simulation(value, &mut layer, Context::Point, (&mut None, &mut None))?
                }
                name @ ("name" | "description" | "output" | "points" | PHASE_UNITS_KEY) => {
                    return Err(self.invalid(
                        key.span(),
                        format!("`{name}` cannot be set per point: it applies to the whole scene"),
                    ));
                }
                _ => return Err(self.unknown_key(key, "", &POINT_KEYS)),
            }
        }
        self.check_stage_keys(&layer)?;
        Ok(layer)
    }

    /// Refuses a layer whose stage keys over-determine a stage.
    pub(super) fn check_stage_keys(&self, layer: &Layer) -> Result<(), SceneError> {
        for (axis, name) in AXIS_NAMES.iter().enumerate() {
            let given = layer.axis_given(axis);
            let span = |j: usize| {
                layer.entries[axis_slot(axis, j)]
                    .as_ref()
                    .map_or(0..0, |e| e.span.clone())
            };
            if given[STAGE_MASS] && given[STIFFNESS] && given[RESONANCE] {
                return Err(self.invalid(
                    span(RESONANCE),
                    format!(
                        "axis.{name}: stage_mass, stiffness and resonance_hz over-determine the \
                         stage (f_r = sqrt(k/m) / (2 pi)); give two of them"
                    ),
                ));
            }
            if given[DAMPING] && given[QUALITY] {
                return Err(self.invalid(
                    span(QUALITY),
                    format!(
                        "axis.{name}: damping and quality_factor both set the damping \
                         (c = sqrt(k m) / Q); give one of them"
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// Joins a table path and a key.
pub(super) fn join(prefix: &str, name: &str) -> String {
    if prefix.is_empty() {
        name.to_owned()
    } else {
        format!("{prefix}.{name}")
    }
}
