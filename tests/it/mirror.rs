//! The f32 CPU mirror (`pidm::cpu::single`): the integrator's source
//! compiled in f32 with the f32 shader's formulation, against the f64
//! reference. Its agreement with the shader itself is pinned in `gpu.rs`
//! (`the_f32_shader_takes_the_steps_of_its_mirror`).

use pidm::cpu::integrate::{self as reference, STATUS_OK, Settings};
use pidm::cpu::single::{integrate as mirror, si};
use pidm::measurement::window_displacement;
use pidm::model::Instance;

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
    instances.extend(pidm::random::random_instances(5, 50, 4, 1));
    for inst in &instances {
        assert_eq!(
            reference::Coefficients::of(inst, &settings),
            reference::Coefficients::new(inst, &settings, f64::EPSILON)
        );
    }
}

/// The mirror holds the f32 shader's bar on random scenes: every step
/// within 0.005 um + 1 % of the f64 reference's, every status OK.
#[test]
fn f32_mirror_holds_the_step_tolerance_on_random_scenes() {
    let settings = Settings::default();
    let mut worst = (0.0, String::new());
    let mut outside = Vec::new();
    for seed in [1u64, 2, 3] {
        for (k, inst) in pidm::random::random_instances(seed, 300, 4, 1)
            .iter()
            .enumerate()
        {
            let exact = reference::run_instance(inst, &settings).state;
            let f32_run = si::run(&mirror::run_instance(inst, &settings));
            assert_eq!(exact.status, STATUS_OK, "seed {seed} #{k}: f64 status");
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
        "f32 mirror, random scenes: worst {:.3} of the allowance ({})",
        worst.0, worst.1
    );
    assert!(outside.is_empty(), "outside the allowance: {outside:#?}");
}

/// Like the reference, the mirror integrates in slices to the same state
/// bit for bit as in one go, and twice to the same state.
#[test]
fn f32_mirror_runs_in_slices_and_repeats_bit_for_bit() {
    let settings = Settings::default();
    for inst in pidm::random::random_instances(7, 20, 3, 1) {
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

/// The mirror's steady measurement (MODEL.md section 4) measures as the
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
        let exact = reduce(inst, &reference::run_instance(inst, &settings));
        let single = reduce(inst, &si::run(&mirror::run_instance(inst, &settings)));
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
