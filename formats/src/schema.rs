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
        ],
        "odometer",
        time_origin_utc_ns,
    )
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
    "lat_deg",
    "lon_deg",
    "h_m",
    "north_m",
    "east_m",
    "roll_deg",
    "pitch_deg",
    "heading_deg",
];

/// Schema metadata key of `truth`: the true settings as JSON.
pub const META_TRUE_SETTINGS: &str = "unz.true_settings";

/// `truth`: the simulator's true state at every IMU sample.
pub fn truth(time_origin_utc_ns: Option<i64>, true_settings_json: &str) -> SchemaRef {
    let deg = |n: &str| scalar(n, DataType::Float64, false, "deg");
    let m = |n: &str| scalar(n, DataType::Float64, false, "m");
    let schema = with_meta(
        vec![
            time_field(),
            deg("lat_deg"),
            deg("lon_deg"),
            m("h_m"),
            vec3("vel_ned_mps", "m/s", FRAME_NED),
            deg("roll_deg"),
            deg("pitch_deg"),
            deg("heading_deg"),
            m(DISTANCE_M),
            m("north_m"),
            m("east_m"),
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

/// `derived`: the derive stage's per-sample series. `meta` holds the
/// [`derived_meta`] keys with their values.
pub fn derived(meta: impl IntoIterator<Item = (&'static str, String)>) -> SchemaRef {
    let mut m = table_meta("derived");
    m.extend(meta.into_iter().map(|(k, v)| (k.to_owned(), v)));
    Arc::new(Schema::new_with_metadata(
        vec![
            time_field(),
            f64_field("dt_s", "s"),
            vec3(DTHETA_RAD, "rad", FRAME_BODY),
            vec3(DVEL_MPS, "m/s", FRAME_BODY),
            f64_field("odo_dist_m", "m"),
            f64_field("u_mps", "m/s"),
            f64_field("u_dot_mps2", "m/s^2"),
            f64_field("r_rad_s", "rad/s"),
            f64_field("ru_mps2", "m/s^2"),
        ],
        m,
    ))
}

/// `epochs`: the derive stage's accelerometer references per ΔTg epoch.
pub fn epochs() -> SchemaRef {
    Arc::new(Schema::new_with_metadata(
        vec![
            time_field(),
            scalar("block", DataType::UInt64, false, "1"),
            f64_field("theta_p_rad", "rad"),
            f64_field("phi_p_rad", "rad"),
            f64_field("theta_p_per_yaw", "rad/rad"),
            f64_field("phi_p_per_yaw", "rad/rad"),
            f64_field("theta_p_per_bias", "rad/(m/s)"),
            f64_field("phi_p_per_bias", "rad/(m/s)"),
            Field::new("valid", DataType::Boolean, false),
            f64_field("ax_f_mps2", "m/s^2"),
            f64_field("ay_f_mps2", "m/s^2"),
            f64_field("u_dot_f_mps2", "m/s^2"),
            f64_field("ru_f_mps2", "m/s^2"),
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
            f64_field("ax_f_mps2", "m/s^2"),
            f64_field("ay_f_mps2", "m/s^2"),
            f64_field("u_dot_f_mps2", "m/s^2"),
            f64_field("ru_f_mps2", "m/s^2"),
            f64_field("r_moving_f_rad_s", "rad/s"),
            f64_field("moving_dot_f_per_s", "1/s"),
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
            scalar("sample", DataType::Int64, false, ""),
            f64_field("u_mps", "m/s"),
            f64_field("u_dot_mps2", "m/s^2"),
            f64_field("ru_mps2", "m/s^2"),
            vec3("gyro_deg_s", "deg/s", FRAME_BODY),
            vec3("accel_mps2", "m/s^2", FRAME_BODY),
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
        fields.push(f32_field("sigma_north_m", "m"));
        fields.push(f32_field("sigma_east_m", "m"));
        fields.push(f32_field("sigma_heading_deg", "deg"));
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
    "theta_p_rad",
    "phi_p_rad",
    "d_theta_rad",
    "d_phi_rad",
    "kf_d_theta_rad",
    "kf_d_phi_rad",
    "kryt1_cum",
];

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
        f64_field("kryt1_cum", "rad"),
        f64_field("kf_d_theta_rad", "rad"),
        f64_field("kf_d_phi_rad", "rad"),
    ]))
}

/// `sweep`: the criteria over a grid of one or two settings (named by `axes`, unitless
/// in the file: each axis's unit is in its name).
pub fn sweep(axes: &[&str]) -> SchemaRef {
    let mut fields: Vec<Field> = axes
        .iter()
        .map(|a| scalar(a, DataType::Float64, false, ""))
        .collect();
    fields.push(f64_field("kryt1_rad", "rad"));
    fields.push(f64_field("kryt2_m", "m"));
    Arc::new(Schema::new(fields))
}

/// `campaign`: one row per run; `stage_seconds` names the per-stage wall-time columns and
/// `values` the nullable result columns that follow them.
pub fn campaign(stage_seconds: &[String], values: &[&str]) -> SchemaRef {
    let mut fields = vec![
        Field::new("run", DataType::Utf8, false),
        Field::new("manifest", DataType::Utf8, false),
        Field::new("ok", DataType::Boolean, false),
        Field::new("error", DataType::Utf8, true),
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
