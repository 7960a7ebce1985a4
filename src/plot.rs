//! `pidm plot`: PNG pictures of a result file, for readers who do not know
//! the code.
//!
//! What is drawn depends on the file:
//!
//! - a grid with two or more axes: a heatmap of the step per axis for every
//!   2-D slice (the two axes with the most values span it, the earlier in
//!   the file across; one picture per combination of the other axes'
//!   values, at most [`MAX_SLICES`]),
//!   on a diverging colour scale centred on zero with symmetric limits, so a
//!   reversal of direction shows as a change of hue; with baselines also the
//!   ratio of the 2-DOF step to the 1-DOF step per axis and a map of the
//!   coupling regime ([`Regime`]);
//! - a grid with one axis: line plots of the steps (and baselines, ratios
//!   and regimes);
//! - a points scene (or a single instance): a bar chart of the steps, with
//!   the baselines beside them;
//! - every stored trajectory: stage and slider displacement against time
//!   per axis and the slider's path in the x-y plane, like the paper's
//!   Figs. 5-8.
//!
//! Steps are drawn in micrometres per own drive cycle; instances that ended
//! with a non-zero status are drawn in grey, never as a number.

use std::path::{Path, PathBuf};
use std::sync::Once;

use anyhow::{Context, Result, bail};
use hdf5::types::VarLenUnicode;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::model::AXIS_NAMES;
use crate::scene::{Layout, Scene};

/// At most this many 2-D slices are drawn per map of an N-D grid; beyond
/// it, evenly spaced slices are chosen and the choice is reported.
pub const MAX_SLICES: usize = 24;

/// Steps smaller than this in magnitude count as no motion in the coupling
/// regimes and ratios [m]: 0.001 um, the accuracy the maps are claimed to
/// have at the default tolerance.
pub const ZERO_STEP_M: f64 = 1e-9;

/// The colour of instances with a non-zero status: a neutral grey that no
/// colour scale here uses.
pub const FAILED: RGBColor = RGBColor(120, 120, 120);

/// The colour of cells where a ratio is undefined (1-DOF step about zero).
pub const UNDEFINED: RGBColor = RGBColor(205, 205, 205);

/// ColorBrewer's RdBu, from the most negative (dark blue) through the
/// neutral midpoint (near white) to the most positive (dark red).
const RDBU: [(u8, u8, u8); 11] = [
    (5, 48, 97),
    (33, 102, 172),
    (67, 147, 195),
    (146, 197, 222),
    (209, 229, 240),
    (247, 247, 247),
    (253, 219, 199),
    (244, 165, 130),
    (214, 96, 77),
    (178, 24, 43),
    (103, 0, 31),
];

/// The colour at the midpoint of the diverging scale.
pub const NEUTRAL: RGBColor = RGBColor(247, 247, 247);

/// Width and height of a map picture [px].
const MAP_SIZE: (u32, u32) = (1160, 860);
/// Width of the legend column right of a map [px].
const LEGEND_WIDTH: u32 = 330;
const FONT: &str = "sans-serif";

fn register_fonts() {
    static FONTS: Once = Once::new();
    FONTS.call_once(|| {
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular());
        let _ = plotters::style::register_font(FONT, FontStyle::Bold, dejavu::sans::bold());
    });
}

// ---------------------------------------------------------------------------
// Colour scales and regimes: pure functions, unit-tested.

/// A diverging colour scale with limits symmetric about its centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Diverging {
    /// The value drawn in the neutral colour.
    pub centre: f64,
    /// Distance from the centre to either end of the scale; values beyond
    /// are drawn at the ends.
    pub half_width: f64,
}

impl Diverging {
    /// The scale that just covers `values` (non-finite ones ignored), with
    /// limits symmetric about `centre`, its half width at least
    /// `min_half_width` (so values that differ from the centre by less, such
    /// as rounding noise around zero, stay pale) and at most
    /// `max_half_width` (values beyond are drawn at the ends).
    pub fn covering(
        values: impl IntoIterator<Item = f64>,
        centre: f64,
        min_half_width: f64,
        max_half_width: f64,
    ) -> Self {
        let spread = values
            .into_iter()
            .filter(|v| v.is_finite())
            .fold(0.0f64, |m, v| m.max((v - centre).abs()));
        Diverging {
            centre,
            half_width: spread.min(max_half_width).max(min_half_width),
        }
    }

    /// The lowest and highest value of the scale.
    pub fn limits(&self) -> (f64, f64) {
        (self.centre - self.half_width, self.centre + self.half_width)
    }

    /// Position of `value` on the scale, 0 (low end) to 1 (high end), 0.5 at
    /// the centre.
    pub fn fraction(&self, value: f64) -> f64 {
        (0.5 + 0.5 * (value - self.centre) / self.half_width).clamp(0.0, 1.0)
    }

    /// The colour of `value`.
    pub fn colour(&self, value: f64) -> RGBColor {
        rdbu(self.fraction(value))
    }
}

/// RdBu at a fraction 0..1 (linear between the eleven classes); exactly
/// [`NEUTRAL`] at 0.5.
pub fn rdbu(fraction: f64) -> RGBColor {
    let x = fraction.clamp(0.0, 1.0) * (RDBU.len() - 1) as f64;
    let i = (x.floor() as usize).min(RDBU.len() - 2);
    let t = x - i as f64;
    let (a, b) = (RDBU[i], RDBU[i + 1]);
    let mix = |p: u8, q: u8| (p as f64 + (q as f64 - p as f64) * t).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// How the motion along one axis changes when the other axis is driven too:
/// the 2-DOF step against the 1-DOF step (the axis driven alone).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Regime {
    /// Both move, in opposite directions.
    Reversed,
    /// The 2-DOF step is larger in magnitude, same direction.
    Amplified,
    /// The axis moves only when the other is driven too (its 1-DOF step is
    /// about zero).
    Started,
    /// The 2-DOF step is smaller in magnitude, same direction.
    Reduced,
    /// The two steps agree within [`ZERO_STEP_M`].
    Unchanged,
    /// The axis moves alone but not in 2-DOF.
    Stalled,
    /// The axis moves in neither.
    AtRest,
    /// The instance or a baseline ended with a non-zero status.
    Failed,
}

impl Regime {
    /// Every regime, in legend order.
    pub const ALL: [Regime; 8] = [
        Regime::Reversed,
        Regime::Amplified,
        Regime::Started,
        Regime::Reduced,
        Regime::Unchanged,
        Regime::Stalled,
        Regime::AtRest,
        Regime::Failed,
    ];

    /// Classifies a 2-DOF step against its 1-DOF step [m]; `ok` is false
    /// when either run ended with a non-zero status.
    pub fn classify(two_dof: f64, one_dof: f64, ok: bool) -> Regime {
        let moves = |s: f64| s.abs() >= ZERO_STEP_M;
        if !ok || !two_dof.is_finite() || !one_dof.is_finite() {
            Regime::Failed
        } else if !moves(two_dof) && !moves(one_dof) {
            Regime::AtRest
        } else if !moves(two_dof) {
            Regime::Stalled
        } else if (two_dof - one_dof).abs() < ZERO_STEP_M {
            Regime::Unchanged
        } else if !moves(one_dof) {
            Regime::Started
        } else if two_dof.signum() != one_dof.signum() {
            Regime::Reversed
        } else if two_dof.abs() > one_dof.abs() {
            Regime::Amplified
        } else {
            Regime::Reduced
        }
    }

    /// Its colour in regime maps.
    pub fn colour(self) -> RGBColor {
        match self {
            Regime::Reversed => RGBColor(33, 102, 172),
            Regime::Amplified => RGBColor(178, 24, 43),
            Regime::Started => RGBColor(118, 42, 131),
            Regime::Reduced => RGBColor(244, 165, 130),
            Regime::Unchanged => RGBColor(230, 220, 180),
            Regime::Stalled => RGBColor(20, 20, 20),
            Regime::AtRest => RGBColor(255, 255, 255),
            Regime::Failed => FAILED,
        }
    }

    /// Its legend text.
    pub fn describe(self) -> &'static str {
        match self {
            Regime::Reversed => "reversed: opposite sign to 1-DOF",
            Regime::Amplified => "amplified: |2-DOF| > |1-DOF|",
            Regime::Started => "started: moves only in 2-DOF",
            Regime::Reduced => "reduced: |2-DOF| < |1-DOF|",
            Regime::Unchanged => "unchanged (within 0.001 µm)",
            Regime::Stalled => "stalled: moves only in 1-DOF",
            Regime::AtRest => "at rest in both",
            Regime::Failed => "not computed (status ≠ 0)",
        }
    }
}

// ---------------------------------------------------------------------------
// Reading a result file.

/// One grid axis as stored in `/axes`.
#[derive(Clone, Debug)]
struct AxisData {
    key: String,
    units: String,
    values: Vec<f64>,
}

/// What kind of instances the file holds.
enum Kind {
    Grid(Vec<AxisData>),
    Points(Vec<String>),
}

/// One stored run in time: the point's, or a 1-DOF run beside it (which
/// holds only its driven axis' series).
struct RunData {
    /// Sample times [s].
    time: Vec<f64>,
    /// Stage and slider displacement per axis [m].
    stage: [Vec<f64>; 2],
    slider: [Vec<f64>; 2],
    /// Drive amplitude [V], frequency [Hz], rise fraction and phase
    /// [cycles] per axis.
    voltage: [f64; 2],
    frequency: [f64; 2],
    duty: [f64; 2],
    phase: [f64; 2],
    /// Scene period and the end of the settle periods [s].
    period_s: f64,
    settle_s: f64,
    /// End of the measured periods [s].
    measured_end_s: f64,
    /// Integrator status at the end of the run (0 = ok).
    status: u64,
}

impl RunData {
    /// The slider's step per own drive cycle of axis `a` over the measured
    /// periods, from the samples [um]; `None` when they do not cover them.
    fn step_um(&self, a: usize) -> Option<f64> {
        let at = |t: f64| {
            self.time
                .iter()
                .position(|&s| s >= t - 1e-9 * self.period_s)
        };
        let (i, j) = (at(self.settle_s)?, at(self.measured_end_s)?);
        let kept = self.time[j] - self.time[i];
        (kept > 0.0 && self.frequency[a] > 0.0 && self.status == 0)
            .then(|| (self.slider[a][j] - self.slider[a][i]) / kept / self.frequency[a] * 1e6)
    }
}

/// A stored trajectory.
struct TrajectoryData {
    point: String,
    /// The point's label in a points scene, else "".
    label: String,
    /// The flat instance index.
    index: u64,
    run: RunData,
    /// The 1-DOF runs, x driven alone and y driven alone.
    baselines: Option<[RunData; 2]>,
}

/// Everything `pidm plot` reads.
struct Data {
    name: String,
    kind: Kind,
    shape: Vec<usize>,
    /// Steps per axis [m per own drive cycle], row-major.
    step: [Vec<f64>; 2],
    status: Vec<u32>,
    baseline: Option<([Vec<f64>; 2], Vec<u32>)>,
    trajectories: Vec<TrajectoryData>,
    notes: Vec<String>,
}

fn read_str_attr(loc: &hdf5::Location, name: &str) -> Option<String> {
    crate::output::read_str_attr(loc, name).ok()
}

fn read_f64_attr(loc: &hdf5::Location, name: &str) -> f64 {
    loc.attr(name)
        .and_then(|a| a.read_scalar::<f64>())
        .unwrap_or(f64::NAN)
}

fn read_f64(file: &hdf5::Group, name: &str) -> Result<Vec<f64>> {
    file.dataset(name)
        .and_then(|d| d.read_raw::<f64>())
        .with_context(|| format!("cannot read dataset /{name}"))
}

impl Data {
    fn read(path: &Path) -> Result<Data> {
        let file = hdf5::File::open(path)
            .with_context(|| format!("cannot open {} as HDF5", path.display()))?;
        let stem = path
            .file_stem()
            .map_or_else(|| "result".to_owned(), |s| s.to_string_lossy().into_owned());
        if file.attr("shard_index").is_ok() {
            bail!(
                "{} is one shard of a sharded run (its maps hold only that shard's \
                 instances); join the shards with `pidm merge OUT.h5 SHARDS...` and plot OUT.h5",
                path.display()
            );
        }
        let mut notes = Vec::new();
        let name = read_str_attr(&file, "name").unwrap_or(stem);
        let scene = read_str_attr(&file, "scene")
            .and_then(|text| Scene::from_toml(&text, Some(&name)).ok());
        if !file.link_exists("maps") {
            bail!(
                "{} has no /maps group: not a pidm result file",
                path.display()
            );
        }
        let step_x = file
            .dataset("maps/step_x")
            .context("cannot read /maps/step_x")?;
        let shape = step_x.shape();
        let step = [
            read_f64(&file, "maps/step_x")?,
            read_f64(&file, "maps/step_y")?,
        ];
        let count: usize = shape.iter().product();
        let status: Vec<u32> = file
            .dataset("maps/status")
            .and_then(|d| d.read_raw::<u32>())
            .unwrap_or_else(|_| vec![0; count]);
        let baseline = if file.link_exists("baseline") {
            let bs = [
                read_f64(&file, "baseline/step_x")?,
                read_f64(&file, "baseline/step_y")?,
            ];
            let bstatus = file
                .dataset("baseline/status")
                .and_then(|d| d.read_raw::<u32>())
                .unwrap_or_else(|_| vec![0; count]);
            Some((bs, bstatus))
        } else {
            None
        };
        let kind = if file.link_exists("labels") {
            let labels: Vec<VarLenUnicode> = file.dataset("labels")?.read_raw()?;
            Kind::Points(labels.iter().map(|l| l.as_str().to_owned()).collect())
        } else {
            Kind::Grid(read_axes(&file, &shape, scene.as_ref(), &mut notes)?)
        };
        let trajectories = read_trajectories(&file)?;
        Ok(Data {
            name,
            kind,
            shape,
            step,
            status,
            baseline,
            trajectories,
            notes,
        })
    }
}

/// The grid axes in grid order. HDF5 lists `/axes` alphabetically, so the
/// order comes from the stored scene when it parses; otherwise each
/// dimension takes the first unused axis of its length.
fn read_axes(
    file: &hdf5::File,
    shape: &[usize],
    scene: Option<&Scene>,
    notes: &mut Vec<String>,
) -> Result<Vec<AxisData>> {
    let read = |key: &str| -> Result<AxisData> {
        let ds = file.dataset(&format!("axes/{key}"))?;
        Ok(AxisData {
            key: key.to_owned(),
            units: read_str_attr(&ds, "units").unwrap_or_else(|| "1".to_owned()),
            values: ds.read_raw()?,
        })
    };
    if let Some(Scene {
        layout: Layout::Grid { axes },
        ..
    }) = scene
    {
        let out: Vec<AxisData> = axes
            .iter()
            .map(|a| read(&a.key))
            .collect::<Result<_>>()
            .unwrap_or_default();
        if out.len() == shape.len() && out.iter().zip(shape).all(|(a, &n)| a.values.len() == n) {
            return Ok(out);
        }
    }
    let names = if file.link_exists("axes") {
        file.group("axes")?.member_names()?
    } else {
        Vec::new()
    };
    let mut all: Vec<AxisData> = names.iter().map(|n| read(n)).collect::<Result<_>>()?;
    let mut out = Vec::with_capacity(shape.len());
    for (d, &n) in shape.iter().enumerate() {
        match all.iter().position(|a| a.values.len() == n) {
            Some(i) => out.push(all.remove(i)),
            None => out.push(AxisData {
                key: format!("dimension {d}"),
                units: "1".to_owned(),
                values: (0..n).map(|v| v as f64).collect(),
            }),
        }
    }
    if !shape.is_empty() {
        notes.push(
            "the stored scene did not give the grid order; axes were matched to dimensions \
             by length"
                .to_owned(),
        );
    }
    Ok(out)
}

/// Reads the attributes and time of a run group.
fn read_run(g: &hdf5::Group) -> Result<RunData> {
    let per_axis = |attr: &str| {
        [
            read_f64_attr(g, &format!("{attr}_x")),
            read_f64_attr(g, &format!("{attr}_y")),
        ]
    };
    let period_s = read_f64_attr(g, "period_s");
    let measured_cycles = g
        .attr("measured_cycles")
        .and_then(|a| a.read_scalar::<u64>())
        .ok();
    let duration_s = read_f64_attr(g, "duration_s");
    Ok(RunData {
        time: read_f64(g, "time")?,
        stage: [Vec::new(), Vec::new()],
        slider: [Vec::new(), Vec::new()],
        voltage: per_axis("voltage"),
        frequency: per_axis("frequency"),
        duty: per_axis("duty"),
        phase: per_axis("phase"),
        period_s,
        settle_s: read_f64_attr(g, "settle_s"),
        measured_end_s: measured_cycles.map_or(duration_s, |c| c as f64 * period_s),
        status: g
            .attr("status")
            .and_then(|a| a.read_scalar::<u64>())
            .unwrap_or(0),
    })
}

fn read_trajectories(file: &hdf5::File) -> Result<Vec<TrajectoryData>> {
    if !file.link_exists("trajectories") {
        return Ok(Vec::new());
    }
    let root = file.group("trajectories")?;
    let mut names = root.member_names()?;
    names.sort_by_key(|n| n.parse::<u64>().unwrap_or(u64::MAX));
    let mut out = Vec::with_capacity(names.len());
    for name in names {
        let g = root.group(&name)?;
        let mut run = read_run(&g)?;
        for (a, axis) in AXIS_NAMES.iter().enumerate() {
            run.stage[a] = read_f64(&g, &format!("stage_{axis}"))?;
            run.slider[a] = read_f64(&g, &format!("slider_{axis}"))?;
        }
        let baselines = if g.link_exists("baseline_x") && g.link_exists("baseline_y") {
            let mut pair = Vec::with_capacity(2);
            for (a, axis) in AXIS_NAMES.iter().enumerate() {
                let b = g.group(&format!("baseline_{axis}"))?;
                let mut base = read_run(&b)?;
                base.stage[a] = read_f64(&b, "stage")?;
                base.slider[a] = read_f64(&b, "slider")?;
                pair.push(base);
            }
            let y = pair.pop();
            let x = pair.pop();
            x.zip(y).map(|(x, y)| [x, y])
        } else {
            None
        };
        out.push(TrajectoryData {
            point: read_str_attr(&g, "point").unwrap_or_else(|| format!("trajectory {name}")),
            label: read_str_attr(&g, "label").unwrap_or_default(),
            index: g
                .attr("index")
                .and_then(|a| a.read_scalar::<u64>())
                .unwrap_or(u64::MAX),
            run,
            baselines,
        });
    }
    Ok(out)
}

// ---------------------------------------------------------------------------
// Text helpers.

/// A plain-words name of a scene key's last part.
fn key_meaning(key: &str) -> Option<String> {
    let mut parts = key.split('.');
    let table = parts.next()?;
    let axis = if table == "axis" { parts.next() } else { None };
    let field = parts.next_back()?;
    let what = match field {
        "voltage" => "drive amplitude",
        "frequency" => "drive frequency",
        "phase" => "drive phase",
        "duty" => "drive rise fraction",
        "gain" => "actuator gain",
        "stage_mass" => "stage mass",
        "stiffness" => "stage stiffness",
        "damping" => "stage damping",
        "resonance_hz" => "stage resonance",
        "quality_factor" => "stage quality factor",
        "slider_mass" => "slider mass",
        "static_friction" => "static friction",
        "coulomb_friction" => "sliding friction",
        "velocity_band" => "velocity band",
        "cycles" => "simulated periods",
        "settle" => "settle periods",
        _ => return None,
    };
    Some(match axis {
        Some(a) => format!("{a} {what}"),
        None => what.to_owned(),
    })
}

/// An axis title: key, meaning and unit, e.g. "axis.x.voltage (x drive
/// amplitude) [V]".
fn axis_title(key: &str, units: &str) -> String {
    let meaning = key_meaning(key).map_or(String::new(), |m| format!(" ({m})"));
    let unit = if units == "1" || units.is_empty() {
        String::new()
    } else {
        format!(" [{units}]")
    };
    format!("{key}{meaning}{unit}")
}

/// A number for labels: up to four significant digits, no trailing zeros.
fn short(value: f64) -> String {
    if value == 0.0 || !value.is_finite() {
        return format!("{value}");
    }
    let magnitude = value.abs().log10().floor();
    if (-3.0..6.0).contains(&magnitude) {
        let decimals = (3.0 - magnitude).max(0.0) as usize;
        let text = format!("{value:.decimals$}");
        if text.contains('.') {
            text.trim_end_matches('0').trim_end_matches('.').to_owned()
        } else {
            text
        }
    } else {
        format!("{value:.2e}")
    }
}

/// A value with its unit, e.g. "100 V".
fn with_unit(value: f64, units: &str) -> String {
    if units == "1" || units.is_empty() {
        short(value)
    } else {
        format!("{} {units}", short(value))
    }
}

/// A file name part from free text: lower-case letters, digits, '-' and
/// '_' for anything else.
fn slug(text: &str) -> String {
    let mut out = String::new();
    for c in text.chars() {
        if c.is_ascii_alphanumeric() || c == '-' {
            out.push(c.to_ascii_lowercase());
        } else if !out.ends_with('_') {
            out.push('_');
        }
    }
    out.trim_matches('_').to_owned()
}

fn font(size: u32) -> TextStyle<'static> {
    (FONT, size).into_font().color(&BLACK)
}

fn bold(size: u32) -> TextStyle<'static> {
    (FONT, size, FontStyle::Bold).into_font().color(&BLACK)
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// Draws a bold first line and plain further lines at the top of `area`
/// and returns the area below them.
fn title_block<'a>(area: &Area<'a>, lines: &[String]) -> Result<Area<'a>> {
    let height = 20 + 32 + 22 * lines.len().saturating_sub(1) as u32;
    let (top, rest) = area.split_vertically(height);
    let mut y = 10;
    for (k, line) in lines.iter().enumerate() {
        let style = if k == 0 { bold(22) } else { font(16) };
        top.draw_text(line, &style, (20, y))?;
        y += if k == 0 { 32 } else { 22 };
    }
    Ok(rest)
}

/// Draws one legend entry (a swatch and its text) at `(x, y)` of `area`.
fn swatch(area: &Area<'_>, x: i32, y: i32, colour: RGBColor, text: &str) -> Result<()> {
    area.draw(&Rectangle::new([(x, y), (x + 18, y + 18)], colour.filled()))?;
    area.draw(&Rectangle::new(
        [(x, y), (x + 18, y + 18)],
        BLACK.stroke_width(1),
    ))?;
    area.draw_text(text, &font(14), (x + 26, y + 2))?;
    Ok(())
}

/// Draws a picture in memory and writes it as a PNG at the best
/// compression (about half the size plotters' own encoder gives), through a
/// temporary name, so a failed drawing leaves no half-written file under
/// the final name.
fn save(path: &Path, size: (u32, u32), draw: impl FnOnce(&Area<'_>) -> Result<()>) -> Result<()> {
    register_fonts();
    let mut pixels = vec![0u8; size.0 as usize * size.1 as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area();
        root.fill(&WHITE)?;
        draw(&root)?;
        root.present()?;
    }
    let temp = path.with_extension("partial.png");
    let write = || -> Result<()> {
        let file = std::io::BufWriter::new(std::fs::File::create(&temp)?);
        let mut encoder = png::Encoder::new(file, size.0, size.1);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_compression(png::Compression::Best);
        encoder.set_adaptive_filter(png::AdaptiveFilterType::Adaptive);
        let mut writer = encoder.write_header()?;
        writer.write_image_data(&pixels)?;
        writer.finish()?;
        Ok(())
    };
    write().with_context(|| format!("cannot write {}", temp.display()))?;
    std::fs::rename(&temp, path).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

// ---------------------------------------------------------------------------
// Heatmaps.

/// How a grid axis is laid out on the page: linearly, or by the logarithm
/// of its values when they are geometrically spaced.
#[derive(Clone, Copy)]
struct Placement {
    log: bool,
}

impl Placement {
    fn of(values: &[f64]) -> Placement {
        let n = values.len();
        let log = n > 2 && values.iter().all(|&v| v > 0.0) && {
            let ratio = values[1] / values[0];
            (ratio - 1.0).abs() > 1e-9
                && values
                    .windows(2)
                    .all(|w| ((w[1] / w[0]) / ratio - 1.0).abs() < 1e-6)
        };
        Placement { log }
    }

    fn place(self, v: f64) -> f64 {
        if self.log { v.log10() } else { v }
    }

    fn value(self, c: f64) -> f64 {
        if self.log { 10f64.powf(c) } else { c }
    }

    /// Cell edges on the page: halfway between neighbouring values, and as
    /// far again beyond the ends.
    fn edges(self, values: &[f64]) -> Vec<f64> {
        let c: Vec<f64> = values.iter().map(|&v| self.place(v)).collect();
        let n = c.len();
        if n == 1 {
            return vec![c[0] - 0.5, c[0] + 0.5];
        }
        let mut e = Vec::with_capacity(n + 1);
        e.push(c[0] - 0.5 * (c[1] - c[0]));
        for w in c.windows(2) {
            e.push(0.5 * (w[0] + w[1]));
        }
        e.push(c[n - 1] + 0.5 * (c[n - 1] - c[n - 2]));
        e
    }
}

/// At most eight of an axis' values, evenly spaced by index, for labels.
fn label_values(values: &[f64]) -> Vec<f64> {
    let n = values.len();
    let count = n.min(8);
    if count < 2 {
        return values.to_vec();
    }
    (0..count)
        .map(|k| values[k * (n - 1) / (count - 1)])
        .collect()
}

/// What the right-hand column of a map shows.
enum MapLegend {
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

/// Draws one heatmap: `colour(i, j)` is the cell at value i of `across`
/// and value j of `up`.
fn heatmap(
    path: &Path,
    title: &[String],
    across: &AxisData,
    up: &AxisData,
    colour: &dyn Fn(usize, usize) -> RGBColor,
    legend: &MapLegend,
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
        .y_label_formatter(&|v| short(*v))
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

/// The two dimensions a grid's pictures span: those with the most values
/// (the earlier on ties), in grid order.
pub fn plane_dims(shape: &[usize]) -> (usize, usize) {
    let mut dims: Vec<usize> = (0..shape.len()).collect();
    dims.sort_by_key(|&d| std::cmp::Reverse(shape[d]));
    let (a, b) = (dims[0], dims[1]);
    (a.min(b), a.max(b))
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

/// The per-axis words for map titles.
fn per_cycle(axis: usize) -> String {
    format!("µm per {} drive cycle", AXIS_NAMES[axis])
}

/// Writes the heatmaps of a grid with two or more axes.
fn grid_maps(
    data: &Data,
    axes: &[AxisData],
    dir: &Path,
    files: &mut Vec<PathBuf>,
    notes: &mut Vec<String>,
) -> Result<()> {
    let shape = &data.shape;
    let (p, q) = plane_dims(shape);
    let rest: Vec<usize> = (0..shape.len()).filter(|&d| d != p && d != q).collect();
    let rest_shape: Vec<usize> = rest.iter().map(|&d| shape[d]).collect();
    let mut strides = vec![1; shape.len()];
    for d in (0..shape.len().saturating_sub(1)).rev() {
        strides[d] = strides[d + 1] * shape[d + 1];
    }
    let (combos, total) = slices(&rest_shape);
    if combos.len() < total {
        notes.push(format!(
            "{total} slices over {} per map; drew {} evenly spaced ones",
            rest.iter()
                .map(|&d| axes[d].key.as_str())
                .collect::<Vec<_>>()
                .join(" x "),
            combos.len()
        ));
    }
    let (n0, n1) = (shape[p], shape[q]);
    let (across, up) = (&axes[p], &axes[q]);
    for combo in &combos {
        let offset: usize = combo.iter().zip(&rest).map(|(&i, &d)| i * strides[d]).sum();
        let flat = |i: usize, j: usize| i * strides[p] + j * strides[q] + offset;
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
        let suffix: String = combo
            .iter()
            .zip(&rest)
            .map(|(&i, &d)| format!("__{}={}", axes[d].key, short(axes[d].values[i])))
            .collect();
        let slice_line = if at.is_empty() {
            None
        } else {
            Some(format!("slice at {}", at.join(", ")))
        };
        let cells: Vec<usize> = (0..n0)
            .flat_map(|i| (0..n1).map(move |j| (i, j)))
            .map(|(i, j)| flat(i, j))
            .collect();
        let failed = cells.iter().filter(|&&k| data.status[k] != 0).count();
        let failed_line = (failed > 0).then(|| {
            format!(
                "grey: {failed} of {} instances ended with a non-zero status (see \
                 /maps/status); no value is drawn",
                cells.len()
            )
        });
        for axis in 0..2 {
            let steps_um: Vec<f64> = cells
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
            ];
            title.extend(slice_line.clone());
            title.extend(failed_line.clone());
            let path = dir.join(format!("step_{}{suffix}.png", AXIS_NAMES[axis]));
            let mut swatches = Vec::new();
            if failed > 0 {
                swatches.push((FAILED, "not computed (status ≠ 0)".to_owned()));
            }
            heatmap(
                &path,
                &title,
                across,
                up,
                &|i, j| {
                    let k = flat(i, j);
                    if data.status[k] != 0 {
                        FAILED
                    } else {
                        scale.colour(data.step[axis][k] * 1e6)
                    }
                },
                &MapLegend::Bar {
                    scale,
                    title: format!("step along {} [{}]", AXIS_NAMES[axis], per_cycle(axis)),
                    swatches,
                },
            )?;
            files.push(path);

            let Some((base, base_status)) = &data.baseline else {
                continue;
            };
            let ok = |k: usize| data.status[k] == 0 && base_status[k] == 0;
            let ratio = |k: usize| {
                let one = base[axis][k];
                if ok(k) && one.abs() >= ZERO_STEP_M {
                    Some(data.step[axis][k] / one)
                } else {
                    None
                }
            };
            let ratios: Vec<f64> = cells.iter().filter_map(|&k| ratio(k)).collect();
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
            title.extend(slice_line.clone());
            let path = dir.join(format!("ratio_{a}{suffix}.png"));
            let mut swatches = vec![(UNDEFINED, "1-DOF step < 0.001 µm: no ratio".to_owned())];
            if cells.iter().any(|&k| !ok(k)) {
                swatches.push((FAILED, "not computed (status ≠ 0)".to_owned()));
            }
            heatmap(
                &path,
                &title,
                across,
                up,
                &|i, j| {
                    let k = flat(i, j);
                    match ratio(k) {
                        Some(r) => rscale.colour(r),
                        None if ok(k) => UNDEFINED,
                        None => FAILED,
                    }
                },
                &MapLegend::Bar {
                    scale: rscale,
                    title: format!("2-DOF step / 1-DOF step along {a}"),
                    swatches,
                },
            )?;
            files.push(path);

            let regime = |k: usize| Regime::classify(data.step[axis][k], base[axis][k], ok(k));
            let mut counts = [0usize; Regime::ALL.len()];
            for &k in &cells {
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
            title.extend(slice_line.clone());
            let path = dir.join(format!("regime_{a}{suffix}.png"));
            heatmap(
                &path,
                &title,
                across,
                up,
                &|i, j| regime(flat(i, j)).colour(),
                &MapLegend::Categories(items),
            )?;
            files.push(path);
        }
    }
    Ok(())
}

/// Ratio colour scales reach at most this far from 1.
const RATIO_HALF_WIDTH: f64 = 3.0;

// ---------------------------------------------------------------------------
// Line plots of 1-D grids.

/// One line of a line chart.
struct Series {
    name: String,
    colour: RGBColor,
    /// Dashed without dots (1-DOF), or solid with a dot per value.
    dashed: bool,
    /// (grid value, y) pairs.
    points: Vec<(f64, f64)>,
}

/// A line chart against one grid axis.
struct LineChart<'a> {
    title: Vec<String>,
    axis: &'a AxisData,
    y_title: &'a str,
    /// A horizontal black line at this y.
    reference: f64,
    series: Vec<Series>,
    /// Extra dots (grid value, y, colour), drawn over the lines.
    markers: Vec<(f64, f64, RGBColor)>,
    /// Swatches listed after the series in the legend.
    extra_legend: Vec<(RGBColor, String)>,
}

impl LineChart<'_> {
    fn draw(&self, path: &Path) -> Result<()> {
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
                .y_label_formatter(&|v| short(*v))
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

const X_COLOUR: RGBColor = RGBColor(33, 102, 172);
const Y_COLOUR: RGBColor = RGBColor(178, 24, 43);

fn axis_colour(axis: usize) -> RGBColor {
    if axis == 0 { X_COLOUR } else { Y_COLOUR }
}

/// Writes the line plots of a grid with one axis.
fn grid_lines(data: &Data, axis: &AxisData, dir: &Path, files: &mut Vec<PathBuf>) -> Result<()> {
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
    let path = dir.join("steps.png");
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
    .draw(&path)?;
    files.push(path);

    let Some((base, bstatus)) = &data.baseline else {
        return Ok(());
    };
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
    let path = dir.join("ratio.png");
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
    .draw(&path)?;
    files.push(path);
    Ok(())
}

// ---------------------------------------------------------------------------
// Bar charts of points.

/// Writes the bar chart of a points scene (or of a single instance).
fn point_bars(data: &Data, labels: &[String], dir: &Path, files: &mut Vec<PathBuf>) -> Result<()> {
    let n = labels.len();
    let base = data.baseline.as_ref();
    // Bars per point: 2-DOF x, 1-DOF x, 2-DOF y, 1-DOF y (the 1-DOF ones
    // only with baselines).
    let mut bars: Vec<(usize, usize, bool, f64, bool)> = Vec::new();
    for k in 0..n {
        for a in 0..2 {
            bars.push((k, a, false, data.step[a][k] * 1e6, data.status[k] == 0));
            if let Some((b, bs)) = base {
                bars.push((k, a, true, b[a][k] * 1e6, bs[k] == 0));
            }
        }
    }
    let per = if base.is_some() { 4 } else { 2 };
    let values: Vec<f64> = bars.iter().filter(|b| b.4).map(|b| b.3).collect();
    let hi = values.iter().copied().fold(0.0f64, f64::max);
    let lo = values.iter().copied().fold(0.0f64, f64::min);
    let pad = 0.15 * (hi - lo).max(1e-6);
    let failed = (0..n).filter(|&k| data.status[k] != 0).count();
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
    let width = (1100u32).max(220 * n as u32 + LEGEND_WIDTH + 120).min(4000);
    let path = dir.join("steps.png");
    save(&path, (width, 760), |root| {
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
            .y_desc("step [µm per own drive cycle]")
            .y_label_formatter(&|v| short(*v))
            .label_style(font(15))
            .axis_desc_style(font(17))
            .draw()?;
        chart.draw_series(LineSeries::new(
            vec![(0.0, 0.0), (n as f64, 0.0)],
            BLACK.stroke_width(1),
        ))?;
        let slot = 0.8 / per as f64;
        for (m, &(k, a, is_base, value, ok)) in bars.iter().enumerate() {
            let j = m % per;
            let x0 = k as f64 + 0.1 + slot * j as f64;
            let x1 = x0 + slot * 0.9;
            let colour = if !ok {
                FAILED
            } else if is_base {
                light(axis_colour(a), 0.35)
            } else {
                axis_colour(a)
            };
            let v = if ok {
                value
            } else {
                0.04 * (hi - lo).max(1e-6)
            };
            chart.draw_series(std::iter::once(Rectangle::new(
                [(x0, 0.0), (x1, v)],
                colour.filled(),
            )))?;
            if is_base {
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
        }
        for (k, label) in labels.iter().enumerate() {
            let (px, py) = chart.backend_coord(&(k as f64 + 0.5, lo - pad));
            root.draw_text(
                label,
                &font(16).pos(Pos::new(HPos::Center, VPos::Top)),
                (px, py + 8),
            )?;
        }
        let mut items = vec![
            (X_COLOUR, "2-DOF step along x".to_owned()),
            (Y_COLOUR, "2-DOF step along y".to_owned()),
        ];
        if base.is_some() {
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
        for (k, (c, text)) in items.iter().enumerate() {
            swatch(&right, 0, 30 + 30 * k as i32, *c, text)?;
        }
        Ok(())
    })?;
    files.push(path);
    Ok(())
}

// ---------------------------------------------------------------------------
// Trajectories.

/// A colour blended towards white by `keep` (1: unchanged).
fn light(c: RGBColor, keep: f64) -> RGBColor {
    let f = |v: u8| (255.0 - (255.0 - v as f64) * keep).round() as u8;
    RGBColor(f(c.0), f(c.1), f(c.2))
}

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

const BASELINE_GREY: RGBColor = RGBColor(150, 150, 150);
const SETTLE_GREY: RGBColor = RGBColor(236, 236, 236);

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
fn trajectory_figure(data: &Data, k: usize, t: &TrajectoryData, dir: &Path) -> Result<PathBuf> {
    let name = if t.label.is_empty() {
        format!("instance_{}", t.index)
    } else {
        slug(&t.label)
    };
    let path = dir.join(format!("trajectory_{name}.png"));
    let run = &t.run;
    let ms = |time: &[f64]| time.iter().map(|s| s * 1e3).collect::<Vec<f64>>();
    let um = |v: &[f64]| v.iter().map(|x| x * 1e6).collect::<Vec<f64>>();
    let time_ms = ms(&run.time);
    let describe_axis = |a: usize| {
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
    };
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
            describe_axis(0),
            describe_axis(1)
        ),
        steps_line,
    ];
    if run.status != 0 {
        title.push(format!(
            "the run ended early with status {} (README: status codes); the curves stop there",
            run.status
        ));
    }
    let size = (1600u32, 1120u32);
    let title_height = 110;
    save(&path, size, |root| {
        let body = title_block(root, &title)?;
        let (left, right) = body.split_horizontally(1000);
        let (top, bottom) = left.split_vertically((size.1 - title_height) / 2);
        let t_end = time_ms.last().copied().unwrap_or(1.0);
        let settle_ms = run.settle_s * 1e3;
        for (a, area) in [(0usize, &top), (1usize, &bottom)] {
            let stage = um(&run.stage[a]);
            let slider = um(&run.slider[a]);
            let base = t
                .baselines
                .as_ref()
                .map(|b| (ms(&b[a].time), um(&b[a].stage[a]), um(&b[a].slider[a])));
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
        }

        let (path_area, rest) = right.split_vertically(500);
        let (zoom_area, legend_area) = rest.split_vertically(290);
        // The slider path in the x-y plane, on equal scales.
        let xs = um(&run.slider[0]);
        let ys = um(&run.slider[1]);
        let range = covering_range(xs.iter().chain(&ys));
        let mut chart = ChartBuilder::on(&path_area)
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

        // A zoom on the fast fall that ends the second-to-last period.
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
        if window.len() >= 2 {
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
            let mut chart = ChartBuilder::on(&zoom_area)
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
        }
        trajectory_legend(&legend_area, 20, 10, t.baselines.is_some())?;
        Ok(())
    })?;
    Ok(path)
}

// ---------------------------------------------------------------------------
// The command.

/// What `pidm plot` wrote.
#[derive(Clone, Debug, Default)]
pub struct Plotted {
    /// Every PNG written, in order.
    pub files: Vec<PathBuf>,
    /// Things the reader should know (slices left out, guessed axis order).
    pub notes: Vec<String>,
}

/// Default output folder: `results/plots/<file stem>/`.
pub fn default_out_dir(file: &Path) -> PathBuf {
    let stem = file
        .file_stem()
        .map_or_else(|| "result".to_owned(), |s| s.to_string_lossy().into_owned());
    PathBuf::from("results").join("plots").join(stem)
}

/// Draws every picture of the result file `file` into `dir`.
pub fn plot_file(file: &Path, dir: &Path) -> Result<Plotted> {
    let data = Data::read(file)?;
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut out = Plotted {
        notes: data.notes.clone(),
        ..Plotted::default()
    };
    match &data.kind {
        Kind::Points(labels) => point_bars(&data, labels, dir, &mut out.files)?,
        Kind::Grid(axes) if axes.is_empty() => point_bars(
            &data,
            &["the single instance".to_owned()],
            dir,
            &mut out.files,
        )?,
        Kind::Grid(axes) if axes.len() == 1 => grid_lines(&data, &axes[0], dir, &mut out.files)?,
        Kind::Grid(axes) => grid_maps(&data, axes, dir, &mut out.files, &mut out.notes)?,
    }
    for (k, t) in data.trajectories.iter().enumerate() {
        if t.run.time.len() < 2 {
            out.notes.push(format!(
                "trajectory {k} ({}) has fewer than two samples; not drawn",
                t.point
            ));
            continue;
        }
        out.files.push(trajectory_figure(&data, k, t, dir)?);
    }
    Ok(out)
}

/// `pidm plot`: draws the pictures and prints every file written.
pub fn run(file: &Path, out: Option<&Path>) -> Result<()> {
    let dir = out.map_or_else(|| default_out_dir(file), Path::to_path_buf);
    let plotted = plot_file(file, &dir)?;
    for path in &plotted.files {
        println!("wrote {}", path.display());
    }
    for note in &plotted.notes {
        println!("note: {note}");
    }
    Ok(())
}
