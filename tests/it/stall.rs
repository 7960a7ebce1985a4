//! Stall-load maps (`[stall]`, docs/model.md section 7) end to end: the issue's
//! stall loads through `pidm run`, the maps with their units, long names
//! and dimensions, an actuator that never stalls, the GPU's waves, and
//! shards, merge and resume giving the single run's file.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use hdf5::types::VarLenUnicode;
use pidm::output::compare_contents;

use crate::common::{pidm, s};

/// The stdout of a run that must succeed.
fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Writes a scene file `name.toml` into `dir`.
fn scene(dir: &Path, name: &str, body: &str) -> PathBuf {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, format!("name = \"{name}\"\n{body}")).unwrap();
    path
}

/// One map of a result file.
fn map<T: hdf5::H5Type>(file: &hdf5::File, name: &str) -> Vec<T> {
    file.dataset(&format!("maps/{name}"))
        .unwrap()
        .read_raw()
        .unwrap()
}

/// The issue's point with y at 0 V and at 100 V (a grid over axis.y.voltage).
const ISSUE: &str = "[axis.y]\nvoltage = [0.0, 100.0]\n[simulation]\nmeasure = \"window\"\n\
                     [stall]\naxis = \"x\"\n";

/// The issue's stall loads from an independent reference, -0.0379 N (y at
/// 0 V) and +0.0792 N (y at 100 V), within the default tolerance of 1e-4 N
/// (plus the reference's last digit); the bracket's steps on either side
/// of zero; the waves bracketing and bisection took; the maps described
/// like every map; and the summary's best stall load.
#[test]
fn the_stall_map_finds_the_reference_stall_loads() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let path = scene(d, "issue", ISSUE);
    let out = d.join("issue.h5");
    let stdout = ok(&pidm(
        &["run", s(&path), "--backend", "cpu", "--out", s(&out)],
        d,
    ));
    let file = hdf5::File::open(&out).unwrap();
    let load: Vec<f64> = map(&file, "stall_load_x");
    for (got, want) in load.iter().zip([-0.0379, 0.0792]) {
        assert!((got - want).abs() <= 1e-4 + 0.5e-4, "{got} against {want}");
    }
    let near: Vec<f64> = map(&file, "stall_step_near_x");
    let far: Vec<f64> = map(&file, "stall_step_far_x");
    let step: Vec<f64> = map(&file, "step_x");
    for k in 0..2 {
        assert!(near[k] * step[k] > 0.0 && far[k] * step[k] < 0.0, "#{k}");
        // Within the tolerance of the crossing, on slopes of 12-16 um/N.
        assert!(near[k].abs() < 2e-4 * 16.2e-6 * 1.5, "#{k}: {}", near[k]);
    }
    assert_eq!(map::<u32>(&file, "stall_waves_x"), [12, 14]);
    assert_eq!(map::<u32>(&file, "stall_status_x"), [0, 0]);
    let ds = file.dataset("maps/stall_load_x").unwrap();
    let units: VarLenUnicode = ds.attr("units").unwrap().read_scalar().unwrap();
    assert_eq!(units.as_str(), "N");
    let long: VarLenUnicode = ds.attr("long_name").unwrap().read_scalar().unwrap();
    assert!(
        long.as_str().contains("zero crossing nearest zero load"),
        "{long}"
    );
    // The dimension scale of the grid, and the root link, as every map.
    assert!(ds.attr("DIMENSION_LIST").is_ok());
    assert!(file.dataset("stall_load_x").is_ok());
    assert!(
        stdout.contains("best: +0.07916 N at axis.y.voltage = 100 V"),
        "{stdout}"
    );
    assert!(
        stdout.contains("13 waves after the unloaded run, 24 probe integrations"),
        "{stdout}"
    );
}

/// docs/model.md section 7: where the step keeps its direction at every load
/// probed, the stall status is 8 and the map 0 (never a made-up number);
/// the near step is the step at the largest load probed, still backward.
/// Table 1 with f_c = 0.2 N at 100 V backs off at -6.9 um and pushes
/// any load it can hold.
#[test]
fn an_actuator_that_never_stalls_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let path = scene(
        d,
        "strong",
        "[mechanism]\ncoulomb_friction = 0.2\n[simulation]\nmeasure = \"window\"\n\
         [stall]\naxis = \"x\"\n",
    );
    let out = d.join("strong.h5");
    let stdout = ok(&pidm(
        &["run", s(&path), "--backend", "cpu", "--out", s(&out)],
        d,
    ));
    let file = hdf5::File::open(&out).unwrap();
    assert_eq!(map::<u32>(&file, "stall_status_x"), [8]);
    assert_eq!(map::<f64>(&file, "stall_load_x"), [0.0]);
    assert_eq!(map::<f64>(&file, "stall_step_far_x"), [0.0]);
    let near: Vec<f64> = map(&file, "stall_step_near_x");
    let step: Vec<f64> = map(&file, "step_x");
    assert!(step[0] < -6e-6 && near[0] < 0.0, "{step:?} {near:?}");
    // The unloaded run and one probe per bracketing fraction.
    assert_eq!(
        map::<u32>(&file, "stall_waves_x"),
        [1 + pidm::stall::BRACKET.len() as u32]
    );
    assert!(stdout.contains("no stall load below f_c: 1"), "{stdout}");
}

/// The GPU runs whole waves: its stall maps are the CPU's, in f64 to the
/// tolerance's own scale (it takes the CPU's steps, so the same
/// decisions), in f32 within a few tolerances.
#[test]
fn the_gpu_runs_the_waves_to_the_cpu_stall_loads() {
    if pidm::gpu::GpuContext::new(true).is_err() {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI must run the shader: no GPU adapter (install mesa-vulkan-drivers, WGPU_BACKEND=vulkan)"
        );
        eprintln!("NOTICE: no GPU adapter here; the GPU stall test did not run");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let path = scene(d, "issue", ISSUE);
    let mut loads = Vec::new();
    for (name, backend, precision) in [
        ("cpu.h5", "cpu", "f64"),
        ("gpu64.h5", "gpu", "f64"),
        ("gpu32.h5", "gpu", "f32"),
    ] {
        let out = d.join(name);
        ok(&pidm(
            &[
                "run",
                s(&path),
                "--backend",
                backend,
                "--precision",
                precision,
                "--out",
                s(&out),
            ],
            d,
        ));
        let file = hdf5::File::open(&out).unwrap();
        assert_eq!(map::<u32>(&file, "stall_status_x"), [0, 0], "{name}");
        loads.push(map::<f64>(&file, "stall_load_x"));
    }
    for k in 0..2 {
        assert!((loads[1][k] - loads[0][k]).abs() <= 1e-12, "{loads:?}");
        assert!((loads[2][k] - loads[0][k]).abs() <= 3e-4, "{loads:?}");
    }
}

/// Waits until the checkpoint at `path` is at least `bytes` long.
fn wait_for(path: &Path, bytes: u64) {
    let deadline = Instant::now() + Duration::from_secs(120);
    while std::fs::metadata(path).map_or(0, |m| m.len()) < bytes {
        assert!(
            Instant::now() < deadline,
            "no checkpoint progress at {path:?}"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// A stall scene split into shards and merged, and one stopped by Ctrl-C
/// in its waves and resumed, give the single run's file bit for bit.
#[test]
fn stall_runs_shard_merge_and_resume_to_the_single_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 24 instances of 30 periods: waves long enough to stop part-way.
    let path = scene(
        d,
        "grid",
        "[axis.x]\nvoltage = [60.0, 70.0, 80.0, 90.0, 100.0, 110.0, 120.0, 130.0, 140.0, \
         150.0, 160.0, 170.0]\n[axis.y]\nvoltage = [0.0, 100.0]\n\
         [simulation]\nmeasure = \"window\"\ncycles = 30\n[stall]\naxis = \"x\"\n",
    );
    let single = d.join("single.h5");
    ok(&pidm(
        &["run", s(&path), "--backend", "cpu", "--out", s(&single)],
        d,
    ));

    for k in 1..=2 {
        ok(&pidm(
            &[
                "run",
                s(&path),
                "--backend",
                "cpu",
                "--shard",
                &format!("{k}/2"),
            ],
            d,
        ));
    }
    let merged = d.join("merged.h5");
    ok(&pidm(
        &[
            "merge",
            s(&merged),
            "results/grid.shard-1-of-2.h5",
            "results/grid.shard-2-of-2.h5",
        ],
        d,
    ));
    compare_contents(&single, &merged).unwrap();

    let out = d.join("stopped.h5");
    let checkpoint = d.join(".stopped.h5.checkpoint");
    let args = [
        "run",
        s(&path),
        "--out",
        s(&out),
        "--backend",
        "cpu",
        "--threads",
        "1",
        "--chunk-size",
        "4",
    ];
    let child = Command::new(env!("CARGO_BIN_EXE_pidm"))
        .args(args)
        .current_dir(d)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The header, wave 0's six entries of 4 records (32-byte head, 85
    // bytes a record, 8-byte sum) and a first wave of 24 probes.
    let entry = |n: u64| 32 + 85 * n + 8;
    wait_for(&checkpoint, 1);
    let header = std::fs::metadata(&checkpoint).unwrap().len();
    wait_for(&checkpoint, header + 6 * entry(4) + entry(24));
    crate::common::signal(&child, "INT");
    let ended = child.wait_with_output().unwrap();
    assert!(!ended.status.success(), "the run was not stopped");
    assert!(!out.exists() && checkpoint.exists());
    let mut resume = args.to_vec();
    resume.push("--resume");
    let resumed = pidm(&resume, d);
    ok(&resumed);
    let stderr = String::from_utf8_lossy(&resumed.stderr);
    assert!(
        stderr.contains("24 of 24 unloaded instances and"),
        "{stderr}"
    );
    assert!(!checkpoint.exists());
    compare_contents(&single, &out).unwrap();
}

/// The PNG files in a folder, sorted.
fn pictures(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".png"))
        .collect();
    names.sort();
    names
}

/// `pidm plot` draws the stall-load map of a grid of two axes (a heatmap),
/// of one axis (a line) and of points (a dot each), beside the step maps;
/// and a step against a load at two voltages as a family of lines, the
/// picture read at a glance.
#[test]
fn pidm_plot_draws_the_stall_load_map_and_steps_against_a_load() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let window = "[simulation]\nmeasure = \"window\"\ncycles = 4\n";
    let cases = [
        (
            "grid2",
            format!(
                "[mechanism]\ncoulomb_friction = [0.2, 1.0]\n[axis.x]\nvoltage = [60.0, 100.0, \
                 140.0]\n{window}[stall]\naxis = \"x\"\n"
            ),
            vec!["stall_load_x.png", "step_x.png", "step_y.png"],
        ),
        (
            "grid1",
            format!("[axis.y]\nvoltage = [0.0, 50.0, 100.0]\n{window}[stall]\naxis = \"x\"\n"),
            vec!["stall_load_x.png", "steps.png"],
        ),
        (
            "points",
            format!(
                "{window}[stall]\naxis = \"y\"\n[axis.y]\nvoltage = 100.0\n\
                 [[points]]\nlabel = \"a\"\n[[points]]\nlabel = \"b\"\naxis.y = {{ duty = 1.0 }}\n"
            ),
            vec!["stall_load_y.png", "steps.png"],
        ),
        (
            "load",
            format!(
                "[mechanism]\nload_x = {{ from = -0.8, to = 0.8, steps = 9 }}\n\
                 [axis.y]\nvoltage = [0.0, 100.0]\n{window}"
            ),
            vec![
                "step_x.png",
                "step_x_lines.png",
                "step_y.png",
                "step_y_lines.png",
            ],
        ),
    ];
    for (name, body, want) in cases {
        let path = scene(d, name, &body);
        let out = d.join(format!("{name}.h5"));
        ok(&pidm(
            &["run", s(&path), "--backend", "cpu", "--out", s(&out)],
            d,
        ));
        let pics = d.join(format!("pics_{name}"));
        ok(&pidm(&["plot", s(&out), "--out", s(&pics)], d));
        assert_eq!(pictures(&pics), want, "{name}");
    }
}

/// The shipped scenes of the load (docs/model.md section 7): `sweeps/stall.toml`
/// maps the stall load of x over V_x and duty (steady), holding the
/// issue's -0.0379 N at 100 V and duty 0.98; `sweeps/load.toml` is the
/// step against a load on x at two y voltages, holding the reference's
/// ends of the sweep; each draws its picture.
#[test]
fn the_shipped_load_scenes_hold_the_reference_and_draw() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let stall = d.join("stall.h5");
    let scene = crate::common::manifest("sweeps/stall.toml");
    ok(&pidm(
        &["run", &scene, "--backend", "cpu", "--out", s(&stall)],
        d,
    ));
    let file = hdf5::File::open(&stall).unwrap();
    let volts: Vec<f64> = file
        .dataset("axes/axis.x.voltage")
        .unwrap()
        .read_raw()
        .unwrap();
    let duty: Vec<f64> = file
        .dataset("axes/axis.x.duty")
        .unwrap()
        .read_raw()
        .unwrap();
    // At least four samples a period of the step's swing with the duty
    // (about 0.006, sweeps/stall.toml), so its bands are not aliased.
    assert!(
        duty.windows(2).all(|w| w[1] - w[0] <= 0.006 / 4.0),
        "{duty:?}"
    );
    let (i, j) = (
        volts.iter().position(|&v| v == 100.0).unwrap(),
        duty.iter().position(|&v| (v - 0.98).abs() < 1e-12).unwrap(),
    );
    let load: Vec<f64> = map(&file, "stall_load_x");
    let at = load[i * duty.len() + j];
    assert!((at + 0.0379).abs() <= 1.5e-4, "{at}");
    assert!(map::<u32>(&file, "stall_status_x").iter().all(|&s| s == 0));
    ok(&pidm(&["plot", s(&stall), "--out", "pics_stall"], d));
    assert!(pictures(&d.join("pics_stall")).contains(&"stall_load_x.png".to_owned()));

    let sweep = d.join("load.h5");
    let scene = crate::common::manifest("sweeps/load.toml");
    ok(&pidm(
        &["run", &scene, "--backend", "cpu", "--out", s(&sweep)],
        d,
    ));
    let file = hdf5::File::open(&sweep).unwrap();
    let step: Vec<f64> = map(&file, "step_x");
    // load_x from -0.95 to 0.95 N (39 values) by y at 0 and 100 V.
    let (first, last) = (step[1] * 1e6, step[2 * 38 + 1] * 1e6);
    assert!(
        (first + 77.7).abs() <= 0.1 && (last - 115.9).abs() <= 0.1,
        "{first} {last}"
    );
    ok(&pidm(&["plot", s(&sweep), "--out", "pics_load"], d));
    assert!(pictures(&d.join("pics_load")).contains(&"step_x_lines.png".to_owned()));
}
