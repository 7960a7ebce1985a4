//! `pidm refine-study`: a refined run against a uniform run of its finest
//! grid, and the refinement rule's variants replayed, as Markdown tables.

use std::path::Path;

use anyhow::{Context, Result, bail};

use super::scenes::load_scene;
use crate::backend::{BackendChoice, Hardware, select_backend};
use crate::refine::LevelStats;
use crate::run::{RunResult, RunScope, run_scene};
use crate::scene::Refine;
use crate::sweep;

/// The header of the rule tables: one row per rule, its integrated points
/// and its mismatches against the uniform run.
const RULE_HEADER: &str = "| rule | integrated | share | sign labels differ (dead zone tol) | sign differs \
                  (0.001 um) | coupling regime differs (0.001 um) | coupling regime differs \
                  (tol) | step values within tol + 1 % | largest error [um] |\n\
                  |---|---|---|---|---|---|---|---|---|";

/// `pidm refine-study`: a uniform run of a refined scene's finest grid and
/// the refined run, both timed on the same backend; the rule's variants
/// replayed on the uniform run's values; prints Markdown tables.
pub fn refine_study(
    scene_path: &Path,
    out_dir: &Path,
    choice: BackendChoice,
    uniform: Option<&Path>,
) -> Result<()> {
    let scene = load_scene(scene_path)?;
    let Some(refine) = scene.refine else {
        bail!("{}: the scene has no [refine]", scene_path.display());
    };
    crate::run::install_interrupt_handler();
    let selected = select_backend(choice, None, None, &crate::run::estimate::workload(&scene))?;
    let backend = selected.backend();
    std::fs::create_dir_all(out_dir)
        .with_context(|| format!("cannot create {}", out_dir.display()))?;
    let quiet = RunScope {
        progress: Some(crate::progress::ProgressMode::Off),
        ..RunScope::default()
    };
    let (uniform_path, uniform_wall) = match uniform {
        Some(path) => {
            let f = hdf5::File::open(path)?;
            let wall = f
                .attr(crate::output::schema::WALL_TIME_S)?
                .read_scalar::<f64>()?;
            (path.to_path_buf(), wall)
        }
        None => {
            let mut whole = scene.clone();
            whole.refine = None;
            let out = out_dir.join(format!("{}.uniform.h5", scene.name));
            let r = run_scene(&whole, backend, &out, 0, quiet)?;
            (r.path, r.wall_time_s)
        }
    };
    let refined_out = out_dir.join(format!("{}.refined.h5", scene.name));
    let refined = run_scene(&scene, backend, &refined_out, 0, quiet)?;
    println!(
        "scene {:?}: coarse {} x {}, levels {}, tolerance {:e} m, finest grid {} points; \
         backend {}\n",
        scene.name,
        refine.coarse[0],
        refine.coarse[1],
        refine.levels,
        refine.tolerance,
        scene.instance_count(),
        backend.describe()
    );
    print_refined_against_uniform(&refined, (&uniform_path, uniform_wall), refine.tolerance)?;
    print_rule_variants(&uniform_path, refine)?;
    if backend.hardware() == Hardware::Gpu {
        std::mem::forget(selected);
    }
    Ok(())
}

/// The refined run against the uniform one (its file and wall time): the
/// standard rule's row, whether the integrated points are bit for bit the
/// uniform run's, and the wall times.
fn print_refined_against_uniform(
    refined: &RunResult,
    (uniform_path, uniform_wall): (&Path, f64),
    tolerance: f64,
) -> Result<()> {
    use crate::refine::study;
    let (_, uniform_records, baselines) = study::read_records(uniform_path)?;
    let (_, raster, _) = study::read_records(&refined.path)?;
    let index: Vec<u64> = hdf5::File::open(&refined.path)?
        .dataset(crate::output::schema::REFINE_INDEX)?
        .read_raw()?;
    let same = index.iter().all(|&k| {
        let (a, b) = (&raster[k as usize], &uniform_records[k as usize]);
        let bits = |r: &sweep::Record| {
            [r.step, r.step_se, r.velocity, r.baseline_step].map(|v| v.map(f64::to_bits))
        };
        bits(a) == bits(b) && a.status == b.status && a.baseline_status == b.baseline_status
    });
    let mut m = study::compare(&raster, &uniform_records, tolerance, baselines);
    m.integrated = index.len() as u64;
    println!(
        "The refined run ({}) against the uniform one ({}):\n",
        refined.path.display(),
        uniform_path.display()
    );
    println!("{RULE_HEADER}");
    print_rule_row("refined run (standard rule)", &m);
    let share = m.integrated as f64 / m.points as f64;
    println!(
        "\nintegrated points bit-identical to the uniform run's: {}\nwall time: uniform \
         {uniform_wall:.3} s, refined {:.3} s = {:.3} of uniform; integrated share \
         {share:.3} (bound: share x 1.2 = {:.3})\n",
        if same { "yes" } else { "NO" },
        refined.wall_time_s,
        refined.wall_time_s / uniform_wall,
        share * 1.2
    );
    Ok(())
}

/// The rule's variants replayed on the uniform run's values, one row
/// each, then the standard rules' levels.
fn print_rule_variants(uniform_path: &Path, refine: Refine) -> Result<()> {
    println!("Rule variants, replayed on the uniform run's values:\n\n{RULE_HEADER}");
    let mut levels = Vec::new();
    for (name, m, r) in
        crate::refine::study::study(uniform_path, refine.coarse, refine.levels, refine.tolerance)?
    {
        print_rule_row(name, &m);
        levels.push((name, r.stats));
    }
    print_level_table(&levels);
    Ok(())
}

/// A share as a percentage: "12.34 %".
fn pct(x: f64) -> String {
    format!("{:.2} %", 100.0 * x)
}

/// One row of a rule table.
fn print_rule_row(name: &str, m: &crate::refine::study::Metrics) {
    println!(
        "| {name} | {} | {} | {} | {} | {} | {} | {} | {:.4} |",
        m.integrated,
        pct(m.integrated as f64 / m.points as f64),
        pct(m.sign_mismatch),
        pct(m.zero_sign_mismatch),
        m.regime_mismatch.map_or("-".to_string(), pct),
        m.regime_tol_mismatch.map_or("-".to_string(), pct),
        pct(m.within),
        m.worst * 1e6
    );
}

/// The table of the standard rules' levels: per level the points, the
/// cells judged and refined and why, the audit and the batches.
fn print_level_table(levels: &[(&str, Vec<LevelStats>)]) {
    println!(
        "\n| rule | level | points | cells judged | refined | by labels | by probes | by \
         neighbours | audited | audit finds | largest miss [um] | batches |\n|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for (name, stats) in levels
        .iter()
        .filter(|(name, _)| name.starts_with("standard ("))
    {
        for (level, st) in stats.iter().enumerate() {
            println!(
                "| {name} | {level} | {} | {} | {} | {} | {} | {} | {} | {} | {:.4} | {} |",
                st.integrated,
                st.candidates,
                st.flagged,
                st.by_label,
                st.by_probe,
                st.by_neighbours,
                st.audited,
                st.audit_finds,
                st.largest_miss * 1e6,
                st.batches
            );
        }
    }
}
