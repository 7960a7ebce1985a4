//! The backward travel (issue 59, docs/model.md section 4 "Backward
//! travel"): measuring it changes no step, it follows the step's estimate
//! under both laws, LuGre's tends to Karnopp's, and a scene's backward
//! maps are written, merged and refused as docs/output.md and
//! docs/scenes.md say. Its agreement with SciPy is
//! `crosscheck::waveforms_slew_limits_and_backward_travel_agree_with_scipy_on_the_cpu`;
//! the waveform invariants `waveform::a_sawtooths_trapezoid_and_table_step_as_the_sawtooth`.

use pidm::laws::Settings;
use pidm::laws::status::STATUS_OK;
use pidm::model::{Friction, Instance, Lugre, Measure};
use pidm::sweep::{self, run_one};

use crate::common::{pidm, run_maps, s};
use pidm::model::random::random_instances;

fn backward() -> Settings {
    Settings {
        backward: true,
        ..Settings::default()
    }
}

/// Steady from period 1, under LuGre (`stribeck_velocity` 1e-5 m/s,
/// `bristle_stiffness` sigma0) where given.
fn steady(mut inst: Instance, lugre: Option<f64>) -> Instance {
    inst.settle = 1;
    inst.cycles = 3000;
    inst.measure = Measure::Steady {
        step_tolerance: Measure::DEFAULT_STEP_TOLERANCE,
    };
    if let Some(sigma0) = lugre {
        inst.mechanism.friction = Friction::Lugre(Lugre {
            stribeck_velocity: 1e-5,
            bristle_stiffness: sigma0,
            ..Lugre::DEFAULT
        });
    }
    inst
}

/// The step's outcome does not move when the run also keeps the slider's
/// total variation, bit for bit: windows and steady runs of every verdict
/// (periodic, phase-resolved at 10 / 14.1421 Hz, converged or not steady
/// on random instances), under both laws; and the backward travel is at
/// least 0, its ratio in [0, 1], both finite.
#[test]
fn measuring_the_backward_travel_changes_no_step() {
    let mut cases: Vec<Instance> = random_instances(5, 12, 8, 2);
    let mut incommensurate = Instance::TABLE1;
    incommensurate.axes[1].frequency = 10.0 * 2f64.sqrt();
    incommensurate.axes[1].voltage = 60.0;
    cases.push(steady(incommensurate, None));
    cases.push(steady(Instance::TABLE1, None));
    cases.push(steady(Instance::TABLE1, Some(1e8)));
    let mut two = Instance::TABLE1;
    two.axes[1].frequency = 14.0;
    cases.push(steady(two, Some(1e9)));
    for inst in random_instances(9, 6, 60, 4) {
        cases.push(steady(Instance { cycles: 60, ..inst }, None));
    }
    let mut verdicts = std::collections::BTreeSet::new();
    for (k, inst) in cases.iter().enumerate() {
        let plain = run_one(inst, &Settings::default());
        let kept = run_one(inst, &backward());
        let bits = |o: &sweep::Outcome| {
            (
                o.displacement.map(f64::to_bits),
                o.span.to_bits(),
                o.se.map(f64::to_bits),
                (o.periods, o.lag, o.status, o.motion, o.steps),
            )
        };
        assert_eq!(bits(&plain), bits(&kept), "instance {k}: {inst:?}");
        verdicts.insert(format!("{:?}", kept.motion));
        let rec = sweep::record(inst, &kept);
        assert_eq!(rec.implausibility(), None, "instance {k}");
        let b = rec.backward;
        for i in 0..2 {
            assert!(b.travel[i] >= 0.0 && b.ratio[i] >= 0.0 && b.ratio[i] <= 1.0);
        }
        if inst.axes[0].voltage != 0.0 && kept.status == STATUS_OK {
            assert!(
                b.travel[0] > 0.0,
                "instance {k}: the slider goes back: {b:?}"
            );
        }
    }
    // Periodic, quasi-periodic and (random short runs) undetermined at least.
    assert!(verdicts.len() >= 3, "{verdicts:?}");
}

/// docs/model.md section 8's Karnopp limit, for the backward travel: at
/// sigma0 = 1e10 N/m, 1-DOF, 100 V, v_S = 1e-5 m/s, LuGre's backward
/// travel is within 1 % of Karnopp's (measured: 72.73 against 73.17 um,
/// 0.59 %) and its step within 0.65 % (0.6122 against 0.6159 um, 0.61 %,
/// the step section 8 gives).
#[test]
fn lugres_backward_travel_tends_to_karnopps() {
    let mut inst = Instance::TABLE1;
    inst.axes[1].voltage = 0.0;
    let travel = |lugre: Option<f64>| {
        let inst = steady(inst, lugre);
        let out = run_one(&inst, &backward());
        assert_eq!(out.status, STATUS_OK);
        let rec = sweep::record(&inst, &out);
        (rec.step[0], rec.backward.travel[0], rec.backward.ratio[0])
    };
    let (karnopp, lugre) = (travel(None), travel(Some(1e10)));
    let relative = |a: f64, b: f64| (a - b).abs() / b.abs();
    assert!(
        relative(lugre.1, karnopp.1) <= 0.01,
        "backward {lugre:?} against {karnopp:?}"
    );
    assert!(
        relative(lugre.0, karnopp.0) <= 0.0065,
        "step {lugre:?} against {karnopp:?}"
    );
    assert!(karnopp.1 > 50e-6 && karnopp.2 > 0.9, "{karnopp:?}");
    // A window of whole cycles of this periodic motion (10 / 2) measures
    // what the steady run does, under both laws: the window's start is
    // where each law sets it.
    for lugre in [None, Some(1e10)] {
        let steady_travel = travel(lugre).1;
        let mut window = steady(inst, lugre);
        (window.measure, window.cycles, window.settle) = (Measure::Window, 10, 2);
        let out = run_one(&window, &backward());
        let rec = sweep::record(&window, &out);
        let b = rec.backward.travel[0];
        assert!(
            (b - steady_travel).abs() <= 1e-10,
            "{lugre:?}: {b} against {steady_travel}"
        );
    }
}

const SCENE: &str = "name = \"bw\"\n[axis.x]\nduty = [0.9, 0.95, 0.98, 1.0]\n\
                     [axis.y]\nvoltage = [0, 60]\n[output]\nbackward = true\n";

/// A scene with `backward = true` writes the eight maps with units, and
/// its shards merge into the single run's file bit for bit; f32 is
/// refused before any work, naming the key, leaving no file
/// (`gpu_backward` and `gpu_lugre_backward` run the shaders).
#[test]
fn backward_maps_are_written_merged_and_refused() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let d = dir.path();
    let scene = d.join("bw.toml");
    std::fs::write(&scene, SCENE).expect("written");
    let single = d.join("single.h5");
    let run = |args: &[&str]| {
        let out = pidm(args, d);
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let said = run(&["run", s(&scene), "--out", s(&single)]);
    assert!(
        said.contains("too few for a GPU") && !said.contains("output.backward"),
        "{said}"
    );
    let file = hdf5::File::open(&single).expect("a result file");
    for axis in ["x", "y"] {
        for (name, units) in [
            (format!("backward_{axis}"), "m"),
            (format!("backward_{axis}_se"), "m"),
            (format!("backward_ratio_{axis}"), "1"),
            (format!("backward_ratio_{axis}_se"), "1"),
        ] {
            let ds = file.dataset(&format!("maps/{name}")).expect(&name);
            assert_eq!(ds.shape(), vec![4, 2], "{name}");
            let u: hdf5::types::VarLenUnicode = ds.attr("units").unwrap().read_scalar().unwrap();
            assert_eq!(u.as_str(), units, "{name}");
        }
    }
    let ratio: Vec<f64> = file
        .dataset("maps/backward_ratio_x")
        .unwrap()
        .read_raw()
        .unwrap();
    assert!(ratio.iter().all(|r| (0.0..=1.0).contains(r)) && ratio.iter().any(|&r| r > 0.5));
    drop(file);
    for k in 1..=2 {
        let shard = format!("{k}/2");
        run(&["run", s(&scene), "--shard", &shard, "--backend", "cpu"]);
    }
    let merged = d.join("merged.h5");
    run(&[
        "merge",
        s(&merged),
        "results/bw.shard-1-of-2.h5",
        "results/bw.shard-2-of-2.h5",
    ]);
    let compared = pidm::output::compare_contents(&single, &merged).expect("equal");
    assert!(compared >= 20, "{compared} datasets");

    let out = d.join("refused.h5");
    let refused = |args: &[&str], text: &str, needle: &str| {
        std::fs::write(&scene, text).expect("written");
        let mut all = vec!["run", s(&scene), "--out", s(&out)];
        all.extend_from_slice(args);
        let run = pidm(&all, d);
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(
            !run.status.success() && err.contains(needle),
            "{all:?}: {err}"
        );
        assert!(!out.exists(), "{all:?} left {}", out.display());
    };
    let why = "output.backward = true: the backward travel is measured in f64 only";
    refused(&["--backend", "cpu", "--precision", "f32"], SCENE, why);
    refused(&["--backend", "gpu", "--precision", "f32"], SCENE, why);
    let wrong = SCENE.replace("backward = true", "backward = 1");
    refused(&[], &wrong, "output.backward");
}

/// `pidm run --backend gpu` measures a LuGre scene's backward travel in
/// LuGre's shader (issue 59; no longer refused): on a software adapter its
/// maps are the CPU path's bit for bit, on hardware the steps within
/// LuGre's hardware bound and the backward travels within its self-test's
/// allowance.
#[test]
fn pidm_runs_lugres_backward_travel_on_the_gpu() {
    let Some(ctx) = crate::gpu::f64_context() else {
        return;
    };
    let dir = tempfile::tempdir().expect("a temporary directory");
    let d = dir.path();
    std::fs::write(
        d.join("lb.toml"),
        "name = \"lb\"\n[mechanism]\nfriction = \"lugre\"\n[axis.x]\nduty = [0.9, 0.98]\n\
         [axis.y]\nvoltage = [0, 60]\nfrequency = 20.0\n[simulation]\nmeasure = \"window\"\n\
         cycles = 3\nsettle = 1\n[output]\nbackward = true\n",
    )
    .expect("written");
    let names = ["step_x", "step_y", "backward_x", "backward_y"];
    let maps = |backend: &str| run_maps(d, "lb.toml", backend, &names);
    let (cpu, gpu) = (maps("cpu"), maps("gpu"));
    assert!(cpu[2].iter().any(|&b| b > 1e-7), "travels back: {cpu:?}");
    if ctx.is_hardware() {
        let bars = [2e-11, 2e-11, pidm::gpu::lugre::BACKWARD_ALLOWANCE_M];
        for (k, (g, c)) in gpu.iter().zip(&cpu).enumerate() {
            for (g, c) in g.iter().zip(c) {
                let bar = bars[k.min(2)];
                assert!((g - c).abs() <= bar, "{}: {g} against {c} m", names[k]);
            }
        }
    } else {
        assert_eq!(gpu, cpu);
    }
}

/// `pidm plot` draws each moving axis' backward ratio beside the step maps
/// of a 2-D grid (a line along a 1-D one, a bar per point), notes the axis that
/// never travels back, and refuses a ratio outside [0, 1] naming the
/// dataset, drawing nothing.
#[test]
fn pidm_plot_maps_the_backward_ratio() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let d = dir.path();
    std::fs::write(
        d.join("bw.toml"),
        "name = \"bw\"\n[axis.x]\nduty = [0.9, 0.95, 0.98]\nvoltage = [80.0, 100.0]\n\
         [axis.y]\nvoltage = 0\n[output]\nbackward = true\n",
    )
    .expect("written");
    let run = |args: &[&str]| pidm(args, d);
    assert!(run(&["run", "bw.toml", "--out", "bw.h5"]).status.success());
    let plotted = run(&["plot", "bw.h5", "--out", "plots"]);
    let said = String::from_utf8_lossy(&plotted.stdout);
    assert!(plotted.status.success(), "{said}");
    assert!(
        said.contains("backward_ratio_y is 0 everywhere; not drawn"),
        "{said}"
    );
    let png = std::fs::read(d.join("plots/backward_ratio_x.png")).expect("drawn");
    assert!(
        png.starts_with(b"\x89PNG") && png.len() > 10_000,
        "{} bytes",
        png.len()
    );
    assert!(!d.join("plots/backward_ratio_y.png").exists());

    std::fs::write(
        d.join("line.toml"),
        "name = \"line\"\n[axis.x]\nduty = [0.9, 0.95, 0.98]\n[axis.y]\nvoltage = 0\n\
         [output]\nbackward = true\n",
    )
    .expect("written");
    assert!(
        run(&["run", "line.toml", "--out", "line.h5"])
            .status
            .success()
    );
    let plotted = run(&["plot", "line.h5", "--out", "line"]);
    let said = String::from_utf8_lossy(&plotted.stdout);
    assert!(
        plotted.status.success() && said.contains("line/backward_ratio.png"),
        "{said}"
    );
    let png = std::fs::read(d.join("line/backward_ratio.png")).expect("drawn");
    assert!(
        png.starts_with(b"\x89PNG") && png.len() > 10_000,
        "{} bytes",
        png.len()
    );

    std::fs::copy(d.join("bw.h5"), d.join("bad.h5")).expect("copied");
    let file = hdf5::File::open_rw(d.join("bad.h5")).expect("opened");
    let ds = file.dataset("maps/backward_ratio_x").expect("stored");
    let mut values: Vec<f64> = ds.read_raw().expect("read");
    values[1] = 1.5;
    ds.write_raw(&values).expect("written");
    drop(ds);
    file.close().expect("closed");
    let refused = run(&["plot", "bad.h5", "--out", "bad"]);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success(), "{err}");
    assert!(
        err.contains("dataset /maps/backward_ratio_x holds 1.5: a backward ratio is in [0, 1]"),
        "{err}"
    );
    assert!(!d.join("bad").exists());
}
