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
    let f = |n: &str, unit: &str| scalar(n, DataType::Float64, false, unit);
    vec![
        f("lat_deg", "deg"),
        f("lon_deg", "deg"),
        f("h_m", "m"),
        f("north_m", "m"),
        f("east_m", "m"),
        f("roll_deg", "deg"),
        f("pitch_deg", "deg"),
        f("heading_deg", "deg"),
    ]
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
