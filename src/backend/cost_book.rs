//! The GPU costs measured on this machine, kept for `--backend auto`: after
//! every run on a hardware GPU, its fixed costs (opening the device, the
//! pipeline from pidm's cache, the self-test), and where auto had probed
//! the run, its throughput in CPU-core equivalents (the probe's estimate of
//! the run's core-seconds on the CPU path over the GPU's integrating
//! seconds), keyed by adapter and precision. auto weighs the median of an
//! adapter's last [`KEEP`] runs ([`Book::costs`]), each figure on its own,
//! and the results/gpu.md defaults where nothing was measured.
//!
//! The file is `gpu-costs.txt` in pidm's cache folder (beside the pipeline
//! cache: [`crate::gpu::cache::folder`], so `PIDM_CACHE_DIR` moves it and
//! `PIDM_CACHE_DIR=off` turns it off), one line per run after a header. A
//! file that cannot be read as one is ignored with a warning and replaced
//! by the next record; a record that cannot be written is reported on
//! stderr. Neither stops a run. Concurrent runs may lose each other's
//! record (the file is replaced whole, atomically), never corrupt it.

use std::path::{Path, PathBuf};

use super::Precision;
use super::cost::{GpuCosts, Measured};

/// The file's first line.
const HEADER: &str =
    "# pidm GPU costs 1: adapter, precision, open_s, ready_s, cores (- unmeasured)";

/// The file's name in the cache folder.
pub const FILE_NAME: &str = "gpu-costs.txt";

/// Runs kept per adapter and precision.
pub const KEEP: usize = 16;

/// A GPU run's integrating time below which it measures the GPU's start
/// more than its throughput [s]: its throughput is not recorded.
pub const MIN_INTEGRATING_S: f64 = 0.05;

/// One GPU run's measured costs.
#[derive(Clone, Debug, PartialEq)]
pub struct Entry {
    /// The adapter, as `GpuContext::describe` names it.
    pub adapter: String,
    pub precision: Precision,
    /// Finding the adapter and opening the device [s].
    pub open_s: f64,
    /// The pipeline and the self-test [s].
    pub ready_s: f64,
    /// The run's throughput in CPU-core equivalents, where it was measured.
    pub cores: Option<f64>,
}

/// Every run recorded.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Book {
    entries: Vec<Entry>,
}

/// The file's path, or `None` where pidm keeps no cache.
pub fn path() -> Option<PathBuf> {
    crate::gpu::cache::folder().map(|dir| dir.join(FILE_NAME))
}

fn precision_of(text: &str) -> Option<Precision> {
    match text {
        "f32" => Some(Precision::F32),
        "f64" => Some(Precision::F64),
        _ => None,
    }
}

/// A positive finite number of seconds or cores.
fn positive(text: &str) -> Option<f64> {
    text.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite() && *v > 0.0)
}

/// The median of `values` (not empty).
fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

impl Book {
    /// Reads a book from its text; `Err` says why it is not one.
    pub fn parse(text: &str) -> Result<Book, String> {
        let mut lines = text.lines();
        if lines.next() != Some(HEADER) {
            return Err("not a pidm GPU cost file of this version".into());
        }
        let mut entries = Vec::new();
        for (n, line) in lines.enumerate() {
            let fields: Vec<&str> = line.split('\t').collect();
            let entry = match fields[..] {
                [adapter, precision, open, ready, cores] if !adapter.is_empty() => (|| {
                    Some(Entry {
                        adapter: adapter.to_string(),
                        precision: precision_of(precision)?,
                        open_s: positive(open)?,
                        ready_s: positive(ready)?,
                        cores: match cores {
                            "-" => None,
                            c => Some(positive(c)?),
                        },
                    })
                })(
                ),
                _ => None,
            };
            match entry {
                Some(e) => entries.push(e),
                None => return Err(format!("line {} is not a record: {line:?}", n + 2)),
            }
        }
        Ok(Book { entries })
    }

    /// The book's text.
    pub fn render(&self) -> String {
        let mut text = format!("{HEADER}\n");
        for e in &self.entries {
            let cores = e.cores.map_or("-".to_string(), |c| format!("{c}"));
            text.push_str(&format!(
                "{}\t{}\t{}\t{}\t{cores}\n",
                e.adapter, e.precision, e.open_s, e.ready_s
            ));
        }
        text
    }

    /// Reads the book at `path`: an empty one where there is no file, and
    /// where the file cannot be read as a book an empty one and a warning.
    pub fn load(path: &Path) -> (Book, Option<String>) {
        let text = match std::fs::read(path) {
            Ok(bytes) => bytes,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return (Book::default(), None),
            Err(e) => return (Book::default(), Some(ignored(path, &e.to_string()))),
        };
        if text.len() > 1 << 20 {
            return (Book::default(), Some(ignored(path, "larger than 1 MiB")));
        }
        let parsed = std::str::from_utf8(&text)
            .map_err(|_| "not UTF-8 text".to_string())
            .and_then(Book::parse);
        match parsed {
            Ok(book) => (book, None),
            Err(why) => (Book::default(), Some(ignored(path, &why))),
        }
    }

    /// Adds a run, keeping the last [`KEEP`] of its adapter and precision.
    pub fn add(&mut self, entry: Entry) {
        let clean = |s: &str| s.replace(['\t', '\n', '\r'], " ");
        let entry = Entry {
            adapter: clean(&entry.adapter),
            ..entry
        };
        let same = |e: &Entry| e.adapter == entry.adapter && e.precision == entry.precision;
        let kept = self.entries.iter().filter(|e| same(e)).count();
        if kept >= KEEP {
            let mut drop = kept + 1 - KEEP;
            self.entries.retain(|e| {
                if drop > 0 && same(e) {
                    drop -= 1;
                    false
                } else {
                    true
                }
            });
        }
        self.entries.push(entry);
    }

    /// What a GPU costs on `adapter` in `precision`: the medians of its
    /// runs' fixed costs and throughputs, the defaults where none measured
    /// one.
    pub fn costs(&self, adapter: &str, precision: Precision) -> GpuCosts {
        let runs: Vec<&Entry> = self
            .entries
            .iter()
            .filter(|e| e.adapter == adapter && e.precision == precision)
            .collect();
        let mut costs = GpuCosts::default();
        let from = |runs: usize| Measured {
            adapter: adapter.to_string(),
            precision,
            runs,
        };
        if !runs.is_empty() {
            costs.open_s = median(runs.iter().map(|e| e.open_s).collect());
            costs.ready_s = median(runs.iter().map(|e| e.ready_s).collect());
            costs.fixed_from = Some(from(runs.len()));
        }
        let cores: Vec<f64> = runs.iter().filter_map(|e| e.cores).collect();
        if !cores.is_empty() {
            costs.cores_from = Some(from(cores.len()));
            costs.cores = median(cores);
        }
        costs
    }

    /// The GPUs auto may open before it knows which: every adapter and
    /// precision measured (in `precision` where one is asked for), or the
    /// default where none was.
    pub fn known(&self, precision: Option<Precision>) -> Vec<GpuCosts> {
        let mut keys: Vec<(&str, Precision)> = Vec::new();
        for e in &self.entries {
            let key = (e.adapter.as_str(), e.precision);
            if precision.is_none_or(|p| p == e.precision) && !keys.contains(&key) {
                keys.push(key);
            }
        }
        if keys.is_empty() {
            return vec![GpuCosts::default()];
        }
        keys.into_iter()
            .map(|(adapter, precision)| self.costs(adapter, precision))
            .collect()
    }

    /// Writes the book to `path` (to a temporary name, then renamed).
    pub fn save(&self, path: &Path) -> std::io::Result<()> {
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir)?;
        }
        let tmp = path.with_extension(format!("tmp{}", std::process::id()));
        std::fs::write(&tmp, self.render())?;
        std::fs::rename(&tmp, path).inspect_err(|_| {
            let _ = std::fs::remove_file(&tmp);
        })
    }
}

fn ignored(path: &Path, why: &str) -> String {
    format!(
        "pidm: ignoring the GPU cost file {} ({why}): --backend auto weighs the default GPU costs \
         of results/gpu.md, and the next GPU run replaces the file",
        path.display()
    )
}

/// The book auto weighs: this machine's file, or an empty book where there
/// is none or it cannot be read (said on stderr).
pub fn load() -> Book {
    let Some(path) = path() else {
        return Book::default();
    };
    let (book, warning) = Book::load(&path);
    if let Some(warning) = warning {
        eprintln!("{warning}");
    }
    book
}

/// Adds a run to this machine's file; a failure is said on stderr, never
/// returned.
pub fn record(entry: Entry) {
    if let Some(path) = path() {
        for line in record_at(&path, entry) {
            eprintln!("{line}");
        }
    }
}

/// Adds a run to the book at `path`, replacing a file that is not a book;
/// returns what there is to say (a warning, a failure to write).
pub fn record_at(path: &Path, entry: Entry) -> Vec<String> {
    let (mut book, warning) = Book::load(path);
    let mut said: Vec<String> = warning.into_iter().collect();
    book.add(entry);
    if let Err(e) = book.save(path) {
        said.push(format!(
            "pidm: could not record the GPU's costs in {}: {e}",
            path.display()
        ));
    }
    said
}

#[cfg(test)]
mod tests {
    use super::*;

    const H100: &str = "NVIDIA H100 80GB HBM3 (Vulkan, DiscreteGpu)";

    fn entry(adapter: &str, precision: Precision, open_s: f64, cores: Option<f64>) -> Entry {
        Entry {
            adapter: adapter.into(),
            precision,
            open_s,
            ready_s: 0.04,
            cores,
        }
    }

    #[test]
    fn the_book_weighs_the_median_of_each_adapters_runs() {
        use Precision::{F32, F64};
        let mut book = Book::default();
        assert_eq!(book.known(None), vec![GpuCosts::default()]);
        assert_eq!(book.costs(H100, F64), GpuCosts::default());
        // A cold first run (a pipeline compile) and two warm ones: the
        // median is a warm one's.
        book.add(entry(H100, F64, 2.5, None));
        book.add(entry(H100, F64, 0.15, Some(28.0)));
        book.add(entry(H100, F64, 0.13, Some(40.0)));
        book.add(entry(H100, F32, 0.14, Some(50.0)));
        let c = book.costs(H100, F64);
        assert_eq!((c.open_s, c.ready_s, c.cores), (0.15, 0.04, 34.0));
        assert_eq!(c.fixed_from.as_ref().unwrap().runs, 3);
        assert_eq!(c.cores_from.as_ref().unwrap().runs, 2);
        // Another adapter has the defaults; f32 its own figures.
        assert_eq!(book.costs("other", F64), GpuCosts::default());
        assert_eq!(book.costs(H100, F32).cores, 50.0);
        assert_eq!(book.known(None).len(), 2);
        assert_eq!(book.known(Some(F32)).len(), 1);
        assert_eq!(book.known(Some(F32))[0].cores, 50.0);
        // Fixed costs measured without a throughput keep the default one.
        let mut fixed = Book::default();
        fixed.add(entry(H100, F64, 0.12, None));
        let c = fixed.costs(H100, F64);
        assert_eq!((c.open_s, c.cores), (0.12, 31.0));
        assert!(c.cores_from.is_none() && c.fixed_from.is_some());
    }

    #[test]
    fn the_book_keeps_the_last_runs_of_each_adapter() {
        let mut book = Book::default();
        book.add(entry("other", Precision::F64, 0.3, None));
        for k in 0..(KEEP + 5) {
            book.add(entry(H100, Precision::F64, 1.0 + k as f64, None));
        }
        let c = book.costs(H100, Precision::F64);
        assert_eq!(c.fixed_from.unwrap().runs, KEEP);
        // The oldest five are gone: the median of 6..=21.
        assert_eq!(c.open_s, 13.5);
        assert_eq!(book.costs("other", Precision::F64).open_s, 0.3);
    }

    #[test]
    fn the_book_survives_its_text_and_refuses_what_is_not_one() {
        let mut book = Book::default();
        book.add(entry("tab\there", Precision::F32, 0.2, Some(12.5)));
        book.add(entry(H100, Precision::F64, 0.15, None));
        let text = book.render();
        let back = Book::parse(&text).unwrap();
        assert_eq!(back, book);
        assert_eq!(back.costs("tab here", Precision::F32).cores, 12.5);
        for bad in [
            "",
            "some other file\n",
            &format!("{HEADER}\nx\tf64\t0.1\t0.1\n"),
            &format!("{HEADER}\nx\tf16\t0.1\t0.1\t-\n"),
            &format!("{HEADER}\nx\tf64\t-0.1\t0.1\t-\n"),
            &format!("{HEADER}\nx\tf64\t0.1\tNaN\t-\n"),
            &format!("{HEADER}\nx\tf64\t0.1\t0.1\tinf\n"),
            &format!("{HEADER}\n\tf64\t0.1\t0.1\t-\n"),
        ] {
            assert!(Book::parse(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn a_damaged_file_is_ignored_with_a_warning_and_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub").join(FILE_NAME);
        // No file: an empty book, nothing said.
        assert_eq!(Book::load(&path), (Book::default(), None));
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, b"\xff\xfe garbage").unwrap();
        let (book, warning) = Book::load(&path);
        assert_eq!(book, Book::default());
        let warning = warning.unwrap();
        assert!(warning.contains("ignoring the GPU cost file"), "{warning}");
        assert!(warning.contains("not UTF-8"), "{warning}");
        let mut book = Book::default();
        book.add(entry(H100, Precision::F64, 0.15, Some(30.0)));
        book.save(&path).unwrap();
        assert_eq!(Book::load(&path), (book, None));
        // A folder where the file should be is reported, not fatal.
        let folder = dir.path().join("folder");
        std::fs::create_dir(&folder).unwrap();
        let (book, warning) = Book::load(&folder);
        assert_eq!(book, Book::default());
        assert!(warning.is_some());
        assert_eq!(
            record_at(&folder, entry(H100, Precision::F64, 0.1, None)).len(),
            2
        );
        // A foreign file is replaced by the next record, with a warning.
        std::fs::write(&path, "something else\n").unwrap();
        let said = record_at(&path, entry(H100, Precision::F32, 0.14, Some(20.0)));
        assert_eq!(said.len(), 1, "{said:?}");
        let (book, warning) = Book::load(&path);
        assert_eq!(warning, None);
        assert_eq!(book.costs(H100, Precision::F32).cores, 20.0);
        assert_eq!(book.costs(H100, Precision::F64), GpuCosts::default());
        // Later records add to it.
        assert!(record_at(&path, entry(H100, Precision::F32, 0.16, Some(30.0))).is_empty());
        assert_eq!(Book::load(&path).0.costs(H100, Precision::F32).cores, 25.0);
    }
}
