//! Layers of keys: the base scene and each `[[points]]` entry give keys at
//! their own level, and an upper layer (`axis.y` over `axis.x`, a point over
//! the base) takes from the one below what it does not give itself.

use std::ops::Range;

use super::keys::{
    AXIS_FIELDS, DAMPING, FREQUENCY, FREQUENCY_RATIO, GAIN, PHASE, QUALITY, RESONANCE, SHAPE_KEYS,
    SLEW_RATE, SLOTS, STAGE_MASS, STIFFNESS, VOLTAGE, axis_slot,
};
use super::values::Entry;
use crate::model::{AXES, Shape};

/// An axis' waveform as a layer gives it (`waveform`, with its `table`).
#[derive(Clone, Debug)]
pub(super) struct ShapeGiven {
    pub(super) shape: Shape,
    /// Where `waveform` is in the text.
    pub(super) span: Range<usize>,
}

/// A key given as `{ same_as = "..." }`: it takes another key's value in
/// every instance (only in the base, only a drive key of one axis to the
/// same key of the other).
#[derive(Clone, Debug)]
pub(super) struct Tie {
    /// The raw slot whose value the tied key takes.
    pub(super) target: usize,
    /// Where the tie is in the text.
    pub(super) span: Range<usize>,
}

/// The keys given at one level (the base, or one point), by raw slot.
#[derive(Clone, Debug)]
pub(super) struct Layer {
    /// The entry of each raw slot, when given.
    pub(super) entries: [Option<Entry>; SLOTS],
    /// The tie of each raw slot given as `{ same_as = "..." }`; such a slot
    /// has no entry.
    pub(super) ties: [Option<Tie>; SLOTS],
    /// Each axis' waveform, when given.
    pub(super) shapes: [Option<ShapeGiven>; AXES],
}

impl Default for Layer {
    fn default() -> Self {
        Layer {
            entries: std::array::from_fn(|_| None),
            ties: std::array::from_fn(|_| None),
            shapes: [None, None],
        }
    }
}

impl Layer {
    /// Which keys of axis `axis` are given.
    pub(super) fn axis_given(&self, axis: usize) -> [bool; AXIS_FIELDS.len()] {
        std::array::from_fn(|j| self.entries[axis_slot(axis, j)].is_some())
    }
}

/// One `[[points]]` entry.
#[derive(Debug)]
pub(super) struct PointSpec {
    /// The point's `label`, "" when none was given.
    pub(super) label: String,
    /// The keys the point sets.
    pub(super) layer: Layer,
}

/// Which keys of a lower layer survive under an upper layer: those the upper
/// one does not give, as long as they do not over-determine the stage. The
/// voltage is kept only when `voltage` is set (a point over the base, not
/// `axis.y` over `axis.x`); the shape keys only when the upper layer gives
/// no waveform of its own (`upper_shape`).
pub(super) fn kept_from_lower(
    upper: &[bool; AXIS_FIELDS.len()],
    lower: &[bool; AXIS_FIELDS.len()],
    voltage: bool,
    upper_shape: bool,
) -> [bool; AXIS_FIELDS.len()] {
    let mut kept = [false; AXIS_FIELDS.len()];
    for j in [GAIN, VOLTAGE, FREQUENCY, PHASE, FREQUENCY_RATIO, SLEW_RATE] {
        kept[j] = lower[j] && !upper[j];
    }
    for j in SHAPE_KEYS {
        kept[j] = lower[j] && !upper[j] && !upper_shape;
    }
    kept[VOLTAGE] &= voltage;
    // A frequency and a frequency ratio are two ways to give one value: an
    // upper layer that gives either takes neither from below. The x axis
    // never has a ratio, so `axis.y` over `axis.x` inherits the frequency
    // unless it gives one of the two.
    if upper[FREQUENCY] || upper[FREQUENCY_RATIO] {
        kept[FREQUENCY] = false;
        kept[FREQUENCY_RATIO] = false;
    }
    let triple = [RESONANCE, STIFFNESS, STAGE_MASS];
    let mut count = triple.iter().filter(|&&j| upper[j]).count();
    for j in triple {
        if lower[j] && !upper[j] && count < 2 {
            kept[j] = true;
            count += 1;
        }
    }
    if !upper[DAMPING] && !upper[QUALITY] {
        kept[DAMPING] = lower[DAMPING];
        kept[QUALITY] = lower[QUALITY];
    }
    kept
}
