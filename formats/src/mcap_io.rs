//! MCAP output with ROS 2 messages (CDR-encoded, described by `ros2msg` schemas, see
//! [`crate::ros2_msgs`]): binary, compact, and decoded by Foxglove and Rerun's MCAP
//! importer without set-up. Written atomically like every other output.

use std::collections::BTreeMap;
use std::path::Path;

use crate::atomic::{AtomicFile, HashedFileWriter};
use crate::error::{FileError, FormatError, write_error_in_file};
use crate::mcap_chunks::{ChunkedMcap, MessageError};
use crate::ros2_msgs::Ros2Message;

/// CDR encapsulation header: plain CDR, little-endian.
const CDR_LE: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// Channel handle returned by [`Ros2Mcap::add_channel`], typed by its message.
#[derive(Debug)]
pub struct Channel<M> {
    id: u16,
    sequence: u32,
    _message: std::marker::PhantomData<fn(&M)>,
}

/// How an MCAP file's chunks are compressed.
///
/// A chunk is compressed in one go when it is full ([`crate::mcap_chunks`]), so the choice
/// costs the compressor's own time only. `unz bench ingest` (a 40-min run): the full ingest
/// at 195 MB/s of raw log with uncompressed chunks and 181 MB/s with zstd ones, half the
/// size (with the mcap crate's writer, which fed zstd each record field apart, 101–105
/// MB/s).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum McapCompression {
    /// Uncompressed chunks: fastest to write and to open.
    #[default]
    None,
    /// zstd (level 1) chunks: about half the size.
    Zstd,
    /// lz4 (fast level) chunks: a 40-min run's `raw.mcap` 14.9 MB against 12.0 with
    /// zstd and 22.5 uncompressed, its ingest's CPU between the two.
    Lz4,
}

/// An MCAP file of ROS 2 channels being written (by [`ChunkedMcap`]: the mcap crate's
/// writer's bytes, a chunk at a time).
pub struct Ros2Mcap {
    writer: ChunkedMcap<HashedFileWriter>,
    file: AtomicFile,
}

impl Ros2Mcap {
    /// Starts an MCAP file at `dest` with chunks compressed as `compression` says.
    pub fn create(dest: &Path, compression: McapCompression) -> Result<Self, FileError> {
        let file = AtomicFile::create(dest)?;
        let handle = file.hashed_writer(1 << 20)?;
        let writer = ChunkedMcap::new(
            handle,
            compression,
            "ros2",
            concat!("unz ", env!("CARGO_PKG_VERSION")),
        )
        .map_err(|e| write_error_in_file(dest, e))?;
        Ok(Self { writer, file })
    }

    /// Registers a channel of `M` messages on `topic`.
    pub fn add_channel<M: Ros2Message>(&mut self, topic: &str) -> Result<Channel<M>, FileError> {
        let dest = self.file.dest();
        let schema_id = self
            .writer
            .add_schema(M::NAME, "ros2msg", M::DEFINITION.as_bytes())
            .map_err(|e| write_error_in_file(dest, e))?;
        let id = self
            .writer
            .add_channel(schema_id, topic, "cdr", &BTreeMap::new())
            .map_err(|e| write_error_in_file(dest, e))?;
        Ok(Channel {
            id,
            sequence: 0,
            _message: std::marker::PhantomData,
        })
    }

    /// Writes `message` on `channel` at `log_time_ns`.
    pub fn write<M: Ros2Message>(
        &mut self,
        channel: &mut Channel<M>,
        log_time_ns: u64,
        message: &M,
    ) -> Result<(), FileError> {
        let dest = self.file.dest();
        self.writer
            .message(
                channel.id,
                channel.sequence,
                log_time_ns,
                log_time_ns,
                |buf| -> Result<(), FileError> {
                    buf.extend_from_slice(&CDR_LE);
                    // CDR aligns from the end of the encapsulation header: the body is
                    // aligned from the buffer's length when it starts.
                    message
                        .write_cdr(buf)
                        .map_err(|e| FormatError::from(e).in_file(dest))
                },
            )
            .map_err(|e| match e {
                MessageError::Io(e) => write_error_in_file(dest, e),
                MessageError::Data(e) => e,
            })?;
        channel.sequence = channel.sequence.wrapping_add(1);
        Ok(())
    }

    /// Writes the summary, flushes and renames the file into place, its blake3 hashed as
    /// its bytes were written (front to back: [`crate::hashing_writer::HashingWriter`])
    /// told to the listener ([`crate::hashing_writer::listen_to_written`]).
    pub fn finish(self) -> Result<(), FileError> {
        let dest = self.file.dest();
        let buffered = self
            .writer
            .finish()
            .map_err(|e| write_error_in_file(dest, e))?;
        self.file.commit_written(buffered)
    }
}
