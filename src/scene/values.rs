//! The values given to one numeric key: a scalar, a list or a range.

use std::ops::Range;

use super::memory::MAP_MEMORY_BUDGET_BYTES;

/// Largest `steps` of a range: the most values one grid axis can have while
/// its output maps (69 bytes per instance, without baselines) fit the
/// default budget [`MAP_MEMORY_BUDGET_BYTES`], 124491805. A larger range could never
/// run, and a cap keeps every count of values far from overflowing.
pub const MAX_RANGE_STEPS: u64 =
    MAP_MEMORY_BUDGET_BYTES / crate::output::schema::bytes_per_instance(false, false, false);

/// The values given to one key.
#[derive(Clone, Debug)]
pub(super) enum Values {
    /// A scalar or a list.
    List(Vec<f64>),
    /// A range, endpoints included.
    Range {
        /// The first value, in the key's units.
        from: f64,
        /// The last value, in the key's units.
        to: f64,
        /// Number of values, from 1 to [`MAX_RANGE_STEPS`].
        steps: u64,
        /// Whether the values are spaced geometrically.
        log: bool,
    },
}

impl Values {
    /// Number of values.
    pub(super) fn len(&self) -> u64 {
        match self {
            Values::List(values) => values.len() as u64,
            Values::Range { steps, .. } => *steps,
        }
    }

    /// Value `i`, computed without expanding a range.
    pub(super) fn value(&self, i: u64) -> f64 {
        match *self {
            Values::List(ref values) => values[i as usize],
            Values::Range {
                from,
                to,
                steps,
                log,
            } => {
                if i == 0 || steps == 1 {
                    return from;
                }
                if i == steps - 1 {
                    return to;
                }
                let v = if log {
                    from * (to / from).powf(i as f64 / (steps - 1) as f64)
                } else {
                    // Multiplying before dividing keeps integer grids exact.
                    from + (to - from) * i as f64 / (steps - 1) as f64
                };
                // Rounding must not leave the interval: the checks rely on it.
                v.clamp(from.min(to), from.max(to))
            }
        }
    }

    /// All values.
    pub(super) fn expand(&self) -> Vec<f64> {
        (0..self.len()).map(|i| self.value(i)).collect()
    }

    /// The values a validity check must look at: all of a list, the two ends
    /// of a (monotone) range.
    pub(super) fn extremes(&self) -> Vec<(u64, f64)> {
        match self {
            Values::List(values) => values
                .iter()
                .copied()
                .enumerate()
                .map(|(i, v)| (i as u64, v))
                .collect(),
            Values::Range { from, steps: 1, .. } => vec![(0, *from)],
            Values::Range {
                from, to, steps, ..
            } => vec![(0, *from), (steps - 1, *to)],
        }
    }

    /// The smallest and largest value.
    pub(super) fn min_max(&self) -> (f64, f64) {
        self.extremes()
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &(_, v)| {
                (lo.min(v), hi.max(v))
            })
    }
}

/// One key as given in the file.
#[derive(Clone, Debug)]
pub(super) struct Entry {
    /// Its values.
    pub(super) values: Values,
    /// Where its value is in the text.
    pub(super) span: Range<usize>,
}
