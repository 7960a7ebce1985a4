//! The figure of one stored trajectory: stage and slider displacement
//! against time per axis, a zoom on one fast fall, and the slider's path in
//! the x-y plane, like the paper's Figs. 5-8.

use std::path::{Path, PathBuf};

use anyhow::Result;
use plotters::prelude::*;

use super::canvas::{Area, font, save, title_block};
use super::colour::{BASELINE_GREY, SETTLE_GREY, X_COLOUR, Y_COLOUR, axis_colour, light};
use super::read::Data;
use super::read_trajectories::{RunData, TrajectoryData};
use super::text::{short, slug};
use crate::model::AXIS_NAMES;

/// A legend mark of a trajectory figure.
enum Mark {
    /// A line: colour, width, dashed.
    Line(RGBColor, u32, bool),
    Dot(RGBColor),
    Band(RGBColor),
}

/// Draws the manual legend of a trajectory figure at `(x, y)` of `area`.
fn trajectory_legend(area: &Area<'_>, x: i32, y: i32, baselines: bool) -> Result<()> {
    let mut rows = vec![
        (
            Mark::Line(X_COLOUR, 2, false),
            "slider along x (2-DOF: both axes driven)",
        ),
        (Mark::Line(Y_COLOUR, 2, false), "slider along y (2-DOF)"),
        (
            Mark::Line(light(X_COLOUR, 0.55), 1, true),
            "stage (2-DOF), dashed; the slider rides on it while stuck",
        ),
    ];
    if baselines {
        rows.push((
            Mark::Line(BASELINE_GREY, 2, false),
            "1-DOF slider: that axis driven alone (grey)",
        ));
        rows.push((
            Mark::Line(BASELINE_GREY, 1, true),
            "1-DOF stage (grey, dashed)",
        ));
    }
    rows.push((
        Mark::Dot(X_COLOUR),
        "slider at the end of each scene period",
    ));
    rows.push((
        Mark::Band(SETTLE_GREY),
        "settle periods (discarded before measuring)",
    ));
    for (k, (mark, text)) in rows.iter().enumerate() {
        let y = y + 24 * k as i32;
        match *mark {
            Mark::Line(colour, width, true) => {
                for d in 0..3 {
                    area.draw(&PathElement::new(
                        vec![(x + 9 * d, y + 8), (x + 9 * d + 5, y + 8)],
                        colour.stroke_width(width),
                    ))?;
                }
            }
            Mark::Line(colour, width, false) => {
                area.draw(&PathElement::new(
                    vec![(x, y + 8), (x + 24, y + 8)],
                    colour.stroke_width(width),
                ))?;
            }
            Mark::Dot(colour) => area.draw(&Circle::new((x + 12, y + 8), 4, colour.filled()))?,
            Mark::Band(colour) => {
                area.draw(&Rectangle::new([(x, y), (x + 24, y + 16)], colour.filled()))?
            }
        }
        area.draw_text(text, &font(14), (x + 34, y + 1))?;
    }
    Ok(())
}

/// An axis range [um] that covers zero and `values`, padded by 5 %; at
/// least +-1 um around values that all lie within 1 nm (an axis at rest).
fn covering_range<'a>(values: impl Iterator<Item = &'a f64>) -> std::ops::Range<f64> {
    let (lo, hi) = values.fold((0.0f64, 0.0f64), |(l, h), &v| (l.min(v), h.max(v)));
    if hi - lo < 1e-3 {
        return (lo - 1.0)..(hi + 1.0);
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad)..(hi + pad)
}

/// Writes the figure of one trajectory: displacement against time per
/// axis, a zoom on one fast fall, and the slider path in the x-y plane.
pub(super) fn trajectory_figure(
    data: &Data,
    k: usize,
    t: &TrajectoryData,
    dir: &Path,
) -> Result<PathBuf> {
    let name = if t.label.is_empty() {
        format!("instance_{}", t.index)
    } else {
        slug(&t.label)
    };
    let path = dir.join(format!("trajectory_{name}.png"));
    let run = &t.run;
    let time_ms = to_ms(&run.time);
    let title = trajectory_title(data, k, t);
    let size = (1600u32, 1120u32);
    let title_height = 110;
    save(&path, size, |root| {
        let body = title_block(root, &title)?;
        let (left, right) = body.split_horizontally(1000);
        let (top, bottom) = left.split_vertically((size.1 - title_height) / 2);
        let t_end = time_ms.last().copied().unwrap_or(1.0);
        for (a, area) in [(0usize, &top), (1usize, &bottom)] {
            displacement_panel(area, t, a, &time_ms, t_end)?;
        }

        let (path_area, rest) = right.split_vertically(500);
        let (zoom_area, legend_area) = rest.split_vertically(290);
        slider_path_panel(&path_area, run)?;
        fall_zoom_panel(&zoom_area, run, &time_ms, t_end)?;
        trajectory_legend(&legend_area, 20, 10, t.baselines.is_some())?;
        Ok(())
    })?;
    Ok(path)
}

/// Times [s] in ms.
fn to_ms(time: &[f64]) -> Vec<f64> {
    time.iter().map(|s| s * 1e3).collect::<Vec<f64>>()
}

/// Displacements [m] in µm.
fn to_um(v: &[f64]) -> Vec<f64> {
    v.iter().map(|x| x * 1e6).collect::<Vec<f64>>()
}

/// The drive of axis `a` of `run` in words: "x: 100 V, 10 Hz, duty 0.98"
/// (and the phase where it is not 0), or "x: undriven".
fn describe_drive(run: &RunData, a: usize) -> String {
    if run.voltage[a] == 0.0 {
        format!("{}: undriven", AXIS_NAMES[a])
    } else {
        format!(
            "{}: {} V, {} Hz, duty {}{}",
            AXIS_NAMES[a],
            short(run.voltage[a]),
            short(run.frequency[a]),
            short(run.duty[a]),
            if run.phase[a] != 0.0 {
                format!(", phase {} cycles", short(run.phase[a]))
            } else {
                String::new()
            }
        )
    }
}

/// The title lines of the figure of trajectory `k`, `t`: the point, its
/// drive, its steps (and the 1-DOF ones) and an early end.
fn trajectory_title(data: &Data, k: usize, t: &TrajectoryData) -> Vec<String> {
    let run = &t.run;
    let fmt_step = |s: Option<f64>| s.map_or("n/a".to_owned(), |v| format!("{v:+.4} µm"));
    let mut steps_line = format!(
        "step per own drive cycle (after the settle periods): x {}, y {}",
        fmt_step(run.step_um(0)),
        fmt_step(run.step_um(1))
    );
    if let Some(b) = &t.baselines {
        steps_line.push_str(&format!(
            "; 1-DOF, each axis driven alone: x {}, y {}",
            fmt_step(b[0].step_um(0)),
            fmt_step(b[1].step_um(1))
        ));
    }
    let mut title = vec![
        format!(
            "{}: {} (trajectory {k}), stage and slider over the whole run",
            data.name, t.point
        ),
        format!(
            "drive {}; {}. Displacements from rest at t = 0.",
            describe_drive(run, 0),
            describe_drive(run, 1)
        ),
        steps_line,
    ];
    if run.status != 0 {
        title.push(format!(
            "the run ended early with status {} (docs/output.md: status codes); the curves stop there",
            run.status
        ));
    }
    title
}

/// Draws the stage and slider displacement along axis `a` [µm] against
/// time [ms] (`time_ms`, up to `t_end`) on `area`: the settle periods, the
/// 1-DOF run when stored, and the slider at the end of every scene period.
fn displacement_panel(
    area: &Area<'_>,
    t: &TrajectoryData,
    a: usize,
    time_ms: &[f64],
    t_end: f64,
) -> Result<()> {
    let run = &t.run;
    let settle_ms = run.settle_s * 1e3;
    let stage = to_um(&run.stage[a]);
    let slider = to_um(&run.slider[a]);
    let base = t.baselines.as_ref().map(|b| {
        (
            to_ms(&b[a].time),
            to_um(&b[a].stage[a]),
            to_um(&b[a].slider[a]),
        )
    });
    let all = stage
        .iter()
        .chain(&slider)
        .chain(base.iter().flat_map(|b| b.1.iter().chain(&b.2)));
    let y_range = covering_range(all);
    let mut chart = ChartBuilder::on(area)
        .margin(12)
        .x_label_area_size(50)
        .y_label_area_size(75)
        .build_cartesian_2d(0.0..t_end, y_range.clone())?;
    chart
        .configure_mesh()
        .x_desc("time [ms]")
        .y_desc(format!("displacement along {} [µm]", AXIS_NAMES[a]))
        .x_label_formatter(&|v| short(*v))
        .y_label_formatter(&|v| short(*v))
        .label_style(font(14))
        .axis_desc_style(font(16))
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    if settle_ms > 0.0 {
        chart.draw_series(std::iter::once(Rectangle::new(
            [(0.0, y_range.start), (settle_ms, y_range.end)],
            SETTLE_GREY.filled(),
        )))?;
    }
    if let Some((bt, bs, bl)) = &base {
        chart.draw_series(DashedLineSeries::new(
            bt.iter().copied().zip(bs.iter().copied()),
            6,
            4,
            BASELINE_GREY.stroke_width(1),
        ))?;
        chart.draw_series(LineSeries::new(
            bt.iter().copied().zip(bl.iter().copied()),
            BASELINE_GREY.stroke_width(2),
        ))?;
    }
    let colour = axis_colour(a);
    chart.draw_series(DashedLineSeries::new(
        time_ms.iter().copied().zip(stage.iter().copied()),
        6,
        4,
        light(colour, 0.55).stroke_width(1),
    ))?;
    chart.draw_series(LineSeries::new(
        time_ms.iter().copied().zip(slider.iter().copied()),
        colour.stroke_width(2),
    ))?;
    // The slider at the end of every scene period: its stepping.
    if run.period_s > 0.0 && run.time.len() > 1 {
        let per = ((run.period_s / (run.time[1] - run.time[0])).round() as usize).max(1);
        chart.draw_series(
            (0..time_ms.len())
                .step_by(per)
                .map(|i| Circle::new((time_ms[i], slider[i]), 4, colour.filled())),
        )?;
    }
    Ok(())
}

/// Draws the slider path of `run` in the x-y plane [µm] on `area`, on
/// equal scales, with its start and end marked.
fn slider_path_panel(area: &Area<'_>, run: &RunData) -> Result<()> {
    let xs = to_um(&run.slider[0]);
    let ys = to_um(&run.slider[1]);
    let range = covering_range(xs.iter().chain(&ys));
    let mut chart = ChartBuilder::on(area)
        .caption("slider path in the x-y plane (2-DOF)", font(17))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(range.clone(), range)?;
    chart
        .configure_mesh()
        .x_desc("slider x [µm]")
        .y_desc("slider y [µm]")
        .x_label_formatter(&|v| short(*v))
        .y_label_formatter(&|v| short(*v))
        .label_style(font(14))
        .axis_desc_style(font(16))
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    let purple = RGBColor(118, 42, 131);
    chart.draw_series(LineSeries::new(
        xs.iter().copied().zip(ys.iter().copied()),
        purple.stroke_width(1),
    ))?;
    let end = xs.len() - 1;
    chart
        .draw_series(std::iter::once(Circle::new(
            (xs[0], ys[0]),
            6,
            BLACK.filled(),
        )))?
        .label("start")
        .legend(|(x, y)| Circle::new((x + 9, y), 5, BLACK.filled()));
    chart
        .draw_series(std::iter::once(TriangleMarker::new(
            (xs[end], ys[end]),
            8,
            purple.filled(),
        )))?
        .label("end")
        .legend(move |(x, y)| TriangleMarker::new((x + 9, y), 6, purple.filled()));
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.4))
        .label_font(font(13))
        .draw()?;
    Ok(())
}

/// Draws on `area` a zoom on the fast fall that ends the second-to-last
/// period of `run` (stage and slider, both axes [µm], against time [ms]:
/// `time_ms`, up to `t_end`); nothing when fewer than two samples fall in
/// the window.
fn fall_zoom_panel(area: &Area<'_>, run: &RunData, time_ms: &[f64], t_end: f64) -> Result<()> {
    let fall_ms = (0..2)
        .filter(|&a| run.voltage[a] != 0.0 && run.frequency[a] > 0.0)
        .map(|a| (1.0 - run.duty[a]) / run.frequency[a] * 1e3)
        .fold(0.0f64, f64::max)
        .max(run.period_s * 10.0);
    let centre = t_end - run.period_s * 1e3;
    let (z0, z1) = (
        (centre - 2.0 * fall_ms).max(0.0),
        (centre + 4.0 * fall_ms).min(t_end),
    );
    let window: Vec<usize> = (0..time_ms.len())
        .filter(|&i| time_ms[i] >= z0 && time_ms[i] <= z1)
        .collect();
    if window.len() < 2 {
        return Ok(());
    }
    let values: Vec<f64> = window
        .iter()
        .flat_map(|&i| {
            [
                run.stage[0][i],
                run.stage[1][i],
                run.slider[0][i],
                run.slider[1][i],
            ]
        })
        .map(|v| v * 1e6)
        .collect();
    let y_range = covering_range(values.iter());
    let mut chart = ChartBuilder::on(area)
        .caption(
            format!(
                "zoom: around the period end at {} ms (2-DOF)",
                short(centre)
            ),
            font(16),
        )
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(z0..z1, y_range)?;
    chart
        .configure_mesh()
        .x_desc("time [ms]")
        .y_desc("displacement [µm]")
        .x_label_formatter(&|v| short(*v))
        .y_label_formatter(&|v| short(*v))
        .label_style(font(13))
        .axis_desc_style(font(15))
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    for a in 0..2 {
        let colour = axis_colour(a);
        chart.draw_series(DashedLineSeries::new(
            window.iter().map(|&i| (time_ms[i], run.stage[a][i] * 1e6)),
            6,
            4,
            light(colour, 0.55).stroke_width(1),
        ))?;
        chart.draw_series(LineSeries::new(
            window.iter().map(|&i| (time_ms[i], run.slider[a][i] * 1e6)),
            colour.stroke_width(2),
        ))?;
    }
    Ok(())
}
