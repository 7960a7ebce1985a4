//! The data a lab has (docs/fit.md, "The data"): the CSV reader (a BOM,
//! `;` and tab files, quotes, `#` comments, a decimal comma refused), units
//! in the header (m, um, nm; velocities in m/s and um/s turned into steps
//! with each row's own drive frequency, `frequency_ratio` included), a
//! bare `step_x` over 100 um refused, repeats pooled (the numbers checked
//! by hand), empty and NaN key cells refused with their line and column,
//! and a missing standard error refused; then a seeded synthetic set in um
//! and um/s with 3 repeats per setting and no error columns, fitted end
//! to end.
//!
//! Run with `cargo test --release --test it -- fit_data::`.

use std::fmt::Write;
use std::path::Path;

use pidm::fit::data::Data;
use pidm::fit::problem::Problem;
use pidm::fit::spec;
use pidm::model::{AXES, AXIS_NAMES};

use crate::common::{pidm, s};

/// A fit scene's `[fit]`: one free key that moves no frequency.
const FIT: &str = "[fit]\nfree = { \"mechanism.static_friction\" = [0.5, 3.0] }\n";

/// Reads `csv` (with `scene`, a fit scene's text before its `[fit]`, also
/// through `Problem::new`: velocities turned into steps, repeats pooled)
/// and renders what came out, or checks that the error holds `expected`.
///
/// The rendering: the delimiter, the key columns and each measured axis'
/// standard errors' source, then one line per row: its lines, its keys,
/// and each axis' step and standard error [m per own drive cycle].
fn check(scene: Option<&str>, csv: &str, expected: Result<&str, &str>) {
    let path = Path::new("d.csv");
    let data = Data::parse(csv, path).and_then(|data| match scene {
        None => Ok(data),
        Some(scene) => {
            let fit = spec::read(&format!("{scene}{FIT}"), Path::new("s.toml"))?;
            Ok(Problem::new(&fit, data)?.data)
        }
    });
    match (data, expected) {
        (Ok(data), Ok(want)) => assert_eq!(render(&data), want, "{csv}"),
        (Err(e), Err(part)) => assert!(format!("{e:#}").contains(part), "{e:#}\n{csv}"),
        (Ok(data), Err(part)) => panic!("read {csv:?}, expected {part:?}:\n{}", render(&data)),
        (Err(e), Ok(_)) => panic!("{csv:?} refused: {e:#}"),
    }
}

fn render(data: &Data) -> String {
    let mut out = format!(
        "{:?} {:?}",
        data.delimiter as char,
        data.keys.iter().map(String::as_str).collect::<Vec<_>>()
    );
    for (axis, name) in AXIS_NAMES.iter().enumerate() {
        if data.measured_on(axis) > 0 {
            write!(out, " {name}:{}", data.se_source[axis].name()).unwrap();
        }
    }
    for row in &data.rows {
        write!(out, "\n{:?} {:?}", row.lines, row.keys).unwrap();
        for axis in (0..AXES).filter(|&a| data.value[a].is_some()) {
            match (row.step[axis], row.se[axis]) {
                (Some(step), Some(se)) => write!(out, " {step:.4e}+-{se:.4e}").unwrap(),
                (Some(step), None) => write!(out, " {step:.4e}").unwrap(),
                _ => out.push_str(" -"),
            }
        }
    }
    out
}

#[test]
fn fit_data_files_are_read_in_their_format() {
    let plain = "',' [\"axis.x.voltage\"] x:residuals\n[2] [100.0] -2.0000e-6";
    // A BOM (Excel's "CSV UTF-8"), quotes, a `;` file and a tab file.
    check(
        None,
        "\u{feff}axis.x.voltage,step_x\n100,-2e-6\n",
        Ok(plain),
    );
    check(
        None,
        "\"axis.x.voltage\",\"step_x\"\n\"100\",\" -2e-6\"\n",
        Ok(plain),
    );
    check(
        None,
        "axis.x.voltage;step_x\n100;-2e-6\n",
        Ok(&plain.replace("','", "';'")),
    );
    check(
        None,
        "axis.x.voltage\tstep_x\n100\t-2e-6\n",
        Ok(&plain.replace("','", "'\\t'")),
    );
    // Comments and blank lines are skipped; a row keeps its own line.
    check(
        None,
        "# lab A, stage 3\n\naxis.x.voltage,step_x\n# run 2\n100,-2e-6\n  \n120,-3e-6\n",
        Ok("',' [\"axis.x.voltage\"] x:residuals\n[5] [100.0] -2.0000e-6\n[7] [120.0] -3.0000e-6"),
    );
    // Two axes, one row measuring only y.
    check(
        None,
        "axis.x.voltage,step_x,step_y\n100,-2e-6,\n100,,1e-7\n",
        Ok(
            "',' [\"axis.x.voltage\"] x:residuals y:residuals\n[2] [100.0] -2.0000e-6 -\n[3] [100.0] - 1.0000e-7",
        ),
    );
    // A decimal comma: in a `;` file's cell, and split in two in a `,` file.
    check(
        None,
        "axis.x.voltage;step_x_um\n100;-1,5\n",
        Err(
            "line 2, column step_x_um: \"-1,5\": a decimal comma; pidm reads numbers with a decimal point (-1.5)",
        ),
    );
    check(
        None,
        "axis.x.voltage;step_x_um\n0,5e2;-1.5\n",
        Err("line 2, column axis.x.voltage: \"0,5e2\": a decimal comma"),
    );
    check(
        None,
        "axis.x.voltage,step_x_um\n100,-0,25\n",
        Err(
            "line 2: 3 cells where the header has 2 columns (column step_x_um: -0,25 looks like a number with a decimal comma",
        ),
    );
    check(
        None,
        "axis.x.voltage,step_x_um\n100,\"0,25\"\n",
        Err("line 2, column step_x_um: \"0,25\": a decimal comma"),
    );
    check(
        None,
        "axis.x.voltage,step_x;step_y\n",
        Err("mixes `,` and `;`"),
    );
    check(
        None,
        "# only a comment\n\n",
        Err("empty: expected a header line"),
    );
    check(None, "axis.x.voltage,step_x\n", Err("no rows"));
    check(
        None,
        "axis.x.voltage;step_x;\n100;1e-6;\n",
        Err("the header's column 3 has no name"),
    );
}

#[test]
fn fit_data_units_are_named_in_the_header() {
    // Steps in m, um, nm (and mm), errors in their own units.
    check(
        None,
        "step_x_um,step_x_se_nm,step_y_nm,step_y_se_m\n-2.5,30,150,2e-8\n",
        Ok("',' [] x:file y:file\n[2] [] -2.5000e-6+-3.0000e-8 1.5000e-7+-2.0000e-8"),
    );
    check(
        None,
        "step_x_m,step_y_mm\n-2.5e-6,0.0015\n",
        Ok("',' [] x:residuals y:residuals\n[2] [] -2.5000e-6 1.5000e-6"),
    );
    // A bare step_x is in metres: over 100 um it is refused, naming the unit.
    check(
        None,
        "step_x\n9.9e-5\n",
        Ok("',' [] x:residuals\n[2] [] 9.9000e-5"),
    );
    check(
        None,
        "axis.x.voltage,step_x\n100,-2e-6\n120,-2.5\n",
        Err(
            "line 3, column step_x: -2.5: over 100 um per cycle in metres, the unit of a bare step_x; name the unit in the header: step_x_um",
        ),
    );
    check(
        None,
        "step_x,step_x_se\n-2e-6,0.02\n",
        Err("line 2, column step_x_se: 0.02: over 100 um per cycle"),
    );
    check(
        None,
        "step_x_um,velocity_x_um_s\n1,2\n",
        Err("columns `step_x_um` and `velocity_x_um_s` both measure axis x: give one"),
    );
    check(
        None,
        "step_x,step_x_um\n1e-6,1\n",
        Err("columns `step_x` and `step_x_um` both measure axis x"),
    );
    check(
        None,
        "step_x_um,step_x_se_um,step_x_se_nm\n1,0.1,100\n",
        Err("columns `step_x_se_um` and `step_x_se_nm` both give the standard error of axis x"),
    );
    check(
        None,
        "velocity_x_um_s,step_x_se_um\n1,0.1\n",
        Err(
            "column step_x_se_um is the standard error of a step, but axis x is measured as velocity_x_um_s",
        ),
    );
    check(
        None,
        "velocity_x\n1e-6\n",
        Err("column `velocity_x`: expected velocity_x_m_s"),
    );
    check(
        None,
        "step_x_mu\n1\n",
        Err("column `step_x_mu`: expected step_x_m, step_x_mm, step_x_um or step_x_nm"),
    );
    check(
        None,
        "step_z_um\n1\n",
        Err("column `step_z_um`: expected step_x or step_y"),
    );
    check(
        None,
        "step_x_um,step_y_se_um\n1,1\n",
        Err("column step_y_se_um without a measured y column"),
    );
}

#[test]
fn fit_data_cells_are_refused_naming_line_and_column() {
    let h = "axis.x.voltage,axis.x.frequency,step_x,step_x_se\n";
    check(
        None,
        &format!("{h}100,10,-2e-6,1e-8\n120,10,-3e-6,1e-8\n"),
        Ok(
            "',' [\"axis.x.voltage\", \"axis.x.frequency\"] x:file\n[2] [100.0, 10.0] -2.0000e-6+-1.0000e-8\n[3] [120.0, 10.0] -3.0000e-6+-1.0000e-8",
        ),
    );
    // Empty and NaN key cells: the scene's value is never taken.
    check(
        None,
        &format!("{h}100,10,-2e-6,1e-8\n,10,-3e-6,1e-8\n"),
        Err("line 3, column axis.x.voltage: empty: expected a number"),
    );
    check(
        None,
        &format!("{h}100,NaN,-2e-6,1e-8\n"),
        Err("line 2, column axis.x.frequency: \"NaN\": expected a finite number"),
    );
    check(
        None,
        &format!("{h}100,ten,-2e-6,1e-8\n"),
        Err("line 2, column axis.x.frequency: \"ten\""),
    );
    // A file that gives errors gives one on every measured row.
    check(
        None,
        &format!("{h}100,10,-2e-6,1e-8\n120,10,-3e-6,\n"),
        Err("line 3, column step_x_se: empty, but the row gives step_x"),
    );
    check(
        None,
        &format!("{h}100,10,,1e-8\n"),
        Err("line 2: nothing measured"),
    );
    check(
        None,
        "step_x,step_y,step_y_se\n1e-6,,1e-8\n",
        Err("line 2, column step_y_se: an error without a value"),
    );
    check(
        None,
        &format!("{h}100,10,NaN,1e-8\n"),
        Err("line 2, column step_x: \"NaN\": expected a finite number (leave the cell empty"),
    );
    check(None, &format!("{h}100,10,-2e-6,-1e-8\n"), Err("above 0"));
    check(
        None,
        &format!("{h}100,10,-2e-6\n"),
        Err("line 2: 3 cells where the header has 4 columns"),
    );
    check(
        None,
        "axis.x.volts,step_x\n1,1e-6\n",
        Err("column `axis.x.volts`: not a scene key"),
    );
    check(
        None,
        "axis.x.voltage\n100\n",
        Err("no step_x or step_y column"),
    );
    check(
        None,
        "axis.x.voltage,axis.x.voltage,step_x\n1,1,1e-6\n",
        Err("column `axis.x.voltage` appears twice"),
    );
}

#[test]
fn fit_data_velocities_are_steps_at_each_rows_own_frequency() {
    // 40 um/s at 20 Hz is 2 um per cycle; the key column sets x's frequency.
    check(
        Some("[axis.x]\nfrequency = 20.0\n"),
        "axis.x.voltage,velocity_x_um_s,velocity_x_se_m_s\n100,40,2e-7\n",
        Ok("',' [\"axis.x.voltage\"] x:file\n[2] [100.0] 2.0000e-6+-1.0000e-8"),
    );
    check(
        Some(""),
        "axis.x.frequency,velocity_x_m_s\n10,4e-5\n50,4e-5\n",
        Ok("',' [\"axis.x.frequency\"] x:residuals\n[2] [10.0] 4.0000e-6\n[3] [50.0] 8.0000e-7"),
    );
    // y at frequency_ratio x the row's x frequency: 2 x 10 Hz, 2 x 25 Hz.
    let ratio = "[axis.y]\nfrequency_ratio = 2.0\nvoltage = 100.0\n";
    check(
        Some(ratio),
        "axis.x.frequency,step_x_um,velocity_y_um_s\n10,1,40\n25,1,40\n",
        Ok(
            "',' [\"axis.x.frequency\"] x:residuals y:residuals\n[2] [10.0] 1.0000e-6 2.0000e-6\n[3] [25.0] 1.0000e-6 8.0000e-7",
        ),
    );
    // A free key that moves the frequency of a velocity axis is refused;
    // one that moves the other axis' frequency is not.
    let free_ratio =
        format!("{ratio}[fit]\nfree = {{ \"axis.y.frequency_ratio\" = [1.0, 3.0] }}\n");
    let refused = |csv: &str| {
        let fit = spec::read(&free_ratio, Path::new("s.toml")).unwrap();
        let data = Data::parse(csv, Path::new("d.csv")).unwrap();
        Problem::new(&fit, data).map(|p| render(&p.data))
    };
    let e = refused("axis.x.voltage,velocity_y_um_s\n100,40\n").unwrap_err();
    assert!(
        format!("{e:#}").contains("`axis.y.frequency_ratio` is free in [fit] and moves axis y's drive frequency, which turns velocity_y_um_s of d.csv into a step"),
        "{e:#}"
    );
    assert_eq!(
        refused("axis.x.voltage,velocity_x_um_s\n100,40\n").unwrap(),
        "',' [\"axis.x.voltage\"] x:residuals\n[2] [100.0] 4.0000e-6"
    );
}

#[test]
fn fit_data_repeats_are_pooled_when_the_file_gives_no_errors() {
    // x: settings 100 V (1, 2, 3 um), 120 V (5, 7 um), 140 V (9 um).
    // Means 2, 6, 9 um. Squared deviations: 1 + 0 + 1 = 2 on 2 degrees of
    // freedom, and 1 + 1 = 2 on 1; s^2 = 4 / 3, s = 1.154700538 um. The
    // means' errors: s / sqrt(3) = 0.666666667 um, s / sqrt(2) =
    // 0.816496581 um, s / 1 = 1.154700538 um. y repeats nowhere (one value
    // per setting): it keeps the residuals' scale, its rows the means.
    let csv = "axis.x.voltage,step_x_um,step_y_um\n100,1,0.5\n120,5,\n100,2,\n140,9,\n100,3,\n120,7,0.25\n";
    check(
        Some(""),
        csv,
        Ok("',' [\"axis.x.voltage\"] x:repeats y:residuals\n\
            [2, 4, 6] [100.0] 2.0000e-6+-6.6667e-7 5.0000e-7\n\
            [3, 7] [120.0] 6.0000e-6+-8.1650e-7 2.5000e-7\n\
            [5] [140.0] 9.0000e-6+-1.1547e-6 -"),
    );
    // Velocities are pooled as the steps they become (10 Hz: /10).
    check(
        Some(""),
        "axis.x.voltage,velocity_x_um_s\n100,10\n100,20\n100,30\n",
        Ok("',' [\"axis.x.voltage\"] x:repeats\n[2, 3, 4] [100.0] 2.0000e-6+-5.7735e-7"),
    );
    // With an error column nothing is pooled; without repeats nothing is.
    check(
        Some(""),
        "axis.x.voltage,step_x_um,step_x_se_um\n100,1,0.1\n100,2,0.1\n",
        Ok(
            "',' [\"axis.x.voltage\"] x:file\n[2] [100.0] 1.0000e-6+-1.0000e-7\n[3] [100.0] 2.0000e-6+-1.0000e-7",
        ),
    );
    check(
        Some(""),
        "axis.x.voltage,step_x_um\n100,1\n120,2\n",
        Ok("',' [\"axis.x.voltage\"] x:residuals\n[2] [100.0] 1.0000e-6\n[3] [120.0] 2.0000e-6"),
    );
    let data = {
        let fit = spec::read(FIT, Path::new("s.toml")).unwrap();
        let data = Data::parse(csv, Path::new("d.csv")).unwrap();
        Problem::new(&fit, data).unwrap().data
    };
    let pooled = data.pooled[0].unwrap();
    assert!(
        (pooled.sd - (4.0f64 / 3.0).sqrt() * 1e-6).abs() < 1e-18,
        "{pooled:?}"
    );
    assert_eq!((pooled.dof, pooled.settings, data.lines), (3, 2, 6));
}

/// Box-Muller: a standard normal draw from two uniform ones.
fn normal(rng: &mut pidm::model::random::Rng) -> f64 {
    let (u, v) = (rng.unit().max(1e-300), rng.unit());
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// examples/fit/coupling's truth: static 1.2 N, Coulomb 1.0 N, y gain
/// -0.45 N/V, both axes driven at 10 Hz.
const TRUTH: [(&str, f64); 3] = [
    ("mechanism.static_friction", 1.2),
    ("mechanism.coulomb_friction", 1.0),
    ("axis.y.gain", -0.45),
];
const BOUNDS: [[f64; 2]; 3] = [[0.5, 3.0], [0.3, 2.0], [-1.0, -0.2]];

#[test]
fn fit_data_a_seeded_set_in_um_and_um_per_s_with_repeats_is_recovered() {
    let dir = tempfile::tempdir().unwrap();
    let settings: Vec<(f64, f64)> = [60.0, 100.0, 140.0]
        .iter()
        .flat_map(|&vx| [-120.0, -60.0, 60.0, 120.0].map(|vy| (vx, vy)))
        .collect();
    // The truth's steps at each setting, through the fit's own machinery.
    let free: Vec<String> = TRUTH
        .iter()
        .zip(BOUNDS)
        .map(|((k, _), [lo, hi])| format!("\"{k}\" = [{lo:?}, {hi:?}]"))
        .collect();
    let fit_table = format!(
        "[fit]\ndata = \"d.csv\"\nfree = {{ {} }}\n",
        free.join(", ")
    );
    let truth_scene = format!(
        "[axis.x]\ngain = -0.6\n[axis.y]\ngain = -0.45\n[simulation]\nstep_tolerance = 1e-10\n{fit_table}"
    );
    let rows: String = settings
        .iter()
        .map(|(x, y)| format!("{x},{y},1e-7\n"))
        .collect();
    let data = Data::parse(
        &format!("axis.x.voltage,axis.y.voltage,step_x\n{rows}"),
        Path::new("rows.csv"),
    )
    .unwrap();
    let backend = pidm::backend::CpuBackend::new(None).unwrap();
    let spec = spec::read(&truth_scene, Path::new("truth.toml")).unwrap();
    let mut problem = Problem::new(&spec, data).unwrap();
    problem.on(&backend);
    let truth: Vec<f64> = TRUTH.iter().map(|(_, v)| *v).collect();
    let models = problem.evaluate_points(&truth, problem.points()).unwrap();
    // 3 repeats of each setting, in three passes; x in um per cycle with
    // a noise of 0.02 um, y in um/s (10 Hz) with 0.2 um/s, seeded.
    let mut rng = pidm::model::random::Rng::new(4);
    let mut csv = String::from(
        "# a seeded synthetic set\naxis.x.voltage;axis.y.voltage;step_x_um;velocity_y_um_s\n",
    );
    for _ in 0..3 {
        for ((vx, vy), model) in settings.iter().zip(&models) {
            let model = model.expect("the truth runs");
            let x = model.step[0] * 1e6 + 0.02 * normal(&mut rng);
            let y = model.step[1] * 1e7 + 0.2 * normal(&mut rng);
            writeln!(csv, "{vx};{vy};{x:.6};{y:.5}").unwrap();
        }
    }
    std::fs::write(dir.path().join("d.csv"), csv).unwrap();
    let scene = dir.path().join("scene.toml");
    std::fs::write(&scene, format!("[axis.y]\ngain = -0.5\n{fit_table}")).unwrap();
    let started = std::time::Instant::now();
    let out = dir.path().join("fit.json");
    let run = pidm(
        &["fit", s(&scene), "--out", s(&out), "--backend", "cpu"],
        dir.path(),
    );
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    eprintln!(
        "the fit of 36 lines in 12 settings took {:?}:\n{stdout}",
        started.elapsed()
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(
        json["se_source"],
        serde_json::json!({"x": "repeats", "y": "repeats"})
    );
    let described = &json["data_description"];
    assert_eq!(described["lines"], 36, "{described:#}");
    assert_eq!(described["settings"], 12, "{described:#}");
    assert_eq!(described["delimiter"], ";");
    assert_eq!(described["axes"]["y"]["quantity"], "velocity");
    assert_eq!(described["axes"]["y"]["column"], "velocity_y_um_s");
    assert_eq!(described["axes"]["x"]["pooled_dof"], 24);
    assert_eq!(json["rows"].as_array().unwrap().len(), 12);
    assert_eq!(json["rows"][0]["lines"], serde_json::json!([3, 15, 27]));
    assert!(
        stdout.contains("data: 36 lines in 12 settings (12 repeated)"),
        "{stdout}"
    );
    assert!(
        stdout.contains("step y from the velocity velocity_y_um_s [um/s] divided by each row's own drive frequency on y"),
        "{stdout}"
    );
    assert!(
        stdout.contains("standard errors from the repeats: s = "),
        "{stdout}"
    );
    for (key, truth) in TRUTH {
        let p = &json["parameters"][key];
        let (value, se) = (p["value"].as_f64().unwrap(), p["se"].as_f64().unwrap());
        assert!(
            (value - truth).abs() <= 3.0 * se && se < 0.1 * truth.abs(),
            "{key} = {value} +- {se}, truth {truth}\n{stdout}"
        );
    }
}
