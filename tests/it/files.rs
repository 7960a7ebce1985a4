//! Result files as users meet them: opened by xarray through the netCDF-4
//! conventions, split into shards and merged, and resumed after a crash or
//! Ctrl-C. Every comparison with a single uninterrupted run is bit for bit
//! (`pidm::output::compare_contents`).

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use crate::common::{pidm, s, signal};
use pidm::output::compare_contents;

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
             [simulation]\nmeasure = \"window\"\ncycles = {cycles}\nsettle = 1\n\
             [output]\nbaselines = true\n"
        ),
    )
    .unwrap();
    path
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
    // Two trajectories with their two 1-DOF runs each: six groups, each
    // opens in xarray as its own Dataset.
    let mut text = std::fs::read_to_string(&scene).unwrap();
    text.push_str("trajectories = [0, 5]\n");
    std::fs::write(&scene, text).unwrap();
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
    assert!(
        stdout.contains("6 trajectory groups open in xarray over time"),
        "{stdout}"
    );

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
    // An entry is a 32-byte head, the records and an 8-byte sum
    // (`src/checkpoint.rs`).
    let entry = 32 + pidm::checkpoint::RECORD_BYTES as u64 * chunk + 8;
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
    names_in(dir)
        .into_iter()
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
        crate::common::signal(&child, signal);
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
        let resumed = pidm(&resume, d);
        let stderr = ok(&resumed);
        let done = resumed_done(&stderr);
        assert!(
            (2 * chunk..48).contains(&done),
            "{signal}: {done} done before resuming"
        );
        // The summary tells the file's instances from this run's work.
        let summary = String::from_utf8_lossy(&resumed.stdout);
        assert!(
            summary.contains(&format!(
                "48 instances ({done} of them from the checkpoint; "
            )),
            "{summary}"
        );
        assert!(!checkpoint.exists());
        assert!(leftovers(d).is_empty(), "{:?}", leftovers(d));
        compare_contents(&whole, &out).unwrap();
        std::fs::remove_file(&out).unwrap();
    }

    // A second run of the same output, while the first is running (here
    // held still with SIGSTOP so that it cannot finish meanwhile), is
    // refused before it touches anything, whether it resumes or not; the
    // first then finishes its file as if alone.
    let child = Command::new(env!("CARGO_BIN_EXE_pidm"))
        .args(args)
        .current_dir(d)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    wait_for_checkpoint(&checkpoint, 1, chunk);
    signal(&child, "STOP");
    let partial = d.join(".long.h5.partial");
    let journal = std::fs::read(&checkpoint).unwrap();
    let partial_len = std::fs::metadata(&partial).unwrap().len();
    let mut resume = args.to_vec();
    resume.push("--resume");
    for second in [&args[..], &resume[..]] {
        let err = failed(&pidm(second, d));
        assert!(err.contains("another pidm process is writing"), "{err}");
        assert_eq!(std::fs::read(&checkpoint).unwrap(), journal);
        assert_eq!(std::fs::metadata(&partial).unwrap().len(), partial_len);
    }
    signal(&child, "CONT");
    let ended = child.wait_with_output().unwrap();
    assert!(ended.status.success());
    compare_contents(&whole, &out).unwrap();
    std::fs::remove_file(&out).unwrap();

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

/// Every file in the folder, sorted (hidden ones included).
fn names_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn outputs_that_are_not_regular_files_or_new_paths_are_refused_untouched() {
    use std::os::unix::fs::FileTypeExt;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = grid_scene(d, "grid", "[50.0, 100.0]", 2);
    std::fs::create_dir(d.join("folder")).unwrap();
    let made = Command::new("mkfifo").arg(d.join("fifo")).status().unwrap();
    assert!(made.success());
    let victim = d.join("victim.h5");
    std::fs::write(&victim, b"not to be touched").unwrap();
    std::os::unix::fs::symlink(&victim, d.join("link.h5")).unwrap();
    // A side file that is a link must not be followed either.
    std::os::unix::fs::symlink(&victim, d.join(".side.h5.partial")).unwrap();
    let before = names_in(d);

    let check = |out: &str, expected: &str| {
        let err = failed(&pidm(
            &["run", s(&scene), "--out", out, "--backend", "cpu"],
            d,
        ));
        assert!(err.contains(expected), "--out {out}: {err}");
        assert!(!err.contains("panicked"), "--out {out}: {err}");
        assert_eq!(names_in(d), before, "--out {out} left files behind");
    };
    check("folder", "is a folder, not a regular file");
    check("fifo", "is a FIFO, not a regular file");
    check("link.h5", "is a symbolic link, not a regular file");
    check("side.h5", ".side.h5.partial is a symbolic link");
    check(
        "/dev/null",
        "/dev/null is a character device, not a regular file",
    );
    check(".", ". is not a file name");
    check("..", ".. is not a file name");
    check("/", "/ is not a file name");
    check("folder/", "folder/ is not a file name");
    check("folder/..", "folder/.. is not a file name");
    check(s(&scene), "is the scene file itself");

    assert_eq!(std::fs::read(&victim).unwrap(), b"not to be touched");
    let null = std::fs::metadata("/dev/null").unwrap();
    assert!(null.file_type().is_char_device(), "/dev/null was replaced");
    assert_eq!(leftovers(Path::new("/dev")), Vec::<String>::new());
    // An existing regular file is replaced as a whole.
    std::fs::write(d.join("old.h5"), b"an older result").unwrap();
    ok(&pidm(
        &["run", s(&scene), "--out", "old.h5", "--backend", "cpu"],
        d,
    ));
    hdf5::File::open(d.join("old.h5")).unwrap();
    assert!(!d.join(".old.h5.lock").exists());
}

/// Runs a small grid scene in `dir` as two shards, `shard-1.h5` and
/// `shard-2.h5`.
fn two_shards(dir: &Path) {
    let scene = grid_scene(dir, "grid", "[50.0, 100.0, 150.0]", 2);
    for k in 1..=2 {
        let shard = format!("{k}/2");
        let out = format!("shard-{k}.h5");
        let args = [
            "run",
            s(&scene),
            "--shard",
            &shard,
            "--out",
            &out,
            "--backend",
            "cpu",
        ];
        ok(&pidm(&args, dir));
    }
}

#[test]
fn a_merge_names_the_shard_and_dataset_that_cannot_be_right() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    two_shards(d);
    ok(&pidm(&["merge", "good.h5", "shard-1.h5", "shard-2.h5"], d));

    // Each damage is done to a copy of shard 1.
    let check = |what: &str, damage: &dyn Fn(&hdf5::File), expected: &str| {
        let copy = d.join("damaged.h5");
        std::fs::copy(d.join("shard-1.h5"), &copy).unwrap();
        damage(&hdf5::File::open_rw(&copy).unwrap());
        let err = failed(&pidm(&["merge", "bad.h5", "damaged.h5", "shard-2.h5"], d));
        assert!(err.contains("damaged.h5"), "{what}: {err}");
        assert!(err.contains(expected), "{what}: {err}");
        assert!(!err.contains("panicked"), "{what}: {err}");
        assert!(
            !err.contains("Some(") && !err.contains("None"),
            "{what}: {err}"
        );
        assert!(!d.join("bad.h5").exists(), "{what}");
        assert!(leftovers(d).is_empty(), "{what}: {:?}", leftovers(d));
    };
    let write_f64 = |name: &'static str, at: usize, value: f64| {
        move |f: &hdf5::File| {
            let ds = f.dataset(name).unwrap();
            let mut v: Vec<f64> = ds.read_raw().unwrap();
            v[at] = value;
            ds.write_raw(&v).unwrap();
        }
    };
    let write_u32 = |name: &'static str, at: usize, value: u32| {
        move |f: &hdf5::File| {
            let ds = f.dataset(name).unwrap();
            let mut v: Vec<u32> = ds.read_raw().unwrap();
            v[at] = value;
            ds.write_raw(&v).unwrap();
        }
    };
    check(
        "NaN with status 0",
        &write_f64("maps/step_x", 1, f64::NAN),
        "its step_x is NaN",
    );
    check(
        "a status that does not exist",
        &write_u32("maps/status", 0, 17),
        "its status is 17, which is no status code",
    );
    let write_u8 = |name: &'static str, at: usize, value: u8| {
        move |f: &hdf5::File| {
            let ds = f.dataset(name).unwrap();
            let mut v: Vec<u8> = ds.read_raw().unwrap();
            v[at] = value;
            ds.write_raw(&v).unwrap();
        }
    };
    check(
        "a motion that does not exist",
        &write_u8("maps/motion", 1, 9),
        "cannot be right: its motion is 9, which is no motion code (flag_values [0, 1, 2, 3, 4])",
    );
    check(
        "a failed instance with a kind of motion",
        &|f: &hdf5::File| {
            write_u32("maps/status", 0, 1)(f);
            write_u8("maps/motion", 0, 1)(f);
        },
        "its status is 1 (step budget exceeded (simulation.max_steps_per_period)) but its \
         motion is periodic, not undetermined",
    );
    check(
        "a failed instance with a step",
        &|f: &hdf5::File| {
            write_u32("maps/status", 2, 3)(f);
            write_f64("maps/step_y", 2, 1e-6)(f);
        },
        "its status is 3 (step size underflow",
    );
    check(
        "a shortened map",
        &|f: &hdf5::File| {
            let maps = f.group("maps").unwrap();
            maps.unlink("step_y").unwrap();
            maps.new_dataset_builder()
                .with_data(&[0.0f64; 2])
                .create("step_y")
                .unwrap();
        },
        "`maps/step_y` has shape [2]",
    );
    check(
        "a missing map",
        &|f: &hdf5::File| f.group("baseline").unwrap().unlink("status").unwrap(),
        "`baseline/status` is missing",
    );
    check(
        "a missing instance list",
        &|f: &hdf5::File| f.unlink("shard/instance").unwrap(),
        "`shard/instance` is missing",
    );
    // The output may not be one of the shards it reads.
    let err = failed(&pidm(
        &["merge", "shard-1.h5", "shard-1.h5", "shard-2.h5"],
        d,
    ));
    assert!(err.contains("is also given as the shard"), "{err}");
    hdf5::File::open(d.join("shard-1.h5"))
        .unwrap()
        .dataset("shard/instance")
        .unwrap();
}

#[test]
fn ctrl_c_stops_a_long_instance_at_once_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // One instance of ten million cycles: hours of integration.
    let scene = d.join("endless.toml");
    std::fs::write(
        &scene,
        "name = \"endless\"\n[axis.x]\nvoltage = 100.0\n[simulation]\nmeasure = \"window\"\ncycles = 10000000\n",
    )
    .unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_pidm"))
        .args(["run", s(&scene), "--out", "endless.h5", "--backend", "cpu"])
        .current_dir(d)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    wait_for_checkpoint(&d.join(".endless.h5.checkpoint"), 0, 1);
    std::thread::sleep(Duration::from_millis(300));
    let asked = Instant::now();
    signal(&child, "INT");
    let ended = child.wait_with_output().unwrap();
    let waited = asked.elapsed();
    let err = String::from_utf8_lossy(&ended.stderr);
    assert!(!ended.status.success(), "{err}");
    assert!(err.contains("interrupted after 0 of 1 instances"), "{err}");
    // The integrator looks at the stop request every 2^14 iterations
    // (about a millisecond); five seconds leaves room for a loaded machine.
    assert!(waited < Duration::from_secs(5), "took {waited:?} to stop");
    assert!(!d.join("endless.h5").exists());
    assert!(leftovers(d).is_empty(), "{:?}", leftovers(d));
}

/// One structural damage to a shard file.
#[derive(Clone, Debug)]
enum ShardDamage {
    /// Remove the dataset.
    Delete(usize),
    /// Replace the dataset with one of another length.
    Resize(usize, usize),
    /// Write a value at a position (taken modulo the length).
    Set(usize, usize, f64),
}

/// The datasets a merge reads from a shard with baselines.
fn shard_datasets() -> Vec<String> {
    use pidm::output::schema;
    let in_group = |group: &str, d: &schema::MapDataset| format!("{group}/{}", d.name);
    let maps = schema::MAP_DATASETS
        .iter()
        .map(|d| in_group(schema::MAPS, d));
    let baselines = schema::BASELINE_DATASETS
        .iter()
        .map(|d| in_group(schema::BASELINE, d));
    maps.chain(baselines)
        .chain([schema::SHARD_INSTANCE.to_string()])
        .collect()
}

fn apply(file: &hdf5::File, damage: &ShardDamage) {
    let k = match damage {
        ShardDamage::Delete(k) | ShardDamage::Resize(k, _) | ShardDamage::Set(k, ..) => *k,
    };
    let names = shard_datasets();
    let (group, leaf) = names[k % names.len()].split_once('/').unwrap();
    let Ok(group) = file.group(group) else { return };
    let Ok(ds) = group.dataset(leaf) else { return };
    let is_float = ds.dtype().unwrap().is::<f64>();
    match *damage {
        ShardDamage::Delete(_) => group.unlink(leaf).unwrap(),
        ShardDamage::Resize(_, len) => {
            group.unlink(leaf).unwrap();
            let builder = group.new_dataset_builder();
            if is_float {
                builder.with_data(&vec![0.5f64; len]).create(leaf).unwrap();
            } else {
                builder.with_data(&vec![1u32; len]).create(leaf).unwrap();
            }
        }
        ShardDamage::Set(_, at, value) => {
            if is_float {
                let mut v: Vec<f64> = ds.read_raw().unwrap();
                if !v.is_empty() {
                    let at = at % v.len();
                    v[at] = value;
                    ds.write_raw(&v).unwrap();
                }
            } else if let Ok(mut v) = ds.read_raw::<u32>()
                && !v.is_empty()
            {
                let at = at % v.len();
                v[at] = value.abs().min(u32::MAX as f64) as u32;
                ds.write_raw(&v).unwrap();
            }
        }
    }
}

fn shard_damage() -> impl proptest::strategy::Strategy<Value = Vec<ShardDamage>> {
    use proptest::prelude::*;
    let value = prop_oneof![
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(-0.0),
        Just(1e300),
        Just(6.0),
        any::<f64>(),
    ];
    let one = prop_oneof![
        (0..15usize).prop_map(ShardDamage::Delete),
        (0..15usize, 0..12usize).prop_map(|(k, n)| ShardDamage::Resize(k, n)),
        (0..15usize, any::<usize>(), value).prop_map(|(k, at, v)| ShardDamage::Set(k, at, v)),
    ];
    proptest::collection::vec(one, 1..4)
}

/// Whatever is done to a shard's datasets, a merge gives an error or a
/// file, never a panic; and when it gives a file, every value in it is one
/// a run could have written.
#[test]
fn a_merge_of_damaged_shards_gives_an_error_or_a_plausible_file() {
    use proptest::test_runner::{Config, TestRunner};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    two_shards(d);
    let mut runner = TestRunner::new(Config {
        cases: 48,
        failure_persistence: None,
        ..Config::default()
    });
    let merged_files = std::cell::Cell::new(0);
    // A fresh name per case: a child that another test spawns while a case
    // holds a file open inherits its descriptor, and with it the file's
    // HDF5 lock, for as long as the child runs; a new file is not locked.
    let case = std::cell::Cell::new(0);
    runner
        .run(&shard_damage(), |damages| {
            case.set(case.get() + 1);
            let copy = d.join(format!("damaged-{}.h5", case.get()));
            std::fs::copy(d.join("shard-1.h5"), &copy).unwrap();
            {
                let file = hdf5::File::open_rw(&copy).unwrap();
                for damage in &damages {
                    apply(&file, damage);
                }
            }
            let out = d.join(format!("merged-{}.h5", case.get()));
            let merged = pidm::run::shard::merge(&out, &[copy, d.join("shard-2.h5")]);
            if merged.is_ok() {
                merged_files.set(merged_files.get() + 1);
                let file = hdf5::File::open(&out).unwrap();
                let status: Vec<u32> = file.dataset("maps/status").unwrap().read_raw().unwrap();
                let step: Vec<f64> = file.dataset("maps/step_x").unwrap().read_raw().unwrap();
                let motion: Vec<u8> = file.dataset("maps/motion").unwrap().read_raw().unwrap();
                for ((s, x), m) in status.iter().zip(&step).zip(&motion) {
                    proptest::prop_assert!(
                        pidm::measurement::status::Status::from_code(*s).is_some()
                    );
                    proptest::prop_assert!(x.is_finite());
                    proptest::prop_assert!(pidm::model::motion::Motion::from_code(*m).is_some());
                    proptest::prop_assert!(*s == 0 || *m == 0);
                }
            } else {
                proptest::prop_assert!(!out.exists());
            }
            Ok(())
        })
        .unwrap();
    eprintln!("{} of 48 damaged shards still merged", merged_files.get());
}
