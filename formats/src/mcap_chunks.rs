//! MCAP files written a chunk at a time, in the bytes the mcap crate's `Writer` writes with
//! the options [`crate::mcap_io::Ros2Mcap`] gives it: chunks of [`CHUNK_BYTES`] (the crate's
//! default target), uncompressed, lz4 (fast level) or zstd (level 1, no worker threads);
//! message indexes after each chunk; the summary with its schemas, channels, statistics,
//! chunk indexes and offsets; every CRC.
//!
//! Why not the crate's writer: it passes each record field (seven writes a message) through
//! three layers of writers, two CRCs and the compressor, and in a 20-run campaign that path
//! took 12.5 % of the CPU (7.6 % `raw.mcap`'s 264 000 messages a run, 5.2 % the export's
//! `corrected.mcap`). Here a chunk's records are gathered in memory as they come (a message
//! is serialized straight into it), then checksummed, compressed and written at once. The
//! records around the messages are the crate's own types (`mcap::records`), serialized by
//! binrw as the crate serializes them; the tests compare whole files with the crate's, byte
//! for byte.
//!
//! The one place the bytes could part from the crate's: lz4's frame encoder compresses a
//! block from its own buffer when it was given in writes shorter than a block, and from the
//! caller's otherwise, and its output differs between the two. The crate hands it each
//! record field apart, so here a chunk goes to it in pieces shorter than any block
//! (`LZ4_PIECE_BYTES`); the files are the crate's as long as no message is as long as an
//! lz4 block (64 KiB), which none of ours comes near.

use std::collections::BTreeMap;
use std::io::{self, Cursor, Write};

use binrw::{BinWrite, BinWriterExt};
use mcap::records::{self, op};

use crate::mcap_io::McapCompression;

/// A chunk is closed before a message once it holds more than this many bytes of records
/// (uncompressed): the crate's default target.
pub const CHUNK_BYTES: usize = 1 << 20;

/// The pieces a chunk goes to lz4's frame encoder in: shorter than its smallest block
/// (64 KiB), as the crate's per-field writes are (see the module's notes).
const LZ4_PIECE_BYTES: usize = 16 << 10;

/// Bytes of a message record's header (channel, sequence, log and publish times).
const MESSAGE_HEADER_BYTES: u64 = 2 + 4 + 8 + 8;

/// Bytes of a message record before its data: opcode, record length, header.
const MESSAGE_RECORD_HEAD_BYTES: usize = 1 + 8 + MESSAGE_HEADER_BYTES as usize;

/// A schema's content (what the crate tells schemas apart by).
#[derive(Debug, Clone, PartialEq, Eq)]
struct SchemaContent {
    name: String,
    encoding: String,
    data: Vec<u8>,
}

/// A channel's content (what the crate tells channels apart by).
#[derive(Debug, Clone, PartialEq, Eq)]
struct ChannelContent {
    topic: String,
    schema_id: u16,
    message_encoding: String,
    metadata: BTreeMap<String, String>,
}

impl SchemaContent {
    /// Appends its Schema record, with ID `id`, to `out` (`scratch` for its header).
    fn record(&self, id: u16, scratch: &mut Vec<u8>, out: &mut Vec<u8>) -> io::Result<()> {
        let header = records::SchemaHeader {
            id,
            name: self.name.clone(),
            encoding: self.encoding.clone(),
        };
        serialize(scratch, &header)?;
        let data_len = u32::try_from(self.data.len()).map_err(io::Error::other)?;
        out.push(op::SCHEMA);
        out.extend_from_slice(&((scratch.len() + 4 + self.data.len()) as u64).to_le_bytes());
        out.extend_from_slice(scratch);
        out.extend_from_slice(&data_len.to_le_bytes());
        out.extend_from_slice(&self.data);
        Ok(())
    }
}

impl ChannelContent {
    /// Appends its Channel record, with ID `id`, to `out` (`scratch` for its body).
    fn record(&self, id: u16, scratch: &mut Vec<u8>, out: &mut Vec<u8>) -> io::Result<()> {
        let channel = records::Channel {
            id,
            schema_id: self.schema_id,
            topic: self.topic.clone(),
            message_encoding: self.message_encoding.clone(),
            metadata: self.metadata.clone(),
        };
        serialize(scratch, &channel)?;
        out.push(op::CHANNEL);
        out.extend_from_slice(&(scratch.len() as u64).to_le_bytes());
        out.extend_from_slice(scratch);
        Ok(())
    }
}

/// The output's bytes so far: how many, and their CRC-32 (the data section's, then the
/// summary's).
struct Counted<W: Write> {
    inner: W,
    position: u64,
    crc: crc32fast::Hasher,
}

impl<W: Write> Counted<W> {
    fn put(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.inner.write_all(bytes)?;
        self.crc.update(bytes);
        self.position += bytes.len() as u64;
        Ok(())
    }

    /// Puts `bytes` whose CRC-32 is `crc` (known already): the running CRC is combined
    /// with it rather than computed over them again.
    fn put_with_crc(&mut self, bytes: &[u8], crc: u32) -> io::Result<()> {
        self.inner.write_all(bytes)?;
        let len = bytes.len() as u64;
        self.crc
            .combine(&crc32fast::Hasher::new_with_initial_len(crc, len));
        self.position += len;
        Ok(())
    }

    /// A record: its opcode, its length and `body`.
    fn record(&mut self, opcode: u8, body: &[u8]) -> io::Result<()> {
        self.put(&[opcode])?;
        self.put(&(body.len() as u64).to_le_bytes())?;
        self.put(body)
    }

    /// The CRC of the bytes since the last call (or the start), starting a new one.
    fn take_crc(&mut self) -> u32 {
        std::mem::take(&mut self.crc).finalize()
    }
}

/// `value` as binrw serializes it (little-endian), into `buf` (emptied first).
fn serialize<T>(buf: &mut Vec<u8>, value: &T) -> io::Result<()>
where
    T: BinWrite,
    for<'a> T::Args<'a>: Default,
{
    buf.clear();
    Cursor::new(&mut *buf)
        .write_le(value)
        .map_err(io::Error::other)
}

/// A MessageIndex record's body for `entries` of `channel_id`, into `buf` (emptied first),
/// as binrw serializes `records::MessageIndex`: the channel, the entries' length in bytes,
/// each entry's log time and offset (a chunk's index is thousands of entries, which binrw
/// writes a field at a time through a cursor).
fn message_index_body(
    buf: &mut Vec<u8>,
    channel_id: u16,
    entries: &[records::MessageIndexEntry],
) -> io::Result<()> {
    const ENTRY_BYTES: usize = 8 + 8;
    let entry_bytes = u32::try_from(ENTRY_BYTES * entries.len()).map_err(io::Error::other)?;
    buf.clear();
    buf.reserve(2 + 4 + ENTRY_BYTES * entries.len());
    buf.extend_from_slice(&channel_id.to_le_bytes());
    buf.extend_from_slice(&entry_bytes.to_le_bytes());
    for entry in entries {
        let mut bytes = [0u8; ENTRY_BYTES];
        bytes[..8].copy_from_slice(&entry.log_time.to_le_bytes());
        bytes[8..].copy_from_slice(&entry.offset.to_le_bytes());
        buf.extend_from_slice(&bytes);
    }
    Ok(())
}

/// Why a message was not written.
#[derive(Debug)]
pub enum MessageError<E> {
    /// Writing the file (a chunk finished before it), or an unknown channel.
    Io(io::Error),
    /// The message's data.
    Data(E),
}

/// A chunk's compressor, kept across chunks where the crate keeps one.
enum Packer {
    None,
    Lz4,
    /// zstd's context, made at the first chunk and reset for each next one (as the crate
    /// does: a context reset is not a new one, byte for byte).
    Zstd(Option<zstd::stream::raw::Encoder<'static>>),
}

impl Packer {
    fn name(&self) -> &'static str {
        match self {
            Packer::None => "",
            Packer::Lz4 => "lz4",
            Packer::Zstd(_) => "zstd",
        }
    }

    /// The chunk `data` as written: `data` itself when uncompressed (no copy), else
    /// compressed into `out` (emptied first).
    fn pack<'a>(&mut self, data: &'a [u8], out: &'a mut Vec<u8>) -> io::Result<&'a [u8]> {
        out.clear();
        match self {
            Packer::None => return Ok(data),
            Packer::Lz4 => {
                let mut encoder = lz4::EncoderBuilder::new()
                    .level(1)
                    .block_checksum(lz4::liblz4::BlockChecksum::NoBlockChecksum)
                    .build(std::mem::take(out))?;
                for piece in data.chunks(LZ4_PIECE_BYTES) {
                    encoder.write_all(piece)?;
                }
                let (packed, result) = encoder.finish();
                *out = packed;
                result?;
            }
            Packer::Zstd(context) => {
                use zstd::stream::raw::Operation;
                let encoder = match context.take() {
                    Some(mut encoder) => {
                        encoder.reinit()?;
                        encoder
                    }
                    None => {
                        let mut encoder = zstd::stream::raw::Encoder::with_dictionary(1, &[])?;
                        encoder.set_parameter(zstd::stream::raw::CParameter::NbWorkers(0))?;
                        encoder
                    }
                };
                let mut writer = zstd::stream::zio::Writer::new(std::mem::take(out), encoder);
                writer.write_all(data)?;
                writer.finish()?;
                let (packed, encoder) = writer.into_inner();
                *out = packed;
                *context = Some(encoder);
            }
        }
        Ok(out)
    }
}

/// An MCAP file being written (see the module's notes): schemas and channels registered,
/// messages appended, then [`ChunkedMcap::finish`].
pub struct ChunkedMcap<W: Write> {
    out: Counted<W>,
    packer: Packer,
    /// The open chunk's records, uncompressed (empty: no chunk open).
    chunk: Vec<u8>,
    /// The open chunk's first and last message times.
    chunk_bounds: Option<(u64, u64)>,
    /// The open chunk's message index entries, by channel ID.
    chunk_index: Vec<Vec<records::MessageIndexEntry>>,
    chunk_indexes: Vec<records::ChunkIndex>,
    schemas: Vec<SchemaContent>,
    channels: Vec<ChannelContent>,
    /// Messages written, by channel ID.
    message_counts: Vec<u64>,
    message_bounds: Option<(u64, u64)>,
    /// Scratch: a record's serialized body, a chunk compressed.
    scratch: Vec<u8>,
    packed: Vec<u8>,
}

impl<W: Write> ChunkedMcap<W> {
    /// Starts a file on `inner` (its magic and header record), with chunks compressed as
    /// `compression` says, naming `profile` and `library` in its header.
    pub fn new(
        inner: W,
        compression: McapCompression,
        profile: &str,
        library: &str,
    ) -> io::Result<Self> {
        let mut w = Self {
            out: Counted {
                inner,
                position: 0,
                crc: crc32fast::Hasher::new(),
            },
            packer: match compression {
                McapCompression::None => Packer::None,
                McapCompression::Lz4 => Packer::Lz4,
                McapCompression::Zstd => Packer::Zstd(None),
            },
            chunk: Vec::with_capacity(CHUNK_BYTES + (64 << 10)),
            chunk_bounds: None,
            chunk_index: Vec::new(),
            chunk_indexes: Vec::new(),
            schemas: Vec::new(),
            channels: Vec::new(),
            message_counts: Vec::new(),
            message_bounds: None,
            scratch: Vec::new(),
            packed: Vec::new(),
        };
        w.out.put(mcap::MAGIC)?;
        let header = records::Header {
            profile: profile.to_owned(),
            library: library.to_owned(),
        };
        serialize(&mut w.scratch, &header)?;
        w.out.record(op::HEADER, &w.scratch)?;
        Ok(w)
    }

    /// The ID of the schema `name` (`encoding`, `data`), written into the open chunk when
    /// new; one already registered with the same content keeps its ID.
    pub fn add_schema(&mut self, name: &str, encoding: &str, data: &[u8]) -> io::Result<u16> {
        let content = SchemaContent {
            name: name.to_owned(),
            encoding: encoding.to_owned(),
            data: data.to_vec(),
        };
        if let Some(i) = self.schemas.iter().position(|s| *s == content) {
            return Ok(id_of(i));
        }
        let id = new_id(self.schemas.len())?;
        content.record(id, &mut self.scratch, &mut self.chunk)?;
        self.schemas.push(content);
        Ok(id)
    }

    /// The ID of the channel `topic` (of schema `schema_id`, messages in
    /// `message_encoding`), written into the open chunk when new; one already registered
    /// with the same content keeps its ID.
    pub fn add_channel(
        &mut self,
        schema_id: u16,
        topic: &str,
        message_encoding: &str,
        metadata: &BTreeMap<String, String>,
    ) -> io::Result<u16> {
        let content = ChannelContent {
            topic: topic.to_owned(),
            schema_id,
            message_encoding: message_encoding.to_owned(),
            metadata: metadata.clone(),
        };
        if let Some(i) = self.channels.iter().position(|c| *c == content) {
            return Ok(id_of(i));
        }
        if schema_id != 0 && usize::from(schema_id) > self.schemas.len() {
            return Err(io::Error::other(format!(
                "channel {topic}: no schema {schema_id}"
            )));
        }
        let id = new_id(self.channels.len())?;
        content.record(id, &mut self.scratch, &mut self.chunk)?;
        self.channels.push(content);
        self.message_counts.push(0);
        self.chunk_index.push(Vec::new());
        Ok(id)
    }

    /// Appends a message on `channel_id` whose data `data` appends to the buffer it is
    /// given (the open chunk, after the record's header); an error from `data` is
    /// returned with the message left out.
    pub fn message<E>(
        &mut self,
        channel_id: u16,
        sequence: u32,
        log_time: u64,
        publish_time: u64,
        data: impl FnOnce(&mut Vec<u8>) -> Result<(), E>,
    ) -> Result<(), MessageError<E>> {
        let slot = usize::from(channel_id)
            .checked_sub(1)
            .filter(|&slot| slot < self.channels.len())
            .ok_or_else(|| {
                MessageError::Io(io::Error::other(format!(
                    "message on unknown channel {channel_id}"
                )))
            })?;
        if self.chunk.len() > CHUNK_BYTES {
            self.finish_chunk().map_err(MessageError::Io)?;
        }
        let start = self.chunk.len();
        // The record's opcode, its length (set below, once the data is in) and header,
        // appended at once.
        let mut head = [0u8; MESSAGE_RECORD_HEAD_BYTES];
        head[0] = op::MESSAGE;
        head[9..11].copy_from_slice(&channel_id.to_le_bytes());
        head[11..15].copy_from_slice(&sequence.to_le_bytes());
        head[15..23].copy_from_slice(&log_time.to_le_bytes());
        head[23..31].copy_from_slice(&publish_time.to_le_bytes());
        self.chunk.extend_from_slice(&head);
        let data_start = self.chunk.len();
        if let Err(e) = data(&mut self.chunk) {
            self.chunk.truncate(start);
            return Err(MessageError::Data(e));
        }
        let len = MESSAGE_HEADER_BYTES + (self.chunk.len() - data_start) as u64;
        self.chunk[start + 1..start + 9].copy_from_slice(&len.to_le_bytes());
        self.message_counts[slot] += 1;
        widen(&mut self.message_bounds, log_time);
        widen(&mut self.chunk_bounds, log_time);
        self.chunk_index[slot].push(records::MessageIndexEntry {
            log_time,
            offset: start as u64,
        });
        Ok(())
    }

    /// Writes the open chunk (if any) and its message indexes.
    fn finish_chunk(&mut self) -> io::Result<()> {
        if self.chunk.is_empty() {
            return Ok(());
        }
        let chunk_start_offset = self.out.position;
        let uncompressed_crc = crc32fast::hash(&self.chunk);
        // An uncompressed chunk is its records as they are: written from the open chunk,
        // its CRC (the records') combined into the data section's, not computed again (a
        // 40-minute run's `raw.mcap` is 22.5 MB: a copy and a CRC pass less).
        let uncompressed = matches!(self.packer, Packer::None);
        let packed = self.packer.pack(&self.chunk, &mut self.packed)?;
        let (message_start_time, message_end_time) = self.chunk_bounds.take().unwrap_or((0, 0));
        let header = records::ChunkHeader {
            message_start_time,
            message_end_time,
            uncompressed_size: self.chunk.len() as u64,
            uncompressed_crc,
            compression: self.packer.name().to_owned(),
            compressed_size: packed.len() as u64,
        };
        serialize(&mut self.scratch, &header)?;
        self.out.put(&[op::CHUNK])?;
        let record_bytes = (self.scratch.len() + packed.len()) as u64;
        self.out.put(&record_bytes.to_le_bytes())?;
        self.out.put(&self.scratch)?;
        if uncompressed {
            self.out.put_with_crc(packed, uncompressed_crc)?;
        } else {
            self.out.put(packed)?;
        }
        let data_end = self.out.position;
        let mut message_index_offsets = BTreeMap::new();
        for (slot, entries) in self.chunk_index.iter_mut().enumerate() {
            if entries.is_empty() {
                continue;
            }
            let channel_id = id_of(slot);
            message_index_offsets.insert(channel_id, self.out.position);
            message_index_body(&mut self.scratch, channel_id, entries)?;
            self.out.record(op::MESSAGE_INDEX, &self.scratch)?;
            // The entries' room kept for the next chunk.
            entries.clear();
        }
        self.chunk_indexes.push(records::ChunkIndex {
            message_start_time,
            message_end_time,
            chunk_start_offset,
            chunk_length: data_end - chunk_start_offset,
            message_index_offsets,
            message_index_length: self.out.position - data_end,
            compression: header.compression,
            compressed_size: header.compressed_size,
            uncompressed_size: header.uncompressed_size,
        });
        self.chunk.clear();
        Ok(())
    }

    /// Writes the last chunk, the data section's end and the summary, and returns the
    /// output.
    pub fn finish(mut self) -> io::Result<W> {
        self.finish_chunk()?;
        let data_section_crc = self.out.take_crc();
        serialize(&mut self.scratch, &records::DataEnd { data_section_crc })?;
        self.out.record(op::DATA_END, &self.scratch)?;
        self.out.take_crc();
        let summary_start = self.out.position;
        let mut offsets = Vec::new();
        let mut group = |out: &mut Counted<W>, group_opcode: u8, group_start: u64| {
            offsets.push(records::SummaryOffset {
                group_opcode,
                group_start,
                group_length: out.position - group_start,
            });
        };
        // The schemas, then the channels, again (their records as in the first chunk).
        let mut record = Vec::new();
        if !self.schemas.is_empty() {
            let start = self.out.position;
            for (i, schema) in self.schemas.iter().enumerate() {
                record.clear();
                schema.record(id_of(i), &mut self.scratch, &mut record)?;
                self.out.put(&record)?;
            }
            group(&mut self.out, op::SCHEMA, start);
        }
        if !self.channels.is_empty() {
            let start = self.out.position;
            for (i, channel) in self.channels.iter().enumerate() {
                record.clear();
                channel.record(id_of(i), &mut self.scratch, &mut record)?;
                self.out.put(&record)?;
            }
            group(&mut self.out, op::CHANNEL, start);
        }
        let (message_start_time, message_end_time) = self.message_bounds.unwrap_or((0, 0));
        let channel_message_counts: BTreeMap<u16, u64> = self
            .message_counts
            .iter()
            .enumerate()
            .filter(|&(_, &n)| n > 0)
            .map(|(i, &n)| (id_of(i), n))
            .collect();
        let statistics = records::Statistics {
            message_count: self.message_counts.iter().sum(),
            schema_count: self.schemas.len() as u16,
            channel_count: self.channels.len() as u32,
            attachment_count: 0,
            metadata_count: 0,
            chunk_count: self.chunk_indexes.len() as u32,
            message_start_time,
            message_end_time,
            channel_message_counts,
        };
        let start = self.out.position;
        serialize(&mut self.scratch, &statistics)?;
        self.out.record(op::STATISTICS, &self.scratch)?;
        group(&mut self.out, op::STATISTICS, start);
        if !self.chunk_indexes.is_empty() {
            let start = self.out.position;
            for index in &self.chunk_indexes {
                serialize(&mut self.scratch, index)?;
                self.out.record(op::CHUNK_INDEX, &self.scratch)?;
            }
            group(&mut self.out, op::CHUNK_INDEX, start);
        }
        let summary_end = self.out.position;
        let summary_offset_start = summary_end;
        for offset in &offsets {
            serialize(&mut self.scratch, offset)?;
            self.out.record(op::SUMMARY_OFFSET, &self.scratch)?;
        }
        let summary_start = if summary_end > summary_start {
            summary_start
        } else {
            0
        };
        // The summary's CRC takes in the footer up to the CRC itself.
        self.out.put(&[op::FOOTER])?;
        self.out.put(&20u64.to_le_bytes())?;
        self.out.put(&summary_start.to_le_bytes())?;
        self.out.put(&summary_offset_start.to_le_bytes())?;
        let summary_crc = self.out.take_crc();
        self.out.put(&summary_crc.to_le_bytes())?;
        self.out.put(mcap::MAGIC)?;
        self.out.inner.flush()?;
        Ok(self.out.inner)
    }
}

/// The ID of the `i`th schema or channel registered (IDs start at 1).
fn id_of(i: usize) -> u16 {
    // `new_id` refused any index whose ID would not fit.
    (i + 1) as u16
}

/// The ID for the next schema or channel when `registered` are.
fn new_id(registered: usize) -> io::Result<u16> {
    u16::try_from(registered + 1).map_err(|_| io::Error::other("too many schemas or channels"))
}

/// `bounds` widened to take in `t`.
fn widen(bounds: &mut Option<(u64, u64)>, t: u64) {
    *bounds = Some(match *bounds {
        None => (t, t),
        Some((lo, hi)) => (lo.min(t), hi.max(t)),
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// One message of a test stream: channel (index into the channels), log time, data.
    type Msg = (usize, u64, Vec<u8>);

    const TOPICS: [(&str, &str); 3] = [("/imu", "a"), ("/odometer", "b"), ("/marks", "a")];

    /// The IDs of [`TOPICS`]' channels, each registered with its schema by `add` (schema
    /// name and data, topic → channel ID).
    fn register(mut add: impl FnMut(&str, &str) -> u16) -> Vec<u16> {
        TOPICS
            .iter()
            .map(|&(topic, schema)| add(schema, topic))
            .collect()
    }

    /// The file the mcap crate's writer makes of `msgs`, with Ros2Mcap's options.
    fn crate_file(compression: McapCompression, msgs: &[Msg]) -> Vec<u8> {
        let mut w = mcap::WriteOptions::new()
            .compression(match compression {
                McapCompression::None => None,
                McapCompression::Zstd => Some(mcap::Compression::Zstd),
                McapCompression::Lz4 => Some(mcap::Compression::Lz4),
            })
            .compression_level(1)
            .compression_threads(0)
            .profile("ros2")
            .library("unz test")
            .create(Cursor::new(Vec::new()))
            .unwrap();
        let ids = register(|schema, topic| {
            let s = w.add_schema(schema, "ros2msg", schema.as_bytes()).unwrap();
            w.add_channel(s, topic, "cdr", &BTreeMap::new()).unwrap()
        });
        let mut seq = [0u32; 3];
        for (c, t, data) in msgs {
            let header = records::MessageHeader {
                channel_id: ids[*c],
                sequence: seq[*c],
                log_time: *t,
                publish_time: *t,
            };
            seq[*c] += 1;
            w.write_to_known_channel(&header, data).unwrap();
        }
        w.finish().unwrap();
        w.into_inner().into_inner()
    }

    /// [`register`] on our writer.
    fn register_ours(w: &mut ChunkedMcap<Vec<u8>>) -> Vec<u16> {
        register(|schema, topic| {
            let s = w.add_schema(schema, "ros2msg", schema.as_bytes()).unwrap();
            w.add_channel(s, topic, "cdr", &BTreeMap::new()).unwrap()
        })
    }

    /// The file [`ChunkedMcap`] makes of `msgs`.
    fn our_file(compression: McapCompression, msgs: &[Msg]) -> Vec<u8> {
        let mut w = ChunkedMcap::new(Vec::new(), compression, "ros2", "unz test").unwrap();
        let ids = register_ours(&mut w);
        let mut seq = [0u32; 3];
        for (c, t, data) in msgs {
            w.message(ids[*c], seq[*c], *t, *t, |buf| {
                buf.extend_from_slice(data);
                Ok::<(), ()>(())
            })
            .unwrap();
            seq[*c] += 1;
        }
        w.finish().unwrap()
    }

    /// `n` messages like a run's: mostly on the first channel at 10 ms, with jitter and
    /// times that go back now and then, of 20–90 bytes of compressible data.
    fn stream(seed: u64, n: usize) -> Vec<Msg> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut t = 1_700_000_000_000_000_000u64;
        (0..n)
            .map(|k| {
                t = if rng.random_bool(0.001) {
                    t - 5_000_000
                } else {
                    t + 10_000_000 + rng.random_range(0..1000)
                };
                let c = match rng.random_range(0..100) {
                    0..90 => 0,
                    90..99 => 1,
                    _ => 2,
                };
                let len = rng.random_range(20..90);
                let data = (0..len)
                    .map(|i| {
                        if i % 3 == 0 {
                            rng.random()
                        } else {
                            (k + i) as u8
                        }
                    })
                    .collect();
                (c, t, data)
            })
            .collect()
    }

    #[test]
    fn files_are_the_crates_byte_for_byte() {
        for compression in [
            McapCompression::None,
            McapCompression::Lz4,
            McapCompression::Zstd,
        ] {
            // Nothing, one message, less than a chunk, and several chunks (each closed
            // before the message that finds it over the target).
            for (seed, n) in [(1, 0), (2, 1), (3, 500), (4, 60_000)] {
                let msgs = stream(seed, n);
                let ours = our_file(compression, &msgs);
                let theirs = crate_file(compression, &msgs);
                assert!(
                    ours == theirs,
                    "{compression:?}, {n} messages: {} bytes against the crate's {}",
                    ours.len(),
                    theirs.len()
                );
            }
        }
    }

    /// A message index's body written at once is binrw's serialization of the crate's
    /// record, for no entry, one and many.
    #[test]
    fn message_indexes_are_the_crates_records() {
        for n in [0u64, 1, 5000] {
            let entries: Vec<records::MessageIndexEntry> = (0..n)
                .map(|k| records::MessageIndexEntry {
                    log_time: k * 10_000_000 + (k % 7),
                    offset: u64::MAX - 31 * k,
                })
                .collect();
            let mut ours = vec![9; 3];
            message_index_body(&mut ours, 0x0203, &entries).unwrap();
            let mut theirs = Vec::new();
            let index = records::MessageIndex {
                channel_id: 0x0203,
                records: entries,
            };
            serialize(&mut theirs, &index).unwrap();
            assert_eq!(ours, theirs, "{n} entries");
        }
    }

    #[test]
    fn a_chunk_closes_once_over_its_target() {
        // The first chunk's records (its schemas and channels, then the messages) filling
        // it exactly to its target, then one byte over: the next message opens a new
        // chunk only in the second case, as in the crate's files.
        let mut w = ChunkedMcap::new(Vec::new(), McapCompression::None, "", "").unwrap();
        register_ours(&mut w);
        let registry = w.chunk.len();
        let record = |data: usize| 9 + MESSAGE_HEADER_BYTES as usize + data;
        let rest = 1000 - record(0);
        let first = CHUNK_BYTES - registry - 999 * 1000 - record(0);
        for (extra, chunks) in [(0usize, 1u32), (1, 2)] {
            let mut msgs: Vec<Msg> = vec![(0, 0, vec![1; first + extra])];
            msgs.extend((1..1001).map(|k| (1, k as u64, vec![k as u8; rest])));
            for compression in [McapCompression::None, McapCompression::Lz4] {
                let ours = our_file(compression, &msgs);
                assert!(ours == crate_file(compression, &msgs));
                let stats = mcap::Summary::read(&ours).unwrap().unwrap().stats.unwrap();
                assert_eq!(stats.chunk_count, chunks, "{extra} byte(s) over");
            }
        }
    }

    #[test]
    fn schemas_and_channels_of_the_same_content_keep_their_ids() {
        let mut w = ChunkedMcap::new(Vec::new(), McapCompression::None, "", "").unwrap();
        let a = w.add_schema("a", "ros2msg", b"x").unwrap();
        assert_eq!(w.add_schema("a", "ros2msg", b"x").unwrap(), a);
        let b = w.add_schema("a", "ros2msg", b"y").unwrap();
        assert_eq!((a, b), (1, 2));
        let c = w.add_channel(a, "/t", "cdr", &BTreeMap::new()).unwrap();
        assert_eq!(w.add_channel(a, "/t", "cdr", &BTreeMap::new()).unwrap(), c);
        assert_eq!(w.add_channel(b, "/t", "cdr", &BTreeMap::new()).unwrap(), 2);
        assert!(w.add_channel(9, "/u", "cdr", &BTreeMap::new()).is_err());
        for unknown in [0, 3] {
            match w.message(unknown, 0, 0, 0, |_| Ok::<(), ()>(())) {
                Err(MessageError::Io(e)) => {
                    assert!(
                        e.to_string()
                            .contains(&format!("unknown channel {unknown}"))
                    )
                }
                other => panic!("{other:?}"),
            }
        }
        // A message whose data fails is left out: the file holds no trace of it.
        let failed = w.message(c, 0, 5, 5, |buf| {
            buf.extend_from_slice(b"half");
            Err("no")
        });
        assert!(matches!(failed, Err(MessageError::Data("no"))));
        let bytes = w.finish().unwrap();
        let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
        assert_eq!(summary.stats.unwrap().message_count, 0);
    }
}
