//! The stall-load pictures of a scene with `[stall]` (`crate::stall`,
//! docs/model.md section 7): a heatmap per slice of a grid of two or more axes,
//! a line against the axis of a 1-D grid, a dot per point of a points
//! scene. A stall load is drawn only where the search found one; where the
//! step keeps its direction under every load probed, or a run failed, the
//! cell says so in a colour of its own, never as a number.

use std::path::{Path, PathBuf};

use anyhow::Result;

use super::canvas::{LEGEND_WIDTH, font, save, swatch, title_block};
use super::colour::{Diverging, FAILED, NO_STALL};
use super::heatmap::{MapLegend, heatmap};
use super::lines::{LineChart, Series};
use super::maps::{Plane, plane_slices};
use super::read::{AxisData, Data, Kind, StallData};
use super::text::short;
use crate::measurement::keeps_values;
use crate::measurement::status::STATUS_NO_STALL;
use crate::model::AXIS_NAMES;

/// How one instance's stall search is drawn.
fn found(stall: &StallData, k: usize) -> bool {
    keeps_values(stall.status[k])
}

/// The title lines every stall picture shares.
fn title(data: &Data, stall: &StallData, cells: &[usize]) -> Vec<String> {
    let a = AXIS_NAMES[stall.axis];
    let mut lines = vec![
        format!(
            "{}: stall load along {a} [N]: the load at which the {a} step stops (docs/model.md \
             section 7)",
            data.name
        ),
        format!(
            "below zero: a load towards -{a} stops a forward step; above zero: a load towards \
             +{a} stops a backward step; its size is the largest load the actuator moves"
        ),
    ];
    let none = cells
        .iter()
        .filter(|&&k| stall.status[k] == STATUS_NO_STALL)
        .count();
    if none > 0 {
        lines.push(format!(
            "violet: {none} of {} instances have no stall load below the kinetic friction (the \
             step keeps its direction: the actuator pushes any load the interface holds)",
            cells.len()
        ));
    }
    let failed = cells
        .iter()
        .filter(|&&k| !found(stall, k) && stall.status[k] != STATUS_NO_STALL)
        .count();
    if failed > 0 {
        lines.push(format!(
            "grey: {failed} of {} instances whose unloaded run or a probe failed (see \
             /maps/stall_status_{a}); no value is drawn",
            cells.len()
        ));
    }
    lines
}

/// Writes the stall pictures of `data`; `plane` slices a grid of two or
/// more axes.
pub(super) fn stall_pictures(
    data: &Data,
    stall: &StallData,
    plane: Option<&Plane>,
    dir: &Path,
    files: &mut Vec<PathBuf>,
    notes: &mut Vec<String>,
) -> Result<()> {
    let a = AXIS_NAMES[stall.axis];
    match (&data.kind, plane) {
        (Kind::Grid(axes), Some(plane)) if axes.len() >= 2 => {
            let (across, up) = (&axes[plane.across], &axes[plane.up]);
            for slice in plane_slices(data, axes, plane) {
                let cells: Vec<usize> = slice.flat.iter().flatten().copied().collect();
                let loads = cells
                    .iter()
                    .filter(|&&k| found(stall, k))
                    .map(|&k| stall.load[k]);
                let scale = Diverging::covering(loads, 0.0, 1e-6, f64::INFINITY);
                let mut lines = title(data, stall, &cells);
                lines.push(format!(
                    "red: a load towards +{a}, blue: towards -{a}; symmetric colour limits ±{} N",
                    short(scale.half_width)
                ));
                lines.extend(slice.line.clone());
                lines.extend(data.fixed.clone());
                let mut swatches = Vec::new();
                if cells.iter().any(|&k| stall.status[k] == STATUS_NO_STALL) {
                    swatches.push((NO_STALL, "no stall load below f_c".to_owned()));
                }
                if cells
                    .iter()
                    .any(|&k| !found(stall, k) && stall.status[k] != STATUS_NO_STALL)
                {
                    swatches.push((FAILED, "a run failed".to_owned()));
                }
                let path = dir.join(format!("stall_load_{a}{}.png", slice.suffix));
                heatmap(
                    &path,
                    &lines,
                    across,
                    up,
                    &|i, j| {
                        let k = slice.flat[i][j];
                        if found(stall, k) {
                            scale.colour(stall.load[k])
                        } else if stall.status[k] == STATUS_NO_STALL {
                            NO_STALL
                        } else {
                            FAILED
                        }
                    },
                    &MapLegend::Bar {
                        scale,
                        title: format!("stall load along {a} [N]"),
                        swatches,
                    },
                )?;
                files.push(path);
            }
        }
        (Kind::Grid(axes), _) if axes.len() == 1 => {
            let path = dir.join(format!("stall_load_{a}.png"));
            line_chart(stall, &axes[0], title(data, stall, &all(data)), &path)?;
            files.push(path);
        }
        // One value is a number, not a picture: the summary prints it.
        (Kind::Points(labels), _) if labels.len() < 2 => notes.push(one_value(stall)),
        (Kind::Grid(_), _) if data.status.len() < 2 => notes.push(one_value(stall)),
        (Kind::Points(labels), _) => {
            let path = dir.join(format!("stall_load_{a}.png"));
            point_bars(stall, labels, title(data, stall, &all(data)), &path)?;
            files.push(path);
        }
        (Kind::Grid(_), _) => notes.push(one_value(stall)),
    }
    Ok(())
}

/// The note of a file with one instance, whose stall load is a number.
fn one_value(stall: &StallData) -> String {
    format!(
        "one instance: its stall load is in /maps/stall_load_{} (stall status {}); no picture \
         is drawn",
        AXIS_NAMES[stall.axis], stall.status[0]
    )
}

/// Every instance of the file.
fn all(data: &Data) -> Vec<usize> {
    (0..data.status.len()).collect()
}

/// A bar per point: its stall load, blue below zero and red above; a
/// violet stub where it has none below f_c, a grey one where a run failed.
fn point_bars(stall: &StallData, labels: &[String], title: Vec<String>, path: &Path) -> Result<()> {
    use plotters::prelude::*;
    use plotters::style::text_anchor::{HPos, Pos, VPos};
    let a = AXIS_NAMES[stall.axis];
    let n = labels.len();
    let values: Vec<f64> = (0..n)
        .filter(|&k| found(stall, k))
        .map(|k| stall.load[k])
        .collect();
    let hi = values.iter().copied().fold(0.0f64, f64::max);
    let lo = values.iter().copied().fold(0.0f64, f64::min);
    let pad = 0.15 * (hi - lo).max(1e-6);
    let scale = Diverging::covering(values.iter().copied(), 0.0, 1e-6, f64::INFINITY);
    let width = 1100u32.max(160 * n as u32 + LEGEND_WIDTH + 120).min(4000);
    save(path, (width, 760), |root| {
        let body = title_block(root, &title)?;
        let (left, right) = body.split_horizontally(width - LEGEND_WIDTH);
        let mut chart = ChartBuilder::on(&left)
            .margin(15)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d(0.0..n as f64, (lo - pad)..(hi + pad))?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .disable_x_axis()
            .y_desc(format!("stall load along {a} [N]"))
            .y_label_formatter(&|v| {
                short(if v.abs() <= 1e-9 * (hi - lo + 2.0 * pad) {
                    0.0
                } else {
                    *v
                })
            })
            .label_style(font(15))
            .axis_desc_style(font(17))
            .draw()?;
        chart.draw_series(LineSeries::new(
            vec![(0.0, 0.0), (n as f64, 0.0)],
            BLACK.stroke_width(1),
        ))?;
        for (k, label) in labels.iter().enumerate() {
            let (x0, x1) = (k as f64 + 0.25, k as f64 + 0.75);
            let stub = 0.04 * (hi - lo).max(1e-6);
            let (value, colour) = if found(stall, k) {
                (stall.load[k], scale.colour(stall.load[k]))
            } else if stall.status[k] == STATUS_NO_STALL {
                (stub, NO_STALL)
            } else {
                (stub, FAILED)
            };
            chart.draw_series(std::iter::once(Rectangle::new(
                [(x0, 0.0), (x1, value)],
                colour.filled(),
            )))?;
            if found(stall, k) {
                let (px, py) = chart.backend_coord(&(0.5 * (x0 + x1), value));
                let (anchor, dy) = if value >= 0.0 {
                    (VPos::Bottom, -3)
                } else {
                    (VPos::Top, 3)
                };
                root.draw_text(
                    &format!("{value:+.4}"),
                    &font(13).pos(Pos::new(HPos::Center, anchor)),
                    (px, py + dy),
                )?;
            }
            let (px, py) = chart.backend_coord(&(k as f64 + 0.5, lo - pad));
            let name = if label.is_empty() {
                format!("point {k}")
            } else {
                label.clone()
            };
            root.draw_text(
                &name,
                &font(16).pos(Pos::new(HPos::Center, VPos::Top)),
                (px, py + 8),
            )?;
        }
        let mut row = 0;
        for (colour, text) in [
            (
                scale.colour(-scale.half_width),
                format!("a load towards -{a}"),
            ),
            (
                scale.colour(scale.half_width),
                format!("a load towards +{a}"),
            ),
        ] {
            swatch(&right, 0, 30 + 30 * row, colour, &text)?;
            row += 1;
        }
        if (0..n).any(|k| stall.status[k] == STATUS_NO_STALL) {
            swatch(
                &right,
                0,
                30 + 30 * row,
                NO_STALL,
                "no stall load below f_c",
            )?;
            row += 1;
        }
        if (0..n).any(|k| !found(stall, k) && stall.status[k] != STATUS_NO_STALL) {
            swatch(&right, 0, 30 + 30 * row, FAILED, "a run failed")?;
        }
        Ok(())
    })
}

/// The stall loads against one axis: a line through those found, a violet
/// dot at zero where none is below f_c, a grey one where a run failed.
fn line_chart(stall: &StallData, axis: &AxisData, title: Vec<String>, path: &Path) -> Result<()> {
    let a = AXIS_NAMES[stall.axis];
    let n = axis.values.len();
    let markers: Vec<(f64, f64, plotters::style::RGBColor)> = (0..n)
        .filter(|&k| !found(stall, k))
        .map(|k| {
            let colour = if stall.status[k] == STATUS_NO_STALL {
                NO_STALL
            } else {
                FAILED
            };
            (axis.values[k], 0.0, colour)
        })
        .collect();
    let mut extra_legend = Vec::new();
    if markers.iter().any(|m| m.2 == NO_STALL) {
        extra_legend.push((NO_STALL, "no stall load below f_c".to_owned()));
    }
    if markers.iter().any(|m| m.2 == FAILED) {
        extra_legend.push((FAILED, "a run failed".to_owned()));
    }
    let y_title = format!("stall load along {a} [N]");
    LineChart {
        title,
        axis,
        y_title: &y_title,
        reference: 0.0,
        series: vec![Series {
            name: format!("stall load along {a}"),
            colour: super::colour::axis_colour(stall.axis),
            dashed: false,
            points: (0..n)
                .filter(|&k| found(stall, k))
                .map(|k| (axis.values[k], stall.load[k]))
                .collect(),
        }],
        markers,
        extra_legend,
    }
    .draw(path)
}
