//! The Karnopp limit of LuGre friction (docs/model.md section 8): as sigma0
//! grows (sigma1 = sqrt(sigma0 m_s)) and v_S shrinks, LuGre tends to the
//! Coulomb friction with stiction of section 3. `pidm accuracy` runs a
//! LuGre scene's instances at a ladder of sigma0 with v_S = 1e-5 m/s and
//! compares each with the same instance under Karnopp: a table in
//! `accuracy.md` and a picture.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use anyhow::Result;
use plotters::prelude::*;

use super::{LogLog, log_log_png};
use crate::backend::{Backend, CpuBackend};
use crate::laws::{Law, Settings};
use crate::model::{AXES, Friction, Instance};

/// The ladder of bristle stiffness [N/m]: docs/model.md's table and the issue's
/// limit, 1e7 to 1e10.
pub const LIMIT_STIFFNESS: [f64; 4] = [1e7, 1e8, 1e9, 1e10];
/// The Stribeck velocity of the limit [m/s]: docs/model.md's table.
pub const LIMIT_STRIBECK: f64 = 1e-5;

/// One rung of the ladder.
#[derive(Clone, Debug)]
pub struct LimitRow {
    /// sigma0 [N/m].
    pub bristle_stiffness: f64,
    /// Each instance's LuGre steps [um per own cycle].
    pub steps_um: Vec<[f64; AXES]>,
    /// The largest |LuGre - Karnopp| over instances and axes [um].
    pub max_difference_um: f64,
    /// Wall time of the rung on one thread [s].
    pub wall_s: f64,
    /// Instances that did not end with status 0.
    pub failed: usize,
}

/// The Karnopp steps of `instances` [um] (their friction replaced by
/// their law's limit, `Law::limit`: Karnopp's at its default band) and the
/// ladder's rows, at `settings`. The rungs keep the instances' law (LuGre)
/// with its own keys at sigma0, a derived sigma1, no viscous friction and
/// [`LIMIT_STRIBECK`].
///
/// # Panics
/// If the instances' law has no limit.
pub fn karnopp_limit(
    instances: &[Instance],
    settings: Settings,
) -> Result<(Vec<[f64; AXES]>, Vec<LimitRow>)> {
    let backend = CpuBackend::new(Some(1))?;
    let with = |friction: Friction| -> Vec<Instance> {
        instances
            .iter()
            .map(|inst| {
                let mut out = *inst;
                out.mechanism.friction = friction;
                out
            })
            .collect()
    };
    let steps = |list: &[Instance]| -> Result<(Vec<[f64; AXES]>, usize, f64)> {
        let started = Instant::now();
        let outs = backend.run(list, &settings, &|_| {})?;
        let wall = started.elapsed().as_secs_f64();
        let failed = outs.iter().filter(|o| o.status != 0).count();
        let um = list
            .iter()
            .zip(&outs)
            .map(|(inst, o)| std::array::from_fn(|i| o.step(inst, i) * 1e6))
            .collect();
        Ok((um, failed, wall))
    };
    let Some(first) = instances.first() else {
        return Ok((Vec::new(), Vec::new()));
    };
    let law = Law::of_instance(first);
    let limit = law.limit().expect("a law with a limit");
    let (karnopp, _, _) = steps(&with(limit.friction([f64::NAN; 4])))?;
    let mut rows = Vec::new();
    for sigma0 in LIMIT_STIFFNESS {
        let rung = law.friction([sigma0, f64::NAN, 0.0, LIMIT_STRIBECK]);
        let (um, failed, wall_s) = steps(&with(rung))?;
        let max_difference_um = um
            .iter()
            .zip(&karnopp)
            .flat_map(|(a, b)| (0..AXES).map(move |i| (a[i] - b[i]).abs()))
            .fold(0.0, f64::max);
        rows.push(LimitRow {
            bristle_stiffness: sigma0,
            steps_um: um,
            max_difference_um,
            wall_s,
            failed,
        });
    }
    Ok((karnopp, rows))
}

/// The Markdown section of the limit: one row per sigma0 with the first
/// instance's x step, the largest difference and the time.
pub fn limit_markdown(name: &str, karnopp: &[[f64; AXES]], rows: &[LimitRow]) -> String {
    let mut md = format!(
        "## Scene `{name}`: the Karnopp limit\n\n![LuGre against Karnopp](accuracy_{name}_limit.png)\
         \n\nEach instance of the scene with its friction replaced: LuGre with bristle_stiffness \
         sigma0, bristle_damping sqrt(sigma0 m_s), viscous_friction 0, stribeck_velocity \
         {LIMIT_STRIBECK:e} m/s, against Karnopp's friction (docs/model.md section 3, the default \
         band), both at the scene's tolerance. Difference: the largest |LuGre - Karnopp| over \
         instances and axes [um per own cycle].\n\n\
         | sigma0 [N/m] | instance 0 step_x [um] | Karnopp's [um] | largest difference [um] | \
         wall [s] | failed |\n|---|---|---|---|---|---|\n"
    );
    for row in rows {
        let _ = writeln!(
            md,
            "| {:.0e} | {:+.6} | {:+.6} | {:.2e} | {:.4} | {} |",
            row.bristle_stiffness,
            row.steps_um.first().map_or(f64::NAN, |s| s[0]),
            karnopp.first().map_or(f64::NAN, |s| s[0]),
            row.max_difference_um,
            row.wall_s,
            row.failed
        );
    }
    md.push('\n');
    md
}

/// Draws the largest difference against sigma0, log-log.
pub fn plot_limit(path: &Path, title: &str, rows: &[LimitRow]) -> Result<()> {
    let floor = 1e-6;
    let top = rows
        .iter()
        .map(|r| r.max_difference_um)
        .fold(floor, f64::max);
    let (left, right) = (LIMIT_STIFFNESS[0] * 0.5, LIMIT_STIFFNESS[3] * 2.0);
    let axes = LogLog {
        title,
        x: left..right,
        y: floor..top * 3.0,
        x_desc: "bristle stiffness sigma0 [N/m]",
        y_desc: "largest |LuGre - Karnopp| step [um]",
        legend: false,
    };
    log_log_png(path, &axes, |chart| {
        let series: Vec<(f64, f64)> = rows
            .iter()
            .map(|r| (r.bristle_stiffness, r.max_difference_um.max(floor)))
            .collect();
        let color = Palette99::pick(0).to_rgba();
        chart.draw_series(LineSeries::new(series.clone(), color.stroke_width(2)))?;
        chart.draw_series(
            series
                .iter()
                .map(|&(x, y)| Circle::new((x, y), 4, color.filled())),
        )?;
        chart.draw_series(LineSeries::new(
            vec![(left, 0.01), (right, 0.01)],
            BLACK.mix(0.3),
        ))?;
        Ok(())
    })
}
