//! A Rerun log sink that encodes the recording into its file as it is logged: no copy
//! of the recording is held in memory (a 12-hour run's is about 180 MB encoded, more as
//! the SDK's messages), and the operating system's own errors reach the caller.
//!
//! The same review gives the same bytes. The SDK alone would not:
//! - it names every message, chunk and row with a time-based id (a TUID: the clock's
//!   nanoseconds and a counter). The sink renames them in the order they come, each a
//!   fixed "time" drawn from the recording's id and a counter, so two recordings' ids
//!   still differ. Rows keep their order within a chunk, chunks the order they came in.
//! - it sends a blueprint's messages on another path than the recording's chunks, so the
//!   two interleave differently each time: the blueprint's (a few dozen small messages)
//!   are held and written after the recording's, when the file is finished;
//! - its footer (an index of each store's chunks, which `rerun rrd verify` requires) lists
//!   the stores, and each store's schema its columns, in hash maps' orders: the sink
//!   rewrites it with the stores in the order of their ids and the columns in the order of
//!   their names, and the frames around it to match.
//!
//! The streams are built with the batching [`IN_LOGGED_ORDER`] and
//! [`without_wall_clock`] timelines.

use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::path::Path;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use re_protos::common::v1alpha1::Schema as SchemaProto;
use re_protos::external::prost::Message;
use re_protos::log_msg::v1alpha1::RrdFooter as FooterProto;
use rerun::external::arrow::datatypes::{FieldRef, Schema};
use rerun::external::arrow::error::ArrowError;
use rerun::external::arrow::ipc::reader::StreamReader;
use rerun::external::re_log_encoding::{
    CodecError, CrateVersion, Decodable, Encodable, EncodeError, Encoder, EncodingOptions,
    MessageHeader, MessageKind, StreamFooter,
};
use rerun::external::re_tuid::Tuid;
use rerun::log::{Chunk, ChunkBatcherConfig, ChunkId, LogMsg, RowId};
use rerun::sink::{LogSink, SinkFlushError};
use rerun::{RecordingStream, StoreKind};

type FileEncoder = Encoder<BufWriter<File>>;

/// The batching of a stream whose messages come in the order they were logged: each row
/// logged is sent on as a chunk of its own at once. The SDK's default holds rows per
/// entity and sends them on a timer, or on a flush in its hash map's order, so the same
/// recording came in another order, in other chunks, each time. Set explicitly, it also
/// overrides the `RERUN_FLUSH_*` environment variables. Our recordings log few rows one by
/// one (texts, static layouts); their series go as whole columns, which it leaves alone.
pub(crate) const IN_LOGGED_ORDER: ChunkBatcherConfig = ChunkBatcherConfig {
    flush_num_rows: 1,
    ..ChunkBatcherConfig::DEFAULT
};

/// Turns `rec`'s wall-clock timelines (`log_time`, `log_tick`) off, whatever
/// `RERUN_LOG_TIME` and `RERUN_LOG_TICK` say: the same review gives the same recording.
pub(crate) fn without_wall_clock(rec: &RecordingStream) {
    rec.set_log_time_enabled(false);
    rec.set_log_tick_enabled(false);
}

/// The encoder, the first error it met, the ids handed out so far, and the blueprint's
/// messages held until the file is finished.
struct State {
    encoder: Option<FileEncoder>,
    error: Option<EncodeError>,
    ids: StableIds,
    blueprint: Vec<LogMsg>,
}

impl State {
    /// Encodes `msg` with its ids renamed; the first error is kept, and anything after it
    /// is dropped.
    fn append(&mut self, msg: LogMsg) {
        if self.error.is_some() {
            return;
        }
        let Self { encoder, ids, .. } = self;
        let result = ids.rename(msg).and_then(|msg| match encoder.as_mut() {
            Some(encoder) => encoder.append(&msg).map(|_| ()),
            None => Err(EncodeError::AlreadyFinished),
        });
        if let Err(e) = result {
            self.error = Some(e);
        }
    }
}

/// Whether `msg` belongs to a blueprint (its store's, or the command activating it).
fn is_blueprint(msg: &LogMsg) -> bool {
    match msg {
        LogMsg::BlueprintActivationCommand(_) => true,
        other => other.store_id().kind() == StoreKind::Blueprint,
    }
}

/// Time-based ids made stable: a fixed "time" and a counter.
struct StableIds {
    time_nanos: u64,
    next: u64,
}

impl StableIds {
    /// Ids for the recording `recording_id`: its "time" is drawn from the id (below 2^62
    /// ns, so that no counter wraps it), the counter starts at 1.
    fn for_recording(recording_id: &str) -> Self {
        let h = blake3::hash(format!("unz-review-ids/{recording_id}").as_bytes());
        let mut first = [0u8; 8];
        first.copy_from_slice(&h.as_bytes()[..8]);
        Self {
            time_nanos: u64::from_le_bytes(first) >> 2,
            next: 1,
        }
    }

    /// The first of the next `n` ids.
    fn take(&mut self, n: usize) -> Tuid {
        let first = Tuid::from_nanos_and_inc(self.time_nanos, self.next);
        self.next += n as u64;
        first
    }

    /// `msg` with its ids replaced by the next ones: the store's info, or the chunk and
    /// its rows (in the order the rows had).
    fn rename(&mut self, msg: LogMsg) -> Result<LogMsg, EncodeError> {
        Ok(match msg {
            LogMsg::SetStoreInfo(mut info) => {
                info.row_id = self.take(1);
                LogMsg::SetStoreInfo(info)
            }
            LogMsg::ArrowMsg(store_id, arrow) => {
                let chunk = Chunk::from_arrow_msg(&arrow).map_err(chunk_error)?;
                let rows = chunk.row_ids_slice();
                if !rows.is_sorted() {
                    // The SDK hands rows out in order; a chunk that is not in order is left
                    // as it came rather than reordered.
                    return Ok(LogMsg::ArrowMsg(store_id, arrow));
                }
                let id = ChunkId::from_tuid(self.take(1));
                let first_row = RowId::from_tuid(self.take(rows.len()));
                let renamed = chunk.clone_as(id, first_row);
                LogMsg::ArrowMsg(store_id, renamed.to_arrow_msg().map_err(chunk_error)?)
            }
            other @ LogMsg::BlueprintActivationCommand(_) => other,
        })
    }
}

fn chunk_error(e: rerun::log::ChunkError) -> EncodeError {
    EncodeError::Chunk(Box::new(e))
}

fn lock(state: &Mutex<State>) -> MutexGuard<'_, State> {
    state.lock().unwrap_or_else(|e| e.into_inner())
}

/// The sink a recording stream sends its messages to.
pub(crate) struct RrdFileSink {
    state: Arc<Mutex<State>>,
}

/// What finishes the file once the stream is done with the sink.
pub(crate) struct RrdFile {
    state: Arc<Mutex<State>>,
}

/// Starts an RRD stream into `path` (created) for the recording `recording_id`: the sink
/// to set on a recording stream, and the handle that finishes the file.
pub(crate) fn create(
    path: &Path,
    recording_id: &str,
) -> Result<(RrdFileSink, RrdFile), EncodeError> {
    // Read too: the footer is read back to be put in order.
    let file = OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(true)
        .open(path)?;
    let file = BufWriter::with_capacity(1 << 20, file);
    // What the SDK's memory and file sinks write: this version, compressed protobuf.
    let encoder = Encoder::new_eager(
        CrateVersion::LOCAL,
        EncodingOptions::PROTOBUF_COMPRESSED,
        file,
    )?;
    let state = Arc::new(Mutex::new(State {
        encoder: Some(encoder),
        error: None,
        ids: StableIds::for_recording(recording_id),
        blueprint: Vec::new(),
    }));
    Ok((
        RrdFileSink {
            state: state.clone(),
        },
        RrdFile { state },
    ))
}

impl LogSink for RrdFileSink {
    fn send(&self, msg: LogMsg) {
        let mut s = lock(&self.state);
        if is_blueprint(&msg) {
            s.blueprint.push(msg);
        } else {
            s.append(msg);
        }
    }

    fn flush_blocking(&self, _timeout: Duration) -> Result<(), SinkFlushError> {
        // Messages are encoded as they come; the file is flushed by `RrdFile::finish`.
        Ok(())
    }
}

impl RrdFile {
    /// Writes the blueprint's messages, the stream's footer in order, and flushes the file
    /// (call once the recording stream has been flushed and dropped); the first error of
    /// the whole stream, if any.
    pub(crate) fn finish(self) -> Result<(), EncodeError> {
        let mut s = lock(&self.state);
        for msg in std::mem::take(&mut s.blueprint) {
            s.append(msg);
        }
        if let Some(e) = s.error.take() {
            s.encoder = None;
            return Err(e);
        }
        let Some(mut encoder) = s.encoder.take() else {
            return Err(EncodeError::AlreadyUnwrapped);
        };
        encoder.finish()?;
        let file = encoder.into_inner()?;
        // Flushed, not synced: like every other output, the file is made whole by the
        // rename that follows, not made durable.
        let mut file = file.into_inner().map_err(|e| e.into_error())?;
        footer_in_order(&mut file)
    }
}

/// Rewrites the RRD footer at the end of `file` in a fixed order: its stores in the
/// order of their ids, and each store's schema with its columns in the order of their
/// names (the encoder builds both from hash maps; the schema's checksum in the footer is
/// already taken over the columns sorted by name). The footer's message header and the
/// stream footer's span and checksum follow.
fn footer_in_order(file: &mut File) -> Result<(), EncodeError> {
    let size = StreamFooter::ENCODED_SIZE_BYTES as u64;
    let header_size = MessageHeader::ENCODED_SIZE_BYTES as u64;
    let end = file.seek(SeekFrom::End(0))?;
    if end < size {
        return Err(footer_error("the file is shorter than its stream footer"));
    }
    let mut tail = [0u8; StreamFooter::ENCODED_SIZE_BYTES];
    file.seek(SeekFrom::Start(end - size))?;
    file.read_exact(&mut tail)?;
    let stream_footer = StreamFooter::from_rrd_bytes(&tail)?;
    let [entry] = stream_footer.entries.as_slice() else {
        return Err(footer_error(
            "a stream footer that points at several footers",
        ));
    };
    let span = entry.rrd_footer_byte_span_from_start_excluding_header;
    if span.start < header_size || span.start.checked_add(span.len) != Some(end - size) {
        return Err(footer_error(
            "a footer that does not end where the stream footer starts",
        ));
    }
    let mut header = [0u8; MessageHeader::ENCODED_SIZE_BYTES];
    file.seek(SeekFrom::Start(span.start - header_size))?;
    file.read_exact(&mut header)?;
    let header = MessageHeader::from_rrd_bytes(&header)?;
    if header.kind != MessageKind::End || header.len != span.len {
        return Err(footer_error("no end-of-stream message before the footer"));
    }
    let len = usize::try_from(span.len).map_err(|_| footer_error("a footer too large"))?;
    let mut bytes = vec![0u8; len];
    file.seek(SeekFrom::Start(span.start))?;
    file.read_exact(&mut bytes)?;
    let mut footer = FooterProto::decode(bytes.as_slice())
        .map_err(|e| footer_error(&format!("the footer does not decode: {e}")))?;
    for manifest in &mut footer.manifests {
        if let Some(schema) = manifest.sorbet_schema.as_mut() {
            *schema = columns_by_name(schema)?;
        }
    }
    footer.manifests.sort_by_key(|m| {
        m.store_id
            .as_ref()
            .map(|id| (id.kind, id.recording_id.clone()))
    });
    let ordered = footer.encode_to_vec();
    if ordered == bytes {
        return Ok(());
    }
    let mut frame = Vec::with_capacity(ordered.len() + (header_size + size) as usize);
    MessageHeader {
        kind: MessageKind::End,
        len: ordered.len() as u64,
    }
    .to_rrd_bytes(&mut frame)?;
    frame.extend_from_slice(&ordered);
    StreamFooter::from_rrd_footer_bytes(span.start, &ordered).to_rrd_bytes(&mut frame)?;
    file.seek(SeekFrom::Start(span.start - header_size))?;
    file.write_all(&frame)?;
    file.set_len(span.start - header_size + frame.len() as u64)?;
    Ok(())
}

/// A footer's schema (Arrow IPC, as rerun writes it) with its columns in the order of
/// their names, written back as rerun writes it (`Schema::try_from`); read as it is, not
/// migrated.
fn columns_by_name(schema: &SchemaProto) -> Result<SchemaProto, EncodeError> {
    let arrow_error = |e: ArrowError| footer_error(&format!("the footer's schema: {e}"));
    let Some(ipc) = schema.arrow_schema.as_ref() else {
        return Ok(schema.clone());
    };
    let read = StreamReader::try_new(std::io::Cursor::new(ipc), None)
        .map_err(arrow_error)?
        .schema();
    let mut fields: Vec<FieldRef> = read.fields().iter().cloned().collect();
    fields.sort_by(|a, b| a.name().cmp(b.name()));
    SchemaProto::try_from(&Schema::new_with_metadata(fields, read.metadata().clone()))
        .map_err(arrow_error)
}

fn footer_error(reason: &str) -> EncodeError {
    EncodeError::Codec(Box::new(CodecError::FrameDecoding(format!(
        "RRD footer: {reason}"
    ))))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What the recording stream sends: series as columns, static texts, a log call's row.
    fn messages(recording_id: &str) -> Vec<LogMsg> {
        let rec = rerun::RecordingStreamBuilder::new("unz-review")
            .recording_id(recording_id)
            .batcher_config(IN_LOGGED_ORDER)
            .buffered()
            .unwrap();
        without_wall_clock(&rec);
        let storage = rec.memory();
        rec.send_recording_name(recording_id).unwrap();
        for series in 0..7u32 {
            let n = 20_000 + 3_001 * series as usize;
            let t = (0..n).map(|k| k as f64 * 0.01);
            let v = (0..n).map(|k| (k as f64 * 1e-3 + f64::from(series)).sin());
            rec.send_columns(
                format!("plots/series/{series}"),
                [rerun::TimeColumn::new_duration_secs("time", t)],
                rerun::Scalars::new(v).columns_of_unit_batches().unwrap(),
            )
            .unwrap();
            rec.log_static(
                format!("notes/{series}"),
                &rerun::TextDocument::new(format!("series {series}")),
            )
            .unwrap();
        }
        rec.log(
            "points",
            &rerun::Points3D::new([(1.0, 2.0, 3.0), (4.0, 5.0, 6.0)]),
        )
        .unwrap();
        storage.take()
    }

    /// `messages` renamed and encoded one after the other by the SDK's own encoder, with
    /// its footer, put in order: what the sink wrote when it encoded on the stream's
    /// thread.
    fn encoded_one_by_one(messages: &[LogMsg], recording_id: &str, path: &Path) -> Vec<u8> {
        let mut ids = StableIds::for_recording(recording_id);
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(path)
            .unwrap();
        let mut encoder = Encoder::new_eager(
            CrateVersion::LOCAL,
            EncodingOptions::PROTOBUF_COMPRESSED,
            file,
        )
        .unwrap();
        for msg in messages {
            encoder.append(&ids.rename(msg.clone()).unwrap()).unwrap();
        }
        encoder.finish().unwrap();
        let mut file = encoder.into_inner().unwrap();
        footer_in_order(&mut file).unwrap();
        std::fs::read(path).unwrap()
    }

    #[test]
    fn the_sinks_file_is_the_sdks_encoders_bytes_for_the_messages_renamed() {
        let dir = tempfile::tempdir().unwrap();
        let id = "renamed";
        let msgs = messages(id);
        assert!(msgs.len() > 8, "{} messages", msgs.len());
        let (sink, file) = create(&dir.path().join("a.rrd"), id).unwrap();
        for msg in msgs.iter().cloned() {
            sink.send(msg);
        }
        file.finish().unwrap();
        let ours = std::fs::read(dir.path().join("a.rrd")).unwrap();
        let sdk = encoded_one_by_one(&msgs, id, &dir.path().join("b.rrd"));
        assert!(ours.len() > 100_000, "{} bytes", ours.len());
        assert!(ours == sdk, "{} bytes against {}", ours.len(), sdk.len());
    }
}
