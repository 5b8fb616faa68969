//! A Rerun log sink that encodes the recording into its file as it is logged: no copy
//! of the recording is held in memory (a 12-hour run's is about 180 MB encoded, more as
//! the SDK's messages), and the operating system's own errors reach the caller.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use rerun::external::re_log_encoding::{CrateVersion, EncodeError, Encoder, EncodingOptions};
use rerun::log::LogMsg;
use rerun::sink::{LogSink, SinkFlushError};

type FileEncoder = Encoder<BufWriter<File>>;

/// The encoder and the first error it met.
struct State {
    encoder: Option<FileEncoder>,
    error: Option<EncodeError>,
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

/// Starts an RRD stream into `path` (created): the sink to set on a recording stream, and
/// the handle that finishes the file.
pub(crate) fn create(path: &Path) -> Result<(RrdFileSink, RrdFile), EncodeError> {
    let file = BufWriter::with_capacity(1 << 20, File::create(path)?);
    // What the SDK's memory and file sinks write: this version, compressed protobuf.
    let encoder = Encoder::new_eager(
        CrateVersion::LOCAL,
        EncodingOptions::PROTOBUF_COMPRESSED,
        file,
    )?;
    let state = Arc::new(Mutex::new(State {
        encoder: Some(encoder),
        error: None,
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
        if s.error.is_some() {
            return;
        }
        if let Some(encoder) = s.encoder.as_mut()
            && let Err(e) = encoder.append(&msg)
        {
            s.error = Some(e);
        }
    }

    fn flush_blocking(&self, _timeout: Duration) -> Result<(), SinkFlushError> {
        // Messages are encoded as they come; the file is flushed by `RrdFile::finish`.
        Ok(())
    }
}

impl RrdFile {
    /// Writes the stream's footer and flushes the file (call once the recording stream has
    /// been flushed and dropped); the first error of the whole stream, if any.
    pub(crate) fn finish(self) -> Result<(), EncodeError> {
        let mut s = lock(&self.state);
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
        file.into_inner().map_err(|e| e.into_error())?;
        Ok(())
    }
}
