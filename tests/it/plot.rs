//! `pidm plot` end to end on tiny scenes (a 2-D grid with baselines, a 1-D
//! grid, a points scene with a trajectory).

use std::path::Path;

use crate::common::pidm;

/// Runs pidm and fails with its stderr unless it succeeds; returns stdout.
fn ok(args: &[&str], dir: &Path) -> String {
    let out = pidm(args, dir);
    assert!(
        out.status.success(),
        "pidm {args:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Decodes a PNG and checks it is a real picture: a sensible size and many
/// colours (axes, text and data, not a blank page).
fn check_png(path: &Path) {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .unwrap();
    let mut pixels = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut pixels).unwrap();
    assert!(
        info.width >= 800 && info.height >= 600,
        "{}: {}x{}",
        path.display(),
        info.width,
        info.height
    );
    let mut colours: Vec<[u8; 3]> = pixels[..info.buffer_size()]
        .chunks(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(
        colours.len() >= 20,
        "{}: only {} colours",
        path.display(),
        colours.len()
    );
}

/// The names of the pictures in `dir`: its files but the hidden manifest.
fn pictures_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n != ".pidm-plot-manifest")
        .collect();
    names.sort();
    names
}

#[test]
fn a_grid_with_baselines_gives_step_ratio_and_regime_maps() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("tiny.toml"),
        "name = \"tiny\"\n\
         [axis.x]\nvoltage = [-100.0, 0.0, 60.0, 100.0]\n\
         [axis.y]\nvoltage = [0.0, 50.0, 100.0]\n\
         [simulation]\nmeasure = \"window\"\ncycles = 2\nsettle = 1\n\
         [output]\nbaselines = true\n",
    )
    .unwrap();
    ok(&["run", "tiny.toml", "--threads", "1"], dir.path());
    // No --out: the default folder results/plots/<file stem>/.
    let stdout = ok(&["plot", "results/tiny.h5"], dir.path());
    let out = dir.path().join("results/plots/tiny");
    let mut names = pictures_in(&out);
    names.sort();
    assert_eq!(
        names,
        [
            "ratio_x.png",
            "ratio_y.png",
            "regime_x.png",
            "regime_y.png",
            "step_x.png",
            "step_y.png"
        ]
    );
    for name in &names {
        check_png(&out.join(name));
        assert!(
            stdout.contains(&format!("wrote results/plots/tiny/{name}")),
            "{stdout}"
        );
    }
}

#[test]
fn a_points_scene_gives_bars_and_trajectory_figures() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("pts.toml"),
        "name = \"pts\"\n\
         [simulation]\nmeasure = \"window\"\ncycles = 2\nsettle = 1\n\
         [output]\nbaselines = true\ntrajectories = [\"both\", 0]\n\
         trajectory_samples_per_cycle = 200\n\
         [[points]]\nlabel = \"x only\"\naxis.x.voltage = 100.0\n\
         [[points]]\nlabel = \"both\"\naxis.y.voltage = 100.0\naxis.y.frequency = 20.0\n",
    )
    .unwrap();
    ok(&["run", "pts.toml", "--out", "pts.h5"], dir.path());
    let file = hdf5::File::open(dir.path().join("pts.h5")).unwrap();
    let slider: Vec<f64> = file
        .dataset("trajectories/0/slider_y")
        .unwrap()
        .read_raw()
        .unwrap();
    assert_eq!(slider.len(), 401);
    let base: Vec<f64> = file
        .dataset("trajectories/0/baseline_y/slider")
        .unwrap()
        .read_raw()
        .unwrap();
    // The 20 Hz baseline covers the whole run (4 of its periods), as densely
    // in time as the point.
    assert_eq!(base.len(), 401);
    let stdout = ok(&["plot", "pts.h5", "--out", "pics"], dir.path());
    for name in ["steps.png", "trajectory_both.png", "trajectory_x_only.png"] {
        let path = dir.path().join("pics").join(name);
        check_png(&path);
        assert!(stdout.contains(name), "{stdout}");
    }
}

#[test]
fn a_one_axis_grid_gives_line_plots_and_a_missing_file_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("line.toml"),
        "name = \"line\"\n\
         [axis.x]\nvoltage = { from = 20.0, to = 120.0, steps = 6 }\n\
         [axis.y]\nvoltage = 60.0\n\
         [simulation]\nmeasure = \"window\"\ncycles = 2\nsettle = 1\n\
         [output]\nbaselines = true\n",
    )
    .unwrap();
    ok(&["run", "line.toml", "--out", "line.h5"], dir.path());
    ok(&["plot", "line.h5", "--out", "pics"], dir.path());
    for name in ["steps.png", "ratio.png"] {
        check_png(&dir.path().join("pics").join(name));
    }
    let missing = pidm(&["plot", "nothing.h5"], dir.path());
    assert!(!missing.status.success());
    let err = String::from_utf8_lossy(&missing.stderr);
    assert!(err.contains("nothing.h5"), "{err}");
}

/// A LuGre map over the bristle stiffness at four voltages
/// (`sweeps/lugre.toml`) draws each voltage's Karnopp step as a dashed line
/// in its colour: the same file with its scene text unreadable (so nothing
/// says LuGre) draws the same lines without them, hundreds of pixels fewer
/// of each colour.
#[test]
fn a_lugre_family_draws_the_karnopp_reference_lines() {
    let dir = tempfile::tempdir().unwrap();
    let scene = crate::common::manifest("sweeps/lugre.toml");
    ok(&["run", &scene, "--out", "lugre.h5"], dir.path());
    ok(&["plot", "lugre.h5", "--out", "with"], dir.path());
    let picture = |sub: &str| dir.path().join(sub).join("step_x_lines.png");
    check_png(&picture("with"));
    // The same maps under a scene text that does not parse.
    edit(&dir.path().join("lugre.h5"), |file| {
        file.delete_attr("scene")?;
        let text: hdf5::types::VarLenUnicode = "not a scene".parse().unwrap();
        file.new_attr::<hdf5::types::VarLenUnicode>()
            .create("scene")?
            .write_scalar(&text)
    });
    ok(&["plot", "lugre.h5", "--out", "without"], dir.path());
    for colour in [[33, 102, 172], [118, 42, 131]] {
        let (with, without) = (
            pixels_of(&picture("with"), colour),
            pixels_of(&picture("without"), colour),
        );
        assert!(with > without + 300, "{colour:?}: {with} against {without}");
    }
}

/// How many pixels of the PNG at `path` have exactly `colour`.
fn pixels_of(path: &Path, colour: [u8; 3]) -> usize {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .unwrap();
    let mut pixels = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut pixels).unwrap();
    pixels[..info.buffer_size()]
        .chunks(3)
        .filter(|c| *c == colour)
        .count()
}

/// The colours of periodic, quasi-periodic and not-steady cells in the
/// motion pictures (`src/plot/motion.rs`).
const PERIODIC: [u8; 3] = [33, 102, 172];
const QUASI_PERIODIC: [u8; 3] = [90, 174, 97];
const NOT_STEADY: [u8; 3] = [200, 200, 200];

#[test]
fn a_steady_grid_gives_a_map_of_the_kinds_of_motion() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 10 Hz against 14 Hz repeats (lag 5); against 10 sqrt(3) Hz it does
    // not: the phase-resolved estimate decides (quasi-periodic).
    std::fs::write(
        d.join("kinds.toml"),
        "name = \"kinds\"\n\
         [axis.x]\nvoltage = [60.0, 100.0]\nfrequency = 10.0\n\
         [axis.y]\nvoltage = 100.0\nfrequency = [14.0, 17.320508075688775]\n\
         [simulation]\nstep_tolerance = 3e-8\nmax_cycles = 5000\n",
    )
    .unwrap();
    ok(&["run", "kinds.toml", "--out", "kinds.h5"], d);
    let stdout = ok(&["plot", "kinds.h5", "--out", "pics"], d);
    let pics = d.join("pics");
    assert_eq!(
        pictures_in(&pics),
        [
            "motion.png",
            "step_x.png",
            "step_x_se.png",
            "step_y.png",
            "step_y_se.png"
        ]
    );
    assert!(stdout.contains("wrote pics/motion.png"), "{stdout}");
    let picture = pics.join("motion.png");
    check_png(&picture);
    // Half the map is periodic, half quasi-periodic: large areas of each
    // colour, beyond the legend's swatches (18 x 18 px).
    for (what, colour) in [("periodic", PERIODIC), ("quasi-periodic", QUASI_PERIODIC)] {
        let n = pixels_of(&picture, colour);
        assert!(n > 10_000, "{what}: {n} pixels");
    }

    // A file written before /maps/motion existed plots as before, without
    // that picture.
    let old = d.join("old.h5");
    std::fs::copy(d.join("kinds.h5"), &old).unwrap();
    edit(&old, |f| {
        f.unlink("maps/motion")?;
        f.unlink("motion")
    });
    ok(&["plot", "old.h5", "--out", "old"], d);
    assert_eq!(
        pictures_in(&d.join("old")),
        ["step_x.png", "step_x_se.png", "step_y.png", "step_y_se.png"]
    );

    // A code that is no kind of motion is an error naming the dataset.
    let bad = d.join("bad.h5");
    std::fs::copy(d.join("kinds.h5"), &bad).unwrap();
    edit(&bad, |f| {
        f.dataset("maps/motion")?.write_raw(&[1u8, 3, 7, 3])
    });
    let out = pidm(&["plot", "bad.h5", "--out", "bad"], d);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.h5")
            && err.contains("dataset /maps/motion holds 7: expected one of the motion codes"),
        "{err}"
    );
    assert!(!d.join("bad").exists());
}

#[test]
fn a_steady_line_gives_a_strip_of_the_kinds_of_motion() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 14 Hz repeats; 10 sqrt(3) Hz is stopped at max_cycles, not steady.
    std::fs::write(
        d.join("strip.toml"),
        "name = \"strip\"\n\
         [axis.x]\nvoltage = 100.0\nfrequency = 10.0\n\
         [axis.y]\nvoltage = 100.0\nfrequency = [14.0, 17.320508075688775]\n\
         [simulation]\nstep_tolerance = 3e-8\nmax_cycles = 200\n",
    )
    .unwrap();
    ok(&["run", "strip.toml", "--out", "strip.h5"], d);
    ok(&["plot", "strip.h5", "--out", "pics"], d);
    let pics = d.join("pics");
    assert_eq!(pictures_in(&pics), ["motion.png", "steps.png"]);
    let picture = pics.join("motion.png");
    check_png(&picture);
    for (what, colour) in [("periodic", PERIODIC), ("not steady", NOT_STEADY)] {
        let n = pixels_of(&picture, colour);
        assert!(n > 10_000, "{what}: {n} pixels");
    }
}

// ---------------------------------------------------------------------------
// Damaged result files: every one is an error that names the file and the
// dataset, never a panic, and leaves no picture behind.

/// A valid result file of a 3 x 2 grid with baselines and one trajectory,
/// made once per test process: `<dir>/dmg.h5`.
fn valid_file() -> &'static Path {
    static FILE: std::sync::OnceLock<std::path::PathBuf> = std::sync::OnceLock::new();
    FILE.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap().keep();
        std::fs::write(
            dir.join("dmg.toml"),
            "name = \"dmg\"\n\
             [axis.x]\nvoltage = [0.0, 60.0, 100.0]\n\
             [axis.y]\nvoltage = [0.0, 100.0]\n\
             [simulation]\nmeasure = \"window\"\ncycles = 2\nsettle = 1\n\
             [output]\nbaselines = true\ntrajectories = [0]\n\
             trajectory_samples_per_cycle = 20\n",
        )
        .unwrap();
        ok(&["run", "dmg.toml", "--threads", "1"], &dir);
        dir.join("results/dmg.h5")
    })
}

/// Opens the copy at `path` for writing and applies `change`, then closes
/// it explicitly (every handle into it invalidated) before `pidm plot`
/// opens it (see `common::pidm` on HDF5's file locks).
fn edit(path: &Path, change: impl FnOnce(&hdf5::File) -> hdf5::Result<()>) {
    let file = hdf5::File::open_rw(path).unwrap();
    change(&file).unwrap();
    file.close().unwrap();
}

/// Replaces the dataset `name` by one of `shape` holding `values`.
fn replace<T: hdf5::H5Type>(
    file: &hdf5::File,
    name: &str,
    shape: &[usize],
    values: &[T],
) -> hdf5::Result<()> {
    file.unlink(name)?;
    file.new_dataset::<T>()
        .shape(shape)
        .create(name)?
        .write_raw(values)
}

/// Changes the float dataset `name` by `change`, keeping its shape unless
/// the change alters the number of values (then it becomes 1-D).
fn alter(file: &hdf5::File, name: &str, change: impl FnOnce(&mut Vec<f64>)) -> hdf5::Result<()> {
    let ds = file.dataset(name)?;
    let mut shape = ds.shape();
    let mut values: Vec<f64> = ds.read_raw()?;
    let before = values.len();
    change(&mut values);
    if values.len() != before {
        shape = vec![values.len()];
    }
    replace(file, name, &shape, &values)
}

/// What a damaged file must give.
enum Want {
    /// An error whose message holds every one of these texts.
    Error(&'static [&'static str]),
    /// Success with this many pictures and these texts in the output.
    Pictures(usize, &'static [&'static str]),
}

/// Copies the valid file, damages the copy with `damage`, plots it and
/// checks the outcome against `want`.
fn check(what: &str, damage: impl FnOnce(&Path), want: Want) {
    let dir = tempfile::tempdir().unwrap();
    let copy = dir.path().join("dmg.h5");
    std::fs::copy(valid_file(), &copy).unwrap();
    damage(&copy);
    let out = pidm(&["plot", "dmg.h5", "--out", "pics"], dir.path());
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !stderr.contains("panicked"),
        "{what}: pidm panicked:\n{stderr}"
    );
    let pngs: Vec<String> = std::fs::read_dir(dir.path().join("pics"))
        .map(|entries| {
            entries
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .filter(|n| n.ends_with(".png"))
                .collect()
        })
        .unwrap_or_default();
    let leftovers: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("plotting"))
        .collect();
    assert!(leftovers.is_empty(), "{what}: staging left: {leftovers:?}");
    match want {
        Want::Error(texts) => {
            assert_eq!(
                out.status.code(),
                Some(1),
                "{what}: want a plain failure\nstdout:\n{stdout}\nstderr:\n{stderr}"
            );
            assert!(stderr.contains("dmg.h5"), "{what}: no file name: {stderr}");
            for text in texts {
                assert!(stderr.contains(text), "{what}: want {text:?} in:\n{stderr}");
            }
            assert!(pngs.is_empty(), "{what}: pictures left behind: {pngs:?}");
        }
        Want::Pictures(count, texts) => {
            assert!(out.status.success(), "{what}: failed:\n{stderr}");
            assert_eq!(pngs.len(), count, "{what}: {pngs:?}\n{stdout}");
            for text in texts {
                assert!(stdout.contains(text), "{what}: want {text:?} in:\n{stdout}");
            }
        }
    }
}

#[test]
fn damaged_result_files_are_errors_that_name_the_dataset() {
    let undamaged = |_: &Path| {};
    check("the valid file", undamaged, Want::Pictures(7, &[]));
    check(
        "trajectory series of unequal lengths (the reported panic)",
        |p| {
            edit(p, |f| {
                alter(f, "trajectories/0/slider_x", |v| v.truncate(40))
            })
        },
        Want::Error(&[
            "dataset /trajectories/0/slider_x has shape [40], expected [41]",
            "the length of /trajectories/0/time",
        ]),
    );
    check(
        "a 1-DOF series shorter than its time",
        |p| {
            edit(p, |f| {
                alter(f, "trajectories/0/baseline_y/stage", |v| v.truncate(3))
            })
        },
        Want::Error(&["dataset /trajectories/0/baseline_y/stage has shape [3]"]),
    );
    check(
        "a map of the wrong shape",
        |p| edit(p, |f| replace(f, "maps/step_y", &[2, 3], &[0.0f64; 6])),
        Want::Error(&["dataset /maps/step_y has shape [2, 3], expected [3, 2]"]),
    );
    check(
        "a baseline status of the wrong shape",
        |p| edit(p, |f| replace(f, "baseline/status", &[6], &[0u32; 6])),
        Want::Error(&["dataset /baseline/status has shape [6], expected [3, 2]"]),
    );
    check(
        "a missing axis",
        |p| edit(p, |f| f.unlink("axes/axis.x.voltage")),
        Want::Error(&["dataset /axes/axis.x.voltage is missing"]),
    );
    check(
        "an axis of the wrong length",
        |p| edit(p, |f| alter(f, "axes/axis.y.voltage", |v| v.push(200.0))),
        Want::Error(&[
            "dataset /maps/step_x has shape [3, 2], expected [3, 3]",
            "/axes/axis.y.voltage",
        ]),
    );
    check(
        "a status map of floats",
        |p| edit(p, |f| replace(f, "maps/status", &[3, 2], &[0.0f64; 6])),
        Want::Error(&["dataset /maps/status holds float64 values, expected integer"]),
    );
    check(
        "a group where a map belongs",
        |p| {
            edit(p, |f| {
                f.unlink("maps/step_x")?;
                f.create_group("maps/step_x").map(drop)
            })
        },
        Want::Error(&["dataset /maps/step_x is not a dataset"]),
    );
    check(
        "a non-finite axis value",
        |p| edit(p, |f| alter(f, "axes/axis.x.voltage", |v| v[1] = f64::NAN)),
        Want::Error(&[
            "dataset /axes/axis.x.voltage holds 1 values that are not finite or beyond ±1e100, \
             the first at index 1",
        ]),
    );
    // Finite but so large that a chart's range would overflow and its
    // labels never end: refused before drawing.
    check(
        "a sample time beyond ±1e100",
        |p| {
            edit(p, |f| {
                alter(f, "trajectories/0/time", |v| {
                    *v.last_mut().unwrap() = f64::MAX
                })
            })
        },
        Want::Error(&[
            "dataset /trajectories/0/time holds 1 values that are not finite or beyond ±1e100, \
             the first at index 40",
        ]),
    );
    check(
        "a run attribute beyond ±1e100",
        |p| {
            edit(p, |f| {
                f.group("trajectories/0")?
                    .attr("settle_s")?
                    .write_scalar(&-1e300)
            })
        },
        Want::Error(&["attribute settle_s of /trajectories/0 is -1e300, expected a finite number"]),
    );
    check(
        "sample times that decrease",
        |p| edit(p, |f| alter(f, "trajectories/0/time", |v| v.swap(4, 5))),
        Want::Error(&["dataset /trajectories/0/time decreases after index 4"]),
    );
    check(
        "a run attribute of the wrong type",
        |p| {
            edit(p, |f| {
                let g = f.group("trajectories/0")?;
                g.delete_attr("period_s")?;
                let text: hdf5::types::VarLenUnicode = "long".parse().unwrap();
                g.new_attr::<hdf5::types::VarLenUnicode>()
                    .create("period_s")?
                    .write_scalar(&text)
            })
        },
        Want::Error(&[
            "attribute period_s of /trajectories/0 holds text values, expected floating-point",
        ]),
    );
    check(
        "a missing run attribute",
        |p| {
            edit(p, |f| {
                f.group("trajectories/0/baseline_x")?
                    .delete_attr("settle_s")
            })
        },
        Want::Error(&["attribute settle_s of /trajectories/0/baseline_x is missing"]),
    );
    check(
        "half a pair of 1-DOF runs",
        |p| edit(p, |f| f.unlink("trajectories/0/baseline_y")),
        Want::Error(&[
            "group /trajectories/0/baseline_y is missing while /trajectories/0/baseline_x exists",
        ]),
    );
    check(
        "no maps",
        |p| edit(p, |f| f.unlink("maps")),
        Want::Error(&["group /maps is missing: not a pidm result file"]),
    );
    check(
        "a shard",
        |p| {
            edit(p, |f| {
                f.new_attr::<u64>()
                    .create("shard_index")?
                    .write_scalar(&0u64)
            })
        },
        Want::Error(&["is one shard of a sharded run"]),
    );
    check(
        "an empty file",
        |p| std::fs::write(p, b"").unwrap(),
        Want::Error(&["cannot open dmg.h5 as an HDF5 result file: the file is empty"]),
    );
    check(
        "a file that is not HDF5",
        |p| std::fs::write(p, "name = \"dmg\"\n").unwrap(),
        Want::Error(&["cannot open dmg.h5 as an HDF5 result file"]),
    );
    check(
        "a truncated file",
        |p| {
            let bytes = std::fs::read(p).unwrap();
            std::fs::write(p, &bytes[..bytes.len() / 2]).unwrap();
        },
        Want::Error(&["cannot open dmg.h5 as an HDF5 result file"]),
    );
    // Optional groups may be missing; values that may be non-finite are
    // left out with a note.
    check(
        "no trajectories and no baselines",
        |p| {
            edit(p, |f| {
                f.unlink("trajectories")?;
                f.unlink("baseline")
            })
        },
        Want::Pictures(2, &["wrote pics/step_x.png", "wrote pics/step_y.png"]),
    );
    check(
        "steps that are not finite or beyond ±1e100 with status 0",
        |p| {
            edit(p, |f| {
                alter(f, "maps/step_x", |v| v[1] = f64::NAN)?;
                alter(f, "baseline/step_y", |v| v[2] = -f64::MAX)
            })
        },
        Want::Pictures(
            7,
            &[
                "note: 1 instances have status 0 in /maps/status but a value in /maps/step_x or \
                 /maps/step_y that is not finite or beyond ±1e100",
                "note: 1 instances have status 0 in /baseline/status but a value in \
                 /baseline/step_x or /baseline/step_y",
            ],
        ),
    );
    check(
        "a trajectory with displacements beyond ±1e100",
        |p| {
            edit(p, |f| {
                alter(f, "trajectories/0/slider_y", |v| v[7] = f64::MAX)
            })
        },
        Want::Pictures(
            6,
            &[
                "note: trajectory 0 (instance 0",
                "holds displacements that are not finite or beyond ±1e100 (the run diverged); not drawn",
            ],
        ),
    );
}

#[test]
fn a_failed_plot_leaves_an_earlier_output_folder_as_it_was() {
    let dir = tempfile::tempdir().unwrap();
    let copy = dir.path().join("dmg.h5");
    std::fs::copy(valid_file(), &copy).unwrap();
    ok(&["plot", "dmg.h5", "--out", "pics"], dir.path());
    // Names and inode numbers: a picture moved into place is a new file,
    // even with the same bytes.
    let snapshot = |dir: &Path| {
        use std::os::unix::fs::MetadataExt;
        let mut files: Vec<(String, u64)> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| {
                let e = e.unwrap();
                let name = e.file_name().to_string_lossy().into_owned();
                (name, e.metadata().unwrap().ino())
            })
            .collect();
        files.sort();
        files
    };
    let before = snapshot(&dir.path().join("pics"));
    // Seven pictures and the manifest.
    assert_eq!(before.len(), 8);
    // The trajectory is read last: everything before it would draw.
    edit(&copy, |f| {
        alter(f, "trajectories/0/stage_y", |v| v.truncate(5))
    });
    let out = pidm(&["plot", "dmg.h5", "--out", "pics"], dir.path());
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("/trajectories/0/stage_y"));
    assert!(
        before == snapshot(&dir.path().join("pics")),
        "the earlier pictures changed"
    );
    // A folder in the place of the last picture: found only once every
    // picture is drawn, yet none is moved into place.
    std::fs::copy(valid_file(), &copy).unwrap();
    let last = dir.path().join("pics/trajectory_instance_0.png");
    std::fs::remove_file(&last).unwrap();
    std::fs::create_dir(&last).unwrap();
    let before = snapshot(&dir.path().join("pics"));
    let out = pidm(&["plot", "dmg.h5", "--out", "pics"], dir.path());
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("pics/trajectory_instance_0.png: a folder of that name is in the way"),
        "{err}"
    );
    assert!(
        before == snapshot(&dir.path().join("pics")),
        "pictures were replaced"
    );
}

/// Plotting a result into a folder that holds the pictures of an earlier
/// result of the same name replaces them: no ratio or regime map of a run
/// with baselines stays beside the maps of a run without, and only the
/// pictures pidm drew there go (a user's own file stays).
#[test]
fn replotting_removes_the_earlier_pictures_and_nothing_else() {
    let dir = tempfile::tempdir().unwrap();
    let scene = |baselines: bool| {
        format!(
            "name = \"tiny\"\n\
             [axis.x]\nvoltage = [0.0, 100.0]\n\
             [axis.y]\nvoltage = [0.0, 100.0]\n\
             [simulation]\nmeasure = \"window\"\ncycles = 2\nsettle = 1\n\
             [output]\nbaselines = {baselines}\n"
        )
    };
    std::fs::write(dir.path().join("tiny.toml"), scene(true)).unwrap();
    ok(&["run", "tiny.toml", "--threads", "1"], dir.path());
    ok(&["plot", "results/tiny.h5", "--out", "pics"], dir.path());
    let pics = dir.path().join("pics");
    assert_eq!(pictures_in(&pics).len(), 6);
    // The user's own files: a picture and a note, and a folder.
    std::fs::write(pics.join("mine.png"), "not pidm's").unwrap();
    std::fs::write(pics.join("notes.txt"), "keep").unwrap();
    std::fs::create_dir(pics.join("old")).unwrap();
    std::fs::write(dir.path().join("tiny.toml"), scene(false)).unwrap();
    ok(&["run", "tiny.toml", "--threads", "1"], dir.path());
    let stdout = ok(&["plot", "results/tiny.h5", "--out", "pics"], dir.path());
    assert_eq!(
        pictures_in(&pics),
        ["mine.png", "notes.txt", "old", "step_x.png", "step_y.png"],
        "{stdout}"
    );
    assert_eq!(
        std::fs::read_to_string(pics.join("mine.png")).unwrap(),
        "not pidm's"
    );
    // The manifest lists this plot's pictures only.
    let manifest = std::fs::read_to_string(pics.join(".pidm-plot-manifest")).unwrap();
    assert_eq!(manifest, "step_x.png\nstep_y.png\n");
    // A manifest edited to name something outside the folder, or the
    // user's file, removes nothing but listed pictures inside it.
    std::fs::write(dir.path().join("outside.png"), "outside").unwrap();
    std::fs::write(
        pics.join(".pidm-plot-manifest"),
        "../outside.png\n/etc/passwd\n..\n.\nold\nstep_x.png\n",
    )
    .unwrap();
    ok(&["plot", "results/tiny.h5", "--out", "pics"], dir.path());
    assert!(dir.path().join("outside.png").exists());
    assert!(pics.join("old").is_dir());
    assert_eq!(
        pictures_in(&pics),
        ["mine.png", "notes.txt", "old", "step_x.png", "step_y.png"]
    );
}

/// `pidm plot --x KEY --y KEY --at KEY=VALUE` slices a grid of three axes:
/// the maps span the axes named, at the value held; a key or value the
/// grid does not have is an error naming what it has, and nothing is
/// drawn.
#[test]
fn plot_slices_a_grid_by_the_axes_and_values_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("g3.toml"),
        "name = \"g3\"\n\
         [axis.x]\nvoltage = [50.0, 100.0, 150.0]\n\
         [axis.y]\nvoltage = [0.0, 50.0, 100.0, 150.0]\nfrequency = [10.0, 20.0]\n\
         [simulation]\nmeasure = \"window\"\ncycles = 2\nsettle = 1\n",
    )
    .unwrap();
    ok(&["run", "g3.toml", "--threads", "1"], dir.path());
    // By default: the two longest axes span the maps, one per frequency.
    ok(&["plot", "results/g3.h5", "--out", "all"], dir.path());
    assert_eq!(
        pictures_in(&dir.path().join("all")),
        [
            "step_x__axis.y.frequency=10.png",
            "step_x__axis.y.frequency=20.png",
            "step_y__axis.y.frequency=10.png",
            "step_y__axis.y.frequency=20.png"
        ]
    );
    let stdout = ok(
        &[
            "plot",
            "results/g3.h5",
            "--out",
            "one",
            "--x",
            "axis.y.frequency",
            "--y",
            "axis.x.voltage",
            "--at",
            "axis.y.voltage=100",
        ],
        dir.path(),
    );
    assert_eq!(
        pictures_in(&dir.path().join("one")),
        [
            "step_x__axis.y.voltage=100.png",
            "step_y__axis.y.voltage=100.png"
        ],
        "{stdout}"
    );
    check_png(&dir.path().join("one/step_x__axis.y.voltage=100.png"));
    for (args, want) in [
        (
            &["--x", "axis.z.voltage"][..],
            "--x axis.z.voltage: not a grid axis of this file; expected one of axis.x.voltage, \
             axis.y.voltage, axis.y.frequency",
        ),
        (
            &["--at", "axis.y.frequency=15"][..],
            "--at axis.y.frequency=15: not a value of that axis; it has 10, 20",
        ),
        (
            &["--x", "axis.x.voltage", "--at", "axis.x.voltage=50"][..],
            "--at axis.x.voltage: it is the axis --x or --y spans",
        ),
        (
            &["--x", "axis.x.voltage", "--y", "axis.x.voltage"][..],
            "--x and --y name the same axis axis.x.voltage",
        ),
    ] {
        let mut all = vec!["plot", "results/g3.h5", "--out", "bad"];
        all.extend(args);
        let out = pidm(&all, dir.path());
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(!dir.path().join("bad").exists());
    }
}
