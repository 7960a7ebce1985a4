//! `pidm fit` (`pidm::fit`, docs/fit.md): recovery of the shipped
//! synthetic data sets (`examples/fit/`, made by pidm at known parameters
//! with 2 % noise) within 3 reported standard errors, a degenerate set
//! flagged as not identifiable, bad scenes and data refused with a message
//! naming the file, row or key, the same fit on the GPU (lavapipe in CI)
//! as on the CPU, the same seed giving the same fit, and Ctrl-C leaving
//! the best point written.
//!
//! Run with `WGPU_BACKEND=vulkan cargo test --release --test it -- fit::`.

use std::io::BufRead;
use std::path::Path;
use std::process::{Command, Stdio};

use crate::common::{manifest, pidm, s, signal};

/// Fits `scene` on `backend` into `dir`; FIT.json's object.
pub(crate) fn fit(scene: &str, dir: &Path, backend: &str, extra: &[&str]) -> serde_json::Value {
    let out = dir.join("fit.json");
    let mut args = vec!["fit", scene, "--out", s(&out), "--backend", backend];
    args.extend(extra);
    let run = pidm(&args, dir);
    assert!(
        run.status.success(),
        "pidm fit {scene} failed:\n{}",
        String::from_utf8_lossy(&run.stderr)
    );
    for sibling in ["fit.toml", "fit.png"] {
        assert!(dir.join(sibling).is_file(), "{sibling} was not written");
    }
    serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap()
}

/// Every true value within 3 standard errors of the fit, each standard
/// error under 10 % of its value, and the fit identifiable.
fn check_recovery(scene: &str, truth: &[(&str, f64)]) {
    let dir = tempfile::tempdir().unwrap();
    let json = fit(&manifest(scene), dir.path(), "cpu", &[]);
    assert_eq!(json["status"], "converged", "{json:#}");
    assert_eq!(json["identifiable"], true, "{json:#}");
    for (key, true_value) in truth {
        let p = &json["parameters"][key];
        let (value, se) = (p["value"].as_f64().unwrap(), p["se"].as_f64().unwrap());
        assert!(
            (value - true_value).abs() <= 3.0 * se,
            "{scene}: {key} = {value} +- {se}, truth {true_value}"
        );
        assert!(
            se > 0.0 && se < 0.1 * value.abs(),
            "{scene}: {key}: se {se} of {value}"
        );
    }
}

#[test]
fn the_shipped_synthetic_sets_are_recovered_within_three_standard_errors() {
    check_recovery(
        "examples/fit/karnopp.toml",
        &[
            ("mechanism.static_friction", 1.2),
            ("mechanism.coulomb_friction", 1.0),
            ("axis.x.gain", -0.6),
        ],
    );
    check_recovery(
        "examples/fit/lugre.toml",
        &[("mechanism.bristle_stiffness", 3.0e6)],
    );
    check_recovery(
        "examples/fit/coupling.toml",
        &[
            ("mechanism.static_friction", 1.2),
            ("mechanism.coulomb_friction", 1.0),
            ("axis.y.gain", -0.45),
        ],
    );
}

#[test]
fn one_point_cannot_determine_two_frictions() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("one.csv"),
        "axis.x.voltage,axis.x.frequency,step_x,step_x_se\n100,50,-1.4e-5,3e-7\n",
    )
    .unwrap();
    let scene = dir.path().join("one.toml");
    std::fs::write(
        &scene,
        "[fit]\ndata = \"one.csv\"\nfree = { \"mechanism.static_friction\" = [0.5, 3.0], \
         \"mechanism.coulomb_friction\" = [0.3, 2.0] }\n",
    )
    .unwrap();
    let json = fit(s(&scene), dir.path(), "cpu", &[]);
    assert_eq!(json["identifiable"], false, "{json:#}");
    let warnings = json["warnings"].to_string();
    assert!(
        warnings.contains("1 measured values for 2 free keys"),
        "{warnings}"
    );
    assert!(warnings.contains("correlated"), "{warnings}");
}

/// A bad fit scene or data file: `files` written into a folder, `pidm
/// fit` (or `run`, for "run:") on `scene.toml` fails with each fragment in
/// its message.
fn check_refused(files: &[(&str, &str)], fragments: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    for (name, text) in files {
        std::fs::write(dir.path().join(name), text).unwrap();
    }
    let command = if fragments[0] == "run:" { "run" } else { "fit" };
    let out = pidm(&[command, "scene.toml", "--backend", "cpu"], dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    for fragment in fragments.iter().filter(|f| **f != "run:") {
        assert!(stderr.contains(fragment), "no {fragment:?} in:\n{stderr}");
    }
    assert!(
        !dir.path().join("results").exists(),
        "a refused fit wrote files"
    );
}

const FIT: &str =
    "[fit]\ndata = \"d.csv\"\nfree = { \"mechanism.static_friction\" = [0.5, 3.0] }\n";
const HEADER: &str = "axis.x.voltage,step_x,step_x_se\n";

#[test]
fn bad_scenes_and_data_are_refused_naming_the_file_row_or_key() {
    let data = |rows: &str| format!("{HEADER}{rows}");
    check_refused(&[("scene.toml", FIT)], &["d.csv", "cannot be read"]);
    check_refused(
        &[
            ("scene.toml", FIT),
            ("d.csv", "axis.x.volts,step_x\n100,-1e-6\n"),
        ],
        &["d.csv", "column `axis.x.volts`: not a scene key"],
    );
    check_refused(
        &[
            ("scene.toml", FIT),
            ("d.csv", &data("100,-1e-6,1e-8\n120,NaN,1e-8\n")),
        ],
        &["d.csv", "line 3, column step_x: \"NaN\""],
    );
    check_refused(
        &[("scene.toml", FIT), ("d.csv", &data("100,-2.5,0.05\n"))],
        &[
            "data file d.csv",
            "line 2, column step_x: -2.5",
            "over 100 um",
            "step_x_um",
        ],
    );
    check_refused(
        &[("scene.toml", FIT), ("d.csv", &data(",-1e-6,1e-8\n"))],
        &["data file d.csv", "line 2, column axis.x.voltage: empty"],
    );
    check_refused(
        &[
            ("scene.toml", FIT),
            ("d.csv", "axis.x.voltage;step_x_um\n100;-1,5\n"),
        ],
        &[
            "data file d.csv",
            "line 2, column step_x_um: \"-1,5\": a decimal comma",
        ],
    );
    let free_frequency = FIT.replace(
        "mechanism.static_friction\" = [0.5, 3.0]",
        "axis.x.frequency\" = [5.0, 50.0]",
    );
    check_refused(
        &[
            ("scene.toml", &free_frequency),
            ("d.csv", "axis.x.voltage,velocity_x_um_s\n100,-20\n"),
        ],
        &["`axis.x.frequency` is free in [fit] and moves axis x's drive frequency"],
    );
    let reversed = FIT.replace("[0.5, 3.0]", "[3.0, 0.5]");
    check_refused(
        &[
            ("scene.toml", &reversed),
            ("d.csv", &data("100,-1e-6,1e-8\n")),
        ],
        &["mechanism.static_friction", "lower < upper"],
    );
    check_refused(
        &[
            ("scene.toml", FIT),
            ("d.csv", "mechanism.static_friction,step_x\n1.0,-1e-6\n"),
        ],
        &["`mechanism.static_friction` is both free in [fit] and a column of"],
    );
    let grid = format!("[axis.x]\nfrequency = [10.0, 20.0]\n{FIT}");
    check_refused(
        &[("scene.toml", &grid), ("d.csv", &data("100,-1e-6,1e-8\n"))],
        &["`axis.x.frequency` has 2 values"],
    );
    let stall = format!("[stall]\naxis = \"x\"\n{FIT}");
    check_refused(
        &[("scene.toml", &stall), ("d.csv", &data("100,-1e-6,1e-8\n"))],
        &["a fit scene takes no `stall`"],
    );
    let lugre_key = FIT.replace(
        "static_friction\" = [0.5, 3.0]",
        "bristle_stiffness\" = [1e5, 1e8]",
    );
    check_refused(
        &[
            ("scene.toml", &lugre_key),
            ("d.csv", &data("100,-1e-6,1e-8\n")),
        ],
        &["d.csv line 2", "bristle_stiffness"],
    );
    check_refused(
        &[("scene.toml", FIT)],
        &["run:", "pidm fit SCENE", "line 1"],
    );
}

#[test]
fn the_gpu_fits_what_the_cpu_fits() {
    if crate::gpu::context().is_none() {
        return;
    }
    let scene = manifest("examples/fit/coupling.toml");
    let (cpu, gpu) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let cpu = fit(&scene, cpu.path(), "cpu", &[]);
    let gpu = fit(&scene, gpu.path(), "gpu", &[]);
    assert!(
        gpu["backend"].as_str().unwrap().starts_with("gpu"),
        "{gpu:#}"
    );
    for key in cpu["order"].as_array().unwrap() {
        let key = key.as_str().unwrap();
        let (c, g) = (&cpu["parameters"][key], &gpu["parameters"][key]);
        let se = c["se"].as_f64().unwrap();
        let gap = (c["value"].as_f64().unwrap() - g["value"].as_f64().unwrap()).abs();
        // Both integrate to the same converged steps (1e-4 um); the fits
        // differ by far less than their uncertainty.
        assert!(gap < 1e-3 * se, "{key}: cpu {c} gpu {g}");
    }
}

#[test]
fn a_seed_gives_the_same_fit_and_check_describes_it() {
    let scene = manifest("examples/fit/coupling.toml");
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let first = fit(&scene, a.path(), "cpu", &["--seed", "7"]);
    let second = fit(&scene, b.path(), "cpu", &["--seed", "7"]);
    assert_eq!(first["parameters"], second["parameters"]);
    assert_eq!(first["seed"], 7);
    let fitted = std::fs::read_to_string(a.path().join("fit.toml")).unwrap();
    assert!(
        !fitted.contains("[fit]") && fitted.contains("static_friction"),
        "{fitted}"
    );
    let check = pidm(&["check", &scene], a.path());
    let text = String::from_utf8_lossy(&check.stdout);
    assert!(
        check.status.success(),
        "{}",
        String::from_utf8_lossy(&check.stderr)
    );
    assert!(
        text.contains("fit scene: 3 free keys against 24 measured values"),
        "{text}"
    );
    assert!(
        text.contains("axis.y.gain in [-1, -0.2] N/V (linear)"),
        "{text}"
    );
}

#[test]
fn ctrl_c_leaves_the_best_point_written() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("fit.json");
    let mut child = Command::new(env!("CARGO_BIN_EXE_pidm"))
        .args([
            "fit",
            &manifest("examples/fit/lugre.toml"),
            "--backend",
            "cpu",
        ])
        .args(["--progress", "jsonl", "--out", s(&out)])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = std::io::BufReader::new(child.stderr.take().unwrap()).lines();
    // The first batch done: the global stage is under way.
    let first = lines.find(|l| l.as_ref().is_ok_and(|l| l.starts_with("{\"")));
    assert!(first.is_some(), "no progress line");
    signal(&child, "INT");
    let rest: Vec<String> = lines.map_while(Result::ok).collect();
    assert_eq!(child.wait().unwrap().code(), Some(130), "{rest:?}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(json["status"], "interrupted");
    let value = json["parameters"]["mechanism.bristle_stiffness"]["value"]
        .as_f64()
        .unwrap();
    assert!((1e5..=1e8).contains(&value), "{value}");
    assert!(dir.path().join("fit.toml").is_file());
}

#[test]
fn a_window_scene_fits_with_no_tolerance_to_tighten() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("window.toml");
    let text = std::fs::read_to_string(manifest("examples/fit/coupling.toml")).unwrap();
    let data = manifest("examples/fit/coupling_steps.csv");
    let text = text.replace(
        "[fit]",
        "[simulation]\nmeasure = \"window\"\ncycles = 10\nsettle = 2\n\n[fit]",
    );
    std::fs::write(
        &scene,
        text.replace("\"coupling_steps.csv\"", &format!("{data:?}")),
    )
    .unwrap();
    let json = fit(s(&scene), dir.path(), "cpu", &[]);
    assert!(json["step_tolerance"].is_null(), "{json:#}");
    let p = &json["parameters"]["mechanism.coulomb_friction"];
    let (value, se) = (p["value"].as_f64().unwrap(), p["se"].as_f64().unwrap());
    assert!((value - 1.0).abs() <= 3.0 * se, "{value} +- {se}");
}

#[test]
fn check_json_describes_a_fit_and_out_never_overwrites_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let scene = manifest("examples/fit/lugre.toml");
    let check = pidm(&["check", &scene, "--json"], dir.path());
    assert!(
        check.status.success(),
        "{}",
        String::from_utf8_lossy(&check.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&check.stdout).unwrap();
    assert_eq!(json["fit"], true);
    assert_eq!(json["rows"], 12);
    assert_eq!(json["free"][0]["key"], "mechanism.bristle_stiffness");
    assert_eq!(json["free"][0]["scale"], "log");
    // FIT.toml beside --out x.json would be the scene x.toml itself.
    let copy = dir.path().join("x.toml");
    std::fs::copy(&scene, &copy).unwrap();
    std::fs::copy(
        manifest("examples/fit/lugre_steps.csv"),
        dir.path().join("lugre_steps.csv"),
    )
    .unwrap();
    let out = pidm(
        &["fit", "x.toml", "--out", "x.json", "--backend", "cpu"],
        dir.path(),
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("would overwrite the scene file"),
        "{stderr}"
    );
    assert_eq!(
        std::fs::read_to_string(&copy).unwrap(),
        std::fs::read_to_string(&scene).unwrap()
    );
}
