//! Two drive frequencies (issue 31): common periods from the frequencies as
//! written, the phase-resolved estimate (`pidm::laws::floor::phase`)
//! against long references, near resonances, and the kind of motion each
//! run records (`/maps/motion`).

use pidm::laws::status::STATUS_NOT_STEADY;
use pidm::laws::status::STATUS_OK;
use pidm::measurement::Measured;
use pidm::model::Instance;
use pidm::model::motion::Motion;

use crate::common::{pidm, s};
use crate::steady::{measure, steady, step_um, window};

/// Asserts that each axis' step of `got` lies within 3 standard errors +
/// 0.002 um of `reference`'s [um], printing both.
fn covers(name: &str, inst: &Instance, got: &Measured, reference: [f64; 2]) {
    for (axis, b) in reference.into_iter().enumerate() {
        let a = step_um(inst, got, axis);
        let se = got.se[axis] * 1e6;
        eprintln!(
            "{name} axis {axis}: status {} ({:?}) after {} periods, {a:+.5} +- {se:.5} um; \
             reference {b:+.5} um",
            got.status, got.motion, got.periods
        );
        assert!(
            (a - b).abs() <= 3.0 * se + 0.002,
            "{name} axis {axis}: {a} +- {se} um against {b} um"
        );
    }
}

/// 21.34 and 23.66 Hz repeat after 1067 periods of the 21.34 Hz drive
/// (beyond the old search of 1000, so the map of issue 31 left them "not
/// steady" at 10,000 periods): found periodic with a lag that is a
/// multiple of 1067, an exact step (a window over the detected cycle
/// gives it to 1e-6 um) and no standard error. They lie near 10/9, where
/// the phases of 1,000 periods bunch into 46 arcs: stopped there, the run
/// is not steady, and its standard error covers its distance to the exact
/// step.
#[test]
fn two_decimal_frequencies_repeat_after_their_common_period() {
    let inst = steady(21.34, 23.66, 2, 1e-8, 10_000);
    let got = measure(&inst);
    assert_eq!(got.status, STATUS_OK, "{got:?}");
    assert!(got.lag > 0 && got.lag.is_multiple_of(1067), "{got:?}");
    assert_eq!(got.se, [0.0, 0.0]);
    assert_eq!(got.motion, Motion::Periodic);
    assert!(got.periods <= 2 * 1067 + 2, "{got:?}");
    let mut cycle = window(&inst, got.periods);
    cycle.settle = got.periods - got.lag;
    let exact = measure(&cycle);
    let steps = [0, 1].map(|axis| step_um(&cycle, &exact, axis));
    for (axis, b) in steps.into_iter().enumerate() {
        let a = step_um(&inst, &got, axis);
        assert!((a - b).abs() < 1e-6, "axis {axis}: {a} um, window {b} um");
    }
    let cut = steady(21.34, 23.66, 2, 1e-8, 1000);
    let short = measure(&cut);
    assert_eq!(short.status, STATUS_NOT_STEADY, "{short:?}");
    assert_eq!(short.motion, Motion::Undetermined);
    covers("21.34 / 23.66 Hz stopped at 1000", &cut, &short, steps);
}

/// An irrational ratio, the issue's 25.98 Hz against 25.98 x 0.96 sqrt 2
/// Hz: quasi-periodic, converged to 0.01 um (in 1,362 periods; 10 Hz
/// against 10 sqrt 2 Hz converges in 962, `steady::
/// a_quasi_periodic_standard_error_covers_the_error_against_a_long_run`),
/// and its standard error covers its distance to a 20,000-period window
/// (whose own error is about the oscillation range over 20,000 periods,
/// 0.002 um). And a near resonance, 10 Hz against 15.0141 Hz (0.0014
/// cycles per period from 3:2): its phases cover the circle only after
/// about 700 periods, and it converges no earlier than that, or says it is
/// not steady, but is never wrong.
#[test]
fn quasi_periodic_steps_converge_fast_and_cover_a_long_run() {
    let cases = [
        ("25.98 / 35.27 Hz", 25.98, 25.98 * 0.96 * 2f64.sqrt()),
        ("10 / 15.0141 Hz", 10.0, 15.0 + 0.01 * 2f64.sqrt()),
    ];
    let runs: Vec<(Measured, [f64; 2], Instance)> = std::thread::scope(|scope| {
        let handles: Vec<_> = cases
            .iter()
            .map(|&(_, fx, fy)| {
                scope.spawn(move || {
                    let inst = steady(fx, fy, 2, 1e-8, 10_000);
                    let long = window(&inst, 20_002);
                    let reference = measure(&long);
                    let steps = [0, 1].map(|axis| step_um(&long, &reference, axis));
                    (measure(&inst), steps, inst)
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let (quasi, reference, inst) = &runs[0];
    assert_eq!(quasi.status, STATUS_OK, "{quasi:?}");
    assert_eq!(quasi.motion, Motion::QuasiPeriodic);
    assert!(quasi.periods <= 2000, "{quasi:?}");
    assert!(
        quasi.se.iter().all(|&se| se <= 1e-8 * (1.0 + 1e-12)),
        "{quasi:?}"
    );
    covers(cases[0].0, inst, quasi, *reference);
    let (near, reference, inst) = &runs[1];
    assert!(
        near.status == STATUS_OK || near.status == STATUS_NOT_STEADY,
        "{near:?}"
    );
    assert!(near.periods > 680, "{near:?}");
    covers(cases[1].0, inst, near, *reference);
}

/// `/maps/motion` on a small map with one instance of each kind, and the
/// summary's counts: 10 / 14 Hz repeats after 5 periods (periodic); 10 /
/// 10 sqrt 2 Hz is quasi-periodic; and a random instance at one frequency
/// (`pidm random-scene --seed 5`, point 135, both axes at 38.9 Hz with a
/// 0.76 g stage) never repeats within 8 common periods and is not a
/// function of any phase: only its batch means converge (irregular).
#[test]
fn each_kind_of_motion_is_mapped() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = d.join("kinds.toml");
    std::fs::write(
        &scene,
        r#"name = "kinds"
[axis.x]
voltage = 100.0
frequency = 10.0
[axis.y]
voltage = 100.0
frequency = 10.0
[simulation]
step_tolerance = 5e-8
max_cycles = 3000

[[points]]
label = "10 / 14 Hz"
axis.y.frequency = 14.0

[[points]]
label = "10 / 10 sqrt 2 Hz"
axis.y.frequency = 14.142135623730951

[[points]]
label = "random 135"
mechanism = { slider_mass = 0.01993236496451117, static_friction = 0.8115104497563089, coulomb_friction = 0.3229814314183403, velocity_band = 1.2659958894161014e-6 }
axis.x = { stage_mass = 0.0007616601235063126, stiffness = 349218.9592462832, damping = 0.4117215535486394, gain = -0.6, voltage = -15.901192100218708, frequency = 38.889395369166, duty = 0.6285951376998208, phase = 0.4134980590611882 }
axis.y = { stage_mass = 0.0037993192709642435, stiffness = 709391.8036570002, damping = 2.724928470128627, gain = -0.6, voltage = -34.62010027905498, frequency = 38.889395369166, duty = 0.7169729462732813, phase = 0.3388566640549282 }
"#,
    )
    .unwrap();
    let out = d.join("kinds.h5");
    let run = pidm(&["run", s(&scene), "--out", s(&out), "--backend", "cpu"], d);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        stdout.contains("  motion: 1 periodic, 1 quasi_periodic, 1 irregular, 0 undetermined\n"),
        "{stdout}"
    );
    let file = hdf5::File::open(&out).unwrap();
    let motion: Vec<u8> = file.dataset("maps/motion").unwrap().read_raw().unwrap();
    let kinds = [Motion::Periodic, Motion::QuasiPeriodic, Motion::Irregular];
    assert_eq!(motion, kinds.map(Motion::code));
    let status: Vec<u32> = file.dataset("maps/status").unwrap().read_raw().unwrap();
    assert_eq!(status, [0, 0, 0]);
    let lag: Vec<u32> = file.dataset("maps/period_lag").unwrap().read_raw().unwrap();
    assert_eq!(lag, [5, 0, 0]);
}
