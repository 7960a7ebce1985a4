//! HDF5 output: step-displacement maps written chunk by chunk into a
//! temporary file that is renamed into place only once it is complete.
//!
//! Layout (a contract):
//! - root attributes `scene` (TOML text), `pidm_version`, `backend`,
//!   `precision`, `wall_time_s`, `variant`, `tolerance`;
//! - `/axes/<key>`: one 1-D dataset per grid axis, in grid order, with a
//!   `units` attribute (a points scene has `/axes/point` and `/labels`);
//! - `/maps/step_x`, `/maps/step_y` [m per own drive cycle],
//!   `/maps/velocity_x`, `/maps/velocity_y` [m/s], `/maps/status`,
//!   `/maps/steps`, each shaped like the grid;
//! - `/baseline/step_x`, `/baseline/step_y`, `/baseline/status` when
//!   baselines are asked for;
//! - `/trajectories/<k>/` when the scene asks for trajectories (written by
//!   `crate::trajectory`, which documents its layout).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use hdf5::types::VarLenUnicode;
use hdf5::{Dataset, File, H5Type, Hyperslab, SliceOrIndex};
use ndarray::ArrayView;

use crate::sweep::Record;

/// One grid axis as it is written to `/axes`.
#[derive(Clone, Debug)]
pub struct AxisInfo {
    pub key: String,
    pub values: Vec<f64>,
    pub units: String,
}

/// What the file describes, known before the run starts.
#[derive(Clone, Debug)]
pub struct FileInfo {
    pub name: String,
    pub scene_text: String,
    /// Grid shape; empty for a single instance.
    pub shape: Vec<usize>,
    pub axes: Vec<AxisInfo>,
    /// Point labels of a points scene.
    pub labels: Option<Vec<String>>,
    pub baselines: bool,
    pub backend: String,
    pub precision: String,
    /// Which integrator variant ran (for example "2-DOF" or "1-DOF").
    pub variant: String,
    pub tolerance: f64,
}

/// Writes one result file. Dropping it before [`MapWriter::finish`] removes
/// the temporary file, so a failed or interrupted run leaves nothing behind.
pub struct MapWriter {
    file: Option<File>,
    temp_path: PathBuf,
    final_path: PathBuf,
    shape: Vec<usize>,
    maps: Vec<Dataset>,
    baselines: Vec<Dataset>,
}

/// Map datasets in the order [`Record`] fields are written.
const MAPS: [(&str, &str, &str); 6] = [
    ("step_x", "m", "slider step along x per x drive cycle"),
    ("step_y", "m", "slider step along y per y drive cycle"),
    ("velocity_x", "m/s", "mean slider velocity along x"),
    ("velocity_y", "m/s", "mean slider velocity along y"),
    ("status", "1", "integrator status code (0 = ok)"),
    ("steps", "1", "integrator steps taken"),
];

const BASELINES: [(&str, &str, &str); 3] = [
    ("step_x", "m", "1-DOF step along x with the y drive off"),
    ("step_y", "m", "1-DOF step along y with the x drive off"),
    (
        "status",
        "1",
        "integrator status code of the baselines (0 = ok)",
    ),
];

fn write_str_attr(loc: &hdf5::Location, name: &str, value: &str) -> Result<()> {
    let v: VarLenUnicode = value
        .parse()
        .with_context(|| format!("attribute {name} is not valid text"))?;
    loc.new_attr::<VarLenUnicode>()
        .create(name)?
        .write_scalar(&v)?;
    Ok(())
}

fn write_f64_attr(loc: &hdf5::Location, name: &str, value: f64) -> Result<()> {
    loc.new_attr::<f64>().create(name)?.write_scalar(&value)?;
    Ok(())
}

impl MapWriter {
    /// Creates the temporary file next to `path` with axes and empty maps.
    pub fn create(path: &Path, info: &FileInfo) -> Result<MapWriter> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("cannot create the folder {}", dir.display()))?;
        }
        let file_name = path
            .file_name()
            .with_context(|| format!("{} is not a file path", path.display()))?;
        let temp_path = path.with_file_name(format!(
            ".{}.partial-{}",
            file_name.to_string_lossy(),
            std::process::id()
        ));
        let file = File::create(&temp_path)
            .with_context(|| format!("cannot create {}", temp_path.display()))?;
        let mut writer = MapWriter {
            file: None,
            temp_path,
            final_path: path.to_path_buf(),
            shape: info.shape.clone(),
            maps: Vec::new(),
            baselines: Vec::new(),
        };
        write_str_attr(&file, "scene", &info.scene_text)?;
        write_str_attr(&file, "name", &info.name)?;
        write_str_attr(&file, "pidm_version", env!("CARGO_PKG_VERSION"))?;
        write_str_attr(&file, "backend", &info.backend)?;
        write_str_attr(&file, "precision", &info.precision)?;
        write_str_attr(&file, "variant", &info.variant)?;
        write_f64_attr(&file, "tolerance", info.tolerance)?;

        let axes = file.create_group("axes")?;
        for axis in &info.axes {
            let ds = axes
                .new_dataset_builder()
                .with_data(&axis.values)
                .create(axis.key.as_str())?;
            write_str_attr(&ds, "units", &axis.units)?;
        }
        if let Some(labels) = &info.labels {
            let index: Vec<u64> = (0..labels.len() as u64).collect();
            let ds = axes
                .new_dataset_builder()
                .with_data(&index)
                .create("point")?;
            write_str_attr(&ds, "units", "1")?;
            let text: Vec<VarLenUnicode> = labels
                .iter()
                .map(|l| l.parse().context("point label is not valid text"))
                .collect::<Result<_>>()?;
            file.new_dataset_builder()
                .with_data(&text)
                .create("labels")?;
        }

        let maps = file.create_group("maps")?;
        for (name, units, long_name) in MAPS {
            let ds = if name == "status" || name == "steps" {
                maps.new_dataset::<u32>()
                    .shape(info.shape.clone())
                    .create(name)?
            } else {
                maps.new_dataset::<f64>()
                    .shape(info.shape.clone())
                    .create(name)?
            };
            write_str_attr(&ds, "units", units)?;
            write_str_attr(&ds, "long_name", long_name)?;
            writer.maps.push(ds);
        }
        if info.baselines {
            let group = file.create_group("baseline")?;
            for (name, units, long_name) in BASELINES {
                let ds = if name == "status" {
                    group
                        .new_dataset::<u32>()
                        .shape(info.shape.clone())
                        .create(name)?
                } else {
                    group
                        .new_dataset::<f64>()
                        .shape(info.shape.clone())
                        .create(name)?
                };
                write_str_attr(&ds, "units", units)?;
                write_str_attr(&ds, "long_name", long_name)?;
                writer.baselines.push(ds);
            }
        }
        writer.file = Some(file);
        Ok(writer)
    }

    /// Writes the records of instances `start .. start + records.len()`
    /// (row-major flat indices).
    pub fn write(&mut self, start: u64, records: &[Record]) -> Result<()> {
        let take = |f: &dyn Fn(&Record) -> f64| records.iter().map(f).collect::<Vec<f64>>();
        let take_u32 = |f: &dyn Fn(&Record) -> u32| records.iter().map(f).collect::<Vec<u32>>();
        let columns_f64 = [
            take(&|r| r.step[0]),
            take(&|r| r.step[1]),
            take(&|r| r.velocity[0]),
            take(&|r| r.velocity[1]),
        ];
        for (ds, column) in self.maps.iter().zip(&columns_f64) {
            write_flat(ds, &self.shape, start, column)?;
        }
        write_flat(&self.maps[4], &self.shape, start, &take_u32(&|r| r.status))?;
        write_flat(&self.maps[5], &self.shape, start, &take_u32(&|r| r.steps))?;
        if !self.baselines.is_empty() {
            write_flat(
                &self.baselines[0],
                &self.shape,
                start,
                &take(&|r| r.baseline_step[0]),
            )?;
            write_flat(
                &self.baselines[1],
                &self.shape,
                start,
                &take(&|r| r.baseline_step[1]),
            )?;
            write_flat(
                &self.baselines[2],
                &self.shape,
                start,
                &take_u32(&|r| r.baseline_status),
            )?;
        }
        Ok(())
    }

    /// The open result file, for extra groups written beside the maps (the
    /// trajectories).
    pub fn file(&self) -> &File {
        self.file
            .as_ref()
            .expect("the file stays open until finish")
    }

    /// Records the run's wall time, closes the file and renames it into
    /// place.
    pub fn finish(mut self, wall_time_s: f64) -> Result<PathBuf> {
        let file = self.file.take().context("result file already closed")?;
        write_f64_attr(&file, "wall_time_s", wall_time_s)?;
        self.maps.clear();
        self.baselines.clear();
        file.close()?;
        std::fs::rename(&self.temp_path, &self.final_path).with_context(|| {
            format!(
                "cannot move {} to {}",
                self.temp_path.display(),
                self.final_path.display()
            )
        })?;
        Ok(self.final_path.clone())
    }
}

impl Drop for MapWriter {
    fn drop(&mut self) {
        if self.file.take().is_some() {
            self.maps.clear();
            self.baselines.clear();
            let _ = std::fs::remove_file(&self.temp_path);
        }
    }
}

/// Writes a run of row-major flat indices into an N-D dataset as a sequence
/// of hyperslabs.
fn write_flat<T: H5Type>(ds: &Dataset, shape: &[usize], start: u64, data: &[T]) -> Result<()> {
    if shape.is_empty() {
        if let Some(value) = data.first() {
            ds.write_scalar(value)?;
        }
        return Ok(());
    }
    let mut offset = 0;
    for block in flat_to_blocks(shape, start as usize, start as usize + data.len()) {
        let count: usize = block.iter().map(|&(_, n)| n).product();
        let dims: Vec<usize> = block.iter().map(|&(_, n)| n).collect();
        let view = ArrayView::from_shape(dims, &data[offset..offset + count])
            .context("internal: block shape does not match its data")?;
        let slab: Vec<SliceOrIndex> = block
            .iter()
            .map(|&(s, n)| SliceOrIndex::SliceCount {
                start: s,
                step: 1,
                count: n,
                block: 1,
            })
            .collect();
        ds.write_slice(view, Hyperslab::from(slab))?;
        offset += count;
    }
    Ok(())
}

/// Splits the row-major flat range [a, b) of an array of `shape` into
/// rectangular blocks, each given as (start, count) per dimension, in order.
pub fn flat_to_blocks(shape: &[usize], a: usize, b: usize) -> Vec<Vec<(usize, usize)>> {
    let mut out = Vec::new();
    blocks_rec(shape, a, b, &mut Vec::new(), &mut out);
    out
}

fn blocks_rec(
    shape: &[usize],
    a: usize,
    b: usize,
    prefix: &mut Vec<(usize, usize)>,
    out: &mut Vec<Vec<(usize, usize)>>,
) {
    if a >= b {
        return;
    }
    let inner: usize = shape[1..].iter().product();
    let (first, a_rem) = (a / inner, a % inner);
    let (last, b_rem) = (b / inner, b % inner);
    let full_block = |prefix: &Vec<(usize, usize)>, start: usize, count: usize| {
        let mut block = prefix.clone();
        block.push((start, count));
        block.extend(shape[1..].iter().map(|&n| (0, n)));
        block
    };
    if first == last {
        // Within one slice of the leading dimension.
        prefix.push((first, 1));
        blocks_rec(&shape[1..], a_rem, b_rem, prefix, out);
        prefix.pop();
        return;
    }
    let mut lead = first;
    if a_rem != 0 {
        prefix.push((first, 1));
        blocks_rec(&shape[1..], a_rem, inner, prefix, out);
        prefix.pop();
        lead += 1;
    }
    if last > lead {
        out.push(full_block(prefix, lead, last - lead));
    }
    if b_rem != 0 {
        prefix.push((last, 1));
        blocks_rec(&shape[1..], 0, b_rem, prefix, out);
        prefix.pop();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flatten(shape: &[usize], blocks: &[Vec<(usize, usize)>]) -> Vec<usize> {
        let mut out = Vec::new();
        for block in blocks {
            let mut idx: Vec<usize> = block.iter().map(|&(s, _)| s).collect();
            loop {
                let mut flat = 0;
                for (d, &i) in idx.iter().enumerate() {
                    flat = flat * shape[d] + i;
                }
                out.push(flat);
                // Row-major increment within the block.
                let mut d = block.len();
                loop {
                    if d == 0 {
                        break;
                    }
                    d -= 1;
                    idx[d] += 1;
                    if idx[d] < block[d].0 + block[d].1 {
                        break;
                    }
                    idx[d] = block[d].0;
                    if d == 0 {
                        d = usize::MAX;
                        break;
                    }
                }
                if d == usize::MAX || block.iter().all(|&(_, n)| n == 0) {
                    break;
                }
            }
        }
        out
    }

    #[test]
    fn blocks_cover_every_flat_range_in_order() {
        for shape in [vec![7], vec![3, 4], vec![2, 3, 5], vec![4, 1, 3]] {
            let n: usize = shape.iter().product();
            for a in 0..n {
                for b in a..=n {
                    let blocks = flat_to_blocks(&shape, a, b);
                    let got = flatten(&shape, &blocks);
                    let want: Vec<usize> = (a..b).collect();
                    assert_eq!(got, want, "shape {shape:?} range {a}..{b}: {blocks:?}");
                }
            }
        }
    }
}
