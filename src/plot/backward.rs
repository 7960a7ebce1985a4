//! The backward-ratio maps of a scene with `[output] backward = true`
//! (docs/model.md section 4, "Backward travel"): a heatmap per axis and
//! slice of a grid with two or more axes, `backward_ratio_x.png` beside
//! `step_x.png`. A ratio is drawn where the status keeps values (0, and
//! 6 with its estimate); failed instances are grey, never a number.

use std::path::{Path, PathBuf};

use anyhow::Result;

use super::colour::{Diverging, FAILED};
use super::heatmap::{MapLegend, heatmap};
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
    let Some(ratio) = &data.backward_ratio else {
        return Ok(());
    };
    // An axis whose slider never travels back (undriven) has no picture.
    let drawn: Vec<usize> = (0..2)
        .filter(|&a| ratio[a].iter().any(|&r| r != 0.0))
        .collect();
    for a in (0..2).filter(|a| !drawn.contains(a)) {
        let a = AXIS_NAMES[a];
        notes.push(format!("backward_ratio_{a} is 0 everywhere; not drawn"));
    }
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
