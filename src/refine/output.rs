//! The `/refine` group of a refined run's file (names in
//! `crate::output::schema`): the integrated points, the level of each, and
//! what each level did.

use anyhow::Result;
use hdf5::File;

use super::waves::{INFERRED, Refinement};
use crate::output::schema;
use crate::output::{write_f64_attr, write_str_attr, write_u64_attr};
use crate::scene::Refine;

/// Writes `/refine` into an open result file.
/// `exact_baselines` says whether the inferred points' 1-DOF baselines were
/// integrated rather than interpolated.
pub fn write_group(
    file: &File,
    refine: &Refine,
    r: &Refinement,
    exact_baselines: bool,
) -> Result<()> {
    let group = file.create_group(schema::REFINE)?;
    write_u64_attr(
        &group,
        schema::REFINE_EXACT_BASELINES,
        exact_baselines as u64,
    )?;
    write_u64_attr(&group, schema::REFINE_LEVELS, refine.levels as u64)?;
    write_f64_attr(&group, schema::REFINE_TOLERANCE, refine.tolerance)?;
    {
        let coarse = refine.coarse.map(|n| n as u64);
        let attr = group
            .new_attr::<u64>()
            .shape(coarse.len())
            .create(schema::REFINE_COARSE_SHAPE)?;
        attr.write_raw(&coarse)?;
    }
    let (index, level): (Vec<u64>, Vec<u8>) = r
        .level_of
        .iter()
        .enumerate()
        .filter(|(_, l)| **l != INFERRED)
        .map(|(k, l)| (k as u64, *l))
        .unzip();
    let name = |path: &'static str| &path[schema::REFINE.len() + 1..];
    let ds = group
        .new_dataset_builder()
        .with_data(&index)
        .create(name(schema::REFINE_INDEX))?;
    write_str_attr(
        &ds,
        schema::LONG_NAME,
        "flat row-major index of each integrated point",
    )?;
    let ds = group
        .new_dataset_builder()
        .with_data(&level)
        .create(name(schema::REFINE_LEVEL))?;
    write_str_attr(
        &ds,
        schema::LONG_NAME,
        "level that integrated each point (0 = coarse grid)",
    )?;
    let columns: [(&'static str, Vec<u64>, &str); 5] = [
        (
            schema::REFINE_LEVEL_INTEGRATED,
            r.stats.iter().map(|s| s.integrated).collect(),
            "points integrated at each level",
        ),
        (
            schema::REFINE_LEVEL_CANDIDATES,
            r.stats.iter().map(|s| s.candidates).collect(),
            "cells judged at each level",
        ),
        (
            schema::REFINE_LEVEL_FLAGGED,
            r.stats.iter().map(|s| s.flagged).collect(),
            "cells refined at each level",
        ),
        (
            schema::REFINE_LEVEL_AUDITED,
            r.stats.iter().map(|s| s.audited).collect(),
            "cells given an audit point at each level",
        ),
        (
            schema::REFINE_LEVEL_AUDIT_FINDS,
            r.stats.iter().map(|s| s.audit_finds).collect(),
            "cells only their audit point flagged",
        ),
    ];
    for (path, values, long_name) in columns {
        let ds = group
            .new_dataset_builder()
            .with_data(&values)
            .create(name(path))?;
        write_str_attr(&ds, schema::LONG_NAME, long_name)?;
    }
    let misses: Vec<f64> = r.stats.iter().map(|s| s.largest_miss).collect();
    let ds = group
        .new_dataset_builder()
        .with_data(&misses)
        .create(name(schema::REFINE_LEVEL_LARGEST_MISS))?;
    write_str_attr(&ds, schema::UNITS, "m")?;
    write_str_attr(
        &ds,
        schema::LONG_NAME,
        "largest difference between the interpolant and an integrated probe at each level",
    )?;
    Ok(())
}
