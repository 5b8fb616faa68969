//! Canonical Arrow schemas of the pipeline's tables, in one place.
//!
//! Every field carries `unit` metadata (and `frame` for vectors); vectors are
//! `FixedSizeList<Float64, 3>`. Time is `t_ns: Int64`, nanoseconds in the log's own time
//! base (binary logs: since the header's `start_time_us`; text logs: the file's time
//! column); the schema metadata `unz.time_origin_utc_ns` gives UTC of `t_ns = 0` when known.

use std::collections::HashMap;
use std::sync::Arc;

use arrow::datatypes::{DataType, Field, Schema, SchemaRef};

/// Column: time, ns.
pub const T_NS: &str = "t_ns";
/// Column: unwrapped IMU sample counter.
pub const SEQ: &str = "seq";
/// Column: angle increments over the interval, rad, body FRD.
pub const DTHETA_RAD: &str = "dtheta_rad";
/// Column: velocity increments over the interval, m/s, body FRD.
pub const DVEL_MPS: &str = "dvel_mps";
/// Column: raw status bits.
pub const STATUS: &str = "status";
/// Column: cumulative odometer distance, m.
pub const DISTANCE_M: &str = "distance_m";
/// Column: cumulative odometer pulses (unwrapped), when the odometer counts pulses.
pub const PULSES: &str = "pulses";
/// Column: where an odometer sample's distance comes from ([`DistanceSource`]'s codes).
pub const DISTANCE_SOURCE: &str = "distance_source";
/// Column: control-point id.
pub const POINT_ID: &str = "point_id";

/// Schema metadata key: table name.
pub const META_TABLE: &str = "unz.table";
/// Schema metadata key: UTC of `t_ns = 0`, ns since 1970, when known.
pub const META_TIME_ORIGIN: &str = "unz.time_origin_utc_ns";

/// Body frame: x forward, y right, z down.
pub const FRAME_BODY: &str = "body_frd";
/// Navigation frame: local-level north, east, down.
pub const FRAME_NED: &str = "ned";

/// A scalar field with a `unit`.
pub fn scalar(name: &str, data_type: DataType, nullable: bool, unit: &str) -> Field {
    Field::new(name, data_type, nullable)
        .with_metadata(HashMap::from([("unit".to_owned(), unit.to_owned())]))
}

/// A 3-vector field (`FixedSizeList<Float64, 3>`) with `unit` and `frame`.
pub fn vec3(name: &str, unit: &str, frame: &str) -> Field {
    Field::new(name, vec3_type(), false).with_metadata(HashMap::from([
        ("unit".to_owned(), unit.to_owned()),
        ("frame".to_owned(), frame.to_owned()),
    ]))
}

/// `FixedSizeList<Float64, 3>`.
pub fn vec3_type() -> DataType {
    DataType::FixedSizeList(Arc::new(Field::new("item", DataType::Float64, false)), 3)
}

fn time_field() -> Field {
    scalar(T_NS, DataType::Int64, false, "ns")
}

fn with_meta(fields: Vec<Field>, table: &str, time_origin_utc_ns: Option<i64>) -> SchemaRef {
    let mut meta = HashMap::from([(META_TABLE.to_owned(), table.to_owned())]);
    if let Some(t0) = time_origin_utc_ns {
        meta.insert(META_TIME_ORIGIN.to_owned(), t0.to_string());
    }
    Arc::new(Schema::new_with_metadata(fields, meta))
}

/// `imu`: one row per accepted IMU sample.
pub fn imu(time_origin_utc_ns: Option<i64>) -> SchemaRef {
    with_meta(
        vec![
            time_field(),
            scalar(SEQ, DataType::UInt64, false, "1"),
            vec3(DTHETA_RAD, "rad", FRAME_BODY),
            vec3(DVEL_MPS, "m/s", FRAME_BODY),
            scalar(STATUS, DataType::UInt16, false, "bits"),
        ],
        "imu",
        time_origin_utc_ns,
    )
}

/// `odometer`: cumulative distance (and pulses when counted) at the odometer's own rate.
pub fn odometer(time_origin_utc_ns: Option<i64>) -> SchemaRef {
    with_meta(
        vec![
            time_field(),
            scalar(DISTANCE_M, DataType::Float64, false, "m"),
            scalar(PULSES, DataType::Int64, true, "pulses"),
            scalar(DISTANCE_SOURCE, DataType::UInt8, false, "code").with_metadata(HashMap::from([
                ("unit".to_owned(), "code".to_owned()),
                ("values".to_owned(), DistanceSource::CODES.to_owned()),
            ])),
        ],
        "odometer",
        time_origin_utc_ns,
    )
}

/// Where an odometer sample's distance comes from (column [`DISTANCE_SOURCE`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(u8)]
pub enum DistanceSource {
    /// The odometer's reading (after a failure, moved on to continue the distance).
    #[default]
    Reading = 0,
    /// Failed, and bridged: the distance is the inertial along-track speed's.
    Bridged = 1,
    /// Failed, not bridged: the distance held over it.
    Held = 2,
}

impl DistanceSource {
    /// The codes as the column's `values` metadata states them.
    pub const CODES: &str = "0 the odometer's reading, 1 failed and bridged, 2 failed and held";

    /// The source of a code; `None` for a code no writer makes.
    pub fn of_code(code: u8) -> Option<Self> {
        match code {
            0 => Some(Self::Reading),
            1 => Some(Self::Bridged),
            2 => Some(Self::Held),
            _ => None,
        }
    }
}

/// `marks`: control-point marks.
pub fn marks(time_origin_utc_ns: Option<i64>) -> SchemaRef {
    with_meta(
        vec![time_field(), scalar(POINT_ID, DataType::UInt32, false, "1")],
        "marks",
        time_origin_utc_ns,
    )
}

/// The navigation state columns shared by `nav.parquet`, `corrected_nav.parquet` and
/// `tracks.parquet`: position (degrees, m), local north/east of the start (m) and
/// attitude (degrees).
pub fn nav_state_fields() -> Vec<Field> {
    // Latitude and longitude need f64 (f32 degrees resolve only about a metre); the rest
    // in f32 resolves far below what the navigation knows (millimetres at 100 km,
    // 2e-5° in attitude) and halves the files.
    let [lat, lon, rest @ ..] = NAV_STATE;
    let mut fields = vec![f64_field(lat, "deg"), f64_field(lon, "deg")];
    let units = ["m", "m", "m", "deg", "deg", "deg"];
    fields.extend(rest.iter().zip(units).map(|(n, unit)| f32_field(n, unit)));
    fields
}

/// The columns of [`nav_state_fields`], in order: latitude and longitude (f64), then
/// height, north, east, roll, pitch and heading (f32).
pub const NAV_STATE: [&str; 8] = [
    nav_cols::LAT_DEG,
    nav_cols::LON_DEG,
    nav_cols::H_M,
    nav_cols::NORTH_M,
    nav_cols::EAST_M,
    nav_cols::ROLL_DEG,
    nav_cols::PITCH_DEG,
    nav_cols::HEADING_DEG,
];

/// Columns of the navigation state ([`nav_state_fields`]), of [`nav`]'s route σ, and of
/// [`truth`]'s position and attitude.
pub mod nav_cols {
    /// Latitude, deg.
    pub const LAT_DEG: &str = "lat_deg";
    /// Longitude, deg.
    pub const LON_DEG: &str = "lon_deg";
    /// Height, m.
    pub const H_M: &str = "h_m";
    /// North of the start, m.
    pub const NORTH_M: &str = "north_m";
    /// East of the start, m.
    pub const EAST_M: &str = "east_m";
    /// Roll, deg.
    pub const ROLL_DEG: &str = "roll_deg";
    /// Pitch, deg.
    pub const PITCH_DEG: &str = "pitch_deg";
    /// Heading, deg.
    pub const HEADING_DEG: &str = "heading_deg";
    /// The corrected route's 1σ north, m (`corrected_nav.parquet` of a joint fit).
    pub const SIGMA_NORTH_M: &str = "sigma_north_m";
    /// The corrected route's 1σ east, m.
    pub const SIGMA_EAST_M: &str = "sigma_east_m";
    /// The corrected route's 1σ heading, deg.
    pub const SIGMA_HEADING_DEG: &str = "sigma_heading_deg";
}

/// Columns of [`truth`] beyond the navigation state's ([`nav_cols`]) and [`DISTANCE_M`].
pub mod truth_cols {
    /// True velocity, m/s, NED.
    pub const VEL_NED_MPS: &str = "vel_ned_mps";
}

/// Schema metadata key of `truth`: the true settings as JSON.
pub const META_TRUE_SETTINGS: &str = "unz.true_settings";

/// `truth`: the simulator's true state at every IMU sample.
pub fn truth(time_origin_utc_ns: Option<i64>, true_settings_json: &str) -> SchemaRef {
    let deg = |n: &str| scalar(n, DataType::Float64, false, "deg");
    let m = |n: &str| scalar(n, DataType::Float64, false, "m");
    let schema = with_meta(
        vec![
            time_field(),
            deg(nav_cols::LAT_DEG),
            deg(nav_cols::LON_DEG),
            m(nav_cols::H_M),
            vec3(truth_cols::VEL_NED_MPS, "m/s", FRAME_NED),
            deg(nav_cols::ROLL_DEG),
            deg(nav_cols::PITCH_DEG),
            deg(nav_cols::HEADING_DEG),
            m(DISTANCE_M),
            m(nav_cols::NORTH_M),
            m(nav_cols::EAST_M),
        ],
        "truth",
        time_origin_utc_ns,
    );
    let mut meta = schema.metadata().clone();
    meta.insert(META_TRUE_SETTINGS.to_owned(), true_settings_json.to_owned());
    Arc::new(Schema::new_with_metadata(schema.fields().clone(), meta))
}

/// Schema metadata key of `odometer`: metres per pulse used for `distance_m`.
pub const META_ODO_M_PER_PULSE: &str = "unz.odo_m_per_pulse";

/// `odometer` with the scale that produced `distance_m` from pulses, when it did.
pub fn odometer_scaled(time_origin_utc_ns: Option<i64>, m_per_pulse: Option<f64>) -> SchemaRef {
    let schema = odometer(time_origin_utc_ns);
    let Some(s) = m_per_pulse else {
        return schema;
    };
    let mut meta = schema.metadata().clone();
    meta.insert(META_ODO_M_PER_PULSE.to_owned(), s.to_string());
    Arc::new(Schema::new_with_metadata(schema.fields().clone(), meta))
}

/// Schema metadata keys of `derived`: the derive stage's scalars and counts.
pub mod derived_meta {
    /// Samples per block of the filter F.
    pub const BLOCK: &str = "unz.block";
    /// Nominal sample period, s.
    pub const NOMINAL_DT_S: &str = "unz.nominal_dt_s";
    /// Samples whose time tag derive repaired.
    pub const REPAIRED_TIMES: &str = "unz.repaired_times";
    /// Samples that closed a gap and were scaled to it.
    pub const FILLED_GAPS: &str = "unz.filled_gaps";
    /// Samples flagged with an IMU failure.
    pub const IMU_FAILURES: &str = "unz.imu_failure_samples";
    /// Samples flagged with an odometer failure.
    pub const ODO_FAILURES: &str = "unz.odometer_failure_samples";
    /// Samples whose increments exceeded the IMU's range and were replaced.
    pub const OUT_OF_RANGE: &str = "unz.out_of_range_samples";
    /// The check of the IMU's axes against the vehicle's (JSON of
    /// `unz_stages::imu_axes::AxesCheck`).
    pub const IMU_AXES_CHECK: &str = "unz.imu_axes_check";
    /// What the drive says of the odometer's clock (JSON of
    /// `unz_stages::odo_clock::ClockFit`).
    pub const ODOMETER_CLOCK: &str = "unz.odometer_clock";
}

fn f64_field(name: &str, unit: &str) -> Field {
    scalar(name, DataType::Float64, false, unit)
}

fn f32_field(name: &str, unit: &str) -> Field {
    scalar(name, DataType::Float32, false, unit)
}

fn table_meta(table: &str) -> HashMap<String, String> {
    HashMap::from([(META_TABLE.to_owned(), table.to_owned())])
}

/// Columns of [`derived`] beyond [`T_NS`].
pub mod derived_cols {
    /// The sample's interval, s.
    pub const DT_S: &str = "dt_s";
    /// Odometer distance over the interval, m.
    pub const ODO_DIST_M: &str = "odo_dist_m";
    /// Odometer speed u, m/s (eq 9).
    pub const U_MPS: &str = "u_mps";
    /// Odometer acceleration u̇, m/s² (eq 10).
    pub const U_DOT_MPS2: &str = "u_dot_mps2";
    /// Centripetal term ru, m/s² (eq 11).
    pub const RU_MPS2: &str = "ru_mps2";
}

/// `derived`: the derive stage's per-sample series: the repaired time base and the
/// odometer's terms (one row per row of the ingest's `imu`). The IMU's increments are
/// `imu`'s but for the samples in [`imu_repairs`]. `meta` holds the [`derived_meta`]
/// keys with their values.
pub fn derived(meta: impl IntoIterator<Item = (&'static str, String)>) -> SchemaRef {
    let mut m = table_meta("derived");
    m.extend(meta.into_iter().map(|(k, v)| (k.to_owned(), v)));
    Arc::new(Schema::new_with_metadata(
        vec![
            time_field(),
            f64_field(derived_cols::DT_S, "s"),
            f64_field(derived_cols::ODO_DIST_M, "m"),
            f64_field(derived_cols::U_MPS, "m/s"),
            f64_field(derived_cols::U_DOT_MPS2, "m/s^2"),
            f64_field(derived_cols::RU_MPS2, "m/s^2"),
        ],
        m,
    ))
}

/// Columns of [`imu_repairs`] beyond [`T_NS`], [`DTHETA_RAD`] and [`DVEL_MPS`].
pub mod imu_repairs_cols {
    /// The sample: its row in the ingest's `imu` and in `derived`.
    pub const SAMPLE: &str = "sample";
}

/// `imu_repairs` (`derive/imu_repairs.parquet`): the IMU samples whose increments the
/// derive replaced (scaled over a gap they close, or held at the rates before where they
/// exceed the instrument's range), in order, with the increments it uses and the
/// sample's repaired time; every other sample's increments are the ingest's `imu`'s.
pub fn imu_repairs() -> SchemaRef {
    Arc::new(Schema::new_with_metadata(
        vec![
            scalar(imu_repairs_cols::SAMPLE, DataType::UInt64, false, ""),
            time_field(),
            vec3(DTHETA_RAD, "rad", FRAME_BODY),
            vec3(DVEL_MPS, "m/s", FRAME_BODY),
        ],
        table_meta("imu_repairs"),
    ))
}

/// Columns of [`epochs`] beyond [`T_NS`], [`VALID`] and the filtered terms
/// ([`filtered_cols`]).
pub mod epochs_cols {
    /// The epoch's block of F.
    pub const BLOCK: &str = "block";
    /// Accelerometer pitch Θ_p, rad.
    pub const THETA_P_RAD: &str = "theta_p_rad";
    /// Accelerometer roll Φ_p, rad.
    pub const PHI_P_RAD: &str = "phi_p_rad";
    /// ∂Θ_p per rad of odometer boresight yaw.
    pub const THETA_P_PER_YAW: &str = "theta_p_per_yaw";
    /// ∂Φ_p per rad of odometer boresight yaw.
    pub const PHI_P_PER_YAW: &str = "phi_p_per_yaw";
    /// ∂Θ_p per m/s of odometer speed bias.
    pub const THETA_P_PER_BIAS: &str = "theta_p_per_bias";
    /// ∂Φ_p per m/s of odometer speed bias.
    pub const PHI_P_PER_BIAS: &str = "phi_p_per_bias";
}

/// The filtered terms, per block in [`blocks`] and at the epochs in [`epochs`].
pub mod filtered_cols {
    /// Filtered forward specific force, m/s².
    pub const AX_F_MPS2: &str = "ax_f_mps2";
    /// Filtered lateral specific force, m/s².
    pub const AY_F_MPS2: &str = "ay_f_mps2";
    /// Filtered odometer acceleration u̇, m/s².
    pub const U_DOT_F_MPS2: &str = "u_dot_f_mps2";
    /// Filtered centripetal term ru, m/s².
    pub const RU_F_MPS2: &str = "ru_f_mps2";
    /// Filtered r over the samples in which the odometer moved, rad/s (what an odometer
    /// speed bias adds to ru, per m/s; blocks only).
    pub const R_MOVING_F_RAD_S: &str = "r_moving_f_rad_s";
    /// Filtered rate of change of "the odometer moved", 1/s (what an odometer speed bias
    /// adds to u̇, per m/s; blocks only).
    pub const MOVING_DOT_F_PER_S: &str = "moving_dot_f_per_s";
}

/// `epochs`: the derive stage's accelerometer references per ΔTg epoch.
pub fn epochs() -> SchemaRef {
    Arc::new(Schema::new_with_metadata(
        vec![
            time_field(),
            scalar(epochs_cols::BLOCK, DataType::UInt64, false, "1"),
            f64_field(epochs_cols::THETA_P_RAD, "rad"),
            f64_field(epochs_cols::PHI_P_RAD, "rad"),
            f64_field(epochs_cols::THETA_P_PER_YAW, "rad/rad"),
            f64_field(epochs_cols::PHI_P_PER_YAW, "rad/rad"),
            f64_field(epochs_cols::THETA_P_PER_BIAS, "rad/(m/s)"),
            f64_field(epochs_cols::PHI_P_PER_BIAS, "rad/(m/s)"),
            Field::new(VALID, DataType::Boolean, false),
            f64_field(filtered_cols::AX_F_MPS2, "m/s^2"),
            f64_field(filtered_cols::AY_F_MPS2, "m/s^2"),
            f64_field(filtered_cols::U_DOT_F_MPS2, "m/s^2"),
            f64_field(filtered_cols::RU_F_MPS2, "m/s^2"),
        ],
        table_meta("epochs"),
    ))
}

/// `blocks`: the derive stage's filtered series, one row per block of F (the samples
/// between two outputs of the filter): what a re-derive at another odometer timing starts
/// from, so that the configured derive is never computed twice.
pub fn blocks() -> SchemaRef {
    Arc::new(Schema::new_with_metadata(
        vec![
            f64_field(filtered_cols::AX_F_MPS2, "m/s^2"),
            f64_field(filtered_cols::AY_F_MPS2, "m/s^2"),
            f64_field(filtered_cols::U_DOT_F_MPS2, "m/s^2"),
            f64_field(filtered_cols::RU_F_MPS2, "m/s^2"),
            f64_field(filtered_cols::R_MOVING_F_RAD_S, "rad/s"),
            f64_field(filtered_cols::MOVING_DOT_F_PER_S, "1/s"),
        ],
        table_meta("blocks"),
    ))
}

/// Schema metadata keys of `sensors`.
pub mod sensors_meta {
    /// IMU samples per block.
    pub const STEP: &str = "unz.step";
    /// Time of the derive's first sample, ns (the blocks' times are since it).
    pub const T0_NS: &str = "unz.t0_ns";
    /// Nominal sample period, s.
    pub const NOMINAL_DT_S: &str = "unz.nominal_dt_s";
    /// Time of the derive's last sample since its first, s.
    pub const DURATION_S: &str = "unz.duration_s";
    /// IMU samples of the derive.
    pub const SAMPLES: &str = "unz.samples";
}

/// Columns of [`sensors`] beyond [`T_NS`] and the block means of u, u̇ and ru (named as
/// in [`derived_cols`]).
pub mod sensors_cols {
    /// The block's first sample.
    pub const SAMPLE: &str = "sample";
    /// Body rate, deg/s, body FRD.
    pub const GYRO_DEG_S: &str = "gyro_deg_s";
    /// Specific force, m/s², body FRD.
    pub const ACCEL_MPS2: &str = "accel_mps2";
}

/// `sensors` (`derive/sensors.parquet`): the derive's per-sample sensor series in the
/// review recording's blocks of `unz.step` samples (the last may be shorter): each
/// block's first time and sample, the means of u, u̇ and ru, and the body rates and
/// specific forces from the block's increments.
pub fn sensors(meta: impl IntoIterator<Item = (&'static str, String)>) -> SchemaRef {
    let mut m = table_meta("sensors");
    m.extend(meta.into_iter().map(|(k, v)| (k.to_owned(), v)));
    Arc::new(Schema::new_with_metadata(
        vec![
            time_field(),
            scalar(sensors_cols::SAMPLE, DataType::Int64, false, ""),
            f64_field(derived_cols::U_MPS, "m/s"),
            f64_field(derived_cols::U_DOT_MPS2, "m/s^2"),
            f64_field(derived_cols::RU_MPS2, "m/s^2"),
            vec3(sensors_cols::GYRO_DEG_S, "deg/s", FRAME_BODY),
            vec3(sensors_cols::ACCEL_MPS2, "m/s^2", FRAME_BODY),
        ],
        m,
    ))
}

/// `nav` (`nav.parquet`, `corrected_nav.parquet`): the navigation state per IMU sample,
/// with the route's 1σ north, east and heading when `with_sigma`.
pub fn nav(with_sigma: bool) -> SchemaRef {
    let mut fields = vec![time_field()];
    fields.extend(nav_state_fields());
    fields.push(f32_field(DISTANCE_M, "m"));
    if with_sigma {
        fields.push(f32_field(nav_cols::SIGMA_NORTH_M, "m"));
        fields.push(f32_field(nav_cols::SIGMA_EAST_M, "m"));
        fields.push(f32_field(nav_cols::SIGMA_HEADING_DEG, "deg"));
    }
    Arc::new(Schema::new(fields))
}

/// `criteria`: Kryt1's terms per epoch.
pub fn criteria() -> SchemaRef {
    let mut fields = vec![time_field()];
    fields.extend(CRITERIA_FLOATS.iter().map(|n| f64_field(n, "rad")));
    fields.push(Field::new(VALID, DataType::Boolean, false));
    Arc::new(Schema::new(fields))
}

/// The float columns of [`criteria`], in order (all in rad).
pub const CRITERIA_FLOATS: [&str; 9] = [
    "theta_n_rad",
    "phi_n_rad",
    epochs_cols::THETA_P_RAD,
    epochs_cols::PHI_P_RAD,
    "d_theta_rad",
    "d_phi_rad",
    criteria_cols::KF_D_THETA_RAD,
    criteria_cols::KF_D_PHI_RAD,
    criteria_cols::KRYT1_CUM,
];

/// The columns of [`criteria`] that [`kryt1_series`] repeats per method.
pub mod criteria_cols {
    /// The Kalman filter's estimate of the pitch difference, rad.
    pub const KF_D_THETA_RAD: &str = "kf_d_theta_rad";
    /// The Kalman filter's estimate of the roll difference, rad.
    pub const KF_D_PHI_RAD: &str = "kf_d_phi_rad";
    /// Kryt1 accumulated up to the epoch, rad.
    pub const KRYT1_CUM: &str = "kryt1_cum";
}

/// Column: whether an epoch was used (not gated).
pub const VALID: &str = "valid";

/// Column: the method a row belongs to (`tracks`, `kryt1_series`).
pub const METHOD: &str = "method";

/// `tracks`: every method's route, rows grouped by method.
pub fn tracks() -> SchemaRef {
    let mut fields = vec![Field::new(METHOD, DataType::Utf8, false), time_field()];
    fields.extend(nav_state_fields());
    Arc::new(Schema::new(fields))
}

/// `kryt1_series`: every method's cumulative Kryt1 and filtered residuals per epoch.
pub fn kryt1_series() -> SchemaRef {
    Arc::new(Schema::new(vec![
        Field::new(METHOD, DataType::Utf8, false),
        time_field(),
        f64_field(criteria_cols::KRYT1_CUM, "rad"),
        f64_field(criteria_cols::KF_D_THETA_RAD, "rad"),
        f64_field(criteria_cols::KF_D_PHI_RAD, "rad"),
    ]))
}

/// The criteria columns of [`sweep`], after its axes.
pub mod sweep_cols {
    /// Kryt1 over the run, rad.
    pub const KRYT1_RAD: &str = "kryt1_rad";
    /// RMS Kryt2 over the control points, m.
    pub const KRYT2_M: &str = "kryt2_m";
}

/// `sweep`: the criteria over a grid of one or two settings (named by `axes`, unitless
/// in the file: each axis's unit is in its name).
pub fn sweep(axes: &[&str]) -> SchemaRef {
    let mut fields: Vec<Field> = axes
        .iter()
        .map(|a| scalar(a, DataType::Float64, false, ""))
        .collect();
    fields.push(f64_field(sweep_cols::KRYT1_RAD, "rad"));
    fields.push(f64_field(sweep_cols::KRYT2_M, "m"));
    Arc::new(Schema::new(fields))
}

/// Column of [`campaign`]: the run's name.
pub const CAMPAIGN_RUN: &str = "run";
/// Column of [`campaign`]: the run's manifest, as the campaign was given it.
pub const CAMPAIGN_MANIFEST: &str = "manifest";
/// Column of [`campaign`]: what the reports of a run that did not fail flag (an odometer
/// flagged failed on some samples, methods not run or not used, a coarse azimuth turn
/// refused, an odometer boresight estimated, control points inconsistent with the rest or
/// marked more than once), null when nothing.
pub const CAMPAIGN_NOTE: &str = "note";

/// `campaign`: one row per run; `stage_seconds` names the per-stage wall-time columns and
/// `values` the nullable result columns that follow them.
pub fn campaign(stage_seconds: &[String], values: &[&str]) -> SchemaRef {
    let mut fields = vec![
        Field::new(CAMPAIGN_RUN, DataType::Utf8, false),
        Field::new(CAMPAIGN_MANIFEST, DataType::Utf8, false),
        Field::new("ok", DataType::Boolean, false),
        Field::new("error", DataType::Utf8, true),
        Field::new(CAMPAIGN_NOTE, DataType::Utf8, true),
        Field::new("stages_computed", DataType::UInt64, false),
    ];
    fields.extend(
        stage_seconds
            .iter()
            .map(|n| Field::new(n.as_str(), DataType::Float64, true)),
    );
    fields.extend(
        values
            .iter()
            .map(|n| Field::new(*n, DataType::Float64, true)),
    );
    Arc::new(Schema::new(fields))
}
