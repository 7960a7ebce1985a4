//! The design commands (issue 61, docs/design.md): `pidm sensitivity`'s
//! indices are right where they are known, reproducible, and refused
//! before any work on bad input; `pidm optimize` finds a grid's best and
//! front. SALib's agreement on the samples' CSV is
//! tests/python/test_design.py's.

use std::path::Path;

use serde_json::Value;

use crate::common::{pidm, s};

/// A 1-DOF steady scene of Table 1 with `section` after it.
fn scene(dir: &Path, name: &str, section: &str) -> std::path::PathBuf {
    let path = dir.join(format!("{name}.toml"));
    let text = format!("name = \"{name}\"\n[axis.y]\nvoltage = 0\n{section}");
    std::fs::write(&path, text).unwrap();
    path
}

fn read_json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Runs `pidm sensitivity` on the CPU; SENS.json.
fn sensitivity(dir: &Path, scene: &Path, seed: &str, out: &str) -> Value {
    let out = dir.join(out);
    let run = pidm(
        &[
            "sensitivity",
            s(scene),
            "--out",
            s(&out),
            "--backend",
            "cpu",
            "--seed",
            seed,
        ],
        dir,
    );
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    assert!(out.with_extension("png").is_file());
    read_json(&out)
}

/// Two keys whose effect on the step is nearly additive (the voltage and
/// a small load, 1-DOF) and one it ignores (the undriven y stage's
/// stiffness): the ignored key's indices are within 0.02 of 0, and the
/// others' first-order and total indices agree within 0.02 (N = 4096,
/// 20,480 runs, under a second on one core).
#[test]
fn sensitivity_finds_an_additive_model_and_an_ignored_key() {
    let dir = tempfile::tempdir().unwrap();
    let path = scene(
        dir.path(),
        "additive",
        "[sensitivity]\nsamples = 4096\noutputs = [\"step_x\"]\n[sensitivity.inputs]\n\
         \"axis.x.voltage\" = { uniform = [90, 110] }\n\
         \"mechanism.load_x\" = { uniform = [-0.02, 0.02] }\n\
         \"axis.y.stiffness\" = { uniform = [0.9e6, 1.1e6] }\n",
    );
    let json = sensitivity(dir.path(), &path, "3", "a.json");
    let out = &json["outputs"][0];
    let index = |name: &str, i: usize| out[name][i].as_f64().unwrap();
    for i in 0..2 {
        let (s1, st) = (index("first", i), index("total", i));
        assert!((s1 - st).abs() <= 0.02, "input {i}: S1 {s1} ST {st}");
        assert!(s1 > 0.1, "input {i} matters: S1 {s1}");
    }
    assert!(index("first", 2).abs() <= 0.02 && index("total", 2).abs() <= 0.02, "{out}");
    assert_eq!(json["runs"], 4096 * 5);
    assert_eq!(json["rows_dropped"], 0);
}

/// The same seed gives the same SENS.json but its wall time; another
/// seed another sample.
#[test]
fn sensitivity_is_reproducible_by_its_seed() {
    let dir = tempfile::tempdir().unwrap();
    let path = scene(
        dir.path(),
        "seeded",
        "[simulation]\nmeasure = \"window\"\ncycles = 3\nsettle = 1\n[sensitivity]\nsamples = 32\n\
         outputs = [\"step_x\", \"abs(step_x)\"]\n[sensitivity.inputs]\n\
         \"axis.x.voltage\" = { normal = { mean = 100, sd = 5 } }\n\
         \"mechanism.static_friction\" = { lognormal = { median = 1.2, factor = 1.05 } }\n",
    );
    let strip = |mut v: Value| {
        v.as_object_mut().unwrap().remove("wall_time_s").expect("timed");
        v
    };
    let a = strip(sensitivity(dir.path(), &path, "5", "a.json"));
    let b = strip(sensitivity(dir.path(), &path, "5", "b.json"));
    let c = strip(sensitivity(dir.path(), &path, "6", "c.json"));
    assert_eq!(a, b);
    assert_ne!(a["outputs"], c["outputs"]);
}

/// Each bad study is refused before any run, naming what is wrong, and
/// leaves no file; `pidm check` says what a good one costs.
#[test]
fn sensitivity_refuses_bad_studies_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let input = "\"axis.x.voltage\" = { uniform = [90, 110] }";
    let cases = [
        ("samples = 1\noutputs = [\"step_x\"]", input, "from 2 to 1048576"),
        ("samples = 1048577\noutputs = [\"step_x\"]", input, "from 2 to 1048576"),
        ("samples = 8\noutputs = [\"step_z\"]", input, "`step_z` is no quantity"),
        (
            "samples = 8\noutputs = [\"backward_ratio_x\"]",
            input,
            "only with `[output] backward = true`",
        ),
        (
            "samples = 8\noutputs = [\"step_x\"]",
            "\"simulation.cycles\" = { uniform = [1, 3] }",
            "`simulation.cycles` cannot take a distribution",
        ),
        (
            "samples = 8\noutputs = [\"step_x\"]",
            "\"axis.x.duty\" = { uniform = [0.9, 1.1] }",
            "outside the key's range",
        ),
    ];
    for (k, (head, inputs, part)) in cases.iter().enumerate() {
        let path = scene(
            dir.path(),
            &format!("bad{k}"),
            &format!("[sensitivity]\n{head}\ninputs = {{ {inputs} }}\n"),
        );
        for cmd in ["check", "sensitivity"] {
            let out = dir.path().join(format!("bad{k}.json"));
            let run = pidm(&[cmd, s(&path), "--out", s(&out)][..if cmd == "check" { 2 } else { 4 }], dir.path());
            let err = String::from_utf8_lossy(&run.stderr);
            assert!(!run.status.success() && err.contains(part), "{cmd} case {k}: {err}");
            assert!(!out.exists() && !out.with_extension("png").exists());
        }
    }
    let good = scene(
        dir.path(),
        "good",
        &format!("[sensitivity]\nsamples = 10\noutputs = [\"step_x\"]\ninputs = {{ {input} }}\n"),
    );
    let run = pidm(&["check", s(&good)], dir.path());
    let text = String::from_utf8_lossy(&run.stdout);
    assert!(text.contains("N = 10 base rows x (k + 2 = 3) = 30 runs"), "{text}");
}
