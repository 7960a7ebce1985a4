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
//!   `/maps/steps`, `/maps/step_x_se`, `/maps/step_y_se` [m per own drive
//!   cycle], `/maps/periods`, `/maps/period_lag`, and `/maps/motion` (u8,
//!   the codes of `crate::motion::Motion`, with CF `flag_values` and
//!   `flag_meanings`), each shaped like the grid;
//! - `/baseline/step_x`, `/baseline/step_y`, `/baseline/status` when
//!   baselines are asked for;
//! - `/maps/stall_load_x` [N], `/maps/stall_step_near_x`,
//!   `/maps/stall_step_far_x` [m per own drive cycle], `/maps/stall_waves_x`
//!   and `/maps/stall_status_x` (or `_y`) for a scene with `[stall]`
//!   (`crate::stall`), shaped like the grid;
//! - `/trajectories/<k>/` when the scene asks for trajectories (written by
//!   `crate::trajectory`, which documents its layout).
//!
//! The file also follows the netCDF-4 conventions, so netCDF tools and
//! `xarray.open_dataset(file, engine="h5netcdf")` see labelled arrays: each
//! `/axes` dataset is an HDF5 dimension scale named by its key and attached
//! to every map, and the root group holds hard links (the same objects, not
//! copies) named `step_x`, ..., `baseline_step_x`, ... and one per axis key.
//! Every map has `units` and `long_name` attributes.
//!
//! A shard file (`pidm run --shard K/N`) holds only its own instances: its
//! maps are 1-D in ascending flat-index order, `/shard/instance` lists those
//! indices, and root attributes `shard_index`, `shard_count` and
//! `instance_count` say which part of the scene it is. `pidm merge` turns
//! shards back into one map file.

use std::ops::Range;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use hdf5::types::VarLenUnicode;
use hdf5::{Dataset, File, H5Type, Hyperslab, SliceOrIndex};
use ndarray::ArrayView;

use crate::scene::{Layout, Scene};
pub use shard_spec::ShardSpec;

pub mod claim;
pub mod schema;
pub mod shard_spec;
use crate::sweep::Record;
pub use claim::OutputClaim;

/// Where a shard file's instances sit in the scene.
#[derive(Clone, Debug)]
pub struct ShardInfo {
    pub spec: ShardSpec,
    /// Instances in the whole scene.
    pub total: u64,
    /// The flat indices this shard holds, ascending and disjoint.
    pub ranges: Vec<Range<u64>>,
}

impl ShardInfo {
    pub fn new(spec: ShardSpec, total: u64) -> ShardInfo {
        ShardInfo {
            spec,
            total,
            ranges: spec.ranges(total),
        }
    }

    /// Instances the shard holds.
    pub fn len(&self) -> u64 {
        self.ranges.iter().map(|r| r.end - r.start).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

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
    /// The tolerance of the `--verify` reruns, when the run was verified.
    pub verify_tolerance: Option<f64>,
    /// Set for a shard file: which part of the scene it holds.
    pub shard: Option<ShardInfo>,
    /// The stalled axis of a scene with `[stall]`: its stall maps are
    /// written too (`schema::STALL_DATASETS`).
    pub stall: Option<usize>,
}

impl FileInfo {
    /// The file layout of a scene's results, run on `backend` (its
    /// description) in `precision` by the integrator `variant`.
    pub fn of_scene(
        scene: &Scene,
        backend: String,
        precision: String,
        variant: String,
    ) -> FileInfo {
        let (axes, labels) = match &scene.layout {
            Layout::Grid { axes } => (
                axes.iter()
                    .map(|a| AxisInfo {
                        key: a.key.clone(),
                        values: a.values.clone(),
                        units: a.units.to_string(),
                    })
                    .collect(),
                None,
            ),
            Layout::Points { labels } => (Vec::new(), Some(labels.clone())),
        };
        FileInfo {
            name: scene.name.clone(),
            scene_text: scene.text.clone(),
            shape: scene.shape(),
            axes,
            labels,
            baselines: scene.baselines,
            backend,
            precision,
            variant,
            tolerance: scene.settings.tolerance,
            verify_tolerance: None,
            shard: None,
            stall: scene.stall.map(|stall| stall.axis),
        }
    }
}

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
    /// The grid axes' keys, in grid order (their dimension scales).
    scale_names: Vec<String>,
}

/// Writes a text attribute (netCDF readers take variable-length UTF-8).
pub(crate) fn write_str_attr(loc: &hdf5::Location, name: &str, value: &str) -> Result<()> {
    let v: VarLenUnicode = value
        .parse()
        .with_context(|| format!("attribute {name} is not valid text"))?;
    loc.new_attr::<VarLenUnicode>()
        .create(name)?
        .write_scalar(&v)?;
    Ok(())
}

pub(crate) fn write_u64_attr(loc: &hdf5::Location, name: &str, value: u64) -> Result<()> {
    loc.new_attr::<u64>().create(name)?.write_scalar(&value)?;
    Ok(())
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

/// HDF5 dimension scales (the `H5DS` API of the HDF5 high-level library,
/// which netCDF-4 uses for its dimensions). hdf5-metno does not wrap it.
pub(crate) mod dimension_scales {
    use std::ffi::{CString, c_char};

    use anyhow::{Result, bail};
    use hdf5::Dataset;

    #[link(name = "hdf5_hl")]
    unsafe extern "C" {
        fn H5DSset_scale(dsid: i64, dimname: *const c_char) -> i32;
        fn H5DSattach_scale(did: i64, dsid: i64, idx: u32) -> i32;
    }

    /// Makes `ds` a dimension scale named `name`.
    pub fn set_scale(ds: &Dataset, name: &str) -> Result<()> {
        let name = CString::new(name)?;
        // SAFETY: the id is a live dataset and the name a C string; the
        // library lock serialises HDF5 calls as hdf5-metno's own do.
        let rc = hdf5::sync::sync(|| unsafe { H5DSset_scale(ds.id(), name.as_ptr()) });
        if rc < 0 {
            bail!("cannot make {} a dimension scale", ds.name());
        }
        Ok(())
    }

    /// Attaches the scale to dimension `dim` of `ds`.
    pub fn attach(ds: &Dataset, scale: &Dataset, dim: u32) -> Result<()> {
        // SAFETY: both ids are live datasets.
        let rc = hdf5::sync::sync(|| unsafe { H5DSattach_scale(ds.id(), scale.id(), dim) });
        if rc < 0 {
            bail!("cannot attach {} to {}", scale.name(), ds.name());
        }
        Ok(())
    }
}

/// The CF attributes of `/maps/motion`: `flag_values`, every code as u8
/// (the map's type, as CF asks), and `flag_meanings`, their names in code
/// order, both from [`crate::motion::Motion`].
fn write_motion_flags(ds: &Dataset) -> Result<()> {
    let values = crate::motion::Motion::flag_values();
    ds.new_attr::<u8>()
        .shape(values.len())
        .create(schema::FLAG_VALUES)?
        .write_raw(&values)?;
    write_str_attr(
        ds,
        schema::FLAG_MEANINGS,
        &crate::motion::Motion::flag_meanings(),
    )
}

pub(crate) fn write_f64_attr(loc: &hdf5::Location, name: &str, value: f64) -> Result<()> {
    loc.new_attr::<f64>().create(name)?.write_scalar(&value)?;
    Ok(())
}

/// Reads a text attribute written by [`write_str_attr`].
pub(crate) fn read_str_attr(loc: &hdf5::Location, name: &str) -> Result<String> {
    let value: VarLenUnicode = loc
        .attr(name)
        .and_then(|a| a.read_scalar())
        .with_context(|| format!("no text attribute `{name}`"))?;
    // The bytes are checked here: the stored text of a damaged file need
    // not be UTF-8, and `as_str` would take it on trust.
    String::from_utf8(value.as_bytes().to_vec())
        .map_err(|_| anyhow::anyhow!("the text attribute `{name}` is not valid UTF-8"))
}

impl MapWriter {
    /// Creates the temporary file of the claimed output with axes and
    /// empty maps. A temporary file left by a killed run is replaced: the
    /// claim proves that no other run is writing it.
    pub fn create(claim: &OutputClaim, info: &FileInfo) -> Result<MapWriter> {
        let path = claim.path();
        let temp_path = claim.partial_path();
        // Removing first replaces a stale file without following it, should
        // it have become a link since the claim checked it.
        match std::fs::remove_file(&temp_path) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => {
                return Err(e).with_context(|| format!("cannot remove {}", temp_path.display()));
            }
        }
        let file = File::create_excl(&temp_path)
            .with_context(|| format!("cannot create {}", temp_path.display()))?;
        // A shard's maps are 1-D over its own instances.
        let map_shape = match &info.shard {
            Some(shard) => vec![shard.len() as usize],
            None => info.shape.clone(),
        };
        let mut shard_ranges = Vec::new();
        if let Some(shard) = &info.shard {
            let mut position = 0;
            for range in &shard.ranges {
                shard_ranges.push((range.clone(), position));
                position += range.end - range.start;
            }
        }
        let mut writer = MapWriter {
            file: None,
            temp_path,
            final_path: path.to_path_buf(),
            shape: map_shape.clone(),
            shard_ranges,
            maps: Vec::new(),
            baselines: Vec::new(),
            stall: Vec::new(),
            scale_names: info.axes.iter().map(|a| a.key.clone()).collect(),
        };
        write_str_attr(&file, schema::SCENE, &info.scene_text)?;
        write_str_attr(&file, schema::NAME, &info.name)?;
        write_str_attr(&file, schema::PIDM_VERSION, env!("CARGO_PKG_VERSION"))?;
        write_str_attr(&file, schema::BACKEND, &info.backend)?;
        write_str_attr(&file, schema::PRECISION, &info.precision)?;
        write_str_attr(&file, schema::VARIANT, &info.variant)?;
        write_f64_attr(&file, schema::TOLERANCE, info.tolerance)?;
        if let Some(tolerance) = info.verify_tolerance {
            write_f64_attr(&file, schema::VERIFY_TOLERANCE, tolerance)?;
        }

        // The dimension scales, in grid order.
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
        let netcdf = info.shard.is_none();
        if netcdf {
            for (key, ds) in &scales {
                dimension_scales::set_scale(ds, key)?;
                file.link_hard(&format!("axes/{key}"), key)?;
            }
            if let Some(labels) = &coordinates {
                dimension_scales::attach(labels, &scales[0].1, 0)?;
            }
        }
        if let Some(shard) = &info.shard {
            write_u64_attr(&file, schema::SHARD_INDEX, shard.spec.index as u64)?;
            write_u64_attr(&file, schema::SHARD_COUNT, shard.spec.count as u64)?;
            write_u64_attr(&file, schema::INSTANCE_COUNT, shard.total)?;
            let group = file.create_group(schema::SHARD)?;
            let ds = group
                .new_dataset::<u64>()
                .shape(map_shape.clone())
                .create("instance")?;
            let index: Vec<u64> = shard.ranges.iter().flat_map(|r| r.clone()).collect();
            ds.write(&index)?;
            write_str_attr(
                &ds,
                "long_name",
                "flat row-major index of each instance in the scene",
            )?;
        }

        let make = |group: &hdf5::Group, name: &str, ty: schema::MapType| -> Result<Dataset> {
            let builder = match ty {
                schema::MapType::F64 => group.new_dataset::<f64>(),
                schema::MapType::U32 => group.new_dataset::<u32>(),
                schema::MapType::U8 => group.new_dataset::<u8>(),
            };
            let builder = builder.shape(map_shape.clone());
            let ds = match chunk_shape(&map_shape) {
                Some(chunk) => builder.chunk(chunk).create(name)?,
                None => builder.create(name)?,
            };
            Ok(ds)
        };
        let describe =
            |ds: &Dataset, prefix: &str, name: &str, units: &str, long_name: &str| -> Result<()> {
                write_str_attr(ds, schema::UNITS, units)?;
                write_str_attr(ds, schema::LONG_NAME, long_name)?;
                if netcdf {
                    for (dim, (_, scale)) in scales.iter().enumerate() {
                        dimension_scales::attach(ds, scale, dim as u32)?;
                    }
                    if coordinates.is_some() {
                        write_str_attr(ds, "coordinates", schema::LABELS)?;
                    }
                    file.link_hard(&format!("{prefix}/{name}"), &root_name(prefix, name))?;
                }
                Ok(())
            };
        let maps = file.create_group(schema::MAPS)?;
        for d in schema::MAP_DATASETS {
            let ds = make(&maps, d.name, d.ty)?;
            describe(&ds, schema::MAPS, d.name, d.units, d.long_name)?;
            if d.name == schema::MOTION_NAME {
                write_motion_flags(&ds)?;
            }
            writer.maps.push(ds);
        }
        if let Some(axis) = info.stall {
            for d in schema::STALL_DATASETS[axis] {
                let ds = make(&maps, d.name, d.ty)?;
                describe(&ds, schema::MAPS, d.name, d.units, d.long_name)?;
                writer.stall.push(ds);
            }
        }
        if info.baselines {
            let group = file.create_group(schema::BASELINE)?;
            for d in schema::BASELINE_DATASETS {
                let ds = make(&group, d.name, d.ty)?;
                describe(&ds, schema::BASELINE, d.name, d.units, d.long_name)?;
                writer.baselines.push(ds);
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

    /// Writes the stall maps of instances `start .. start +
    /// records.len()` (row-major flat indices) of a scene with `[stall]`.
    pub fn write_stall(&mut self, start: u64, records: &[crate::stall::StallRecord]) -> Result<()> {
        if self.stall.is_empty() {
            bail!("internal: stall maps for a file of a scene without [stall]");
        }
        let start = self.position(start, records.len() as u64)?;
        let f64s = |f: &dyn Fn(&crate::stall::StallRecord) -> f64| -> Vec<f64> {
            records.iter().map(f).collect()
        };
        let u32s = |f: &dyn Fn(&crate::stall::StallRecord) -> u32| -> Vec<u32> {
            records.iter().map(f).collect()
        };
        write_flat(&self.stall[0], &self.shape, start, &f64s(&|r| r.load))?;
        write_flat(&self.stall[1], &self.shape, start, &f64s(&|r| r.step_near))?;
        write_flat(&self.stall[2], &self.shape, start, &f64s(&|r| r.step_far))?;
        write_flat(&self.stall[3], &self.shape, start, &u32s(&|r| r.waves))?;
        write_flat(&self.stall[4], &self.shape, start, &u32s(&|r| r.status))?;
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

/// Every value of a dataset or attribute, exactly: floats as their bits.
#[derive(Debug, PartialEq)]
enum Values {
    Float(Vec<u64>),
    Unsigned(Vec<u64>),
    Signed(Vec<i64>),
    Text(Vec<String>),
    /// Object references (the dimension-scale attributes `DIMENSION_LIST`
    /// and `REFERENCE_LIST`) hold file addresses, which need not agree
    /// between two files of the same content: only their count is compared.
    References(usize),
}

/// True for a type that holds object references anywhere.
fn has_references(ty: &hdf5::types::TypeDescriptor) -> bool {
    use hdf5::types::TypeDescriptor as T;
    match ty {
        T::Reference(_) => true,
        T::VarLenArray(inner) | T::FixedArray(inner, _) => has_references(inner),
        T::Compound(c) => c.fields.iter().any(|f| has_references(&f.ty)),
        _ => false,
    }
}

fn values(c: &hdf5::Container) -> Result<Values> {
    use hdf5::types::{FixedAscii, FloatSize, IntSize, TypeDescriptor as T};
    fn widen<A, B: From<A>>(v: Vec<A>) -> Vec<B> {
        v.into_iter().map(B::from).collect()
    }
    let ty = c.dtype()?.to_descriptor()?;
    if has_references(&ty) {
        return Ok(Values::References(c.size()));
    }
    Ok(match ty {
        T::Float(FloatSize::U8) => {
            Values::Float(c.read_raw::<f64>()?.iter().map(|x| x.to_bits()).collect())
        }
        T::Float(FloatSize::U4) => Values::Float(
            c.read_raw::<f32>()?
                .iter()
                .map(|x| u64::from(x.to_bits()))
                .collect(),
        ),
        T::Unsigned(size) => Values::Unsigned(match size {
            IntSize::U1 => widen(c.read_raw::<u8>()?),
            IntSize::U2 => widen(c.read_raw::<u16>()?),
            IntSize::U4 => widen(c.read_raw::<u32>()?),
            IntSize::U8 => c.read_raw::<u64>()?,
        }),
        T::Integer(size) => Values::Signed(match size {
            IntSize::U1 => widen(c.read_raw::<i8>()?),
            IntSize::U2 => widen(c.read_raw::<i16>()?),
            IntSize::U4 => widen(c.read_raw::<i32>()?),
            IntSize::U8 => c.read_raw::<i64>()?,
        }),
        T::FixedAscii(_) => Values::Text(
            c.read_raw::<FixedAscii<256>>()?
                .iter()
                .map(|v| v.as_str().to_owned())
                .collect(),
        ),
        T::VarLenUnicode => Values::Text(
            c.read_raw::<VarLenUnicode>()?
                .iter()
                .map(|v| v.as_str().to_owned())
                .collect(),
        ),
        other => bail!("unexpected element type {other:?}"),
    })
}

/// Checks that two result files hold the same scene and the same contents,
/// bit for bit: every group and dataset at any depth (maps, axes,
/// baselines, labels, trajectories), with the same types, shapes, values
/// and dataset attributes. Run-specific root attributes (`wall_time_s`,
/// `backend`) may differ. Returns how many datasets were compared; the
/// error names the first difference.
pub fn compare_contents(a: &Path, b: &Path) -> Result<usize> {
    let fa = File::open(a).with_context(|| format!("cannot open {}", a.display()))?;
    let fb = File::open(b).with_context(|| format!("cannot open {}", b.display()))?;
    if read_str_attr(&fa, "scene")? != read_str_attr(&fb, "scene")? {
        bail!("the `scene` attributes differ");
    }
    let mut compared = 0;
    compare_group(&fa, &fb, &mut compared)?;
    Ok(compared)
}

fn compare_group(a: &hdf5::Group, b: &hdf5::Group, compared: &mut usize) -> Result<()> {
    let (mut names_a, mut names_b) = (a.member_names()?, b.member_names()?);
    names_a.sort();
    names_b.sort();
    if names_a != names_b {
        bail!(
            "{} holds {names_a:?} in one file and {names_b:?} in the other",
            a.name()
        );
    }
    for name in &names_a {
        if let Ok(group_a) = a.group(name) {
            compare_group(&group_a, &b.group(name)?, compared)?;
            continue;
        }
        let (da, db) = (a.dataset(name)?, b.dataset(name)?);
        let what = da.name();
        if da.shape() != db.shape() {
            bail!("{what}: shapes {:?} and {:?}", da.shape(), db.shape());
        }
        if da.dtype()?.to_descriptor()? != db.dtype()?.to_descriptor()? {
            bail!("{what}: the element types differ");
        }
        if values(&da).with_context(|| what.clone())? != values(&db)? {
            bail!("{what} differs");
        }
        let (mut attrs_a, mut attrs_b) = (da.attr_names()?, db.attr_names()?);
        attrs_a.sort();
        attrs_b.sort();
        if attrs_a != attrs_b {
            bail!("{what}: attributes {attrs_a:?} and {attrs_b:?}");
        }
        for attr in &attrs_a {
            let (aa, ab) = (da.attr(attr)?, db.attr(attr)?);
            if aa.dtype()?.to_descriptor()? != ab.dtype()?.to_descriptor()?
                || values(&aa)? != values(&ab)?
            {
                bail!("{what}: attribute {attr} differs");
            }
        }
        *compared += 1;
    }
    Ok(())
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
