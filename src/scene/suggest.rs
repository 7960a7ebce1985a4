//! Hints for unknown keys: the table a key belongs in, or the closest valid
//! key by edit distance.

use super::keys::{
    AXIS_FIELDS, Field, MEASURE_KEY, MECHANISM_FIELDS, OUTPUT_KEYS, REPLICAS_KEY, ROOT_KEYS,
    SIMULATION_FIELDS,
};
use crate::model::AXIS_NAMES;

/// The table a key belongs in, when it is a valid key somewhere.
pub(super) fn home_of(name: &str) -> Option<&'static str> {
    let is = |fields: &[Field]| fields.iter().any(|f| f.name() == name);
    if is(&MECHANISM_FIELDS) {
        Some("[mechanism]")
    } else if is(&AXIS_FIELDS) {
        Some("[axis.x] or [axis.y]")
    } else if is(&SIMULATION_FIELDS) || name == MEASURE_KEY || name == REPLICAS_KEY {
        Some("[simulation]")
    } else if OUTPUT_KEYS.contains(&name) {
        Some("[output]")
    } else if AXIS_NAMES.contains(&name) {
        Some("[axis], as [axis.x] and [axis.y]")
    } else if name == "label" {
        Some("[[points]]")
    } else if ROOT_KEYS.contains(&name) {
        Some("the top level of the scene")
    } else {
        None
    }
}

/// The candidate closest to `name`: one within a few edits, one that
/// contains it, or the longest one of at least 4 characters that it
/// contains (`measurement` for `measure`).
pub(super) fn suggest<'c>(name: &str, candidates: &[&'c str]) -> Option<&'c str> {
    let lower = name.to_ascii_lowercase();
    let best = candidates
        .iter()
        .map(|&c| (edit_distance(&lower, c), c))
        .min_by_key(|&(d, _)| d)?;
    let length = lower.chars().count();
    if best.0 < length && best.0 <= (length / 3).max(1) {
        return Some(best.1);
    }
    if length >= 3
        && let Some(container) = candidates
            .iter()
            .copied()
            .find(|c| c.contains(lower.as_str()))
    {
        return Some(container);
    }
    candidates
        .iter()
        .copied()
        .filter(|c| c.chars().count() >= 4 && lower.contains(*c))
        .max_by_key(|c| c.chars().count())
}

/// Optimal-string-alignment edit distance (insertions, deletions,
/// substitutions and transpositions of neighbours).
pub(super) fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let mut d = vec![vec![0usize; b.len() + 1]; a.len() + 1];
    for (i, row) in d.iter_mut().enumerate() {
        row[0] = i;
    }
    for (j, cell) in d[0].iter_mut().enumerate() {
        *cell = j;
    }
    for i in 1..=a.len() {
        for j in 1..=b.len() {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            let mut best = (d[i - 1][j] + 1)
                .min(d[i][j - 1] + 1)
                .min(d[i - 1][j - 1] + cost);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                best = best.min(d[i - 2][j - 2] + 1);
            }
            d[i][j] = best;
        }
    }
    d[a.len()][b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::keys::SIMULATION_KEYS;

    #[test]
    fn misspelt_measurement_keys_find_their_key() {
        for (typed, meant) in [
            ("max_cycle", "max_cycles"),
            ("maxcycles", "max_cycles"),
            ("step_tolerence", "step_tolerance"),
            ("steptolerance", "step_tolerance"),
            ("mesure", "measure"),
            ("measurement", "measure"),
            ("steady_step_tolerance", "step_tolerance"),
        ] {
            assert_eq!(suggest(typed, &SIMULATION_KEYS), Some(meant), "{typed}");
        }
        assert_eq!(suggest("xyz", &SIMULATION_KEYS), None);
        assert_eq!(home_of("measure"), Some("[simulation]"));
        assert_eq!(home_of("max_cycles"), Some("[simulation]"));
        assert_eq!(home_of("step_tolerance"), Some("[simulation]"));
    }
}
