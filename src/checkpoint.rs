//! Checkpoints: a journal of finished chunks beside the output file, so an
//! interrupted or crashed run can be resumed (`pidm run --resume`) and
//! computes only what is missing.
//!
//! The journal is append-only: a header that names the run, then one entry
//! per finished chunk (first flat index, record count, the part of the run
//! that wrote it and that part's wall time so far, the records, a
//! checksum), each synced to disk before the next chunk starts. A part is
//! one process: the first run is part 0, each `--resume` the next; the
//! wall times let the finished file record the time of every part
//! (`wall_time_parts_s`) and their total (`wall_time_s`). A crash can
//! only tear the last entry, which the checksum exposes and resume drops.
//! The HDF5 output itself is written to a temporary file and renamed only
//! when complete, so the output is never half-written; on resume the
//! temporary file is rebuilt from the journal.

use std::fs::{File, OpenOptions};
use std::io::{BufReader, Read, Seek, SeekFrom, Write};
use std::ops::Range;
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

use crate::output::{FileInfo, MapWriter, OutputClaim};
use crate::sweep::Record;

/// The journal's first bytes: its format. Format 3 added the kind of motion
/// to every record, format 4 its replica count; a journal of another format is refused by name, never
/// read with this format's record layout.
const MAGIC: &[u8; 12] = b"PIDM-CKPT-5\n";
/// What every format's magic starts with.
const MAGIC_FAMILY: &[u8] = b"PIDM-CKPT-";

/// Bytes of an entry's head: start, count, part, wall time so far.
const HEAD_BYTES: usize = 32;

/// Bytes of one record in the journal: sixteen f64 (the backward maps
/// since format 5), six u32 and the motion code (one byte).
pub const RECORD_BYTES: usize = 16 * 8 + 4 * 6 + 1;

/// The checkpoint journal of one output file.
pub struct Checkpoint {
    file: File,
    path: PathBuf,
    /// The part this process writes: 0 for a new run, one more than the
    /// journal's last for a resumed one.
    part: u64,
    /// When this part began.
    started: std::time::Instant,
    /// The wall time of each earlier part up to its last entry [s].
    earlier: Vec<f64>,
    /// Entries appended but not yet written ([`Checkpoint::append_unsynced`]).
    pending: Vec<u8>,
}

/// FNV-1a, 64 bit: enough to tell a torn or garbled entry.
fn checksum(bytes: &[u8]) -> u64 {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        hash ^= b as u64;
        hash = hash.wrapping_mul(0x0000_0100_0000_01b3);
    }
    hash
}

fn encode(record: &Record, out: &mut Vec<u8>) {
    for v in record
        .step
        .iter()
        .chain(&record.velocity)
        .chain(&record.baseline_step)
        .chain(&record.step_se)
        .chain(&record.backward.travel)
        .chain(&record.backward.travel_se)
        .chain(&record.backward.ratio)
        .chain(&record.backward.ratio_se)
    {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in [
        record.status,
        record.steps,
        record.baseline_status,
        record.periods,
        record.period_lag,
        record.replicas,
    ] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.push(record.motion.code());
}

/// The record of one journal entry's bytes, or why it cannot be right (a
/// motion code that does not exist; `Record` cannot hold one, so it is
/// refused here, as [`Record::implausibility`] refuses the rest).
fn decode(bytes: &[u8]) -> Result<Record, String> {
    let f = |k: usize| f64::from_le_bytes(bytes[8 * k..8 * k + 8].try_into().unwrap());
    let u = |k: usize| u32::from_le_bytes(bytes[128 + 4 * k..132 + 4 * k].try_into().unwrap());
    Ok(Record {
        step: [f(0), f(1)],
        velocity: [f(2), f(3)],
        baseline_step: [f(4), f(5)],
        step_se: [f(6), f(7)],
        backward: crate::sweep::Backward {
            travel: [f(8), f(9)],
            travel_se: [f(10), f(11)],
            ratio: [f(12), f(13)],
            ratio_se: [f(14), f(15)],
        },
        status: u(0),
        steps: u(1),
        baseline_status: u(2),
        periods: u(3),
        period_lag: u(4),
        replicas: u(5),
        motion: crate::sweep::stored_motion(bytes[152])?,
    })
}

/// A new run's journal and output writer, the journal first: it also keeps
/// a second run of the same output from starting beside this one. Refuses
/// where an interrupted run's journal is in the way (`--resume` continues
/// it). Every kind of run starts here: plain, refined and stall runs.
pub fn start(
    path: &Path,
    identity: &str,
    claim: &OutputClaim,
    info: &FileInfo,
) -> Result<(Checkpoint, MapWriter)> {
    if path.exists() {
        bail!(
            "{} holds the finished part of an interrupted run of this output; continue it \
             with --resume, or delete it to start over",
            path.display()
        );
    }
    let checkpoint = Checkpoint::create(path, identity)?;
    Ok((checkpoint, MapWriter::create(claim, info)?))
}

/// Opens an existing journal for reading and appending, never through a
/// link.
fn open_journal(path: &Path) -> Result<File> {
    OpenOptions::new()
        .read(true)
        .write(true)
        .custom_flags(libc::O_NOFOLLOW)
        .open(path)
        .with_context(|| format!("cannot open the checkpoint {}", path.display()))
}

/// Reads the journal's magic and the length of the identity that follows
/// it, refusing a journal of another format by name and anything else
/// that is no journal of this format.
fn read_magic(reader: &mut impl Read, path: &Path) -> Result<u64> {
    let mut magic = [0u8; MAGIC.len()];
    let mut len = [0u8; 8];
    let read_magic = reader.read_exact(&mut magic).is_ok();
    if read_magic && &magic != MAGIC && magic.starts_with(MAGIC_FAMILY) {
        let format = String::from_utf8_lossy(&magic[MAGIC_FAMILY.len()..]);
        bail!(
            "the checkpoint {} is of another pidm (journal format {}; this pidm reads \
             format {} only); finish the run with the pidm that began it, or delete the \
             checkpoint to start over",
            path.display(),
            format.trim_end(),
            String::from_utf8_lossy(&MAGIC[MAGIC_FAMILY.len()..]).trim_end()
        );
    }
    if !read_magic || &magic != MAGIC || reader.read_exact(&mut len).is_err() {
        bail!("{} is not a pidm checkpoint", path.display());
    }
    Ok(u64::from_le_bytes(len))
}

/// Reads the stored identity (`stored_len` bytes) and refuses a journal
/// of a run other than `identity`.
fn check_identity(
    reader: &mut impl Read,
    stored_len: u64,
    identity: &str,
    path: &Path,
) -> Result<()> {
    // Nothing is allocated on the word of the file alone: a length that
    // is not the identity's cannot be this run's.
    let mut stored = vec![0u8; identity.len()];
    if stored_len != identity.len() as u64 || reader.read_exact(&mut stored).is_err() {
        stored.clear();
    }
    if stored != identity.as_bytes() {
        bail!(
            "the checkpoint {} is of a different run (another scene, version, backend \
             or shard); delete it to start over",
            path.display()
        );
    }
    Ok(())
}

/// One intact journal entry: its head's words and its records' bytes.
struct JournalEntry {
    start: u64,
    n: u64,
    part: u64,
    wall: f64,
    records: Vec<u8>,
}

impl JournalEntry {
    /// Bytes the entry takes in the journal: head, records and checksum.
    fn bytes(&self) -> u64 {
        HEAD_BYTES as u64 + (self.records.len() + 8) as u64
    }
}

/// Reads the next entry, which starts `valid_len` bytes into a journal of
/// `file_len` bytes; `None` at the end or at a torn or garbled entry.
fn read_entry(reader: &mut impl Read, file_len: u64, valid_len: u64) -> Option<JournalEntry> {
    let mut head = [0u8; HEAD_BYTES];
    reader.read_exact(&mut head).ok()?;
    let word = |k: usize| u64::from_le_bytes(head[8 * k..8 * k + 8].try_into().unwrap());
    let (start, n, part, wall) = (word(0), word(1), word(2), f64::from_bits(word(3)));
    let body_len = (n as usize).checked_mul(RECORD_BYTES)?;
    // An entry longer than what is left of the file is torn.
    if body_len as u64 + 8 > file_len.saturating_sub(valid_len + HEAD_BYTES as u64) {
        return None;
    }
    let mut body = vec![0u8; body_len + 8];
    reader.read_exact(&mut body).ok()?;
    let (records_bytes, sum) = body.split_at(body_len);
    let mut summed = head.to_vec();
    summed.extend_from_slice(records_bytes);
    if checksum(&summed) != u64::from_le_bytes(sum.try_into().unwrap()) {
        return None;
    }
    body.truncate(body_len);
    Some(JournalEntry {
        start,
        n,
        part,
        wall,
        records: body,
    })
}

/// Decodes an intact entry's records (the first is instance `start`),
/// refusing the journal if one cannot be right.
fn plausible_records(path: &Path, start: u64, records_bytes: &[u8]) -> Result<Vec<Record>> {
    let decoded: Vec<Result<Record, String>> =
        records_bytes.chunks(RECORD_BYTES).map(decode).collect();
    let why_not = |r: &Result<Record, String>| match r {
        Ok(r) => r.implausibility(),
        Err(why) => Some(why.clone()),
    };
    if let Some((k, why)) = decoded
        .iter()
        .enumerate()
        .find_map(|(k, r)| Some((k, why_not(r)?)))
    {
        bail!(
            "the checkpoint {} holds a record that cannot be right (instance {}: \
             {why}); delete it to start over",
            path.display(),
            start.saturating_add(k as u64)
        );
    }
    Ok(decoded.into_iter().flatten().collect())
}

/// Records an entry's part and wall time so far in `earlier`, the wall
/// time of each earlier part.
fn note_wall_time(earlier: &mut Vec<f64>, part: u64, wall: f64) {
    // Parts follow one another; a part number far beyond the
    // entries there are cannot be right and counts as the next.
    let part = (part as usize).min(earlier.len());
    if part == earlier.len() {
        earlier.push(0.0);
    }
    if wall.is_finite() && wall >= 0.0 {
        earlier[part] = earlier[part].max(wall);
    }
}

impl Checkpoint {
    /// Starts a new journal for a run identified by `identity` (the scene
    /// text, version, backend and everything else that must match on
    /// resume). Refuses to overwrite an existing journal.
    pub fn create(path: &Path, identity: &str) -> Result<Checkpoint> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("cannot create the folder {}", dir.display()))?;
        }
        let mut file = OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(path)
            .with_context(|| format!("cannot create the checkpoint {}", path.display()))?;
        let mut header = MAGIC.to_vec();
        header.extend_from_slice(&(identity.len() as u64).to_le_bytes());
        header.extend_from_slice(identity.as_bytes());
        file.write_all(&header)?;
        file.sync_data()?;
        Ok(Checkpoint {
            file,
            path: path.to_path_buf(),
            part: 0,
            started: std::time::Instant::now(),
            earlier: Vec::new(),
            pending: Vec::new(),
        })
    }

    /// Opens an existing journal for resuming, checks that it belongs to
    /// the run `identity`, hands every intact entry to `replay` in order,
    /// drops a torn last entry, and returns the journal ready to append,
    /// with the flat index ranges it already holds.
    pub fn resume(
        path: &Path,
        identity: &str,
        replay: &mut dyn FnMut(u64, &[Record]) -> Result<()>,
    ) -> Result<(Checkpoint, Vec<Range<u64>>)> {
        let file = open_journal(path)?;
        let mut reader = BufReader::new(&file);
        let stored_len = read_magic(&mut reader, path)?;
        let file_len = file
            .metadata()
            .with_context(|| format!("cannot inspect {}", path.display()))?
            .len();
        check_identity(&mut reader, stored_len, identity, path)?;
        let mut valid_len = (MAGIC.len() + 8 + identity.len()) as u64;
        let mut done: Vec<Range<u64>> = Vec::new();
        let mut earlier: Vec<f64> = Vec::new();
        while let Some(entry) = read_entry(&mut reader, file_len, valid_len) {
            let records = plausible_records(path, entry.start, &entry.records)?;
            replay(entry.start, &records)?;
            done.push(entry.start..entry.start + entry.n);
            valid_len += entry.bytes();
            note_wall_time(&mut earlier, entry.part, entry.wall);
        }
        drop(reader);
        // Drop a torn tail so new entries follow the last intact one.
        file.set_len(valid_len)?;
        let mut file = file;
        file.seek(SeekFrom::End(0))?;
        done.sort_by_key(|r| r.start);
        Ok((
            Checkpoint {
                file,
                path: path.to_path_buf(),
                part: earlier.len() as u64,
                started: std::time::Instant::now(),
                earlier,
                pending: Vec::new(),
            },
            done,
        ))
    }

    /// Appends the records of instances `start .. start + records.len()`
    /// and syncs them to disk.
    pub fn append(&mut self, start: u64, records: &[Record]) -> Result<()> {
        self.append_unsynced(start, records)?;
        self.sync()
    }

    /// Writes the entries appended so far and syncs them to disk.
    pub fn sync(&mut self) -> Result<()> {
        if !self.pending.is_empty() {
            self.file.write_all(&self.pending)?;
            self.pending.clear();
        }
        self.file
            .sync_data()
            .with_context(|| format!("cannot sync the checkpoint {}", self.path.display()))
    }

    /// Appends an entry without writing it yet: for a chunk of many
    /// scattered ranges (a refined run's), whose entries are written and
    /// synced together by [`Checkpoint::sync`] (a crash before then loses
    /// them, or tears the last, which resume drops).
    pub fn append_unsynced(&mut self, start: u64, records: &[Record]) -> Result<()> {
        let mut entry = Vec::with_capacity(HEAD_BYTES + 8 + records.len() * RECORD_BYTES);
        entry.extend_from_slice(&start.to_le_bytes());
        entry.extend_from_slice(&(records.len() as u64).to_le_bytes());
        entry.extend_from_slice(&self.part.to_le_bytes());
        let wall = self.started.elapsed().as_secs_f64();
        entry.extend_from_slice(&wall.to_bits().to_le_bytes());
        for r in records {
            encode(r, &mut entry);
        }
        let sum = checksum(&entry);
        entry.extend_from_slice(&sum.to_le_bytes());
        self.pending.extend_from_slice(&entry);
        Ok(())
    }

    /// Ends a run whose output file is complete but for its closing: the
    /// file is finished with the wall time of every part of the run (the
    /// earlier parts and this one's `wall_time_s`) and renamed into place,
    /// then the journal is removed. Returns the file's path and the parts.
    pub fn finish(self, writer: MapWriter, wall_time_s: f64) -> Result<(PathBuf, Vec<f64>)> {
        let mut parts = self.earlier.clone();
        parts.push(wall_time_s);
        let path = writer.finish(&parts)?;
        self.remove()?;
        Ok((path, parts))
    }

    /// Deletes the journal once the output file is complete.
    pub fn remove(self) -> Result<()> {
        drop(self.file);
        std::fs::remove_file(&self.path)
            .with_context(|| format!("cannot remove the checkpoint {}", self.path.display()))
    }
}

/// Ascending indices as ranges of consecutive ones (a sweep's work, a
/// journal's entries).
pub fn ranges_of(indices: &[u64]) -> Vec<Range<u64>> {
    let mut out: Vec<Range<u64>> = Vec::new();
    for &i in indices {
        match out.last_mut() {
            Some(r) if r.end == i => r.end += 1,
            _ => out.push(i..i + 1),
        }
    }
    out
}

/// `--resume`'s first check, for every mode: the checkpoint of an
/// interrupted run exists at `path`.
pub fn require(path: &Path) -> Result<()> {
    if !path.exists() {
        bail!(
            "--resume: there is no checkpoint {} of an interrupted run; run without --resume",
            path.display()
        );
    }
    Ok(())
}

/// The ranges of `all` not covered by `done` (both ascending; `done` may
/// hold overlapping or adjacent ranges).
pub fn missing(all: &[Range<u64>], done: &[Range<u64>]) -> Vec<Range<u64>> {
    let mut out = Vec::new();
    for range in all {
        let mut start = range.start;
        for d in done {
            if d.end <= start || d.start >= range.end {
                continue;
            }
            if d.start > start {
                out.push(start..d.start);
            }
            start = start.max(d.end);
        }
        if start < range.end {
            out.push(start..range.end);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::motion::Motion;

    /// A record a run could have written: a failed instance (every third)
    /// has zeros in its map entries and no kind of motion; the others
    /// take every kind in turn.
    fn record(i: u64) -> Record {
        let failed = i % 3 == 1;
        let value = |v: f64| if failed { 0.0 } else { v };
        let motion = if failed {
            Motion::Undetermined
        } else {
            Motion::ALL[i as usize % Motion::ALL.len()]
        };
        Record {
            step: [value(i as f64 * 1e-9), value(-1.5)],
            velocity: [value(f64::MIN_POSITIVE), value(2.0)],
            status: if failed { 1 + i as u32 % 5 } else { 0 },
            steps: i as u32,
            step_se: [value(i as f64 * 1e-12), 0.0],
            periods: 10 + i as u32,
            period_lag: i as u32 % 4,
            motion,
            replicas: 1 + i as u32 % 3,
            baseline_step: [0.25, -0.0],
            baseline_status: 5,
            backward: crate::sweep::Backward {
                travel: [value(i as f64 * 1e-10), 0.0],
                travel_se: [value(1e-12), 0.0],
                ratio: [value(0.25), 0.0],
                ratio_se: [value(0.01), 0.0],
            },
        }
    }

    #[test]
    fn every_kind_of_motion_survives_the_journal() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(".out.h5.checkpoint");
        let mut ck = Checkpoint::create(&path, "run A").unwrap();
        let records: Vec<Record> = (0..12).map(record).collect();
        let kinds: Vec<Motion> = records.iter().map(|r| r.motion).collect();
        for kind in Motion::ALL {
            assert!(kinds.contains(&kind), "{kind:?} missing from {kinds:?}");
        }
        ck.append(0, &records).unwrap();
        drop(ck);
        let mut replayed = Vec::new();
        Checkpoint::resume(&path, "run A", &mut |_, r| {
            replayed.extend_from_slice(r);
            Ok(())
        })
        .unwrap();
        assert_eq!(replayed, records);
    }

    /// The journal of one record, and where that record's motion code sits.
    fn journal_of(path: &Path, record: &Record) -> (Vec<u8>, usize) {
        let mut ck = Checkpoint::create(path, "run A").unwrap();
        ck.append(0, std::slice::from_ref(record)).unwrap();
        drop(ck);
        let bytes = std::fs::read(path).unwrap();
        let header = MAGIC.len() + 8 + "run A".len();
        (bytes, header + HEAD_BYTES + RECORD_BYTES - 1)
    }

    /// Sets the motion code of the journal's one record and its checksum
    /// to match, as a journal written with a wrong code would be.
    fn with_motion_code(path: &Path, mut bytes: Vec<u8>, at: usize, code: u8) {
        bytes[at] = code;
        let entry = at + 1 - RECORD_BYTES - HEAD_BYTES;
        let sum = checksum(&bytes[entry..at + 1]);
        bytes[at + 1..at + 9].copy_from_slice(&sum.to_le_bytes());
        std::fs::write(path, &bytes).unwrap();
    }

    #[test]
    fn a_journal_with_an_impossible_motion_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(".out.h5.checkpoint");
        let (bytes, at) = journal_of(&path, &record(0));
        assert_eq!(bytes[at], record(0).motion.code());
        // No such code.
        with_motion_code(&path, bytes.clone(), at, 9);
        let err = Checkpoint::resume(&path, "run A", &mut |_, _| Ok(()))
            .err()
            .expect("refused");
        let err = err.to_string();
        assert!(
            err.contains("holds a record that cannot be right (instance 0: its motion is 9, which is no motion code"),
            "{err}"
        );
        // A kind of motion on a failed instance.
        std::fs::remove_file(&path).unwrap();
        let (bytes, at) = journal_of(&path, &record(1));
        with_motion_code(&path, bytes, at, Motion::Periodic.code());
        let err = Checkpoint::resume(&path, "run A", &mut |_, _| Ok(()))
            .err()
            .expect("refused");
        let err = err.to_string();
        assert!(
            err.contains("but its motion is periodic, not undetermined"),
            "{err}"
        );
    }

    #[test]
    fn a_journal_of_an_older_format_is_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(".out.h5.checkpoint");
        // A format 3 journal: its records lack the replica count.
        let mut bytes = b"PIDM-CKPT-3\n".to_vec();
        bytes.extend_from_slice(&5u64.to_le_bytes());
        bytes.extend_from_slice(b"run A");
        std::fs::write(&path, &bytes).unwrap();
        let err = Checkpoint::resume(&path, "run A", &mut |_, _| Ok(()))
            .err()
            .expect("refused");
        let err = err.to_string();
        assert!(
            err.contains("is of another pidm (journal format 3; this pidm reads format 5 only)")
                && err.contains("delete the checkpoint to start over"),
            "{err}"
        );
        std::fs::write(&path, b"something else entirely").unwrap();
        let err = Checkpoint::resume(&path, "run A", &mut |_, _| Ok(()))
            .err()
            .expect("refused");
        assert!(
            err.to_string().ends_with("is not a pidm checkpoint"),
            "{err}"
        );
    }

    #[test]
    #[allow(clippy::single_range_in_vec_init)]
    fn missing_ranges_are_the_complement() {
        let check = |all: &[Range<u64>], done: &[Range<u64>], want: &[Range<u64>]| {
            assert_eq!(missing(all, done), want, "{all:?} minus {done:?}");
        };
        check(&[0..10], &[], &[0..10]);
        check(&[0..10], &[0..10], &[]);
        check(&[0..10], &[2..4, 6..7], &[0..2, 4..6, 7..10]);
        check(&[0..4, 8..12], &[3..9], &[0..3, 9..12]);
        check(&[0..4], &[0..2, 2..4], &[]);
    }

    #[test]
    #[allow(clippy::single_range_in_vec_init)]
    fn a_journal_replays_what_was_appended_and_drops_a_torn_tail() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(".out.h5.checkpoint");
        let mut ck = Checkpoint::create(&path, "run A").unwrap();
        let first: Vec<Record> = (0..3).map(record).collect();
        let second: Vec<Record> = (10..12).map(record).collect();
        ck.append(0, &first).unwrap();
        ck.append(10, &second).unwrap();
        drop(ck);
        // Tear the last entry, as a crash in the middle of a write would.
        let len = std::fs::metadata(&path).unwrap().len();
        let f = OpenOptions::new().write(true).open(&path).unwrap();
        f.set_len(len - 5).unwrap();
        drop(f);

        let mut replayed = Vec::new();
        let (mut ck, done) = Checkpoint::resume(&path, "run A", &mut |s, r| {
            replayed.push((s, r.to_vec()));
            Ok(())
        })
        .unwrap();
        assert_eq!(done, [0..3]);
        assert_eq!(replayed, [(0, first.clone())]);
        // New entries follow the last intact one.
        ck.append(10, &second).unwrap();
        drop(ck);
        let mut again = Vec::new();
        let (_, done) = Checkpoint::resume(&path, "run A", &mut |s, r| {
            again.push((s, r.to_vec()));
            Ok(())
        })
        .unwrap();
        assert_eq!(done, [0..3, 10..12]);
        assert_eq!(again, [(0, first), (10, second)]);

        let err = Checkpoint::resume(&path, "run B", &mut |_, _| Ok(()))
            .err()
            .unwrap();
        assert!(err.to_string().contains("different run"), "{err}");
        assert!(Checkpoint::create(&path, "run A").is_err());
    }

    /// One way of damaging a journal.
    #[derive(Clone, Debug)]
    enum Damage {
        Truncate(usize),
        Flip(usize, u8),
        Insert(usize, Vec<u8>),
        Overwrite(usize, u64),
    }

    fn damage_strategy() -> impl proptest::strategy::Strategy<Value = Vec<Damage>> {
        use proptest::prelude::*;
        let one = prop_oneof![
            any::<usize>().prop_map(Damage::Truncate),
            (any::<usize>(), 1..=255u8).prop_map(|(at, bits)| Damage::Flip(at, bits)),
            (
                any::<usize>(),
                proptest::collection::vec(any::<u8>(), 1..64)
            )
                .prop_map(|(at, bytes)| Damage::Insert(at, bytes)),
            (any::<usize>(), any::<u64>()).prop_map(|(at, v)| Damage::Overwrite(at, v)),
        ];
        proptest::collection::vec(one, 1..4)
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig {
            cases: 100,
            failure_persistence: None,
            ..Default::default()
        })]

        /// Whatever happens to a journal, resuming gives an error or a
        /// prefix of what was appended, never a panic, a foreign record or
        /// an allocation on the file's word.
        #[test]
        fn a_damaged_journal_resumes_to_a_prefix_or_an_error(damages in damage_strategy()) {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join(".out.h5.checkpoint");
            let mut ck = Checkpoint::create(&path, "run A").unwrap();
            let entries: Vec<(u64, Vec<Record>)> = [(0u64, 0..4u64), (4, 4..5), (9, 9..12)]
                .into_iter()
                .map(|(start, range)| (start, range.map(record).collect()))
                .collect();
            for (start, records) in &entries {
                ck.append(*start, records).unwrap();
            }
            drop(ck);
            let mut bytes = std::fs::read(&path).unwrap();
            for damage in damages {
                let at = |k: usize| k % (bytes.len() + 1);
                match damage {
                    Damage::Truncate(k) => bytes.truncate(at(k)),
                    Damage::Flip(k, bits) if !bytes.is_empty() => {
                        let k = k % bytes.len();
                        bytes[k] ^= bits;
                    }
                    Damage::Flip(..) => {}
                    Damage::Insert(k, extra) => {
                        let k = at(k);
                        bytes.splice(k..k, extra);
                    }
                    Damage::Overwrite(k, v) => {
                        let k = at(k);
                        let end = (k + 8).min(bytes.len());
                        bytes.splice(k..end, v.to_le_bytes());
                    }
                }
            }
            std::fs::write(&path, &bytes).unwrap();
            let mut replayed = Vec::new();
            let resumed = Checkpoint::resume(&path, "run A", &mut |s, r| {
                replayed.push((s, r.to_vec()));
                Ok(())
            });
            if resumed.is_ok() {
                proptest::prop_assert!(replayed.len() <= entries.len());
                proptest::prop_assert_eq!(&replayed[..], &entries[..replayed.len()]);
            }
        }
    }
}
