//! Errors a lab can quote (issue 60): a fit next to a region a scene rule
//! refuses still writes FIT.json, understated standard errors make the
//! p-value warn and the scaled errors cover the truth, `fit.errors =
//! "scaled"` reports those, and fits the data cannot determine are
//! flagged (no degree of freedom without standard errors, a key that
//! moves nothing).

use std::path::Path;

use crate::common::{manifest, pidm, s};

/// Writes `files` into `dir` and fits `scene.toml` on the CPU: FIT.json.
fn fit_in(dir: &Path, files: &[(&str, String)]) -> serde_json::Value {
    for (name, text) in files {
        std::fs::write(dir.join(name), text).unwrap();
    }
    let out = dir.join("fit.json");
    let run = pidm(
        &["fit", "scene.toml", "--out", s(&out), "--backend", "cpu"],
        dir,
    );
    assert!(
        run.status.success(),
        "pidm fit failed:\n{}",
        String::from_utf8_lossy(&run.stderr)
    );
    serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap()
}

fn warnings(json: &serde_json::Value) -> String {
    json["warnings"].to_string()
}

/// `coulomb_friction` free, its truth (0.99 N) 0.005 N above the scene's
/// load (0.985 N, which a candidate's kinetic friction must exceed): the
/// probes one standard error (0.024 N) below the best value are refused,
/// the Jacobian takes the other side, and FIT.json holds the value. The
/// data are the model's own steps at the truth (pidm 9130285 ended this
/// fit with "the model failed next to the best point" and no FIT.json).
#[test]
fn a_fit_next_to_a_refused_region_writes_its_values() {
    let steps = [
        (12.0, 10.0, 2.388251e-06),
        (12.0, 12.0, 6.368883e-06),
        (16.0, 10.0, 5.582195e-06),
        (16.0, 12.0, 3.439148e-06),
        (20.0, 10.0, 1.080882e-05),
        (20.0, 12.0, 5.947898e-05),
        (24.0, 10.0, 5.387794e-05),
        (24.0, 12.0, 8.282749e-05),
    ];
    // In micrometres: the errors (3 times the step) pass 100 um.
    let mut csv = String::from("axis.x.voltage,axis.x.frequency,step_x_um,step_x_se_um\n");
    for (v, f, step) in steps {
        csv += &format!("{v},{f},{:e},{:e}\n", step * 1e6, 3.0 * step * 1e6);
    }
    let scene = "[mechanism]\nload_x = 0.985\n[axis.y]\nvoltage = 0.0\n[fit]\ndata = \"d.csv\"\n\
                 free = { \"mechanism.coulomb_friction\" = [0.5, 2.0] }\n";
    let dir = tempfile::tempdir().unwrap();
    let json = fit_in(dir.path(), &[("scene.toml", scene.into()), ("d.csv", csv)]);
    let p = &json["parameters"]["mechanism.coulomb_friction"];
    let (value, se) = (p["value"].as_f64().unwrap(), p["se"].as_f64().unwrap());
    assert!((value - 0.99).abs() < 1e-6, "{json:#}");
    assert!(se > 0.005 && se.is_finite(), "{json:#}");
    assert!(json["infeasible"].as_u64().unwrap() > 0, "{json:#}");
    assert!(json["p_value"].as_f64().unwrap() > 0.99, "{json:#}");
}

/// The shipped Karnopp set with its standard errors divided by 3: the
/// p-value warns, and the standard errors scaled by sqrt(reduced chi2)
/// put each truth within 2 of them; `fit.errors = "scaled"` reports the
/// scaled ones.
#[test]
fn understated_errors_warn_and_scale() {
    let data = std::fs::read_to_string(manifest("examples/fit/karnopp_steps.csv")).unwrap();
    let mut lines = data.lines();
    let header = lines.next().unwrap();
    let se_column = header.split(',').position(|c| c == "step_x_se").unwrap();
    let mut csv = format!("{header}\n");
    for line in lines {
        let mut cells: Vec<String> = line.split(',').map(str::to_owned).collect();
        let se: f64 = cells[se_column].parse().unwrap();
        cells[se_column] = format!("{:e}", se / 3.0);
        csv += &(cells.join(",") + "\n");
    }
    let scene = |errors: &str| {
        format!(
            "[fit]\ndata = \"d.csv\"\n{errors}free = {{ \"mechanism.static_friction\" = [0.5, \
             3.0], \"mechanism.coulomb_friction\" = [0.3, 2.0], \"axis.x.gain\" = [-1.0, -0.2] }}\n"
        )
    };
    let truth = [
        ("mechanism.static_friction", 1.2),
        ("mechanism.coulomb_friction", 1.0),
        ("axis.x.gain", -0.6),
    ];
    let dir = tempfile::tempdir().unwrap();
    let given = fit_in(
        dir.path(),
        &[("scene.toml", scene("")), ("d.csv", csv.clone())],
    );
    assert!(given["p_value"].as_f64().unwrap() < 1e-3, "{given:#}");
    assert!(
        warnings(&given).contains("too small for the misfit"),
        "{given:#}"
    );
    assert_eq!(given["errors"], "given");
    for (key, value) in truth {
        let p = &given["parameters"][key];
        let (got, scaled) = (
            p["value"].as_f64().unwrap(),
            p["se_scaled"].as_f64().unwrap(),
        );
        assert!(scaled > p["se"].as_f64().unwrap(), "{key}: {p}");
        assert!(
            (got - value).abs() <= 2.0 * scaled,
            "{key}: {got} +- {scaled}, truth {value}"
        );
    }
    let scaled = fit_in(
        dir.path(),
        &[
            ("scene.toml", scene("errors = \"scaled\"\n")),
            ("d.csv", csv),
        ],
    );
    assert_eq!(scaled["errors"], "scaled");
    for (key, _) in truth {
        let (a, b) = (&scaled["parameters"][key], &given["parameters"][key]);
        assert_eq!(a["se"], a["se_scaled"], "{key}");
        assert_eq!(
            a["se"], b["se_scaled"],
            "{key}: the same fit, its errors scaled"
        );
    }
}

/// Two rows without standard errors for two free keys: no degree of
/// freedom is left for the scale, and the fit says the SEs say nothing.
#[test]
fn an_exact_fit_without_errors_is_flagged() {
    let dir = tempfile::tempdir().unwrap();
    let csv = "axis.x.voltage,step_x\n80,5.1e-6\n120,9.8e-6\n".to_owned();
    let scene = "[fit]\ndata = \"d.csv\"\nfree = { \"mechanism.static_friction\" = [0.5, 3.0], \
                 \"mechanism.coulomb_friction\" = [0.3, 2.0] }\n";
    let json = fit_in(dir.path(), &[("scene.toml", scene.into()), ("d.csv", csv)]);
    assert_eq!(json["identifiable"], false, "{json:#}");
    assert!(warnings(&json).contains("no degree of freedom"), "{json:#}");
    assert!(json["p_value"].is_null(), "{json:#}");
}

/// `axis.y.gain` with y undriven moves no step: flagged not identifiable.
#[test]
fn a_key_that_moves_nothing_is_flagged() {
    let dir = tempfile::tempdir().unwrap();
    let csv = "axis.x.voltage,step_x,step_x_se\n80,5.1e-6,1e-7\n100,7.0e-6,1e-7\n120,9.8e-6,1e-7\n"
        .to_owned();
    let scene = "[axis.y]\nvoltage = 0.0\ngain = -0.6\n[fit]\ndata = \"d.csv\"\n\
                 free = { \"axis.y.gain\" = [-1.0, -0.2] }\n";
    let json = fit_in(dir.path(), &[("scene.toml", scene.into()), ("d.csv", csv)]);
    assert_eq!(json["identifiable"], false, "{json:#}");
}

/// The coverage study of `results/fit/coverage.py`, one draw per set (CI;
/// results/fit.md has the 20 draws): each truth inside its 95 % profile
/// interval for the Karnopp, LuGre and lab (um, um/s, 3 repeats, no error
/// columns) sets, and with errors 3 times too small the p-value warns and
/// the scaled errors cover each truth within 2 of them.
#[test]
fn the_coverage_study_passes_one_draw_per_set() {
    use std::process::Command;
    let root = env!("CARGO_MANIFEST_DIR");
    let python_ok = Command::new("python3")
        .args(["-c", "import numpy, h5py"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !python_ok {
        assert!(
            std::env::var_os("CI").is_none(),
            "python3 with numpy and h5py is missing (pip install -r tests/requirements.txt)"
        );
        eprintln!("notice: python3 with numpy and h5py is missing; the coverage study is not run");
        return;
    }
    let out = Command::new("python3")
        .args(["results/fit/coverage.py", "--draws", "1"])
        .args(["--pidm", env!("CARGO_BIN_EXE_pidm")])
        .env("HDF5_USE_FILE_LOCKING", "FALSE")
        .current_dir(root)
        .output()
        .expect("python3 runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("| lab | axis.y.gain | 1 of 1 |"),
        "{stdout}"
    );
    assert!(stdout.contains("| p < 0.001 warned | 1 of 1 |"), "{stdout}");
}

/// One free key (LuGre's bristle stiffness, `examples/fit/lugre.toml`):
/// its 68 % interval is where a dense scan of chi2 along the key rises by
/// 1 above the scan's least, within 5 % of the interval's width. The scan
/// is `pidm run` of every data row at 81 stiffnesses spaced evenly in the
/// logarithm across the 95 % interval, at the fit's `step_tolerance`, with
/// chi2 computed here from the data's standard errors.
#[test]
fn one_keys_interval_is_the_scans_rise_of_one() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("fit.json");
    let run = pidm(
        &[
            "fit",
            &manifest("examples/fit/lugre.toml"),
            "--out",
            s(&out),
            "--backend",
            "cpu",
        ],
        dir.path(),
    );
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let p = &json["parameters"]["mechanism.bristle_stiffness"];
    let number = |v: &serde_json::Value| v.as_f64().expect("a closed side");
    let (lo68, hi68) = (number(&p["interval68"][0]), number(&p["interval68"][1]));
    let (lo95, hi95) = (number(&p["interval95"][0]), number(&p["interval95"][1]));
    let tolerance = json["step_tolerance"]["fit"].as_f64().unwrap();
    let rows = json["rows"].as_array().unwrap();
    let grid: Vec<f64> = (0..81)
        .map(|i| (lo95.ln() + (hi95 / lo95).ln() * i as f64 / 80.0).exp())
        .collect();
    let mut scene = format!(
        "name = \"scan\"\n[mechanism]\nfriction = \"lugre\"\nstribeck_velocity = 1e-5\n\
         [axis.y]\nvoltage = 0\n[simulation]\nstep_tolerance = {tolerance:e}\n"
    );
    for &k in &grid {
        for row in rows {
            scene += &format!(
                "[[points]]\nmechanism.bristle_stiffness = {k:e}\naxis.x.voltage = {}\n\
                 mechanism.load_x = {}\n",
                row["axis.x.voltage"], row["mechanism.load_x"]
            );
        }
    }
    std::fs::write(dir.path().join("scan.toml"), scene).unwrap();
    let map = dir.path().join("scan.h5");
    let run = pidm(
        &[
            "run",
            "scan.toml",
            "--backend",
            "cpu",
            "--progress",
            "none",
            "--out",
            s(&map),
        ],
        dir.path(),
    );
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let steps = hdf5::File::open(&map)
        .unwrap()
        .dataset("maps/step_x")
        .unwrap()
        .read_raw::<f64>()
        .unwrap();
    let chi2: Vec<f64> = steps
        .chunks(rows.len())
        .map(|model| {
            model
                .iter()
                .zip(rows)
                .map(|(m, row)| ((m - number(&row["step_x"])) / number(&row["step_x_se"])).powi(2))
                .sum()
        })
        .collect();
    let least = chi2.iter().copied().fold(f64::INFINITY, f64::min);
    // The outermost crossings of a rise of 1, interpolated in the logarithm.
    let crossing = |a: usize, b: usize| {
        let (ra, rb) = (chi2[a] - least - 1.0, chi2[b] - least - 1.0);
        let t = ra / (ra - rb);
        (grid[a].ln() + t * (grid[b].ln() - grid[a].ln())).exp()
    };
    let inside: Vec<usize> = (0..grid.len())
        .filter(|&i| chi2[i] - least <= 1.0)
        .collect();
    let (first, last) = (inside[0], inside[inside.len() - 1]);
    assert!(
        first > 0 && last + 1 < grid.len(),
        "the scan's rise of 1 lies inside the 95 % interval"
    );
    let (scan_lo, scan_hi) = (crossing(first - 1, first), crossing(last, last + 1));
    let width = hi68 - lo68;
    assert!(
        (scan_lo - lo68).abs() <= 0.05 * width && (scan_hi - hi68).abs() <= 0.05 * width,
        "68 % interval {lo68:e} .. {hi68:e}, the scan's {scan_lo:e} .. {scan_hi:e}"
    );
}
