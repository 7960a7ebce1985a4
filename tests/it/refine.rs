//! Adaptive regime maps (`[refine]`, issue 22): the waves on synthetic maps
//! (a straight boundary, an island, the audit finding a planted island),
//! and refined runs of the binary against uniform runs of the finest grid
//! (integrated points bit for bit, labels of the raster), resumed in the
//! middle of a level, refused with shards.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use pidm::output::{compare_contents, schema};
use pidm::refine::grid::{Cell, FineGrid, Point};
use pidm::refine::rule::{self, Sample};
use pidm::refine::waves::{self, INFERRED, Options, Refinement};

use crate::common::{pidm, s};

fn ok(out: &Output) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "pidm failed: {stderr}");
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Runs the waves on a synthetic map `f` of the finest grid point.
fn refine_map(grid: FineGrid, opts: &Options, f: &dyn Fn(Point) -> Sample) -> Refinement {
    let mut integrate = |indices: &[u64]| -> anyhow::Result<Vec<Sample>> {
        Ok(indices.iter().map(|&k| f(grid.point(k as usize))).collect())
    };
    waves::refine(grid, opts, vec![None; grid.len()], &mut integrate).unwrap()
}

/// The value the raster holds at every point: the sample where integrated,
/// the bilinear interpolant of the smallest leaf holding it elsewhere.
fn raster(r: &Refinement) -> Vec<Sample> {
    let grid = r.grid;
    let mut out = vec![None; grid.len()];
    let mut leaves = r.leaves.clone();
    leaves.sort_by_key(|c| std::cmp::Reverse(c.size));
    for leaf in &leaves {
        let corners = leaf
            .corners()
            .map(|p| r.samples[grid.index(p)].expect("leaf corners are integrated"));
        for p in leaf.points() {
            let (u, v) = leaf.local(p);
            out[grid.index(p)] = Some(Sample::bilinear(&corners, u, v));
        }
    }
    for (k, s) in r.samples.iter().enumerate() {
        if s.is_some() {
            out[k] = *s;
        }
    }
    out.into_iter()
        .map(|s| s.expect("every point is integrated or in a leaf"))
        .collect()
}

fn step_map(x: f64, y: f64) -> Sample {
    Sample {
        step: [x, y],
        baseline: [0.0; 2],
        ok: true,
    }
}

const TOL: f64 = 2e-8;

#[test]
fn a_straight_boundary_is_followed_to_the_finest_level_and_the_plains_are_inferred() {
    // 5 x 5 coarse, 3 levels: 33 x 33. step_x changes sign between i = 13
    // and 14 (a kink: |.| grows linearly on both sides, with another
    // slope); step_y is a smooth plane.
    let grid = FineGrid::new([5, 5], 3);
    let f = |(i, j): Point| {
        let d = i as f64 - 13.5;
        let x = if d < 0.0 { 3e-8 * d } else { 1e-7 * d };
        step_map(x, 1e-7 + 2e-9 * j as f64)
    };
    let opts = Options::standard(TOL, false);
    let r = refine_map(grid, &opts, &f);
    let got = raster(&r);
    let integrated = r.level_of.iter().filter(|&&l| l != INFERRED).count();
    assert!(
        integrated < grid.len() / 2,
        "{integrated} of {} integrated",
        grid.len()
    );
    for (k, s) in got.iter().enumerate() {
        let want = f(grid.point(k));
        assert_eq!(
            rule::label(s, TOL, None),
            rule::label(&want, TOL, None),
            "label at {:?}",
            grid.point(k)
        );
        for a in 0..2 {
            assert!(
                rule::within(s.step[a], want.step[a], TOL),
                "{:?}: {} against {}",
                grid.point(k),
                s.step[a],
                want.step[a]
            );
        }
    }
    // Along the whole boundary the cells are refined beyond the coarse
    // ones: every column has points integrated at level 2 or later beside
    // it.
    for j in 0..grid.n[1] {
        assert!(
            (12..=15).any(|i| (2..=3).contains(&r.level_of[grid.index((i, j))])),
            "column {j}"
        );
    }
    // Far from it, the plains are inferred.
    assert_eq!(r.level_of[grid.index((29, 17))], INFERRED);
    assert!(
        r.stats[1..3].iter().all(|st| st.flagged > 0),
        "{:?}",
        r.stats
    );
}

#[test]
fn an_island_that_a_probe_sees_is_refined() {
    // A round island of forward motion around a coarse cell's centre in a
    // plain of backward motion.
    let grid = FineGrid::new([5, 5], 3);
    let centre = (12.0, 20.0);
    let f = |(i, j): Point| {
        let r = ((i as f64 - centre.0).powi(2) + (j as f64 - centre.1).powi(2)).sqrt();
        step_map(if r < 3.0 { 5e-7 } else { -2e-7 }, 0.0)
    };
    let r = refine_map(grid, &Options::standard(TOL, false), &f);
    let got = raster(&r);
    let mismatches = (0..grid.len())
        .filter(|&k| rule::label(&got[k], TOL, None) != rule::label(&f(grid.point(k)), TOL, None))
        .count();
    // The island has 25 points; the raster gets (nearly) all of them.
    let island = (0..grid.len())
        .filter(|&k| f(grid.point(k)).step[0] > 0.0)
        .count();
    assert_eq!(island, 25);
    assert!(mismatches <= 2, "{mismatches} labels differ");
    assert_ne!(r.level_of[grid.index((12, 20))], INFERRED);
}

#[test]
fn the_audit_finds_an_island_the_probes_miss() {
    // A one-point island at the audit point of a coarse cell, where no
    // corner or probe looks: only the audit sees it.
    let grid = FineGrid::new([5, 5], 3);
    let audited = Options {
        audit_fraction: 1.0,
        ..Options::standard(TOL, false)
    };
    let cell = Cell {
        i: 8,
        j: 16,
        size: 8,
    };
    let p = waves::audit_point(&cell, 1, &audited).expect("every cell is audited");
    assert_ne!(p, cell.centre());
    assert!(
        p.0 != cell.i + 4 && p.1 != cell.j + 4,
        "off the midlines: {p:?}"
    );
    let f = |q: Point| step_map(if q == p { 1e-6 } else { 2e-7 }, 0.0);

    let r = refine_map(grid, &audited, &f);
    assert_eq!(r.stats[1].audit_finds, 1, "{:?}", r.stats);
    assert_eq!(r.level_of[grid.index(p)], 1);
    assert_eq!(raster(&r)[grid.index(p)].step[0], 1e-6);

    // Without the audit the island is lost: the failure mode
    // docs/adaptive.md names.
    let blind = Options {
        audit_fraction: 0.0,
        ..audited
    };
    let r = refine_map(grid, &blind, &f);
    assert_eq!(r.level_of[grid.index(p)], INFERRED);
    assert!((raster(&r)[grid.index(p)].step[0] - 2e-7).abs() < 1e-20);
    assert_eq!(
        r.level_of.iter().filter(|&&l| l != INFERRED).count(),
        25 + 16,
        "the coarse grid and the level-1 probes"
    );
}

#[test]
fn a_failed_corner_refines_its_cells_and_known_points_are_not_integrated_again() {
    let grid = FineGrid::new([3, 3], 2);
    let f = |(i, j): Point| Sample {
        ok: (i, j) != (4, 4),
        ..step_map(1e-7, 1e-7)
    };
    let opts = Options::standard(TOL, false);
    let r = refine_map(grid, &opts, &f);
    // Every cell that touches the failed point is refined to the finest
    // level: the points within two steps of it are all integrated.
    for i in 2..=6 {
        for j in 2..=6 {
            assert_ne!(r.level_of[grid.index((i, j))], INFERRED, "({i}, {j})");
        }
    }
    let integrated = r.level_of.iter().filter(|&&l| l != INFERRED).count();

    // Resuming: points already known are not handed to the integration
    // again, and the waves come out the same.
    let mut known = vec![None; grid.len()];
    for k in [0usize, 4, 20, 24, 40] {
        known[k] = Some(f(grid.point(k)));
    }
    let mut asked = Vec::new();
    let mut integrate = |indices: &[u64]| -> anyhow::Result<Vec<Sample>> {
        asked.extend_from_slice(indices);
        Ok(indices.iter().map(|&k| f(grid.point(k as usize))).collect())
    };
    let again = waves::refine(grid, &opts, known, &mut integrate).unwrap();
    assert_eq!(again.level_of, r.level_of);
    assert_eq!(again.stats, r.stats);
    assert_eq!(asked.len(), integrated - 5);
    assert!(![0u64, 4, 20, 24, 40].iter().any(|k| asked.contains(k)));
}

/// A V_x by V_y scene, 5 x 5 coarse refined `levels` times, measured in a
/// short window (`[refine]` left out when `levels` is 0: a uniform run of
/// the finest grid then needs `steps` of it).
fn scene(dir: &Path, name: &str, steps: usize, levels: u32, cycles: u32) -> PathBuf {
    let path = dir.join(format!("{name}.toml"));
    let refine = if levels > 0 {
        format!("[refine]\nlevels = {levels}\n")
    } else {
        String::new()
    };
    std::fs::write(
        &path,
        format!(
            "name = \"{name}\"\n\
             [axis.x]\nvoltage = {{ from = -150.0, to = 150.0, steps = {steps} }}\n\
             [axis.y]\nvoltage = {{ from = -150.0, to = 150.0, steps = {steps} }}\n\
             [simulation]\nmeasure = \"window\"\ncycles = {cycles}\nsettle = 1\n\
             [output]\nbaselines = true\n{refine}"
        ),
    )
    .unwrap();
    path
}

fn read<T: hdf5::H5Type>(path: &Path, name: &str) -> Vec<T> {
    hdf5::File::open(path)
        .unwrap()
        .dataset(name)
        .unwrap_or_else(|e| panic!("{}: /{name}: {e}", path.display()))
        .read_raw()
        .unwrap()
}

#[test]
fn integrated_points_equal_the_uniform_run_bit_for_bit_and_the_labels_a_dense_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let refined = d.join("refined.h5");
    let uniform = d.join("uniform.h5");
    let summary = ok(&pidm(
        &[
            "run",
            s(&scene(d, "refined", 9, 3, 4)),
            "--out",
            s(&refined),
            "--backend",
            "cpu",
        ],
        d,
    ));
    assert!(summary.contains("refined map: "), "{summary}");
    assert!(summary.contains("level 3: "), "{summary}");
    ok(&pidm(
        &[
            "run",
            s(&scene(d, "uniform", 65, 0, 4)),
            "--out",
            s(&uniform),
            "--backend",
            "cpu",
        ],
        d,
    ));
    let n = 65 * 65;
    let inferred: Vec<u8> = read(&refined, schema::INFERRED);
    let index: Vec<u64> = read(&refined, schema::REFINE_INDEX);
    let level: Vec<u8> = read(&refined, schema::REFINE_LEVEL);
    assert_eq!(inferred.len(), n);
    assert_eq!(index.len(), level.len());
    assert_eq!(
        index,
        (0..n as u64)
            .filter(|&k| inferred[k as usize] == 0)
            .collect::<Vec<_>>()
    );
    assert!(level.iter().all(|&l| l <= 3));
    let per_level: Vec<u64> = read(&refined, schema::REFINE_LEVEL_INTEGRATED);
    assert_eq!(per_level.iter().sum::<u64>(), index.len() as u64);
    assert_eq!(per_level[0], 81);
    assert!(
        index.len() < n * 3 / 4,
        "{} of {n} points integrated",
        index.len()
    );

    let mut mismatched = 0;
    let mut outside = 0;
    for map in [
        "maps/step_x",
        "maps/step_y",
        "maps/velocity_x",
        "maps/step_x_se",
        "baseline/step_x",
    ] {
        let (a, b): (Vec<f64>, Vec<f64>) = (read(&refined, map), read(&uniform, map));
        for &k in &index {
            assert_eq!(
                a[k as usize].to_bits(),
                b[k as usize].to_bits(),
                "{map} at {k}"
            );
        }
    }
    for map in ["maps/status", "maps/steps", "maps/periods"] {
        let (a, b): (Vec<u32>, Vec<u32>) = (read(&refined, map), read(&uniform, map));
        for &k in &index {
            assert_eq!(a[k as usize], b[k as usize], "{map} at {k}");
        }
    }
    // The 1-DOF baselines depend on one voltage each, so the inferred
    // points' are few and integrated: every point's equals the uniform
    // run's, bit for bit.
    let exact: u64 = hdf5::File::open(&refined)
        .unwrap()
        .group("refine")
        .unwrap()
        .attr(schema::REFINE_EXACT_BASELINES)
        .unwrap()
        .read_scalar()
        .unwrap();
    assert_eq!(exact, 1);
    for map in ["baseline/step_x", "baseline/step_y"] {
        let (a, b): (Vec<f64>, Vec<f64>) = (read(&refined, map), read(&uniform, map));
        for k in 0..n {
            assert_eq!(a[k].to_bits(), b[k].to_bits(), "{map} at {k}");
        }
    }
    let (a, b): (Vec<u32>, Vec<u32>) = (
        read(&refined, "baseline/status"),
        read(&uniform, "baseline/status"),
    );
    assert_eq!(a, b);
    let steps = |path: &Path| -> Vec<[f64; 2]> {
        let (x, y): (Vec<f64>, Vec<f64>) = (read(path, "maps/step_x"), read(path, "maps/step_y"));
        x.into_iter().zip(y).map(|(x, y)| [x, y]).collect()
    };
    let (a, b) = (steps(&refined), steps(&uniform));
    for k in 0..n {
        let (sa, sb) = (step_map(a[k][0], a[k][1]), step_map(b[k][0], b[k][1]));
        mismatched += (rule::label(&sa, TOL, None) != rule::label(&sb, TOL, None)) as usize;
        outside += (0..2)
            .filter(|&x| !rule::within(a[k][x], b[k][x], TOL))
            .count();
    }
    // The raster's labels against the dense run: at most 1 % differ, and
    // at least 98 % of the step values lie within 0.02 um + 1 %.
    assert!(mismatched * 100 <= n, "{mismatched} of {n} labels differ");
    assert!(outside * 50 <= 2 * n, "{outside} of {} values off", 2 * n);
}

#[test]
fn a_refined_run_resumes_in_the_middle_of_a_level_to_the_uninterrupted_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Long instances (200 periods), one thread and chunks of 4, so a run
    // can be stopped after the coarse grid, inside level 1 or later.
    let path = scene(d, "long", 5, 2, 200);
    let whole = d.join("whole.h5");
    ok(&pidm(
        &["run", s(&path), "--out", s(&whole), "--backend", "cpu"],
        d,
    ));
    let integrated = read::<u64>(&whole, schema::REFINE_INDEX).len();
    let out = d.join("long.h5");
    let checkpoint = d.join(".long.h5.checkpoint");
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
    // The coarse grid is 25 isolated points: 25 journal entries of one
    // record (32-byte head, the record, 8-byte sum); two more chunks of
    // level 1 beyond them.
    let entry = (32 + pidm::checkpoint::RECORD_BYTES + 8) as u64;
    for signal in ["INT", "KILL"] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_pidm"))
            .args(args)
            .current_dir(d)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let deadline = Instant::now() + Duration::from_secs(120);
        let mut header = None;
        loop {
            assert!(Instant::now() < deadline, "no checkpoint progress");
            // Created empty, then its header written in one write.
            if let Ok(meta) = std::fs::metadata(&checkpoint)
                && meta.len() > 0
            {
                let header = *header.get_or_insert(meta.len());
                if meta.len() >= header + (25 + 8) * entry {
                    break;
                }
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(
            child.try_wait().unwrap().is_none(),
            "the run ended too soon"
        );
        crate::common::signal(&child, signal);
        let ended = child.wait_with_output().unwrap();
        assert!(!ended.status.success(), "{signal}: the run was not stopped");
        assert!(!out.exists());
        assert!(checkpoint.exists());

        let mut resume = args.to_vec();
        resume.push("--resume");
        let resumed = pidm(&resume, d);
        ok(&resumed);
        let stderr = String::from_utf8_lossy(&resumed.stderr);
        let line = stderr
            .lines()
            .find(|l| l.contains("resuming from"))
            .unwrap_or_else(|| panic!("no resume line in {stderr}"));
        let done: usize = line
            .split(": ")
            .nth(2)
            .unwrap()
            .split(' ')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        assert!(
            (26..integrated).contains(&done),
            "{signal}: {done} of {integrated} done before resuming (in level 1 or later)"
        );
        assert!(!checkpoint.exists());
        compare_contents(&whole, &out).unwrap();
        std::fs::remove_file(&out).unwrap();
    }
}

#[test]
fn shards_are_refused_with_refine() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let path = scene(d, "sharded", 5, 1, 3);
    let out = pidm(&["run", s(&path), "--shard", "1/2", "--backend", "cpu"], d);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--shard") && err.contains("[refine]"), "{err}");
    assert!(
        !d.join("results").exists() || std::fs::read_dir(d.join("results")).unwrap().count() == 0
    );
}

/// A refined steady map writes `/maps/motion` like a uniform one: the
/// integrated points keep the kind their measurement found, an inferred
/// point (whose values are interpolated) is undetermined, and the run
/// summary counts the integrated points' kinds.
#[test]
fn a_refined_steady_map_has_kinds_only_where_it_integrated() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let path = d.join("kinds.toml");
    // 10 Hz against 20 Hz: every integrated point repeats (lag 1).
    std::fs::write(
        &path,
        "name = \"kinds\"\n\
         [axis.x]\nvoltage = { from = 80.0, to = 150.0, steps = 5 }\nfrequency = 10.0\n\
         [axis.y]\nvoltage = { from = 80.0, to = 150.0, steps = 5 }\nfrequency = 20.0\n\
         [simulation]\nstep_tolerance = 3e-8\nmax_cycles = 2000\n\
         [refine]\nlevels = 2\n",
    )
    .unwrap();
    let out = d.join("kinds.h5");
    let summary = ok(&pidm(
        &["run", s(&path), "--out", s(&out), "--backend", "cpu"],
        d,
    ));
    let inferred: Vec<u8> = read(&out, schema::INFERRED);
    let motion: Vec<u8> = read(&out, schema::MOTION);
    assert_eq!(motion.len(), 17 * 17);
    let integrated = inferred.iter().filter(|&&m| m == 0).count();
    assert!(
        integrated < motion.len(),
        "nothing inferred: the test needs plains"
    );
    let periodic = pidm::model::motion::Motion::Periodic.code();
    for (k, (&m, &i)) in motion.iter().zip(&inferred).enumerate() {
        let want = if i == 1 { 0 } else { periodic };
        assert_eq!(m, want, "point {k} (inferred {i})");
    }
    assert!(
        summary.contains(&format!(
            "motion: {integrated} periodic, 0 quasi_periodic, 0 irregular, 0 undetermined"
        )),
        "{summary}"
    );
}
