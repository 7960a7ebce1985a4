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
//!   coupling regime ([`Regime`]); with kinds of motion (`/maps/motion`
//!   of a steady measurement), a categorical map of them per slice;
//! - a grid with one axis: line plots of the steps (and baselines, ratios
//!   and regimes), and a strip of the kinds of motion;
//! - a points scene (or a single instance): a bar chart of the steps, with
//!   the baselines beside them and each point's kind of motion under its
//!   label;
//! - a grid of two axes, one of at most 4 values and the other of at least
//!   8 (a step against the load at two voltages): also line plots of the
//!   steps against the long axis, one line per value of the short one; for
//!   a LuGre map whose long axis is a bristle key, each line's instance
//!   under Karnopp's friction as a dashed reference line (integrated on
//!   the CPU when the picture is drawn: docs/model.md section 8's limit);
//! - a scene with `[output] backward`: also each moving axis' backward
//!   ratio (`backward`), a map per slice of a grid of two or more axes, a
//!   line for a grid of one axis, a bar per point of a points scene;
//! - a scene with `[stall]`: the stall-load map (`stall`), a heatmap per
//!   slice, a line for a 1-D grid or a dot per point;
//! - every stored trajectory: stage and slider displacement against time
//!   per axis and the slider's path in the x-y plane, like the paper's
//!   Figs. 5-8.
//!
//! Steps are drawn in micrometres per own drive cycle; instances that ended
//! with a non-zero status are drawn in grey, never as a number.
//!
//! Nothing is half-done: the whole file is read and checked first (a
//! missing dataset, a wrong type or a shape that disagrees with the others
//! is a [`ResultFileError`] naming the file and the dataset), then every
//! picture is drawn into a staging folder beside the output folder and
//! moved into it only when all are written.
//!
//! The files, one concern each:
//! - reading: `crate::output::schema` (the names read), `error`, `checked` (checked
//!   access to one HDF5 file), `read` (maps, baselines, axes, labels) and
//!   `read_trajectories`;
//! - colours and classes: `colour`, `regime`, `motion` (also its
//!   pictures);
//! - drawing helpers: `canvas` (fonts, titles, swatches, PNG writing),
//!   `text` (labels and numbers), `placement` (linear or log axes);
//! - pictures: `heatmap` (one map), `maps` (the maps of an N-D grid),
//!   `lines` (1-D grids), `bars` (points), `trajectory`;
//! - `staging`: all pictures or none.

mod backward;
mod bars;
mod canvas;
mod checked;
mod colour;
mod error;
mod fit;
mod heatmap;
mod lines;
mod maps;
mod motion;
mod placement;
mod read;
mod read_trajectories;
mod regime;
pub use regime::{Regime, ZERO_STEP_M};
mod sobol;
mod staging;
mod stall;
mod text;
mod trajectory;

use std::path::{Path, PathBuf};

use anyhow::Result;

pub use error::{Problem, ResultFileError};

use read::{Data, Kind};
use staging::Staging;

/// At most this many 2-D slices are drawn per map of an N-D grid; beyond
/// it, evenly spaced slices are chosen and the choice is reported.
pub const MAX_SLICES: usize = 24;

/// What `pidm plot` wrote.
#[derive(Clone, Debug, Default)]
pub struct Plotted {
    /// Every PNG written, in order.
    pub files: Vec<PathBuf>,
    /// Things the reader should know (slices left out, guessed axis order,
    /// values or trajectories left out).
    pub notes: Vec<String>,
}

pub use fit::{FitPanel, FitSeries, fit_figure};
pub use sobol::{IndexPanel, sensitivity_figure};

/// Default output folder: `results/plots/<file stem>/`.
pub fn default_out_dir(file: &Path) -> PathBuf {
    let stem = file
        .file_stem()
        .map_or_else(|| "result".to_owned(), |s| s.to_string_lossy().into_owned());
    PathBuf::from("results").join("plots").join(stem)
}

/// Which slices of a grid the maps show (`pidm plot --x --y --at`): the
/// keys of the axes across and up (the two longest when not given), and
/// values at which other axes are held.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct View {
    /// The grid axis across the maps.
    pub x: Option<String>,
    /// The grid axis up the maps.
    pub y: Option<String>,
    /// Grid axes held at one value each: (key, value).
    pub at: Vec<(String, f64)>,
}

impl View {
    /// Whether the view asks for anything but the default.
    pub fn is_default(&self) -> bool {
        self == &View::default()
    }
}

/// Checks the result file `file` whole, then draws every picture of it
/// into `dir`: all of them, or, on any error, none.
pub fn plot_file(file: &Path, dir: &Path) -> Result<Plotted> {
    plot_view(file, dir, &View::default())
}

/// [`plot_file`] with the maps of a grid sliced as `view` says.
pub fn plot_view(file: &Path, dir: &Path, view: &View) -> Result<Plotted> {
    let data = Data::read(file)?;
    let plane = match &data.kind {
        Kind::Grid(axes) if axes.len() >= 2 => Some(maps::Plane::choose(axes, &data.shape, view)?),
        _ if !view.is_default() => anyhow::bail!(
            "--x, --y and --at slice the maps of a grid of two or more axes; {} has none",
            file.display()
        ),
        _ => None,
    };
    let staging = Staging::new(dir)?;
    let mut notes = data.notes.clone();
    let mut staged = Vec::new();
    draw(
        &data,
        plane.as_ref(),
        staging.path(),
        &mut staged,
        &mut notes,
    )?;
    Ok(Plotted {
        files: staging.commit(&staged)?,
        notes,
    })
}

/// Draws every picture of `data` into `dir`, adding each file to `files`;
/// `plane` says how a grid of two or more axes is sliced.
fn draw(
    data: &Data,
    plane: Option<&maps::Plane>,
    dir: &Path,
    files: &mut Vec<PathBuf>,
    notes: &mut Vec<String>,
) -> Result<()> {
    match &data.kind {
        Kind::Points(labels) => {
            bars::point_bars(data, labels, dir, files)?;
            backward::backward_bars(data, labels, dir, files, notes)?;
        }
        Kind::Grid(axes) if axes.is_empty() => {
            let labels = ["the single instance".to_owned()];
            bars::point_bars(data, &labels, dir, files)?;
            backward::backward_bars(data, &labels, dir, files, notes)?;
        }
        Kind::Grid(axes) if axes.len() == 1 => {
            lines::grid_lines(data, &axes[0], dir, files)?;
            backward::backward_lines(data, &axes[0], dir, files, notes)?;
        }
        Kind::Grid(axes) => {
            let default;
            let plane = match plane {
                Some(plane) => plane,
                None => {
                    default = maps::Plane::choose(axes, &data.shape, &View::default())?;
                    &default
                }
            };
            maps::grid_maps(data, axes, plane, dir, files, notes)?;
            backward::backward_maps(data, axes, plane, dir, files, notes)?;
            if let Some(dims) = lines::family_dims(&data.shape) {
                lines::family_lines(data, axes, dims, dir, files)?;
            }
        }
    }
    if let Some(stall) = &data.stall {
        let default;
        let plane = match (&data.kind, plane) {
            (_, Some(plane)) => Some(plane),
            (Kind::Grid(axes), None) if axes.len() >= 2 => {
                default = maps::Plane::choose(axes, &data.shape, &View::default())?;
                Some(&default)
            }
            _ => None,
        };
        stall::stall_pictures(data, stall, plane, dir, files, notes)?;
    }
    for (k, t) in data.trajectories.iter().enumerate() {
        if let Some(why) = &t.not_drawn {
            notes.push(format!("trajectory {k} ({}) {why}; not drawn", t.point));
            continue;
        }
        files.push(trajectory::trajectory_figure(data, k, t, dir)?);
    }
    Ok(())
}

/// `pidm plot`: draws the pictures and prints every file written.
pub fn run(file: &Path, out: Option<&Path>, view: &View) -> Result<()> {
    let dir = out.map_or_else(|| default_out_dir(file), Path::to_path_buf);
    let plotted = plot_view(file, &dir, view)?;
    for path in &plotted.files {
        println!("wrote {}", path.display());
    }
    for note in &plotted.notes {
        println!("note: {note}");
    }
    Ok(())
}
