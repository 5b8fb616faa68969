//! Writer for the binary UNZ log.

use std::io::Write;

use super::header::FileHeader;
use super::record::{ImuRecord, MarkRecord, TYPE_IMU, TYPE_MARK, encode_frame};

/// Streams a header and framed records to any writer.
pub struct RawWriter<W: Write> {
    out: W,
    frame: Vec<u8>,
}

impl<W: Write> RawWriter<W> {
    /// Writes the 128-byte header and returns the writer.
    pub fn new(mut out: W, header: &FileHeader) -> std::io::Result<Self> {
        out.write_all(&header.encode())?;
        Ok(Self {
            out,
            frame: Vec::with_capacity(64),
        })
    }

    /// Writes one IMU record.
    pub fn write_imu(&mut self, r: &ImuRecord) -> std::io::Result<()> {
        self.write_frame(TYPE_IMU, &r.encode_payload())
    }

    /// Writes one control-point mark.
    pub fn write_mark(&mut self, r: &MarkRecord) -> std::io::Result<()> {
        self.write_frame(TYPE_MARK, &r.encode_payload())
    }

    /// Writes a record of any type (reserved types included) with a valid CRC.
    pub fn write_frame(&mut self, record_type: u8, payload: &[u8]) -> std::io::Result<()> {
        if payload.len() > 255 {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "record payload longer than 255 bytes",
            ));
        }
        self.frame.clear();
        encode_frame(record_type, payload, &mut self.frame);
        self.out.write_all(&self.frame)
    }

    /// Writes bytes as they are (fault injection in the simulator and the tests).
    pub fn write_raw(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.out.write_all(bytes)
    }

    /// Flushes and returns the inner writer.
    pub fn finish(mut self) -> std::io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}
