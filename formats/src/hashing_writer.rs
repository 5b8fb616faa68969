//! A writer that hashes (blake3) the bytes it passes on, in the order it passes them: a
//! file written front to back is hashed as it is written, not read back afterwards for
//! its stage's record (a 12-hour run's `raw.mcap` is 405 MB, its tables 330 MB over the
//! stages). It does not seek, so the bytes it hashed are the file's.
//!
//! The MCAP and Parquet files the formats write go through one, and once each is renamed
//! into place its hash is told to the process's listener ([`listen_to_written`]: the
//! pipeline's record of file hashes).

use std::io::{self, Write};
use std::path::Path;
use std::sync::OnceLock;

/// Told of each file hashed as written, once it is in place.
static LISTENER: OnceLock<fn(&Path, &blake3::Hash)> = OnceLock::new();

/// Has `listener` told, from now on, of each file the formats write through a
/// [`HashingWriter`] (MCAP, Parquet): its path and blake3, once it is renamed into place.
/// The first listener set stays.
pub fn listen_to_written(listener: fn(&Path, &blake3::Hash)) {
    let _ = LISTENER.set(listener);
}

/// Tells the listener, if any, that the file at `path` was put in place with `hash`.
pub(crate) fn tell_written(path: &Path, hash: &blake3::Hash) {
    if let Some(listener) = LISTENER.get() {
        listener(path, hash);
    }
}

/// `inner` with a running blake3 of everything written through it.
pub struct HashingWriter<W: Write> {
    inner: W,
    hasher: blake3::Hasher,
}

impl<W: Write> HashingWriter<W> {
    /// Hashes what is written to `inner` from now on.
    pub fn new(inner: W) -> Self {
        Self {
            inner,
            hasher: blake3::Hasher::new(),
        }
    }

    /// The writer and the hash of the bytes it took (flush it first: bytes still held
    /// by `inner` are hashed but not yet written).
    pub fn finish(self) -> (W, blake3::Hash) {
        let hash = self.hasher.finalize();
        (self.inner, hash)
    }
}

impl<W: Write> Write for HashingWriter<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        // Only what `inner` took: a short write's rest comes again.
        let n = self.inner.write(buf)?;
        self.hasher.update(&buf[..n]);
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

/// The crate's tests' listener: one for the whole test process, as the pipeline's.
#[cfg(test)]
pub(crate) mod told {
    use std::path::{Path, PathBuf};
    use std::sync::Mutex;

    /// The files told as written in this test process, with their hashes.
    static TOLD: Mutex<Vec<(PathBuf, blake3::Hash)>> = Mutex::new(Vec::new());

    fn record(path: &Path, hash: &blake3::Hash) {
        let mut told = TOLD.lock().unwrap_or_else(|e| e.into_inner());
        told.push((path.to_path_buf(), *hash));
    }

    /// The hash last told for `path` (listening from the first call on).
    pub(crate) fn told(path: &Path) -> Option<blake3::Hash> {
        super::listen_to_written(record);
        let told = TOLD.lock().unwrap_or_else(|e| e.into_inner());
        told.iter().rev().find(|(p, _)| p == path).map(|(_, h)| *h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Takes at most 3 bytes a write, and fails every fourth call.
    struct Stingy {
        out: Vec<u8>,
        calls: usize,
    }

    impl Write for Stingy {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            self.calls += 1;
            if self.calls.is_multiple_of(4) {
                return Err(io::Error::new(io::ErrorKind::Interrupted, "again"));
            }
            let n = buf.len().min(3);
            self.out.extend_from_slice(&buf[..n]);
            Ok(n)
        }

        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn the_hash_is_the_written_bytes_hash_through_short_and_interrupted_writes() {
        let data: Vec<u8> = (0..10_000u32).map(|i| (i * 7 % 251) as u8).collect();
        let mut w = HashingWriter::new(Stingy {
            out: Vec::new(),
            calls: 0,
        });
        for piece in data.chunks(97) {
            w.write_all(piece).unwrap();
        }
        let (inner, hash) = w.finish();
        assert_eq!(inner.out, data);
        assert_eq!(hash, blake3::hash(&data));
    }
}
