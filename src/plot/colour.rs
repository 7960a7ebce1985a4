//! Colours: the diverging scale of steps and ratios, the axis colours and
//! the greys for instances without a value.

use plotters::style::RGBColor;

/// The colour of instances with a non-zero status: a neutral grey that no
/// colour scale here uses.
pub const FAILED: RGBColor = RGBColor(120, 120, 120);
/// Instances whose steady measurement ran to max_cycles (status 6): their
/// estimate is in the file, with its standard error, but not drawn as a
/// value.
pub const NOT_STEADY: RGBColor = RGBColor(200, 200, 200);

/// Instances whose step keeps its direction under every load probed (no
/// stall load, stall status 8): a violet no diverging scale here uses.
pub const NO_STALL: RGBColor = RGBColor(118, 42, 131);

/// The colour of cells where a ratio is undefined (1-DOF step about zero).
pub const UNDEFINED: RGBColor = RGBColor(205, 205, 205);

/// ColorBrewer's RdBu, from the most negative (dark blue) through the
/// neutral midpoint (near white) to the most positive (dark red).
const RDBU: [(u8, u8, u8); 11] = [
    (5, 48, 97),
    (33, 102, 172),
    (67, 147, 195),
    (146, 197, 222),
    (209, 229, 240),
    (247, 247, 247),
    (253, 219, 199),
    (244, 165, 130),
    (214, 96, 77),
    (178, 24, 43),
    (103, 0, 31),
];

/// The colour at the midpoint of the diverging scale (the middle class of
/// [`RDBU`]).
#[cfg(test)]
const NEUTRAL: RGBColor = RGBColor(RDBU[5].0, RDBU[5].1, RDBU[5].2);

/// A diverging colour scale with limits symmetric about its centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Diverging {
    /// The value drawn in the neutral colour.
    pub centre: f64,
    /// Distance from the centre to either end of the scale; values beyond
    /// are drawn at the ends.
    pub half_width: f64,
}

impl Diverging {
    /// The scale that just covers `values` (non-finite ones ignored), with
    /// limits symmetric about `centre`, its half width at least
    /// `min_half_width` (so values that differ from the centre by less, such
    /// as rounding noise around zero, stay pale) and at most
    /// `max_half_width` (values beyond are drawn at the ends).
    pub fn covering(
        values: impl IntoIterator<Item = f64>,
        centre: f64,
        min_half_width: f64,
        max_half_width: f64,
    ) -> Self {
        let spread = values
            .into_iter()
            .filter(|v| v.is_finite())
            .fold(0.0f64, |m, v| m.max((v - centre).abs()));
        Diverging {
            centre,
            half_width: spread.min(max_half_width).max(min_half_width),
        }
    }

    /// The lowest and highest value of the scale.
    pub fn limits(&self) -> (f64, f64) {
        (self.centre - self.half_width, self.centre + self.half_width)
    }

    /// Position of `value` on the scale, 0 (low end) to 1 (high end), 0.5 at
    /// the centre.
    pub fn fraction(&self, value: f64) -> f64 {
        (0.5 + 0.5 * (value - self.centre) / self.half_width).clamp(0.0, 1.0)
    }

    /// The colour of `value`.
    pub fn colour(&self, value: f64) -> RGBColor {
        rdbu(self.fraction(value))
    }
}

/// RdBu at a fraction 0..1 (linear between the eleven classes); exactly
/// [`NEUTRAL`] at 0.5.
pub fn rdbu(fraction: f64) -> RGBColor {
    let x = fraction.clamp(0.0, 1.0) * (RDBU.len() - 1) as f64;
    let i = (x.floor() as usize).min(RDBU.len() - 2);
    let t = x - i as f64;
    let (a, b) = (RDBU[i], RDBU[i + 1]);
    let mix = |p: u8, q: u8| (p as f64 + (q as f64 - p as f64) * t).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// The colour of everything along x: blue.
pub(super) const X_COLOUR: RGBColor = RGBColor(33, 102, 172);
/// The colour of everything along y: red.
pub(super) const Y_COLOUR: RGBColor = RGBColor(178, 24, 43);

/// The colour of axis `axis` (0 = x, 1 = y).
pub(super) fn axis_colour(axis: usize) -> RGBColor {
    if axis == 0 { X_COLOUR } else { Y_COLOUR }
}

/// A colour blended towards white by `keep` (1: unchanged).
pub(super) fn light(c: RGBColor, keep: f64) -> RGBColor {
    let f = |v: u8| (255.0 - (255.0 - v as f64) * keep).round() as u8;
    RGBColor(f(c.0), f(c.1), f(c.2))
}

/// The colour of 1-DOF runs in trajectory figures.
pub(super) const BASELINE_GREY: RGBColor = RGBColor(150, 150, 150);
/// The background band of the settle periods in trajectory figures.
pub(super) const SETTLE_GREY: RGBColor = RGBColor(236, 236, 236);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_colour_scale_is_centred_and_symmetric() {
        let scale = Diverging::covering([-0.5, 2.0, 1.0, f64::NAN], 0.0, 1e-3, f64::INFINITY);
        assert_eq!(scale.limits(), (-2.0, 2.0), "symmetric about zero");
        assert_eq!(scale.colour(0.0), NEUTRAL, "zero is the neutral midpoint");
        assert_eq!(scale.fraction(0.0), 0.5);
        assert_eq!(scale.fraction(-2.0), 0.0);
        assert_eq!(scale.fraction(2.0), 1.0);
        assert_eq!(scale.fraction(7.0), 1.0, "values beyond are clamped");
        assert_eq!(rdbu(0.5), NEUTRAL);
        // Opposite signs take opposite hues: negative blue, positive red.
        let (neg, pos) = (scale.colour(-1.5), scale.colour(1.5));
        assert!(neg.2 > neg.0 && pos.0 > pos.2, "{neg:?} {pos:?}");
        // Equal magnitudes are equally far from neutral.
        assert_eq!(
            scale.fraction(-1.5) - 0.5,
            0.5 - scale.fraction(1.5),
            "symmetric"
        );
        // Noise around zero stays pale; a cap bounds outliers; other centres.
        let noise = Diverging::covering([1e-10, -3e-10], 0.0, 1e-3, f64::INFINITY);
        assert_eq!(noise.half_width, 1e-3);
        let capped = Diverging::covering([100.0, 1.5], 1.0, 0.25, 3.0);
        assert_eq!(capped.limits(), (-2.0, 4.0));
        assert_eq!(capped.colour(1.0), NEUTRAL);
        let empty = Diverging::covering([], 0.0, 0.5, 3.0);
        assert_eq!(empty.limits(), (-0.5, 0.5));
    }
}
