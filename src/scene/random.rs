//! `[random]`: a list of seeded random instances, `count` of them from
//! `seed`, the instances `pidm random-scene --seed SEED --count COUNT`
//! writes out as `[[points]]` (`crate::model::random`), in a few lines instead of
//! 680 bytes a point (100,000 random instances are 68 MB of points, which
//! take seconds and gigabytes to read). The instances are those of the
//! written scene bit for bit; their window is the scene's `[simulation]`
//! `cycles` and `settle`.

use super::error::SceneError;
use super::keys::{RANDOM_KEYS, SIMULATION_SLOTS, slot_path};
use super::layer::Layer;
use super::parser::{Parser, RandomSpec, Value};

/// The most instances `[random] count` takes: a list held in memory (about
/// 250 bytes an instance and its label).
pub const MAX_RANDOM_COUNT: u64 = 10_000_000;

/// The largest `[random] seed`: every integer up to it is exact in the
/// TOML reader's numbers.
pub const MAX_RANDOM_SEED: u64 = 1 << 53;

impl Parser<'_> {
    /// `[random]`: `seed` and `count`, both required integers.
    pub(super) fn random(&self, value: &Value<'_>) -> Result<RandomSpec, SceneError> {
        let table = self.table("random", "expected a table ([random])", value)?;
        let mut seed = None;
        let mut count = None;
        for (key, value) in table.iter() {
            let (slot, low, high, what) = match key.get_ref().as_ref() {
                "seed" => (&mut seed, 0, MAX_RANDOM_SEED, "the random generator's seed"),
                "count" => (&mut count, 1, MAX_RANDOM_COUNT, "the number of instances"),
                _ => return Err(self.unknown_key(key, "random", &RANDOM_KEYS)),
            };
            let name = key.get_ref().as_ref();
            let expected = format!("expected an integer from {low} to {high} ({what})");
            let number = Self::number(value.get_ref())
                .ok_or_else(|| self.wrong_type(&format!("random.{name}"), &expected, value))?;
            if !(low as f64..=high as f64).contains(&number) || number.fract() != 0.0 {
                return Err(self.invalid(
                    value.span(),
                    format!("random.{name} = {}: {expected}", self.source(value.span())),
                ));
            }
            *slot = Some(number as u64);
        }
        let missing = |name: &str, what: &str| {
            self.invalid(
                value.span(),
                format!("random.{name}: missing; expected an integer ({what})"),
            )
        };
        Ok(RandomSpec {
            seed: seed.ok_or_else(|| missing("seed", "the random generator's seed"))?,
            count: count.ok_or_else(|| missing("count", "the number of instances"))?,
            span: value.span(),
        })
    }

    /// Refuses every key of `base` that random instances draw themselves
    /// (the mechanism's and the axes'): only `[simulation]` applies.
    pub(super) fn check_random_keys(&self, base: &Layer) -> Result<(), SceneError> {
        for slot in 0..SIMULATION_SLOTS {
            let span = match (&base.entries[slot], &base.ties[slot]) {
                (Some(entry), _) => entry.span.clone(),
                (None, Some(tie)) => tie.span.clone(),
                (None, None) => continue,
            };
            return Err(self.invalid(
                span,
                format!(
                    "{}: a scene with [random] draws every mechanism and axis parameter \
                         of its instances (see `pidm random-scene`); expected only \
                         [simulation] keys beside [random]",
                    slot_path(slot)
                ),
            ));
        }
        if let Some((axis, given)) = base
            .shapes
            .iter()
            .enumerate()
            .find_map(|(axis, s)| s.as_ref().map(|s| (axis, s)))
        {
            return Err(self.invalid(
                given.span.clone(),
                format!(
                    "axis.{}.waveform: a scene with [random] draws sawtooth instances (see \
                     `pidm random-scene`); expected only [simulation] keys beside [random]",
                    crate::model::AXIS_NAMES[axis]
                ),
            ));
        }
        Ok(())
    }
}
