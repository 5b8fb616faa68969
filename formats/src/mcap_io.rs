//! MCAP output with JSON messages described by JSON Schema, the encodings Foxglove
//! decodes without set-up. Written atomically like every other output.

use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::Path;

use crate::atomic::AtomicFile;
use crate::error::{FileError, FormatError};

/// Channel handle returned by [`JsonMcap::add_channel`].
#[derive(Debug, Clone, Copy)]
pub struct Channel {
    id: u16,
    sequence: u32,
}

/// An MCAP file of JSON channels being written.
pub struct JsonMcap {
    writer: mcap::Writer<BufWriter<std::fs::File>>,
    file: AtomicFile,
    message: Vec<u8>,
}

fn mcap_err(path: &Path, e: impl Into<FormatError>) -> FileError {
    e.into().in_file(path)
}

impl JsonMcap {
    /// Starts a zstd-chunked MCAP file at `dest`.
    pub fn create(dest: &Path) -> Result<Self, FileError> {
        let file = AtomicFile::create(dest)?;
        let handle = BufWriter::with_capacity(1 << 20, file.file_handle()?);
        let writer = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(1)
            .compression_threads(0)
            .profile("")
            .library(concat!("unz ", env!("CARGO_PKG_VERSION")))
            .create(handle)
            .map_err(|e| mcap_err(dest, e))?;
        Ok(Self {
            writer,
            file,
            message: Vec::with_capacity(512),
        })
    }

    /// Registers a channel whose messages are JSON objects described by `json_schema`.
    pub fn add_channel(
        &mut self,
        topic: &str,
        schema_name: &str,
        json_schema: &str,
    ) -> Result<Channel, FileError> {
        let dest = self.file.dest().to_path_buf();
        let schema_id = self
            .writer
            .add_schema(schema_name, "jsonschema", json_schema.as_bytes())
            .map_err(|e| mcap_err(&dest, e))?;
        let id = self
            .writer
            .add_channel(schema_id, topic, "json", &BTreeMap::new())
            .map_err(|e| mcap_err(&dest, e))?;
        Ok(Channel { id, sequence: 0 })
    }

    /// Writes one message serialised from `value` at `log_time_ns`.
    pub fn write(
        &mut self,
        channel: &mut Channel,
        log_time_ns: u64,
        value: &impl serde::Serialize,
    ) -> Result<(), FileError> {
        self.message.clear();
        serde_json::to_writer(&mut self.message, value)
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

/// JSON Schema of an object whose properties are all numbers or arrays of numbers.
pub fn numeric_object_schema(title: &str, scalars: &[&str], vectors: &[&str]) -> String {
    let mut props = serde_json::Map::new();
    for s in scalars {
        props.insert((*s).to_owned(), serde_json::json!({ "type": "number" }));
    }
    for v in vectors {
        props.insert(
            (*v).to_owned(),
            serde_json::json!({ "type": "array", "items": { "type": "number" }, "minItems": 3, "maxItems": 3 }),
        );
    }
    serde_json::json!({ "title": title, "type": "object", "properties": props }).to_string()
}
