//! What the simulated UNZ-50 emits: integer counts with their scales and time tags,
//! before any file format (the raw log's bytes are written where the format lives,
//! `unz_formats::raw`).

/// The device's timing and count scales (what a raw log's header states).
#[derive(Debug, Clone, PartialEq)]
pub struct SensorSpec {
    /// Nominal IMU sample period, µs.
    pub sample_period_us: u32,
    /// UTC of the log's time origin, µs since 1970.
    pub start_time_us: i64,
    /// Angle increment per count, rad.
    pub dtheta_lsb_rad: f64,
    /// Velocity increment per count, m/s.
    pub dvel_lsb_mps: f64,
    /// Odometer distance per pulse (nominal), m.
    pub odo_lsb_m: f64,
    /// Device serial number.
    pub serial: String,
}

impl SensorSpec {
    /// An UNZ-50 (LN-200 at 100 Hz, 2^-26 rad and 2^-20 m/s per count, 12.5 mm pulses).
    pub fn unz50(start_time_us: i64, serial: &str) -> Self {
        Self {
            sample_period_us: 10_000,
            start_time_us,
            dtheta_lsb_rad: 2f64.powi(-26),
            dvel_lsb_mps: 2f64.powi(-20),
            odo_lsb_m: 0.0125,
            serial: serial.to_owned(),
        }
    }

    /// Nominal sample period, s.
    pub fn sample_period_s(&self) -> f64 {
        f64::from(self.sample_period_us) * 1e-6
    }
}

/// One IMU sample as the device counts it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SensorSample {
    /// Sample counter (wraps at 2^32).
    pub seq: u32,
    /// Time tag at the end of the interval, µs since the log's origin.
    pub t_us: u64,
    /// Angle increments over the interval, counts, body FRD.
    pub dtheta_counts: [i32; 3],
    /// Velocity increments over the interval, counts, body FRD.
    pub dvel_counts: [i32; 3],
    /// Cumulative odometer pulses (wraps at 2^32).
    pub odo_count: u32,
    /// Status bits.
    pub status: u16,
}

/// A control-point mark: the operator's button press at a surveyed point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SensorMark {
    /// Time tag, µs since the log's origin.
    pub t_us: u64,
    /// Control-point id.
    pub point_id: u32,
}
