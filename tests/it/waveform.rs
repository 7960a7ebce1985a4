//! The drive as a design variable (issue 59): waveforms and slew limits in
//! scenes (the keys, their refusals and inheritance) and the invariants of
//! their steps and backward travels on the f64 CPU path, under both
//! friction laws.

use pidm::laws::Settings;
use pidm::laws::status::STATUS_OK;
use pidm::model::{Instance, Lugre, Measure, NO_SLEW_LIMIT, Shape, Table};
use pidm::scene::Scene;
use pidm::sweep::{self, run_one};

use crate::common::{pidm, run_maps, s};

/// A scene's error message, which must contain `needle`.
fn check(text: &str, needle: &str) {
    let text = format!("name = \"w\"\n{text}");
    match Scene::from_toml(&text, None) {
        Ok(_) => panic!("accepted\n{text}\nexpected an error with {needle:?}"),
        Err(e) => {
            let message = e.to_string();
            assert!(
                message.contains(needle),
                "{text}\ngave {message}\nwithout {needle:?}"
            );
        }
    }
}

fn parse(text: &str) -> Scene {
    Scene::from_toml(&format!("name = \"w\"\n{text}"), None).expect("a valid scene")
}

#[test]
fn bad_waveforms_are_refused_by_key() {
    let trapezoid = "[axis.x]\nwaveform = \"trapezoid\"\n";
    let table = "[axis.x]\nwaveform = \"table\"\n";
    let cases: Vec<(String, &str)> = vec![
        (format!("{trapezoid}rise = 0.5\nduty = 0.3"), "axis.x.duty applies to waveform = \"sawtooth\" only"),
        ("[axis.x]\nrise = 0.5".into(), "axis.x.rise applies to waveform = \"trapezoid\" only"),
        (format!("{trapezoid}rise = 0.5\n[axis.y]\nduty = 0.5"), "axis.y.duty applies to waveform = \"sawtooth\""),
        (format!("{trapezoid}rise = 0.5\nfall = 0.6"), "rise + hold + fall = 0.5 + 0 + 0.6 = 1.1"),
        (format!("{trapezoid}rise = [0.2, 0.5]\nfall = [0.1, 0.6]"), "0.5 + 0 + 0.6 = 1.1"),
        (trapezoid.into(), "rise + hold + fall = 0 + 0 + 0 = 0"),
        (format!("{trapezoid}rise = -0.1\nfall = 0.5"), "axis.x.rise = -0.1: expected a number >= 0"),
        (format!("{trapezoid}hold = 1.5"), "axis.x.hold = 1.5"),
        ("[axis.x]\ntable = [[0.0, 0.0], [0.5, 1.0]]".into(), "axis.x.table applies to waveform = \"table\" only"),
        (table.into(), "waveform = \"table\" needs axis.x.table"),
        (format!("{table}table = [[0.5, 0.0], [0.2, 1.0]]"), "no earlier than entry 0's"),
        (format!("{table}table = [[0.5, 0.0], [0.5, 1.0], [0.5, 0.3]]"), "at most two entries (a jump) at one u"),
        (format!("{table}table = [[0.5, 2.0], [0.6, 1.0]]"), "level in [-1, 1]"),
        (format!("{table}table = [[1.0, 0.0], [0.6, 1.0]]"), "u in [0, 1)"),
        (format!("{table}table = [[0.5, 0.0]]"), "a table of 2 to 64"),
        (format!("{table}table = [[0.5, 0.0], 3]"), "is no [u, level] pair"),
        (format!("{table}table = 3"), "axis.x.table"),
        ("[axis.x]\nwaveform = \"square\"".into(), "axis.x.waveform = \"square\": expected \"sawtooth\""),
        ("[axis.x]\nwaveform = 3".into(), "axis.x.waveform"),
        ("[axis.x]\nslew_rate = 0".into(), "axis.x.slew_rate = 0: expected a number > 0"),
        ("[axis.x]\nslew_rate = -3".into(), "axis.x.slew_rate = -3"),
        ("[axis.x]\nslew_rate = inf".into(), "axis.x.slew_rate"),
        ("[axis.x]\nslew_rate = nan".into(), "axis.x.slew_rate"),
        (
            "[simulation]\nmeasure = \"window\"\n[random]\nseed = 1\ncount = 2\n[axis.x]\nwaveform = \"trapezoid\"".into(),
            "draws sawtooth instances",
        ),
        (
            format!("{trapezoid}rise = 0.5\n[[points]]\naxis.x = {{ duty = 0.5 }}"),
            "points[0]: axis.x.duty applies to waveform = \"sawtooth\" only",
        ),
    ];
    for (text, needle) in &cases {
        check(text, needle);
    }
    let table = 64;
    let entries: Vec<String> = (0..=table)
        .map(|k| format!("[{}, 0.5]", k as f64 / 100.0))
        .collect();
    check(
        &format!(
            "[axis.x]\nwaveform = \"table\"\ntable = [{}]",
            entries.join(", ")
        ),
        "a table of 2 to 64",
    );
}

#[test]
fn axes_and_points_take_waveforms_as_the_keys_say() {
    // axis.y takes axis.x's waveform and shape keys unless it names its own.
    let scene = parse(
        "[axis.x]\nwaveform = \"trapezoid\"\nrise = 0.5\nfall = 0.2\nslew_rate = 1e5\n\
         [axis.y]\nvoltage = 50\n",
    );
    let [x, y] = scene.instance(0).axes;
    assert_eq!(
        (x.shape, x.rise, x.hold, x.fall),
        (Shape::Trapezoid, 0.5, 0.0, 0.2)
    );
    assert_eq!(
        (y.shape, y.rise, y.fall, y.slew_rate),
        (x.shape, 0.5, 0.2, 1e5)
    );
    let scene = parse(
        "[axis.x]\nwaveform = \"trapezoid\"\nrise = 0.5\n[axis.y]\nvoltage = 50\n\
         waveform = \"sawtooth\"\n",
    );
    let y = scene.instance(0).axes[1];
    assert_eq!(
        (y.shape, y.rise, y.duty, y.slew_rate),
        (Shape::Sawtooth, 0.0, 0.98, NO_SLEW_LIMIT)
    );
    // A point's waveform replaces the base's, with none of its shape keys.
    let scene = parse(
        "[axis.x]\nwaveform = \"trapezoid\"\nrise = 0.5\n[[points]]\n\
         axis.x = { waveform = \"table\", table = [[0.0, 0.0], [0.5, 1.0], [0.5, -1.0]] }\n\
         [[points]]\naxis.x = { hold = 0.25 }\n",
    );
    let [a, b] = [0, 1].map(|k| scene.instance(k).axes[0]);
    let want = Table::intern(&[[0.0, 0.0], [0.5, 1.0], [0.5, -1.0]]);
    assert_eq!((a.shape, a.rise), (Shape::Table(want), 0.0));
    assert_eq!((b.shape, b.rise, b.hold), (Shape::Trapezoid, 0.5, 0.25));
    // Ties and grids of the fractions.
    let scene = parse(
        "[axis.x]\nwaveform = \"trapezoid\"\nrise = [0.3, 0.5]\nfall = 0.1\n\
         [axis.y]\nvoltage = 50\nrise = { same_as = \"axis.x.rise\" }\n",
    );
    assert_eq!(scene.instance_count(), 2);
    for k in 0..2 {
        let [x, y] = scene.instance(k).axes;
        assert_eq!(x.rise, y.rise);
    }
}

/// The steady steps [um] of `inst` on the f64 CPU path; finished normally.
fn steps_um(inst: &Instance) -> [f64; 2] {
    travels_um(inst).0
}

/// The steady steps and backward travels [um per own drive cycle] of
/// `inst` on the f64 CPU path (`Settings::backward`); finished normally.
fn travels_um(inst: &Instance) -> ([f64; 2], [f64; 2]) {
    let settings = Settings {
        backward: true,
        ..Settings::default()
    };
    let out = run_one(inst, &settings);
    assert_eq!(out.status, STATUS_OK, "{inst:?}");
    let rec = sweep::record(inst, &out);
    (
        rec.step.map(|v| v * 1e6),
        rec.backward.travel.map(|v| v * 1e6),
    )
}

/// Table 1 at 100 V on x and 60 V at 14 Hz on y, unloaded, steady from
/// period 1, under `lugre` friction where given.
fn base(lugre: bool) -> Instance {
    let mut inst = Instance::TABLE1;
    inst.axes[1].voltage = 60.0;
    inst.axes[1].frequency = 14.0;
    inst.settle = 1;
    inst.cycles = 400;
    inst.measure = Measure::Steady {
        step_tolerance: Measure::DEFAULT_STEP_TOLERANCE,
    };
    if lugre {
        inst.mechanism.friction = pidm::model::Friction::Lugre(Lugre {
            stribeck_velocity: 1e-5,
            ..Lugre::DEFAULT
        });
    }
    inst
}

/// `inst` with axis x driven by `shape` (and its fractions).
fn shaped(mut inst: Instance, shape: Shape, fractions: [f64; 3]) -> Instance {
    let x = &mut inst.axes[0];
    x.shape = shape;
    [x.rise, x.hold, x.fall] = fractions;
    inst
}

/// A trapezoid (d, 0, 1 - d), the table of that shape and the sawtooth of
/// duty d are one drive: the same steps and backward travels, under both
/// laws (the same bits, since their corners are the same).
#[test]
fn a_sawtooths_trapezoid_and_table_step_as_the_sawtooth() {
    for lugre in [false, true] {
        for duty in [0.98, 0.9] {
            let mut saw = base(lugre);
            saw.axes[0].duty = duty;
            let trapezoid = shaped(base(lugre), Shape::Trapezoid, [duty, 0.0, 1.0 - duty]);
            let table = Table::intern(&[[0.0, 0.0], [duty, 1.0]]);
            let table = shaped(base(lugre), Shape::Table(table), [0.0; 3]);
            let (want, want_back) = travels_um(&saw);
            assert!(
                want_back[0] > 1.0,
                "the slider rides the ramp back: {want_back:?}"
            );
            for inst in [trapezoid, table] {
                let (got, got_back) = travels_um(&inst);
                for i in 0..2 {
                    let what = format!("lugre {lugre} duty {duty} axis {i}");
                    assert!(
                        (got[i] - want[i]).abs() <= 1e-6,
                        "{what}: {} um against the sawtooth's {} um",
                        got[i],
                        want[i]
                    );
                    assert!(
                        (got_back[i] - want_back[i]).abs() <= 1e-6,
                        "{what}: backward {} um against the sawtooth's {} um",
                        got_back[i],
                        want_back[i]
                    );
                }
            }
        }
    }
}

/// Negated levels on x negate x's step and keep y's (the friction is
/// isotropic, so the mirror image x -> -x is a motion too); a
/// constant level moves nothing; a slew limit at or above every flank is
/// no limit, bit for bit.
#[test]
fn negated_constant_and_unlimited_drives_step_as_they_must() {
    let up = Table::intern(&[[0.0, 0.0], [0.6, 1.0], [0.7, 0.4], [0.72, 0.0]]);
    let down = Table::intern(&[[0.0, -0.0], [0.6, -1.0], [0.7, -0.4], [0.72, -0.0]]);
    let [(a, a_back), (b, b_back)] =
        [up, down].map(|t| travels_um(&shaped(base(false), Shape::Table(t), [0.0; 3])));
    assert!(a[0].abs() > 0.01, "the table moves x: {a:?}");
    assert!((a[0] + b[0]).abs() <= 1e-6, "x: {} and {} um", a[0], b[0]);
    assert!((a[1] - b[1]).abs() <= 1e-6, "y: {} and {} um", a[1], b[1]);
    // The mirror image travels back as far.
    for i in 0..2 {
        assert!(
            (a_back[i] - b_back[i]).abs() <= 1e-6,
            "backward {i}: {a_back:?} and {b_back:?} um"
        );
    }
    let flat = Table::intern(&[[0.0, 0.5], [0.5, 0.5]]);
    let mut still = shaped(base(false), Shape::Table(flat), [0.0; 3]);
    still.axes[1].voltage = 0.0;
    let (steps, back) = travels_um(&still);
    assert!(
        steps[0].abs() <= 1e-6 && back[0].abs() <= 1e-6,
        "a constant drive steps {steps:?} um and travels back {back:?} um"
    );
    // The sawtooth's steepest flank: 100 V over 0.02 of a 10 Hz cycle.
    let mut limited = base(false);
    limited.axes[0].slew_rate = 100.0 * 10.0 / 0.02;
    limited.axes[1].slew_rate = 1e9;
    assert_eq!(steps_um(&limited), steps_um(&base(false)));
    limited.axes[0].slew_rate *= 0.5;
    assert_ne!(steps_um(&limited)[0], steps_um(&base(false))[0]);
}

/// A refused scene leaves no file.
#[test]
fn refusals_leave_no_file() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let bad = dir.path().join("bad.toml");
    std::fs::write(
        &bad,
        "name = \"bad\"\n[axis.x]\nwaveform = \"trapezoid\"\nrise = 0.6\nfall = 0.6\n",
    )
    .expect("written");
    let out = dir.path().join("bad.h5");
    let run = pidm(&["run", s(&bad), "--out", s(&out)], dir.path());
    assert!(!run.status.success());
    assert!(String::from_utf8_lossy(&run.stderr).contains("rise + hold + fall"));
    assert!(!out.exists());
}

/// Window instances over the waveform families: trapezoids with holds and
/// jumps, tables with jumps and negative levels, slew-limited sawtooths
/// and trapezoids, 1-DOF and 2-DOF.
fn gpu_instances() -> Vec<Instance> {
    let table = |e: &[[f64; 2]]| Shape::Table(Table::intern(e));
    let drives: [(Shape, [f64; 3], f64); 8] = [
        (Shape::Trapezoid, [0.9, 0.05, 0.02], NO_SLEW_LIMIT),
        (Shape::Trapezoid, [0.0, 0.6, 0.03], NO_SLEW_LIMIT),
        (Shape::Trapezoid, [0.95, 0.0, 0.0], NO_SLEW_LIMIT),
        (
            table(&[[0.0, 0.0], [0.5, 1.0], [0.5, -1.0]]),
            [0.0; 3],
            NO_SLEW_LIMIT,
        ),
        (
            table(&[[0.1, -0.5], [0.8, 1.0], [0.82, 0.2], [0.82, -0.3]]),
            [0.0; 3],
            NO_SLEW_LIMIT,
        ),
        (Shape::Sawtooth, [0.0; 3], 3e4),
        (Shape::Trapezoid, [0.8, 0.1, 0.03], 2e4),
        (table(&[[0.0, 0.0], [0.7, 1.0], [0.7, 0.0]]), [0.0; 3], 4e4),
    ];
    let mut out = Vec::new();
    for (k, &(shape, fractions, slew)) in drives.iter().enumerate() {
        let mut inst = Instance::TABLE1;
        inst.cycles = 4;
        inst.settle = 1;
        inst.measure = Measure::Window;
        inst.axes[0].shape = shape;
        [inst.axes[0].rise, inst.axes[0].hold, inst.axes[0].fall] = fractions;
        inst.axes[0].slew_rate = slew;
        inst.axes[0].phase = 0.1 * k as f64;
        // Every other instance 2-DOF, y on the next family at 14 Hz.
        if k % 2 == 1 {
            let (shape, fractions, slew) = drives[(k + 1) % drives.len()];
            let y = &mut inst.axes[1];
            y.voltage = 70.0;
            y.frequency = 14.0;
            y.shape = shape;
            [y.rise, y.hold, y.fall] = fractions;
            y.slew_rate = slew;
        } else {
            inst.axes[1].voltage = 0.0;
        }
        out.push(inst);
    }
    out
}

/// The shader drives every waveform as the CPU does: f64 within 1e-6 um
/// per cycle of the f64 CPU path on each axis (the bar; rounding
/// apart they are the same arithmetic), f32 within its allowance.
#[test]
fn the_shader_drives_waveforms_as_the_cpu_does() {
    use pidm::gpu::{BatchOptions, Precision};
    use pidm::laws::karnopp::integrate::run_instance;
    use pidm::measurement::window_displacement;
    let Some(ctx) = crate::gpu::context() else {
        return;
    };
    let settings = Settings::default();
    let instances = gpu_instances();
    let cpu: Vec<[f64; 2]> = instances
        .iter()
        .map(|inst| {
            let st = run_instance(inst, &settings).state;
            assert_eq!(st.status, STATUS_OK);
            let d = window_displacement(inst, &st);
            [0, 1].map(|i| inst.measure(i, d[i]).1 * 1e6)
        })
        .collect();
    assert!(
        cpu.iter().any(|s| s[0].abs() > 0.05),
        "the instances move: {cpu:?}"
    );
    let mut precisions = vec![Precision::F32];
    if ctx.supports_f64() {
        precisions.push(Precision::F64);
    }
    for precision in precisions {
        let gpu = crate::gpu::gpu_batch(
            ctx,
            &instances,
            &settings,
            precision,
            &BatchOptions::default(),
        );
        for (k, (inst, g)) in instances.iter().zip(&gpu).enumerate() {
            assert_eq!(g.status, STATUS_OK, "{precision:?} #{k}");
            for (i, &c) in cpu[k].iter().enumerate() {
                let v = inst.measure(i, g.displacement[i]).1 * 1e6;
                let allowed = match precision {
                    Precision::F64 => 1e-6,
                    Precision::F32 => crate::gpu::f32_allowance(c),
                };
                eprintln!("{precision:?} #{k} axis {i}: cpu {c:.6} gpu {v:.6} um");
                assert!(
                    (v - c).abs() <= allowed,
                    "{precision:?} #{k} axis {i}: {v} against {c} um"
                );
            }
        }
    }
}

/// The LuGre shader drives every waveform from its corners
/// (`shaders/lugre/corners.wgsl`) as the CPU's clock does: the batch of
/// waveform families (and a plain sawtooth among them, which the waveform
/// variant drives from its corners too, and a slow 1 Hz lane whose every
/// dispatch is full of attempts) takes the waveform variant, whose
/// records on a software adapter are the CPU's bit for bit (steps
/// included), and within 1e-6 um per cycle elsewhere; the hardware's
/// variant (fused arithmetic) within 2e-5 um, LuGre's hardware bound at
/// the default tolerance (`gpu_lugre.rs`).
#[test]
fn the_lugre_shader_drives_waveforms_as_the_cpu_does() {
    use pidm::gpu::lugre::LugreGpu;
    use pidm::laws::lugre::run_instance_until;
    use pidm::measurement::reduce;
    use pidm::model::{Friction, Lugre};
    let Some(ctx) = crate::gpu::f64_context() else {
        return;
    };
    let mut instances = gpu_instances();
    let mut sawtooth = Instance::TABLE1;
    (sawtooth.cycles, sawtooth.settle, sawtooth.measure) = (4, 1, Measure::Window);
    instances.push(sawtooth);
    // A slow lane (1 Hz, a table with a jump): its dispatches are all
    // attempts, where llvmpipe's loop limit would cut one short.
    let mut slow = instances[3];
    (slow.axes[0].frequency, slow.axes[1].frequency, slow.cycles) = (1.0, 1.0, 2);
    instances.push(slow);
    for inst in &mut instances {
        inst.mechanism.friction = Friction::Lugre(Lugre::DEFAULT);
    }
    let settings = Settings::default();
    let cpu: Vec<_> = instances
        .iter()
        .map(|inst| run_instance_until(inst, &settings, || false).expect("not stopped"))
        .collect();
    let software = !ctx.is_hardware();
    let own = LugreGpu::for_instances(ctx, &instances, &settings).expect("the waveform pipeline");
    assert!(own.drives_waveforms());
    let hardware = LugreGpu::hardware_variant(ctx, true).expect("the hardware's waveform pipeline");
    for (label, gpu, bound) in [
        ("adapter's", &own, if software { 0.0 } else { 1e-6 }),
        ("hardware's", &hardware, 2e-5),
    ] {
        let (runs, _) = gpu.run(&instances, &settings).expect("the batch");
        for (k, inst) in instances.iter().enumerate() {
            let (want, got) = (reduce(inst, &cpu[k]), reduce(inst, &runs[k]));
            assert_eq!(
                (got.status, want.status),
                (STATUS_OK, STATUS_OK),
                "{label} #{k}"
            );
            for i in 0..2 {
                let w = inst.measure_over(i, want.travel[i], want.span).1 * 1e6;
                let g = inst.measure_over(i, got.travel[i], got.span).1 * 1e6;
                eprintln!(
                    "LuGre {label} #{k} axis {i}: cpu {w:.9} gpu {g:.9} um, {} steps",
                    cpu[k].record.steps
                );
                assert!(
                    (g - w).abs() <= bound,
                    "{label} #{k} axis {i}: {g} against {w} um"
                );
            }
            if bound == 0.0 {
                assert_eq!(runs[k].record, cpu[k].record, "{label} #{k}");
            }
        }
    }
}

/// `pidm run --backend gpu` runs a LuGre scene of trapezoids and a table
/// on LuGre's waveform pipeline (no longer refused): on a software adapter
/// its step maps are the CPU path's bit for bit, on hardware within LuGre's
/// hardware bound.
#[test]
fn pidm_runs_lugre_waveforms_on_the_gpu() {
    let Some(ctx) = crate::gpu::f64_context() else {
        return;
    };
    let dir = tempfile::tempdir().expect("a temporary directory");
    let d = dir.path();
    std::fs::write(
        d.join("lw.toml"),
        "name = \"lw\"\n[mechanism]\nfriction = \"lugre\"\n[axis.x]\n\
         waveform = \"trapezoid\"\nrise = [0.6, 0.9]\nhold = 0.05\nfall = 0.03\n\
         slew_rate = [3e4, 1e9]\n[axis.y]\nwaveform = \"table\"\n\
         table = [[0.1, -0.5], [0.6, 1.0], [0.6, 0.2]]\nvoltage = 60\n\
         [simulation]\nmeasure = \"window\"\ncycles = 3\nsettle = 1\n",
    )
    .expect("written");
    let maps = |backend: &str| run_maps(d, "lw.toml", backend, &["step_x", "step_y"]);
    let (cpu, gpu) = (maps("cpu"), maps("gpu"));
    assert!(
        cpu[0].iter().any(|v| v.abs() > 1e-8),
        "the slider moves: {cpu:?}"
    );
    if ctx.is_hardware() {
        // The hardware's arithmetic: LuGre's bound at the default
        // tolerance, 2e-5 um per cycle (`gpu_lugre.rs`).
        for (g, c) in gpu.iter().flatten().zip(cpu.iter().flatten()) {
            assert!((g - c).abs() <= 2e-11, "{g} against {c} m");
        }
    } else {
        assert_eq!(gpu, cpu);
    }
}

/// `pidm fit` fits a trapezoid's fall like any key: steps made by pidm at
/// fall 0.012 over seven voltages (2 % errors, no noise) give back 0.012
/// within 3 standard errors, from a start of 0.011.
#[test]
fn a_fit_recovers_a_trapezoids_fall() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let path = |name: &str| dir.path().join(name);
    let shape = "[axis.x]\nwaveform = \"trapezoid\"\nrise = 0.9\n";
    std::fs::write(
        path("truth.toml"),
        format!(
            "name = \"truth\"\n{shape}fall = 0.012\nvoltage = [60, 70, 80, 90, 100, 110, 120]\n\
             [axis.y]\nvoltage = 0\n"
        ),
    )
    .expect("written");
    let truth = Scene::from_toml(
        &std::fs::read_to_string(path("truth.toml")).expect("read"),
        None,
    )
    .expect("the truth scene");
    let mut csv = String::from("axis.x.voltage,step_x,step_x_se\n");
    for k in 0..truth.instance_count() {
        let inst = truth.instance(k);
        let step = steps_um(&inst)[0] * 1e-6;
        let se = (0.02 * step.abs()).max(1e-8);
        csv += &format!("{},{step:e},{se:e}\n", inst.axes[0].voltage);
    }
    std::fs::write(path("steps.csv"), csv).expect("written");
    std::fs::write(
        path("fall.toml"),
        format!(
            "name = \"fit_fall\"\n{shape}fall = 0.011\n[axis.y]\nvoltage = 0\n[fit]\n\
             data = \"steps.csv\"\nfree = {{ \"axis.x.fall\" = [0.010, 0.014] }}\n"
        ),
    )
    .expect("written");
    let json = crate::fit::fit(s(&path("fall.toml")), dir.path(), "cpu", &[]);
    assert_eq!(json["status"], "converged", "{json:#}");
    let p = &json["parameters"]["axis.x.fall"];
    let (value, se) = (p["value"].as_f64().unwrap(), p["se"].as_f64().unwrap());
    assert!(
        se > 0.0 && (value - 0.012).abs() <= 3.0 * se,
        "fall {value} +- {se}"
    );
}
