//! The f32 CPU mirror (`pidm::laws::karnopp::single`): the integrator's source
//! compiled in f32 with the f32 shader's formulation, against the f64
//! reference. Its agreement with the shader itself is pinned in `gpu.rs`
//! (`the_f32_shader_takes_the_steps_of_its_mirror`).

use pidm::backend::Precision;
use pidm::backend::cpu::{run_one, run_one_in};
use pidm::laws::Settings;
use pidm::laws::karnopp::integrate as reference;
use pidm::laws::karnopp::single::{integrate as mirror, si};
use pidm::laws::status::STATUS_GRAZE;
use pidm::laws::status::STATUS_OK;
use pidm::measurement::window_displacement;
use pidm::model::{Instance, Measure};

/// Allowed f32 error per axis: 0.005 um + 1 % of the f64 step [um] (issue
/// 19's bar for the f32 shader).
fn f32_allowance(step_um: f64) -> f64 {
    0.005 + 0.01 * step_um.abs()
}

/// The f64 instance's coefficients are its reference ones: `of` in SI
/// units rounds nothing.
#[test]
fn f64_coefficients_of_an_instance_are_the_reference_ones() {
    let settings = Settings::default();
    let mut instances = vec![Instance::TABLE1];
    instances.extend(pidm::model::random::random_instances(5, 50, 4, 1));
    for inst in &instances {
        assert_eq!(
            reference::Coefficients::of(inst, &settings),
            reference::Coefficients::new(inst, &settings, f64::EPSILON)
        );
    }
}

/// The mirror holds the f32 shader's bar on random scenes: every step
/// within 0.005 um + 1 % of the f64 reference's, every status OK but the
/// band grazes it stops at (`STATUS_GRAZE`), which are few; through the
/// backend those carry the reference's own value.
#[test]
fn f32_mirror_holds_the_step_tolerance_on_random_scenes() {
    let scenes =
        [1u64, 2, 3].map(|seed| (seed, pidm::model::random::random_instances(seed, 300, 4, 1)));
    mirror_holds_the_step_tolerance("random scenes", &scenes);
}

/// The same bar under a load on the slider (docs/model.md section 7): the random
/// scenes under random loads up to 0.9 f_c, and the issue's
/// step-against-load points, whose steps reach 120 um.
#[test]
fn f32_mirror_holds_the_step_tolerance_under_loads() {
    let scenes = [
        (
            1u64,
            crate::common::loaded(&pidm::model::random::random_instances(1, 300, 4, 1), 11),
        ),
        (
            2,
            crate::common::loaded(&pidm::model::random::random_instances(2, 300, 4, 1), 12),
        ),
        (0, crate::common::load_sweep_instances()),
    ];
    mirror_holds_the_step_tolerance("loaded scenes", &scenes);
}

/// Every instance of `scenes` ((seed, instances): the seed only names
/// them) in the f32 mirror against the f64 reference: within 0.005 um + 1 %
/// or stopped at a band graze, which carries the reference's value through
/// the backend and is rare.
fn mirror_holds_the_step_tolerance(name: &str, scenes: &[(u64, Vec<Instance>)]) {
    let settings = Settings::default();
    let mut worst = (0.0, String::new());
    let mut outside = Vec::new();
    let (mut grazes, mut instances) = (0, 0);
    for (seed, scene) in scenes {
        for (k, inst) in scene.iter().enumerate() {
            instances += 1;
            let exact = reference::run_instance(inst, &settings).state;
            let f32_run = si::run(&mirror::run_instance(inst, &settings));
            assert_eq!(exact.status, STATUS_OK, "seed {seed} #{k}: f64 status");
            if f32_run.state.status == STATUS_GRAZE {
                grazes += 1;
                let via_backend = run_one_in(inst, &settings, Precision::F32);
                assert!(via_backend.on_cpu, "seed {seed} #{k}: a graze runs in f64");
                assert_eq!(
                    via_backend.displacement,
                    run_one(inst, &settings).displacement,
                    "seed {seed} #{k}: a graze carries the reference's value"
                );
                continue;
            }
            assert_eq!(
                f32_run.state.status, STATUS_OK,
                "seed {seed} #{k}: f32 status"
            );
            let (e, m) = (
                window_displacement(inst, &exact),
                window_displacement(inst, &f32_run.state),
            );
            for i in 0..2 {
                let c = inst.measure(i, e[i]).1 * 1e6;
                let v = inst.measure(i, m[i]).1 * 1e6;
                let ratio = (v - c).abs() / f32_allowance(c);
                let what = format!("seed {seed} #{k} axis {i}: f32 {v:.5} um, f64 {c:.5} um");
                if ratio > worst.0 {
                    worst = (ratio, what.clone());
                }
                if ratio > 1.0 {
                    outside.push(what);
                }
            }
        }
    }
    eprintln!(
        "f32 mirror, {name}: worst {:.3} of the allowance ({}); {grazes} of {instances} \
         stopped at a band graze",
        worst.0, worst.1
    );
    assert!(outside.is_empty(), "outside the allowance: {outside:#?}");
    // About 4 % of random instances graze (results/gpu.md); far more would
    // make the f32 path a CPU path.
    assert!(
        grazes * 100 <= 8 * instances,
        "{grazes} of {instances} grazes"
    );
}

/// One instance the f32 formulation without the graze guard got wrong:
/// the mirror stops it at a graze, and through the backend it carries the
/// f64 reference's value. (seed, index) of `pidm random-scene --count
/// 3000`, and f32's error without the guard in allowances.
fn check_graze(seed: u64, k: usize, unguarded_error: f64) {
    let settings = Settings::default();
    let inst = pidm::model::random::random_instances(seed, k + 1, 4, 1)[k];
    let what = format!("seed {seed} #{k} (unguarded f32 {unguarded_error} allowances off)");
    let raw = mirror::run_instance(&inst, &settings).state;
    assert_eq!(raw.status, STATUS_GRAZE, "{what}: the mirror's status");
    let via_backend = run_one_in(&inst, &settings, Precision::F32);
    let reference = run_one(&inst, &settings);
    assert!(via_backend.on_cpu, "{what}: integrated again in f64");
    assert_eq!(via_backend.status, reference.status, "{what}: status");
    assert_eq!(
        via_backend.displacement, reference.displacement,
        "{what}: the reference's value"
    );
}

/// Issue 19: band grazes decide these steps, and f32 without the guard
/// decided them otherwise than the f64 reference (results/gpu.md, "Band
/// grazes"): the f32 shader's three misses over eighteen seeds, and three
/// of the mirror's four.
#[test]
fn f32_hands_band_grazes_to_the_reference() {
    for (seed, k, error) in [
        (5, 1920, 2.2),
        (21, 83, 3.5),
        (56, 2196, 40.8),
        (4, 43, 2.8),
        (21, 2776, 1.0),
        // (34, 934, 17.6) grazes no more under issue 47's step rule, and
        // f32 gets it right.
        (52, 1525, 40.6),
    ] {
        check_graze(seed, k, error);
    }
}

/// A steady measurement is not stopped at a graze: its value is the long
/// run's mean, which a graze on the way does not move (`sweeps/
/// frequency.toml`: 312 of 1,296 instances graze, and the unguarded f32
/// mirror is within 0.01 of the allowance on all), so the mirror runs the
/// steady twin of a grazing window to its end.
#[test]
fn f32_steady_measurements_run_through_grazes() {
    let settings = Settings::default();
    let mut inst = pidm::model::random::random_instances(21, 84, 4, 1)[83];
    assert_eq!(
        mirror::run_instance(&inst, &settings).state.status,
        STATUS_GRAZE
    );
    inst.measure = Measure::Steady {
        step_tolerance: Measure::DEFAULT_STEP_TOLERANCE,
    };
    inst.cycles = 12;
    let steady = mirror::run_instance(&inst, &settings).state;
    assert_ne!(steady.status, STATUS_GRAZE);
    assert!(!run_one_in(&inst, &settings, Precision::F32).on_cpu);
}

/// Like the reference, the mirror integrates in slices to the same state
/// bit for bit as in one go, and twice to the same state.
#[test]
fn f32_mirror_runs_in_slices_and_repeats_bit_for_bit() {
    let settings = Settings::default();
    for inst in pidm::model::random::random_instances(7, 20, 3, 1) {
        let whole = mirror::run_instance(&inst, &settings);
        assert_eq!(whole, mirror::run_instance(&inst, &settings));
        let c = mirror::Coefficients::of(&inst, &settings);
        let mut st = mirror::initial_state(&c);
        let mut m = mirror::initial_measure(&c);
        while !mirror::is_finished(&c, &st) {
            mirror::advance(&c, &mut st, &mut m, 7);
        }
        assert_eq!(st, whole.state);
    }
}

/// The mirror's steady measurement (docs/model.md section 4) measures as the
/// reference does: the same status on the periodic, the quasi-periodic
/// and the cut-short instances of `gpu.rs`'s steady test, and every step
/// within three combined standard errors + 0.002 um plus the f32
/// allowance of the f64 value.
#[test]
fn f32_mirror_measures_steady_steps_as_the_reference() {
    use pidm::measurement::reduce;
    let instances = crate::common::steady_instances();
    let settings = Settings::default();
    for (k, inst) in instances.iter().enumerate() {
        let exact = reduce(inst, &reference::run_instance(inst, &settings).ended());
        let single = reduce(
            inst,
            &si::run(&mirror::run_instance(inst, &settings)).ended(),
        );
        assert_eq!(single.status, exact.status, "#{k}: status");
        assert_eq!(single.lag, exact.lag, "#{k}: the detected cycle");
        assert_eq!(single.periods, exact.periods, "#{k}: periods run");
        for i in 0..2 {
            let a = inst.measure_over(i, single.travel[i], single.span).1 * 1e6;
            let b = inst.measure_over(i, exact.travel[i], exact.span).1 * 1e6;
            let bound = 3.0 * (single.se[i] + exact.se[i]) * 1e6 + 0.002 + f32_allowance(b);
            assert!(
                (a - b).abs() <= bound,
                "#{k} axis {i}: f32 {a} um, f64 {b} um"
            );
        }
    }
}

/// Issue 19: the mirror's backend checks its heaviest runs as the shader's
/// batches do on a software adapter (`pidm::laws::floor::check`, the reference
/// route). Six instances the guarded mirror got wrong on the fresh seeds
/// 61-80 (results/gpu.md, "The heaviest tenth"), among 24 light ones: the
/// heaviest fifth of the runs that neither failed nor grazed (by the
/// unchecked mirror's steps) is checked and only it, every run on the CPU
/// was checked or grazed, and the six carry the f64 reference's value (two
/// of them reach it at a band graze since issue 47's step rule).
#[test]
fn the_f32_mirror_checks_its_heaviest_runs_against_the_reference() {
    use pidm::backend::{Backend, CpuBackend};
    use pidm::laws::floor::check::{heaviest, is_candidate};
    let settings = Settings::default();
    let mut instances = Vec::new();
    for (seed, k) in [
        (63, 1160),
        (64, 864),
        (65, 2480),
        (65, 2754),
        (79, 457),
        (79, 2094),
    ] {
        instances.push(pidm::model::random::random_instances(seed, 3000, 4, 1)[k]);
    }
    instances.extend(crate::common::light_instances(24, 2.0));
    let backend = CpuBackend::with_precision(Some(2), Precision::F32).expect("a pool");
    let out = backend
        .run(&instances, &settings, &|_| {})
        .expect("the mirror runs");
    let unchecked: Vec<_> = instances
        .iter()
        .map(|inst| run_one_in(inst, &settings, Precision::F32))
        .collect();
    let candidates: Vec<(usize, u32)> = unchecked
        .iter()
        .zip(&instances)
        .enumerate()
        .filter(|(_, (u, inst))| is_candidate(inst, u.status, u.on_cpu))
        .map(|(k, (u, _))| (k, u.steps))
        .collect();
    let picked = heaviest(&candidates);
    let mut missed = 0;
    for (k, (o, inst)) in out.iter().zip(&instances).enumerate() {
        assert_eq!(o.checked, picked.contains(&k), "#{k}: checked");
        assert_eq!(
            o.on_cpu,
            o.checked || unchecked[k].on_cpu,
            "#{k}: on the CPU"
        );
        if k < 6 {
            let reference = run_one(inst, &settings);
            assert!(o.on_cpu, "#{k}: on the CPU");
            assert_eq!(
                o.displacement, reference.displacement,
                "#{k}: the reference"
            );
            missed += (0..2).any(|i| {
                let c = reference.step(inst, i) * 1e6;
                (unchecked[k].step(inst, i) * 1e6 - c).abs() > f32_allowance(c)
            }) as usize;
        }
    }
    // The check is what puts them right: unchecked, the mirror misses.
    assert!(missed >= 1, "the unchecked mirror now gets all six right");
}
