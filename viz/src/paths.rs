//! Entity paths and timelines of the review recording, in one place (the Python
//! cross-check and the blueprint read the same names).

/// Timeline: seconds since the run's first IMU sample.
pub const TIME: &str = "time";
/// Timeline: raw IMU sample index.
pub const SAMPLE: &str = "sample";

/// Map trajectories, one child per method (`initial`, `oepi`, `owpi`, `joint`, `truth`).
pub const MAP_TRAJECTORY: &str = "map/trajectory";
/// Surveyed control points on the map.
pub const MAP_CONTROL_POINTS: &str = "map/control_points";
/// The vehicle on the map over time (corrected navigation).
pub const MAP_VEHICLE: &str = "map/vehicle";

/// Root of the 3D view: local east-north-up metres from the start.
pub const WORLD: &str = "world";
/// 3D trajectories, one child per method.
pub const WORLD_TRAJECTORY: &str = "world/trajectory";
/// Control points in 3D with their labels and errors.
pub const WORLD_CONTROL_POINTS: &str = "world/control_points";
/// The vehicle's pose over time (corrected navigation).
pub const WORLD_VEHICLE: &str = "world/vehicle";
/// The vehicle's body box, child of [`WORLD_VEHICLE`].
pub const WORLD_VEHICLE_BODY: &str = "world/vehicle/body";
/// The vehicle's control-point mark, child of [`WORLD_VEHICLE`] (when away from the
/// navigated point).
pub const WORLD_VEHICLE_MARK: &str = "world/vehicle/mark";

/// Pitch: gyro (navigated) and accelerometer.
pub const PLOT_PITCH: &str = "plots/pitch";
/// Roll: gyro (navigated) and accelerometer.
pub const PLOT_ROLL: &str = "plots/roll";
/// ΔΘ, ΔΦ and their Kalman estimates.
pub const PLOT_RESIDUALS: &str = "plots/residuals";
/// Cumulative Kryt1 per settings (the paper's Fig. 1).
pub const PLOT_KRYT1: &str = "plots/kryt1";
/// Odometer speed u, filtered and raw.
pub const PLOT_SPEED: &str = "plots/speed";
/// u̇ and ru.
pub const PLOT_ACCEL_TERMS: &str = "plots/accel_terms";
/// Gyro rates from the raw increments, decimated.
pub const PLOT_IMU_GYRO: &str = "plots/imu/gyro";
/// Specific force from the raw increments, decimated.
pub const PLOT_IMU_ACCEL: &str = "plots/imu/accel";

/// 1σ of the corrected route: north, east (m) and heading (°).
pub const PLOT_ROUTE_SIGMA: &str = "plots/route_sigma";

/// Sensitivity maps (when a sweep exists).
pub const SENSITIVITY: &str = "sensitivity";
/// The DISUPT tables.
pub const DISUPT_TABLES: &str = "disupt/tables";
/// What the recording shows and in which frames.
pub const README: &str = "readme";
