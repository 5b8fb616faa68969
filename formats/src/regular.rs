//! Opening an input that must be a regular file, without blocking on anything else.
//!
//! An archived campaign is untrusted: a run folder may hold a FIFO, a socket or a device
//! node where its manifest names the raw log (an archive tool restores them as they
//! were). Opening a FIFO for reading waits for a writer, forever, and a device may never
//! end: either would stop the whole campaign, not only its run. Every input a run names
//! (its manifest, raw log and odometer file, and the stage cache's hashes of them) is
//! opened here: without blocking, then refused unless it is a regular file.

use std::fs::File;
use std::io;
use std::path::Path;

/// Opens `path` (following symbolic links) for reading if it is a regular file; any
/// other kind is refused with [`io::ErrorKind::InvalidInput`], without waiting on it.
///
/// On Unix the open does not block (`O_NONBLOCK`: a FIFO opens at once), and the kind is
/// read from the opened file, so a file switched after a check cannot slip through.
/// `O_NONBLOCK` stays set, which has no effect on a regular file's reads.
pub fn open_regular(path: &Path) -> io::Result<File> {
    #[cfg(unix)]
    let file = {
        use std::os::unix::fs::OpenOptionsExt;
        let nonblock = rustix::fs::OFlags::NONBLOCK.bits();
        std::fs::OpenOptions::new()
            .read(true)
            .custom_flags(nonblock as i32)
            .open(path)?
    };
    #[cfg(not(unix))]
    let file = File::open(path)?;
    let kind = file.metadata()?.file_type();
    if kind.is_file() {
        Ok(file)
    } else {
        Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("not a regular file but {}", kind_name(kind)),
        ))
    }
}

/// What a file that is not a regular one is, for a message.
fn kind_name(kind: std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if kind.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if kind.is_socket() {
            return "a socket";
        }
        if kind.is_block_device() || kind.is_char_device() {
            return "a device";
        }
    }
    if kind.is_dir() {
        "a folder"
    } else {
        "not a file"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_regular_file_opens_and_reads() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("log.unz");
        std::fs::write(&path, b"bytes").unwrap();
        let mut text = String::new();
        io::Read::read_to_string(&mut open_regular(&path).unwrap(), &mut text).unwrap();
        assert_eq!(text, "bytes");
    }

    #[test]
    fn a_folder_is_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let e = open_regular(tmp.path()).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
        assert!(e.to_string().contains("a folder"), "{e}");
    }

    /// Regression (probe with a FIFO for a raw log): opening it waited for a writer, and
    /// the campaign with it. Now refused at once (the test would hang otherwise).
    #[cfg(unix)]
    #[test]
    fn a_fifo_is_refused_without_waiting_for_a_writer() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("log.unz");
        rustix::fs::mknodat(
            rustix::fs::CWD,
            &path,
            rustix::fs::FileType::Fifo,
            rustix::fs::Mode::RUSR | rustix::fs::Mode::WUSR,
            0,
        )
        .unwrap();
        let e = open_regular(&path).unwrap_err();
        assert!(e.to_string().contains("FIFO"), "{e}");
    }

    #[cfg(unix)]
    #[test]
    fn a_device_is_refused() {
        let e = open_regular(Path::new("/dev/null")).unwrap_err();
        assert!(e.to_string().contains("a device"), "{e}");
    }
}
