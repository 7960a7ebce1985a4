//! `pidm refine-study`: a refined run against a uniform run of its finest
//! grid, and the refinement rule's variants replayed, as Markdown tables.

use std::path::Path;

use anyhow::{Context, Result, bail};

use super::scenes::load_scene;
use crate::backend::{BackendChoice, Hardware, select_backend};
use crate::run::{RunScope, run_scene};
use crate::sweep;

/// `pidm refine-study`: a uniform run of a refined scene's finest grid and
/// the refined run, both timed on the same backend; the rule's variants
/// replayed on the uniform run's values; prints Markdown tables.
pub fn refine_study(
    scene_path: &Path,
    out_dir: &Path,
    choice: BackendChoice,
    uniform: Option<&Path>,
) -> Result<()> {
    use crate::refine::study;
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
    let pct = |x: f64| format!("{:.2} %", 100.0 * x);
    let row = |name: &str, m: &study::Metrics| {
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
    };
    let header = "| rule | integrated | share | sign labels differ (dead zone tol) | sign differs \
                  (0.001 um) | coupling regime differs (0.001 um) | coupling regime differs \
                  (tol) | step values within tol + 1 % | largest error [um] |\n\
                  |---|---|---|---|---|---|---|---|---|";
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
    let (_, uniform_records, baselines) = study::read_records(&uniform_path)?;
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
    let mut m = study::compare(&raster, &uniform_records, refine.tolerance, baselines);
    m.integrated = index.len() as u64;
    println!(
        "The refined run ({}) against the uniform one ({}):\n",
        refined.path.display(),
        uniform_path.display()
    );
    println!("{header}");
    row("refined run (standard rule)", &m);
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
    println!("Rule variants, replayed on the uniform run's values:\n\n{header}");
    let mut levels = Vec::new();
    for (name, m, r) in study::study(
        &uniform_path,
        refine.coarse,
        refine.levels,
        refine.tolerance,
    )? {
        row(name, &m);
        levels.push((name, r.stats));
    }
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
    if backend.hardware() == Hardware::Gpu {
        std::mem::forget(selected);
    }
    Ok(())
}
