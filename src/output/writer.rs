//! [`MapWriter`]: one result file written chunk by chunk into its
//! temporary file (hyperslabs of flat chunks, dimension scales attached,
//! root hard links) and renamed into place when finished.

use std::ops::Range;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use hdf5::types::VarLenUnicode;
use hdf5::{Dataset, File};

use super::attributes::{write_f64_attr, write_motion_flags, write_str_attr, write_u64_attr};
use super::blocks::write_flat;
use super::{FileInfo, OutputClaim, ShardInfo, claim, dimension_scales, schema};
use crate::sweep::Record;

/// Writes one result file. Dropping it before [`MapWriter::finish`] removes
/// the temporary file, so a failed or interrupted run leaves nothing behind.
pub struct MapWriter {
    file: Option<File>,
    temp_path: PathBuf,
    final_path: PathBuf,
    shape: Vec<usize>,
    /// For a shard: (first flat index, position in the file) of each range.
    shard_ranges: Vec<(Range<u64>, u64)>,
    maps: Vec<Dataset>,
    baselines: Vec<Dataset>,
    /// The stall maps of a scene with `[stall]` (empty otherwise).
    stall: Vec<Dataset>,
    /// The backward maps of a scene with `[output] backward`, x's then
    /// y's (empty otherwise).
    backward: Vec<Dataset>,
    /// The grid axes' keys, in grid order (their dimension scales).
    scale_names: Vec<String>,
}

/// The name of a map's hard link in the root group: `step_x` for
/// `/maps/step_x`, `baseline_step_x` for `/baseline/step_x`.
pub fn root_name(group: &str, name: &str) -> String {
    if group == schema::MAPS {
        name.to_string()
    } else {
        format!("{group}_{name}")
    }
}

/// The chunk shape of a map: at most 2^16 entries, whole along the last
/// dimensions, so a run writing in flat order touches few chunks and a
/// map read back by rows is fast. `None` for a scalar (single instance).
fn chunk_shape(shape: &[usize]) -> Option<Vec<usize>> {
    const CHUNK_ENTRIES: usize = 1 << 16;
    if shape.is_empty() {
        return None;
    }
    let mut chunk = vec![1; shape.len()];
    let mut entries = 1;
    for d in (0..shape.len()).rev() {
        let n = shape[d].clamp(1, (CHUNK_ENTRIES / entries).max(1));
        chunk[d] = n;
        entries *= n;
    }
    Some(chunk)
}

/// Creates the temporary file at `temp_path`, first removing a stale one
/// left by a killed run.
fn create_temp_file(temp_path: &Path) -> Result<File> {
    // Removing first replaces a stale file without following it, should
    // it have become a link since the claim checked it.
    match std::fs::remove_file(temp_path) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => {
            return Err(e).with_context(|| format!("cannot remove {}", temp_path.display()));
        }
    }
    File::create_excl(temp_path).with_context(|| format!("cannot create {}", temp_path.display()))
}

/// The shape of every map in the file: the grid's, or for a shard 1-D
/// over its own instances.
fn map_shape(info: &FileInfo) -> Vec<usize> {
    match &info.shard {
        Some(shard) => vec![shard.len() as usize],
        None => info.shape.clone(),
    }
}

/// For a shard: each range of flat indices it holds with the position of
/// its first instance in the file (empty for a whole scene).
fn shard_ranges(info: &FileInfo) -> Vec<(Range<u64>, u64)> {
    let mut ranges = Vec::new();
    if let Some(shard) = &info.shard {
        let mut position = 0;
        for range in &shard.ranges {
            ranges.push((range.clone(), position));
            position += range.end - range.start;
        }
    }
    ranges
}

/// Writes the root attributes that describe the run: scene, name, version,
/// backend, precision, variant, tolerances and friction law.
fn write_file_attributes(file: &File, info: &FileInfo) -> Result<()> {
    write_str_attr(file, schema::SCENE, &info.scene_text)?;
    write_str_attr(file, schema::NAME, &info.name)?;
    write_str_attr(file, schema::PIDM_VERSION, env!("CARGO_PKG_VERSION"))?;
    write_str_attr(file, schema::BACKEND, &info.backend)?;
    write_str_attr(file, schema::PRECISION, &info.precision)?;
    write_str_attr(file, schema::VARIANT, &info.variant)?;
    write_f64_attr(file, schema::TOLERANCE, info.tolerance)?;
    write_str_attr(file, schema::FRICTION, &info.friction)?;
    if let Some(parameters) = &info.friction_parameters {
        write_str_attr(file, schema::FRICTION_PARAMETERS, parameters)?;
    }
    if let Some(tolerance) = info.verify_tolerance {
        write_f64_attr(file, schema::VERIFY_TOLERANCE, tolerance)?;
    }
    Ok(())
}

/// The dimension scales, keyed and in grid order (then `point` for a
/// points scene).
type Scales = Vec<(String, Dataset)>;

/// Writes the dimension scales under `/axes`, in grid order, and for a
/// points scene the `point` index and the labels dataset; returns the
/// scales and the labels (the maps' coordinates).
fn write_scales(file: &File, info: &FileInfo) -> Result<(Scales, Option<Dataset>)> {
    let axes = file.create_group(schema::AXES)?;
    let mut scales = Vec::new();
    for axis in &info.axes {
        let ds = axes
            .new_dataset_builder()
            .with_data(&axis.values)
            .create(axis.key.as_str())?;
        write_str_attr(&ds, schema::UNITS, &axis.units)?;
        write_str_attr(&ds, schema::LONG_NAME, &axis.key)?;
        scales.push((axis.key.clone(), ds));
    }
    let mut coordinates = None;
    if let Some(labels) = &info.labels {
        let index: Vec<u64> = (0..labels.len() as u64).collect();
        let ds = axes
            .new_dataset_builder()
            .with_data(&index)
            .create("point")?;
        write_str_attr(&ds, "units", "1")?;
        write_str_attr(&ds, "long_name", "point of the scene, in file order")?;
        let text: Vec<VarLenUnicode> = labels
            .iter()
            .map(|l| l.parse().context("point label is not valid text"))
            .collect::<Result<_>>()?;
        let label_ds = file
            .new_dataset_builder()
            .with_data(&text)
            .create(schema::LABELS)?;
        write_str_attr(&label_ds, "long_name", "point label")?;
        scales.push(("point".to_string(), ds));
        coordinates = Some(label_ds);
    }
    Ok((scales, coordinates))
}

/// Makes the scales NetCDF dimensions: marks each a dimension scale, links
/// it from the root, and attaches the labels (if any) to the first.
fn link_scales(file: &File, scales: &Scales, coordinates: Option<&Dataset>) -> Result<()> {
    for (key, ds) in scales {
        dimension_scales::set_scale(ds, key)?;
        file.link_hard(&format!("axes/{key}"), key)?;
    }
    if let Some(labels) = coordinates {
        dimension_scales::attach(labels, &scales[0].1, 0)?;
    }
    Ok(())
}

/// Writes a shard file's attributes and its `/shard/instance` dataset:
/// the scene's flat index of each instance it holds.
fn write_shard_index(file: &File, shard: &ShardInfo, map_shape: &[usize]) -> Result<()> {
    write_u64_attr(file, schema::SHARD_INDEX, shard.spec.index as u64)?;
    write_u64_attr(file, schema::SHARD_COUNT, shard.spec.count as u64)?;
    write_u64_attr(file, schema::INSTANCE_COUNT, shard.total)?;
    let group = file.create_group(schema::SHARD)?;
    let ds = group
        .new_dataset::<u64>()
        .shape(map_shape.to_vec())
        .create("instance")?;
    let index: Vec<u64> = shard.ranges.iter().flat_map(|r| r.clone()).collect();
    ds.write(&index)?;
    write_str_attr(
        &ds,
        "long_name",
        "flat row-major index of each instance in the scene",
    )?;
    Ok(())
}

/// What every empty map of a file is made with: its shape (and so chunks)
/// and, for a NetCDF file, the scales to attach and root links to make.
struct MapMaker<'a> {
    file: &'a File,
    shape: &'a [usize],
    scales: &'a Scales,
    /// Whether the file has point labels (the maps' coordinates).
    labelled: bool,
    /// Whether the file is NetCDF (not a shard).
    netcdf: bool,
}

impl MapMaker<'_> {
    /// Creates the empty map `d` in `group` (named `prefix`) and describes
    /// it.
    fn create(&self, group: &hdf5::Group, prefix: &str, d: schema::MapDataset) -> Result<Dataset> {
        let ds = self.make(group, d.name, d.ty)?;
        self.describe(&ds, prefix, d)?;
        Ok(ds)
    }

    /// Creates an empty map of type `ty`, chunked by [`chunk_shape`].
    fn make(&self, group: &hdf5::Group, name: &str, ty: schema::MapType) -> Result<Dataset> {
        let builder = match ty {
            schema::MapType::F64 => group.new_dataset::<f64>(),
            schema::MapType::U32 => group.new_dataset::<u32>(),
            schema::MapType::U8 => group.new_dataset::<u8>(),
        };
        let builder = builder.shape(self.shape.to_vec());
        let ds = match chunk_shape(self.shape) {
            Some(chunk) => builder.chunk(chunk).create(name)?,
            None => builder.create(name)?,
        };
        Ok(ds)
    }

    /// Writes the units and long name of map `d` and, for a NetCDF file,
    /// attaches the scales, names the coordinates and links the map from
    /// the root.
    fn describe(&self, ds: &Dataset, prefix: &str, d: schema::MapDataset) -> Result<()> {
        write_str_attr(ds, schema::UNITS, d.units)?;
        write_str_attr(ds, schema::LONG_NAME, d.long_name)?;
        if self.netcdf {
            for (dim, (_, scale)) in self.scales.iter().enumerate() {
                dimension_scales::attach(ds, scale, dim as u32)?;
            }
            if self.labelled {
                write_str_attr(ds, "coordinates", schema::LABELS)?;
            }
            let name = d.name;
            self.file
                .link_hard(&format!("{prefix}/{name}"), &root_name(prefix, name))?;
        }
        Ok(())
    }
}

impl MapWriter {
    /// Creates the temporary file of the claimed output with axes and
    /// empty maps. A temporary file left by a killed run is replaced: the
    /// claim proves that no other run is writing it.
    pub fn create(claim: &OutputClaim, info: &FileInfo) -> Result<MapWriter> {
        let temp_path = claim.partial_path();
        let file = create_temp_file(&temp_path)?;
        let map_shape = map_shape(info);
        let mut writer = MapWriter {
            file: None,
            temp_path,
            final_path: claim.path().to_path_buf(),
            shape: map_shape.clone(),
            shard_ranges: shard_ranges(info),
            maps: Vec::new(),
            baselines: Vec::new(),
            stall: Vec::new(),
            backward: Vec::new(),
            scale_names: info.axes.iter().map(|a| a.key.clone()).collect(),
        };
        write_file_attributes(&file, info)?;
        let (scales, coordinates) = write_scales(&file, info)?;
        let netcdf = info.shard.is_none();
        if netcdf {
            link_scales(&file, &scales, coordinates.as_ref())?;
        }
        if let Some(shard) = &info.shard {
            write_shard_index(&file, shard, &map_shape)?;
        }
        let maker = MapMaker {
            file: &file,
            shape: &map_shape,
            scales: &scales,
            labelled: coordinates.is_some(),
            netcdf,
        };
        let maps = file.create_group(schema::MAPS)?;
        for d in schema::MAP_DATASETS {
            let ds = maker.create(&maps, schema::MAPS, d)?;
            if d.name == schema::MOTION_NAME {
                write_motion_flags(&ds)?;
            }
            writer.maps.push(ds);
        }
        if info.backward {
            for d in schema::BACKWARD_DATASETS.iter().flatten() {
                writer.backward.push(maker.create(&maps, schema::MAPS, *d)?);
            }
        }
        if let Some(axis) = info.stall {
            for d in schema::STALL_DATASETS[axis] {
                writer.stall.push(maker.create(&maps, schema::MAPS, d)?);
            }
        }
        if info.baselines {
            let group = file.create_group(schema::BASELINE)?;
            for d in schema::BASELINE_DATASETS {
                writer
                    .baselines
                    .push(maker.create(&group, schema::BASELINE, d)?);
            }
        }
        writer.file = Some(file);
        Ok(writer)
    }

    /// Writes the records of instances `start .. start + records.len()`
    /// (row-major flat indices).
    pub fn write(&mut self, start: u64, records: &[Record]) -> Result<()> {
        let start = self.position(start, records.len() as u64)?;
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
        write_flat(&self.maps[6], &self.shape, start, &take(&|r| r.step_se[0]))?;
        write_flat(&self.maps[7], &self.shape, start, &take(&|r| r.step_se[1]))?;
        write_flat(&self.maps[8], &self.shape, start, &take_u32(&|r| r.periods))?;
        write_flat(
            &self.maps[9],
            &self.shape,
            start,
            &take_u32(&|r| r.period_lag),
        )?;
        let motion: Vec<u8> = records.iter().map(|r| r.motion.code()).collect();
        write_flat(&self.maps[10], &self.shape, start, &motion)?;
        write_flat(
            &self.maps[11],
            &self.shape,
            start,
            &take_u32(&|r| r.replicas),
        )?;
        for (k, ds) in self.backward.iter().enumerate() {
            let (axis, column) = (k / 4, k % 4);
            let values = take(&|r| r.backward.columns(axis)[column]);
            write_flat(ds, &self.shape, start, &values)?;
        }
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

    /// Writes the stall maps of instances `start .. start + n` (row-major
    /// flat indices, n the columns' length) of a scene with `[stall]`.
    pub fn write_stall(&mut self, start: u64, columns: &StallColumns) -> Result<()> {
        if self.stall.is_empty() {
            bail!("internal: stall maps for a file of a scene without [stall]");
        }
        let start = self.position(start, columns.load.len() as u64)?;
        write_flat(&self.stall[0], &self.shape, start, &columns.load)?;
        write_flat(&self.stall[1], &self.shape, start, &columns.step_near)?;
        write_flat(&self.stall[2], &self.shape, start, &columns.step_far)?;
        write_flat(&self.stall[3], &self.shape, start, &columns.waves)?;
        write_flat(&self.stall[4], &self.shape, start, &columns.status)?;
        Ok(())
    }

    /// Where the instances `start .. start + n` sit in the maps: the flat
    /// index itself, or for a shard its position among the shard's own.
    fn position(&self, start: u64, n: u64) -> Result<u64> {
        if self.shard_ranges.is_empty() {
            return Ok(start);
        }
        let k = self.shard_ranges.partition_point(|(r, _)| r.end <= start);
        match self.shard_ranges.get(k) {
            Some((range, position)) if range.start <= start && start + n <= range.end => {
                Ok(position + (start - range.start))
            }
            _ => bail!(
                "internal: instances {start}..{} are not in this shard",
                start + n
            ),
        }
    }

    /// Writes `/maps/inferred` of a refined run: a u8 map shaped like the
    /// grid, with the dimension scales and root link every map has.
    pub fn write_inferred(&mut self, mask: &[u8]) -> Result<()> {
        if !self.shard_ranges.is_empty() {
            bail!("internal: a shard file has no inferred map");
        }
        let file = self.file();
        let maps = file.group(schema::MAPS)?;
        let builder = maps.new_dataset::<u8>().shape(self.shape.clone());
        let ds = match chunk_shape(&self.shape) {
            Some(chunk) => builder.chunk(chunk).create(schema::INFERRED_NAME)?,
            None => builder.create(schema::INFERRED_NAME)?,
        };
        write_flat(&ds, &self.shape, 0, mask)?;
        write_str_attr(&ds, schema::UNITS, "1")?;
        write_str_attr(&ds, schema::LONG_NAME, schema::INFERRED_LONG_NAME)?;
        let axes = file.group(schema::AXES)?;
        for (dim, key) in self.scale_names.iter().enumerate() {
            let scale = axes.dataset(key)?;
            dimension_scales::attach(&ds, &scale, dim as u32)?;
        }
        file.link_hard(
            schema::INFERRED,
            &root_name(schema::MAPS, schema::INFERRED_NAME),
        )?;
        Ok(())
    }

    /// The open result file, for extra groups written beside the maps (the
    /// trajectories).
    pub fn file(&self) -> &File {
        self.file
            .as_ref()
            .expect("the file stays open until finish")
    }

    /// Records the run's wall time, the total of its `parts` (the runs of
    /// an interrupted and resumed run, or the shards of a merged one; one
    /// for a plain run), closes the file and renames it into place. On an
    /// error the temporary file is removed and the output is left as it
    /// was.
    pub fn finish(mut self, parts: &[f64]) -> Result<PathBuf> {
        write_f64_attr(self.file(), schema::WALL_TIME_S, parts.iter().sum())?;
        {
            let attr = self
                .file()
                .new_attr::<f64>()
                .shape(parts.len())
                .create(schema::WALL_TIME_PARTS_S)?;
            attr.write_raw(parts)?;
        }
        // The output may have changed since the claim checked it; a rename
        // would silently replace a FIFO or device that appeared meanwhile.
        claim::check_regular_or_absent(&self.final_path)?;
        let file = self.file.take().context("result file already closed")?;
        self.maps.clear();
        self.baselines.clear();
        let moved = file.close().map_err(anyhow::Error::from).and_then(|()| {
            std::fs::rename(&self.temp_path, &self.final_path).with_context(|| {
                format!(
                    "cannot move {} to {}",
                    self.temp_path.display(),
                    self.final_path.display()
                )
            })
        });
        if let Err(e) = moved {
            let _ = std::fs::remove_file(&self.temp_path);
            return Err(e);
        }
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

/// The stall maps of consecutive instances, one column per dataset of
/// `schema::STALL_DATASETS` in its order (`crate::stall::StallRecord::
/// columns` makes them), so the writer needs nothing of the stall search.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StallColumns {
    /// Stall loads [N].
    pub load: Vec<f64>,
    /// Steps at the bracket's ends [m per own drive cycle].
    pub step_near: Vec<f64>,
    pub step_far: Vec<f64>,
    /// Integrations of each search.
    pub waves: Vec<u32>,
    /// Stall statuses.
    pub status: Vec<u32>,
}
