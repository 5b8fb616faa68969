//! Pure kernels of the unz pipeline: the campaign simulator, the Earth model, attitude
//! conventions and the strapdown / odometer navigation (the UNZ algorithm).
//!
//! Conventions (`shared/spec/method.md`): body FRD, navigation NED, heading clockwise
//! from true north, Euler 3-2-1; a gyro drift is subtracted from the measured rate.
//!
//! ```
//! use unz_stages::simulate::{SimConfig, SensorErrors, simulate};
//! let mut config = SimConfig::new("demo", 7);
//! config.duration_s = 120.0;
//! config.errors = SensorErrors::NONE;
//! let run = simulate(&config);
//! assert_eq!(run.records.len(), 12_000);
//! ```

pub mod align;
pub mod angle_increments;
pub mod attitude;
#[cfg(test)]
mod counted_heap;
pub mod criteria;
pub mod derive;
pub mod disupt;
pub mod earth;
pub mod euler_f32;
pub mod filter;
pub mod hypot;
pub mod imu_axes;
pub mod imu_mounting;
pub mod in_motion_level;
pub mod initial;
pub mod linearized;
pub mod lost_samples;
pub mod nth_smallest;
pub mod odo_bridge;
pub mod odo_clock;
pub mod odo_lag;
pub mod odo_rebridge;
pub mod odo_travel;
pub mod route_sigma;
pub mod simulate;
pub mod stand_speed;
pub mod strapdown;
pub mod time_base;
pub mod units;

/// The unit tests count the heap their walks hold.
#[cfg(test)]
#[global_allocator]
static HEAP: counted_heap::CountedHeap = counted_heap::CountedHeap;

/// Serde helpers for report fields that may have no value: a non-finite number is left
/// out of the report (never written as `null` or a bare NaN) and reads back as NaN.
pub mod finite {
    /// Whether `v` is left out (`skip_serializing_if`).
    pub fn is_absent(v: &f64) -> bool {
        !v.is_finite()
    }

    /// The value of a field left out (`default`).
    pub fn absent() -> f64 {
        f64::NAN
    }
}
