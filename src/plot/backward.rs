//! The backward-ratio pictures of a scene with `[output] backward = true`
//! (docs/model.md section 4, "Backward travel"): a heatmap per axis and
//! slice of a grid with two or more axes, `backward_ratio_x.png` beside
//! `step_x.png`; for a grid of one axis a line per moving axis, and for a
//! points scene a bar per moving axis and point, `backward_ratio.png`
//! beside `steps.png`. A ratio is drawn where the
//! status keeps values (0, and 6 with its estimate); failed instances are
//! grey, never a number.

use std::path::{Path, PathBuf};

use anyhow::Result;

use super::bars::{Bar, Bars, draw_bars};
use super::colour::{Diverging, FAILED, axis_colour};
use super::heatmap::{MapLegend, heatmap};
use super::lines::{LineChart, Series};
use super::maps::{Plane, plane_slices};
use super::read::{AxisData, Data};
use crate::measurement::keeps_values;
use crate::model::AXIS_NAMES;

/// Draws the backward-ratio maps of `data` sliced as `plane`, adding each
/// file to `files`; nothing where the file has no backward maps.
pub(super) fn backward_maps(
    data: &Data,
    axes: &[AxisData],
    plane: &Plane,
    dir: &Path,
    files: &mut Vec<PathBuf>,
    notes: &mut Vec<String>,
) -> Result<()> {
    let Some((ratio, drawn)) = drawn(data, notes) else {
        return Ok(());
    };
    let (across, up) = (&axes[plane.across], &axes[plane.up]);
    for slice in plane_slices(data, axes, plane) {
        for &axis in &drawn {
            let cells: Vec<usize> = slice.flat.iter().flatten().copied().collect();
            let failed = cells
                .iter()
                .filter(|&&k| !keeps_values(data.status[k]))
                .count();
            let a = AXIS_NAMES[axis];
            let mut title = vec![
                format!(
                    "{}: backward ratio along {a}: backward_{a} / (|step_{a}| + backward_{a})",
                    data.name
                ),
                format!(
                    "the slider's travel against its step, as a share of its path: blue 0 (no \
                     travel back), white 0.5 (as far back as the step), red 1 (no net step)"
                ),
            ];
            title.extend(slice.line.clone());
            let mut swatches = Vec::new();
            if failed > 0 {
                title.push(format!(
                    "grey: {failed} of {} instances failed (see /maps/status)",
                    cells.len()
                ));
                swatches.push((FAILED, "failed (status ≠ 0, 6)".to_owned()));
            }
            let scale = Diverging {
                centre: 0.5,
                half_width: 0.5,
            };
            let path = dir.join(format!("backward_ratio_{a}{}.png", slice.suffix));
            heatmap(
                &path,
                &title,
                across,
                up,
                &|i, j| {
                    let k = slice.flat[i][j];
                    if keeps_values(data.status[k]) {
                        scale.colour(ratio[axis][k])
                    } else {
                        FAILED
                    }
                },
                &MapLegend::Bar {
                    scale,
                    title: format!("backward ratio along {a} [1]"),
                    swatches,
                },
            )?;
            files.push(path);
        }
    }
    Ok(())
}

/// The file's ratios and the axes drawn: an axis whose slider never
/// travels back (undriven) has no picture, and a note says so; `None`
/// where the file has no backward maps or no axis is drawn.
fn drawn<'d>(data: &'d Data, notes: &mut Vec<String>) -> Option<(&'d [Vec<f64>; 2], Vec<usize>)> {
    let ratio = data.backward_ratio.as_ref()?;
    let drawn: Vec<usize> = (0..2)
        .filter(|&a| ratio[a].iter().any(|&r| r != 0.0))
        .collect();
    for a in (0..2).filter(|a| !drawn.contains(a)) {
        let a = AXIS_NAMES[a];
        notes.push(format!("backward_ratio_{a} is 0 everywhere; not drawn"));
    }
    (!drawn.is_empty()).then_some((ratio, drawn))
}

/// Draws the backward ratio of a grid of one axis, `backward_ratio.png`:
/// a line per moving axis against the grid's axis, with a line at 0.5 (as
/// far back as the step); failed instances are marked on it in grey.
/// Nothing where the file has no backward maps or no axis moves.
pub(super) fn backward_lines(
    data: &Data,
    axis: &AxisData,
    dir: &Path,
    files: &mut Vec<PathBuf>,
    notes: &mut Vec<String>,
) -> Result<()> {
    let Some((ratio, drawn)) = drawn(data, notes) else {
        return Ok(());
    };
    let n = axis.values.len();
    let kept = |k: &usize| keeps_values(data.status[*k]);
    let failed: Vec<usize> = (0..n).filter(|k| !kept(k)).collect();
    let series = drawn
        .iter()
        .map(|&a| Series {
            name: format!("backward ratio along {}", AXIS_NAMES[a]),
            colour: axis_colour(a),
            dashed: false,
            points: (0..n)
                .filter(kept)
                .map(|k| (axis.values[k], ratio[a][k]))
                .collect(),
        })
        .collect();
    let chart = LineChart {
        title: vec![
            format!(
                "{}: backward ratio backward / (|step| + backward) against {}",
                data.name, axis.key
            ),
            "the slider's travel against its step, as a share of its path: 0 no travel back, \
             0.5 as far back as the step (the line), 1 no net step"
                .to_owned(),
        ],
        axis,
        y_title: "backward ratio [1]",
        reference: 0.5,
        series,
        markers: failed
            .iter()
            .map(|&k| (axis.values[k], 0.5, FAILED))
            .collect(),
        extra_legend: if failed.is_empty() {
            Vec::new()
        } else {
            vec![(FAILED, format!("failed (status ≠ 0, 6): {}", failed.len()))]
        },
    };
    let path = dir.join("backward_ratio.png");
    chart.draw(&path)?;
    files.push(path);
    Ok(())
}

/// Draws the backward ratio of a points scene (or a single instance),
/// `backward_ratio.png`: a bar per moving axis and point, failed runs as
/// grey stubs. Nothing where the file has no backward maps or no axis
/// moves.
pub(super) fn backward_bars(
    data: &Data,
    labels: &[String],
    dir: &Path,
    files: &mut Vec<PathBuf>,
    notes: &mut Vec<String>,
) -> Result<()> {
    let Some((ratio, drawn)) = drawn(data, notes) else {
        return Ok(());
    };
    let n = labels.len();
    let failed = (0..n).filter(|&k| !keeps_values(data.status[k])).count();
    let bars = (0..n)
        .flat_map(|k| {
            drawn.iter().map(move |&axis| Bar {
                point: k,
                axis,
                baseline: false,
                value: ratio[axis][k],
                ok: keeps_values(data.status[k]),
            })
        })
        .collect();
    let mut legend: Vec<_> = drawn
        .iter()
        .map(|&a| {
            (
                axis_colour(a),
                format!("backward ratio along {}", AXIS_NAMES[a]),
            )
        })
        .collect();
    if failed > 0 {
        legend.push((FAILED, "failed (status ≠ 0, 6)".to_owned()));
    }
    let chart = Bars {
        file: "backward_ratio.png",
        title: vec![
            format!(
                "{}: backward ratio backward / (|step| + backward) at each point",
                data.name
            ),
            "the slider's travel against its step, as a share of its path: 0 no travel back, \
             0.5 as far back as the step, 1 no net step"
                .to_owned(),
        ],
        y_desc: "backward ratio [1]".to_owned(),
        bars,
        per: drawn.len(),
        legend,
    };
    draw_bars(data, labels, dir, files, &chart)
}
