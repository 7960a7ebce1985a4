//! `SENS.png` of `pidm sensitivity`: the Sobol' indices of each output
//! quantity per input key, first order and total side by side, each with
//! its bootstrap 95 % interval. The analysis hands over plain numbers
//! ([`IndexPanel`]); this module only draws.

use std::path::Path;

use anyhow::Result;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::canvas::{Area, font, save, swatch, title_block};
use super::colour::X_COLOUR;

/// One panel: one output quantity's Sobol' indices per input key.
pub struct IndexPanel {
    /// The output quantity with its unit, e.g. "step_x [m]".
    pub title: String,
    /// The input keys, e.g. "mechanism.static_friction".
    pub keys: Vec<String>,
    /// First-order index S1 per key [1]: the share of the output's
    /// variance due to the key alone.
    pub first: Vec<f64>,
    /// Bootstrap 95 % half-width of each S1 [1].
    pub first_conf: Vec<f64>,
    /// Total index ST per key [1]: the share due to the key with all its
    /// interactions.
    pub total: Vec<f64>,
    /// Bootstrap 95 % half-width of each ST [1].
    pub total_conf: Vec<f64>,
    /// Drawn instead of the bars when there are no indices (e.g. "the
    /// output does not vary: no index is defined"); with indices, a small
    /// line under the caption.
    pub note: Option<String>,
}

/// Colour of the first-order bars: the blue of the other pictures.
const FIRST_COLOUR: RGBColor = X_COLOUR;
/// Colour of the total bars: an orange that stays apart from the blue for
/// colour-blind readers too.
const TOTAL_COLOUR: RGBColor = RGBColor(230, 97, 1);
/// At most this many panels per row, so each stays wide enough for its keys.
const PER_ROW: usize = 3;
/// Size of one panel [px].
const PANEL: (u32, u32) = (900, 640);
/// Margin of each chart [px].
const MARGIN: u32 = 16;
/// Width of the y labels and description left of each chart [px].
const Y_LABELS: u32 = 80;

/// A panel's chart: keys across (key k spans k..k+1), indices [1] up.
type IndexChart<'a, 'b> =
    ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// One bar: key slot, whether it is the total index, value and half-width
/// (0 when not finite) [1].
type Bar = (usize, bool, f64, f64);

/// Draws `SENS.png` at `path`: a title block with the `title` lines, then
/// the panels in rows of at most [`PER_ROW`]; with no panels only the
/// title block.
pub fn sensitivity_figure(path: &Path, title: &[String], panels: &[IndexPanel]) -> Result<()> {
    let columns = panels.len().clamp(1, PER_ROW);
    let rows = panels.len().div_ceil(PER_ROW);
    let head = 60 + 22 * title.len() as u32;
    let size = (PANEL.0 * columns as u32, head + PANEL.1 * rows as u32);
    save(path, size, |root| {
        let body = title_block(root, title)?;
        if rows == 0 {
            return Ok(());
        }
        for (area, panel) in body.split_evenly((rows, columns)).iter().zip(panels) {
            draw_panel(area, panel)?;
        }
        Ok(())
    })
}

/// The finite bars of `panel`, S1 before ST per key; a missing entry (the
/// lists shorter than the keys) counts as not finite.
fn bars_of(panel: &IndexPanel) -> Vec<Bar> {
    let at = |v: &[f64], k: usize| v.get(k).copied().unwrap_or(f64::NAN);
    let mut bars = Vec::new();
    for k in 0..panel.keys.len() {
        for (total, values, conf) in [
            (false, &panel.first, &panel.first_conf),
            (true, &panel.total, &panel.total_conf),
        ] {
            let (v, c) = (at(values, k), at(conf, k));
            if v.is_finite() {
                bars.push((k, total, v, if c.is_finite() { c.abs() } else { 0.0 }));
            }
        }
    }
    bars
}

/// The y range [1]: from min(0, lowest value - half-width) to max(1,
/// highest value + half-width), so noise below 0 or above 1 shows as is.
fn y_range(bars: &[Bar]) -> (f64, f64) {
    bars.iter()
        .fold((0.0f64, 1.0f64), |(lo, hi), &(_, _, v, c)| {
            (lo.min(v - c), hi.max(v + c))
        })
}

/// A key as its x label: without a leading "mechanism." or "axis.", which
/// most keys share and which only take room.
fn short_key(key: &str) -> &str {
    ["mechanism.", "axis."]
        .iter()
        .find_map(|p| key.strip_prefix(p))
        .unwrap_or(key)
}

/// Draws one panel in `area`: the caption, legend and note on top, then
/// the bars, or only the note when there are no finite indices.
fn draw_panel(area: &Area<'_>, panel: &IndexPanel) -> Result<()> {
    let bars = bars_of(panel);
    let (w, h) = area.dim_in_pixel();
    let centred = |size| font(size).pos(Pos::new(HPos::Center, VPos::Top));
    let note_line = panel.note.as_deref().filter(|_| !bars.is_empty());
    let (top, rest) = area.split_vertically(if note_line.is_some() { 86 } else { 64 });
    top.draw_text(&panel.title, &centred(18), (w as i32 / 2, 8))?;
    if let Some(note) = note_line {
        top.draw_text(note, &centred(13), (w as i32 / 2, 64))?;
    }
    if let (true, Some(note)) = (bars.is_empty(), &panel.note) {
        rest.draw_text(note, &centred(16), (w as i32 / 2, (h as i32 - 64) / 2))?;
        return Ok(());
    }
    let x = (MARGIN + Y_LABELS) as i32;
    swatch(&top, x, 36, FIRST_COLOUR, "first order S1")?;
    swatch(&top, x + 180, 36, TOTAL_COLOUR, "total ST")?;
    draw_chart(&rest, panel, &bars)
}

/// Draws the chart of `panel`'s `bars` in `area`, with the keys under it,
/// turned upright when they do not fit side by side.
fn draw_chart(area: &Area<'_>, panel: &IndexPanel, bars: &[Bar]) -> Result<()> {
    let n = panel.keys.len().max(1);
    let labels: Vec<&str> = panel.keys.iter().map(|k| short_key(k)).collect();
    let style = font(13);
    let mut longest = 0;
    for label in &labels {
        longest = longest.max(area.estimate_text_size(label, &style)?.0);
    }
    let slot = area.dim_in_pixel().0.saturating_sub(2 * MARGIN + Y_LABELS) / n as u32;
    let upright = longest + 8 > slot;
    let label_area = if upright { longest + 16 } else { 30 };
    let (lo, hi) = y_range(bars);
    let mut chart = ChartBuilder::on(area)
        .margin(MARGIN)
        .x_label_area_size(label_area.min(PANEL.1 / 2))
        .y_label_area_size(Y_LABELS)
        .build_cartesian_2d(0.0..n as f64, lo..hi)?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .disable_x_axis()
        .y_desc("Sobol' index")
        .label_style(font(14))
        .axis_desc_style(font(16))
        .draw()?;
    chart.draw_series(LineSeries::new([(0.0, 0.0), (n as f64, 0.0)], &BLACK))?;
    for &bar in bars {
        draw_bar(&mut chart, bar)?;
    }
    key_labels(area, &chart, &labels, upright, lo)
}

/// Draws one bar with its error bar of ± its half-width.
fn draw_bar(chart: &mut IndexChart<'_, '_>, (k, total, v, c): Bar) -> Result<()> {
    let x0 = k as f64 + if total { 0.52 } else { 0.12 };
    let x1 = x0 + 0.36;
    let colour = if total { TOTAL_COLOUR } else { FIRST_COLOUR };
    chart.draw_series([Rectangle::new([(x0, 0.0), (x1, v)], colour.filled())])?;
    if c > 0.0 {
        let (mid, style) = (0.5 * (x0 + x1), BLACK.stroke_width(1));
        chart.draw_series([ErrorBar::new_vertical(mid, v - c, v, v + c, style, 10)])?;
    }
    Ok(())
}

/// Writes each key's label in `area` under the chart's bottom `bottom`
/// [1], upright (reading downwards) when `upright`.
fn key_labels(
    area: &Area<'_>,
    chart: &IndexChart<'_, '_>,
    labels: &[&str],
    upright: bool,
    bottom: f64,
) -> Result<()> {
    let base = area.get_base_pixel();
    let style = if upright {
        font(13)
            .transform(FontTransform::Rotate90)
            .pos(Pos::new(HPos::Left, VPos::Center))
    } else {
        font(13).pos(Pos::new(HPos::Center, VPos::Top))
    };
    for (k, label) in labels.iter().enumerate() {
        let (px, py) = chart.backend_coord(&(k as f64 + 0.5, bottom));
        area.draw_text(label, &style, (px - base.0, py - base.1 + 8))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A panel with indices (one of them not finite, one above 1, one
    /// below 0) and a panel with only a note both draw.
    #[test]
    fn draws_a_figure_with_indices_and_a_note() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("SENS.png");
        let keys = ["mechanism.static_friction", "axis.x.voltage", "slider_mass"];
        let panels = [
            IndexPanel {
                title: "step_x [m]".to_owned(),
                keys: keys.iter().map(|k| k.to_string()).collect(),
                first: vec![0.62, -0.03, f64::NAN],
                first_conf: vec![0.05, 0.04, 0.02],
                total: vec![1.04, 0.12, 0.2],
                total_conf: vec![0.08, f64::INFINITY, 0.03],
                note: Some("2048 samples".to_owned()),
            },
            IndexPanel {
                title: "step_y [m]".to_owned(),
                keys: keys.iter().map(|k| k.to_string()).collect(),
                first: vec![],
                first_conf: vec![],
                total: vec![],
                total_conf: vec![],
                note: Some("the output does not vary: no index is defined".to_owned()),
            },
        ];
        let title = ["Sobol' indices".to_owned(), "second line".to_owned()];
        sensitivity_figure(&path, &title, &panels).unwrap();
        assert!(std::fs::metadata(&path).unwrap().len() > 0);
        let empty = dir.path().join("EMPTY.png");
        sensitivity_figure(&empty, &title, &[]).unwrap();
        assert!(std::fs::metadata(&empty).unwrap().len() > 0);
    }
}
