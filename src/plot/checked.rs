//! Checked access to one result file. Every read checks that the object
//! exists, is of the right kind (dataset, group or attribute) and holds the
//! right type of values; shapes are checked against each other with
//! [`ResultFile::expect_shape`]. Every failure is a [`ResultFileError`]
//! that names the file and the object.

use std::path::{Path, PathBuf};

use hdf5::types::{TypeDescriptor, VarLenAscii, VarLenUnicode};
use hdf5::{Attribute, Dataset, Group, Location, LocationType};

use super::error::{Problem, ResultFileError};

/// The largest magnitude a number read from a result file may have. Far
/// beyond any physical value here, it keeps every quantity derived for a
/// picture (micrometres, milliseconds, spans, padding) finite: a range
/// that overflows to infinity would hang the chart's label placement.
pub(super) const PLAUSIBLE: f64 = 1e100;

/// Whether `value` is finite and within [`PLAUSIBLE`].
pub(super) fn is_plausible(value: f64) -> bool {
    value.abs() <= PLAUSIBLE
}

/// The result of a checked read.
pub(super) type Checked<T> = Result<T, ResultFileError>;

/// A whole dataset: its path in the file, its shape and its values in
/// row-major order.
#[derive(Clone, Debug)]
pub(super) struct Array<T> {
    pub(super) path: String,
    pub(super) shape: Vec<usize>,
    pub(super) values: Vec<T>,
}

/// The kinds of values a dataset or attribute can be asked for.
#[derive(Clone, Copy, Debug)]
enum Want {
    Float,
    Integer,
    Text,
}

impl Want {
    fn describe(self) -> &'static str {
        match self {
            Want::Float => "floating-point",
            Want::Integer => "integer",
            Want::Text => "variable-length text",
        }
    }

    fn accepts(self, found: &TypeDescriptor) -> bool {
        match self {
            Want::Float => matches!(found, TypeDescriptor::Float(_)),
            Want::Integer => matches!(
                found,
                TypeDescriptor::Integer(_) | TypeDescriptor::Unsigned(_)
            ),
            Want::Text => matches!(
                found,
                TypeDescriptor::VarLenUnicode | TypeDescriptor::VarLenAscii
            ),
        }
    }
}

/// An open result file.
pub(super) struct ResultFile {
    path: PathBuf,
    file: hdf5::File,
}

/// The path of an object for messages: with a leading '/'.
fn shown(path: &str) -> String {
    format!("/{}", path.trim_start_matches('/'))
}

/// The path of `name` inside the group at `parent`.
pub(super) fn join(parent: &str, name: &str) -> String {
    if parent.is_empty() {
        name.to_owned()
    } else {
        format!("{parent}/{name}")
    }
}

impl ResultFile {
    /// Opens `path`; a missing file, a folder, an empty, truncated or
    /// non-HDF5 file is a [`ResultFileError::Open`].
    pub(super) fn open(path: &Path) -> Checked<ResultFile> {
        let fail = |reason: String| ResultFileError::Open {
            file: path.to_path_buf(),
            reason,
        };
        let meta = std::fs::metadata(path).map_err(|e| fail(e.to_string()))?;
        if !meta.is_file() {
            return Err(fail("not a regular file".to_owned()));
        }
        if meta.len() == 0 {
            return Err(fail("the file is empty".to_owned()));
        }
        let file = hdf5::File::open(path).map_err(|e| fail(e.to_string()))?;
        Ok(ResultFile {
            path: path.to_path_buf(),
            file,
        })
    }

    /// The root group.
    pub(super) fn root(&self) -> &Group {
        &self.file
    }

    /// An error about `object` (e.g. "dataset /maps/step_x").
    pub(super) fn error(&self, object: impl Into<String>, problem: Problem) -> ResultFileError {
        ResultFileError::Invalid {
            file: self.path.clone(),
            object: object.into(),
            problem,
        }
    }

    /// An error about the dataset at `path`.
    pub(super) fn dataset_error(&self, path: &str, problem: Problem) -> ResultFileError {
        self.error(format!("dataset {}", shown(path)), problem)
    }

    /// Whether anything is linked at `path`.
    pub(super) fn exists(&self, path: &str) -> bool {
        self.file.link_exists(path)
    }

    /// Whether the object at `path` exists and is of kind `kind`, or an
    /// error naming it ("dataset" or "group").
    fn expect_kind(&self, path: &str, kind: LocationType, name: &'static str) -> Checked<()> {
        let object = format!("{name} {}", shown(path));
        if !self.exists(path) {
            return Err(self.error(object, Problem::Missing));
        }
        match self.file.loc_type_by_name(path) {
            Ok(found) if found == kind => Ok(()),
            Ok(_) => Err(self.error(object, Problem::WrongKind { expected: name })),
            Err(e) => Err(self.error(object, Problem::Unreadable(e.to_string()))),
        }
    }

    /// The group at `path`.
    pub(super) fn group(&self, path: &str) -> Checked<Group> {
        self.expect_kind(path, LocationType::Group, "group")?;
        self.file
            .group(path)
            .map_err(|e| self.error(format!("group {}", shown(path)), unreadable(e)))
    }

    /// The names of the members of the group at `path`.
    pub(super) fn members(&self, path: &str) -> Checked<Vec<String>> {
        self.group(path)?
            .member_names()
            .map_err(|e| self.error(format!("group {}", shown(path)), unreadable(e)))
    }

    /// The dataset at `path`, checked to hold values of kind `want`.
    fn dataset(&self, path: &str, want: Want) -> Checked<Dataset> {
        self.expect_kind(path, LocationType::Dataset, "dataset")?;
        let ds = self
            .file
            .dataset(path)
            .map_err(|e| self.dataset_error(path, unreadable(e)))?;
        let found = ds
            .dtype()
            .and_then(|t| t.to_descriptor())
            .map_err(|e| self.dataset_error(path, unreadable(e)))?;
        if !want.accepts(&found) {
            return Err(self.dataset_error(
                path,
                Problem::WrongType {
                    found: type_name(&found),
                    expected: want.describe(),
                },
            ));
        }
        Ok(ds)
    }

    /// Reads the floating-point dataset at `path` whole.
    pub(super) fn floats(&self, path: &str) -> Checked<Array<f64>> {
        let ds = self.dataset(path, Want::Float)?;
        self.read(path, &ds, |ds| ds.read_raw::<f64>())
    }

    /// Reads the integer dataset at `path` whole, as `u32`.
    pub(super) fn integers(&self, path: &str) -> Checked<Array<u32>> {
        let ds = self.dataset(path, Want::Integer)?;
        self.read(path, &ds, |ds| ds.read_raw::<u32>())
    }

    /// Reads the text dataset at `path` whole; text that is not UTF-8 is
    /// an error.
    pub(super) fn texts(&self, path: &str) -> Checked<Array<String>> {
        let ds = self.dataset(path, Want::Text)?;
        let ascii = is_ascii(ds.dtype());
        // The bytes, not `as_str`: HDF5 hands over whatever the file holds,
        // and a damaged file may hold bytes that are not UTF-8.
        let raw = self.read(path, &ds, |ds| {
            Ok(if ascii {
                let raw: Vec<VarLenAscii> = ds.read_raw()?;
                raw.iter().map(|s| s.as_bytes().to_vec()).collect()
            } else {
                let raw: Vec<VarLenUnicode> = ds.read_raw()?;
                raw.iter().map(|s| s.as_bytes().to_vec()).collect()
            })
        })?;
        let values = raw
            .values
            .into_iter()
            .enumerate()
            .map(|(k, bytes)| {
                String::from_utf8(bytes).map_err(|_| {
                    self.dataset_error(
                        path,
                        Problem::Invalid(format!("holds text that is not UTF-8 at index {k}")),
                    )
                })
            })
            .collect::<Checked<_>>()?;
        Ok(Array {
            path: raw.path,
            shape: raw.shape,
            values,
        })
    }

    /// Reads the dataset `ds` at `path` whole with `read`, and checks that
    /// it gave one value per element of the dataset's shape.
    fn read<T>(
        &self,
        path: &str,
        ds: &Dataset,
        read: impl FnOnce(&Dataset) -> hdf5::Result<Vec<T>>,
    ) -> Checked<Array<T>> {
        let shape = ds.shape();
        let values = read(ds).map_err(|e| self.dataset_error(path, unreadable(e)))?;
        let count: usize = shape.iter().product();
        if values.len() != count {
            return Err(self.dataset_error(
                path,
                Problem::Unreadable(format!("{} values read for shape {shape:?}", values.len())),
            ));
        }
        Ok(Array {
            path: path.to_owned(),
            shape,
            values,
        })
    }

    /// An error unless `array` has shape `expected`; `reason` says where
    /// the expected shape comes from.
    pub(super) fn expect_shape<T>(
        &self,
        array: &Array<T>,
        expected: &[usize],
        reason: impl Into<String>,
    ) -> Checked<()> {
        if array.shape == expected {
            return Ok(());
        }
        Err(self.dataset_error(
            &array.path,
            Problem::WrongShape {
                found: array.shape.clone(),
                expected: expected.to_vec(),
                reason: reason.into(),
            },
        ))
    }

    /// The length of the 1-D dataset `array`, or an error naming its rank.
    pub(super) fn expect_list<T>(&self, array: &Array<T>) -> Checked<usize> {
        match array.shape[..] {
            [n] => Ok(n),
            _ => Err(self.dataset_error(
                &array.path,
                Problem::Invalid(format!("has shape {:?}, expected a 1-D list", array.shape)),
            )),
        }
    }

    /// An error if `array` holds a value that is not finite or beyond
    /// [`PLAUSIBLE`]; `reason` says why it cannot.
    pub(super) fn expect_plausible(&self, array: &Array<f64>, reason: &'static str) -> Checked<()> {
        let Some(first) = array.values.iter().position(|&v| !is_plausible(v)) else {
            return Ok(());
        };
        Err(self.dataset_error(
            &array.path,
            Problem::Implausible {
                count: array.values.iter().filter(|&&v| !is_plausible(v)).count(),
                first,
                reason,
            },
        ))
    }

    /// The attribute `name` of the object at `at` (a path; "" is the root),
    /// checked to be a scalar of kind `want`; `None` when it is missing.
    fn attribute(
        &self,
        loc: &Location,
        at: &str,
        name: &str,
        want: Want,
    ) -> Checked<Option<Attribute>> {
        let object = || format!("attribute {name} of {}", shown(at));
        // Opened by name, not found by listing the attributes: listing
        // builds a table that libhdf5 1.10 frees wrongly when a damaged
        // file breaks it off (a segmentation fault, found by
        // tests/it/plot_fuzz.rs).
        let attr = match loc.attr(name) {
            Ok(attr) => attr,
            Err(e) if is_missing_attribute(&e) => return Ok(None),
            Err(e) => return Err(self.error(object(), unreadable(e))),
        };
        let found = attr
            .dtype()
            .and_then(|t| t.to_descriptor())
            .map_err(|e| self.error(object(), unreadable(e)))?;
        if !want.accepts(&found) {
            return Err(self.error(
                object(),
                Problem::WrongType {
                    found: type_name(&found),
                    expected: want.describe(),
                },
            ));
        }
        if !attr.is_scalar() {
            return Err(self.error(
                object(),
                Problem::WrongShape {
                    found: attr.shape(),
                    expected: Vec::new(),
                    reason: "a single value".to_owned(),
                },
            ));
        }
        Ok(Some(attr))
    }

    /// The text attribute `name` of the object at `at`, if it exists.
    pub(super) fn text_attr(
        &self,
        loc: &Location,
        at: &str,
        name: &str,
    ) -> Checked<Option<String>> {
        let Some(attr) = self.attribute(loc, at, name, Want::Text)? else {
            return Ok(None);
        };
        let object = || format!("attribute {name} of {}", shown(at));
        let bytes = if is_ascii(attr.dtype()) {
            attr.read_scalar::<VarLenAscii>()
                .map(|s| s.as_bytes().to_vec())
        } else {
            attr.read_scalar::<VarLenUnicode>()
                .map(|s| s.as_bytes().to_vec())
        }
        .map_err(|e| self.error(object(), unreadable(e)))?;
        String::from_utf8(bytes).map(Some).map_err(|_| {
            self.error(
                object(),
                Problem::Invalid("holds text that is not UTF-8".to_owned()),
            )
        })
    }

    /// The number attribute `name` of the object at `at`, which must exist
    /// and be finite and within [`PLAUSIBLE`].
    pub(super) fn number_attr(&self, loc: &Location, at: &str, name: &str) -> Checked<f64> {
        let object = || format!("attribute {name} of {}", shown(at));
        let attr = self
            .attribute(loc, at, name, Want::Float)?
            .ok_or_else(|| self.error(object(), Problem::Missing))?;
        let value = attr
            .read_scalar::<f64>()
            .map_err(|e| self.error(object(), unreadable(e)))?;
        if !is_plausible(value) {
            return Err(self.error(
                object(),
                Problem::Invalid(format!(
                    "is {value:e}, expected a finite number within ±{PLAUSIBLE:e}"
                )),
            ));
        }
        Ok(value)
    }

    /// The integer attribute `name` of the object at `at`, if it exists.
    pub(super) fn integer_attr(
        &self,
        loc: &Location,
        at: &str,
        name: &str,
    ) -> Checked<Option<u64>> {
        let Some(attr) = self.attribute(loc, at, name, Want::Integer)? else {
            return Ok(None);
        };
        attr.read_scalar::<u64>()
            .map(Some)
            .map_err(|e| self.error(format!("attribute {name} of {}", shown(at)), unreadable(e)))
    }

    /// Whether the object at `at` has an attribute `name`.
    pub(super) fn has_attr(&self, loc: &Location, name: &str) -> bool {
        loc.attr(name).is_ok()
    }
}

/// Whether opening an attribute by name failed because there is none of
/// that name (libhdf5 says "can't locate attribute").
fn is_missing_attribute(e: &hdf5::Error) -> bool {
    e.to_string().contains("can't locate attribute")
}

/// Whether `dtype` is ASCII text (else, for text, UTF-8).
fn is_ascii(dtype: hdf5::Result<hdf5::Datatype>) -> bool {
    matches!(
        dtype.and_then(|t| t.to_descriptor()),
        Ok(TypeDescriptor::VarLenAscii)
    )
}

/// A short name of a stored type for messages: "float64", "uint32",
/// "text", ...
fn type_name(found: &TypeDescriptor) -> String {
    match found {
        TypeDescriptor::VarLenUnicode
        | TypeDescriptor::VarLenAscii
        | TypeDescriptor::FixedAscii(_)
        | TypeDescriptor::FixedUnicode(_) => "text".to_owned(),
        other => other.to_string(),
    }
}

/// The problem of an object that libhdf5 could not read, with its reason.
fn unreadable(e: hdf5::Error) -> Problem {
    Problem::Unreadable(e.to_string())
}
