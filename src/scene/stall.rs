//! `[stall]`: a stall-load map (docs/model.md section 7; the search and its
//! waves live in `crate::stall`). This module reads the table: `axis`
//! ("x" or "y", required), the axis whose stall load each instance gets,
//! and `tolerance` [N], how close to a zero crossing of its step the load
//! must be. The search sets that axis' load itself, so the scene may not
//! give it (not as a value, a grid axis or a point's key); the other
//! axis' load may be anything below f_c, a grid axis included.

use super::error::SceneError;
use super::format::fmt_num;
use super::keys::{LOAD_SLOTS, STALL_KEYS, slot_path};
use super::layer::Layer;
use super::parser::{Parser, Value};
use crate::model::AXIS_NAMES;
use crate::stall::DEFAULT_TOLERANCE_N;

/// The largest `[stall] tolerance` [N], like the bounds of the friction it
/// is a fraction of (a tolerance at or above a scene's f_c only makes the
/// first bracket its answer).
const MAX_TOLERANCE_N: f64 = 1e9;

/// A scene's `[stall]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stall {
    /// The axis whose stall load is searched (0 = x, 1 = y).
    pub axis: usize,
    /// `tolerance` [N]: the stall load is within it of a zero crossing of
    /// the axis' step (default [`DEFAULT_TOLERANCE_N`]).
    pub tolerance: f64,
}

impl Parser<'_> {
    /// `[stall]`: `axis` (required) and `tolerance`.
    pub(super) fn stall(&self, value: &Value<'_>) -> Result<Stall, SceneError> {
        let table = self.table("stall", "expected a table ([stall])", value)?;
        let mut axis = None;
        let mut tolerance = DEFAULT_TOLERANCE_N;
        for (key, value) in table.iter() {
            match key.get_ref().as_ref() {
                "axis" => {
                    let name = self.string("stall.axis", value)?;
                    axis = Some(AXIS_NAMES.iter().position(|a| *a == name).ok_or_else(|| {
                        self.invalid(
                            value.span(),
                            format!(
                                "stall.axis = {name:?}: expected \"x\" or \"y\" (the axis whose \
                                 stall load is searched)"
                            ),
                        )
                    })?);
                }
                "tolerance" => {
                    let t = self.finite("stall.tolerance", value)?;
                    if !(t > 0.0 && t <= MAX_TOLERANCE_N) {
                        return Err(self.invalid(
                            value.span(),
                            format!(
                                "stall.tolerance = {}: expected a load in N, > 0 and at most {} \
                                 (default {}: the stall load is within it of a zero crossing of \
                                 the step)",
                                fmt_num(t),
                                fmt_num(MAX_TOLERANCE_N),
                                fmt_num(DEFAULT_TOLERANCE_N)
                            ),
                        ));
                    }
                    tolerance = t;
                }
                _ => return Err(self.unknown_key(key, "stall", &STALL_KEYS)),
            }
        }
        let axis = axis.ok_or_else(|| {
            self.invalid(
                value.span(),
                "stall.axis: missing; expected \"x\" or \"y\" (the axis whose stall load is \
                 searched)",
            )
        })?;
        Ok(Stall { axis, tolerance })
    }

    /// Refuses a stall scene that gives the stalled axis' load in `layer`
    /// (the base or a point, named by `within`): the search sets it.
    pub(super) fn check_stall_load(
        &self,
        stall: &Stall,
        layer: &Layer,
        within: &str,
    ) -> Result<(), SceneError> {
        let slot = LOAD_SLOTS[stall.axis];
        let Some(entry) = &layer.entries[slot] else {
            return Ok(());
        };
        Err(self.invalid(
            entry.span.clone(),
            format!(
                "{within}{} = {}: [stall] axis = {:?} searches this load itself, instance by \
                 instance; expected no {} in a stall scene (the other axis' load may be set)",
                slot_path(slot),
                self.source(entry.span.clone()),
                AXIS_NAMES[stall.axis],
                slot_path(slot)
            ),
        ))
    }
}
