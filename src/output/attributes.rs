//! Attributes: text (variable-length UTF-8, as netCDF readers take it),
//! integers and floats written, text read back checked, and the CF flags
//! of `/maps/motion`.

use anyhow::{Context, Result};
use hdf5::Dataset;
use hdf5::types::VarLenUnicode;

use super::schema;

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

/// The CF attributes of `/maps/motion`: `flag_values`, every code as u8
/// (the map's type, as CF asks), and `flag_meanings`, their names in code
/// order, both from [`crate::model::motion::Motion`].
pub(super) fn write_motion_flags(ds: &Dataset) -> Result<()> {
    let values = crate::model::motion::Motion::flag_values();
    ds.new_attr::<u8>()
        .shape(values.len())
        .create(schema::FLAG_VALUES)?
        .write_raw(&values)?;
    write_str_attr(
        ds,
        schema::FLAG_MEANINGS,
        &crate::model::motion::Motion::flag_meanings(),
    )
}
