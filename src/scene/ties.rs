//! Keys tied to other keys: `axis.y.voltage = { same_as = "axis.x.voltage" }`
//! gives both axes the same voltage in every instance (so a grid axis over
//! the x voltage moves both), and `axis.y.frequency_ratio` gives the y
//! drive's frequency as a multiple of the x drive's (so a map can run over
//! the ratio of the two frequencies).
//!
//! A tie is read here and checked against the whole base layer; the
//! [`Plan`](super::plan::Plan) then takes the tied key's value from the
//! source of the key it is tied to.

use toml::de::{DeTable, DeValue};

use super::error::SceneError;
use super::keys::{
    AXIS_FIELDS, AXIS_SLOTS, FREQUENCY, FREQUENCY_RATIO, SAME_AS_KEY, SIMULATION_SLOTS, TIEABLE,
    axis_slot, slot_path,
};
use super::layer::Layer;
use super::parser::{Context, Parser, Value};
use crate::model::AXIS_NAMES;

/// The axis and the index into [`AXIS_FIELDS`] of an axis slot; `None` for
/// the mechanism's and the simulation's slots.
fn axis_key(slot: usize) -> Option<(usize, usize)> {
    (AXIS_SLOTS..SIMULATION_SLOTS).contains(&slot).then(|| {
        let offset = slot - AXIS_SLOTS;
        (offset / AXIS_FIELDS.len(), offset % AXIS_FIELDS.len())
    })
}

impl Parser<'_> {
    /// Reads `{ same_as = "axis.<other>.<key>" }` given to the key in raw
    /// slot `slot` (full path `path`) and returns the slot it is tied to.
    /// Only the base may tie, only a drive key ([`TIEABLE`]), and only to
    /// the same key of the other axis.
    pub(super) fn tie(
        &self,
        path: &str,
        slot: usize,
        table: &DeTable<'_>,
        value: &Value<'_>,
        context: Context,
    ) -> Result<usize, SceneError> {
        let source = self.source(value.span());
        if context == Context::Point {
            return Err(self.invalid(
                value.span(),
                format!(
                    "{path} = {source}: a point cannot tie keys; ties apply to the whole \
                     scene (tie in the base, or give the point a value)"
                ),
            ));
        }
        let tieable: Vec<&str> = TIEABLE.iter().map(|&j| AXIS_FIELDS[j].name()).collect();
        let Some((axis, field)) = axis_key(slot).filter(|(_, j)| TIEABLE.contains(j)) else {
            return Err(self.invalid(
                value.span(),
                format!(
                    "{path} = {source}: only an axis' drive keys ({}) can be tied, each to the \
                     same key of the other axis",
                    tieable.join(", ")
                ),
            ));
        };
        let other = 1 - axis;
        let target = axis_slot(other, field);
        let expected = format!(
            "expected {SAME_AS_KEY} = \"{}\" (the same key of the other axis)",
            slot_path(target)
        );
        for (key, item) in table.iter() {
            if key.get_ref() != SAME_AS_KEY {
                return Err(self.invalid(
                    key.span(),
                    format!(
                        "{path}.{}: a tie takes only `{SAME_AS_KEY}`; {expected}",
                        key.get_ref()
                    ),
                ));
            }
            let DeValue::String(name) = item.get_ref() else {
                return Err(self.wrong_type(&format!("{path}.{SAME_AS_KEY}"), &expected, item));
            };
            if name.as_ref() != slot_path(target) {
                return Err(self.invalid(
                    item.span(),
                    format!("{path}.{SAME_AS_KEY} = {:?}: {expected}", name.as_ref()),
                ));
            }
        }
        Ok(target)
    }

    /// Checks the ties of the base layer against each other and against the
    /// keys given: a tie's target is not tied itself, a tie to `axis.y`
    /// names a key given there (an `axis.y` key not given takes `axis.x`'s
    /// value, so a tie to it would be circular), and `axis.y`'s frequency is
    /// given once (a frequency, a frequency ratio or a tie).
    pub(super) fn check_ties(&self, layer: &Layer) -> Result<(), SceneError> {
        for (slot, tie) in layer.ties.iter().enumerate() {
            let Some(tie) = tie else { continue };
            let (path, target) = (slot_path(slot), slot_path(tie.target));
            if layer.ties[tie.target].is_some() {
                return Err(self.invalid(
                    tie.span.clone(),
                    format!(
                        "{path} and {target} are tied to each other, so neither has a value; \
                         give one of them a value"
                    ),
                ));
            }
            let target_axis = axis_key(tie.target).map(|(a, _)| a);
            if target_axis == Some(1) && layer.entries[tie.target].is_none() {
                return Err(self.invalid(
                    tie.span.clone(),
                    format!(
                        "{path} = {{ {SAME_AS_KEY} = \"{target}\" }}: {target} is not given \
                         in the scene (a key of axis.y that is not given follows axis.x or its \
                         default); give {target} a value, or drop the tie"
                    ),
                ));
            }
        }
        self.check_frequency_keys(layer)
    }

    /// Refuses a layer that gives `axis.y`'s frequency twice: as a
    /// frequency, a frequency ratio or a tie.
    pub(super) fn check_frequency_keys(&self, layer: &Layer) -> Result<(), SceneError> {
        let y = AXIS_NAMES[1];
        let frequency = axis_slot(1, FREQUENCY);
        let ratio = axis_slot(1, FREQUENCY_RATIO);
        let Some(ratio_entry) = &layer.entries[ratio] else {
            return Ok(());
        };
        let other = if layer.entries[frequency].is_some() {
            "a frequency"
        } else if layer.ties[frequency].is_some() {
            "a tied frequency"
        } else {
            return Ok(());
        };
        Err(self.invalid(
            ratio_entry.span.clone(),
            format!(
                "axis.{y}.frequency_ratio and {other} both set axis.{y}'s drive frequency \
                 (f_y = frequency_ratio x axis.x.frequency); give one of them"
            ),
        ))
    }
}
