//! Helpers every test module shares: the `pidm` binary, paths in the
//! repository, and the paper's reference cases.

use std::path::Path;
use std::process::{Child, Command, Output};

use pidm::model::{Axis, Instance, Measure};

/// Sends signal `name` ("INT", "KILL", "STOP", ...) to a child process.
pub fn signal(child: &Child, name: &str) {
    let sent = Command::new("kill")
        .args([&format!("-{name}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(sent.success(), "kill -{name} failed");
}

/// Waits for a run's checkpoint to hold its first finished chunk, then
/// stops the run with Ctrl-C (asserting that it was still running) and
/// returns how it ended.
pub fn interrupt_after_first_chunk(child: Child, checkpoint: &Path) -> Output {
    let started = std::time::Instant::now();
    let header = loop {
        // The journal is created empty, then its header is written in
        // one write: its length once non-zero is the header's.
        if let Ok(m) = std::fs::metadata(checkpoint)
            && m.len() > 0
        {
            break m.len();
        }
        assert!(started.elapsed().as_secs() < 120, "no checkpoint");
        std::thread::sleep(std::time::Duration::from_millis(5));
    };
    while std::fs::metadata(checkpoint).map_or(0, |m| m.len()) <= header {
        assert!(started.elapsed().as_secs() < 120, "no chunk finished");
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let mut child = child;
    assert!(
        child.try_wait().unwrap().is_none(),
        "the run ended too soon"
    );
    signal(&child, "INT");
    child.wait_with_output().unwrap()
}

/// Runs the `pidm` binary built with these tests in `dir`.
///
/// The child runs with `HDF5_USE_FILE_LOCKING=FALSE`: tests run in threads
/// of one process, libhdf5 opens files without close-on-exec, so a child
/// that another test starts while this process has an HDF5 file open
/// inherits the descriptor and its lock, and a `pidm` opening that file
/// (a damaged copy edited in-process, say) would fail with "unable to lock
/// file" for as long as the unrelated child runs. pidm's own output claim
/// (`flock` on `.NAME.lock`) is not HDF5's and stays on.
pub fn pidm(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pidm"))
        .env("HDF5_USE_FILE_LOCKING", "FALSE")
        .args(args)
        .current_dir(dir)
        .output()
        .expect("pidm runs")
}

/// `pidm run SCENE --backend BACKEND` in `dir` (a scene file there): the
/// maps `names` of its result file, after asserting that it ran on that
/// backend.
pub fn run_maps(dir: &Path, scene: &str, backend: &str, names: &[&str]) -> Vec<Vec<f64>> {
    let out = dir.join(format!("{backend}.h5"));
    let run = pidm(&["run", scene, "--backend", backend, "--out", s(&out)], dir);
    let said = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{said}");
    assert!(said.contains(&format!("pidm: backend {backend}")), "{said}");
    let file = hdf5::File::open(&out).expect("a result file");
    names
        .iter()
        .map(|m| {
            file.dataset(&format!("maps/{m}"))
                .unwrap()
                .read_raw()
                .unwrap()
        })
        .collect()
}

/// A path inside the repository, as text.
pub fn manifest(path: &str) -> String {
    format!("{}/{path}", env!("CARGO_MANIFEST_DIR"))
}

/// A path as text (temporary paths are UTF-8).
pub fn s(path: &Path) -> &str {
    path.to_str().expect("temporary paths are UTF-8")
}

/// One case of docs/model.md section 6: both stages `axis`, the given voltages
/// [V] and frequencies [Hz], Table 1's interface, duty 0.98, phases 0, 10
/// periods of which 2 settle.
pub fn case(vx: f64, vy: f64, fx: f64, fy: f64, axis: Axis) -> Instance {
    let mut inst = Instance::TABLE1;
    inst.axes = [axis, axis];
    inst.axes[0].voltage = vx;
    inst.axes[1].voltage = vy;
    inst.axes[0].frequency = fx;
    inst.axes[1].frequency = fy;
    inst
}

/// `n` light window runs for the tests of f32's check of its heaviest runs
/// (`pidm::laws::floor::check`): Table 1 with x at 40 V and up by `volts` [V]
/// each, y at 15 Hz, 2 periods of which 1 settles. Each takes far fewer
/// steps than a random scene's heavy instances, so a check passes them by.
pub fn light_instances(n: usize, volts: f64) -> Vec<Instance> {
    (0..n)
        .map(|k| {
            let mut inst = Instance::TABLE1;
            inst.axes[0].voltage = 40.0 + volts * k as f64;
            inst.axes[1].frequency = 15.0;
            inst.cycles = 2;
            inst.settle = 1;
            inst
        })
        .collect()
}

/// docs/model.md section 6: (name, instance, step_x, step_y) in um, given to 4
/// decimals there.
pub fn reference_cases() -> Vec<(&'static str, Instance, [f64; 2])> {
    let t = Axis::TABLE1;
    let x = Axis::TEXT;
    let r = 100.0 / 2f64.sqrt();
    vec![
        (
            "1-DOF 100 V 10 Hz",
            case(100.0, 0.0, 10.0, 10.0, t),
            [0.6159, 0.0],
        ),
        (
            "1-DOF 50 V 10 Hz",
            case(50.0, 0.0, 10.0, 10.0, t),
            [0.3802, 0.0],
        ),
        (
            "1-DOF 100 V 20 Hz",
            case(100.0, 0.0, 20.0, 20.0, t),
            [-1.1767, 0.0],
        ),
        (
            "2-DOF 70.71/70.71 V",
            case(r, r, 10.0, 10.0, t),
            [0.4355, 0.4355],
        ),
        (
            "2-DOF 100/100 V",
            case(100.0, 100.0, 10.0, 10.0, t),
            [-0.9424, -0.9424],
        ),
        (
            "2-DOF 100/50 V",
            case(100.0, 50.0, 10.0, 10.0, t),
            [0.0545, 0.0273],
        ),
        (
            "2-DOF 10/20 Hz",
            case(100.0, 100.0, 10.0, 20.0, t),
            [1.6151, -0.4950],
        ),
        (
            "text 1-DOF 100 V 20 Hz",
            case(100.0, 0.0, 20.0, 20.0, x),
            [-2.8519, 0.0],
        ),
        (
            "text 2-DOF 100/100 V",
            case(100.0, 100.0, 10.0, 10.0, x),
            [-0.6042, -0.6042],
        ),
        (
            "text 2-DOF 10/20 Hz",
            case(100.0, 100.0, 10.0, 20.0, x),
            [1.0692, -1.1754],
        ),
        (
            "text 1-DOF 100 V 10 Hz",
            case(100.0, 0.0, 10.0, 10.0, x),
            [0.0, 0.0],
        ),
        (
            "text 1-DOF 50 V 10 Hz",
            case(50.0, 0.0, 10.0, 10.0, x),
            [0.0, 0.0],
        ),
    ]
}

/// Steady measurements (docs/model.md section 4) of Table 1 at several drive
/// frequency pairs: six periodic ones (equal frequencies, a phase offset,
/// ratios 1.5, 1.4 and 2, one axis undriven), then a quasi-periodic one
/// converged statistically and the same one cut at 12 periods.
pub fn steady_instances() -> [Instance; 8] {
    let steady = |fx: f64, fy: f64, vy: f64, tolerance: f64, max_cycles: u32| {
        let mut inst = Instance::TABLE1;
        inst.axes[0].frequency = fx;
        inst.axes[1].frequency = fy;
        inst.axes[1].voltage = vy;
        inst.cycles = max_cycles;
        inst.measure = Measure::Steady {
            step_tolerance: tolerance,
        };
        inst
    };
    let mut phased = steady(10.0, 10.0, 100.0, 1e-8, 2000);
    phased.axes[1].phase = 0.3;
    [
        steady(10.0, 10.0, 100.0, 1e-8, 2000),
        phased,
        steady(10.0, 15.0, 100.0, 1e-8, 2000),
        steady(10.0, 14.0, 100.0, 1e-8, 2000),
        steady(10.0, 20.0, 50.0, 1e-8, 2000),
        steady(10.0, 10.0, 0.0, 1e-8, 2000),
        steady(10.0, 10.0 * 3f64.sqrt(), 100.0, 3e-8, 2000),
        steady(10.0, 10.0 * 3f64.sqrt(), 100.0, 1e-8, 12),
    ]
}

/// `instances` under a seeded random load on the slider (docs/model.md section
/// 7): a direction uniform in the plane and a magnitude uniform up to 0.9
/// of each instance's kinetic friction (a load of f_c or more is refused).
pub fn loaded(instances: &[Instance], seed: u64) -> Vec<Instance> {
    let mut rng = pidm::model::random::Rng::new(seed);
    instances
        .iter()
        .map(|inst| {
            let mut inst = *inst;
            let angle = std::f64::consts::TAU * rng.unit();
            let magnitude = 0.9 * inst.mechanism.coulomb_friction * rng.unit();
            inst.mechanism.load = [magnitude * angle.cos(), magnitude * angle.sin()];
            inst
        })
        .collect()
}

/// The step-against-load points (docs/model.md section 7): Table 1 at 10
/// Hz, duty 0.98, 100 V on x and 0 or 100 V on y, window 10 / 2, with the
/// load on x at the sweep's ends, the stall loads and between.
pub fn load_sweep_instances() -> Vec<Instance> {
    let mut out = Vec::new();
    for vy in [0.0, 100.0] {
        for load in [-0.95, -0.5, -0.0379, 0.0792, 0.3, 0.95] {
            let mut inst = Instance::TABLE1;
            inst.axes[1].voltage = vy;
            inst.mechanism.load = [load, 0.0];
            out.push(inst);
        }
    }
    out
}
