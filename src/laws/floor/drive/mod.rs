//! The drive as a design variable (issue 59), f64 host code: an axis'
//! waveform as one cycle's piecewise-linear corners, which both laws and
//! the trajectories are to read, and the amplifier's slew limit as the
//! follower's periodic orbit (`slew.rs`), computed once per instance.
//!
//! A waveform is a normalised level w(u) in [-1, 1] of the cycle phase u
//! (the voltage is `voltage * w`, docs/model.md section 2). Its corners are
//! `(u, level)` pairs with u in [0, 1), not decreasing: w is linear between
//! consecutive corners and from the last one to the first one a cycle
//! later. Two corners at one u are a jump, from the first level to the
//! second; w at a jump is the level after it, as the sawtooth's
//! (`model::sawtooth`) is at its drop. [`axis_corners`] is what a law
//! reads: an axis' waveform, slew-limited where its amplifier is.

mod slew;

#[cfg(test)]
mod tests;

use crate::model::{Axis, Shape};

/// The waveform an axis' keys give.
pub fn axis_waveform(axis: &Axis) -> Waveform {
    match axis.shape {
        Shape::Sawtooth => Waveform::Sawtooth { duty: axis.duty },
        Shape::Trapezoid => Waveform::Trapezoid {
            rise: axis.rise,
            hold: axis.hold,
            fall: axis.fall,
        },
        Shape::Table(table) => Waveform::Table(table.entries().to_vec()),
    }
}

/// One cycle of the levels the stage sees on `axis`: its waveform's
/// corners, on the follower's periodic orbit where the amplifier's
/// `slew_rate` limits a flank. The limit in levels per cycle is
/// slew_rate / (|voltage| frequency); an undriven axis sees no limit.
pub fn axis_corners(axis: &Axis) -> Corners {
    let corners = axis_waveform(axis).corners();
    let sigma = axis.slew_rate / (axis.voltage.abs() * axis.frequency);
    if axis.is_driven() && sigma.is_finite() {
        corners.slew_limited(sigma)
    } else {
        corners
    }
}

/// The most corners a table may hold.
pub const MAX_TABLE_ENTRIES: usize = 64;

/// One axis' waveform, as a scene gives it.
#[derive(Clone, Debug, PartialEq)]
pub enum Waveform {
    /// The paper's sawtooth: a rise from 0 to 1 over the fraction `duty`
    /// of a cycle, in (0, 1], then a fall back to 0.
    Sawtooth { duty: f64 },
    /// A rise from 0 to 1, a hold at 1 and a fall to 0, each a fraction of
    /// a cycle (0 is a jump), then a dwell at 0 for the rest.
    Trapezoid { rise: f64, hold: f64, fall: f64 },
    /// A signal generator's table of `[u, level]` entries.
    Table(Vec<[f64; 2]>),
}

/// A refused waveform: the key, the value given and what was expected.
#[derive(Clone, Debug, PartialEq)]
pub struct DriveError {
    pub key: &'static str,
    pub value: String,
    pub expected: String,
}

impl std::fmt::Display for DriveError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} = {}: expected {}",
            self.key, self.value, self.expected
        )
    }
}

impl std::error::Error for DriveError {}

fn refuse(key: &'static str, value: impl std::fmt::Debug, expected: &str) -> DriveError {
    DriveError {
        key,
        value: format!("{value:?}"),
        expected: expected.to_string(),
    }
}

impl Waveform {
    /// Whether the waveform is one a scene may give: a duty in (0, 1];
    /// fractions each at least 0, not all 0, summing to at most 1; a
    /// table of 2 to 64 entries, u in [0, 1) not decreasing, levels in
    /// [-1, 1], at most two at one u.
    pub fn check(&self) -> Result<(), DriveError> {
        match self {
            Waveform::Sawtooth { duty } => {
                if !(*duty > 0.0 && *duty <= 1.0) {
                    return Err(refuse("duty", duty, "a fraction in (0, 1]"));
                }
            }
            Waveform::Trapezoid { rise, hold, fall } => {
                for (key, v) in [("rise", rise), ("hold", hold), ("fall", fall)] {
                    if !(v.is_finite() && *v >= 0.0) {
                        return Err(refuse(key, v, "a fraction of a cycle, at least 0"));
                    }
                }
                let sum = rise + hold + fall;
                if sum == 0.0 || sum > 1.0 {
                    let expected = "fractions that sum to more than 0 and at most 1";
                    return Err(refuse("rise", [*rise, *hold, *fall], expected));
                }
            }
            Waveform::Table(entries) => check_table(entries)?,
        }
        Ok(())
    }

    /// The waveform's corners over one cycle.
    pub fn corners(&self) -> Corners {
        let points = match self {
            Waveform::Sawtooth { duty } if *duty >= 1.0 => vec![[0.0, 1.0], [0.0, 0.0]],
            Waveform::Sawtooth { duty } => vec![[0.0, 0.0], [*duty, 1.0]],
            Waveform::Trapezoid { rise, hold, fall } => {
                let up = *rise;
                let down = rise + hold;
                let end = down + fall;
                vec![[0.0, 0.0], [up, 1.0], [down, 1.0], [end, 0.0]]
            }
            Waveform::Table(entries) => entries.clone(),
        };
        Corners::wrapped(points)
    }
}

fn check_table(entries: &[[f64; 2]]) -> Result<(), DriveError> {
    if entries.len() < 2 || entries.len() > MAX_TABLE_ENTRIES {
        let expected = format!("a table of 2 to {MAX_TABLE_ENTRIES} [u, level] entries");
        return Err(refuse("table", entries.len(), &expected));
    }
    for (k, &[u, level]) in entries.iter().enumerate() {
        if !(0.0..1.0).contains(&u) || !(-1.0..=1.0).contains(&level) {
            let expected = format!("entry {k} with u in [0, 1) and level in [-1, 1]");
            return Err(refuse("table", [u, level], &expected));
        }
        if k > 0 && u < entries[k - 1][0] {
            let expected = format!("entry {k} at a u no earlier than entry {}'s", k - 1);
            return Err(refuse("table", [u, level], &expected));
        }
        if k > 1 && u == entries[k - 2][0] {
            let expected = format!("entry {k}: at most two entries (a jump) at one u");
            return Err(refuse("table", [u, level], &expected));
        }
    }
    Ok(())
}

/// One cycle's corners, normalised: u in [0, 1) not decreasing, no corner
/// repeated, at most two at one u.
#[derive(Clone, Debug, PartialEq)]
pub struct Corners {
    pub points: Vec<[f64; 2]>,
}

impl Corners {
    /// `points` with u in [0, 1], not decreasing, made one cycle's: the
    /// corners at u = 1 move to the cycle's start (before those at 0, as
    /// the levels just before it); a corner equal to its predecessor goes,
    /// and of three or more at one u the first and last stay (what lies
    /// between lasts no time).
    pub(crate) fn wrapped(points: Vec<[f64; 2]>) -> Corners {
        let (ends, rest): (Vec<[f64; 2]>, Vec<[f64; 2]>) =
            points.into_iter().partition(|p| p[0] >= 1.0);
        let mut out: Vec<[f64; 2]> = Vec::with_capacity(ends.len() + rest.len());
        for p in ends.into_iter().map(|p| [p[0] - 1.0, p[1]]).chain(rest) {
            let n = out.len();
            if n >= 2 && out[n - 1][0] == p[0] && out[n - 2][0] == p[0] {
                out.pop();
            }
            if out.last() != Some(&p) {
                out.push(p);
            }
        }
        Corners { points: out }
    }

    /// The level at cycle phase `u` (any real; w at a jump is the level
    /// after it).
    pub fn level(&self, u: f64) -> f64 {
        let p = u - u.floor();
        let pts = &self.points;
        let n = pts.len();
        // The last corner at or before p, and the next one (a cycle later
        // past the end).
        let k = pts.iter().rposition(|c| c[0] <= p);
        let (a, b) = match k {
            Some(k) if k + 1 < n => (pts[k], pts[k + 1]),
            Some(k) => (pts[k], [pts[0][0] + 1.0, pts[0][1]]),
            None => ([pts[n - 1][0] - 1.0, pts[n - 1][1]], pts[0]),
        };
        if b[0] == a[0] {
            return b[1];
        }
        // From the corner at level 0 where there is one: the sawtooth's
        // p / d and (1 - p) / (1 - d), as `model::sawtooth` has them.
        if b[1] == 0.0 {
            a[1] * (b[0] - p) / (b[0] - a[0])
        } else if a[1] == 0.0 {
            b[1] * (p - a[0]) / (b[0] - a[0])
        } else {
            a[1] + (b[1] - a[1]) * (p - a[0]) / (b[0] - a[0])
        }
    }

    /// The steepest flank's slope [levels per cycle]: infinite where the
    /// waveform jumps.
    pub fn steepest(&self) -> f64 {
        self.segments()
            .map(|(a, b)| {
                if b[0] == a[0] {
                    if b[1] == a[1] { 0.0 } else { f64::INFINITY }
                } else {
                    ((b[1] - a[1]) / (b[0] - a[0])).abs()
                }
            })
            .fold(0.0, f64::max)
    }

    /// The piece of the cycle that holds phase `p` in [0, 1): the segment
    /// (no jump) from corner `a` to corner `b` with a.u <= p < b.u, where
    /// the segment that wraps past the cycle's end is shifted back a cycle
    /// when `p` lies before the first corner.
    pub fn piece_at(&self, p: f64) -> ([f64; 2], [f64; 2]) {
        let mut pieces = self.segments().filter(|(a, b)| b[0] > a[0]);
        let first = pieces.next().expect("a waveform rises or falls");
        if p < first.0[0] {
            let (a, b) = self
                .segments()
                .filter(|(a, b)| b[0] > a[0])
                .last()
                .unwrap_or(first);
            return ([a[0] - 1.0, a[1]], [b[0] - 1.0, b[1]]);
        }
        std::iter::once(first)
            .chain(pieces)
            .find(|(_, b)| p < b[0])
            .unwrap_or(first)
    }

    /// Each segment of one cycle, from a corner to the next (the last to
    /// the first a cycle later).
    pub fn segments(&self) -> impl Iterator<Item = ([f64; 2], [f64; 2])> + '_ {
        let n = self.points.len();
        (0..n).map(move |k| {
            let a = self.points[k];
            let b = if k + 1 < n {
                self.points[k + 1]
            } else {
                [self.points[0][0] + 1.0, self.points[0][1]]
            };
            (a, b)
        })
    }
}
