//! Where a grid axis' values sit on the page: linearly, or by their
//! logarithm when they are geometrically spaced.

/// How a grid axis is laid out on the page: linearly, or by the logarithm
/// of its values when they are geometrically spaced.
#[derive(Clone, Copy)]
pub(super) struct Placement {
    /// Whether the values are placed by their logarithm.
    pub(super) log: bool,
}

impl Placement {
    pub(super) fn of(values: &[f64]) -> Placement {
        let n = values.len();
        let log = n > 2 && values.iter().all(|&v| v > 0.0) && {
            let ratio = values[1] / values[0];
            (ratio - 1.0).abs() > 1e-9
                && values
                    .windows(2)
                    .all(|w| ((w[1] / w[0]) / ratio - 1.0).abs() < 1e-6)
        };
        Placement { log }
    }

    pub(super) fn place(self, v: f64) -> f64 {
        if self.log { v.log10() } else { v }
    }

    pub(super) fn value(self, c: f64) -> f64 {
        if self.log { 10f64.powf(c) } else { c }
    }

    /// Cell edges on the page: halfway between neighbouring values, and as
    /// far again beyond the ends.
    pub(super) fn edges(self, values: &[f64]) -> Vec<f64> {
        let c: Vec<f64> = values.iter().map(|&v| self.place(v)).collect();
        let n = c.len();
        if n == 1 {
            return vec![c[0] - 0.5, c[0] + 0.5];
        }
        let mut e = Vec::with_capacity(n + 1);
        e.push(c[0] - 0.5 * (c[1] - c[0]));
        for w in c.windows(2) {
            e.push(0.5 * (w[0] + w[1]));
        }
        e.push(c[n - 1] + 0.5 * (c[n - 1] - c[n - 2]));
        e
    }
}

/// At most eight of an axis' values, evenly spaced by index, for labels.
pub(super) fn label_values(values: &[f64]) -> Vec<f64> {
    let n = values.len();
    let count = n.min(8);
    if count < 2 {
        return values.to_vec();
    }
    (0..count)
        .map(|k| values[k * (n - 1) / (count - 1)])
        .collect()
}
