//! The floor drive's tests: each waveform's corners against the model's
//! sawtooth and one another, the refusals, and the slew-limited orbit
//! against a hand-solved case and its defining properties.

use super::*;
use crate::model::sawtooth;

/// Levels of `c` and `w` agree within `tol` on a grid over two cycles.
fn check_levels(c: &Corners, w: impl Fn(f64) -> f64, tol: f64) {
    for k in 0..=2000 {
        let u = k as f64 / 1000.0 - 0.5;
        let (got, want) = (c.level(u), w(u));
        assert!(
            (got - want).abs() <= tol,
            "u {u}: {got} against {want}, {c:?}"
        );
    }
}

#[test]
fn a_sawtooth_is_the_models() {
    for duty in [0.98, 0.5, 0.3, 1.0] {
        let c = Waveform::Sawtooth { duty }.corners();
        check_levels(&c, |u| sawtooth(u, duty), 1e-15);
    }
}

/// The trapezoid (d, 0, 1 - d), the table of that shape and the sawtooth
/// of duty d are one waveform; so are a duty-1 ramp and its table.
#[test]
fn a_trapezoid_and_a_table_of_the_sawtooths_shape_are_the_sawtooth() {
    for duty in [0.98, 0.7, 0.25] {
        let saw = Waveform::Sawtooth { duty }.corners();
        let trapezoid = Waveform::Trapezoid {
            rise: duty,
            hold: 0.0,
            fall: 1.0 - duty,
        };
        trapezoid.check().unwrap();
        assert_eq!(trapezoid.corners(), saw);
        let table = Waveform::Table(vec![[0.0, 0.0], [duty, 1.0]]);
        table.check().unwrap();
        assert_eq!(table.corners(), saw);
    }
    let ramp = Waveform::Table(vec![[0.0, 1.0], [0.0, 0.0]]);
    assert_eq!(ramp.corners(), Waveform::Sawtooth { duty: 1.0 }.corners());
}

#[test]
fn a_trapezoid_rises_holds_falls_and_dwells() {
    let c = Waveform::Trapezoid {
        rise: 0.2,
        hold: 0.3,
        fall: 0.1,
    }
    .corners();
    let want = |u: f64| {
        let p = u - u.floor();
        if p < 0.2 {
            p / 0.2
        } else if p < 0.5 {
            1.0
        } else if p < 0.6 {
            (0.6 - p) / 0.1
        } else {
            0.0
        }
    };
    check_levels(&c, want, 1e-12);
    // A rise of 0 is a jump, and a hold of the whole cycle is a constant.
    let jump = Waveform::Trapezoid {
        rise: 0.0,
        hold: 0.5,
        fall: 0.0,
    }
    .corners();
    check_levels(&jump, |u| if u - u.floor() < 0.5 { 1.0 } else { 0.0 }, 0.0);
    let flat = Waveform::Trapezoid {
        rise: 0.0,
        hold: 1.0,
        fall: 0.0,
    };
    check_levels(&flat.corners(), |_| 1.0, 0.0);
    assert_eq!(flat.corners().steepest(), 0.0);
}

/// Each refusal names its key.
#[test]
fn bad_waveforms_are_refused_by_key() {
    let table = |e: &[[f64; 2]]| Waveform::Table(e.to_vec());
    let trapezoid = |rise, hold, fall| Waveform::Trapezoid { rise, hold, fall };
    let too_many: Vec<[f64; 2]> = (0..65).map(|k| [k as f64 / 65.0, 0.0]).collect();
    let cases = [
        (table(&[[0.5, 0.0], [0.2, 1.0]]), "table", "no earlier"),
        (table(&[[0.0, 0.0], [1.0, 1.0]]), "table", "[0, 1)"),
        (table(&[[0.0, 0.0], [0.5, 1.5]]), "table", "[-1, 1]"),
        (
            table(&[[0.0, 0.0], [0.5, 1.0], [0.5, 0.0], [0.5, 1.0]]),
            "table",
            "two",
        ),
        (table(&[[0.0, 0.0]]), "table", "2 to 64"),
        (Waveform::Table(too_many), "table", "2 to 64"),
        (trapezoid(-0.1, 0.5, 0.5), "rise", "at least 0"),
        (trapezoid(0.1, f64::NAN, 0.5), "hold", "at least 0"),
        (trapezoid(0.0, 0.0, 0.0), "rise", "sum"),
        (trapezoid(0.5, 0.4, 0.2), "rise", "sum"),
        (Waveform::Sawtooth { duty: 0.0 }, "duty", "(0, 1]"),
        (Waveform::Sawtooth { duty: 1.5 }, "duty", "(0, 1]"),
    ];
    for (w, key, says) in cases {
        let e = w.check().expect_err("refused");
        assert_eq!(e.key, key, "{w:?}");
        assert!(e.to_string().contains(says), "{e}");
    }
    table(&[[0.0, 0.0], [0.5, 1.0], [0.5, -1.0]])
        .check()
        .unwrap();
}

/// A slew limit no flank reaches changes nothing, bit for bit.
#[test]
fn a_slew_limit_above_every_flank_is_no_limit() {
    let c = Waveform::Sawtooth { duty: 0.9 }.corners();
    assert!((c.steepest() - 10.0).abs() < 1e-12);
    assert_eq!(c.slew_limited(c.steepest()), c);
    assert_eq!(c.slew_limited(1e9), c);
}

/// A sawtooth of duty 0.9 whose fall is limited to 5 levels a cycle: the
/// follower falls from 1 at u = 0.9 until it meets the next rise, at u =
/// 1 + 0.45 / 5.5 (1 - 5 (x + 0.1) = x / 0.9, solved by hand), and tracks
/// from there.
#[test]
fn a_slew_limited_fall_meets_the_next_rise() {
    let c = Waveform::Sawtooth { duty: 0.9 }.corners().slew_limited(5.0);
    let meet = 0.45 / 5.5 + 1.0;
    let want = |u: f64| {
        let p = u - u.floor();
        if p < 0.9 {
            let falling = 1.0 - 5.0 * (p + 1.0 - 0.9);
            if p < meet - 1.0 { falling } else { p / 0.9 }
        } else {
            1.0 - 5.0 * (p - 0.9)
        }
    };
    check_levels(&c, want, 1e-12);
}

/// On any waveform the follower's orbit is continuous, never steeper than
/// the limit, and the same every cycle; where the waveform jumps up and
/// down faster than the limit allows, it never meets it (bisection).
#[test]
fn a_slew_limited_orbit_is_continuous_periodic_and_limited() {
    let shapes = [
        Waveform::Sawtooth { duty: 1.0 },
        Waveform::Trapezoid {
            rise: 0.0,
            hold: 0.3,
            fall: 0.0,
        },
        Waveform::Table(vec![
            [0.0, -1.0],
            [0.2, 0.8],
            [0.2, -0.3],
            [0.6, 1.0],
            [0.9, 0.0],
        ]),
    ];
    for shape in shapes {
        for sigma in [0.5, 2.0, 7.0, 40.0] {
            let c = shape.corners().slew_limited(sigma);
            for (a, b) in c.segments() {
                assert!(b[0] > a[0], "a jump in {c:?}");
                let slope = (b[1] - a[1]) / (b[0] - a[0]);
                assert!(slope.abs() <= sigma * (1.0 + 1e-9), "{slope} in {c:?}");
            }
            let start = c.level(0.0);
            assert!((c.level(1.0) - start).abs() < 1e-12);
            // The orbit's level is the follower's from its own start.
            let again = c.follow(start, sigma);
            assert!((again.last().unwrap().y - start).abs() < 1e-9, "{c:?}");
        }
    }
}

/// The orbit against a follower stepped by brute force: the slew-limited
/// level moves toward the waveform by at most sigma dt a step, over 40
/// cycles from 0; its last cycle is the orbit within the step's size.
#[test]
fn the_orbit_is_where_a_stepped_follower_settles() {
    let shapes = [
        Waveform::Sawtooth { duty: 0.8 },
        Waveform::Trapezoid {
            rise: 0.0,
            hold: 0.3,
            fall: 0.1,
        },
        Waveform::Table(vec![[0.1, -1.0], [0.4, 0.8], [0.4, -0.3], [0.9, 1.0]]),
    ];
    let steps = 20_000;
    let dt = 1.0 / steps as f64;
    for shape in shapes {
        let target = shape.corners();
        for sigma in [0.7, 3.0, 12.0] {
            let orbit = target.slew_limited(sigma);
            let mut y = 0.0;
            let mut worst: f64 = 0.0;
            for cycle in 0..40 {
                for k in 0..steps {
                    let u = (k as f64 + 1.0) * dt;
                    y += (target.level(u) - y).clamp(-sigma * dt, sigma * dt);
                    if cycle == 39 {
                        worst = worst.max((y - orbit.level(u)).abs());
                    }
                }
            }
            assert!(worst < 1e-3, "{shape:?} at {sigma}: {worst}");
        }
    }
}

/// A slew-limited drive is the same drive in every unit system: the f32
/// shader's units (um, ms) scale `slew_rate` with the frequency, so the
/// limit in levels per cycle, and the corners, stay what they are in SI.
#[test]
fn slew_limited_corners_do_not_depend_on_the_units() {
    use crate::laws::floor::units::Units;
    let mut inst = crate::model::Instance::TABLE1;
    inst.axes[0].slew_rate = 3e4;
    let si = axis_corners(&inst.axes[0]);
    let scaled = axis_corners(&Units::MICRO_MILLI.scale(&inst).axes[0]);
    assert!(si.points.len() > 2, "the limit is active: {si:?}");
    assert_eq!(si.points.len(), scaled.points.len());
    for (a, b) in si.points.iter().zip(&scaled.points) {
        assert!(
            (a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12,
            "{a:?} {b:?}"
        );
    }
}
