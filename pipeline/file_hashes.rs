//! Content hashes of the files the stage records name, computed once per file.
//!
//! A file is known by its identity: device, inode, size, modification and status-change
//! times. Every output is written to a new file and renamed into place, so a rewritten
//! file has a new inode (or, when a re-running stage removed the old one first, through
//! [`remove_file`], which forgets its hash, perhaps the old one's number), and any write
//! to a file moves its status-change time (`ctime`, which no user call can set back). A
//! hash is remembered for the process, and saved in
//! the output folder (`OUT/unz.hashes`, read back by the next process holding the
//! folder's lock), so a fully cached campaign stats its files instead of reading them.
//!
//! Timestamps are coarse (one kernel tick, up to 10 ms): a file changed in the same tick
//! as it was read would keep its identity. So a hash is saved only when the file's last
//! change was at least [`SETTLED`] before the read started, and the read kept the
//! file's identity ("racy" entries, as git calls them, are read again by the next
//! process), with one exception: files under the output folder. Only the process holding
//! its lock writes there, and it hashes its outputs right after renaming them into
//! place (a stage's record), or as they are written ([`remember_written`]: a file
//! written front to back, its hash kept with its identity once renamed); a change in
//! that instant from outside would already be taken into the record as if the stage had
//! written it.

use std::collections::HashMap;
use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::{LazyLock, Mutex};
use std::time::{Duration, SystemTime};

use anyhow::Context;
use serde::{Deserialize, Serialize};
use unz_formats::atomic::{remove_stale_temps_of, write_atomic};

/// The saved hashes' file name in an output folder (a reserved run name).
pub const MEMO_FILE: &str = "unz.hashes";

/// Version of [`MEMO_FILE`]'s content; a file of another version is ignored.
const MEMO_VERSION: u32 = 1;

/// How long before a read a file must have last changed for its hash to be saved: more
/// than one kernel tick (10 ms at the lowest usual rate, 100 Hz).
pub const SETTLED: Duration = Duration::from_millis(20);

/// What identifies a file's content without reading it. Not its name: the same file
/// named two ways (`o/r/x` from the campaign's folder, `../o/r/x` from another) is one.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub(crate) struct FileId {
    dev: u64,
    ino: u64,
    len: u64,
    mtime: (i64, i64),
    ctime: (i64, i64),
}

impl FileId {
    fn of(path: &Path) -> Option<FileId> {
        Some(Self::of_metadata(&std::fs::metadata(path).ok()?))
    }

    /// The identity of the file `file` has open (what its reads read).
    fn of_file(file: &File) -> Option<FileId> {
        Some(Self::of_metadata(&file.metadata().ok()?))
    }

    fn of_metadata(m: &std::fs::Metadata) -> FileId {
        use std::os::unix::fs::MetadataExt;
        FileId {
            dev: m.dev(),
            ino: m.ino(),
            len: m.len(),
            mtime: (m.mtime(), m.mtime_nsec()),
            ctime: (m.ctime(), m.ctime_nsec()),
        }
    }

    /// The status-change time as a point in time (`None` before 1970 or out of range).
    fn changed_at(&self) -> Option<SystemTime> {
        let (s, ns) = self.ctime;
        let d = Duration::new(u64::try_from(s).ok()?, u32::try_from(ns).ok()?);
        SystemTime::UNIX_EPOCH.checked_add(d)
    }
}

/// Whether a hash read from `read_start` on can be saved for a file last changed at
/// `changed_at`: any later change falls in a later tick, so it changes the identity.
fn settled(changed_at: Option<SystemTime>, read_start: SystemTime) -> bool {
    changed_at
        .and_then(|c| c.checked_add(SETTLED))
        .is_some_and(|c| c < read_start)
}

/// A remembered hash.
#[derive(Debug, Clone)]
struct Known {
    blake3: String,
    /// Whether the file had settled when read (see [`settled`]).
    settled: bool,
    /// The name this process last asked for it by (a loaded entry's: the saving
    /// process's, which may not resolve from this working directory).
    path: PathBuf,
}

/// Hashes known to this process.
static KNOWN: LazyLock<Mutex<HashMap<FileId, Known>>> = LazyLock::new(Default::default);

fn known() -> std::sync::MutexGuard<'static, HashMap<FileId, Known>> {
    // The map holds plain data: a panic elsewhere while holding it leaves it usable.
    KNOWN.lock().unwrap_or_else(|e| e.into_inner())
}

/// blake3 of a file's content (hex), streamed, or remembered while the file keeps its
/// identity.
pub fn file_hash(path: &Path) -> anyhow::Result<String> {
    let id = FileId::of(path);
    if let Some(id) = &id
        && let Some(k) = known().get_mut(id)
    {
        // Known by the name this process uses: the one `save` can stat again.
        if k.path != path {
            k.path = path.to_path_buf();
        }
        return Ok(k.blake3.clone());
    }
    let read_start = SystemTime::now();
    let h = hash_content(path)?;
    if let Some(id) = id
        && FileId::of(path).as_ref() == Some(&id)
    {
        remember_read(id, read_start, &h, path);
    }
    Ok(h)
}

/// Remembers `hash` (hex) for the file of identity `id`, read whole from `read_start` on
/// and named `path`, the identity being unchanged after the read.
fn remember_read(id: FileId, read_start: SystemTime, hash: &str, path: &Path) {
    let settled = settled(id.changed_at(), read_start);
    known().entry(id).or_insert(Known {
        blake3: hash.to_owned(),
        settled,
        path: path.to_path_buf(),
    });
}

/// A file a stage reads front to back, hashed as its bytes are read: at its end, its
/// hash is remembered as [`file_hash`] would have read it (the identity taken from the
/// open file before the first read and again at the end), so the stage's record does
/// not read it again (a 12-hour binary log is 207 MB; read again from the page cache
/// on this VM at about 0.8 GB/s). A reader that stops before the end remembers
/// nothing.
pub struct HashingRead {
    file: File,
    path: PathBuf,
    /// The identity at the start, the read's start and the hash so far; `None` once at
    /// the end (or when the identity could not be taken).
    open: Option<(FileId, SystemTime, blake3::Hasher)>,
}

impl HashingRead {
    /// Reads `file`, opened at its start, which `path` names.
    pub fn new(file: File, path: &Path) -> Self {
        let read_start = SystemTime::now();
        let open = FileId::of_file(&file).map(|id| (id, read_start, blake3::Hasher::new()));
        Self {
            file,
            path: path.to_path_buf(),
            open,
        }
    }
}

impl Read for HashingRead {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.file.read(buf)?;
        if n > 0 {
            if let Some((_, _, hasher)) = &mut self.open {
                hasher.update(&buf[..n]);
            }
        } else if !buf.is_empty()
            && let Some((id, read_start, hasher)) = self.open.take()
            && FileId::of_file(&self.file).as_ref() == Some(&id)
        {
            let hash = hasher.finalize().to_hex();
            remember_read(id, read_start, &hash, &self.path);
        }
        Ok(n)
    }
}

/// Remembers `hash` for the file this process just put in place at `path`, hashed as
/// its bytes were written ([`unz_formats::hashing_writer`], which tells it here once
/// [`remember_what_formats_write`] was called): the stage's record then takes it without
/// reading the file back. Like any output's, it is kept while the file keeps
/// the identity it has now.
pub fn remember_written(path: &Path, hash: &blake3::Hash) {
    if let Some(id) = FileId::of(path) {
        known().insert(
            id,
            Known {
                blake3: hash.to_hex().to_string(),
                // Under the output folder, where only this process writes (see the
                // module's notes): saved, as an output hashed right after its rename is.
                settled: false,
                path: path.to_path_buf(),
            },
        );
    }
}

fn hash_content(path: &Path) -> anyhow::Result<String> {
    let read = || -> std::io::Result<blake3::Hash> {
        Ok(blake3::Hasher::new()
            .update_reader(unz_formats::regular::open_regular(path)?)?
            .finalize())
    };
    let h = read().with_context(|| format!("cannot read {}", path.display()))?;
    Ok(h.to_hex().to_string())
}

/// Forgets the remembered hashes (a benchmark's "cached" pass measures what a new
/// process would do: it then [`load`]s them).
pub fn forget_hashes() {
    known().clear();
}

/// Removes the file `path` (none there is no error), forgetting its hash first: a file
/// written after it may be given its inode, and one written in the same clock tick with
/// the same length would have its identity.
pub fn remove_file(path: &Path) -> std::io::Result<()> {
    if let Some(id) = FileId::of(path) {
        known().remove(&id);
    }
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(e),
        _ => Ok(()),
    }
}

/// Whether this process remembers a hash for `path` as it is now (no read).
#[cfg(test)]
pub(crate) fn remembered(path: &Path) -> Option<String> {
    known().get(&FileId::of(path)?).map(|k| k.blake3.clone())
}

/// `path`'s identity as it is now.
#[cfg(test)]
pub(crate) fn identity(path: &Path) -> Option<FileId> {
    FileId::of(path)
}

/// Whether this process remembers a hash for a file of identity `id`.
#[cfg(test)]
pub(crate) fn knows(id: &FileId) -> bool {
    known().contains_key(id)
}

/// [`MEMO_FILE`]'s content.
#[derive(Debug, Serialize, Deserialize)]
struct Memo {
    version: u32,
    files: Vec<MemoEntry>,
}

/// One saved hash.
#[derive(Debug, Serialize, Deserialize)]
struct MemoEntry {
    path: PathBuf,
    #[serde(flatten)]
    id: FileId,
    blake3: String,
}

/// Has the files the formats hash as they write them (MCAP, Parquet) remembered
/// ([`remember_written`]) from now on: their stage's record then reads none of them back.
pub fn remember_what_formats_write() {
    unz_formats::hashing_writer::listen_to_written(remember_written);
}

/// Reads the hashes an earlier process saved in `out` into this process's, and remembers
/// the outputs' hashes as they are written from now on ([`remember_what_formats_write`]).
/// A missing, unreadable or foreign file is no error: the files are then read and
/// hashed.
pub fn load(out: &Path) {
    remember_what_formats_write();
    let Ok(bytes) = std::fs::read(out.join(MEMO_FILE)) else {
        return;
    };
    let Ok(memo) = serde_json::from_slice::<Memo>(&bytes) else {
        return;
    };
    if memo.version != MEMO_VERSION {
        return;
    }
    let mut known = known();
    for e in memo.files {
        known.entry(e.id).or_insert(Known {
            blake3: e.blake3,
            settled: true,
            path: e.path,
        });
    }
}

/// Saves into `out` (atomically) the hashes [`load`] may trust: those of files that still
/// have the identity they were hashed with, and were settled when read or lie under
/// `out` (see the module's notes). Returns how many.
pub fn save(out: &Path) -> anyhow::Result<usize> {
    let entries: Vec<MemoEntry> = known()
        .iter()
        .filter(|(_, k)| k.settled || k.path.starts_with(out))
        .map(|(id, k)| MemoEntry {
            path: k.path.clone(),
            id: id.clone(),
            blake3: k.blake3.clone(),
        })
        .collect();
    let mut files: Vec<MemoEntry> = entries
        .into_iter()
        .filter(|e| FileId::of(&e.path).as_ref() == Some(&e.id))
        .collect();
    files.sort_by(|a, b| a.path.cmp(&b.path));
    let n = files.len();
    // One line per file: a campaign of hundreds of runs saves thousands.
    let mut bytes = format!("{{\"version\":{MEMO_VERSION},\"files\":[\n").into_bytes();
    for (i, e) in files.iter().enumerate() {
        if i > 0 {
            bytes.extend_from_slice(b",\n");
        }
        serde_json::to_writer(&mut bytes, e)?;
    }
    bytes.extend_from_slice(b"\n]}\n");
    let dest = out.join(MEMO_FILE);
    // What a process killed while saving left (the folder is this one's: see `crate::lock`).
    remove_stale_temps_of(&dest);
    write_atomic(&dest, &bytes)?;
    Ok(n)
}

#[cfg(test)]
mod tests {
    use std::io::Write;

    use super::*;

    fn hex(bytes: &[u8]) -> String {
        blake3::hash(bytes).to_hex().to_string()
    }

    #[test]
    fn a_file_named_another_way_is_known() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        let p = dir.path().join("a.bin");
        std::fs::write(&p, b"named twice").unwrap();
        assert_eq!(file_hash(&p).unwrap(), hex(b"named twice"));
        // From a sibling folder, as a campaign run from elsewhere names it: no read, and
        // the name asked for last is the one saved (the one that resolves from here).
        let alias = dir.path().join("sub").join("..").join("a.bin");
        assert_eq!(remembered(&alias), Some(hex(b"named twice")));
        assert_eq!(file_hash(&alias).unwrap(), hex(b"named twice"));
        assert_eq!(known()[&FileId::of(&p).unwrap()].path, alias);
    }

    #[test]
    fn a_file_read_whole_is_remembered_with_the_hash_of_its_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("log.unz");
        let bytes: Vec<u8> = (0..300_000u32).map(|i| (i * 7 % 251) as u8).collect();
        std::fs::write(&p, &bytes).unwrap();
        let mut read = HashingRead::new(File::open(&p).unwrap(), &p);
        // In pieces of every size, as a reader's buffer takes them.
        let mut got = Vec::new();
        let mut buf = vec![0u8; 4097];
        for k in 1.. {
            let n = read.read(&mut buf[..k % 4097]).unwrap();
            if n == 0 && k % 4097 != 0 {
                break;
            }
            got.extend_from_slice(&buf[..n]);
            if k < 300_000 {
                assert_eq!(remembered(&p), None, "nothing before the end");
            }
        }
        assert_eq!(got, bytes);
        assert_eq!(remembered(&p), Some(hex(&bytes)));
        assert_eq!(file_hash(&p).unwrap(), hex(&bytes));
    }

    #[test]
    fn a_file_read_in_part_or_changed_while_read_is_not_remembered() {
        let dir = tempfile::tempdir().unwrap();
        let (part, changed) = (dir.path().join("part.unz"), dir.path().join("changed.unz"));
        std::fs::write(&part, b"0123456789").unwrap();
        std::fs::write(&changed, b"0123456789").unwrap();
        let mut buf = [0u8; 4];
        let mut read = HashingRead::new(File::open(&part).unwrap(), &part);
        assert_eq!(read.read(&mut buf).unwrap(), 4);
        // An empty buffer's read of 0 bytes is not the end.
        assert_eq!(read.read(&mut []).unwrap(), 0);
        drop(read);
        assert_eq!(remembered(&part), None);

        let mut read = HashingRead::new(File::open(&changed).unwrap(), &changed);
        let mut got = Vec::new();
        assert_eq!(read.read(&mut buf).unwrap(), 4);
        got.extend_from_slice(&buf);
        // Appended to behind the reader, which reads the new bytes: its identity moved.
        std::fs::OpenOptions::new()
            .append(true)
            .open(&changed)
            .unwrap()
            .write_all(b"ab")
            .unwrap();
        loop {
            let n = read.read(&mut buf).unwrap();
            if n == 0 {
                break;
            }
            got.extend_from_slice(&buf[..n]);
        }
        assert_eq!(got, b"0123456789ab");
        assert_eq!(remembered(&changed), None);
        assert_eq!(file_hash(&changed).unwrap(), hex(b"0123456789ab"));
    }

    #[test]
    fn a_removed_file_is_forgotten() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.bin");
        std::fs::write(&p, b"to go").unwrap();
        file_hash(&p).unwrap();
        let id = FileId::of(&p).unwrap();
        assert!(known().contains_key(&id));
        remove_file(&p).unwrap();
        assert!(!p.exists());
        assert!(!known().contains_key(&id), "a new file may take its inode");
        // Gone already: no error.
        remove_file(&p).unwrap();
    }

    #[test]
    fn a_file_replaced_by_rename_is_hashed_again() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.bin");
        std::fs::write(&p, b"first").unwrap();
        let h1 = file_hash(&p).unwrap();
        assert_eq!(file_hash(&p).unwrap(), h1, "remembered");
        // Same size, written the way every output is: a new file renamed into place.
        let tmp = dir.path().join(".a.bin.tmp");
        std::fs::write(&tmp, b"other").unwrap();
        std::fs::rename(&tmp, &p).unwrap();
        let h2 = file_hash(&p).unwrap();
        assert_ne!(h1, h2);
        assert_eq!(h2, hex(b"other"));
    }

    #[test]
    fn only_a_hash_read_a_tick_after_the_files_last_change_is_saved() {
        let t = SystemTime::UNIX_EPOCH + Duration::from_secs(1_700_000_000);
        assert!(settled(Some(t), t + SETTLED + Duration::from_nanos(1)));
        assert!(!settled(Some(t), t + SETTLED));
        assert!(!settled(Some(t), t));
        // A change time in the future (another machine's clock) is never settled.
        assert!(!settled(Some(t + Duration::from_secs(5)), t));
        assert!(!settled(None, t));
    }

    #[test]
    fn saved_hashes_answer_a_new_process_until_the_file_changes() {
        let dir = tempfile::tempdir().unwrap();
        let (out, p, q) = (
            dir.path().join("out"),
            dir.path().join("a.bin"),
            dir.path().join("b.bin"),
        );
        std::fs::create_dir(&out).unwrap();
        std::fs::write(&p, b"first").unwrap();
        std::fs::write(&q, b"kept!").unwrap();
        std::thread::sleep(SETTLED * 3);
        assert_eq!(file_hash(&p).unwrap(), hex(b"first"));
        assert_eq!(file_hash(&q).unwrap(), hex(b"kept!"));
        assert!(save(&out).unwrap() >= 2);

        // A new process: nothing remembered until the saved hashes are loaded.
        known().retain(|_, k| k.path != p && k.path != q);
        assert_eq!(remembered(&p), None);
        load(&out);
        assert_eq!(remembered(&p), Some(hex(b"first")));
        assert_eq!(remembered(&q), Some(hex(b"kept!")));

        // Rewritten in place with the same size: its change time moves, so it is read.
        std::fs::write(&p, b"other").unwrap();
        assert_eq!(remembered(&p), None);
        assert_eq!(file_hash(&p).unwrap(), hex(b"other"));
        assert_eq!(file_hash(&q).unwrap(), hex(b"kept!"));

        // A file gone since is not saved again, nor a content it no longer has (its new
        // one is saved once settled when read: not here, read right after the write).
        std::fs::remove_file(&q).unwrap();
        save(&out).unwrap();
        let saved: Memo =
            serde_json::from_slice(&std::fs::read(out.join(MEMO_FILE)).unwrap()).unwrap();
        assert!(saved.files.iter().all(|e| e.path != q));
        assert!(
            saved
                .files
                .iter()
                .all(|e| e.path != p || e.blake3 == hex(b"other"))
        );
    }

    #[test]
    fn a_file_read_as_it_changed_is_saved_only_under_the_output_folder() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        std::fs::create_dir(&out).unwrap();
        let (outside, inside) = (dir.path().join("log.unz"), out.join("nav.parquet"));
        // Hashed in the tick they were written (when this thread is not held up for
        // longer than half of SETTLED between the write and the read, which the assertion
        // checks before relying on it).
        let t = std::time::Instant::now();
        std::fs::write(&outside, b"log").unwrap();
        std::fs::write(&inside, b"nav").unwrap();
        file_hash(&outside).unwrap();
        file_hash(&inside).unwrap();
        let fresh = t.elapsed() < SETTLED / 2;
        save(&out).unwrap();
        let saved: Memo =
            serde_json::from_slice(&std::fs::read(out.join(MEMO_FILE)).unwrap()).unwrap();
        assert!(saved.files.iter().any(|e| e.path == inside));
        if fresh {
            assert!(saved.files.iter().all(|e| e.path != outside));
        }
    }

    #[test]
    fn a_damaged_or_foreign_memo_is_ignored() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.bin");
        std::fs::write(&p, b"content").unwrap();
        let id = FileId::of(&p).unwrap();
        let lie = |version: u32| Memo {
            version,
            files: vec![MemoEntry {
                path: p.clone(),
                id: id.clone(),
                blake3: hex(b"a lie"),
            }],
        };
        for bytes in [
            b"{ not json".to_vec(),
            serde_json::to_vec(&lie(MEMO_VERSION + 1)).unwrap(),
            vec![0xff; 64],
        ] {
            std::fs::write(dir.path().join(MEMO_FILE), bytes).unwrap();
            load(dir.path());
            assert_eq!(remembered(&p), None);
        }
        // The file's own version is trusted as long as the identity holds: that is what
        // makes a cached campaign fast, and why only this process writes it.
        std::fs::write(
            dir.path().join(MEMO_FILE),
            serde_json::to_vec(&lie(MEMO_VERSION)).unwrap(),
        )
        .unwrap();
        load(dir.path());
        assert_eq!(remembered(&p), Some(hex(b"a lie")));
    }
}
