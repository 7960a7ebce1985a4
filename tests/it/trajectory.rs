//! Trajectories: recording never changes the run, the samples agree with
//! the map results, and samples inside long closed-form steps are the true
//! motion (checked against an independent integration).

use pidm::laws::Settings;
use pidm::laws::karnopp::integrate::run_instance;
use pidm::laws::status::STATUS_OK;
use pidm::measurement::window_displacement as displacement;
use pidm::model::{Axis, Instance, sawtooth};
use pidm::scene::Scene;
use pidm::trajectory::{measured_displacement, record, record_scene};

/// The paper's points (Figs. 5a-8) and a few harder 2-DOF cases: a phase
/// offset, unequal stages, duty 1.
fn instances() -> Vec<(&'static str, Instance)> {
    let base = |vx: f64, vy: f64, fy: f64| {
        let mut inst = Instance::TABLE1;
        inst.axes[0].voltage = vx;
        inst.axes[1].voltage = vy;
        inst.axes[1].frequency = fy;
        inst
    };
    let r = 100.0 / 2f64.sqrt();
    let mut phase = base(100.0, 80.0, 10.0);
    phase.axes[1].phase = 0.3;
    let mut unequal = base(120.0, -90.0, 10.0);
    unequal.axes[1] = Axis {
        voltage: -90.0,
        ..Axis::TEXT
    };
    let mut ramp = base(100.0, 60.0, 20.0);
    ramp.axes[0].duty = 1.0;
    vec![
        ("Fig. 5a", base(100.0, 0.0, 10.0)),
        ("Fig. 5b", base(r, r, 10.0)),
        ("Fig. 6", base(100.0, 100.0, 10.0)),
        ("Fig. 7", base(100.0, 50.0, 10.0)),
        ("Fig. 8", base(100.0, 100.0, 20.0)),
        ("phase offset", phase),
        ("unequal stages", unequal),
        ("duty 1", ramp),
    ]
}

#[test]
fn recording_leaves_the_run_unchanged_bit_for_bit() {
    let settings = Settings::default();
    for (name, inst) in instances() {
        let plain = run_instance(&inst, &settings).state.record();
        for per in [7, 2000] {
            let t = record(&inst, &settings, per);
            assert_eq!(t.state, plain, "{name}, {per} samples per cycle");
        }
    }
}

#[test]
fn the_samples_give_the_map_displacement() {
    let settings = Settings::default();
    for (name, inst) in instances() {
        let plain = run_instance(&inst, &settings).state.record();
        assert_eq!(plain.status, STATUS_OK, "{name}");
        let want = displacement(&inst, plain);
        let t = record(&inst, &settings, 500);
        assert_eq!(t.time.len(), inst.cycles as usize * 500 + 1, "{name}");
        assert_eq!(t.time[0], 0.0);
        assert!((t.time[t.time.len() - 1] - inst.duration()).abs() < 1e-12);
        let got =
            measured_displacement(&t, inst.settle, inst.cycles).expect("a complete trajectory");
        for i in 0..2 {
            assert!(
                (got[i] - want[i]).abs() <= 1e-12,
                "{name} axis {i}: samples give {} m, the run {} m",
                got[i],
                want[i]
            );
            // The last sample is the final state itself.
            assert_eq!(t.slider[i][t.time.len() - 1], plain.x_s[i], "{name}");
        }
        // The start is at rest at zero.
        assert_eq!([t.stage[0][0], t.slider[1][0]], [0.0, 0.0]);
    }
}

#[test]
fn an_undriven_axis_stays_exactly_at_rest_in_the_samples() {
    let settings = Settings::default();
    let (_, inst) = instances()[0];
    let t = record(&inst, &settings, 300);
    assert!(t.stage[1].iter().chain(&t.slider[1]).all(|&v| v == 0.0));
    assert!(t.voltage[1].iter().all(|&v| v == 0.0));
    assert!(t.voltage[0].iter().any(|&v| v > 99.0));
}

/// Stage position of a stuck instance (a linear oscillator of mass
/// m_p + m_s under the sawtooth force) by classical RK4, `substeps` per
/// sample interval, at every sample time.
fn stuck_oscillator_rk4(inst: &Instance, per: u32, substeps: u32) -> Vec<f64> {
    let axis = &inst.axes[0];
    let mass = axis.stage_mass + inst.mechanism.slider_mass;
    let force = |t: f64| axis.gain * axis.voltage * sawtooth(axis.frequency * t, axis.duty);
    let accel = |t: f64, x: f64, v: f64| (force(t) - axis.damping * v - axis.stiffness * x) / mass;
    let period = inst.period();
    let samples = inst.cycles as usize * per as usize;
    let (mut x, mut v) = (0.0, 0.0);
    let mut out = vec![0.0];
    for k in 0..samples {
        let t0 = k as f64 * period / per as f64;
        let t1 = (k + 1) as f64 * period / per as f64;
        let h = (t1 - t0) / substeps as f64;
        for s in 0..substeps {
            // The force is continuous (duty < 1) and linear between samples
            // (the sample grid contains every drive corner), so RK4 keeps
            // its order.
            let t = t0 + s as f64 * h;
            let (k1x, k1v) = (v, accel(t, x, v));
            let (k2x, k2v) = (
                v + 0.5 * h * k1v,
                accel(t + 0.5 * h, x + 0.5 * h * k1x, v + 0.5 * h * k1v),
            );
            let (k3x, k3v) = (
                v + 0.5 * h * k2v,
                accel(t + 0.5 * h, x + 0.5 * h * k2x, v + 0.5 * h * k2v),
            );
            let (k4x, k4v) = (v + h * k3v, accel(t + h, x + h * k3x, v + h * k3v));
            x += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
            v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
        }
        out.push(x);
    }
    out
}

#[test]
fn samples_inside_long_stick_steps_follow_the_true_motion() {
    // At 1 V the slider never breaks loose, so the stage and slider move as
    // one linear oscillator: the integrator crosses each rise of the drive
    // in a handful of closed-form steps, and the samples inside them must
    // still show the ringing after every fall.
    let mut inst = Instance::TABLE1;
    inst.axes[0].voltage = 1.0;
    inst.axes[1].voltage = 0.0;
    inst.cycles = 2;
    inst.settle = 1;
    let per = 1000;
    let t = record(&inst, &Settings::default(), per);
    assert_eq!(t.state.status, STATUS_OK);
    assert!(
        t.state.steps < 100,
        "expected long steps, took {}",
        t.state.steps
    );
    let reference = stuck_oscillator_rk4(&inst, per, 100);
    let amplitude = (inst.axes[0].gain * inst.axes[0].voltage / inst.axes[0].stiffness).abs();
    let mut worst: f64 = 0.0;
    for (k, want) in reference.iter().enumerate() {
        assert!(
            (t.stage[0][k] - t.slider[0][k]).abs() <= 1e-20,
            "stuck: the slider rides on the stage"
        );
        worst = worst.max((t.stage[0][k] - want).abs());
    }
    assert!(
        worst <= 1e-8 * amplitude,
        "largest difference {worst:e} m against RK4 (amplitude {amplitude:e} m)"
    );
    // The ringing after the first fall (1.8 kHz, inside one long step) is
    // in the samples: the stage turns back and forth.
    let first_period_end = per as usize;
    let window = &t.stage[0][first_period_end..first_period_end + 40];
    let turns = window
        .windows(3)
        .filter(|w| (w[1] - w[0]) * (w[2] - w[1]) < 0.0)
        .count();
    assert!(turns >= 4, "expected ringing after the fall, {turns} turns");
}

#[test]
fn a_scene_records_its_trajectories_with_baselines() {
    let scene = Scene::from_toml(
        "name = \"t\"\n\
         [axis.x]\nvoltage = [60.0, 100.0]\n\
         [axis.y]\nvoltage = [0.0, 100.0]\n\
         [simulation]\nmeasure = \"window\"\ncycles = 3\nsettle = 1\n\
         [output]\nbaselines = true\n\
         trajectories = [{ axis.x.voltage = 100.0, axis.y.voltage = 100.0 }, 0]\n\
         trajectory_samples_per_cycle = 50\n",
        None,
    )
    .unwrap();
    let recorded = record_scene(&scene);
    assert_eq!(recorded.len(), 2);
    assert_eq!(recorded[0].point.index, 3);
    assert_eq!(
        recorded[0].point.name,
        "instance 3 (axis.x.voltage = 100 V, axis.y.voltage = 100 V)"
    );
    let bases = recorded[0].baselines.as_ref().expect("baselines");
    // The x baseline drives x alone, and is the 1-DOF run.
    let mut alone = recorded[0].instance;
    alone.axes[1].voltage = 0.0;
    assert_eq!(bases[0].instance, alone);
    assert_eq!(
        bases[0].trajectory.state,
        run_instance(&alone, &scene.settings).state.record()
    );
    assert!(bases[0].trajectory.slider[1].iter().all(|&v| v == 0.0));
    assert_eq!(recorded[0].main.time.len(), 151);
}

#[test]
fn a_faster_baseline_is_extended_over_the_whole_run_unchanged() {
    // Fig. 8: x at 10 Hz, y at 20 Hz. The y baseline's period is 50 ms, so
    // its 10 periods last half the point's run; it is recorded for 20, and
    // its first 10 are the map's baseline run.
    let (_, inst) = instances()[4];
    let settings = Settings::default();
    let (base, measured) = pidm::trajectory::baseline_instance(&inst, 1);
    assert_eq!((measured, base.cycles), (10, 20));
    assert!((base.duration() - inst.duration()).abs() < 1e-12);
    let t = record(&base, &settings, 200);
    let mut map_run = base;
    map_run.cycles = measured;
    let short = record(&map_run, &settings, 200);
    let n = short.time.len();
    assert_eq!(t.slider[1][..n], short.slider[1][..]);
    assert_eq!(t.stage[1][..n], short.stage[1][..]);
    let want = displacement(&map_run, &run_instance(&map_run, &settings).state);
    let got = measured_displacement(&t, base.settle, measured).unwrap();
    assert!((got[1] - want[1]).abs() <= 1e-12, "{got:?} {want:?}");
    // Axes at one frequency need no extension.
    let (base, measured) = pidm::trajectory::baseline_instance(&inst, 0);
    assert_eq!(base.cycles, measured);
}

/// LuGre runs record too (issue 58), by their own f64 CPU integrator: the
/// recorded run ends in the map run's state bit for bit, the samples at
/// period ends are step ends (Rodas4's segments end there), so they give
/// the window's travel exactly, and between step ends the Hermite
/// interpolant stays within the stroke of the stage.
#[test]
fn lugre_runs_record_their_trajectories() {
    use pidm::model::{Friction, Lugre};
    let settings = Settings::default();
    let mut inst = instances()[0].1;
    inst.axes[1].voltage = 60.0;
    inst.cycles = 4;
    inst.settle = 1;
    inst.mechanism.friction = Friction::Lugre(Lugre::DEFAULT);
    let plain = pidm::laws::run_until(&inst, &settings, || false)
        .expect("not stopped")
        .record;
    let t = record(&inst, &settings, 200);
    assert_eq!(t.state, plain);
    assert_eq!(t.time.len(), 4 * 200 + 1);
    let got = measured_displacement(&t, inst.settle, inst.cycles).expect("a complete trajectory");
    assert_eq!(got, displacement(&inst, plain));
    assert_ne!(got, [0.0, 0.0]);
    // The stage's static stroke: gain V / stiffness, per axis.
    for i in 0..2 {
        let a = &inst.axes[i];
        let stroke = (a.gain * a.voltage / a.stiffness).abs();
        assert!(
            t.stage[i].iter().all(|x| x.abs() <= 1.5 * stroke),
            "axis {i}: stage beyond 1.5 x its stroke {stroke} m"
        );
    }
}

/// A LuGre scene with `[output] trajectories` writes them on either
/// backend (the trajectories are the CPU's), with its baselines.
#[test]
fn a_lugre_scene_writes_its_trajectories_on_either_backend() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("t.toml");
    std::fs::write(
        &scene,
        "name = \"t\"\n[mechanism]\nfriction = \"lugre\"\n\
         [axis.x]\nvoltage = 100.0\n[axis.y]\nvoltage = 50.0\n\
         [simulation]\nmeasure = \"window\"\ncycles = 3\nsettle = 1\n\
         [output]\nbaselines = true\ntrajectories = [0]\ntrajectory_samples_per_cycle = 20\n",
    )
    .unwrap();
    for backend in ["cpu", "gpu"] {
        if backend == "gpu" && crate::gpu::context().is_none_or(|ctx| !ctx.supports_f64()) {
            continue;
        }
        let out = dir.path().join(format!("{backend}.h5"));
        let run = crate::common::pidm(
            &[
                "run",
                "t.toml",
                "--backend",
                backend,
                "--progress",
                "none",
                "--out",
                crate::common::s(&out),
            ],
            dir.path(),
        );
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(run.status.success(), "{backend}: {stderr}");
        let file = hdf5::File::open(&out).unwrap();
        let slider = file.dataset("trajectories/0/slider_x").unwrap();
        assert_eq!(slider.shape(), [61], "{backend}");
        assert!(file.group("trajectories/0/baseline_y").is_ok(), "{backend}");
    }
}
