//! `[refine]`: adaptive refinement of a two-axis grid (issue 22; the rule
//! and the waves live in `crate::refine`). This module reads the table and
//! turns the scene's coarse grid into the finest grid the refinement
//! addresses: each of the two range axes keeps its endpoints and gets
//! `(steps - 1) * 2^levels + 1` values, so every point the refinement
//! integrates is an instance of the finest grid, bit-identical to the same
//! instance of a uniform run of that grid.

use std::ops::Range;

use super::error::SceneError;
use super::format::fmt_num;
use super::keys::{REFINE_KEYS, slot_path};
use super::parser::{Parser, Value};
use super::values::{Entry, MAX_RANGE_STEPS, Values};

/// The most levels `[refine] levels` takes: 2^10 = 1024 times finer than
/// the coarse grid along each axis, beyond any map that fits the output
/// budget from a coarse grid of a few cells.
pub const MAX_REFINE_LEVELS: u32 = 10;

/// `[refine] tolerance` when not given [m per own drive cycle]: 0.02 um,
/// the accuracy bar for a map value (an inferred value must lie
/// within this plus 1 % of the integrated one), twenty times the 0.001 um
/// the integrator claims for each step, so the rule tests interpolation,
/// not integration noise; steady estimates converge to well within it.
pub const DEFAULT_REFINE_TOLERANCE_M: f64 = 2e-8;

/// The largest `[refine] tolerance` [m]: 1 um per cycle, a third of the
/// largest steps of Table 1's drives; a looser one would infer whole maps
/// from their coarse corners.
const MAX_REFINE_TOLERANCE_M: f64 = 1e-6;

/// A scene's `[refine]`, once the grid is known to be refinable.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refine {
    /// `levels`: how often the spacing of both axes is halved (1 to
    /// [`MAX_REFINE_LEVELS`]).
    pub levels: u32,
    /// `tolerance` [m per own drive cycle]: the dead zone of the step's
    /// sign labels and the allowance of a probe against the interpolant
    /// (with 1 % of the probe's value on top).
    pub tolerance: f64,
    /// The coarse grid's shape (the scene's own `steps`), slow axis first.
    pub coarse: [usize; 2],
}

/// `[refine]` as read, before the grid is checked.
#[derive(Clone, Debug)]
pub(super) struct RefineSpec {
    pub(super) levels: u32,
    pub(super) tolerance: f64,
    /// Where the table is, for errors about the scene's shape.
    pub(super) span: Range<usize>,
}

impl Parser<'_> {
    /// `[refine]`: `levels` (required) and `tolerance`.
    pub(super) fn refine(&self, value: &Value<'_>) -> Result<RefineSpec, SceneError> {
        let table = self.table("refine", "expected a table ([refine])", value)?;
        let mut levels = None;
        let mut tolerance = DEFAULT_REFINE_TOLERANCE_M;
        for (key, value) in table.iter() {
            match key.get_ref().as_ref() {
                "levels" => {
                    let expected = format!("expected an integer from 1 to {MAX_REFINE_LEVELS}");
                    let number = Self::number(value.get_ref())
                        .ok_or_else(|| self.wrong_type("refine.levels", &expected, value))?;
                    if !(1.0..=MAX_REFINE_LEVELS as f64).contains(&number) || number.fract() != 0.0
                    {
                        return Err(self.invalid(
                            value.span(),
                            format!(
                                "refine.levels = {}: {expected} (each level halves the \
                                 spacing of both refined axes)",
                                self.source(value.span())
                            ),
                        ));
                    }
                    levels = Some(number as u32);
                }
                "tolerance" => {
                    let t = self.finite("refine.tolerance", value)?;
                    if !(t > 0.0 && t <= MAX_REFINE_TOLERANCE_M) {
                        return Err(self.invalid(
                            value.span(),
                            format!(
                                "refine.tolerance = {}: expected a step tolerance in m per \
                                 own drive cycle, > 0 and at most {} (default {})",
                                fmt_num(t),
                                fmt_num(MAX_REFINE_TOLERANCE_M),
                                fmt_num(DEFAULT_REFINE_TOLERANCE_M)
                            ),
                        ));
                    }
                    tolerance = t;
                }
                _ => return Err(self.unknown_key(key, "refine", &REFINE_KEYS)),
            }
        }
        let levels = levels.ok_or_else(|| {
            self.invalid(
                value.span(),
                format!(
                    "refine.levels: missing; expected an integer from 1 to {MAX_REFINE_LEVELS} \
                     (each level halves the spacing of both refined axes)"
                ),
            )
        })?;
        Ok(RefineSpec {
            levels,
            tolerance,
            span: value.span(),
        })
    }

    /// Checks that the grid can be refined (exactly two grid axes, each a
    /// linear or log range of at least 2 steps whose finest grid fits) and
    /// replaces each axis' values by the finest grid's.
    pub(super) fn refine_grid(
        &self,
        spec: &RefineSpec,
        grid: &mut [(usize, Entry)],
    ) -> Result<Refine, SceneError> {
        if grid.len() != 2 {
            let keys: Vec<String> = grid.iter().map(|(slot, _)| slot_path(*slot)).collect();
            return Err(self.invalid(
                spec.span.clone(),
                format!(
                    "refine: the scene has {} grid axes{}; expected exactly two range axes (the \
                     plane that is refined); run further axes as separate scenes",
                    grid.len(),
                    if keys.is_empty() {
                        String::new()
                    } else {
                        format!(" ({})", keys.join(", "))
                    }
                ),
            ));
        }
        let mut coarse = [0usize; 2];
        for (k, (slot, entry)) in grid.iter_mut().enumerate() {
            let path = slot_path(*slot);
            let Values::Range {
                from,
                to,
                steps,
                log,
            } = entry.values
            else {
                return Err(self.invalid(
                    entry.span.clone(),
                    format!(
                        "{path} = {}: [refine] needs a range {{ from, to, steps }} on each \
                         refined axis, whose spacing it can halve; found a list",
                        self.source(entry.span.clone())
                    ),
                ));
            };
            let fine = (steps - 1)
                .checked_mul(1u64 << spec.levels)
                .and_then(|n| n.checked_add(1))
                .filter(|&n| n <= MAX_RANGE_STEPS);
            let Some(fine) = fine else {
                return Err(self.invalid(
                    entry.span.clone(),
                    format!(
                        "{path}: steps = {steps} with refine.levels = {}: the finest grid would \
                         have more than {MAX_RANGE_STEPS} values on this axis; expected fewer \
                         steps or levels",
                        spec.levels
                    ),
                ));
            };
            coarse[k] = steps as usize;
            entry.values = Values::Range {
                from,
                to,
                steps: fine,
                log,
            };
        }
        Ok(Refine {
            levels: spec.levels,
            tolerance: spec.tolerance,
            coarse,
        })
    }
}
