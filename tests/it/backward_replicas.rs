//! The backward travel of split instances (issue 59 with issue 39's
//! replicas): each replica keeps its total variation beside its step, the
//! group merges the variation's sums at the level its step merged (a
//! phase split) or adds its pieces' variations over the joined cycle (a
//! cycle split), and never decides. So the step's values are those of the
//! group that keeps no variation, bit for bit, and the backward travel
//! agrees with the instance's own run's within their errors (a phase
//! split) or to rounding (a periodic motion), under both laws.

use pidm::backend::{Backend, CpuBackend};
use pidm::laws::status::STATUS_OK;
use pidm::laws::{Replicas, Settings};
use pidm::measurement::{Outcome, reduce, reduce_variation};
use pidm::model::Instance;
use pidm::replicas::{self, cpu::run_group};

use crate::steady::steady;

/// The settings of `count` replicas, with or without the backward travel.
fn settings(count: u32, backward: bool) -> Settings {
    Settings {
        replicas: Replicas::Count(count),
        backward,
        ..Settings::default()
    }
}

/// Per own drive cycle [um] of a travel over `span` periods on `axis`.
fn per_cycle(inst: &Instance, axis: usize, travel: f64, span: f64) -> f64 {
    inst.measure_over(axis, travel, span).1 * 1e6
}

/// A phase split (10 against 10 sqrt 2 Hz) and a cycle split (21.34
/// against 23.66 Hz, periodic after 1067 periods), four replicas each on
/// the CPU: the step as without the variation, bit for bit; the total
/// variation per cycle within 3 of the larger standard error + 0.002 um
/// of the run alone's (phase), or within 1e-6 um of it (the joined
/// cycle, whose errors are 0); and at least the step's magnitude.
#[test]
fn replicas_follow_the_backward_travel_and_change_no_step() {
    let cases = [
        (
            "phase split",
            steady(10.0, 10.0 * 2f64.sqrt(), 2, 1e-8, 20_000),
            false,
        ),
        ("cycle split", steady(21.34, 23.66, 2, 1e-8, 10_000), true),
    ];
    for (name, inst, cycle) in cases {
        let (plain, with) = (settings(4, false), settings(4, true));
        let split = replicas::split_of(&inst, &with, 4).expect("splits");
        assert_eq!(
            (split.count, split.cycle > 0),
            (4, cycle),
            "{name}: {split:?}"
        );
        let without = run_group(&inst, &plain, split, &|| false).expect("ran");
        let group = run_group(&inst, &with, split, &|| false).expect("ran");
        assert_eq!(group.replicas, 4, "{name}: {group:?}");
        assert_eq!(group.measured, without.measured, "{name}: the step moved");
        assert_eq!(without.variation, None, "{name}: kept unasked");
        let (variation, variation_se) = group.variation.expect("kept");
        let (run, v) = pidm::laws::Law::run_with_variation_until(&inst, &with, || false).unwrap();
        let alone = reduce(&inst, &run);
        let (alone_variation, alone_se) = reduce_variation(&inst, &run, &v);
        for axis in 0..2 {
            let merged = per_cycle(&inst, axis, variation[axis], group.measured.span);
            let own = per_cycle(&inst, axis, alone_variation[axis], alone.span);
            let step = per_cycle(
                &inst,
                axis,
                group.measured.travel[axis],
                group.measured.span,
            );
            let se = variation_se[axis].max(alone_se[axis]) * 1e6;
            eprintln!(
                "{name} axis {axis}: variation {merged:.6} um (alone {own:.6} +- {se:.6}), step {step:+.6} um"
            );
            let allowed = if cycle { 1e-6 } else { 3.0 * se + 0.002 };
            assert!(
                (merged - own).abs() <= allowed,
                "{name} axis {axis}: {merged} against {own} um"
            );
            assert!(
                merged >= step.abs() - 1e-9,
                "{name} axis {axis}: {merged} below |{step}|"
            );
            if cycle {
                assert_eq!(variation_se[axis], 0.0, "{name}: a periodic motion's error");
            }
        }
    }
}

/// A LuGre two-frequency instance split into four replicas on the CPU
/// backend: the step's outcome as without the variation, and the
/// variation within 3 of the larger error + 0.002 um per cycle of the
/// instance run alone (`replicas = 1`).
#[test]
fn lugre_replicas_follow_the_backward_travel() {
    let scene = |replicas: u32, backward: bool| {
        pidm::scene::Scene::from_toml(
            &format!(
                "name = \"lugre_backward\"\n[mechanism]\nfriction = \"lugre\"\n\
                 [axis.x]\nvoltage = 100.0\nfrequency = 7.13\n\
                 [axis.y]\nvoltage = 100.0\nfrequency = 9.71\n\
                 [simulation]\nreplicas = {replicas}\n[output]\nbackward = {backward}\n"
            ),
            None,
        )
        .unwrap()
    };
    let cpu = CpuBackend::new(None).unwrap();
    let run = |replicas, backward| -> (Instance, Outcome) {
        let scene = scene(replicas, backward);
        let inst = scene.instance(0);
        let out = cpu.run(&[inst], &scene.settings, &|_| {}).unwrap()[0];
        (inst, out)
    };
    let (inst, split) = run(4, true);
    let (_, plain) = run(4, false);
    let (_, alone) = run(1, true);
    assert_eq!((split.status, split.replicas), (STATUS_OK, 4), "{split:?}");
    assert_eq!(
        (split.displacement, split.span, split.se, split.periods),
        (plain.displacement, plain.span, plain.se, plain.periods),
        "the step moved"
    );
    for axis in 0..2 {
        let merged = per_cycle(&inst, axis, split.variation[axis], split.span);
        let own = per_cycle(&inst, axis, alone.variation[axis], alone.span);
        let se = split.variation_se[axis].max(alone.variation_se[axis]) * 1e6;
        eprintln!("LuGre axis {axis}: variation {merged:.6} um, alone {own:.6} +- {se:.6} um");
        assert!(
            merged > 0.0 && (merged - own).abs() <= 3.0 * se + 0.002,
            "axis {axis}: {merged} against {own}"
        );
    }
}

/// Issue 59's instance that `replicas = "auto"` splits in two (100 V at
/// 10 Hz against 60 V at 10 sqrt 2 Hz): `pidm run` with two replicas
/// writes the step maps of the run without `[output] backward` bit for
/// bit, from two replicas, and a backward travel within its errors of the
/// instance's own run (`replicas = 1`).
#[test]
fn pidm_run_splits_with_the_backward_travel() {
    use crate::common::{pidm, s};
    let dir = tempfile::tempdir().expect("a temporary directory");
    let d = dir.path();
    let run = |name: &str, replicas: u32, backward: bool| -> hdf5::File {
        let scene = d.join(format!("{name}.toml"));
        std::fs::write(
            &scene,
            format!(
                "name = \"{name}\"\n[axis.x]\nvoltage = 100\n\
                 [axis.y]\nvoltage = 60\nfrequency = 14.142135623730951\n\
                 [simulation]\nreplicas = {replicas}\n[output]\nbackward = {backward}\n"
            ),
        )
        .expect("written");
        let out = d.join(format!("{name}.h5"));
        let ran = pidm(&["run", s(&scene), "--out", s(&out)], d);
        let said = String::from_utf8_lossy(&ran.stderr);
        assert!(ran.status.success(), "{said}");
        // auto weighs a split backward run as any: one integration is
        // too few for a GPU.
        assert!(said.contains("too few for a GPU"), "{said}");
        hdf5::File::open(&out).expect("a result file")
    };
    let read = |f: &hdf5::File, name: &str| -> f64 {
        f.dataset(&format!("maps/{name}"))
            .unwrap()
            .read_raw::<f64>()
            .unwrap()[0]
    };
    let (split, plain, alone) = (
        run("split", 2, true),
        run("plain", 2, false),
        run("alone", 1, true),
    );
    for name in ["step_x", "step_y", "step_x_se", "step_y_se", "velocity_x"] {
        assert_eq!(
            read(&split, name).to_bits(),
            read(&plain, name).to_bits(),
            "{name}"
        );
    }
    let replicas: Vec<u32> = split.dataset("maps/replicas").unwrap().read_raw().unwrap();
    assert_eq!(replicas, [2]);
    for axis in ["x", "y"] {
        let (a, b) = (
            read(&split, &format!("backward_{axis}")),
            read(&alone, &format!("backward_{axis}")),
        );
        let se = read(&split, &format!("backward_{axis}_se"))
            .max(read(&alone, &format!("backward_{axis}_se")));
        eprintln!("backward_{axis}: {a:e} m from 2 replicas, {b:e} +- {se:e} m alone");
        assert!(
            a > 0.0 && (a - b).abs() <= 3.0 * se + 2e-9,
            "backward_{axis}: {a} against {b} +- {se}"
        );
    }
}
