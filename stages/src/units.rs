//! Unit conversions used across the stages: one definition each.

/// One degree per hour in rad/s (gyro drifts are reported in °/h).
pub const DEG_PER_H: f64 = std::f64::consts::PI / 180.0 / 3600.0;

/// One milli-g in m/s² (accelerometer biases).
pub const MILLI_G: f64 = 9.806_65e-3;

/// One degree per square-root hour in rad/√s (angle random walk).
pub const DEG_PER_SQRT_H: f64 = std::f64::consts::PI / 180.0 / 60.0;
