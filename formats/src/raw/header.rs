//! The 128-byte file header (§1.1).

use crate::error::FormatError;

/// File magic, first 8 bytes.
pub const MAGIC: &[u8; 8] = b"UNZRAW01";
/// Header length of format version 1.
pub const HEADER_LEN: usize = 128;

/// Decoded file header.
#[derive(Debug, Clone, PartialEq)]
pub struct FileHeader {
    /// Offset of the first record; readers skip to it (≥ 128).
    pub header_len: u16,
    /// Format version, 1.
    pub format_version: u16,
    /// Nominal IMU sample period, µs.
    pub sample_period_us: u32,
    /// UTC of the log's time origin, µs since 1970-01-01.
    pub start_time_us: i64,
    /// Angle-increment LSB, rad.
    pub dtheta_lsb_rad: f64,
    /// Velocity-increment LSB, m/s.
    pub dvel_lsb_mps: f64,
    /// Nominal metres per odometer pulse.
    pub odo_lsb_m: f64,
    /// Device serial number (NUL padding removed).
    pub device_serial: String,
}

impl FileHeader {
    /// A header as an UNZ-50 writes it: 100 Hz, 2^-26 rad, 2^-20 m/s, 12.5 mm per pulse.
    pub fn unz50(start_time_us: i64, device_serial: &str) -> Self {
        Self {
            header_len: HEADER_LEN as u16,
            format_version: 1,
            sample_period_us: 10_000,
            start_time_us,
            dtheta_lsb_rad: 2f64.powi(-26),
            dvel_lsb_mps: 2f64.powi(-20),
            odo_lsb_m: 0.0125,
            device_serial: device_serial.to_owned(),
        }
    }

    /// Nominal sample period in seconds.
    pub fn sample_period_s(&self) -> f64 {
        f64::from(self.sample_period_us) * 1e-6
    }

    /// Encodes the 128-byte header.
    pub fn encode(&self) -> [u8; HEADER_LEN] {
        let mut b = [0u8; HEADER_LEN];
        b[0..8].copy_from_slice(MAGIC);
        b[8..10].copy_from_slice(&(HEADER_LEN as u16).to_le_bytes());
        b[10..12].copy_from_slice(&self.format_version.to_le_bytes());
        b[12..16].copy_from_slice(&self.sample_period_us.to_le_bytes());
        b[16..24].copy_from_slice(&self.start_time_us.to_le_bytes());
        b[24..32].copy_from_slice(&self.dtheta_lsb_rad.to_le_bytes());
        b[32..40].copy_from_slice(&self.dvel_lsb_mps.to_le_bytes());
        b[40..48].copy_from_slice(&self.odo_lsb_m.to_le_bytes());
        let serial = self.device_serial.as_bytes();
        let n = serial.len().min(16);
        b[48..48 + n].copy_from_slice(&serial[..n]);
        b
    }

    /// Decodes and validates the fixed part of a header (the first 128 bytes).
    pub fn decode(b: &[u8]) -> Result<Self, FormatError> {
        let bad = |reason: String| FormatError::Header { reason };
        if b.len() < HEADER_LEN {
            return Err(bad(format!(
                "file is {} bytes, shorter than the {HEADER_LEN}-byte header",
                b.len()
            )));
        }
        if &b[0..8] != MAGIC {
            return Err(bad(format!(
                "magic is {:?}, expected \"UNZRAW01\"",
                String::from_utf8_lossy(&b[0..8])
            )));
        }
        let u16_at = |o: usize| u16::from_le_bytes([b[o], b[o + 1]]);
        let u32_at = |o: usize| u32::from_le_bytes(b[o..o + 4].try_into().unwrap_or_default());
        let f64_at = |o: usize| f64::from_le_bytes(b[o..o + 8].try_into().unwrap_or_default());
        let header_len = u16_at(8);
        let format_version = u16_at(10);
        if usize::from(header_len) < HEADER_LEN {
            return Err(bad(format!("header_len {header_len} < {HEADER_LEN}")));
        }
        if format_version != 1 {
            return Err(bad(format!(
                "format_version {format_version} is not supported (1)"
            )));
        }
        let sample_period_us = u32_at(12);
        if !(50..=1_000_000).contains(&sample_period_us) {
            return Err(bad(format!(
                "sample_period_us is {sample_period_us}, outside [50, 1000000] (20 kHz to 1 Hz)"
            )));
        }
        // Physical ranges: an increment LSB so large that one count is beyond any sensor
        // (or so small that a full i32 is no motion) would navigate to Inf and NaN.
        let in_range = |name: &str, v: f64, lo: f64, hi: f64| {
            if v.is_finite() && (lo..=hi).contains(&v) {
                Ok(v)
            } else {
                Err(bad(format!("{name} is {v}, outside [{lo:e}, {hi:e}]")))
            }
        };
        let serial_bytes = &b[48..64];
        let end = serial_bytes.iter().position(|&c| c == 0).unwrap_or(16);
        Ok(Self {
            header_len,
            format_version,
            sample_period_us,
            start_time_us: i64::from_le_bytes(b[16..24].try_into().unwrap_or_default()),
            dtheta_lsb_rad: in_range("dtheta_lsb_rad", f64_at(24), 1e-15, 1e-3)?,
            dvel_lsb_mps: in_range("dvel_lsb_mps", f64_at(32), 1e-15, 1e-2)?,
            odo_lsb_m: in_range("odo_lsb_m", f64_at(40), 1e-6, 10.0)?,
            device_serial: String::from_utf8_lossy(&serial_bytes[..end]).into_owned(),
        })
    }
}
