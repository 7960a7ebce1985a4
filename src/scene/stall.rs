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

/// The loads the bracketing probes, as fractions of the room along the
/// axis: doubling from 1/64 to 1/2, where a drive stalls under a small
/// load (Table 1 at 10 Hz stalls at 4 to 8 % of f_c), then closing in on
/// f_c, where the last probe is 63/64 of the room: a load that close to
/// f_c is one the interface barely holds at rest.
pub const BRACKET: [f64; 10] = [
    1.0 / 64.0,
    1.0 / 32.0,
    1.0 / 16.0,
    1.0 / 8.0,
    1.0 / 4.0,
    1.0 / 2.0,
    3.0 / 4.0,
    7.0 / 8.0,
    15.0 / 16.0,
    63.0 / 64.0,
];

/// `[stall] tolerance` when not given [N]: 1e-4 N, 0.01 % of Table 1's
/// kinetic friction, where its stall slopes (12-16 um/N, docs/model.md section
/// 7) make the step at the bracket ends 0.002 um from zero: below the
/// steady measurement's own 0.01 um.
pub const DEFAULT_TOLERANCE_N: f64 = 1e-4;

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
