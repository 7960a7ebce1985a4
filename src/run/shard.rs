//! Sharded runs: a deterministic split of a scene's instances into N parts
//! that separate machines (a Slurm job array) run into separate files, and
//! the merge that turns those files back into one map file, identical in
//! content to a single-machine run.
//!
//! The split deals out blocks of consecutive flat indices round-robin, so
//! every shard gets a similar mix of cheap and expensive corners of the
//! grid, while each shard still writes long contiguous runs.

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, bail};
use hdf5::File;

use crate::output::claim::is_same_file;
use crate::output::{MapWriter, OutputClaim, ShardInfo, read_str_attr, schema};
use crate::scene::Scene;
use crate::stall::StallRecord;
use crate::sweep::{Backward, Record, stored_motion};

pub use crate::output::shard_spec::ShardSpec;

fn read_u64_attr(file: &File, name: &str) -> Result<u64> {
    file.attr(name)
        .and_then(|a| a.read_scalar())
        .with_context(|| format!("no integer attribute `{name}`"))
}

/// What a shard file says about itself.
struct ShardFile {
    path: PathBuf,
    file: File,
    spec: ShardSpec,
    total: u64,
    scene: String,
    name: String,
    version: String,
    precision: String,
    variant: String,
    backend: String,
    tolerance: f64,
    verify_tolerance: Option<f64>,
    wall_time_s: f64,
}

impl ShardFile {
    fn open(path: &Path) -> Result<ShardFile> {
        let file = File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
        let read = || -> Result<ShardFile> {
            if file.attr(schema::SHARD_INDEX).is_err() {
                bail!("it is not a shard file (it has no `shard_index` attribute)");
            }
            let index = read_u64_attr(&file, schema::SHARD_INDEX)?;
            let count = read_u64_attr(&file, schema::SHARD_COUNT)?;
            let spec = ShardSpec {
                index: u32::try_from(index)?,
                count: u32::try_from(count)?,
            };
            Ok(ShardFile {
                path: path.to_path_buf(),
                spec,
                total: read_u64_attr(&file, schema::INSTANCE_COUNT)?,
                scene: read_str_attr(&file, schema::SCENE)?,
                name: read_str_attr(&file, schema::NAME)?,
                version: read_str_attr(&file, schema::PIDM_VERSION)?,
                precision: read_str_attr(&file, schema::PRECISION)?,
                variant: read_str_attr(&file, schema::VARIANT)?,
                backend: read_str_attr(&file, schema::BACKEND)?,
                tolerance: file.attr(schema::TOLERANCE)?.read_scalar()?,
                verify_tolerance: file
                    .attr(schema::VERIFY_TOLERANCE)
                    .ok()
                    .map(|a| a.read_scalar())
                    .transpose()?,
                wall_time_s: file.attr(schema::WALL_TIME_S)?.read_scalar()?,
                file: file.clone(),
            })
        };
        read().with_context(|| format!("{}", path.display()))
    }

    /// Checks that every map the merge reads is a 1-D dataset of `len`
    /// values, naming the file and the dataset that is not: the stall maps
    /// of `stall`'s axis too.
    fn check_layout(
        &self,
        len: u64,
        (baselines, backward): (bool, bool),
        stall: Option<usize>,
    ) -> Result<()> {
        let in_group = |group: &str, d: &schema::MapDataset| format!("{group}/{}", d.name);
        let mut names: Vec<String> = schema::MAP_DATASETS
            .iter()
            .map(|d| in_group(schema::MAPS, d))
            .collect();
        if let Some(axis) = stall {
            names.extend(
                (0..schema::STALL_DATASETS[axis].len()).map(|k| schema::stall_path(axis, k)),
            );
        }
        if backward {
            names.extend(
                (0..2).flat_map(|axis| (0..4).map(move |k| schema::backward_path(axis, k))),
            );
        }
        if baselines {
            names.extend(
                schema::BASELINE_DATASETS
                    .iter()
                    .map(|d| in_group(schema::BASELINE, d)),
            );
        }
        names.push(schema::SHARD_INSTANCE.into());
        for name in &names {
            let name = name.as_str();
            let ds = self.file.dataset(name).map_err(|_| {
                anyhow!(
                    "{}: the dataset `{name}` is missing; it is not a complete shard file",
                    self.path.display()
                )
            })?;
            let shape = ds.shape();
            if shape != [len as usize] {
                bail!(
                    "{}: the dataset `{name}` has shape {shape:?}, but shard {} of this scene \
                     holds {len} instances",
                    self.path.display(),
                    self.spec
                );
            }
        }
        Ok(())
    }

    /// The values at positions `range` of the 1-D dataset `path`.
    fn column<T: hdf5::H5Type + Clone>(&self, path: &str, range: Range<usize>) -> Result<Vec<T>> {
        self.file
            .dataset(path)
            .and_then(|ds| ds.read_slice_1d::<T, _>(range))
            .map(|v| v.to_vec())
            .with_context(|| format!("{}: cannot read `{path}`", self.path.display()))
    }

    /// Reads the records at positions `at .. at + n` of the shard's maps,
    /// which hold the instances from flat index `first` on, and checks that
    /// they can be right: a known status and motion, finite values, and
    /// zeros (and no kind of motion) where an instance did not finish
    /// normally.
    fn records(
        &self,
        at: u64,
        n: u64,
        first: u64,
        (baselines, backward): (bool, bool),
    ) -> Result<Vec<Record>> {
        let range = at as usize..(at + n) as usize;
        let f64s = |path: &str| self.column::<f64>(path, range.clone());
        let u32s = |path: &str| self.column::<u32>(path, range.clone());
        let map = |k: usize| format!("{}/{}", schema::MAPS, schema::MAP_DATASETS[k].name);
        let (step_x, step_y) = (f64s(schema::STEP[0])?, f64s(schema::STEP[1])?);
        let (vel_x, vel_y) = (f64s(&map(2))?, f64s(&map(3))?);
        let (status, steps) = (u32s(schema::STATUS)?, u32s(&map(5))?);
        let (se_x, se_y) = (f64s(&map(6))?, f64s(&map(7))?);
        let (periods, lags) = (u32s(&map(8))?, u32s(&map(9))?);
        let replicas = u32s(&map(11))?;
        let motion = self.column::<u8>(schema::MOTION, range.clone())?;
        let zeros_f = vec![0.0; n as usize];
        let zeros_u = vec![0; n as usize];
        let (base_x, base_y, base_status) = if baselines {
            (
                f64s(schema::BASELINE_STEP[0])?,
                f64s(schema::BASELINE_STEP[1])?,
                u32s(schema::BASELINE_STATUS)?,
            )
        } else {
            (zeros_f.clone(), zeros_f, zeros_u)
        };
        let backward_columns = if backward {
            let column = |axis: usize, k: usize| f64s(&schema::backward_path(axis, k));
            let axis = |a: usize| -> Result<[Vec<f64>; 4]> {
                Ok([column(a, 0)?, column(a, 1)?, column(a, 2)?, column(a, 3)?])
            };
            Some([axis(0)?, axis(1)?])
        } else {
            None
        };
        let backward_of = |k: usize| match &backward_columns {
            Some(c) => Backward::from_columns([0, 1].map(|a| [0, 1, 2, 3].map(|j| c[a][j][k]))),
            None => Backward::default(),
        };
        let cannot_be_right = |k: usize, why: String| {
            anyhow!(
                "{}: instance {} cannot be right: {why}",
                self.path.display(),
                first + k as u64
            )
        };
        let records: Vec<Record> = (0..n as usize)
            .map(|k| {
                let motion = stored_motion(motion[k]).map_err(|why| cannot_be_right(k, why))?;
                Ok(Record {
                    step: [step_x[k], step_y[k]],
                    velocity: [vel_x[k], vel_y[k]],
                    status: status[k],
                    steps: steps[k],
                    step_se: [se_x[k], se_y[k]],
                    periods: periods[k],
                    period_lag: lags[k],
                    motion,
                    replicas: replicas[k],
                    baseline_step: [base_x[k], base_y[k]],
                    baseline_status: base_status[k],
                    backward: backward_of(k),
                })
            })
            .collect::<Result<_>>()?;
        for (k, record) in records.iter().enumerate() {
            if let Some(why) = record.implausibility() {
                return Err(cannot_be_right(k, why));
            }
        }
        Ok(records)
    }
}

impl ShardFile {
    /// Reads the stall records of `axis` at positions `at .. at + n`,
    /// which hold the instances from flat index `first` on, and checks
    /// that they can be right (`StallRecord::implausibility`).
    fn stall_records(&self, at: u64, n: u64, first: u64, axis: usize) -> Result<Vec<StallRecord>> {
        let range = at as usize..(at + n) as usize;
        let f64s = |k: usize| self.column::<f64>(&schema::stall_path(axis, k), range.clone());
        let u32s = |k: usize| self.column::<u32>(&schema::stall_path(axis, k), range.clone());
        let (load, near, far) = (f64s(0)?, f64s(1)?, f64s(2)?);
        let (waves, status) = (u32s(3)?, u32s(4)?);
        (0..n as usize)
            .map(|k| {
                let r = StallRecord {
                    load: load[k],
                    step_near: near[k],
                    step_far: far[k],
                    waves: waves[k],
                    status: status[k],
                };
                match r.implausibility() {
                    None => Ok(r),
                    Some(why) => Err(anyhow!(
                        "{}: instance {} cannot be right: {why}",
                        self.path.display(),
                        first + k as u64
                    )),
                }
            })
            .collect()
    }
}

/// What `pidm merge` did.
pub struct MergeSummary {
    pub path: PathBuf,
    pub shards: u32,
    pub instances: u64,
}

/// Merges the shard files of one scene into `out`. Refuses shards of
/// different scenes, versions, precisions or shard counts, a shard given
/// twice, a missing shard, and a file whose instance list is not the one
/// its shard number implies.
pub fn merge(out: &Path, paths: &[PathBuf]) -> Result<MergeSummary> {
    if paths.is_empty() {
        bail!("no shard files given");
    }
    // Nothing is read or written before the output is ours.
    let claim = OutputClaim::acquire(out)?;
    if let Some(shard) = paths.iter().find(|p| is_same_file(out, p)) {
        bail!(
            "{} is also given as the shard {}; merge into another file",
            out.display(),
            shard.display()
        );
    }
    let shards: Vec<ShardFile> = paths
        .iter()
        .map(|p| ShardFile::open(p))
        .collect::<Result<_>>()?;
    let first = &shards[0];
    for other in &shards[1..] {
        check_same_run(first, other)?;
    }
    let count = first.spec.count;
    let by_index = index_shards(&shards, count)?;

    let scene = Scene::from_toml(&first.scene, Some(&first.name))
        .with_context(|| format!("the scene stored in {}", first.path.display()))?;
    let total = scene.instance_count();
    for shard in &shards {
        check_instances(shard, &scene, total)?;
    }

    let path = write_merged(&claim, &scene, &shards, &by_index, total)?;
    Ok(MergeSummary {
        path,
        shards: count,
        instances: total,
    })
}

/// Checks that `other` comes from the same run as `first`: the same scene,
/// pidm version, precision, integrator variant, verification and shard
/// count.
fn check_same_run(first: &ShardFile, other: &ShardFile) -> Result<()> {
    let differs = |what: &str, a: &str, b: &str| -> Result<()> {
        if a != b {
            bail!(
                "{} and {} come from different {what} ({a:?} against {b:?}); \
                 shards of one run must match",
                first.path.display(),
                other.path.display()
            );
        }
        Ok(())
    };
    if other.scene != first.scene {
        bail!(
            "{} and {} come from different scenes (their `scene` attributes differ)",
            first.path.display(),
            other.path.display()
        );
    }
    differs("pidm versions", &first.version, &other.version)?;
    differs("precisions", &first.precision, &other.precision)?;
    differs("integrator variants", &first.variant, &other.variant)?;
    let verification = |tolerance: Option<f64>| {
        tolerance.map_or("none".to_string(), |t| format!("tolerance {t:e}"))
    };
    differs(
        "verifications (--verify)",
        &verification(first.verify_tolerance),
        &verification(other.verify_tolerance),
    )?;
    if other.spec.count != first.spec.count {
        bail!(
            "{} is shard {} but {} is shard {}: the shards overlap (a run is split \
             one way only)",
            first.path.display(),
            first.spec,
            other.path.display(),
            other.spec
        );
    }
    Ok(())
}

/// The shards by shard number, refusing a number given twice and a
/// missing one of `1..=count`.
fn index_shards(shards: &[ShardFile], count: u32) -> Result<BTreeMap<u32, &ShardFile>> {
    let mut by_index: BTreeMap<u32, &ShardFile> = BTreeMap::new();
    for shard in shards {
        if let Some(earlier) = by_index.insert(shard.spec.index, shard) {
            bail!(
                "{} and {} are both shard {}: they overlap",
                earlier.path.display(),
                shard.path.display(),
                shard.spec
            );
        }
    }
    let missing: Vec<String> = (1..=count)
        .filter(|k| !by_index.contains_key(k))
        .map(|k| format!("{k}/{count}"))
        .collect();
    if !missing.is_empty() {
        bail!(
            "missing shard{} {} of {count}; every shard of the run must be given",
            if missing.len() > 1 { "s" } else { "" },
            missing.join(", ")
        );
    }
    Ok(by_index)
}

/// Checks that a shard holds the instances its shard number implies in a
/// scene of `total` instances: its instance count, the layout of its maps
/// and its stored instance list.
fn check_instances(shard: &ShardFile, scene: &Scene, total: u64) -> Result<()> {
    if shard.total != total {
        bail!(
            "{} says the scene has {} instances, but its scene has {total}",
            shard.path.display(),
            shard.total
        );
    }
    let expected: Vec<u64> = shard.spec.ranges(total).into_iter().flatten().collect();
    let stall = scene.stall.map(|stall| stall.axis);
    let optional = (scene.baselines, scene.settings.backward);
    shard.check_layout(expected.len() as u64, optional, stall)?;
    let stored: Vec<u64> = shard
        .file
        .dataset(schema::SHARD_INSTANCE)
        .and_then(|ds| ds.read_raw())
        .with_context(|| format!("{}: cannot read `shard/instance`", shard.path.display()))?;
    if stored != expected {
        bail!(
            "{}: its instance list is not that of shard {} of this scene",
            shard.path.display(),
            shard.spec
        );
    }
    Ok(())
}

/// Writes the merged map file: the records (and stall records) of every
/// shard in shard order, the trajectories and the shards' wall times;
/// returns its path.
fn write_merged(
    claim: &OutputClaim,
    scene: &Scene,
    shards: &[ShardFile],
    by_index: &BTreeMap<u32, &ShardFile>,
    total: u64,
) -> Result<PathBuf> {
    let first = &shards[0];
    let mut backends: Vec<&str> = shards.iter().map(|s| s.backend.as_str()).collect();
    backends.sort_unstable();
    backends.dedup();
    let mut info = scene.file_info(
        backends.join("; "),
        first.precision.clone(),
        first.variant.clone(),
    );
    info.tolerance = first.tolerance;
    info.verify_tolerance = first.verify_tolerance;
    let mut writer = MapWriter::create(claim, &info)?;
    for shard in by_index.values() {
        let mut at = 0;
        for range in ShardInfo::new(shard.spec, total).ranges {
            let n = range.end - range.start;
            let records = shard.records(
                at,
                n,
                range.start,
                (scene.baselines, scene.settings.backward),
            )?;
            writer.write(range.start, &records)?;
            if let Some(stall) = scene.stall {
                let stalls = shard.stall_records(at, n, range.start, stall.axis)?;
                writer.write_stall(range.start, &crate::stall::StallRecord::columns(&stalls))?;
            }
            at += n;
        }
    }
    crate::trajectory::record_and_write(writer.file(), scene)?;
    let parts: Vec<f64> = shards.iter().map(|s| s.wall_time_s).collect();
    writer.finish(&parts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_cover_every_instance_exactly_once() {
        for total in [1, 2, 7, 12, 100, 1000, 100_003] {
            for count in [1, 2, 3, 4, 7, 16] {
                let mut seen = vec![0u8; total as usize];
                for index in 1..=count {
                    let ranges = ShardSpec { index, count }.ranges(total);
                    for w in ranges.windows(2) {
                        assert!(w[0].end < w[1].start, "{ranges:?}");
                    }
                    for i in ranges.into_iter().flatten() {
                        seen[i as usize] += 1;
                    }
                }
                assert!(seen.iter().all(|&n| n == 1), "{total} in {count}");
            }
        }
    }

    #[test]
    fn shards_are_balanced() {
        let total = 1_000_000;
        let count = 7;
        let sizes: Vec<u64> = (1..=count)
            .map(|index| {
                ShardSpec { index, count }
                    .ranges(total)
                    .iter()
                    .map(|r| r.end - r.start)
                    .sum()
            })
            .collect();
        let (min, max) = (sizes.iter().min().unwrap(), sizes.iter().max().unwrap());
        assert!(max - min <= ShardSpec { index: 1, count }.block_size(total));
    }

    #[test]
    fn shard_specs_parse_or_say_what_is_expected() {
        assert_eq!("2/4".parse(), Ok(ShardSpec { index: 2, count: 4 }));
        assert_eq!("1/1".parse(), Ok(ShardSpec { index: 1, count: 1 }));
        for bad in ["0/4", "5/4", "4", "a/b", "1/0", "-1/3", ""] {
            let err = bad.parse::<ShardSpec>().unwrap_err();
            assert!(err.contains("expected K/N"), "{bad}: {err}");
        }
    }
}
