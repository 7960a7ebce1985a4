//! Sharded runs on Slurm: `sweeps/slurm/pidm-array.sbatch` as a job array
//! on a real single-node cluster that `tests/slurm/cluster.sh` starts and
//! stops, `sweeps/slurm/merge.sbatch` behind it, and `pidm merge` of the
//! array's shards, each against a single `pidm run` bit for bit; then
//! `pidm merge` refusing bad sets of those shards. (`tests/files.rs` checks
//! shards run and merged by hand, without Slurm.)
//!
//! The cluster needs root and Debian's `slurm-wlm` and `munge` packages.
//! Without them the test prints a notice and passes, except under CI (`CI`
//! set), where it fails.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use hdf5::types::{FixedAscii, FloatSize, IntSize, TypeDescriptor, VarLenUnicode};

/// A 4 x 3 grid of the two drive voltages with 1-DOF baselines: 12
/// instances of 3 periods, so every shard of 3 has several instances.
const SCENE: &str = r#"name = "small"
description = "4 x 3 voltage grid for the sharding tests"
[axis.x]
voltage = { from = -90.0, to = 120.0, steps = 4 }
[axis.y]
voltage = [-60.0, 0.0, 90.0]
[simulation]
cycles = 3
settle = 1
[output]
baselines = true
"#;

/// The same grid with x reaching 121 V instead of 120 V: another scene of
/// the same shape, whose shards must not merge with `SCENE`'s.
const OTHER_SCENE: &str = r#"name = "small"
description = "4 x 3 voltage grid for the sharding tests"
[axis.x]
voltage = { from = -90.0, to = 121.0, steps = 4 }
[axis.y]
voltage = [-60.0, 0.0, 90.0]
[simulation]
cycles = 3
settle = 1
[output]
baselines = true
"#;

const SHARDS: usize = 3;

fn pidm(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pidm"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("pidm runs")
}

fn text(out: &Output) -> String {
    format!(
        "{}\nstdout:\n{}\nstderr:\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

fn manifest(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

fn s(path: &Path) -> &str {
    path.to_str().expect("temporary paths are UTF-8")
}

/// Runs `pidm run SCENE --out OUT` (with `extra` arguments) and requires success.
fn run_scene(scene: &Path, out: &Path, extra: &[&str], dir: &Path) {
    let mut args = vec!["run", s(scene), "--out", s(out), "--backend", "cpu"];
    args.extend_from_slice(extra);
    let run = pidm(&args, dir);
    assert!(run.status.success(), "pidm {args:?}: {}", text(&run));
    assert!(out.is_file(), "pidm {args:?} wrote no {}", out.display());
}

/// Every value of a dataset or attribute, exactly: floats as their bits.
#[derive(Debug, PartialEq)]
enum Values {
    Float(Vec<u64>),
    Unsigned(Vec<u64>),
    Signed(Vec<i64>),
    Text(Vec<String>),
    /// Object references (the netCDF-4 dimension-scale attributes
    /// `DIMENSION_LIST` and `REFERENCE_LIST`) hold file addresses, which
    /// need not agree between two files of the same content: only their
    /// type and count are compared (`tests/files.rs` checks through xarray
    /// that the scales are attached).
    References(usize),
}

/// True for a type that holds object references anywhere.
fn has_references(ty: &TypeDescriptor) -> bool {
    match ty {
        TypeDescriptor::Reference(_) => true,
        TypeDescriptor::VarLenArray(inner) | TypeDescriptor::FixedArray(inner, _) => {
            has_references(inner)
        }
        TypeDescriptor::Compound(c) => c.fields.iter().any(|f| has_references(&f.ty)),
        _ => false,
    }
}

fn values(c: &hdf5::Container, what: &str) -> Values {
    let ty = c.dtype().unwrap().to_descriptor().unwrap();
    if has_references(&ty) {
        return Values::References(c.size());
    }
    match ty {
        TypeDescriptor::Float(FloatSize::U8) => Values::Float(
            ok(c.read_raw::<f64>(), what)
                .iter()
                .map(|x| x.to_bits())
                .collect(),
        ),
        TypeDescriptor::Float(FloatSize::U4) => Values::Float(
            ok(c.read_raw::<f32>(), what)
                .iter()
                .map(|x| u64::from(x.to_bits()))
                .collect(),
        ),
        TypeDescriptor::Unsigned(size) => Values::Unsigned(match size {
            IntSize::U1 => widen(ok(c.read_raw::<u8>(), what)),
            IntSize::U2 => widen(ok(c.read_raw::<u16>(), what)),
            IntSize::U4 => widen(ok(c.read_raw::<u32>(), what)),
            IntSize::U8 => ok(c.read_raw::<u64>(), what),
        }),
        TypeDescriptor::Integer(size) => Values::Signed(match size {
            IntSize::U1 => widen(ok(c.read_raw::<i8>(), what)),
            IntSize::U2 => widen(ok(c.read_raw::<i16>(), what)),
            IntSize::U4 => widen(ok(c.read_raw::<i32>(), what)),
            IntSize::U8 => ok(c.read_raw::<i64>(), what),
        }),
        TypeDescriptor::FixedAscii(_) => Values::Text(
            ok(c.read_raw::<FixedAscii<256>>(), what)
                .iter()
                .map(|v| v.as_str().to_owned())
                .collect(),
        ),
        TypeDescriptor::VarLenUnicode => Values::Text(
            ok(c.read_raw::<VarLenUnicode>(), what)
                .iter()
                .map(|v| v.as_str().to_owned())
                .collect(),
        ),
        other => panic!("{what}: unexpected type {other:?}"),
    }
}

fn ok<T>(read: hdf5::Result<T>, what: &str) -> T {
    read.unwrap_or_else(|e| panic!("{what}: {e}"))
}

fn widen<T, U: From<T>>(v: Vec<T>) -> Vec<U> {
    v.into_iter().map(U::from).collect()
}

/// Requires `got` to hold every group and dataset of `want`, and nothing
/// else, with the same types, shapes, values (bit for bit) and dataset
/// attributes (units); and the same root `scene` attribute. The root's
/// other attributes (`wall_time_s`, `backend`, ...) may differ.
fn assert_same_content(want: &Path, got: &Path) {
    let (a, b) = (
        hdf5::File::open(want).unwrap(),
        hdf5::File::open(got).unwrap(),
    );
    assert_eq!(
        scene_attr(want),
        scene_attr(got),
        "the scene attribute differs"
    );
    let mut compared = 0;
    compare_group(&a, &b, got, &mut compared);
    // /axes/x.voltage, /axes/y.voltage, six maps and three baselines at least.
    assert!(compared >= 11, "only {compared} datasets compared");
}

/// The root attribute `scene` of an HDF5 file.
fn scene_attr(path: &Path) -> String {
    let file = hdf5::File::open(path).unwrap();
    let v: VarLenUnicode = file.attr("scene").unwrap().read_scalar().unwrap();
    v.as_str().to_owned()
}

fn compare_group(a: &hdf5::Group, b: &hdf5::Group, got: &Path, compared: &mut usize) {
    let (mut names_a, mut names_b) = (a.member_names().unwrap(), b.member_names().unwrap());
    names_a.sort();
    names_b.sort();
    assert_eq!(
        names_a,
        names_b,
        "{} in {} has other members",
        a.name(),
        got.display()
    );
    for name in &names_a {
        if let Ok(group_a) = a.group(name) {
            compare_group(&group_a, &b.group(name).unwrap(), got, compared);
            continue;
        }
        let (da, db) = (a.dataset(name).unwrap(), b.dataset(name).unwrap());
        let what = da.name();
        assert_eq!(da.shape(), db.shape(), "{what}: shape");
        assert_eq!(
            da.dtype().unwrap().to_descriptor().unwrap(),
            db.dtype().unwrap().to_descriptor().unwrap(),
            "{what}: type"
        );
        assert_eq!(values(&da, &what), values(&db, &what), "{what}: values");
        let (mut attrs_a, mut attrs_b) = (da.attr_names().unwrap(), db.attr_names().unwrap());
        attrs_a.sort();
        attrs_b.sort();
        assert_eq!(attrs_a, attrs_b, "{what}: attribute names");
        for attr in &attrs_a {
            let label = format!("{what} attribute {attr}");
            let (aa, ab) = (da.attr(attr).unwrap(), db.attr(attr).unwrap());
            assert_eq!(
                aa.dtype().unwrap().to_descriptor().unwrap(),
                ab.dtype().unwrap().to_descriptor().unwrap(),
                "{label}: type"
            );
            assert_eq!(values(&aa, &label), values(&ab, &label), "{label}");
        }
        *compared += 1;
    }
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
    std::fs::write(&other_scene, OTHER_SCENE).unwrap();
    let foreign = other.join("small.shard-3-of-3.h5");
    run_scene(&other_scene, &foreign, &["--shard", "3/3"], &other);
    assert_refused(
        &[one, two, &foreign],
        "come from different scenes",
        dir,
        "foreign shard",
    );
}
