//! What a program driving `pidm run` reads: `--progress jsonl` lines, the
//! exit statuses of a run stopped by SIGINT (130) or SIGTERM (143) with the
//! `--resume` command on stderr, and `pidm check --json`.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::common::{pidm, s, signal};

/// A 4 x 5 grid with baselines, `cycles` cycles each (40: a few hundred
/// milliseconds of work on one thread).
fn grid_scene(dir: &Path, cycles: u32) -> String {
    let path = dir.join("grid.toml");
    std::fs::write(
        &path,
        format!(
            "name = \"grid\"\n\
         [axis.x]\nvoltage = [40.0, 80.0, 120.0, 160.0]\n\
         [axis.y]\nvoltage = [0.0, 30.0, 60.0, 90.0, 120.0]\nfrequency = 20.0\n\
         [simulation]\nmeasure = \"window\"\ncycles = {cycles}\nsettle = 1\n\
         [output]\nbaselines = true\n"
        ),
    )
    .unwrap();
    s(&path).to_string()
}

/// The JSON progress lines of a stderr text, parsed; every other line is
/// plain text that does not start with `{`.
fn json_lines(stderr: &str) -> Vec<serde_json::Value> {
    stderr
        .lines()
        .filter(|l| l.starts_with('{'))
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{l:?}: {e}")))
        .collect()
}

#[test]
fn jsonl_progress_counts_up_to_the_total() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = grid_scene(d, 40);
    let run = pidm(
        &[
            "run",
            &scene,
            "--out",
            "grid.h5",
            "--backend",
            "cpu",
            "--threads",
            "1",
            "--chunk-size",
            "2",
            "--progress",
            "jsonl",
        ],
        d,
    );
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    let lines = json_lines(&stderr);
    assert!(lines.len() >= 2, "{stderr}");
    let mut done_before = 0;
    let mut elapsed_before = 0.0;
    for line in &lines {
        let done = line["done"].as_u64().unwrap();
        assert_eq!(line["total"], 20, "{line}");
        assert!(done >= done_before && done <= 20, "{line}");
        let elapsed = line["elapsed_s"].as_f64().unwrap();
        assert!(elapsed >= elapsed_before, "{line}");
        assert!(line["instances_per_s"].as_f64().unwrap() >= 0.0, "{line}");
        // The estimate is a number once an instance finished.
        let eta = &line["eta_s"];
        assert!(eta.is_null() == (done == 0), "{line}");
        done_before = done;
        elapsed_before = elapsed;
    }
    assert_eq!(lines[0]["done"], 0);
    let last = lines.last().unwrap();
    assert_eq!(last["done"], 20, "{stderr}");
    assert_eq!(last["eta_s"], 0.0);
    assert!(last["instances_per_s"].as_f64().unwrap() > 0.0);

    // `none` and the default off a terminal print no JSON, and no bar.
    for extra in [&["--progress", "none"][..], &[]] {
        std::fs::remove_file(d.join("grid.h5")).unwrap();
        let mut args = vec!["run", &scene, "--out", "grid.h5", "--backend", "cpu"];
        args.extend_from_slice(extra);
        let run = pidm(&args, d);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(run.status.success(), "{stderr}");
        assert!(json_lines(&stderr).is_empty(), "{stderr}");
        assert!(!stderr.contains("/20 instances"), "{stderr}");
    }

    let bad = pidm(&["run", &scene, "--progress", "loud"], d);
    assert_eq!(bad.status.code(), Some(2));
}

/// A resumed run counts its checkpoint's instances as done from its first
/// line on.
#[test]
fn jsonl_progress_of_a_resumed_run_starts_at_the_checkpoint() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Seconds of work on one thread: it is stopped after its first chunk.
    let scene = grid_scene(d, 300);
    let args = [
        "run",
        &scene,
        "--out",
        "grid.h5",
        "--backend",
        "cpu",
        "--threads",
        "1",
        "--chunk-size",
        "2",
        "--progress",
        "jsonl",
    ];
    let mut child = spawn(&args, d);
    let checkpoint = d.join(".grid.h5.checkpoint");
    // Wait until the checkpoint holds a chunk or more past its header.
    let started = Instant::now();
    let header = loop {
        // The journal is created empty, then its header is written in
        // one write: its length once non-zero is the header's.
        if let Ok(meta) = std::fs::metadata(&checkpoint)
            && meta.len() > 0
        {
            break meta.len();
        }
        assert!(started.elapsed() < Duration::from_secs(30));
        std::thread::sleep(Duration::from_millis(5));
    };
    while std::fs::metadata(&checkpoint).map_or(0, |m| m.len()) <= header {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the run ended too soon"
        );
        assert!(started.elapsed() < Duration::from_secs(30));
        std::thread::sleep(Duration::from_millis(2));
    }
    signal(&child, "INT");
    let ended = child.wait().unwrap();
    assert_eq!(ended.code(), Some(130));

    let mut resume = args.to_vec();
    resume.push("--resume");
    let run = pidm(&resume, d);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    let lines = json_lines(&stderr);
    let first = lines[0]["done"].as_u64().unwrap();
    assert!((2..20).contains(&first), "{stderr}");
    assert!(
        stderr.contains(&format!("{first} of 20 instances done")),
        "{stderr}"
    );
    assert_eq!(lines.last().unwrap()["done"], 20, "{stderr}");
    // The file's wall time counts both parts, and names each.
    let file = hdf5::File::open(d.join("grid.h5")).unwrap();
    let total: f64 = file.attr("wall_time_s").unwrap().read_scalar().unwrap();
    let parts: Vec<f64> = file.attr("wall_time_parts_s").unwrap().read_raw().unwrap();
    assert_eq!(parts.len(), 2, "{parts:?}");
    assert!(parts[0] > 0.0 && parts[1] > 0.0, "{parts:?}");
    assert_eq!(total, parts[0] + parts[1]);
}

fn spawn(args: &[&str], dir: &Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_pidm"))
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// One instance of ten million cycles (hours), stopped by `name` once its
/// first progress line is out: the exit status, the time it took to stop,
/// and stderr.
fn stop_a_long_run(name: &str) -> (Option<i32>, Duration, String) {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("endless.toml"),
        "[axis.x]\nvoltage = 100.0\n[simulation]\nmeasure = \"window\"\ncycles = 10000000\n",
    )
    .unwrap();
    let args = [
        "run",
        "endless.toml",
        "--out",
        "it's here.h5",
        "--backend",
        "cpu",
        "--progress",
        "jsonl",
    ];
    let mut child = spawn(&args, d);
    let mut stderr = BufReader::new(child.stderr.take().unwrap());
    let mut text = String::new();
    // The first JSON line comes once the sweep runs (the handler is in
    // place well before).
    while !text.lines().any(|l| l.starts_with('{')) {
        let mut line = String::new();
        assert!(stderr.read_line(&mut line).unwrap() > 0, "{text}");
        text.push_str(&line);
    }
    std::thread::sleep(Duration::from_millis(200));
    let asked = Instant::now();
    signal(&child, name);
    let status = child.wait().unwrap();
    let waited = asked.elapsed();
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut stderr, &mut rest).unwrap();
    text.push_str(&rest);
    assert!(!d.join("it's here.h5").exists());
    assert!(d.join(".it's here.h5.checkpoint").exists());
    (status.code(), waited, text)
}

#[test]
fn sigint_exits_130_and_prints_the_resume_command() {
    let (code, waited, stderr) = stop_a_long_run("INT");
    assert_eq!(code, Some(130), "{stderr}");
    assert!(waited < Duration::from_secs(5), "took {waited:?} to stop");
    assert!(stderr.contains("stopped by SIGINT"), "{stderr}");
    // The command is this one with --resume, quoted for a shell.
    let command = format!(
        "{} run endless.toml --out 'it'\\''s here.h5' --backend cpu --progress jsonl --resume",
        env!("CARGO_BIN_EXE_pidm")
    );
    assert!(stderr.contains(&command), "{stderr}");
    // No progress line claims a finished run.
    let last = json_lines(&stderr).pop().unwrap();
    assert_eq!(last["done"], 0, "{stderr}");
}

#[test]
fn sigterm_exits_143() {
    let (code, waited, stderr) = stop_a_long_run("TERM");
    assert_eq!(code, Some(143), "{stderr}");
    assert!(waited < Duration::from_secs(5), "took {waited:?} to stop");
    assert!(stderr.contains("stopped by SIGTERM"), "{stderr}");
    assert!(stderr.contains("--resume"), "{stderr}");
}

#[test]
fn check_json_gives_the_grid_and_the_cost() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = grid_scene(d, 40);
    let out = pidm(&["check", "--json", &scene], d);
    assert!(out.status.success());
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["name"], "grid");
    assert_eq!(report["layout"], "grid");
    assert_eq!(report["instances"], 20);
    assert_eq!(report["shape"], serde_json::json!([4, 5]));
    assert_eq!(report["axes"][1]["key"], "axis.y.voltage");
    assert_eq!(report["axes"][1]["units"], "V");
    assert_eq!(report["axes"][1]["last"], 120.0);
    assert_eq!(report["baselines"], true);
    assert!(report["estimate_s"].as_f64().unwrap() > 0.0);
    assert!(report["simulated_s"].as_f64().unwrap() > 0.0);

    // A bad scene: the message on stderr names the key, exit status 1.
    std::fs::write(d.join("bad.toml"), "[axis.x]\nvoltag = 3.0\n").unwrap();
    let bad = pidm(&["check", "--json", "bad.toml"], d);
    assert_eq!(bad.status.code(), Some(1));
    assert!(bad.stdout.is_empty());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("axis.x.voltag"), "{err}");
}

/// The exit statuses are documented where users look: `--help` of pidm and
/// of `pidm run`, and the README.
#[test]
fn help_and_readme_list_the_exit_statuses() {
    let dir = tempfile::tempdir().unwrap();
    for args in [&["--help"][..], &["run", "--help"]] {
        let out = pidm(args, dir.path());
        assert!(out.status.success());
        let help = String::from_utf8_lossy(&out.stdout);
        let statuses = help
            .split("Exit status:")
            .nth(1)
            .unwrap_or_else(|| panic!("{args:?}: no exit statuses in\n{help}"));
        for code in ["0", "1", "2", "3", "130"] {
            assert!(
                statuses
                    .lines()
                    .any(|l| l.trim_start().starts_with(&format!("{code} "))),
                "{args:?}: no exit status {code} in\n{help}"
            );
        }
        assert!(statuses.contains("143 by SIGTERM"), "{help}");
    }
    let readme = include_str!("../../README.md");
    let table = readme
        .split("Exit statuses (also in `pidm --help`):")
        .nth(1)
        .expect("the README lists the exit statuses");
    for row in ["| 0 |", "| 1 |", "| 2 |", "| 3 |", "| 130, 143 |"] {
        assert!(table.contains(row), "README: no row {row}");
    }
}
