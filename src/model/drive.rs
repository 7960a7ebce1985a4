//! An axis' drive shape as plain data (docs/model.md section 2): the
//! waveform's kind and the amplifier's slew limit. The laws read it
//! through the floor's `laws::floor::drive`, which turns it into one
//! cycle's corners.
//!
//! A table is held once per distinct table for the life of the process
//! ([`Table::intern`]), so that an [`super::Axis`] stays `Copy` and a map
//! of a million instances holds a pointer per axis, not a table.

use std::collections::HashMap;
use std::sync::Mutex;

/// The waveform of an axis, beside its numeric keys (`duty` for the
/// sawtooth; `rise`, `hold` and `fall` for the trapezoid).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Shape {
    /// The paper's sawtooth with its `duty`: the default.
    #[default]
    Sawtooth,
    /// A rise, a hold at the top, a fall, and a dwell at 0 for the rest.
    Trapezoid,
    /// A signal generator's table of `[u, level]` entries.
    Table(Table),
}

impl Shape {
    /// The scene's name of the shape (`waveform = "..."`).
    pub fn name(&self) -> &'static str {
        match self {
            Shape::Sawtooth => "sawtooth",
            Shape::Trapezoid => "trapezoid",
            Shape::Table(_) => "table",
        }
    }
}

/// An interned table of `[u, level]` entries: equal tables are one
/// allocation, so that equality and identity agree.
#[derive(Clone, Copy)]
pub struct Table(&'static [[f64; 2]]);

impl Table {
    /// The one copy of `entries` (by their bits), made on first use.
    pub fn intern(entries: &[[f64; 2]]) -> Table {
        type Held = HashMap<Vec<[u64; 2]>, &'static [[f64; 2]]>;
        static HELD: Mutex<Option<Held>> = Mutex::new(None);
        let bits: Vec<[u64; 2]> = entries.iter().map(|e| e.map(f64::to_bits)).collect();
        let mut held = HELD.lock().unwrap_or_else(|e| e.into_inner());
        let kept = held
            .get_or_insert_with(HashMap::new)
            .entry(bits)
            .or_insert_with(|| Box::leak(entries.to_vec().into_boxed_slice()));
        Table(kept)
    }

    /// The entries.
    pub fn entries(&self) -> &'static [[f64; 2]] {
        self.0
    }

    /// The table's identity within the process (one per distinct table).
    pub fn id(&self) -> u64 {
        self.0.as_ptr() as usize as u64
    }
}

impl PartialEq for Table {
    fn eq(&self, other: &Table) -> bool {
        std::ptr::eq(self.0, other.0)
    }
}

impl std::fmt::Debug for Table {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

/// No slew limit: the stage sees the waveform itself.
pub const NO_SLEW_LIMIT: f64 = f64::INFINITY;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_tables_are_one_and_unequal_ones_two() {
        let a = Table::intern(&[[0.0, 0.0], [0.5, 1.0]]);
        let b = Table::intern(&[[0.0, 0.0], [0.5, 1.0]]);
        let c = Table::intern(&[[0.0, 0.0], [0.5, -1.0]]);
        assert_eq!(a, b);
        assert_eq!(a.id(), b.id());
        assert_ne!(a, c);
        assert_eq!(c.entries(), &[[0.0, 0.0], [0.5, -1.0]]);
        // -0 and +0 are different bits, so different tables.
        assert_ne!(Table::intern(&[[0.0, -0.0], [0.5, 1.0]]), a);
    }
}
