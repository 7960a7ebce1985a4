//! Coupling regimes: how the motion along one axis changes when the other
//! axis is driven too.

use plotters::style::RGBColor;

use super::colour::FAILED;

/// Steps smaller than this in magnitude count as no motion in the coupling
/// regimes and ratios [m]: 0.001 um, the accuracy the maps are claimed to
/// have at the default tolerance.
pub const ZERO_STEP_M: f64 = 1e-9;

/// How the motion along one axis changes when the other axis is driven too:
/// the 2-DOF step against the 1-DOF step (the axis driven alone).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Regime {
    /// Both move, in opposite directions.
    Reversed,
    /// The 2-DOF step is larger in magnitude, same direction.
    Amplified,
    /// The axis moves only when the other is driven too (its 1-DOF step is
    /// about zero).
    Started,
    /// The 2-DOF step is smaller in magnitude, same direction.
    Reduced,
    /// The two steps agree within [`ZERO_STEP_M`].
    Unchanged,
    /// The axis moves alone but not in 2-DOF.
    Stalled,
    /// The axis moves in neither.
    AtRest,
    /// The instance or a baseline ended with a non-zero status.
    Failed,
}

impl Regime {
    /// Every regime, in legend order.
    pub const ALL: [Regime; 8] = [
        Regime::Reversed,
        Regime::Amplified,
        Regime::Started,
        Regime::Reduced,
        Regime::Unchanged,
        Regime::Stalled,
        Regime::AtRest,
        Regime::Failed,
    ];

    /// Classifies a 2-DOF step against its 1-DOF step [m]; `ok` is false
    /// when either run ended with a non-zero status.
    pub fn classify(two_dof: f64, one_dof: f64, ok: bool) -> Regime {
        Regime::classify_within(two_dof, one_dof, ok, ZERO_STEP_M)
    }

    /// [`Regime::classify`] with `zero` [m] in place of [`ZERO_STEP_M`]:
    /// steps (and differences) smaller than it count as none. The adaptive
    /// refinement labels points with its tolerance.
    pub fn classify_within(two_dof: f64, one_dof: f64, ok: bool, zero: f64) -> Regime {
        let moves = |s: f64| s.abs() >= zero;
        if !ok || !two_dof.is_finite() || !one_dof.is_finite() {
            Regime::Failed
        } else if !moves(two_dof) && !moves(one_dof) {
            Regime::AtRest
        } else if !moves(two_dof) {
            Regime::Stalled
        } else if (two_dof - one_dof).abs() < zero {
            Regime::Unchanged
        } else if !moves(one_dof) {
            Regime::Started
        } else if two_dof.signum() != one_dof.signum() {
            Regime::Reversed
        } else if two_dof.abs() > one_dof.abs() {
            Regime::Amplified
        } else {
            Regime::Reduced
        }
    }

    /// Its colour in regime maps.
    pub fn colour(self) -> RGBColor {
        match self {
            Regime::Reversed => RGBColor(33, 102, 172),
            Regime::Amplified => RGBColor(178, 24, 43),
            Regime::Started => RGBColor(118, 42, 131),
            Regime::Reduced => RGBColor(244, 165, 130),
            Regime::Unchanged => RGBColor(230, 220, 180),
            Regime::Stalled => RGBColor(20, 20, 20),
            Regime::AtRest => RGBColor(255, 255, 255),
            Regime::Failed => FAILED,
        }
    }

    /// Its legend text.
    pub fn describe(self) -> &'static str {
        match self {
            Regime::Reversed => "reversed: opposite sign to 1-DOF",
            Regime::Amplified => "amplified: |2-DOF| > |1-DOF|",
            Regime::Started => "started: moves only in 2-DOF",
            Regime::Reduced => "reduced: |2-DOF| < |1-DOF|",
            Regime::Unchanged => "unchanged (within 0.001 µm)",
            Regime::Stalled => "stalled: moves only in 1-DOF",
            Regime::AtRest => "at rest in both",
            Regime::Failed => "not computed (status ≠ 0)",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regimes_classify_2dof_against_1dof() {
        let um = 1e-6;
        // (2-DOF step, 1-DOF step, both finished normally, expected regime).
        let cases = [
            (0.5 * um, 0.6 * um, true, Regime::Reduced),
            (0.9 * um, 0.6 * um, true, Regime::Amplified),
            (-0.9 * um, 0.6 * um, true, Regime::Reversed),
            (0.1 * um, -0.6 * um, true, Regime::Reversed),
            (-0.1 * um, -0.6 * um, true, Regime::Reduced),
            (-1.6 * um, -0.6 * um, true, Regime::Amplified),
            (0.6 * um, 0.6 * um, true, Regime::Unchanged),
            (
                0.6 * um + 0.5 * ZERO_STEP_M,
                0.6 * um,
                true,
                Regime::Unchanged,
            ),
            (0.0, 0.6 * um, true, Regime::Stalled),
            (0.3 * ZERO_STEP_M, -0.6 * um, true, Regime::Stalled),
            (0.4 * um, 0.0, true, Regime::Started),
            (-0.4 * um, 0.2 * ZERO_STEP_M, true, Regime::Started),
            (0.0, 0.0, true, Regime::AtRest),
            (0.5 * ZERO_STEP_M, -0.5 * ZERO_STEP_M, true, Regime::AtRest),
            (0.5 * um, 0.6 * um, false, Regime::Failed),
            (f64::NAN, 0.6 * um, true, Regime::Failed),
        ];
        for (two, one, ok, want) in cases {
            check_regime(two, one, ok, want);
        }
        // Every regime has its own colour and text.
        for (i, a) in Regime::ALL.iter().enumerate() {
            for b in &Regime::ALL[i + 1..] {
                assert_ne!(a.colour(), b.colour(), "{a:?} {b:?}");
                assert_ne!(a.describe(), b.describe());
            }
        }
    }

    fn check_regime(two_dof: f64, one_dof: f64, ok: bool, want: Regime) {
        let got = Regime::classify(two_dof, one_dof, ok);
        assert_eq!(
            got, want,
            "2-DOF {two_dof:e} m against 1-DOF {one_dof:e} m (ok {ok})"
        );
    }
}
