//! One heatmap picture: coloured cells over two grid axes, with a colour
//! bar or category swatches beside it.

use std::path::Path;

use anyhow::Result;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::canvas::{Area, LEGEND_WIDTH, font, save, swatch, title_block};
use super::colour::Diverging;
use super::placement::{Placement, label_values};
use super::read::AxisData;
use super::text::{axis_title, short};

/// Width and height of a map picture [px].
const MAP_SIZE: (u32, u32) = (1160, 860);

/// What the right-hand column of a map shows.
pub(super) enum MapLegend {
    /// A colour bar for a diverging scale, with its title, and extra
    /// swatches below it.
    Bar {
        scale: Diverging,
        title: String,
        swatches: Vec<(RGBColor, String)>,
    },
    /// Category swatches.
    Categories(Vec<(RGBColor, String)>),
}

/// The class of a cell for a contour: cells of different classes are
/// parted by a line; `None` (a cell without a value) is parted from none.
pub(super) type ContourClass<'a> = &'a dyn Fn(usize, usize) -> Option<i8>;

/// The cell edges between neighbouring cells of different classes, as
/// line segments in the chart's coordinates (`ex`, `ey`: the cell edges).
pub(super) fn contour_segments(
    class: ContourClass<'_>,
    ex: &[f64],
    ey: &[f64],
) -> Vec<[(f64, f64); 2]> {
    let (nx, ny) = (ex.len() - 1, ey.len() - 1);
    let mut segments = Vec::new();
    for i in 0..nx {
        for j in 0..ny {
            let Some(here) = class(i, j) else {
                continue;
            };
            if i + 1 < nx && class(i + 1, j).is_some_and(|c| c != here) {
                segments.push([(ex[i + 1], ey[j]), (ex[i + 1], ey[j + 1])]);
            }
            if j + 1 < ny && class(i, j + 1).is_some_and(|c| c != here) {
                segments.push([(ex[i], ey[j + 1]), (ex[i + 1], ey[j + 1])]);
            }
        }
    }
    segments
}

/// Draws one heatmap: `colour(i, j)` is the cell at value i of `across`
/// and value j of `up`.
pub(super) fn heatmap(
    path: &Path,
    title: &[String],
    across: &AxisData,
    up: &AxisData,
    colour: &dyn Fn(usize, usize) -> RGBColor,
    legend: &MapLegend,
) -> Result<()> {
    heatmap_contoured(path, title, across, up, colour, legend, None)
}

/// [`heatmap`], and with `contour` a black line parting neighbouring cells
/// of different classes.
pub(super) fn heatmap_contoured(
    path: &Path,
    title: &[String],
    across: &AxisData,
    up: &AxisData,
    colour: &dyn Fn(usize, usize) -> RGBColor,
    legend: &MapLegend,
    contour: Option<ContourClass<'_>>,
) -> Result<()> {
    save(path, MAP_SIZE, |root| {
        let body = title_block(root, title)?;
        let (left, right) = body.split_horizontally(MAP_SIZE.0 - LEGEND_WIDTH);
        let (px, py) = (Placement::of(&across.values), Placement::of(&up.values));
        let (ex, ey) = (px.edges(&across.values), py.edges(&up.values));
        let range = |e: &[f64]| {
            let lo = e.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = e.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            lo..hi
        };
        let mut chart = ChartBuilder::on(&left)
            .margin_left(10)
            .margin_right(20)
            .margin_top(10)
            .margin_bottom(10)
            .x_label_area_size(60)
            .y_label_area_size(80)
            .build_cartesian_2d(range(&ex), range(&ey))?;
        let fx = move |c: &f64| short(px.value(*c));
        let fy = move |c: &f64| short(py.value(*c));
        // A log-spaced axis is labelled at its own values: plotters would
        // pick round numbers of the logarithm.
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc(axis_title(&across.key, &across.units))
            .y_desc(axis_title(&up.key, &up.units))
            .x_labels(if px.log { 0 } else { 10 })
            .y_labels(if py.log { 0 } else { 10 })
            .x_label_formatter(&fx)
            .y_label_formatter(&fy)
            .label_style(font(15))
            .axis_desc_style(font(17))
            .draw()?;
        let (y_bottom, x_left) = (range(&ey).start, range(&ex).start);
        if px.log {
            for v in label_values(&across.values) {
                let (x, y) = chart.backend_coord(&(px.place(v), y_bottom));
                root.draw(&PathElement::new(vec![(x, y), (x, y + 5)], BLACK))?;
                root.draw_text(
                    &short(v),
                    &font(15).pos(Pos::new(HPos::Center, VPos::Top)),
                    (x, y + 8),
                )?;
            }
        }
        if py.log {
            for v in label_values(&up.values) {
                let (x, y) = chart.backend_coord(&(x_left, py.place(v)));
                root.draw(&PathElement::new(vec![(x - 5, y), (x, y)], BLACK))?;
                root.draw_text(
                    &short(v),
                    &font(15).pos(Pos::new(HPos::Right, VPos::Center)),
                    (x - 8, y),
                )?;
            }
        }
        let mut cells = Vec::with_capacity(across.values.len() * up.values.len());
        for i in 0..across.values.len() {
            for j in 0..up.values.len() {
                cells.push(Rectangle::new(
                    [(ex[i], ey[j]), (ex[i + 1], ey[j + 1])],
                    colour(i, j).filled(),
                ));
            }
        }
        chart.draw_series(cells)?;
        if let Some(class) = contour {
            chart.draw_series(
                contour_segments(class, &ex, &ey)
                    .into_iter()
                    .map(|[a, b]| PathElement::new(vec![a, b], BLACK.stroke_width(2))),
            )?;
        }
        match legend {
            MapLegend::Bar {
                scale,
                title,
                swatches,
            } => {
                let bar_height = right.dim_in_pixel().1 as i32 - 60 - 32 * swatches.len() as i32;
                let (bar_area, below) = right.split_vertically(bar_height.max(200));
                colour_bar(&bar_area, scale, title)?;
                for (k, (c, text)) in swatches.iter().enumerate() {
                    swatch(&below, 10, 10 + 30 * k as i32, *c, text)?;
                }
            }
            MapLegend::Categories(items) => {
                for (k, (c, text)) in items.iter().enumerate() {
                    swatch(&right, 0, 30 + 30 * k as i32, *c, text)?;
                }
            }
        }
        Ok(())
    })
}

/// A vertical colour bar of a diverging scale with value labels on its
/// right and the title beside them.
fn colour_bar(area: &Area<'_>, scale: &Diverging, title: &str) -> Result<()> {
    let (lo, hi) = scale.limits();
    let mut chart = ChartBuilder::on(area)
        .margin_top(20)
        .margin_bottom(20)
        .margin_left(20)
        .margin_right(150)
        .set_label_area_size(LabelAreaPosition::Right, 100)
        .build_cartesian_2d(0.0..1.0, lo..hi)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_desc(title)
        .y_labels(9)
        // A tick at the centre computed as lo + k step lands a rounding
        // away from it (-5.55e-17 N): label it as the centre.
        .y_label_formatter(&|v| {
            let centre = scale.centre;
            short(if (v - centre).abs() <= 1e-9 * (hi - lo) {
                centre
            } else {
                *v
            })
        })
        .label_style(font(14))
        .axis_desc_style(font(15))
        .draw()?;
    let n = 240;
    chart.draw_series((0..n).map(|k| {
        let a = lo + (hi - lo) * k as f64 / n as f64;
        let b = lo + (hi - lo) * (k + 1) as f64 / n as f64;
        Rectangle::new([(0.0, a), (1.0, b)], scale.colour(0.5 * (a + b)).filled())
    }))?;
    chart.draw_series(std::iter::once(Rectangle::new(
        [(0.0, lo), (1.0, hi)],
        BLACK.stroke_width(1),
    )))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 3 x 2 grid: + + 0 on the bottom row, - + (none) on the top: lines
    /// part the classes, never a cell without a value.
    #[test]
    fn the_contour_parts_cells_of_different_classes() {
        let classes = [[Some(1), Some(-1)], [Some(1), Some(1)], [Some(0), None]];
        let class = |i: usize, j: usize| classes[i][j];
        let (ex, ey) = ([0.0, 1.0, 2.0, 3.0], [0.0, 1.0, 2.0]);
        let mut segments = contour_segments(&class, &ex, &ey);
        segments.sort_by(|a, b| a.partial_cmp(b).unwrap());
        assert_eq!(
            segments,
            [
                // (0,0)+ | (0,1)- : the edge at y = 1 over x 0..1.
                [(0.0, 1.0), (1.0, 1.0)],
                // (0,1)- | (1,1)+ : the edge at x = 1 over y 1..2.
                [(1.0, 1.0), (1.0, 2.0)],
                // (1,0)+ | (2,0)0 : the edge at x = 2 over y 0..1.
                [(2.0, 0.0), (2.0, 1.0)],
            ]
        );
    }
}
