//! An axis' waveform in a scene (docs/scenes.md): `waveform` and `table`,
//! read beside the axis' numeric keys, and the rule that a shape key
//! (`duty`; `rise`, `hold`, `fall`) applies to its own waveform only.

use std::ops::Range;

use toml::de::DeValue;

use super::error::SceneError;
use super::keys::{
    AXIS_FIELDS, SHAPE_KEYS, TABLE_KEY, WAVEFORM_KEY, WAVEFORMS, axis_slot, slot_path,
};
use super::layer::{Layer, ShapeGiven};
use super::parser::{Context, Parser, Value};
use crate::laws::floor::drive::{MAX_TABLE_ENTRIES, Waveform};
use crate::model::{AXIS_NAMES, Shape, Table};

/// What `waveform` takes.
fn expected_waveform() -> String {
    let names: Vec<String> = WAVEFORMS
        .iter()
        .map(|(name, keys)| format!("{name:?} (with {keys})"))
        .collect();
    format!("expected {}; the default is the sawtooth", names.join(", "))
}

impl Parser<'_> {
    /// `[axis.<name>]`: its numeric keys, `waveform` and `table`.
    pub(super) fn axis(
        &self,
        value: &Value<'_>,
        axis: usize,
        layer: &mut Layer,
        context: Context,
    ) -> Result<(), SceneError> {
        let path = format!("axis.{}", AXIS_NAMES[axis]);
        let table = self.table(&path, "expected a table", value)?;
        let names: Vec<&str> = AXIS_FIELDS
            .iter()
            .map(|f| f.name())
            .chain([WAVEFORM_KEY, TABLE_KEY])
            .collect();
        let mut waveform: Option<(&str, Range<usize>)> = None;
        let mut entries: Option<(Vec<[f64; 2]>, Range<usize>)> = None;
        for (key, value) in table.iter() {
            match key.get_ref().as_ref() {
                WAVEFORM_KEY => waveform = Some((self.waveform_name(&path, value)?, value.span())),
                TABLE_KEY => entries = Some((self.table_entries(&path, value)?, value.span())),
                _ => self.field(
                    key,
                    value,
                    &path,
                    &AXIS_FIELDS,
                    &names,
                    axis_slot(axis, 0),
                    layer,
                    context,
                )?,
            }
        }
        layer.shapes[axis] = self.shape(&path, waveform, entries)?;
        Ok(())
    }

    /// The value of `waveform`, one of [`WAVEFORMS`].
    fn waveform_name(&self, path: &str, value: &Value<'_>) -> Result<&'static str, SceneError> {
        let key = format!("{path}.{WAVEFORM_KEY}");
        let DeValue::String(name) = value.get_ref() else {
            return Err(self.wrong_type(&key, &expected_waveform(), value));
        };
        WAVEFORMS
            .iter()
            .find(|(known, _)| *known == name.as_ref())
            .map(|(known, _)| *known)
            .ok_or_else(|| {
                self.invalid(
                    value.span(),
                    format!("{key} = {:?}: {}", name.as_ref(), expected_waveform()),
                )
            })
    }

    /// The entries of `table`: 2 to 64 `[u, level]` pairs of numbers,
    /// checked as a waveform (`floor::drive::Waveform::check`).
    fn table_entries(&self, path: &str, value: &Value<'_>) -> Result<Vec<[f64; 2]>, SceneError> {
        let key = format!("{path}.{TABLE_KEY}");
        let expected = format!(
            "expected a table of 2 to {MAX_TABLE_ENTRIES} [u, level] entries, u in [0, 1) \
             not decreasing and level in [-1, 1], e.g. [[0.0, 0.0], [0.98, 1.0]]"
        );
        let DeValue::Array(items) = value.get_ref() else {
            return Err(self.wrong_type(&key, &expected, value));
        };
        let mut entries = Vec::with_capacity(items.len());
        for item in items.iter() {
            let pair = match item.get_ref() {
                DeValue::Array(pair) if pair.len() == 2 => {
                    let u = Self::number(pair[0].get_ref());
                    let level = Self::number(pair[1].get_ref());
                    u.zip(level).map(|(u, level)| [u, level])
                }
                _ => None,
            };
            let Some(pair) = pair else {
                return Err(self.invalid(
                    item.span(),
                    format!(
                        "{key}: {} is no [u, level] pair; {expected}",
                        self.source(item.span())
                    ),
                ));
            };
            entries.push(pair);
        }
        Waveform::Table(entries.clone())
            .check()
            .map_err(|e| self.invalid(value.span(), format!("{path}.{e}")))?;
        Ok(entries)
    }

    /// The waveform a layer gives an axis: `waveform` with its `table`
    /// (a table needs `waveform = "table"`, and that a table).
    fn shape(
        &self,
        path: &str,
        waveform: Option<(&str, Range<usize>)>,
        entries: Option<(Vec<[f64; 2]>, Range<usize>)>,
    ) -> Result<Option<ShapeGiven>, SceneError> {
        match (waveform, entries) {
            (None, None) => Ok(None),
            (None, Some((_, span))) => Err(self.invalid(
                span,
                format!(
                    "{path}.{TABLE_KEY} applies to waveform = \"table\" only; give \
                     {path}.{WAVEFORM_KEY} = \"table\" with it"
                ),
            )),
            (Some(("table", span)), None) => Err(self.invalid(
                span,
                format!(
                    "{path}: waveform = \"table\" needs {path}.{TABLE_KEY} = [[u, level], ...]"
                ),
            )),
            (Some(("table", span)), Some((entries, _))) => Ok(Some(ShapeGiven {
                shape: Shape::Table(Table::intern(&entries)),
                span,
            })),
            (Some((name, _)), Some((_, span))) => Err(self.invalid(
                span,
                format!(
                    "{path}.{TABLE_KEY} applies to waveform = \"table\" only, and {path} \
                     gives waveform = {name:?}"
                ),
            )),
            (Some((name, span)), None) => Ok(Some(ShapeGiven {
                shape: if name == "trapezoid" {
                    Shape::Trapezoid
                } else {
                    Shape::Sawtooth
                },
                span,
            })),
        }
    }

    /// Refuses a shape key a layer gives (or ties) to an axis whose
    /// waveform it does not shape: `duty` on a trapezoid, `rise` on a
    /// sawtooth. `shapes` are the axes' waveforms where this layer's keys
    /// land.
    pub(super) fn check_shape_keys(
        &self,
        layer: &Layer,
        shapes: [Shape; 2],
        prefix: &str,
    ) -> Result<(), SceneError> {
        for (axis, shape) in shapes.iter().enumerate() {
            for j in SHAPE_KEYS {
                let slot = axis_slot(axis, j);
                let span = match (&layer.entries[slot], &layer.ties[slot]) {
                    (Some(entry), _) => entry.span.clone(),
                    (None, Some(tie)) => tie.span.clone(),
                    (None, None) => continue,
                };
                let field = AXIS_FIELDS[j];
                let wanted = field.waveform().expect("a shape key shapes a waveform");
                if wanted != shape.name() {
                    let keys = WAVEFORMS
                        .iter()
                        .find(|(name, _)| *name == shape.name())
                        .map_or("", |(_, keys)| keys);
                    return Err(self.invalid(
                        span,
                        format!(
                            "{prefix}{} applies to waveform = {wanted:?} only; axis.{}'s \
                             waveform is {:?}, shaped by {keys}",
                            slot_path(slot),
                            AXIS_NAMES[axis],
                            shape.name()
                        ),
                    ));
                }
            }
        }
        Ok(())
    }
}

/// Each axis' waveform from the given ones, layer over layer (the first
/// that gives one wins), with `axis.y` taking `axis.x`'s where no layer
/// gives its own, and the sawtooth by default.
pub(super) fn effective_shapes(layers: &[&Layer]) -> [Shape; 2] {
    let given = |axis: usize| {
        layers
            .iter()
            .find_map(|layer| layer.shapes[axis].as_ref().map(|s| s.shape))
    };
    let x = given(0).unwrap_or_default();
    [x, given(1).unwrap_or(x)]
}
