//! Result files as users meet them: opened by xarray through the netCDF-4
//! conventions, split into shards and merged, and resumed after a crash or
//! Ctrl-C. Every comparison with a single uninterrupted run is bit for bit
//! (`pidm::output::compare_contents`).

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use pidm::output::compare_contents;

fn pidm(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pidm"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("pidm runs")
}

fn ok(out: &Output) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "pidm failed: {stderr}");
    stderr
}

fn failed(out: &Output) -> String {
    assert!(!out.status.success(), "pidm should have failed");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A small 3 x 4 grid of voltages with baselines, `cycles` cycles each.
fn grid_scene(dir: &Path, name: &str, x_volts: &str, cycles: u32) -> PathBuf {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(
        &path,
        format!(
            "name = \"{name}\"\n\
             [axis.x]\nvoltage = {x_volts}\n\
             [axis.y]\nvoltage = [0.0, 40.0, 80.0, 120.0]\nfrequency = 20.0\n\
             [simulation]\ncycles = {cycles}\nsettle = 1\n\
             [output]\nbaselines = true\n"
        ),
    )
    .unwrap();
    path
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn xarray_opens_a_result_with_coordinates_units_and_values() {
    let python_ok = Command::new("python3")
        .args(["-c", "import xarray, h5netcdf, h5py"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if !python_ok {
        let notice = "python3 with xarray, h5netcdf and h5py is not available \
                      (pip install -r tests/requirements.txt)";
        assert!(
            std::env::var_os("CI").is_none(),
            "{notice}; CI must install them"
        );
        eprintln!("{notice}; skipping the xarray test");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let scene = grid_scene(dir.path(), "grid", "[50.0, 100.0, 150.0]", 3);
    let out = dir.path().join("grid.h5");
    ok(&pidm(
        &["run", s(&scene), "--out", s(&out), "--backend", "cpu"],
        dir.path(),
    ));
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/netcdf/open_with_xarray.py"
    );
    let check = Command::new("python3")
        .args([script, s(&out), "axis.x.voltage=V", "axis.y.voltage=V"])
        .output()
        .expect("python3 runs");
    let stdout = String::from_utf8_lossy(&check.stdout);
    assert!(
        check.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&check.stderr)
    );
    assert!(stdout.contains("ok:"), "{stdout}");

    // The example script loads the same file and draws it.
    let example = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/plot_map.py");
    let png = dir.path().join("map.png");
    let run = Command::new("python3")
        .args([example, s(&out), "--out", s(&png)])
        .output()
        .expect("python3 runs");
    let stderr = String::from_utf8_lossy(&run.stderr);
    if stderr.contains("No module named 'matplotlib'") {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI must install matplotlib"
        );
        return;
    }
    assert!(run.status.success(), "{stderr}");
    assert!(std::fs::metadata(&png).unwrap().len() > 1000);
}

#[test]
fn shards_merge_into_the_single_run_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = grid_scene(d, "grid", "[50.0, 100.0, 150.0]", 3);
    let single = d.join("single.h5");
    ok(&pidm(
        &["run", s(&scene), "--out", s(&single), "--backend", "cpu"],
        d,
    ));
    let mut shards = Vec::new();
    for k in 1..=3 {
        let out = pidm(
            &[
                "run",
                s(&scene),
                "--shard",
                &format!("{k}/3"),
                "--backend",
                "cpu",
            ],
            d,
        );
        assert!(ok(&out).contains(&format!("shard {k}/3: 4 of the 12 instances")));
        shards.push(d.join(format!("results/grid.shard-{k}-of-3.h5")));
    }
    let merged = d.join("merged.h5");
    let mut args = vec!["merge", s(&merged)];
    args.extend(shards.iter().map(|p| s(p)));
    ok(&pidm(&args, d));
    compare_contents(&single, &merged).unwrap();

    // The paper scene records trajectories: the merge records them once,
    // identical to a single run's.
    let paper = concat!(env!("CARGO_MANIFEST_DIR"), "/sweeps/paper.toml");
    let paper_single = d.join("paper.h5");
    ok(&pidm(
        &["run", paper, "--out", s(&paper_single), "--backend", "cpu"],
        d,
    ));
    for k in 1..=2 {
        ok(&pidm(
            &[
                "run",
                paper,
                "--shard",
                &format!("{k}/2"),
                "--backend",
                "cpu",
            ],
            d,
        ));
    }
    let paper_merged = d.join("paper-merged.h5");
    ok(&pidm(
        &[
            "merge",
            s(&paper_merged),
            "results/paper.shard-1-of-2.h5",
            "results/paper.shard-2-of-2.h5",
        ],
        d,
    ));
    let compared = compare_contents(&paper_single, &paper_merged).unwrap();
    let file = hdf5::File::open(&paper_merged).unwrap();
    assert!(file.group("trajectories").is_ok());
    assert!(compared > 20, "{compared} datasets");
    // A shard alone is not a map file: comparing shows it, and plotting
    // one is refused with the way out.
    assert!(compare_contents(&single, &shards[0]).is_err());
    let err = failed(&pidm(&["plot", s(&shards[0]), "--out", "plots"], d));
    assert!(err.contains("pidm merge"), "{err}");

    // Refusals, each naming the problem.
    let other_scene = grid_scene(d, "other", "[60.0, 100.0, 150.0]", 3);
    let other = d.join("other-2.h5");
    ok(&pidm(
        &["run", s(&other_scene), "--shard", "2/3", "--out", s(&other)],
        d,
    ));
    let bad = d.join("bad.h5");
    let check = |shard_files: &[&Path], expected: &str| {
        let mut args = vec!["merge", s(&bad)];
        args.extend(shard_files.iter().map(|p| s(p)));
        let err = failed(&pidm(&args, d));
        assert!(err.contains(expected), "{shard_files:?}: {err}");
        assert!(!bad.exists());
    };
    check(&[&shards[0], &shards[1]], "missing shard 3/3");
    check(
        &[&shards[0], &shards[1], &shards[1], &shards[2]],
        "are both shard 2/3: they overlap",
    );
    check(
        &[&shards[0], &other, &shards[2]],
        "come from different scenes",
    );
    check(&[&shards[0], &single], "it is not a shard file");
}

/// Waits until the checkpoint holds at least `entries` chunk entries of
/// `chunk` records, beyond its size when first seen (the header).
fn wait_for_checkpoint(path: &Path, entries: u64, chunk: u64) {
    // An entry is a 16-byte head, 60 bytes per record and an 8-byte sum.
    let entry = 16 + 60 * chunk + 8;
    let deadline = Instant::now() + Duration::from_secs(120);
    let mut header = None;
    loop {
        assert!(
            Instant::now() < deadline,
            "no checkpoint progress at {path:?}"
        );
        if let Ok(meta) = std::fs::metadata(path) {
            let header = *header.get_or_insert(meta.len());
            if meta.len() >= header + entries * entry {
                return;
            }
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Temporary files in the folder.
fn leftovers(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("partial"))
        .collect()
}

/// How many instances the resumed run said were already done.
fn resumed_done(stderr: &str) -> u64 {
    let line = stderr
        .lines()
        .find(|l| l.contains("resuming from"))
        .unwrap_or_else(|| panic!("no resume line in {stderr}"));
    let done = line.split(": ").nth(2).unwrap();
    done.split(' ').next().unwrap().parse().unwrap()
}

#[test]
fn a_killed_or_interrupted_run_resumes_to_the_uninterrupted_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 48 instances of 60 cycles: long enough (a second or more on one
    // thread) to be stopped part-way.
    let scene = grid_scene(
        d,
        "long",
        "[50.0, 70.0, 90.0, 110.0, 130.0, 150.0, 170.0, 190.0, 210.0, 230.0, 250.0, 270.0]",
        60,
    );
    let whole = d.join("whole.h5");
    ok(&pidm(
        &["run", s(&scene), "--out", s(&whole), "--backend", "cpu"],
        d,
    ));

    let out = d.join("long.h5");
    let checkpoint = d.join(".long.h5.checkpoint");
    let chunk = 4;
    let args = [
        "run",
        s(&scene),
        "--out",
        s(&out),
        "--backend",
        "cpu",
        "--threads",
        "1",
        "--chunk-size",
        "4",
    ];
    for signal in ["KILL", "INT"] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_pidm"))
            .args(args)
            .current_dir(d)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        wait_for_checkpoint(&checkpoint, 2, chunk);
        assert!(
            child.try_wait().unwrap().is_none(),
            "the run ended too soon"
        );
        let kill = Command::new("kill")
            .args([&format!("-{signal}"), &child.id().to_string()])
            .status()
            .unwrap();
        assert!(kill.success());
        let ended = child.wait_with_output().unwrap();
        assert!(!ended.status.success(), "{signal}: the run was not stopped");
        if signal == "INT" {
            // Ctrl-C says where the work is kept and how to go on.
            let err = String::from_utf8_lossy(&ended.stderr);
            assert!(err.contains("interrupted after"), "{err}");
            assert!(err.contains("--resume"), "{err}");
        }
        // Nothing half-written: no output, and a checkpoint. Ctrl-C also
        // removes the temporary file; after SIGKILL it stays until the
        // resumed run overwrites it.
        assert!(!out.exists());
        assert!(checkpoint.exists());
        assert_eq!(
            leftovers(d).is_empty(),
            signal == "INT",
            "{:?}",
            leftovers(d)
        );

        // A plain rerun refuses to throw the finished work away.
        let err = failed(&pidm(&args, d));
        assert!(err.contains("--resume"), "{err}");

        let mut resume = args.to_vec();
        resume.push("--resume");
        let stderr = ok(&pidm(&resume, d));
        let done = resumed_done(&stderr);
        assert!(
            (2 * chunk..48).contains(&done),
            "{signal}: {done} done before resuming"
        );
        assert!(!checkpoint.exists());
        assert!(leftovers(d).is_empty(), "{:?}", leftovers(d));
        compare_contents(&whole, &out).unwrap();
        std::fs::remove_file(&out).unwrap();
    }

    // A checkpoint of another scene is refused, not mixed in.
    let mut child = Command::new(env!("CARGO_BIN_EXE_pidm"))
        .args(args)
        .current_dir(d)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    wait_for_checkpoint(&checkpoint, 1, chunk);
    child.kill().unwrap();
    child.wait().unwrap();
    grid_scene(
        d,
        "long",
        "[50.0, 70.0, 90.0, 110.0, 130.0, 150.0, 170.0, 190.0, 210.0, 230.0, 250.0, 271.0]",
        60,
    );
    let mut resume = args.to_vec();
    resume.push("--resume");
    let err = failed(&pidm(&resume, d));
    assert!(err.contains("is of a different run"), "{err}");
    assert!(!out.exists());
}
