//! The ROS 2 messages of the MCAP files: each Rust type beside its `ros2msg` definition,
//! encoded as little-endian CDR. Foxglove decodes any `ros2msg` schema without set-up,
//! as does Rerun's MCAP importer (`sensor_msgs/msg/NavSatFix` as geographic points,
//! `geometry_msgs/msg/PoseStamped` as poses, our `unz_msgs` by reflection).
//!
//! Field order in a struct is its CDR order: it must match the definition line by line
//! (the end-to-end tests decode every message of both MCAP files with the mcap package's
//! ROS 2 decoder, which parses these definitions, and with Rerun's importer).

use serde::Serialize;

/// A message type with its `ros2msg` definition (dependencies appended after
/// `MSG:` separators, as ROS 2 bags write them).
pub trait Ros2Message: Serialize {
    /// Schema name, `package/msg/Type`.
    const NAME: &'static str;
    /// The `.msg` text with its dependencies.
    const DEFINITION: &'static str;

    /// Appends the message's little-endian CDR body to `buf`, aligned from `buf`'s length
    /// (the end of the encapsulation header), by serde's serializer.
    fn write_cdr(&self, buf: &mut Vec<u8>) -> Result<(), re_cdr::Error> {
        let mut ser = re_cdr::CdrSerializer::<re_cdr::LittleEndian>::new(buf);
        self.serialize(&mut ser)
    }
}

macro_rules! msg_with_deps {
    ($main:literal $(, $dep_name:literal => $dep:literal)* $(,)?) => {
        concat!($main $(, "================================================================================\nMSG: ", $dep_name, "\n", $dep)*)
    };
}

/// `builtin_interfaces/Time`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Time {
    /// Seconds (may be negative for times before the run's origin).
    pub sec: i32,
    /// Nanoseconds within the second, 0..1e9.
    pub nanosec: u32,
}

impl Time {
    /// From nanoseconds (seconds saturate at the range of `int32`).
    pub fn from_ns(t_ns: i64) -> Self {
        let sec = t_ns.div_euclid(1_000_000_000);
        Self {
            sec: i32::try_from(sec).unwrap_or(if sec < 0 { i32::MIN } else { i32::MAX }),
            nanosec: t_ns.rem_euclid(1_000_000_000) as u32,
        }
    }
}

/// `std_msgs/Header`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Header {
    /// Time of the sample (the run's own time, from the start of its log).
    pub stamp: Time,
    /// Frame of the data.
    pub frame_id: &'static str,
}

/// One IMU sample of `raw.mcap`: rates over its interval in single precision (7
/// significant digits, finer than a plot shows); the exact increments are in
/// `imu.parquet`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImuSample {
    /// Sample counter of the log (gaps show lost samples).
    pub seq: u64,
    /// Status word of the IMU (bit meanings in the raw-format spec).
    pub status: u16,
    /// Angular rate, body frame forward-right-down, rad/s.
    pub rate_rad_s: [f32; 3],
    /// Specific force, body frame forward-right-down, m/s².
    pub accel_mps2: [f32; 3],
}

impl Ros2Message for ImuSample {
    const NAME: &'static str = "unz_msgs/msg/ImuSample";
    const DEFINITION: &'static str = "\
# IMU rates over one sample interval, body frame forward-right-down.
# The exact increments are in imu.parquet.
uint64 seq
uint16 status
float32[3] rate_rad_s
float32[3] accel_mps2
";

    /// The bytes serde's serializer writes (`seq` at 0, `status` at 8, two bytes of
    /// padding, the six floats from 12), written at once: one message per IMU sample in
    /// `raw.mcap`, where the serializer's field-by-field path took a tenth of its thread.
    fn write_cdr(&self, buf: &mut Vec<u8>) -> Result<(), re_cdr::Error> {
        let mut body = [0u8; IMU_SAMPLE_CDR_BYTES];
        body[..8].copy_from_slice(&self.seq.to_le_bytes());
        body[8..10].copy_from_slice(&self.status.to_le_bytes());
        let floats = self.rate_rad_s.iter().chain(&self.accel_mps2);
        for (k, v) in floats.enumerate() {
            body[12 + 4 * k..16 + 4 * k].copy_from_slice(&v.to_le_bytes());
        }
        buf.extend_from_slice(&body);
        Ok(())
    }
}

/// Bytes of an [`ImuSample`]'s CDR body: 8 + 2, padding to 12, six 4-byte floats.
const IMU_SAMPLE_CDR_BYTES: usize = 36;

/// One odometer sample of `raw.mcap`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OdometerSample {
    /// Distance since the start of the log, m.
    pub distance_m: f64,
    /// Speed over the interval since the previous sample, m/s.
    pub speed_mps: f64,
}

impl Ros2Message for OdometerSample {
    const NAME: &'static str = "unz_msgs/msg/OdometerSample";
    const DEFINITION: &'static str = "\
# Odometer distance since the start of the log, and the speed since the previous sample.
float64 distance_m
float64 speed_mps
";
}

/// The operator's mark at a control point.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ControlPointMark {
    /// Control point id (the manifest's `[[control_points]]`).
    pub point_id: u32,
}

impl Ros2Message for ControlPointMark {
    const NAME: &'static str = "unz_msgs/msg/ControlPointMark";
    const DEFINITION: &'static str = "\
# The operator marked a stop on a surveyed control point.
uint32 point_id
";
}

/// `sensor_msgs/NavSatStatus`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NavSatStatus {
    /// Fix status (`STATUS_FIX` = 0).
    pub status: i8,
    /// Satellite services used (0: none).
    pub service: u16,
}

/// `sensor_msgs/NavSatFix`: a position on the WGS-84 ellipsoid.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NavSatFix {
    /// Time and frame.
    pub header: Header,
    /// Fix status.
    pub status: NavSatStatus,
    /// Latitude, degrees.
    pub latitude: f64,
    /// Longitude, degrees.
    pub longitude: f64,
    /// Height above the ellipsoid, m.
    pub altitude: f64,
    /// Position covariance (east, north, up), m².
    pub position_covariance: [f64; 9],
    /// How the covariance is known (0: unknown).
    pub position_covariance_type: u8,
}

impl Ros2Message for NavSatFix {
    const NAME: &'static str = "sensor_msgs/msg/NavSatFix";
    const DEFINITION: &'static str = msg_with_deps!(
        "\
# The corrected dead-reckoned position (no satellites involved).
uint8 COVARIANCE_TYPE_UNKNOWN = 0
uint8 COVARIANCE_TYPE_APPROXIMATED = 1
uint8 COVARIANCE_TYPE_DIAGONAL_KNOWN = 2
uint8 COVARIANCE_TYPE_KNOWN = 3
std_msgs/Header header
sensor_msgs/NavSatStatus status
float64 latitude
float64 longitude
float64 altitude
float64[9] position_covariance
uint8 position_covariance_type
",
        "std_msgs/Header" => "builtin_interfaces/Time stamp\nstring frame_id\n",
        "builtin_interfaces/Time" => "int32 sec\nuint32 nanosec\n",
        "sensor_msgs/NavSatStatus" => "\
int8 STATUS_NO_FIX = -1
int8 STATUS_FIX = 0
int8 STATUS_SBAS_FIX = 1
int8 STATUS_GBAS_FIX = 2
uint16 SERVICE_GPS = 1
uint16 SERVICE_GLONASS = 2
uint16 SERVICE_COMPASS = 4
uint16 SERVICE_GALILEO = 8
int8 status
uint16 service
",
    );
}

/// `geometry_msgs/Point`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Point {
    /// x, m.
    pub x: f64,
    /// y, m.
    pub y: f64,
    /// z, m.
    pub z: f64,
}

/// `geometry_msgs/Quaternion`, [x, y, z, w].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w (scalar part).
    pub w: f64,
}

/// `geometry_msgs/Pose`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Pose {
    /// Position.
    pub position: Point,
    /// Orientation of the body in the frame.
    pub orientation: Quaternion,
}

/// `geometry_msgs/PoseStamped`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PoseStamped {
    /// Time and frame.
    pub header: Header,
    /// The pose.
    pub pose: Pose,
}

impl Ros2Message for PoseStamped {
    const NAME: &'static str = "geometry_msgs/msg/PoseStamped";
    const DEFINITION: &'static str = msg_with_deps!(
        "std_msgs/Header header\ngeometry_msgs/Pose pose\n",
        "std_msgs/Header" => "builtin_interfaces/Time stamp\nstring frame_id\n",
        "builtin_interfaces/Time" => "int32 sec\nuint32 nanosec\n",
        "geometry_msgs/Pose" => "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n",
        "geometry_msgs/Point" => "float64 x\nfloat64 y\nfloat64 z\n",
        "geometry_msgs/Quaternion" => "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    );
}

/// Attitude of the corrected navigation, degrees.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Attitude {
    /// Roll, degrees.
    pub roll_deg: f64,
    /// Pitch, degrees.
    pub pitch_deg: f64,
    /// Heading from true north, clockwise, degrees.
    pub heading_deg: f64,
}

impl Ros2Message for Attitude {
    const NAME: &'static str = "unz_msgs/msg/Attitude";
    const DEFINITION: &'static str = "\
# Attitude of the body (forward-right-down) in north-east-down, degrees.
float64 roll_deg
float64 pitch_deg
float64 heading_deg
";
}

/// The criteria at one epoch (the run's initial settings), radians.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Criteria {
    /// Gyro pitch, filtered.
    pub theta_n_rad: f64,
    /// Gyro roll, filtered.
    pub phi_n_rad: f64,
    /// Accelerometer pitch with the odometer's terms removed.
    pub theta_p_rad: f64,
    /// Accelerometer roll with the odometer's terms removed.
    pub phi_p_rad: f64,
    /// Pitch difference.
    pub d_theta_rad: f64,
    /// Roll difference.
    pub d_phi_rad: f64,
    /// Pitch difference after the smoother.
    pub kf_d_theta_rad: f64,
    /// Roll difference after the smoother.
    pub kf_d_phi_rad: f64,
    /// Cumulative Kryt1.
    pub kryt1_cum: f64,
}

impl Ros2Message for Criteria {
    const NAME: &'static str = "unz_msgs/msg/Criteria";
    const DEFINITION: &'static str = "\
# Kryt1's terms at one epoch, with the run's initial settings (radians).
float64 theta_n_rad
float64 phi_n_rad
float64 theta_p_rad
float64 phi_p_rad
float64 d_theta_rad
float64 d_phi_rad
float64 kf_d_theta_rad
float64 kf_d_phi_rad
float64 kryt1_cum
";
}

#[cfg(test)]
mod tests {
    use super::*;

    const SEPARATOR: &str =
        "================================================================================\n";

    /// An IMU sample's CDR body written at once is serde's serializer's, byte for byte,
    /// behind headers of any length (alignment counts from the body's start).
    #[test]
    fn imu_samples_are_written_as_the_serializer_writes_them() {
        let samples = [
            ImuSample {
                seq: 0,
                status: 0,
                rate_rad_s: [0.0; 3],
                accel_mps2: [-0.0; 3],
            },
            ImuSample {
                seq: u64::MAX,
                status: 0xA55A,
                rate_rad_s: [1.5e-3, -2.25e-7, f32::MAX],
                accel_mps2: [9.80665, f32::NAN, -f32::INFINITY],
            },
            ImuSample {
                seq: 0x0102_0304_0506_0708,
                status: 1,
                rate_rad_s: [f32::MIN_POSITIVE, 3.0, -4.0],
                accel_mps2: [1e-40, 0.1, -0.2],
            },
        ];
        for sample in &samples {
            for prefix in [0, 4, 5] {
                let mut ours = vec![0xEE; prefix];
                sample.write_cdr(&mut ours).unwrap();
                let mut serde = vec![0xEE; prefix];
                let mut ser = re_cdr::CdrSerializer::<re_cdr::LittleEndian>::new(&mut serde);
                sample.serialize(&mut ser).unwrap();
                assert_eq!(ours, serde, "{sample:?} behind {prefix} bytes");
                assert_eq!(ours.len(), prefix + IMU_SAMPLE_CDR_BYTES);
            }
        }
    }

    #[test]
    fn dependency_sections_are_separated_as_ros2_bags_write_them() {
        assert!(NavSatFix::DEFINITION.contains(&format!("{SEPARATOR}MSG: std_msgs/Header\n")));
        assert_eq!(PoseStamped::DEFINITION.matches(SEPARATOR).count(), 5);
    }

    #[test]
    fn time_splits_negative_ns_into_a_negative_second_and_positive_nanoseconds() {
        assert_eq!(
            Time::from_ns(-1),
            Time {
                sec: -1,
                nanosec: 999_999_999
            }
        );
        assert_eq!(
            Time::from_ns(1_500_000_000),
            Time {
                sec: 1,
                nanosec: 500_000_000
            }
        );
    }
}
