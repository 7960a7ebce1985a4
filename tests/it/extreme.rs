//! `sweeps/extreme.toml` on the CPU reference: every point converges (a
//! tolerance 1000 times tighter moves it by less than the claimed error)
//! with a bounded step count, no value is NaN or infinite, and each class
//! shows the physics it is there for. The GPU side is in `tests/it/gpu.rs`.

use pidm::laws::Settings;
use pidm::laws::karnopp::integrate::{State, run_instance};
use pidm::laws::status::STATUS_OK;
use pidm::measurement::window_displacement as displacement;
use pidm::model::Instance;
use pidm::scene::{Layout, Scene};

/// The error claimed for any instance at the default tolerance [um].
const CLAIMED_ERROR_UM: f64 = 1e-3;

/// The documented step bound for the extreme scene at the default
/// tolerance: steps per scene period (docs/extreme.md; the worst
/// point, a 1 kg slider with f_c = f_s and a 1e-9 m/s band, took 0.49 M
/// per period when last measured: close to the bound, a sliding mode on the
/// rim of the band worth a look).
const MAX_STEPS_PER_PERIOD: f64 = 5e5;

struct Point {
    label: String,
    inst: Instance,
    default: State,
    tight: State,
}

impl Point {
    fn step_um(&self, st: &State, axis: usize) -> f64 {
        self.inst
            .measure(axis, displacement(&self.inst, st)[axis])
            .1
            * 1e6
    }

    fn steps_um(&self) -> [f64; 2] {
        [
            self.step_um(&self.default, 0),
            self.step_um(&self.default, 1),
        ]
    }
}

fn points() -> Vec<Point> {
    let scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/sweeps/extreme.toml").as_ref())
        .expect("the extreme scene loads");
    let Layout::Points { labels } = &scene.layout else {
        panic!("the extreme scene is a points scene");
    };
    let tight = Settings {
        tolerance: scene.settings.tolerance * 1e-3,
        ..scene.settings
    };
    labels
        .iter()
        .enumerate()
        .map(|(k, label)| {
            let inst = scene.instance(k as u64);
            Point {
                label: label.clone(),
                inst,
                default: run_instance(&inst, &scene.settings).state,
                tight: run_instance(&inst, &tight).state,
            }
        })
        .collect()
}

/// What a class of points must show beyond convergence.
enum Expect {
    /// Converges; nothing more specific.
    Converges,
    /// Both steps are zero within `tol_um`: the slider moves with the
    /// stage or not at all.
    NoNetMotion { tol_um: f64 },
    /// The x step is at least `min_um` (free drift, strong drive).
    XStepAtLeast { min_um: f64 },
    /// The y step matches the point labelled `other` within `tol_um`.
    SameAs { other: &'static str, tol_um: f64 },
}

/// Classes by label prefix, each with its expectation.
const CLASSES: [(&str, Expect); 17] = [
    ("stiffness", Expect::NoNetMotion { tol_um: 1e-6 }),
    ("Q 0.5", Expect::Converges),
    ("Q 1", Expect::Converges),
    ("duty", Expect::Converges),
    ("frequency", Expect::Converges),
    ("voltage +1000", Expect::Converges),
    ("voltage 0 V on both", Expect::NoNetMotion { tol_um: 0.0 }),
    ("voltage 0 V on x", Expect::Converges),
    ("friction almost none", Expect::NoNetMotion { tol_um: 0.0 }),
    ("friction f_c = 0", Expect::XStepAtLeast { min_um: 100.0 }),
    ("friction f_s huge", Expect::NoNetMotion { tol_um: 1e-6 }),
    ("friction f_c", Expect::Converges),
    ("slider mass 1e-6", Expect::NoNetMotion { tol_um: 1e-6 }),
    ("slider mass", Expect::Converges),
    (
        "band 1e-9",
        Expect::SameAs {
            other: "band 1e-3 m/s",
            tol_um: 0.01,
        },
    ),
    ("band", Expect::Converges),
    (
        "cycles 300",
        Expect::SameAs {
            other: "band 1e-9 m/s",
            tol_um: 0.01,
        },
    ),
];

fn check(point: &Point, all: &[Point]) {
    let label = &point.label;
    let [x, y] = point.steps_um();
    assert!(x.is_finite() && y.is_finite(), "{label}: {x} {y}");
    assert_eq!(point.default.status, STATUS_OK, "{label}: status");
    assert_eq!(
        point.tight.status, STATUS_OK,
        "{label}: status at the tight tolerance"
    );
    for axis in 0..2 {
        let change = (point.step_um(&point.tight, axis) - point.steps_um()[axis]).abs();
        assert!(
            change <= CLAIMED_ERROR_UM,
            "{label} axis {axis}: moved {change:e} um"
        );
    }
    let periods = point.inst.cycles as f64;
    let per_period = point.default.steps as f64 / periods;
    assert!(
        per_period <= MAX_STEPS_PER_PERIOD,
        "{label}: {per_period} steps per period"
    );
    let Some((_, expect)) = CLASSES.iter().find(|(prefix, _)| label.starts_with(prefix)) else {
        // Combined cases: convergence and the step bound above.
        assert!(label.starts_with("combined"), "{label} belongs to no class");
        return;
    };
    match expect {
        Expect::Converges => {}
        Expect::NoNetMotion { tol_um } => {
            assert!(x.abs() <= *tol_um && y.abs() <= *tol_um, "{label}: {x} {y}");
        }
        Expect::XStepAtLeast { min_um } => assert!(x >= *min_um, "{label}: {x}"),
        Expect::SameAs { other, tol_um } => {
            let other = all
                .iter()
                .find(|p| p.label == *other)
                .expect("the other point");
            for (a, b) in point.steps_um().iter().zip(other.steps_um()) {
                assert!((a - b).abs() <= *tol_um, "{label}: {a} against {b}");
            }
        }
    }
}

#[test]
fn every_extreme_point_converges_within_its_step_bound_and_shows_its_physics() {
    let all = points();
    assert!(all.len() >= 25);
    for point in &all {
        let [x, y] = point.steps_um();
        eprintln!(
            "{:45} {x:+12.6} {y:+12.6} um  {:>8} steps (tight: {})",
            point.label, point.default.steps, point.tight.steps
        );
    }
    for point in &all {
        check(point, &all);
    }
}

#[test]
fn kinetic_friction_above_static_holds_like_static_friction_of_that_size() {
    // With f_c > f_s the slider is held until |f_need| exceeds f_c (the
    // limit of docs/model.md's chatter as the band shrinks): exactly the motion
    // of an interface whose static friction equals f_c.
    let all = points();
    let point = all
        .iter()
        .find(|p| p.label == "friction f_c > f_s")
        .unwrap();
    let mut held = point.inst;
    held.mechanism.static_friction = held.mechanism.coulomb_friction;
    let st = run_instance(&held, &Settings::default()).state;
    assert_eq!(st.status, STATUS_OK);
    assert_eq!(
        displacement(&held, &st),
        displacement(&point.inst, &point.default)
    );
    // And it differs from f_c = f_s at the smaller friction: the class is
    // not degenerate.
    let equal = all
        .iter()
        .find(|p| p.label == "friction f_c = f_s")
        .unwrap();
    assert!((equal.steps_um()[0] - point.steps_um()[0]).abs() > 0.1);
}

/// Stress grid instance #513 (duty 1, 100 V at 10 Hz and 40 V at 35 Hz,
/// f_c 0.3 N, band 1e-9 m/s), where a 2-D pass of the relative velocity
/// comes within the band of zero, and a regular point. `TOLERANCE` is
/// replaced by each tolerance tried.
const PLATEAU_SCENE: &str = r#"
name = "plateau"
[axis.x]
voltage = 100.0
duty = 1.0
[axis.y]
voltage = 40.0
frequency = 35.0
[mechanism]
coulomb_friction = 0.3
velocity_band = 1e-9
[simulation]
measure = "window"
cycles = 3
settle = 1
tolerance = TOLERANCE
[[points]]
label = "stress #513"
[[points]]
label = "regular"
mechanism.velocity_band = 1e-6
axis.y.phase = 0.37
"#;

/// `--verify` keeps what a 100 times tighter tolerance confirms and marks
/// (status 5, zero in the map) what it moves, pinned both ways: at the
/// default tolerance both points, #513 included, are within the claimed
/// error of the converged value and verify; at 1e-2 both move by more
/// than verify's allowance and are marked, the regular point by more than
/// 0.1 um.
#[test]
fn verify_marks_what_a_tighter_tolerance_moves_and_keeps_the_rest() {
    let dir = tempfile::tempdir().unwrap();
    let run = |tolerance: &str, verify: bool| -> (Vec<f64>, Vec<u32>) {
        let text = PLATEAU_SCENE.replace("TOLERANCE", tolerance);
        let scene_path = dir.path().join(format!("plateau-{tolerance}.toml"));
        std::fs::write(&scene_path, &text).unwrap();
        let out = dir.path().join(format!("plateau-{tolerance}-{verify}.h5"));
        let mut args = vec![
            "run",
            scene_path.to_str().unwrap(),
            "--backend",
            "cpu",
            "--out",
            out.to_str().unwrap(),
        ];
        if verify {
            args.push("--verify");
        }
        let status = std::process::Command::new(env!("CARGO_BIN_EXE_pidm"))
            .args(&args)
            .output()
            .unwrap()
            .status;
        // Exit code 3 says some instance has a non-zero status.
        assert!(status.success() || status.code() == Some(3), "{status}");
        let file = hdf5::File::open(&out).unwrap();
        let step: Vec<f64> = file.dataset("maps/step_x").unwrap().read_raw().unwrap();
        let codes: Vec<u32> = file.dataset("maps/status").unwrap().read_raw().unwrap();
        (step, codes)
    };
    let scene = Scene::from_toml(&PLATEAU_SCENE.replace("TOLERANCE", "1e-4"), None).unwrap();
    let converged = Settings {
        tolerance: 1e-8,
        ..scene.settings
    };
    let truth: Vec<f64> = (0..2)
        .map(|k| {
            let inst = scene.instance(k as u64);
            let st = run_instance(&inst, &converged).state;
            assert_eq!(st.status, STATUS_OK);
            inst.measure(0, displacement(&inst, &st)[0]).1
        })
        .collect();
    let check = |tolerance: &str, off: bool| {
        let (plain, plain_status) = run(tolerance, false);
        let (verified, verified_status) = run(tolerance, true);
        assert_eq!(plain_status, [0, 0], "tolerance {tolerance}");
        for k in 0..2 {
            let error_um = (plain[k] - truth[k]).abs() * 1e6;
            eprintln!(
                "tolerance {tolerance}, point {k}: {:+.6} um against {:+.6} um converged, \
                 verify status {}",
                plain[k] * 1e6,
                truth[k] * 1e6,
                verified_status[k]
            );
            if off {
                // The regular point is far off; #513's x step stays near
                // the converged one (the slip step's limit toward the
                // band resolves its pass at any tolerance: issue 47), but
                // its y step moves by more than verify's 1e-9 m.
                if k == 1 {
                    assert!(error_um > 0.1, "point {k}: only {error_um} um off");
                }
                assert_eq!(verified_status[k], 5, "point {k}");
                assert_eq!(verified[k], 0.0);
            } else {
                assert!(error_um <= CLAIMED_ERROR_UM, "point {k}: {error_um} um off");
                assert_eq!(verified_status[k], 0, "point {k}");
                assert_eq!(verified[k], plain[k]);
            }
        }
    };
    check("1e-4", false);
    check("1e-2", true);
}
