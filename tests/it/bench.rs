//! `results/gpu/bench.sh`, the one device script (issues 32, 47), end to
//! end in its smoke mode: small versions of its three scenes, every run a
//! whole `pidm run` process on the CPU and the GPU in f64 and f32
//! (lavapipe in CI), with the lanes' figures of every GPU run, the time per
//! lockstep pass of 32, 256 and 1,024 alike instances, and one archive of
//! it all. Not timed: the test checks that every run finished and was
//! tabled, never how fast.

use std::process::Command;

use crate::common::manifest;

/// The rows of a Markdown table file (after its header and rule), cells
/// trimmed.
fn rows(table: &str) -> Vec<Vec<&str>> {
    table
        .lines()
        .skip(2)
        .map(|l| l.trim_matches('|').split('|').map(str::trim).collect())
        .collect()
}

fn number(cell: &str) -> bool {
    cell.parse::<f64>().is_ok_and(f64::is_finite)
}

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
        .env_remove("PIDM_BENCH_PASSES")
        .env("PIDM_BENCH_BUDGET", "900")
        .env("PIDM_BENCH_TIMEOUT", "600")
        .output()
        .expect("bash runs");
    let stdout = String::from_utf8_lossy(&run.stdout);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stdout}\n{stderr}");
    let read = |name: &str| std::fs::read_to_string(out.path().join(name)).unwrap();
    let runs = read("runs.log");
    let scenes = [
        "LuGre coupling 6 x 6",
        "coupling 30 x 30",
        "random 400",
        "two-frequency 8 x 8",
    ];
    // LuGre runs in f64 only: its f32 cells say so.
    let f32_cell = |row: &[&str], k: usize| row[0].starts_with("LuGre") && (k == 4 || k == 6);

    // Whole processes: instances, then the CPU, GPU f64 and GPU f32
    // seconds and both speed-ups, every one a number. The two-frequency
    // map's CPU time is its 4 x 4 sample's, scaled: "(x4)".
    let table = read("table.md");
    let whole = rows(&table);
    assert_eq!(
        whole.iter().map(|r| r[0]).collect::<Vec<_>>(),
        scenes,
        "{table}"
    );
    for row in &whole {
        for (k, cell) in row.iter().enumerate().take(7).skip(1) {
            if f32_cell(row, k) {
                assert!(cell.starts_with('-'), "{cell:?} in {row:?}");
                continue;
            }
            assert!(
                number(cell.trim_end_matches(" (x4)")),
                "{cell:?} in {row:?}\n{runs}"
            );
        }
        assert_eq!(
            row[2].ends_with(" (x4)"),
            row[0].starts_with("two-frequency"),
            "{row:?}"
        );
    }
    // Each run's integrating seconds, from its summary.
    let table = read("integrating.md");
    let inner = rows(&table);
    assert_eq!(
        inner.iter().map(|r| r[0]).collect::<Vec<_>>(),
        scenes,
        "{table}"
    );
    for row in &inner {
        let gpu = if row[0].starts_with("LuGre") { 3 } else { 4 };
        assert!(row[1..gpu].iter().all(|c| number(c)), "{row:?}\n{runs}");
    }

    // The lockstep passes: a row per count, each instance on a lane of its
    // own, one batch, and every figure there.
    let table = read("lockstep.md");
    let passes = rows(&table);
    let counts: Vec<&str> = passes.iter().map(|r| r[0]).collect();
    assert_eq!(counts, ["32", "256", "1024"], "{table}");
    for row in &passes {
        assert_eq!(row[1], row[0], "lanes: {row:?}\n{table}");
        assert!(row[2..4].iter().all(|c| number(c)), "{row:?}\n{runs}");
        assert!(row[4].parse::<u64>().is_ok_and(|p| p > 0), "{row:?}");
        assert!(number(row[5]) && number(row[7]), "{row:?}");
        assert!(
            row[6].ends_with(" %") && number(row[6].trim_end_matches(" %")),
            "{row:?}"
        );
    }

    // Every GPU run's phase table: 3 Karnopp scenes x 2 precisions, the
    // LuGre map in f64 and the 3 lockstep runs; the Karnopp runs' lanes'
    // figures.
    let phases = read("phases.txt");
    assert!(phases.contains("pidm: GPU ready in "), "{phases}");
    assert!(
        phases.matches("pidm: phase table (driver").count() >= 10,
        "{phases}"
    );
    assert!(
        phases
            .matches("warps of 32 lanes in dispatch order")
            .count()
            >= 9,
        "{phases}"
    );
    assert!(
        phases.matches("critical path of batch 0").count() >= 9,
        "{phases}"
    );
    // The LuGre run's line (36 instances and 12 baselines): its
    // dispatches, period ends measured on the device and slots.
    assert!(
        phases.contains("pidm: phase LuGre on the GPU: 48 instances, ")
            && phases.contains("period ends measured on the device"),
        "{phases}"
    );
    assert!(phases.contains("== lockstep: time per pass"), "{phases}");
    assert!(
        phases.contains("== whole processes [s], mode smoke"),
        "{phases}"
    );

    // One archive holds it all, the per-run logs only there; what is left
    // beside it fits the device's 8 files.
    let listed = Command::new("tar")
        .arg("-tzf")
        .arg(out.path().join("bench.tgz"))
        .output()
        .expect("tar runs");
    assert!(listed.status.success(), "{listed:?}");
    let listed = String::from_utf8_lossy(&listed.stdout);
    for name in [
        "./table.md",
        "./lockstep.md",
        "./phases.txt",
        "./runs.log",
        "./registers.txt",
        "./logs/random100k-f32.log",
        "./logs/alike1024.log",
        "./scenes/twofreq128.toml",
    ] {
        assert!(listed.lines().any(|l| l == name), "{name} not in\n{listed}");
    }
    let mut left: Vec<String> = std::fs::read_dir(out.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(
        left,
        [
            "adapter.txt",
            "bench.tgz",
            "integrating.md",
            "lockstep.md",
            "phases.txt",
            "registers.txt",
            "runs.log",
            "table.md"
        ]
    );
    // The driver's statistics: on lavapipe, a line saying it lists none,
    // beside ACO's table where RADV is unpacked.
    let registers = std::fs::read_to_string(out.path().join("registers.txt")).unwrap();
    assert!(registers.contains("driver statistics"), "{registers}");
}
