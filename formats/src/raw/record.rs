//! Record framing (§1.2): `A5 5A | type | len | payload | crc16 (LE)`.

use super::crc::record_crc;

/// Sync bytes opening every record.
pub const SYNC: [u8; 2] = [0xA5, 0x5A];
/// Record type of an IMU sample.
pub const TYPE_IMU: u8 = 0x01;
/// Record type of a control-point mark.
pub const TYPE_MARK: u8 = 0x02;
/// Payload length of an IMU sample.
pub const IMU_PAYLOAD_LEN: usize = 42;
/// Payload length of a control-point mark.
pub const MARK_PAYLOAD_LEN: usize = 12;
/// Longest possible frame: sync, type, len, 255 payload bytes, crc.
pub const MAX_FRAME_LEN: usize = frame_len(255);

/// Bytes of a whole frame with a payload of `len` bytes.
pub const fn frame_len(len: usize) -> usize {
    2 + 1 + 1 + len + 2
}

/// One IMU sample as recorded (raw integer counts).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImuRecord {
    /// Sample counter, +1 per record, wraps at 2^32.
    pub seq: u32,
    /// End of the integration interval, µs since the header's `start_time_us`.
    pub t_us: u64,
    /// Angle increments about body x, y, z (FRD), in `dtheta_lsb_rad`.
    pub dtheta: [i32; 3],
    /// Velocity increments along body x, y, z (FRD), in `dvel_lsb_mps`.
    pub dvel: [i32; 3],
    /// Cumulative odometer pulses, wraps at 2^32.
    pub odo_count: u32,
    /// Status bits: 0 IMU BIT failure, 1 odometer failure, 2 stop button held.
    pub status: u16,
}

/// A control-point mark: the crew stands on surveyed point `point_id`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MarkRecord {
    /// µs since the header's `start_time_us`.
    pub t_us: u64,
    /// Refers to `[[control_point]] id` of the manifest.
    pub point_id: u32,
}

/// A record the reader accepted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Record {
    /// IMU sample.
    Imu(ImuRecord),
    /// Control-point mark.
    Mark(MarkRecord),
}

impl ImuRecord {
    /// Encodes the 42-byte payload.
    pub fn encode_payload(&self) -> [u8; IMU_PAYLOAD_LEN] {
        let mut p = [0u8; IMU_PAYLOAD_LEN];
        p[0..4].copy_from_slice(&self.seq.to_le_bytes());
        p[4..12].copy_from_slice(&self.t_us.to_le_bytes());
        for i in 0..3 {
            p[12 + 4 * i..16 + 4 * i].copy_from_slice(&self.dtheta[i].to_le_bytes());
            p[24 + 4 * i..28 + 4 * i].copy_from_slice(&self.dvel[i].to_le_bytes());
        }
        p[36..40].copy_from_slice(&self.odo_count.to_le_bytes());
        p[40..42].copy_from_slice(&self.status.to_le_bytes());
        p
    }

    /// Decodes a 42-byte payload.
    pub fn decode_payload(p: &[u8; IMU_PAYLOAD_LEN]) -> Self {
        let u32_at = |o: usize| u32::from_le_bytes([p[o], p[o + 1], p[o + 2], p[o + 3]]);
        let i32_at = |o: usize| i32::from_le_bytes([p[o], p[o + 1], p[o + 2], p[o + 3]]);
        let mut t = [0u8; 8];
        t.copy_from_slice(&p[4..12]);
        Self {
            seq: u32_at(0),
            t_us: u64::from_le_bytes(t),
            dtheta: [i32_at(12), i32_at(16), i32_at(20)],
            dvel: [i32_at(24), i32_at(28), i32_at(32)],
            odo_count: u32_at(36),
            status: u16::from_le_bytes([p[40], p[41]]),
        }
    }
}

impl MarkRecord {
    /// Encodes the 12-byte payload.
    pub fn encode_payload(&self) -> [u8; MARK_PAYLOAD_LEN] {
        let mut p = [0u8; MARK_PAYLOAD_LEN];
        p[0..8].copy_from_slice(&self.t_us.to_le_bytes());
        p[8..12].copy_from_slice(&self.point_id.to_le_bytes());
        p
    }

    /// Decodes a 12-byte payload.
    pub fn decode_payload(p: &[u8; MARK_PAYLOAD_LEN]) -> Self {
        let mut t = [0u8; 8];
        t.copy_from_slice(&p[0..8]);
        Self {
            t_us: u64::from_le_bytes(t),
            point_id: u32::from_le_bytes([p[8], p[9], p[10], p[11]]),
        }
    }
}

/// Appends one framed record (sync, type, len, payload, CRC) to `out`.
pub fn encode_frame(record_type: u8, payload: &[u8], out: &mut Vec<u8>) {
    debug_assert!(payload.len() <= 255);
    let start = out.len();
    out.extend_from_slice(&SYNC);
    out.push(record_type);
    out.push(payload.len() as u8);
    out.extend_from_slice(payload);
    let crc = record_crc(&out[start + 2..]);
    out.extend_from_slice(&crc.to_le_bytes());
}

/// Whether `frame` (a whole frame starting at the sync) carries a valid CRC.
pub fn frame_crc_ok(frame: &[u8]) -> bool {
    let n = frame.len();
    n >= 6 && record_crc(&frame[2..n - 2]) == u16::from_le_bytes([frame[n - 2], frame[n - 1]])
}
