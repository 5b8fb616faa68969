//! MCAP output with ROS 2 messages (CDR-encoded, described by `ros2msg` schemas, see
//! [`crate::ros2_msgs`]): binary, compact, and decoded by Foxglove and Rerun's MCAP
//! importer without set-up. Written atomically like every other output.

use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::Path;

use crate::atomic::AtomicFile;
use crate::error::{FileError, FormatError};
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
/// The mcap crate feeds its compressor one small write per record field, about seven per
/// message. zstd's stream takes each as a call of its own: with ~240 000 messages per
/// 40-min run it costs more than the rest of the ingest (uncompressed chunks ingest at
/// ~165 MB/s of raw log, zstd ones at ~110 MB/s, about half the size; rosbag2 records
/// uncompressed by default for the same reason). lz4's frame encoder gathers the small
/// writes into its block before compressing: the export's `corrected.mcap` (96 000
/// messages a 40-min run) takes 11 ms less CPU than with zstd, 20 % larger.
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

/// An MCAP file of ROS 2 channels being written.
pub struct Ros2Mcap {
    writer: mcap::Writer<BufWriter<std::fs::File>>,
    file: AtomicFile,
    message: Vec<u8>,
}

fn mcap_err(path: &Path, e: impl Into<FormatError>) -> FileError {
    e.into().in_file(path)
}

impl Ros2Mcap {
    /// Starts an MCAP file at `dest` with chunks compressed as `compression` says.
    pub fn create(dest: &Path, compression: McapCompression) -> Result<Self, FileError> {
        let file = AtomicFile::create(dest)?;
        let handle = BufWriter::with_capacity(1 << 20, file.file_handle()?);
        let writer = mcap::WriteOptions::new()
            .compression(match compression {
                McapCompression::None => None,
                McapCompression::Zstd => Some(mcap::Compression::Zstd),
                McapCompression::Lz4 => Some(mcap::Compression::Lz4),
            })
            .compression_level(1)
            .compression_threads(0)
            .profile("ros2")
            .library(concat!("unz ", env!("CARGO_PKG_VERSION")))
            .create(handle)
            .map_err(|e| mcap_err(dest, e))?;
        Ok(Self {
            writer,
            file,
            message: Vec::with_capacity(512),
        })
    }

    /// Registers a channel of `M` messages on `topic`.
    pub fn add_channel<M: Ros2Message>(&mut self, topic: &str) -> Result<Channel<M>, FileError> {
        let dest = self.file.dest().to_path_buf();
        let schema_id = self
            .writer
            .add_schema(M::NAME, "ros2msg", M::DEFINITION.as_bytes())
            .map_err(|e| mcap_err(&dest, e))?;
        let id = self
            .writer
            .add_channel(schema_id, topic, "cdr", &BTreeMap::new())
            .map_err(|e| mcap_err(&dest, e))?;
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
        self.message.clear();
        self.message.extend_from_slice(&CDR_LE);
        // CDR aligns from the end of the encapsulation header: the serializer counts from
        // the buffer's length when it starts.
        let mut ser = re_cdr::CdrSerializer::<re_cdr::LittleEndian>::new(&mut self.message);
        message
            .serialize(&mut ser)
            .map_err(|e| mcap_err(self.file.dest(), e))?;
        let header = mcap::records::MessageHeader {
            channel_id: channel.id,
            sequence: channel.sequence,
            log_time: log_time_ns,
            publish_time: log_time_ns,
        };
        channel.sequence = channel.sequence.wrapping_add(1);
        self.writer
            .write_to_known_channel(&header, &self.message)
            .map_err(|e| mcap_err(self.file.dest(), e))
    }

    /// Writes the summary, flushes and renames the file into place.
    pub fn finish(mut self) -> Result<(), FileError> {
        let dest = self.file.dest().to_path_buf();
        self.writer.finish().map_err(|e| mcap_err(&dest, e))?;
        let mut inner = self.writer.into_inner();
        std::io::Write::flush(&mut inner).map_err(|e| crate::error::io_in_file(&dest, e))?;
        drop(inner);
        self.file.commit()
    }
}
