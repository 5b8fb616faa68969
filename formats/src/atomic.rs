//! Atomic output files: written under a temporary name in the destination folder, then
//! renamed over the destination, so a killed process never leaves a half-written file
//! under the final name.
//!
//! No fsync: a process killed at any moment cannot expose a partial file (the rename is
//! atomic), and after a power loss an output whose data did not reach the disk fails the
//! content hash that its stage record checks on every re-run, so it is recomputed rather
//! than trusted. Syncing every output would cost more than the stage itself.

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::error::{FileError, io_in_file, write_error_in_file};
use crate::hashing_writer::HashingWriter;

/// A buffered writer of an [`AtomicFile`] that hashes its bytes as they are written.
pub type HashedFileWriter = BufWriter<HashingWriter<std::fs::File>>;

/// A file being written; it appears under its final name only on [`AtomicFile::commit`].
pub struct AtomicFile {
    tmp: tempfile::NamedTempFile,
    dest: PathBuf,
}

impl AtomicFile {
    /// Starts writing `dest` (its folder must exist).
    pub fn create(dest: &Path) -> Result<Self, FileError> {
        let dir = dest
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let file_name = dest
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let tmp = tempfile::Builder::new()
            .prefix(&format!(".{file_name}."))
            .suffix(".tmp")
            .permissions(readable_by_all())
            .tempfile_in(dir)
            .map_err(|e| io_in_file(dest, e))?;
        Ok(Self {
            tmp,
            dest: dest.to_path_buf(),
        })
    }

    /// The open temporary file.
    pub fn file(&mut self) -> &mut std::fs::File {
        self.tmp.as_file_mut()
    }

    /// A clone of the temporary file's handle (for writers that take ownership).
    pub fn file_handle(&self) -> Result<std::fs::File, FileError> {
        self.tmp
            .as_file()
            .try_clone()
            .map_err(|e| io_in_file(&self.dest, e))
    }

    /// The destination path.
    pub fn dest(&self) -> &Path {
        &self.dest
    }

    /// A writer of the file through a buffer of `capacity` bytes, hashing what it writes
    /// front to back ([`crate::hashing_writer`]); [`Self::commit_written`] closes it.
    pub fn hashed_writer(&self, capacity: usize) -> Result<HashedFileWriter, FileError> {
        Ok(BufWriter::with_capacity(
            capacity,
            HashingWriter::new(self.file_handle()?),
        ))
    }

    /// Closes `writer` (its buffer written out, its handle closed) and commits the file
    /// with the hash of what went through it, telling the listener once it is in place
    /// ([`crate::hashing_writer::listen_to_written`]).
    pub fn commit_written(self, writer: HashedFileWriter) -> Result<(), FileError> {
        let (handle, hash) = writer
            .into_inner()
            .map_err(|e| write_error_in_file(&self.dest, e.into_error()))?
            .finish();
        // The file's handle is closed before the file is put in place.
        drop(handle);
        self.commit_hashed(&hash)
    }

    /// Renames the file to its destination (no fsync: see the module documentation).
    pub fn commit(self) -> Result<(), FileError> {
        let dest = self.dest;
        self.tmp
            .persist(&dest)
            .map_err(|e| io_in_file(&dest, e.error))?;
        Ok(())
    }

    /// [`Self::commit`] of a file whose bytes hashed to `hash` as they were written,
    /// front to back ([`crate::hashing_writer`]), telling its listener once in place.
    fn commit_hashed(self, hash: &blake3::Hash) -> Result<(), FileError> {
        let dest = self.dest.clone();
        self.commit()?;
        crate::hashing_writer::tell_written(&dest, hash);
        Ok(())
    }
}

/// Outputs are ordinary files (0644 on Unix), not the private 0600 of temporary files.
fn readable_by_all() -> std::fs::Permissions {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::Permissions::from_mode(0o644)
    }
    #[cfg(not(unix))]
    {
        std::fs::metadata(".")
            .map(|m| m.permissions())
            .unwrap_or_else(|_| unreachable!())
    }
}

/// Removes the temporary files (`.<name>.<random>.tmp`) that writers of `dest` killed
/// before their commit left beside it. Only for a folder this process alone writes (an
/// output folder under its lock): another writer's open temporary file would go too.
pub fn remove_stale_temps_of(dest: &Path) {
    let (Some(dir), Some(name)) = (dest.parent(), dest.file_name()) else {
        return;
    };
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let prefix = format!(".{}.", name.to_string_lossy());
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let file_name = e.file_name();
        let n = file_name.to_string_lossy();
        if n.len() > prefix.len() + ".tmp".len() && n.starts_with(&prefix) && n.ends_with(".tmp") {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// Writes `bytes` to `dest` atomically.
pub fn write_atomic(dest: &Path, bytes: &[u8]) -> Result<(), FileError> {
    let mut f = AtomicFile::create(dest)?;
    {
        let mut w = BufWriter::new(f.file());
        w.write_all(bytes)
            .and_then(|()| w.flush())
            .map_err(|e| write_error_in_file(dest, e))?;
    }
    f.commit()
}

/// Serialises `value` as pretty JSON (with a final newline) to `dest` atomically.
pub fn write_json_atomic(dest: &Path, value: &impl serde::Serialize) -> Result<(), FileError> {
    let mut bytes = serde_json::to_vec_pretty(value)
        .map_err(|e| crate::error::FormatError::from(e).in_file(dest))?;
    bytes.push(b'\n');
    write_atomic(dest, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The names in `dir`, sorted.
    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn a_file_written_through_its_hashed_writer_is_told_once_in_place_whole() {
        use crate::hashing_writer::told::told;
        let dir = tempfile::tempdir().unwrap();
        let dest = dir.path().join("hashed.bin");
        // Listening before the file is written: nothing is told until it is in place.
        assert_eq!(told(&dest), None);
        let file = AtomicFile::create(&dest).unwrap();
        // A buffer smaller than the bytes, and bytes still in it at the close.
        let mut w = file.hashed_writer(4096).unwrap();
        let bytes: Vec<u8> = (0..10_000u32).map(|i| (i * 31 + 3) as u8).collect();
        w.write_all(&bytes).unwrap();
        assert_eq!(told(&dest), None);
        assert!(!dest.exists());
        file.commit_written(w).unwrap();
        assert_eq!(std::fs::read(&dest).unwrap(), bytes);
        assert_eq!(told(&dest), Some(blake3::hash(&bytes)));
        assert_eq!(names(dir.path()), ["hashed.bin"]);
    }

    #[test]
    fn a_new_file_appears_whole_and_alone() {
        let dir = tempfile::tempdir().unwrap();
        let dest = dir.path().join("a.json");
        write_atomic(&dest, b"first").unwrap();
        assert_eq!(std::fs::read(&dest).unwrap(), b"first");
        assert_eq!(names(dir.path()), ["a.json"]);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&dest).unwrap().permissions().mode();
            assert_eq!(mode & 0o777, 0o644);
        }
    }

    #[test]
    fn a_file_there_is_replaced_whole_and_nothing_else_is_left() {
        let dir = tempfile::tempdir().unwrap();
        let dest = dir.path().join("nav.parquet");
        std::fs::write(&dest, b"old contents").unwrap();
        // A reader that has the old file open keeps reading it.
        let mut reader = std::fs::File::open(&dest).unwrap();
        write_atomic(&dest, b"new").unwrap();
        assert_eq!(std::fs::read(&dest).unwrap(), b"new");
        assert_eq!(names(dir.path()), ["nav.parquet"]);
        let mut old = String::new();
        std::io::Read::read_to_string(&mut reader, &mut old).unwrap();
        assert_eq!(old, "old contents");
    }

    #[test]
    fn an_uncommitted_file_leaves_the_old_one_untouched() {
        let dir = tempfile::tempdir().unwrap();
        let dest = dir.path().join("tracks.parquet");
        std::fs::write(&dest, b"old").unwrap();
        {
            let mut f = AtomicFile::create(&dest).unwrap();
            f.file().write_all(b"half of it").unwrap();
        }
        assert_eq!(std::fs::read(&dest).unwrap(), b"old");
        assert_eq!(names(dir.path()), ["tracks.parquet"]);
    }

    #[test]
    fn a_folder_in_the_way_is_an_error_naming_it_and_stays_as_it_was() {
        let dir = tempfile::tempdir().unwrap();
        let dest = dir.path().join("out");
        std::fs::create_dir(&dest).unwrap();
        std::fs::write(dest.join("inside"), b"kept").unwrap();
        let e = write_atomic(&dest, b"x").unwrap_err().to_string();
        assert!(e.contains("out"), "{e}");
        assert_eq!(std::fs::read(dest.join("inside")).unwrap(), b"kept");
        assert_eq!(names(dir.path()), ["out"]);
    }

    #[test]
    fn stale_temporary_files_of_one_destination_are_removed_and_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        let dest = dir.path().join("unz.hashes");
        for name in [
            ".unz.hashes.eKdhjq.tmp",
            ".unz.hashes.x.tmp",
            ".unz.hashes.tmp",
            ".unz.hashes2.ab.tmp",
            ".other.ab.tmp",
            "unz.hashes.ab.tmp",
            ".unz.hashes.ab.tmp.keep",
        ] {
            std::fs::write(dir.path().join(name), b"x").unwrap();
        }
        write_atomic(&dest, b"memo").unwrap();
        remove_stale_temps_of(&dest);
        assert_eq!(
            names(dir.path()),
            [
                ".other.ab.tmp",
                ".unz.hashes.ab.tmp.keep",
                ".unz.hashes.tmp",
                ".unz.hashes2.ab.tmp",
                "unz.hashes",
                "unz.hashes.ab.tmp",
            ]
        );
        assert_eq!(std::fs::read(&dest).unwrap(), b"memo");
    }
}
