//! [`compare_contents`]: two result files compared bit for bit, every
//! group, dataset and dataset attribute.

use std::path::Path;

use anyhow::{Context, Result, bail};
use hdf5::File;
use hdf5::types::VarLenUnicode;

use super::attributes::read_str_attr;

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
