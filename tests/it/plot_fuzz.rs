//! `pidm plot` on randomly damaged result files: a valid small file is cut
//! short, has bytes flipped, or has datasets and attributes deleted or
//! resized, and plotting it must either succeed with every picture written
//! or fail with an error that names the file and leaves no picture behind;
//! it must never panic (a panic fails the case).
//!
//! Files changed through HDF5 or cut short are plotted by calling
//! `pidm::plot::plot_file` here. Files with flipped bytes are plotted by
//! `pidm plot` in a child process, because libhdf5 (1.10) itself may crash
//! or hang on damaged metadata before pidm sees a value; such a fault is
//! printed and allowed, a panic or any other failure is not.
//!
//! The cases come from a fixed seed, so a run is repeatable; set
//! PROPTEST_RNG_SEED to explore others and PROPTEST_CASES for more of them.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use hdf5::types::TypeDescriptor;
use pidm::plot::{ResultFileError, plot_file};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed, TestCaseError};

/// The seed used unless PROPTEST_RNG_SEED gives another.
const SEED: u64 = 20_240_611;

/// What the valid file holds: its bytes, and the paths of its datasets and
/// (object, attribute) pairs, to pick from.
struct Valid {
    bytes: Vec<u8>,
    datasets: Vec<String>,
    attributes: Vec<(String, String)>,
}

/// A valid result file of a 2 x 2 grid with baselines and one trajectory,
/// made once by `pidm run`.
fn valid() -> &'static Valid {
    static VALID: OnceLock<Valid> = OnceLock::new();
    VALID.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("fuzz.toml"),
            "name = \"fuzz\"\n\
             [axis.x]\nvoltage = [0.0, 100.0]\n\
             [axis.y]\nvoltage = [0.0, 100.0]\n\
             [simulation]\nmeasure = \"window\"\ncycles = 2\nsettle = 1\n\
             [output]\nbaselines = true\ntrajectories = [3]\n\
             trajectory_samples_per_cycle = 8\n",
        )
        .unwrap();
        // No HDF5 file locks in the child: see `common::pidm`.
        let out = Command::new(env!("CARGO_BIN_EXE_pidm"))
            .env("HDF5_USE_FILE_LOCKING", "FALSE")
            .args(["run", "fuzz.toml", "--threads", "1", "--out", "fuzz.h5"])
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let path = dir.path().join("fuzz.h5");
        let file = hdf5::File::open(&path).unwrap();
        let mut datasets = Vec::new();
        let mut attributes = Vec::new();
        walk(&file, "", &mut datasets, &mut attributes);
        Valid {
            bytes: std::fs::read(&path).unwrap(),
            datasets,
            attributes,
        }
    })
}

/// Collects the datasets and attributes under the group `g` at `at`.
fn walk(g: &hdf5::Group, at: &str, datasets: &mut Vec<String>, attrs: &mut Vec<(String, String)>) {
    for name in g.attr_names().unwrap() {
        attrs.push((at.to_owned(), name));
    }
    for name in g.member_names().unwrap() {
        let path = format!("{at}/{name}");
        if let Ok(sub) = g.group(&name) {
            walk(&sub, &path, datasets, attrs);
        } else if let Ok(ds) = g.dataset(&name) {
            for attr in ds.attr_names().unwrap() {
                attrs.push((path.clone(), attr));
            }
            datasets.push(path);
        }
    }
}

/// One change to the file; indices and positions are taken modulo what
/// there is, fractions of the file's length.
#[derive(Clone, Debug)]
enum Mutation {
    /// Delete the dataset with this index.
    DeleteDataset(usize),
    /// Replace the dataset with this index by a 1-D one of this length,
    /// of the same kind of numbers.
    ResizeDataset(usize, usize),
    /// Set one value of the float dataset with this index (other datasets
    /// stay as they are).
    SetValue(usize, usize, f64),
    /// Delete the attribute with this index.
    DeleteAttribute(usize),
    /// Keep this fraction of the file's bytes.
    Truncate(f64),
    /// XOR the byte at this fraction of the file with a non-zero mask.
    Flip(f64, u8),
    /// XOR the byte at this offset with a non-zero mask: the start of the
    /// file holds the superblock and the first object headers.
    FlipHead(usize, u8),
}

impl Mutation {
    /// Whether the change goes through HDF5 (and so must come before any
    /// change to the raw bytes, which may leave a file HDF5 cannot open).
    fn is_structural(&self) -> bool {
        matches!(
            self,
            Mutation::DeleteDataset(_)
                | Mutation::ResizeDataset(..)
                | Mutation::SetValue(..)
                | Mutation::DeleteAttribute(_)
        )
    }
}

/// Any one change, the kinds equally likely.
fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        any::<usize>().prop_map(Mutation::DeleteDataset),
        (any::<usize>(), 0usize..40).prop_map(|(i, n)| Mutation::ResizeDataset(i, n)),
        (any::<usize>(), any::<usize>(), value()).prop_map(|(i, k, v)| Mutation::SetValue(i, k, v)),
        any::<usize>().prop_map(Mutation::DeleteAttribute),
        (0.0..1.0f64).prop_map(Mutation::Truncate),
        (0.0..1.0f64, 1u8..=255).prop_map(|(at, mask)| Mutation::Flip(at, mask)),
        (0usize..4096, 1u8..=255).prop_map(|(at, mask)| Mutation::FlipHead(at, mask)),
    ]
}

/// A value to put into a dataset: any number, or one at the edges of what
/// a float can hold.
fn value() -> impl Strategy<Value = f64> {
    prop_oneof![
        any::<f64>(),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(-f64::MAX),
        Just(f64::MAX),
        Just(1e100),
        Just(-1e100),
        Just(f64::MIN_POSITIVE / 4.0),
        Just(0.0),
    ]
}

/// Applies the structural `changes` to the file at `path` through HDF5.
fn restructure(path: &Path, changes: &[&Mutation]) -> hdf5::Result<()> {
    let valid = valid();
    let file = hdf5::File::open_rw(path)?;
    for change in changes {
        match **change {
            Mutation::DeleteDataset(i) => {
                let name = &valid.datasets[i % valid.datasets.len()];
                // Deleted already through another of its names: no change.
                let _ = file.unlink(name);
            }
            Mutation::ResizeDataset(i, n) => {
                let name = &valid.datasets[i % valid.datasets.len()];
                let Ok(ds) = file.dataset(name) else {
                    continue;
                };
                let integer = matches!(
                    ds.dtype()?.to_descriptor()?,
                    TypeDescriptor::Integer(_) | TypeDescriptor::Unsigned(_)
                );
                drop(ds);
                file.unlink(name)?;
                if integer {
                    let values: Vec<u32> = (0..n as u32).collect();
                    file.new_dataset::<u32>()
                        .shape([n])
                        .create(name.as_str())?
                        .write_raw(&values)?;
                } else {
                    let values: Vec<f64> = (0..n).map(|k| k as f64 * 1e-7).collect();
                    file.new_dataset::<f64>()
                        .shape([n])
                        .create(name.as_str())?
                        .write_raw(&values)?;
                }
            }
            Mutation::SetValue(i, k, value) => {
                let name = &valid.datasets[i % valid.datasets.len()];
                let Ok(ds) = file.dataset(name) else {
                    continue;
                };
                if !matches!(ds.dtype()?.to_descriptor()?, TypeDescriptor::Float(_)) {
                    continue;
                }
                let mut values: Vec<f64> = ds.read_raw()?;
                if !values.is_empty() {
                    let n = values.len();
                    values[k % n] = value;
                    ds.write_raw(&values)?;
                }
            }
            Mutation::DeleteAttribute(i) => {
                let (at, name) = &valid.attributes[i % valid.attributes.len()];
                let at = if at.is_empty() { "/" } else { at.as_str() };
                if let Ok(g) = file.group(at) {
                    let _ = g.delete_attr(name);
                } else if let Ok(ds) = file.dataset(at) {
                    let _ = ds.delete_attr(name);
                }
            }
            _ => unreachable!("only structural changes go through HDF5"),
        }
    }
    Ok(())
}

/// Applies the byte-level `changes` to `bytes`.
fn damage_bytes(bytes: &mut Vec<u8>, changes: &[&Mutation]) {
    for change in changes {
        match **change {
            Mutation::Truncate(keep) => bytes.truncate((keep * bytes.len() as f64) as usize),
            Mutation::Flip(at, mask) if !bytes.is_empty() => {
                let k = ((at * bytes.len() as f64) as usize).min(bytes.len() - 1);
                bytes[k] ^= mask;
            }
            Mutation::FlipHead(at, mask) if at < bytes.len() => bytes[at] ^= mask,
            _ => {}
        }
    }
}

/// The names of the PNG files in `dir` (none when it does not exist).
fn pictures(dir: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut found: Vec<PathBuf> = entries
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    found.sort();
    found
}

/// 64 cases from a fixed seed (unless PROPTEST_RNG_SEED is set), no
/// regression files, a short shrink.
fn config() -> Config {
    let default = Config::default();
    Config {
        cases: 64,
        // Cases are repeatable from the seed; no regression files are
        // written into the source tree.
        failure_persistence: None,
        rng_seed: match default.rng_seed {
            RngSeed::Random => RngSeed::Fixed(SEED),
            fixed => fixed,
        },
        max_shrink_iters: 64,
        ..default
    }
}

/// How plotting a damaged file ended.
#[derive(Debug)]
enum Outcome {
    /// Success: the pictures written, as listed.
    Pictures(Vec<PathBuf>),
    /// An error, with its message.
    Error(String),
    /// libhdf5 itself crashed or hung on damaged metadata (see
    /// [`plot_in_child`]).
    LibraryFault(String),
}

/// Plots `file` into `out` by calling the library; any panic fails the
/// case. Every error must be a [`ResultFileError`].
fn plot_here(file: &Path, out: &Path) -> Result<Outcome, TestCaseError> {
    Ok(match plot_file(file, out) {
        Ok(plotted) => Outcome::Pictures(plotted.files),
        Err(err) => {
            let message = format!("{err:#}");
            prop_assert!(
                err.downcast_ref::<ResultFileError>().is_some(),
                "not a result file error: {}",
                message
            );
            Outcome::Error(message)
        }
    })
}

/// Plots `file` into `out` with `pidm plot` in a child process. Flipped
/// bytes can break HDF5's own metadata, and libhdf5 (1.10) is not safe
/// against that: on a damaged global heap it can read out of bounds
/// (SIGSEGV) or loop for ever, before pidm sees any value. Such a death
/// by a memory fault, or no answer within the limit, is reported as a
/// library fault; a panic (exit 101) or any other exit fails the case.
fn plot_in_child(dir: &Path, file: &Path, out: &Path) -> Result<Outcome, TestCaseError> {
    use std::os::unix::process::ExitStatusExt;
    use std::process::Stdio;
    use std::time::{Duration, Instant};

    let mut child = Command::new(env!("CARGO_BIN_EXE_pidm"))
        .arg("plot")
        .arg(file)
        .arg("--out")
        .arg(out)
        .current_dir(dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(5);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            child.kill().unwrap();
            child.wait().unwrap();
            return Ok(Outcome::LibraryFault("no answer in 5 s".to_owned()));
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let output = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    prop_assert!(!stderr.contains("panicked"), "pidm panicked:\n{}", stderr);
    Ok(match (output.status.code(), output.status.signal()) {
        (Some(0), _) => Outcome::Pictures(
            stdout
                .lines()
                .filter_map(|l| l.strip_prefix("wrote "))
                .map(|p| dir.join(p))
                .collect(),
        ),
        (Some(1), _) => Outcome::Error(stderr),
        // SIGSEGV or SIGBUS: a memory fault, which safe Rust cannot cause.
        (None, Some(signal @ (11 | 7))) => {
            Outcome::LibraryFault(format!("signal {signal}: {stderr}"))
        }
        (code, signal) => {
            return Err(TestCaseError::fail(format!(
                "pidm plot ended with code {code:?}, signal {signal:?}:\n{stderr}"
            )));
        }
    })
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn damaged_files_give_all_pictures_or_an_error_never_a_panic(
        changes in proptest::collection::vec(mutation(), 1..4)
    ) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("damaged.h5");
        std::fs::write(&path, &valid().bytes).unwrap();
        let (structural, raw): (Vec<&Mutation>, Vec<&Mutation>) =
            changes.iter().partition(|m| m.is_structural());
        if !structural.is_empty() {
            restructure(&path, &structural).unwrap();
        }
        let mut bytes = std::fs::read(&path).unwrap();
        damage_bytes(&mut bytes, &raw);
        std::fs::write(&path, &bytes).unwrap();

        // Files changed through HDF5 or cut short (which libhdf5 detects
        // on opening) are plotted by the library in this process; files
        // with flipped bytes in a child process.
        let out = dir.path().join("pics");
        let flipped = raw.iter().any(|m| matches!(m, Mutation::Flip(..) | Mutation::FlipHead(..)));
        let outcome = if flipped {
            plot_in_child(dir.path(), &path, &out)?
        } else {
            plot_here(&path, &out)?
        };
        match outcome {
            Outcome::Pictures(mut listed) => {
                listed.sort();
                listed.dedup();
                prop_assert!(!listed.is_empty());
                prop_assert_eq!(pictures(&out), listed);
            }
            Outcome::Error(message) => {
                prop_assert!(message.contains("damaged.h5"), "{}", message);
                prop_assert_eq!(pictures(&out), Vec::<PathBuf>::new(), "{}", message);
            }
            Outcome::LibraryFault(what) => {
                eprintln!("libhdf5 failed on {changes:?}: {what}");
                // The file is read whole before anything is drawn.
                prop_assert_eq!(pictures(&out), Vec::<PathBuf>::new());
            }
        }
        let leftovers: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .filter(|n| n.to_string_lossy().contains("plotting"))
            .collect();
        prop_assert!(leftovers.is_empty(), "staging left: {:?}", leftovers);
    }
}
