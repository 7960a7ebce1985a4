//! Line plots of a grid with one axis: the steps against it, and the ratio
//! of 2-DOF to 1-DOF steps with their regimes; beside them the strip of
//! the kinds of motion (`motion`).

use std::path::{Path, PathBuf};

use anyhow::Result;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::canvas::{LEGEND_WIDTH, font, save, swatch, title_block};
use super::colour::{FAILED, axis_colour};
use super::placement::{Placement, label_values};
use super::read::{AxisData, Data, Kind};
use super::regime::{Regime, ZERO_STEP_M};
use super::text::{axis_title, short};
use crate::laws::Law;
use crate::model::AXIS_NAMES;

/// One line of a line chart.
pub(super) struct Series {
    pub(super) name: String,
    pub(super) colour: RGBColor,
    /// Dashed without dots (1-DOF), or solid with a dot per value.
    pub(super) dashed: bool,
    /// (grid value, y) pairs.
    pub(super) points: Vec<(f64, f64)>,
}

/// A line chart against one grid axis.
pub(super) struct LineChart<'a> {
    pub(super) title: Vec<String>,
    pub(super) axis: &'a AxisData,
    pub(super) y_title: &'a str,
    /// A horizontal black line at this y.
    pub(super) reference: f64,
    pub(super) series: Vec<Series>,
    /// Extra dots (grid value, y, colour), drawn over the lines.
    pub(super) markers: Vec<(f64, f64, RGBColor)>,
    /// Swatches listed after the series in the legend.
    pub(super) extra_legend: Vec<(RGBColor, String)>,
}

impl LineChart<'_> {
    pub(super) fn draw(&self, path: &Path) -> Result<()> {
        let axis = self.axis;
        save(path, (1100, 760), |root| {
            let body = title_block(root, &self.title)?;
            let (left, right) = body.split_horizontally(1100 - LEGEND_WIDTH);
            let place = Placement::of(&axis.values);
            let xs: Vec<f64> = axis.values.iter().map(|&v| place.place(v)).collect();
            let (x_lo, x_hi) = xs
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                    (a.min(x), b.max(x))
                });
            let ys = self
                .series
                .iter()
                .flat_map(|s| s.points.iter().map(|p| p.1))
                .chain(self.markers.iter().map(|m| m.1))
                .chain(std::iter::once(self.reference));
            let (y_lo, y_hi) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| {
                (a.min(y), b.max(y))
            });
            let pad = 0.06 * (y_hi - y_lo).max(1e-6);
            let (y_lo, y_hi) = (y_lo - pad, y_hi + pad);
            let mut chart = ChartBuilder::on(&left)
                .margin(15)
                .x_label_area_size(60)
                .y_label_area_size(80)
                .build_cartesian_2d(x_lo..x_hi, y_lo..y_hi)?;
            let fx = move |c: &f64| short(place.value(*c));
            chart
                .configure_mesh()
                .x_desc(axis_title(&axis.key, &axis.units))
                .y_desc(self.y_title)
                .x_labels(if place.log { 0 } else { 10 })
                .x_label_formatter(&fx)
                // A tick at zero computed as lo + k step lands a rounding
                // away from it: label it zero.
                .y_label_formatter(&|v| {
                    short(if v.abs() <= 1e-9 * (y_hi - y_lo) {
                        0.0
                    } else {
                        *v
                    })
                })
                .label_style(font(15))
                .axis_desc_style(font(17))
                .light_line_style(WHITE.mix(0.0))
                .draw()?;
            if place.log {
                for v in label_values(&axis.values) {
                    let (x, y) = chart.backend_coord(&(place.place(v), y_lo));
                    root.draw(&PathElement::new(vec![(x, y), (x, y + 5)], BLACK))?;
                    root.draw_text(
                        &short(v),
                        &font(15).pos(Pos::new(HPos::Center, VPos::Top)),
                        (x, y + 8),
                    )?;
                }
            }
            chart.draw_series(LineSeries::new(
                vec![(x_lo, self.reference), (x_hi, self.reference)],
                BLACK.stroke_width(1),
            ))?;
            for s in &self.series {
                let pts: Vec<(f64, f64)> =
                    s.points.iter().map(|&(x, y)| (place.place(x), y)).collect();
                let style = s.colour.stroke_width(2);
                if s.dashed {
                    chart.draw_series(DashedLineSeries::new(pts, 8, 5, style))?;
                } else {
                    chart.draw_series(LineSeries::new(pts.clone(), style))?;
                    chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, s.colour.filled())))?;
                }
            }
            chart.draw_series(
                self.markers
                    .iter()
                    .map(|&(x, y, c)| Circle::new((place.place(x), y), 5, c.filled())),
            )?;
            let mut row = 0;
            for s in &self.series {
                let y = 30 + 30 * row;
                let style = s.colour.stroke_width(3);
                if s.dashed {
                    right.draw(&PathElement::new(vec![(0, y + 9), (8, y + 9)], style))?;
                    right.draw(&PathElement::new(vec![(12, y + 9), (20, y + 9)], style))?;
                } else {
                    right.draw(&PathElement::new(vec![(0, y + 9), (20, y + 9)], style))?;
                }
                right.draw_text(&s.name, &font(14), (28, y + 2))?;
                row += 1;
            }
            for (colour, text) in &self.extra_legend {
                swatch(&right, 0, 30 + 30 * row, *colour, text)?;
                row += 1;
            }
            Ok(())
        })
    }
}

/// Writes the line plots of a grid with one axis.
pub(super) fn grid_lines(
    data: &Data,
    axis: &AxisData,
    dir: &Path,
    files: &mut Vec<PathBuf>,
) -> Result<()> {
    let path = dir.join("steps.png");
    step_lines(data, axis).draw(&path)?;
    files.push(path);

    if let Some(motion) = data.motion_shown() {
        let path = dir.join("motion.png");
        super::motion::motion_strip(&path, data, motion, axis)?;
        files.push(path);
    }

    let Some((base, bstatus)) = &data.baseline else {
        return Ok(());
    };
    let path = dir.join("ratio.png");
    ratio_lines(data, axis, base, bstatus).draw(&path)?;
    files.push(path);
    Ok(())
}

/// The chart of the 2-DOF steps [µm per own drive cycle] against the grid
/// `axis` (and the 1-DOF ones, dashed, when stored), failed instances
/// marked on the zero line.
fn step_lines<'a>(data: &Data, axis: &'a AxisData) -> LineChart<'a> {
    let n = axis.values.len();
    let failed: Vec<usize> = (0..n).filter(|&k| data.status[k] != 0).collect();
    let mut series = Vec::new();
    for a in 0..2 {
        series.push(Series {
            name: format!("2-DOF step along {}", AXIS_NAMES[a]),
            colour: axis_colour(a),
            dashed: false,
            points: (0..n)
                .filter(|&k| data.status[k] == 0)
                .map(|k| (axis.values[k], data.step[a][k] * 1e6))
                .collect(),
        });
        if let Some((base, bstatus)) = &data.baseline {
            series.push(Series {
                name: format!("1-DOF step along {} (driven alone)", AXIS_NAMES[a]),
                colour: axis_colour(a),
                dashed: true,
                points: (0..n)
                    .filter(|&k| bstatus[k] == 0)
                    .map(|k| (axis.values[k], base[a][k] * 1e6))
                    .collect(),
            });
        }
    }
    LineChart {
        title: vec![
            format!(
                "{}: slider step per own drive cycle against {}",
                data.name, axis.key
            ),
            "above zero: moves towards +x (+y); below zero: towards -x (-y)".to_owned(),
        ],
        axis,
        y_title: "step [µm per own drive cycle]",
        reference: 0.0,
        series,
        markers: failed
            .iter()
            .map(|&k| (axis.values[k], 0.0, FAILED))
            .collect(),
        extra_legend: if failed.is_empty() {
            Vec::new()
        } else {
            vec![(
                FAILED,
                format!("not computed (status ≠ 0): {}", failed.len()),
            )]
        },
    }
}

/// The chart of the 2-DOF step over the 1-DOF step (`base`, its status
/// `bstatus`) against the grid `axis`, each value dotted in its regime's
/// colour; values whose 1-DOF step is below [`ZERO_STEP_M`] are left out.
fn ratio_lines<'a>(
    data: &Data,
    axis: &'a AxisData,
    base: &[Vec<f64>; 2],
    bstatus: &[u32],
) -> LineChart<'a> {
    let n = axis.values.len();
    let ok = |k: usize| data.status[k] == 0 && bstatus[k] == 0;
    let mut series = Vec::new();
    let mut markers = Vec::new();
    let mut seen = Vec::new();
    for a in 0..2 {
        let kept: Vec<usize> = (0..n)
            .filter(|&k| ok(k) && base[a][k].abs() >= ZERO_STEP_M)
            .collect();
        for &k in &kept {
            let regime = Regime::classify(data.step[a][k], base[a][k], true);
            if !seen.contains(&regime) {
                seen.push(regime);
            }
            markers.push((
                axis.values[k],
                data.step[a][k] / base[a][k],
                regime.colour(),
            ));
        }
        series.push(Series {
            name: format!("2-DOF / 1-DOF step along {}", AXIS_NAMES[a]),
            colour: axis_colour(a),
            dashed: false,
            points: kept
                .iter()
                .map(|&k| (axis.values[k], data.step[a][k] / base[a][k]))
                .collect(),
        });
    }
    LineChart {
        title: vec![
            format!(
                "{}: 2-DOF step / 1-DOF step against {}",
                data.name, axis.key
            ),
            "1 (black line): as if each axis were driven alone; below 0: reversed. Dots: regime"
                .to_owned(),
            "points where the 1-DOF step is below 0.001 µm have no ratio and are left out"
                .to_owned(),
        ],
        axis,
        y_title: "2-DOF step / 1-DOF step",
        reference: 1.0,
        series,
        markers,
        extra_legend: Regime::ALL
            .iter()
            .filter(|r| seen.contains(r))
            .map(|r| (r.colour(), r.describe().to_owned()))
            .collect(),
    }
}

/// The most values of the short axis of a two-axis grid drawn as a family
/// of lines, and the fewest of its long axis: a few curves of many points
/// each (a step against the load at two voltages) read at a glance, where
/// a heatmap two cells tall does not.
pub(super) const FAMILY_MOST_LINES: usize = 4;
pub(super) const FAMILY_FEWEST_POINTS: usize = 8;

/// The line colours of a family, one per value of the short axis.
const FAMILY_COLOURS: [RGBColor; FAMILY_MOST_LINES] = [
    RGBColor(33, 102, 172),
    RGBColor(214, 96, 77),
    RGBColor(27, 120, 55),
    RGBColor(118, 42, 131),
];

/// For a grid of two axes, one with at most [`FAMILY_MOST_LINES`] values
/// and the other with at least [`FAMILY_FEWEST_POINTS`]: the dimensions
/// (long, short).
pub(super) fn family_dims(shape: &[usize]) -> Option<(usize, usize)> {
    let [a, b] = shape else {
        return None;
    };
    let fits =
        |long: usize, short: usize| long >= FAMILY_FEWEST_POINTS && short <= FAMILY_MOST_LINES;
    if fits(*a, *b) {
        Some((0, 1))
    } else if fits(*b, *a) {
        Some((1, 0))
    } else {
        None
    }
}

/// Writes, per axis, the step against the long axis of a two-axis grid
/// ([`family_dims`]), one line per value of the short axis:
/// `step_x_lines.png` and `step_y_lines.png`.
pub(super) fn family_lines(
    data: &Data,
    axes: &[AxisData],
    (long, short): (usize, usize),
    dir: &Path,
    files: &mut Vec<PathBuf>,
) -> Result<()> {
    let stride = [data.shape[1], 1];
    let flat = |l: usize, s: usize| l * stride[long] + s * stride[short];
    let (along, over) = (&axes[long], &axes[short]);
    for (a, name) in AXIS_NAMES.iter().enumerate() {
        let mut failed = Vec::new();
        let mut series: Vec<Series> = (0..over.values.len())
            .map(|s| Series {
                name: format!(
                    "{} = {}",
                    over.key,
                    super::text::with_unit(over.values[s], &over.units)
                ),
                colour: FAMILY_COLOURS[s],
                dashed: false,
                points: (0..along.values.len())
                    .filter(|&l| {
                        let ok = data.status[flat(l, s)] == 0;
                        if !ok {
                            failed.push(along.values[l]);
                        }
                        ok
                    })
                    .map(|l| (along.values[l], data.step[a][flat(l, s)] * 1e6))
                    .collect(),
            })
            .collect();
        // A LuGre map: each line's instance under Karnopp's friction, as
        // the reference the bristles approach (docs/model.md section 8).
        if let Some(twins) = limit_twins(data, (long, short), &flat) {
            for (s, twin) in twins.iter().enumerate() {
                series.push(Series {
                    name: format!("Karnopp, {}", series[s].name),
                    colour: FAMILY_COLOURS[s],
                    dashed: true,
                    points: along.values.iter().map(|&v| (v, twin[a] * 1e6)).collect(),
                });
            }
        }
        let path = dir.join(format!("step_{}_lines.png", name));
        let y_title = format!("step along {} [µm per {} drive cycle]", name, name);
        let mut title = vec![
            format!(
                "{}: slider step along {} against {}, one line per {}",
                data.name, name, along.key, over.key
            ),
            format!(
                "above zero: moves towards +{a}; below zero: towards -{a}; where a line crosses \
                 zero the {a} step stops",
                a = name
            ),
        ];
        title.extend(data.fixed.clone());
        LineChart {
            title,
            axis: along,
            y_title: &y_title,
            reference: 0.0,
            series,
            markers: failed.iter().map(|&v| (v, 0.0, FAILED)).collect(),
            extra_legend: if failed.is_empty() {
                Vec::new()
            } else {
                vec![(
                    FAILED,
                    format!("not computed (status ≠ 0): {}", failed.len()),
                )]
            },
        }
        .draw(&path)?;
        files.push(path);
    }
    Ok(())
}

/// For a file of a law with a limit form (LuGre's, `Law::limit`) whose
/// long axis is one of the law's own keys: the step [m per own cycle] of
/// each line's instance (at the long axis' first value) integrated again
/// under the limit's law on the CPU, at the scene's settings; `None` for
/// any other file.
fn limit_twins(
    data: &Data,
    (long, short): (usize, usize),
    flat: &dyn Fn(usize, usize) -> usize,
) -> Option<Vec<[f64; 2]>> {
    let scene = data.scene.as_ref()?;
    let Kind::Grid(axes) = &data.kind else {
        return None;
    };
    let own = scene.law().keys();
    if !own
        .iter()
        .any(|key| axes[long].key == format!("mechanism.{key}"))
    {
        return None;
    }
    (0..axes[short].values.len())
        .map(|s| {
            let inst = Law::limit_of(&scene.instance(flat(0, s) as u64))?;
            let out = crate::backend::cpu::run_one(&inst, &scene.settings);
            Some(std::array::from_fn(|i| {
                if out.status == 0 {
                    out.step(&inst, i)
                } else {
                    f64::NAN
                }
            }))
        })
        .collect()
}
