//! `FIT.png` of `pidm fit`: the measured steps with their error bars
//! against the fitted model's curves, one panel per measured axis, and the
//! normalized residuals; below them, the profile of each free key. The fit
//! hands over plain numbers ([`FitPanel`]); this module only draws.

use std::path::Path;

use anyhow::Result;
use plotters::prelude::*;

use super::canvas::{font, save, title_block};

/// One panel: the steps of one axis against one key.
pub struct FitPanel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<FitSeries>,
}

/// The data and the model's curve of one group of rows (the rows that
/// share every key but the panel's).
pub struct FitSeries {
    pub label: String,
    /// Measured points: (x, y, standard error of y).
    pub points: Vec<(f64, f64, f64)>,
    /// The fitted model: (x, y), drawn as a line.
    pub curve: Vec<(f64, f64)>,
}

/// Colours of the series, in turn.
const COLOURS: [RGBColor; 6] = [
    RGBColor(33, 102, 172),
    RGBColor(178, 24, 43),
    RGBColor(27, 120, 55),
    RGBColor(118, 42, 131),
    RGBColor(230, 97, 1),
    RGBColor(1, 133, 113),
];

/// Draws `FIT.png` at `path`: a title block, then the panels side by side,
/// and `below` (the profiles, when there are any) in a second row.
pub fn fit_figure(
    path: &Path,
    title: &[String],
    panels: &[FitPanel],
    below: &[FitPanel],
) -> Result<()> {
    let columns = panels.len().max(below.len()).max(1);
    let height = if below.is_empty() { 760 } else { 1360 };
    save(path, (900 * columns as u32, height), |root| {
        let body = title_block(root, title)?;
        let rows: Vec<&[FitPanel]> = [panels, below]
            .into_iter()
            .filter(|r| !r.is_empty())
            .collect();
        let bands = body.split_evenly((rows.len().max(1), 1));
        for (band, row) in bands.iter().zip(rows) {
            let areas = band.split_evenly((1, columns));
            for (area, panel) in areas.iter().zip(row) {
                draw_panel(area, panel)?;
            }
        }
        Ok(())
    })
}

/// The range of some values, widened by 5 % (or by 1 when flat).
fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = if hi > lo {
        0.05 * (hi - lo)
    } else {
        1.0f64.max(lo.abs() * 0.1)
    };
    (lo - pad, hi + pad)
}

fn draw_panel(area: &super::canvas::Area<'_>, panel: &FitPanel) -> Result<()> {
    let xs = panel.series.iter().flat_map(|s| {
        s.points
            .iter()
            .map(|p| p.0)
            .chain(s.curve.iter().map(|c| c.0))
    });
    let ys = panel.series.iter().flat_map(|s| {
        s.points
            .iter()
            .flat_map(|p| [p.1 - p.2, p.1 + p.2])
            .chain(s.curve.iter().map(|c| c.1))
    });
    let (x_lo, x_hi) = range(xs);
    let (y_lo, y_hi) = range(ys);
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, font(18))
        .margin(16)
        .x_label_area_size(50)
        .y_label_area_size(80)
        .build_cartesian_2d(x_lo..x_hi, y_lo..y_hi)?;
    chart
        .configure_mesh()
        .x_desc(&panel.x_label)
        .y_desc(&panel.y_label)
        .label_style(font(14))
        .axis_desc_style(font(16))
        .draw()?;
    for (k, series) in panel.series.iter().enumerate() {
        let colour = COLOURS[k % COLOURS.len()];
        chart
            .draw_series(LineSeries::new(
                series.curve.iter().copied(),
                colour.stroke_width(2),
            ))?
            .label(&series.label)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], colour.stroke_width(2)));
        chart.draw_series(
            series
                .points
                .iter()
                .map(|&(x, y, e)| ErrorBar::new_vertical(x, y - e, y, y + e, colour.filled(), 8)),
        )?;
        chart.draw_series(
            series
                .points
                .iter()
                .map(|&(x, y, _)| Circle::new((x, y), 4, colour.filled())),
        )?;
    }
    chart
        .configure_series_labels()
        .label_font(font(14))
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}
