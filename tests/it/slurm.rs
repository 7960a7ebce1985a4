//! Sharded runs on Slurm: `sweeps/slurm/pidm-array.sbatch` as a job array
//! on a real single-node cluster that `tests/slurm/cluster.sh` starts and
//! stops, `sweeps/slurm/merge.sbatch` behind it, and `pidm merge` of the
//! array's shards, each against a single `pidm run` bit for bit; then
//! `pidm merge` refusing bad sets of those shards. (`tests/it/files.rs` checks
//! shards run and merged by hand, without Slurm.)
//!
//! The cluster needs root and Debian's `slurm-wlm` and `munge` packages.
//! Without them the test prints a notice and passes, except under CI (`CI`
//! set), where it fails.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::common::{manifest, pidm, s};
use pidm::output::compare_contents;

/// A 4 x 3 grid of the two drive voltages with 1-DOF baselines: 12
/// instances of 3 periods, so every shard of 3 has several instances.
const SCENE: &str = r#"name = "small"
description = "4 x 3 voltage grid for the sharding tests"
[axis.x]
voltage = { from = -90.0, to = 120.0, steps = 4 }
[axis.y]
voltage = [-60.0, 0.0, 90.0]
[simulation]
measure = "window"
cycles = 3
settle = 1
[output]
baselines = true
"#;

const SHARDS: usize = 3;

fn text(out: &Output) -> String {
    format!(
        "{}\nstdout:\n{}\nstderr:\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// Runs `pidm run SCENE --out OUT` (with `extra` arguments) and requires success.
fn run_scene(scene: &Path, out: &Path, extra: &[&str], dir: &Path) {
    let mut args = vec!["run", s(scene), "--out", s(out), "--backend", "cpu"];
    args.extend_from_slice(extra);
    let run = pidm(&args, dir);
    assert!(run.status.success(), "pidm {args:?}: {}", text(&run));
    assert!(out.is_file(), "pidm {args:?} wrote no {}", out.display());
}

/// Requires `got` to hold the same contents as `want`, bit for bit
/// (`pidm::output::compare_contents`: every group, dataset and dataset
/// attribute, and the root `scene` attribute).
fn assert_same_content(want: &Path, got: &Path) {
    let compared = compare_contents(want, got)
        .unwrap_or_else(|e| panic!("{} against {}: {e:#}", got.display(), want.display()));
    // /axes/x.voltage, /axes/y.voltage, six maps and three baselines at least.
    assert!(compared >= 11, "only {compared} datasets compared");
}

/// Runs `pidm merge OUT SHARDS...`.
fn merge(out: &Path, shards: &[&Path], dir: &Path) -> Output {
    let mut args = vec!["merge", s(out)];
    args.extend(shards.iter().map(|p| s(p)));
    pidm(&args, dir)
}

/// Requires `pidm merge` of `shards` to fail, write nothing and say
/// `expected` on stderr.
fn assert_refused(shards: &[&Path], expected: &str, dir: &Path, case: &str) {
    let out = dir.join(format!("refused-{}.h5", case.replace(' ', "-")));
    let merged = merge(&out, shards, dir);
    assert!(!merged.status.success(), "{case}: merge succeeded");
    assert!(
        String::from_utf8_lossy(&merged.stderr).contains(expected),
        "{case}: the message does not say {expected:?}: {}",
        text(&merged)
    );
    assert!(
        !out.exists(),
        "{case}: a refused merge wrote {}",
        out.display()
    );
}

/// The path of `tool` on PATH or in the sbin folders (root's PATH has
/// them, a user's may not).
fn find_tool(tool: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .chain(["/usr/sbin", "/sbin"].map(PathBuf::from))
        .map(|dir| dir.join(tool))
        .find(|p| p.is_file())
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|out| String::from_utf8_lossy(&out.stdout).trim() == "0")
}

/// What the cluster runs: the job array with `sbatch --wait`, then the
/// merge job behind it with `--dependency=afterok`.
const SLURM_SCRIPT: &str = r#"set -euo pipefail
jobid=$(sbatch --parsable --wait --array=1-$SHARDS "$ARRAY_SBATCH" small.toml shards)
echo "job array $jobid finished"
sbatch --wait --dependency=afterok:$jobid "$MERGE_SBATCH" slurm-merged.h5 shards
"#;

#[test]
fn a_slurm_job_array_of_shards_merges_into_a_single_run_bit_for_bit_and_bad_sets_are_refused() {
    let missing: Vec<&str> = ["sbatch", "sinfo", "slurmctld", "slurmd", "munged"]
        .into_iter()
        .filter(|t| find_tool(t).is_none())
        .collect();
    if !missing.is_empty() || !is_root() {
        let notice = if missing.is_empty() {
            "slurm: the single-node test cluster needs root".to_owned()
        } else {
            format!(
                "slurm: {} not found (apt-get install -y --no-install-recommends slurm-wlm munge)",
                missing.join(", ")
            )
        };
        if std::env::var_os("CI").is_some() {
            panic!("{notice}; under CI this test must run");
        }
        eprintln!("{notice}; skipping the Slurm job-array test");
        return;
    }

    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    let scene = dir.join("small.toml");
    std::fs::write(&scene, SCENE).unwrap();
    let started = std::time::Instant::now();
    let cluster = Command::new("timeout")
        .arg("300")
        .arg(manifest("tests/slurm/cluster.sh"))
        .args(["run", "--", "bash", "-c", SLURM_SCRIPT])
        .env("SHARDS", SHARDS.to_string())
        .env("ARRAY_SBATCH", manifest("sweeps/slurm/pidm-array.sbatch"))
        .env("MERGE_SBATCH", manifest("sweeps/slurm/merge.sbatch"))
        .env("PIDM_BIN", env!("CARGO_BIN_EXE_pidm"))
        // The sbin folders hold the daemons.
        .env(
            "PATH",
            format!(
                "{}:/usr/sbin:/sbin",
                std::env::var("PATH").unwrap_or_default()
            ),
        )
        .current_dir(dir)
        .output()
        .expect("tests/slurm/cluster.sh runs");
    // Every job's log, for the failure message.
    let mut logs = String::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "out") {
            let body = std::fs::read_to_string(&path).unwrap_or_default();
            logs += &format!("---- {}\n{body}", path.display());
        }
    }
    assert!(
        cluster.status.success(),
        "the Slurm jobs failed: {}\n{logs}",
        text(&cluster)
    );
    eprintln!(
        "slurm: array of {SHARDS} shards and merge job done in {:.1} s",
        started.elapsed().as_secs_f64()
    );

    // One log per task and one for the merge job, each shard file written.
    assert_eq!(logs.matches("---- ").count(), SHARDS + 1, "{logs}");
    let shards: Vec<PathBuf> = (1..=SHARDS)
        .map(|k| dir.join(format!("shards/small.shard-{k}-of-{SHARDS}.h5")))
        .collect();
    for shard in &shards {
        assert!(shard.is_file(), "no {}: {logs}", shard.display());
    }

    let merged = dir.join("merged.h5");
    let refs: Vec<&Path> = shards.iter().map(PathBuf::as_path).collect();
    let run = merge(&merged, &refs, dir);
    assert!(run.status.success(), "{}", text(&run));
    let single = dir.join("single.h5");
    run_scene(&scene, &single, &[], dir);
    assert_same_content(&single, &merged);
    assert_same_content(&single, &dir.join("slurm-merged.h5"));
    // The shard files are HDF5 files of the same scene.
    let scene_attr = |path: &Path| -> String {
        let file = hdf5::File::open(path).unwrap();
        let v: hdf5::types::VarLenUnicode = file.attr("scene").unwrap().read_scalar().unwrap();
        v.as_str().to_owned()
    };
    for shard in &shards {
        assert_eq!(
            scene_attr(shard),
            scene_attr(&single),
            "{}",
            shard.display()
        );
    }

    // Refusals, each naming the problem and writing nothing.
    let (one, two, three) = (&*shards[0], &*shards[1], &*shards[2]);
    assert_refused(&[one, three], "missing shard 2/3", dir, "missing shard");
    // The same shard twice, under another name.
    let copy = dir.join("copy-of-shard-2.h5");
    std::fs::copy(two, &copy).unwrap();
    assert_refused(
        &[one, two, &copy, three],
        "are both shard 2/3: they overlap",
        dir,
        "duplicated shard",
    );
    // A shard of the same scene split another way.
    let halves = dir.join("small.shard-1-of-2.h5");
    run_scene(&scene, &halves, &["--shard", "1/2"], dir);
    assert_refused(
        &[one, two, three, &halves],
        "the shards overlap",
        dir,
        "split two ways",
    );
    // A shard of another scene in place of shard 3.
    let other = dir.join("other");
    std::fs::create_dir(&other).unwrap();
    let other_scene = other.join("small.toml");
    // The same grid with x reaching 121 V instead of 120 V: another scene
    // of the same shape, whose shards must not merge with `SCENE`'s.
    std::fs::write(&other_scene, SCENE.replace("to = 120.0", "to = 121.0")).unwrap();
    let foreign = other.join("small.shard-3-of-3.h5");
    run_scene(&other_scene, &foreign, &["--shard", "3/3"], &other);
    assert_refused(
        &[one, two, &foreign],
        "come from different scenes",
        dir,
        "foreign shard",
    );
}
