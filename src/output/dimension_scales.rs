//! HDF5 dimension scales (the `H5DS` API of the HDF5 high-level library,
//! which netCDF-4 uses for its dimensions). hdf5-metno does not wrap it.

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
