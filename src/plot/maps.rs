//! The maps of a grid with two or more axes: step, ratio, regime and
//! motion heatmaps for every 2-D slice.

use std::path::{Path, PathBuf};

use anyhow::Result;
use plotters::style::RGBColor;

use super::MAX_SLICES;
use super::colour::{Diverging, FAILED, NOT_STEADY, UNDEFINED};
use super::heatmap::{MapLegend, heatmap};
use super::read::{AxisData, Data};
use super::regime::{Regime, ZERO_STEP_M};
use super::text::{short, with_unit};
use crate::laws::status::STATUS_NOT_STEADY;
use crate::model::AXIS_NAMES;
use crate::model::motion::Motion;

/// How a grid's maps are sliced: the dimensions across and up, and for
/// every other dimension the indices drawn (all, or the one `--at` holds).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Plane {
    pub(super) across: usize,
    pub(super) up: usize,
    /// For each dimension but `across` and `up`, in grid order: the
    /// dimension and the indices of its values to draw.
    pub(super) rest: Vec<(usize, Vec<usize>)>,
}

impl Plane {
    /// The plane of a `view` of a grid with `axes` (two or more) and
    /// `shape`: its keys checked against the grid's, an `--at` value
    /// matched to one of its axis' values.
    pub(super) fn choose(
        axes: &[AxisData],
        shape: &[usize],
        view: &super::View,
    ) -> anyhow::Result<Plane> {
        let keys = || {
            axes.iter()
                .map(|a| a.key.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        };
        let find = |flag: &str, key: &str| {
            axes.iter().position(|a| a.key == key).ok_or_else(|| {
                anyhow::anyhow!(
                    "{flag} {key}: not a grid axis of this file; expected one of {}",
                    keys()
                )
            })
        };
        let x = view.x.as_deref().map(|k| find("--x", k)).transpose()?;
        let y = view.y.as_deref().map(|k| find("--y", k)).transpose()?;
        let mut held: Vec<(usize, usize)> = Vec::new();
        for (key, value) in &view.at {
            let d = find("--at", key)?;
            if Some(d) == x || Some(d) == y {
                anyhow::bail!("--at {key}: it is the axis --x or --y spans; hold another axis");
            }
            if held.iter().any(|&(h, _)| h == d) {
                anyhow::bail!("--at {key}: given twice");
            }
            let values = &axes[d].values;
            let scale = values.iter().fold(value.abs(), |m, v| m.max(v.abs()));
            let Some(i) = values
                .iter()
                .position(|v| (v - value).abs() <= 1e-9 * scale.max(f64::MIN_POSITIVE))
            else {
                let list: Vec<String> = values.iter().map(|v| short(*v)).collect();
                anyhow::bail!(
                    "--at {key}={}: not a value of that axis; it has {}",
                    short(*value),
                    list.join(", ")
                );
            };
            held.push((d, i));
        }
        // The longest axes not held span the maps where --x or --y leaves
        // it open (the earlier on ties).
        let mut free: Vec<usize> = (0..shape.len())
            .filter(|d| Some(*d) != x && Some(*d) != y && !held.iter().any(|&(h, _)| h == *d))
            .collect();
        free.sort_by_key(|&d| std::cmp::Reverse(shape[d]));
        let mut free = free.into_iter();
        let (across, up) = match (x, y) {
            (Some(x), Some(y)) if x == y => {
                anyhow::bail!("--x and --y name the same axis {}", axes[x].key)
            }
            (Some(x), Some(y)) => (x, y),
            (Some(x), None) => (x, free.next().context_axis()?),
            (None, Some(y)) => (free.next().context_axis()?, y),
            (None, None) => {
                let (a, b) = (free.next().context_axis()?, free.next().context_axis()?);
                (a.min(b), a.max(b))
            }
        };
        let rest = (0..shape.len())
            .filter(|&d| d != across && d != up)
            .map(|d| match held.iter().find(|&&(h, _)| h == d) {
                Some(&(_, i)) => (d, vec![i]),
                None => (d, (0..shape[d]).collect()),
            })
            .collect();
        Ok(Plane { across, up, rest })
    }
}

/// An axis left to span a map, or the error that none is.
trait ContextAxis {
    fn context_axis(self) -> anyhow::Result<usize>;
}

impl ContextAxis for Option<usize> {
    fn context_axis(self) -> anyhow::Result<usize> {
        self.ok_or_else(|| {
            anyhow::anyhow!("--at holds every axis but one; a map needs two axes to span")
        })
    }
}

/// The combinations of indices of the dimensions of sizes `rest` to draw
/// (all, or [`MAX_SLICES`] evenly spaced ones), and how many there are.
fn slices(rest: &[usize]) -> (Vec<Vec<usize>>, usize) {
    let total: usize = rest.iter().product();
    let chosen: Vec<usize> = if total <= MAX_SLICES {
        (0..total).collect()
    } else {
        (0..MAX_SLICES)
            .map(|k| k * (total - 1) / (MAX_SLICES - 1))
            .collect()
    };
    let combos = chosen
        .into_iter()
        .map(|mut flat| {
            let mut idx = vec![0; rest.len()];
            for d in (0..rest.len()).rev() {
                idx[d] = flat % rest[d];
                flat /= rest[d];
            }
            idx
        })
        .collect();
    (combos, total)
}

/// One 2-D slice of a grid's maps, as [`grid_maps`] draws it.
pub(super) struct Slice {
    /// The file-name suffix naming the held values ("" for a 2-D grid).
    pub(super) suffix: String,
    /// The title line naming the held values, for grids of more axes.
    pub(super) line: Option<String>,
    /// The flat index of cell (i, j): value i across, value j up.
    pub(super) flat: Vec<Vec<usize>>,
}

/// The slices of a grid with two or more axes that `plane` draws (at most
/// [`MAX_SLICES`], evenly spaced), in the order [`grid_maps`] draws them.
pub(super) fn plane_slices(data: &Data, axes: &[AxisData], plane: &Plane) -> Vec<Slice> {
    let shape = &data.shape;
    let (p, q) = (plane.across, plane.up);
    let rest: Vec<usize> = plane.rest.iter().map(|(d, _)| *d).collect();
    let rest_shape: Vec<usize> = plane.rest.iter().map(|(_, ix)| ix.len()).collect();
    let mut strides = vec![1; shape.len()];
    for d in (0..shape.len().saturating_sub(1)).rev() {
        strides[d] = strides[d + 1] * shape[d + 1];
    }
    let (combos, _) = slices(&rest_shape);
    combos
        .into_iter()
        .map(|combo| {
            let combo: Vec<usize> = combo
                .iter()
                .zip(&plane.rest)
                .map(|(&k, (_, ix))| ix[k])
                .collect();
            let offset: usize = combo.iter().zip(&rest).map(|(&i, &d)| i * strides[d]).sum();
            let at: Vec<String> = combo
                .iter()
                .zip(&rest)
                .map(|(&i, &d)| {
                    format!(
                        "{} = {}",
                        axes[d].key,
                        with_unit(axes[d].values[i], &axes[d].units)
                    )
                })
                .collect();
            Slice {
                suffix: combo
                    .iter()
                    .zip(&rest)
                    .map(|(&i, &d)| format!("__{}={}", axes[d].key, short(axes[d].values[i])))
                    .collect(),
                line: (!at.is_empty()).then(|| format!("slice at {}", at.join(", "))),
                flat: (0..shape[p])
                    .map(|i| {
                        (0..shape[q])
                            .map(|j| i * strides[p] + j * strides[q] + offset)
                            .collect()
                    })
                    .collect(),
            }
        })
        .collect()
}

/// The drive parameters of a grid scene that no grid axis changes, as a
/// title line: "fixed: x 100 V, 10 Hz, duty 0.98, phase 0; y 10 Hz, ...".
/// A parameter is fixed when one step along each grid axis leaves it as
/// it is (a grid axis over an `axis.x` key that `axis.y` inherits moves
/// both). `None` for a scene without a grid of two or more axes.
pub(super) fn fixed_drive(scene: &crate::scene::Scene) -> Option<String> {
    let crate::scene::Layout::Grid { axes } = &scene.layout else {
        return None;
    };
    if axes.len() < 2 {
        return None;
    }
    let first = scene.instance(0);
    let mut neighbours = Vec::new();
    let mut stride = 1u64;
    for axis in axes.iter().rev() {
        if axis.values.len() > 1 {
            neighbours.push(scene.instance(stride));
        }
        stride *= axis.values.len() as u64;
    }
    let mut parts = Vec::new();
    for (a, name) in AXIS_NAMES.iter().enumerate() {
        let fixed = |get: &dyn Fn(&crate::model::Axis) -> f64| {
            neighbours
                .iter()
                .all(|n| get(&n.axes[a]).to_bits() == get(&first.axes[a]).to_bits())
        };
        let drive = &first.axes[a];
        let mut items = Vec::new();
        if fixed(&|x| x.voltage) {
            items.push(with_unit(drive.voltage, "V"));
        }
        // An axis undriven everywhere has no drive to describe.
        if items.first().is_some_and(|_| drive.voltage == 0.0) {
            parts.push(format!("{name} undriven"));
            continue;
        }
        if fixed(&|x| x.frequency) {
            items.push(with_unit(drive.frequency, "Hz"));
        }
        match drive.shape {
            crate::model::Shape::Sawtooth if fixed(&|x| x.duty) => {
                items.push(format!("duty {}", short(drive.duty)));
            }
            crate::model::Shape::Trapezoid
                if fixed(&|x| x.rise) && fixed(&|x| x.hold) && fixed(&|x| x.fall) =>
            {
                items.push(format!(
                    "trapezoid {}/{}/{}",
                    short(drive.rise),
                    short(drive.hold),
                    short(drive.fall)
                ));
            }
            crate::model::Shape::Table(_) => items.push("table".to_owned()),
            _ => {}
        }
        if drive.slew_rate != crate::model::NO_SLEW_LIMIT && fixed(&|x| x.slew_rate) {
            items.push(format!("slew {}", with_unit(drive.slew_rate, "V/s")));
        }
        if fixed(&|x| x.phase) {
            items.push(format!("phase {}", short(drive.phase)));
        }
        if !items.is_empty() {
            parts.push(format!("{name} {}", items.join(", ")));
        }
    }
    (!parts.is_empty()).then(|| format!("fixed: {}", parts.join("; ")))
}

/// The per-axis words for map titles.
fn per_cycle(axis: usize) -> String {
    format!("µm per {} drive cycle", AXIS_NAMES[axis])
}

/// Writes the heatmaps of a grid with two or more axes, sliced as `plane`
/// says (by default the two axes with the most values span the maps, the
/// earlier in the file across).
pub(super) fn grid_maps(
    data: &Data,
    axes: &[AxisData],
    plane: &Plane,
    dir: &Path,
    files: &mut Vec<PathBuf>,
    notes: &mut Vec<String>,
) -> Result<()> {
    let drawn = plane_slices(data, axes, plane);
    let total: usize = plane.rest.iter().map(|(_, ix)| ix.len()).product();
    if drawn.len() < total {
        notes.push(format!(
            "{total} slices over {} per map; drew {} evenly spaced ones",
            plane
                .rest
                .iter()
                .map(|&(d, _)| axes[d].key.as_str())
                .collect::<Vec<_>>()
                .join(" x "),
            drawn.len()
        ));
    }
    let (across, up) = (&axes[plane.across], &axes[plane.up]);
    for slice in &drawn {
        let maps = SliceMaps::new(data, across, up, dir, slice);
        for axis in 0..2 {
            files.push(maps.step_map(axis)?);
            files.extend(maps.step_error_map(axis)?);
            let Some((base, base_status)) = &data.baseline else {
                continue;
            };
            let one_dof = OneDof {
                step: &base[axis],
                status: base_status,
            };
            files.push(maps.ratio_map(axis, one_dof)?);
            files.push(maps.regime_map(axis, one_dof)?);
        }
        if let Some(motion) = data.motion_shown() {
            files.push(maps.motion_map(motion)?);
        }
    }
    Ok(())
}

/// The 1-DOF baseline of one axis: its steps [m per own drive cycle] and
/// its status, row-major like the maps.
#[derive(Clone, Copy)]
struct OneDof<'a> {
    step: &'a [f64],
    status: &'a [u32],
}

/// The maps of one 2-D slice of a grid, with what every title says about
/// the slice's instances that have no value to draw.
struct SliceMaps<'a> {
    data: &'a Data,
    across: &'a AxisData,
    up: &'a AxisData,
    /// The folder the pictures are written to.
    dir: &'a Path,
    slice: &'a Slice,
    /// The slice's instances: every value up for the first value across,
    /// then for the next.
    cells: Vec<usize>,
    /// How many of `cells` ended with a non-zero status other than 6.
    failed: usize,
    /// How many of `cells` ended with status 6 (not steady).
    unsteady: usize,
    failed_line: Option<String>,
    unsteady_line: Option<String>,
    inferred_line: Option<String>,
}

impl<'a> SliceMaps<'a> {
    /// The maps of `slice`, `across` and `up` the axes spanning it, to be
    /// written into `dir`.
    fn new(
        data: &'a Data,
        across: &'a AxisData,
        up: &'a AxisData,
        dir: &'a Path,
        slice: &'a Slice,
    ) -> Self {
        let cells: Vec<usize> = slice.flat.iter().flatten().copied().collect();
        let unsteady = cells
            .iter()
            .filter(|&&k| data.status[k] == STATUS_NOT_STEADY)
            .count();
        let failed = cells.iter().filter(|&&k| data.status[k] != 0).count() - unsteady;
        let failed_line = (failed > 0).then(|| {
            format!(
                "dark grey: {failed} of {} instances ended with a non-zero status (see \
                 /maps/status); no value is drawn",
                cells.len()
            )
        });
        let unsteady_line = (unsteady > 0).then(|| {
            format!(
                "light grey: {unsteady} of {} instances did not converge by max_cycles (status \
                 6); their estimates and standard errors are in the file, not drawn",
                cells.len()
            )
        });
        let inferred = |k: usize| data.inferred.as_ref().is_some_and(|m| m[k] == 1);
        let n_inferred = cells.iter().filter(|&&k| inferred(k)).count();
        let inferred_line = data.inferred.is_some().then(|| {
            format!(
                "paler: {n_inferred} of {} values inferred (bilinear) by the adaptive \
                 refinement, not integrated (/maps/inferred)",
                cells.len()
            )
        });
        SliceMaps {
            data,
            across,
            up,
            dir,
            slice,
            cells,
            failed,
            unsteady,
            failed_line,
            unsteady_line,
            inferred_line,
        }
    }

    /// The instance at value `i` across and value `j` up.
    fn flat(&self, i: usize, j: usize) -> usize {
        self.slice.flat[i][j]
    }

    /// Whether instance `k`'s value was inferred by a refinement.
    fn inferred(&self, k: usize) -> bool {
        self.data.inferred.as_ref().is_some_and(|m| m[k] == 1)
    }

    /// The path of the picture `name` (without the slice's suffix).
    fn path(&self, name: &str) -> PathBuf {
        self.dir.join(format!("{name}{}.png", self.slice.suffix))
    }

    /// Draws the step map along `axis` (0 = x) [µm per own drive cycle],
    /// with its zero-step contour; returns its path.
    fn step_map(&self, axis: usize) -> Result<PathBuf> {
        let data = self.data;
        let steps_um: Vec<f64> = self
            .cells
            .iter()
            .filter(|&&k| data.status[k] == 0)
            .map(|&k| data.step[axis][k] * 1e6)
            .collect();
        let scale = Diverging::covering(steps_um, 0.0, ZERO_STEP_M * 1e6, f64::INFINITY);
        let mut title = vec![
            format!(
                "{}: slider step along {} (2-DOF) [{}]",
                data.name,
                AXIS_NAMES[axis],
                per_cycle(axis)
            ),
            format!(
                "red: moves towards +{a}, blue: towards -{a}, white: no motion; symmetric \
                 colour limits ±{} µm",
                short(scale.half_width),
                a = AXIS_NAMES[axis]
            ),
            "black lines: the zero-step contour, where the step changes sign or stops \
             (below 0.001 µm)"
                .to_owned(),
        ];
        title.extend(self.slice.line.clone());
        title.extend(data.fixed.clone());
        title.extend(self.failed_line.clone());
        title.extend(self.unsteady_line.clone());
        title.extend(self.inferred_line.clone());
        let path = self.path(&format!("step_{}", AXIS_NAMES[axis]));
        let mut swatches = Vec::new();
        if self.failed > 0 {
            swatches.push((FAILED, "not computed (status ≠ 0, 6)".to_owned()));
        }
        if self.unsteady > 0 {
            swatches.push((NOT_STEADY, "not steady (status 6)".to_owned()));
        }
        super::heatmap::heatmap_contoured(
            &path,
            &title,
            self.across,
            self.up,
            &|i, j| {
                let k = self.flat(i, j);
                match data.status[k] {
                    0 if self.inferred(k) => paler(scale.colour(data.step[axis][k] * 1e6)),
                    0 => scale.colour(data.step[axis][k] * 1e6),
                    STATUS_NOT_STEADY => NOT_STEADY,
                    _ => FAILED,
                }
            },
            &MapLegend::Bar {
                scale,
                title: format!("step along {} [{}]", AXIS_NAMES[axis], per_cycle(axis)),
                swatches,
            },
            Some(&|i, j| {
                let k = self.flat(i, j);
                (data.status[k] == 0).then(|| {
                    let step = data.step[axis][k];
                    if step.abs() < ZERO_STEP_M {
                        0
                    } else {
                        step.signum() as i8
                    }
                })
            }),
        )?;
        Ok(path)
    }

    /// Draws the map of the step's standard error along `axis` [µm per own
    /// drive cycle] when the file has the errors and one is above 0;
    /// returns its path, `None` when nothing was drawn.
    fn step_error_map(&self, axis: usize) -> Result<Option<PathBuf>> {
        let data = self.data;
        let Some(se) = &data.step_se else {
            return Ok(None);
        };
        // Status 6 ("not steady") keeps its estimate's error too.
        let shown = |k: usize| data.status[k] == 0 || data.status[k] == STATUS_NOT_STEADY;
        let errors_um: Vec<f64> = self
            .cells
            .iter()
            .filter(|&&k| shown(k))
            .map(|&k| se[axis][k] * 1e6)
            .collect();
        if !errors_um.iter().any(|&e| e > 0.0) {
            return Ok(None);
        }
        let escale = Diverging::covering(errors_um, 0.0, 1e-3, f64::INFINITY);
        let hidden = self.cells.iter().filter(|&&k| !shown(k)).count();
        let mut title = vec![
            format!(
                "{}: standard error of the step along {} [{}]",
                data.name,
                AXIS_NAMES[axis],
                per_cycle(axis)
            ),
            format!(
                "white: exact (the motion repeats); red: the statistical error of a \
                 motion that does not; colour limit {} µm",
                short(escale.half_width)
            ),
        ];
        title.extend(self.slice.line.clone());
        if hidden > 0 {
            title.push(format!(
                "grey: {hidden} of {} instances failed (see /maps/status)",
                self.cells.len()
            ));
        }
        let path = self.path(&format!("step_{}_se", AXIS_NAMES[axis]));
        let mut swatches = Vec::new();
        if hidden > 0 {
            swatches.push((FAILED, "failed (status ≠ 0, 6)".to_owned()));
        }
        heatmap(
            &path,
            &title,
            self.across,
            self.up,
            &|i, j| {
                let k = self.flat(i, j);
                if shown(k) {
                    escale.colour(se[axis][k] * 1e6)
                } else {
                    FAILED
                }
            },
            &MapLegend::Bar {
                scale: escale,
                title: format!(
                    "standard error along {} [{}]",
                    AXIS_NAMES[axis],
                    per_cycle(axis)
                ),
                swatches,
            },
        )?;
        Ok(Some(path))
    }

    /// Whether instance `k` and its 1-DOF baseline both ended with status 0.
    fn both_ok(&self, one_dof: OneDof, k: usize) -> bool {
        self.data.status[k] == 0 && one_dof.status[k] == 0
    }

    /// The 2-DOF step along `axis` over the 1-DOF step of instance `k`,
    /// `None` where either failed or the 1-DOF step is below
    /// [`ZERO_STEP_M`].
    fn ratio(&self, axis: usize, one_dof: OneDof, k: usize) -> Option<f64> {
        let one = one_dof.step[k];
        if self.both_ok(one_dof, k) && one.abs() >= ZERO_STEP_M {
            Some(self.data.step[axis][k] / one)
        } else {
            None
        }
    }

    /// Draws the map of the 2-DOF step over the 1-DOF step along `axis`;
    /// returns its path.
    fn ratio_map(&self, axis: usize, one_dof: OneDof) -> Result<PathBuf> {
        let data = self.data;
        let ratio = |k: usize| self.ratio(axis, one_dof, k);
        let ratios: Vec<f64> = self.cells.iter().filter_map(|&k| ratio(k)).collect();
        let rscale = Diverging::covering(ratios.iter().copied(), 1.0, 0.25, RATIO_HALF_WIDTH);
        let other = AXIS_NAMES[1 - axis];
        let a = AXIS_NAMES[axis];
        let mut title = vec![
            format!(
                "{}: 2-DOF step / 1-DOF step along {a} (the effect of driving {other} too)",
                data.name
            ),
            format!(
                "1-DOF: {a} driven alone at the same settings. White = 1 (unchanged), red > 1 \
                 amplified, blue < 1 reduced, below 0 reversed"
            ),
            format!(
                "colour limits {} to {}{}",
                short(rscale.limits().0),
                short(rscale.limits().1),
                if ratios.iter().any(|r| (r - 1.0).abs() > rscale.half_width) {
                    " (values beyond are drawn at the ends)"
                } else {
                    ""
                }
            ),
        ];
        title.extend(self.slice.line.clone());
        title.extend(data.fixed.clone());
        let path = self.path(&format!("ratio_{a}"));
        let mut swatches = vec![(UNDEFINED, "1-DOF step < 0.001 µm: no ratio".to_owned())];
        if self.cells.iter().any(|&k| !self.both_ok(one_dof, k)) {
            swatches.push((FAILED, "not computed (status ≠ 0)".to_owned()));
        }
        heatmap(
            &path,
            &title,
            self.across,
            self.up,
            &|i, j| {
                let k = self.flat(i, j);
                match ratio(k) {
                    Some(r) => rscale.colour(r),
                    None if self.both_ok(one_dof, k) => UNDEFINED,
                    None => FAILED,
                }
            },
            &MapLegend::Bar {
                scale: rscale,
                title: format!("2-DOF step / 1-DOF step along {a}"),
                swatches,
            },
        )?;
        Ok(path)
    }

    /// Draws the map of how driving the other axis changes the motion
    /// along `axis` ([`Regime`]); returns its path.
    fn regime_map(&self, axis: usize, one_dof: OneDof) -> Result<PathBuf> {
        let data = self.data;
        let regime = |k: usize| {
            Regime::classify(
                data.step[axis][k],
                one_dof.step[k],
                self.both_ok(one_dof, k),
            )
        };
        let mut counts = [0usize; Regime::ALL.len()];
        for &k in &self.cells {
            if let Some(r) = Regime::ALL.iter().position(|&r| r == regime(k)) {
                counts[r] += 1;
            }
        }
        let items: Vec<(RGBColor, String)> = Regime::ALL
            .iter()
            .zip(counts)
            .filter(|(_, n)| *n > 0)
            .map(|(r, n)| (r.colour(), format!("{} ({n})", r.describe())))
            .collect();
        let other = AXIS_NAMES[1 - axis];
        let a = AXIS_NAMES[axis];
        let mut title = vec![
            format!(
                "{}: how driving {other} changes the motion along {a}",
                data.name
            ),
            format!(
                "each cell compares the 2-DOF step along {a} with the 1-DOF step ({a} driven \
                 alone);"
            ),
            "a step below 0.001 µm counts as no motion. Counts of instances in brackets."
                .to_owned(),
        ];
        title.extend(self.slice.line.clone());
        title.extend(data.fixed.clone());
        let path = self.path(&format!("regime_{a}"));
        heatmap(
            &path,
            &title,
            self.across,
            self.up,
            &|i, j| regime(self.flat(i, j)).colour(),
            &MapLegend::Categories(items),
        )?;
        Ok(path)
    }

    /// Draws the map of the kinds of motion `motion` (one per instance);
    /// returns its path.
    fn motion_map(&self, motion: &[Motion]) -> Result<PathBuf> {
        let mut extra: Vec<String> = self.slice.line.iter().cloned().collect();
        extra.extend(self.data.fixed.clone());
        let path = self.path("motion");
        super::motion::motion_map(
            &path,
            self.data,
            motion,
            self.across,
            self.up,
            &|i, j| self.flat(i, j),
            &self.cells,
            &extra,
        )?;
        Ok(path)
    }
}

/// Ratio colour scales reach at most this far from 1.
const RATIO_HALF_WIDTH: f64 = 3.0;

/// The lighter colour an inferred value of a refined map is drawn in: a
/// third of the way to white, so the map reads the same and the inferred
/// plains show as a light veil.
fn paler(c: RGBColor) -> RGBColor {
    let mix = |v: u8| v + (255 - v) / 3;
    RGBColor(mix(c.0), mix(c.1), mix(c.2))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pictures_span_the_two_longest_axes() {
        let cases: [(&[usize], (usize, usize)); 5] = [
            (&[3, 4], (0, 1)),
            (&[61, 61], (0, 1)),
            (&[2, 13, 8], (1, 2)),
            (&[13, 2, 8], (0, 2)),
            (&[5, 5, 5, 9], (0, 3)),
        ];
        for (shape, want) in cases {
            let axes: Vec<AxisData> = shape
                .iter()
                .enumerate()
                .map(|(d, &n)| AxisData {
                    key: format!("k{d}"),
                    units: "1".into(),
                    values: (0..n).map(|v| v as f64).collect(),
                })
                .collect();
            let plane = Plane::choose(&axes, shape, &crate::plot::View::default()).unwrap();
            assert_eq!((plane.across, plane.up), want, "{shape:?}");
        }
    }

    use crate::scene::Scene;

    #[test]
    fn map_titles_name_the_drive_parameters_no_grid_axis_changes() {
        let scene = Scene::from_toml(
            "[axis.x]\nvoltage = [50.0, 100.0]\nduty = 0.9\n\
             [axis.y]\nvoltage = [0.0, 60.0]\nfrequency = 20.0\n",
            Some("t"),
        )
        .unwrap();
        assert_eq!(
            fixed_drive(&scene).as_deref(),
            Some("fixed: x 10 Hz, duty 0.9, phase 0; y 20 Hz, duty 0.9, phase 0")
        );
        // A grid over an x key that y inherits moves both.
        let scene = Scene::from_toml(
            "[axis.x]\nfrequency = [10.0, 20.0]\n[axis.y]\nvoltage = [0.0, 60.0]\n",
            Some("t"),
        )
        .unwrap();
        assert_eq!(
            fixed_drive(&scene).as_deref(),
            Some("fixed: x 100 V, duty 0.98, phase 0; y duty 0.98, phase 0")
        );
        // y undriven everywhere; a 1-D grid has no maps.
        let scene = Scene::from_toml(
            "[axis.x]\nvoltage = [50.0, 100.0]\nfrequency = [10.0, 20.0]\n",
            Some("t"),
        )
        .unwrap();
        assert_eq!(
            fixed_drive(&scene).as_deref(),
            Some("fixed: x duty 0.98, phase 0; y undriven")
        );
        let scene = Scene::from_toml("[axis.x]\nvoltage = [50.0, 100.0]\n", Some("t")).unwrap();
        assert_eq!(fixed_drive(&scene), None);
    }
}
