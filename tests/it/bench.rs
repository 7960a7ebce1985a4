//! `results/gpu/bench.sh`, the one device script (issue 32), end to end in
//! its smoke mode: small versions of its scenes, every run a whole `pidm
//! run` process on the CPU, the GPU in f64 and f32 (lavapipe in CI) and
//! `--backend auto`, and one table, with the lanes' figures of every GPU
//! run and the saturation curve. Not timed: the test checks that every run
//! finished and was tabled, never how fast.

use std::process::Command;

use crate::common::manifest;

#[test]
fn the_device_script_runs_end_to_end_in_its_smoke_mode() {
    // Skipped (loudly) without an adapter, failed under CI.
    if crate::gpu::context().is_none() {
        return;
    }
    let out = tempfile::tempdir().unwrap();
    let run = Command::new("bash")
        .arg(manifest("results/gpu/bench.sh"))
        .arg("smoke")
        .env("PIDM", env!("CARGO_BIN_EXE_pidm"))
        .env("OUT", out.path())
        .env("HDF5_USE_FILE_LOCKING", "FALSE")
        .env_remove("PIDM_CACHE_DIR")
        .env_remove("PIDM_BENCH_SCENES")
        .env("PIDM_BENCH_BUDGET", "900")
        .env("PIDM_BENCH_TIMEOUT", "600")
        .output()
        .expect("bash runs");
    let stdout = String::from_utf8_lossy(&run.stdout);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stdout}\n{stderr}");
    let table = std::fs::read_to_string(out.path().join("table.md")).unwrap();
    let rows: Vec<Vec<&str>> = table
        .lines()
        .skip(2)
        .map(|l| l.trim_matches('|').split('|').map(str::trim).collect())
        .collect();
    let scenes: Vec<&str> = rows.iter().map(|r| r[0]).collect();
    assert_eq!(
        scenes,
        [
            "coupling 20 x 20",
            "coupling 30 x 30",
            "random 400",
            "two-frequency 8 x 8"
        ],
        "{table}"
    );
    let runs = std::fs::read_to_string(out.path().join("runs.log")).unwrap();
    for row in &rows {
        // Instances, then the CPU, GPU f64, GPU f32 and auto seconds.
        // The two-frequency map's CPU time is its sample's, scaled: "(x4)".
        for cell in &row[1..6] {
            let number = cell.trim_end_matches(" (x4)");
            assert!(number.parse::<f64>().is_ok(), "{cell:?} in {row:?}\n{runs}");
        }
        assert_eq!(
            row[2].ends_with("(x4)"),
            row[0].starts_with("two-frequency"),
            "{row:?}"
        );
        // The smoke scenes are small, and lavapipe is never auto's: it
        // runs them on the CPU.
        assert_eq!(row[6], "cpu", "{row:?}\n{runs}");
    }
    let phases = std::fs::read_to_string(out.path().join("phases.txt")).unwrap();
    assert!(phases.contains("pidm: GPU ready in "), "{phases}");
    // Every GPU run's phase table.
    assert!(
        phases.matches("pidm: phase table (driver").count() >= 8,
        "{phases}"
    );
    assert!(
        phases.contains("== whole processes [s], mode smoke"),
        "{phases}"
    );
    // The lanes' figures of every GPU run (issue 38).
    assert!(
        phases
            .matches("warps of 32 lanes in dispatch order")
            .count()
            >= 8,
        "{phases}"
    );
    assert!(phases.contains("critical path of batch 0"), "{phases}");
    // The saturation curve: a row per count, each with its numbers.
    let curve = std::fs::read_to_string(out.path().join("saturation.md")).unwrap();
    let rows: Vec<Vec<&str>> = curve
        .lines()
        .skip(2)
        .map(|l| l.trim_matches('|').split('|').map(str::trim).collect())
        .collect();
    let counts: Vec<&str> = rows.iter().map(|r| r[0]).collect();
    assert_eq!(counts, ["100", "400", "1600"], "{curve}");
    for row in &rows {
        let seconds = row[1].split(' ').next().unwrap();
        assert!(seconds.parse::<f64>().is_ok(), "{row:?}\n{runs}");
        assert!(row[2].parse::<f64>().is_ok(), "{row:?}");
        assert!(row[4].ends_with(" %"), "{row:?}");
    }
}
