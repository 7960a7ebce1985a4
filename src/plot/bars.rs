//! The bar chart of a points scene (or of a single instance): the steps
//! per point, with the baselines beside them, and under each label its kind
//! of motion when the file has one.

use std::path::{Path, PathBuf};

use anyhow::Result;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::canvas::{Area, LEGEND_WIDTH, font, save, swatch, title_block};
use super::colour::{FAILED, X_COLOUR, Y_COLOUR, axis_colour, light};
use super::read::Data;
use super::text::short;
use crate::model::motion::Motion;

/// One bar of the chart.
pub(super) struct Bar {
    /// The point's index.
    pub(super) point: usize,
    /// The axis the value is along (0 = x).
    pub(super) axis: usize,
    /// Whether the value is the 1-DOF baseline's (drawn light).
    pub(super) baseline: bool,
    /// The value in the chart's units (a step in µm per own drive cycle).
    pub(super) value: f64,
    /// Whether its run has a value (else a grey stub).
    pub(super) ok: bool,
}

/// A bar chart of one quantity per point: its file, title, y axis, bars
/// (`per` of them a point, in slot order) and legend.
pub(super) struct Bars {
    pub(super) file: &'static str,
    pub(super) title: Vec<String>,
    pub(super) y_desc: String,
    pub(super) bars: Vec<Bar>,
    pub(super) per: usize,
    pub(super) legend: Vec<(RGBColor, String)>,
}

/// The chart of the bars: points across, steps [µm per own drive cycle] up.
type BarChart<'a, 'b> =
    ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Writes the bar chart of a points scene (or of a single instance).
pub(super) fn point_bars(
    data: &Data,
    labels: &[String],
    dir: &Path,
    files: &mut Vec<PathBuf>,
) -> Result<()> {
    let n = labels.len();
    let failed = (0..n).filter(|&k| data.status[k] != 0).count();
    let chart = Bars {
        file: "steps.png",
        title: bars_title(data, failed, data.motion_shown().is_some()),
        y_desc: "step [µm per own drive cycle]".to_owned(),
        bars: bars_of(data, n),
        per: if data.baseline.is_some() { 4 } else { 2 },
        legend: bars_legend(data.baseline.is_some(), failed),
    };
    draw_bars(data, labels, dir, files, &chart)
}

/// Draws `chart` into its file in `dir`, one slot per point of `labels`
/// with its label (and kind of motion, where the file shows them) under
/// it, adding the file to `files`.
pub(super) fn draw_bars(
    data: &Data,
    labels: &[String],
    dir: &Path,
    files: &mut Vec<PathBuf>,
    chart: &Bars,
) -> Result<()> {
    let n = labels.len();
    let values: Vec<f64> = chart
        .bars
        .iter()
        .filter(|b| b.ok)
        .map(|b| b.value)
        .collect();
    let hi = values.iter().copied().fold(0.0f64, f64::max);
    let lo = values.iter().copied().fold(0.0f64, f64::min);
    let pad = 0.15 * (hi - lo).max(1e-6);
    let motion = data.motion_shown();
    let width = (1100u32).max(220 * n as u32 + LEGEND_WIDTH + 120).min(4000);
    let path = dir.join(chart.file);
    save(&path, (width, 760), |root| {
        let body = title_block(root, &chart.title)?;
        let (left, right) = body.split_horizontally(width - LEGEND_WIDTH);
        let mut plot = ChartBuilder::on(&left)
            .margin(15)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d(0.0..n as f64, (lo - pad)..(hi + pad))?;
        plot.configure_mesh()
            .disable_x_mesh()
            .disable_x_axis()
            .y_desc(chart.y_desc.as_str())
            .y_label_formatter(&|v| short(*v))
            .label_style(font(15))
            .axis_desc_style(font(17))
            .draw()?;
        plot.draw_series(LineSeries::new(
            vec![(0.0, 0.0), (n as f64, 0.0)],
            BLACK.stroke_width(1),
        ))?;
        let slot = 0.8 / chart.per as f64;
        let stub = 0.04 * (hi - lo).max(1e-6);
        for (m, bar) in chart.bars.iter().enumerate() {
            draw_bar(
                root,
                &mut plot,
                bar,
                slot * (m % chart.per) as f64,
                slot,
                stub,
            )?;
        }
        point_labels(root, &plot, labels, motion, lo - pad)?;
        for (k, (c, text)) in chart.legend.iter().enumerate() {
            swatch(&right, 0, 30 + 30 * k as i32, *c, text)?;
        }
        Ok(())
    })?;
    files.push(path);
    Ok(())
}

/// The bars of the first `n` points, per point: 2-DOF x, 1-DOF x, 2-DOF
/// y, 1-DOF y (the 1-DOF ones only with baselines).
fn bars_of(data: &Data, n: usize) -> Vec<Bar> {
    let mut bars = Vec::new();
    for k in 0..n {
        for a in 0..2 {
            bars.push(Bar {
                point: k,
                axis: a,
                baseline: false,
                value: data.step[a][k] * 1e6,
                ok: data.status[k] == 0,
            });
            if let Some((b, bs)) = &data.baseline {
                bars.push(Bar {
                    point: k,
                    axis: a,
                    baseline: true,
                    value: b[a][k] * 1e6,
                    ok: bs[k] == 0,
                });
            }
        }
    }
    bars
}

/// The title lines of the bar chart, `failed` the number of points with
/// a non-zero status, `motion` whether the kinds of motion are shown.
fn bars_title(data: &Data, failed: usize, motion: bool) -> Vec<String> {
    let mut title = vec![
        format!(
            "{}: slider step per own drive cycle at each point",
            data.name
        ),
        "above zero: moves towards +x (+y); below zero: towards -x (-y)".to_owned(),
    ];
    if failed > 0 {
        title.push(format!(
            "{failed} points ended with a non-zero status: drawn as grey stubs, no value"
        ));
    }
    if motion {
        title.push(
            "under each label: the kind of motion the steady measurement found (/maps/motion)"
                .to_owned(),
        );
    }
    title
}

/// Draws `bar` in `chart`, `offset` right of its point's slot start and
/// `slot` wide (both in points), with its value written over (or under)
/// it on `root`; a failed run's bar is a grey stub `stub` high [µm].
fn draw_bar(
    root: &Area<'_>,
    chart: &mut BarChart<'_, '_>,
    bar: &Bar,
    offset: f64,
    slot: f64,
    stub: f64,
) -> Result<()> {
    let (a, value, ok) = (bar.axis, bar.value, bar.ok);
    let x0 = bar.point as f64 + 0.1 + offset;
    let x1 = x0 + slot * 0.9;
    let colour = if !ok {
        FAILED
    } else if bar.baseline {
        light(axis_colour(a), 0.35)
    } else {
        axis_colour(a)
    };
    let v = if ok { value } else { stub };
    chart.draw_series(std::iter::once(Rectangle::new(
        [(x0, 0.0), (x1, v)],
        colour.filled(),
    )))?;
    if bar.baseline {
        chart.draw_series(std::iter::once(Rectangle::new(
            [(x0, 0.0), (x1, v)],
            axis_colour(a).stroke_width(1),
        )))?;
    }
    if ok {
        let (px, py) = chart.backend_coord(&(0.5 * (x0 + x1), value));
        let (anchor, dy) = if value >= 0.0 {
            (VPos::Bottom, -3)
        } else {
            (VPos::Top, 3)
        };
        root.draw_text(
            &format!("{value:.3}"),
            &font(12).pos(Pos::new(HPos::Center, anchor)),
            (px, py + dy),
        )?;
    }
    Ok(())
}

/// Writes each point's label on `root` under the chart's bottom `bottom`
/// [µm], and under it the point's kind of motion when `motion` is given.
fn point_labels(
    root: &Area<'_>,
    chart: &BarChart<'_, '_>,
    labels: &[String],
    motion: Option<&[Motion]>,
    bottom: f64,
) -> Result<()> {
    for (k, label) in labels.iter().enumerate() {
        let (px, py) = chart.backend_coord(&(k as f64 + 0.5, bottom));
        root.draw_text(
            label,
            &font(16).pos(Pos::new(HPos::Center, VPos::Top)),
            (px, py + 8),
        )?;
        if let Some(motion) = motion {
            root.draw_text(
                motion[k].name(),
                &font(14).pos(Pos::new(HPos::Center, VPos::Top)),
                (px, py + 28),
            )?;
        }
    }
    Ok(())
}

/// The legend of the step bars: the 2-DOF bars, the 1-DOF ones with
/// `baselines`, and the failed stubs when `failed` is above 0.
fn bars_legend(baselines: bool, failed: usize) -> Vec<(RGBColor, String)> {
    let mut items = vec![
        (X_COLOUR, "2-DOF step along x".to_owned()),
        (Y_COLOUR, "2-DOF step along y".to_owned()),
    ];
    if baselines {
        items.insert(
            1,
            (
                light(X_COLOUR, 0.35),
                "1-DOF along x (x driven alone)".to_owned(),
            ),
        );
        items.push((
            light(Y_COLOUR, 0.35),
            "1-DOF along y (y driven alone)".to_owned(),
        ));
    }
    if failed > 0 {
        items.push((FAILED, "not computed (status ≠ 0)".to_owned()));
    }
    items
}
