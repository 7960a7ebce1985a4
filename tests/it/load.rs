//! A constant load on the slider (docs/model.md section 7) in the f64 CPU
//! integrator: the reference values from an independent
//! implementation, the physics a load must show (an undriven axis that
//! rings and holds, a load on one axis moving the other, a breakaway at
//! t = 0), its symmetries, and every shipped scene unloaded bit for bit
//! what the binary before the load computed.

use pidm::laws::Settings;
use pidm::laws::karnopp::integrate::{
    Coefficients, MODE_STICK, StepMotion, StepObserver, advance_observed, initial_measure,
    initial_state, is_finished,
};
use pidm::laws::status::STATUS_OK;
use pidm::model::{Instance, Measure};
use pidm::sweep::{self, run_one};

use std::path::Path;

use crate::common::{manifest, pidm, s};
use crate::golden::{file_digests, golden_lines};

/// The point: Table 1, 10 Hz, duty 0.98, 100 V on x, `vy` on y,
/// a window of 10 periods of which 2 settle, and a load `load` [N] on x.
fn point(vy: f64, load: f64) -> Instance {
    let mut inst = Instance::TABLE1;
    inst.axes[1].voltage = vy;
    inst.mechanism.load = [load, 0.0];
    inst
}

/// Steps per own drive cycle [um] of one instance on the f64 CPU
/// integrator; the run must finish normally.
fn steps_um(inst: &Instance) -> [f64; 2] {
    let out = run_one(inst, &Settings::default());
    assert_eq!(out.status, STATUS_OK, "{inst:?}");
    let rec = sweep::record(inst, &out);
    [rec.step[0] * 1e6, rec.step[1] * 1e6]
}

/// The reference values, each given to the digits it prints: the
/// ends of the step-against-load sweep with y at 100 V (step_x and step_y,
/// 0.1 um).
#[test]
fn the_ends_of_the_load_sweep_match_the_independent_reference() {
    let cases = [(-0.95, [-77.7, -5.4]), (0.95, [115.9, 6.7])];
    for (load, want) in cases {
        let got = steps_um(&point(100.0, load));
        for axis in 0..2 {
            assert!(
                (got[axis] - want[axis]).abs() <= 0.05 + 1e-3,
                "L_x {load} N axis {axis}: {:.4} um, want {} um",
                got[axis],
                want[axis]
            );
        }
    }
}

/// step_x rises monotonically with L_x across the whole admissible range
/// (y at 100 V), from the reference's -77.7 um to +115.9 um.
#[test]
fn the_x_step_rises_monotonically_with_the_x_load() {
    let loads: Vec<f64> = (-19..=19).map(|k| 0.05 * k as f64).collect();
    let steps: Vec<f64> = loads
        .iter()
        .map(|&l| steps_um(&point(100.0, l))[0])
        .collect();
    for (pair, load) in steps.windows(2).zip(&loads) {
        assert!(
            pair[1] > pair[0],
            "step_x falls from {:.4} to {:.4} um after L_x = {load} N",
            pair[0],
            pair[1]
        );
    }
}

/// The stall loads of the reference, to its three digits: the step changes
/// sign between the two loads the printed value rounds from, and the
/// unloaded steps and the slopes there are the reference's.
#[test]
fn the_stall_loads_match_the_independent_reference() {
    // (V_y, stall load [N], unloaded step [um], slope [um/N]).
    let cases = [(0.0, -0.0379, 0.616, 16.2), (100.0, 0.0792, -0.942, 12.1)];
    for (vy, stall, unloaded, slope) in cases {
        let at = |load: f64| steps_um(&point(vy, load))[0];
        let zero = at(0.0);
        assert!(
            (zero - unloaded).abs() <= 0.5e-3 + 1e-4,
            "V_y {vy}: unloaded {zero:.5} um, want {unloaded}"
        );
        let (below, above) = (at(stall - 0.5e-4), at(stall + 0.5e-4));
        assert!(
            below < 0.0 && above > 0.0,
            "V_y {vy}: the step does not change sign about {stall} N: {below:.6}, {above:.6} um"
        );
        let measured = (above - below) / 1e-4;
        assert!(
            (measured - slope).abs() <= 0.05 + 0.01 * slope,
            "V_y {vy}: slope {measured:.3} um/N, want {slope}"
        );
    }
}

/// Whether the slider ever leaves stick in a run, and its state at the end.
struct SlipWatch {
    slipped: bool,
}

impl StepObserver for SlipWatch {
    fn step(&mut self, st: &pidm::laws::karnopp::integrate::State, _motion: &StepMotion) {
        self.slipped |= st.mode != MODE_STICK;
    }
}

/// Runs `inst` to the end on the f64 integrator and says whether it ever
/// slipped, with the final slider positions [m].
fn watch(inst: &Instance) -> (bool, [f64; 2]) {
    let c = Coefficients::of(inst, &Settings::default());
    let mut st = initial_state(&c);
    let mut m = initial_measure(&c);
    let mut watch = SlipWatch { slipped: false };
    while !is_finished(&c, &st) {
        advance_observed(&c, &mut st, &mut m, 1 << 14, &mut watch);
        watch.slipped |= st.mode != MODE_STICK;
    }
    assert_eq!(st.status, STATUS_OK);
    (watch.slipped, st.x_s.to_array())
}

/// docs/model.md section 7: the load comes on at t = 0, and the stuck stage and
/// slider ring. Undriven, Table 1 holds only below 0.7364 N (the first
/// swing of the ring, damped by the stuck body's Q of 27, asks for
/// (1 + 2/3 x 0.944) L of friction), far below the static limit f_s (m_p +
/// m_s) / m_p = 3.6 N; above it the slider slips a few times, comes to
/// rest, and its window step is exactly zero.
#[test]
fn an_undriven_slider_rings_under_its_load_and_holds_below_0_7364_n() {
    for (load, slips) in [(0.7, false), (0.7360, false), (0.7368, true), (0.9, true)] {
        for axis in 0..2 {
            let mut inst = Instance::TABLE1;
            inst.axes[0].voltage = 0.0;
            inst.axes[1].voltage = 0.0;
            inst.mechanism.load[axis] = load;
            let (slipped, _) = watch(&inst);
            assert_eq!(slipped, slips, "L_{axis} = {load} N");
            assert_eq!(steps_um(&inst), [0.0, 0.0], "L_{axis} = {load} N");
        }
    }
}

/// A load on x moves x even where only y is driven (the shared interface
/// slips along the combined force), and moves it along the load.
#[test]
fn a_load_on_one_axis_moves_that_axis_under_the_other_drive() {
    for load in [-0.3, 0.3] {
        let mut inst = Instance::TABLE1;
        inst.axes[0].voltage = 0.0;
        inst.axes[1].voltage = 100.0;
        inst.mechanism.load = [load, 0.0];
        let got = steps_um(&inst);
        assert!(
            got[0] * load > 0.01,
            "L_x {load} N with only y driven: step_x {:.4} um",
            got[0]
        );
    }
    // Unloaded, x stays exactly at rest (docs/model.md section 6).
    let mut inst = Instance::TABLE1;
    inst.axes[0].voltage = 0.0;
    assert_eq!(steps_um(&inst)[0], 0.0);
}

/// With a phase on y the drive at t = 0 already asks for more friction than
/// the interface holds: the first slip starts at t = 0, where no sign change
/// of the breakaway function announces it (the trap the issue reports), and
/// the load does not hide it.
#[test]
fn a_drive_past_breakaway_at_t_0_slips_at_once() {
    for load in [0.0, 0.5, -0.5] {
        let mut inst = Instance::TABLE1;
        inst.axes[1].voltage = 100.0;
        inst.axes[1].phase = 0.5;
        inst.mechanism.load = [0.0, load];
        let c = Coefficients::of(&inst, &Settings::default());
        let mut st = initial_state(&c);
        let mut m = initial_measure(&c);
        // The first iteration locates the breakaway at the start.
        advance_observed(
            &c,
            &mut st,
            &mut m,
            1,
            &mut pidm::laws::karnopp::integrate::NoObserver,
        );
        assert_ne!(st.mode, MODE_STICK, "L_y {load} N");
        assert_eq!(st.time, 0.0, "L_y {load} N");
    }
}

/// docs/model.md section 6's invariants with a load: negating one axis' voltage
/// and its load negates that axis' step and leaves the other's; swapping
/// the axes, loads included, swaps the steps.
#[test]
fn negating_and_swapping_carry_the_load_along() {
    let mut inst = Instance::TABLE1;
    inst.axes[1].voltage = 70.0;
    inst.mechanism.load = [0.2, -0.3];
    let base = steps_um(&inst);
    let mut negated = inst;
    negated.axes[0].voltage = -negated.axes[0].voltage;
    negated.mechanism.load[0] = -negated.mechanism.load[0];
    let got = steps_um(&negated);
    assert!((got[0] + base[0]).abs() <= 1e-9 * base[0].abs().max(1.0));
    assert!((got[1] - base[1]).abs() <= 1e-9 * base[1].abs().max(1.0));
    let mut swapped = inst;
    swapped.axes.swap(0, 1);
    swapped.mechanism.load.swap(0, 1);
    let got = steps_um(&swapped);
    assert!((got[0] - base[1]).abs() <= 1e-9 * base[1].abs().max(1.0));
    assert!((got[1] - base[0]).abs() <= 1e-9 * base[0].abs().max(1.0));
}

/// The 1-DOF baseline of axis i carries the load (L_i, 0) on its own axis
/// (docs/model.md section 7).
#[test]
fn each_baseline_carries_its_own_axis_load() {
    let mut inst = Instance::TABLE1;
    inst.mechanism.load = [0.1, -0.2];
    assert_eq!(inst.baseline(0).mechanism.load, [0.1, 0.0]);
    assert_eq!(inst.baseline(1).mechanism.load, [0.0, -0.2]);
    assert_eq!(inst.baseline(0).axes[1].voltage, 0.0);
}

/// The runs whose every computed dataset must be what the golden binary
/// wrote (tests/golden/zero_load.txt's header names it): every shipped
/// scene in f64 on the CPU, window and steady, and three in the f32
/// mirror, as (label, scene, precision). `tests/golden/write_goldens.sh`
/// runs them as this test does and digests them.
const RUNS: [(&str, &str, &str); 13] = [
    ("beats", "beats", "f64"),
    ("coupling", "coupling", "f64"),
    ("extreme", "extreme", "f64"),
    ("frequency", "frequency", "f64"),
    ("paper", "paper", "f64"),
    ("paper_text", "paper_text", "f64"),
    ("random", "random", "f64"),
    ("refine_coupling", "refine_coupling", "f64"),
    ("stress", "stress", "f64"),
    ("two_frequency", "two_frequency", "f64"),
    ("paper_f32", "paper", "f32"),
    ("coupling_f32", "coupling", "f32"),
    ("stress_f32", "stress", "f32"),
];

/// `scene` as a copy under `dir/label` that runs every steady instance
/// as one chain (`replicas = 1`): the binary before the load had no
/// replicas, and `auto` splits whatever a batch leaves threads for.
fn single_chains(scene: &str, dir: &Path, label: &str) -> String {
    let parsed = pidm::scene::Scene::load(Path::new(scene)).unwrap();
    let steady = (0..parsed.instance_count())
        .any(|i| matches!(parsed.instance(i).measure, Measure::Steady { .. }));
    if !steady {
        return scene.to_owned();
    }
    let text = std::fs::read_to_string(scene).unwrap();
    let text = if text.contains("\n[simulation]\n") {
        text.replacen("\n[simulation]\n", "\n[simulation]\nreplicas = 1\n", 1)
    } else {
        format!("{text}\n[simulation]\nreplicas = 1\n")
    };
    let copy = dir.join(label);
    std::fs::create_dir_all(&copy).unwrap();
    let copy = copy.join(Path::new(scene).file_name().unwrap());
    std::fs::write(&copy, text).unwrap();
    copy.to_str().unwrap().to_owned()
}

/// With no load every result is bit for bit what it was before the load
/// existed: every map, baseline, trajectory and refinement dataset of every
/// shipped scene, window and steady, f64 and the f32 mirror (the load's
/// terms are subtractions of +0, which change no value, -0 included). The
/// golden lines were the pre-load binary's (8894696) until issue 47
/// changed the integrator's steps; since, the binary's that changed them
/// (tests/golden/write_goldens.sh), which holds every later change that
/// means to keep the results to them.
#[test]
fn zero_load_results_match_the_pre_load_binary_bit_for_bit() {
    let golden = std::fs::read_to_string(manifest("tests/golden/zero_load.txt"))
        .expect("tests/golden/zero_load.txt");
    let dir = tempfile::tempdir().unwrap();
    let mut checked = 0;
    for (label, scene, precision) in RUNS {
        let out = dir.path().join(format!("{label}.h5"));
        let path = single_chains(
            &manifest(&format!("sweeps/{scene}.toml")),
            dir.path(),
            label,
        );
        let run = pidm(
            &[
                "run",
                &path,
                "--backend",
                "cpu",
                "--precision",
                precision,
                "--progress",
                "none",
                "--out",
                s(&out),
            ],
            dir.path(),
        );
        assert!(
            run.status.success(),
            "{label}: {}",
            String::from_utf8_lossy(&run.stderr)
        );
        let file = hdf5::File::open(&out).unwrap();
        let mut got = file_digests(&file);
        // The replica counts came after the load: one chain each (0 for a
        // refined map's inferred points).
        let replicas = got.iter().position(|g| g.0 == "/maps/replicas");
        let replicas = got.remove(replicas.expect("/maps/replicas"));
        let ones: Vec<u32> = file.dataset("maps/replicas").unwrap().read_raw().unwrap();
        assert_eq!(replicas.1, ones.len());
        let split = ones.iter().filter(|&&r| r > 1).count();
        assert_eq!(split, 0, "{label}: instances split into replicas");
        let want = golden_lines(&golden, label);
        assert!(!want.is_empty(), "{label}: no golden lines");
        assert_eq!(
            got.iter().map(|g| &g.0).collect::<Vec<_>>(),
            want.iter().map(|w| &w.0).collect::<Vec<_>>(),
            "{label}: the datasets differ"
        );
        for (g, w) in got.iter().zip(&want) {
            assert_eq!(g, w, "{label}: {} differs from the pre-load binary's", w.0);
        }
        checked += got.len();
    }
    let lines = golden.lines().filter(|l| !l.starts_with('#')).count();
    assert_eq!(checked, lines, "golden lines checked");
}
