//! Campaign simulator: field runs like the paper's, with exact truth.
//!
//! Motion is analytic ([`route`]); the kinematics (WGS-84 position, Earth rate, transport
//! rate, normal gravity, Coriolis) are integrated on a grid ten times finer than the IMU
//! with two-point Gauss–Legendre quadrature, so the increments are the exact integrals
//! of body rate and specific force to far below the sensor LSB. LN-200-class errors are
//! then added: constant gyro drifts, angle random walk, accelerometer biases, velocity
//! random walk, quantisation with the residue carried forward, odometer scale error and
//! pulse quantisation.

pub mod plan;
pub mod route;
pub mod sensor;

use nalgebra::{UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use crate::attitude::Euler;
use crate::earth::{self, Geodetic};
use crate::imu_axes::ImuAxes;
use crate::units::{DEG_PER_H, DEG_PER_SQRT_H, MILLI_G};
pub use sensor::{SensorMark, SensorSample, SensorSpec};

/// LN-200 angle random walk, rad/√s (0.07 °/√h).
pub const LN200_ARW_RAD_SQRT_S: f64 = 0.07 * DEG_PER_SQRT_H;
/// LN-200-class velocity random walk, (m/s)/√s (0.03 m/s/√h).
pub const LN200_VRW_MPS_SQRT_S: f64 = 0.03 / 60.0;

/// What errors the simulated sensors have.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SensorErrors {
    /// Random noise: angle and velocity random walk.
    pub noise: bool,
    /// Constant gyro drifts of 0.1–1 °/h per axis.
    pub gyro_drift: bool,
    /// Accelerometer biases of 0.1–0.5 mg per axis.
    pub accel_bias: bool,
    /// Odometer scale error of ±0.05–0.3 % (a calibrated vehicle odometer).
    pub odo_scale_error: bool,
}

impl SensorErrors {
    /// All errors on.
    pub const ALL: Self = Self {
        noise: true,
        gyro_drift: true,
        accel_bias: true,
        odo_scale_error: true,
    };
    /// Perfect sensors (quantisation only).
    pub const NONE: Self = Self {
        noise: false,
        gyro_drift: false,
        accel_bias: false,
        odo_scale_error: false,
    };
}

/// Simulation parameters of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// Run name.
    pub name: String,
    /// Random seed: same seed, same run, on every platform.
    pub seed: u64,
    /// Run length, s.
    pub duration_s: f64,
    /// Static start, s (≥ 60).
    pub static_s: f64,
    /// Sensor errors.
    pub errors: SensorErrors,
    /// Error of the manifest's azimuth, degrees; `None`: random, 4–8° either way.
    pub azimuth_error_deg: Option<f64>,
    /// Fine-grid steps per IMU sample.
    pub substeps: usize,
    /// Yaw of the IMU on the vehicle, degrees: the odometer's direction of travel is the
    /// IMU's x axis turned by it (clockwise seen from above), so the IMU's heading is the
    /// vehicle's minus it. Zero by default.
    pub odo_boresight_deg: f64,
    /// Pitch of the vehicle's path above the IMU's x axis, degrees (an IMU pitched nose
    /// down on its mount by it): what the disupt stage fits to the control points'
    /// heights. Zero by default.
    pub odo_pitch_deg: f64,
    /// Odometer lag, s: the count logged with IMU time t is the distance at t − lag (so
    /// derive's `odo_time_offset_s` should be −lag). Zero by default.
    pub odo_lag_s: f64,
    /// Every intermediate stop is on a control point too (default: a mid-route and the
    /// final stop only).
    pub cp_at_every_stop: bool,
    /// The log begins this far into the simulated run, s (logging restarted while
    /// driving): no static start, and the manifest's site, truth and settings are those
    /// of that moment. `None`: the log begins with the static start.
    pub log_start_s: Option<f64>,
    /// Where the vehicle's control-point mark lies from the navigated point (the
    /// odometer's, which the truth follows), in the IMU's body axes (x forward, y right,
    /// z down), m: each control point is surveyed under the mark, not under the
    /// navigated point. Zero by default.
    pub mark_lever_arm_m: [f64; 3],
    /// Drive the route out and back ([`plan::plan_out_and_back`]): every control point
    /// but the far one is visited twice, at the same place, and marked at each visit; the
    /// vehicle stands level at the start (no constant tilt). The navigated point stops over
    /// the point both ways, so the mark's lever arm must be zero.
    pub out_and_back: bool,
    /// The IMU's axes on the vehicle, as its log gives them (`"FRD"` by default): the
    /// counts are written in them, and the manifest names them in `[params.vehicle]
    /// imu_axes`.
    pub imu_axes: ImuAxes,
}

impl SimConfig {
    /// A 40-minute run with every error on.
    pub fn new(name: &str, seed: u64) -> Self {
        Self {
            name: name.to_owned(),
            seed,
            duration_s: 2400.0,
            static_s: 90.0,
            errors: SensorErrors::ALL,
            azimuth_error_deg: None,
            substeps: 10,
            odo_boresight_deg: 0.0,
            odo_pitch_deg: 0.0,
            odo_lag_s: 0.0,
            cp_at_every_stop: false,
            log_start_s: None,
            mark_lever_arm_m: [0.0; 3],
            out_and_back: false,
            imu_axes: ImuAxes::FRD,
        }
    }
}

/// The true settings and sensor errors of a simulated run.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrueSettings {
    /// True initial heading, degrees.
    pub azimuth_deg: f64,
    /// Heading written to the manifest (azpocz), degrees.
    pub manifest_azimuth_deg: f64,
    /// True initial pitch, degrees.
    pub pitch_deg: f64,
    /// True initial roll, degrees.
    pub roll_deg: f64,
    /// True gyro drifts (x, y, z), rad/s (measured = true + drift).
    pub drift_rad_s: [f64; 3],
    /// True accelerometer biases (x, y, z), m/s².
    pub accel_bias_mps2: [f64; 3],
    /// True metres per odometer pulse.
    pub odo_scale_m_per_pulse: f64,
    /// Nominal metres per pulse (the header's `odo_lsb_m`).
    pub nominal_odo_m_per_pulse: f64,
    /// Odometer yaw boresight, degrees (see [`SimConfig::odo_boresight_deg`]).
    #[serde(default)]
    pub odo_boresight_deg: f64,
    /// Odometer pitch boresight, degrees (see [`SimConfig::odo_pitch_deg`]).
    #[serde(default)]
    pub odo_pitch_deg: f64,
    /// Odometer lag, s (see [`SimConfig::odo_lag_s`]).
    #[serde(default)]
    pub odo_lag_s: f64,
    /// Angle random walk, rad/√s.
    pub arw_rad_sqrt_s: f64,
    /// Velocity random walk, (m/s)/√s.
    pub vrw_mps_sqrt_s: f64,
    /// Sensor errors switched on.
    pub errors: SensorErrors,
    /// Seed.
    pub seed: u64,
}

/// True state at the end of every IMU interval.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Truth {
    /// Time since the log's origin, ns.
    pub t_ns: Vec<i64>,
    /// Latitude, rad.
    pub lat_rad: Vec<f64>,
    /// Longitude, rad.
    pub lon_rad: Vec<f64>,
    /// Height, m.
    pub h_m: Vec<f64>,
    /// Velocity, NED, m/s.
    pub vel_ned_mps: Vec<[f64; 3]>,
    /// Attitude.
    pub euler: Vec<Euler>,
    /// Path length travelled, m.
    pub distance_m: Vec<f64>,
}

impl Truth {
    /// Drops the first `k` samples.
    fn drain_front(&mut self, k: usize) {
        self.t_ns.drain(..k);
        self.lat_rad.drain(..k);
        self.lon_rad.drain(..k);
        self.h_m.drain(..k);
        self.vel_ned_mps.drain(..k);
        self.euler.drain(..k);
        self.distance_m.drain(..k);
    }
}

/// The true position of the vehicle's mark at truth sample `k`: the navigated point's
/// moved by `arm_b_m` (body axes) turned into north, east and down by the IMU's true
/// attitude.
fn mark_position(truth: &Truth, k: usize, arm_b_m: &[f64; 3]) -> Geodetic {
    let (lat, lon, h) = (truth.lat_rad[k], truth.lon_rad[k], truth.h_m[k]);
    let ned = truth.euler[k].to_quat_b_to_n() * Vector3::from(*arm_b_m);
    let (rm, rn) = earth::radii_m(lat);
    Geodetic {
        lat_rad: lat + ned.x / (rm + h),
        lon_rad: lon + ned.y / ((rn + h) * lat.cos()),
        h_m: h - ned.z,
    }
}

/// A control point of the manifest.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimControlPoint {
    /// Id (also in the mark record).
    pub id: u32,
    /// Surveyed latitude, degrees.
    pub latitude_deg: f64,
    /// Surveyed longitude, degrees.
    pub longitude_deg: f64,
    /// Surveyed height, m.
    pub height_m: f64,
    /// Time of the mark, s since the log's origin.
    pub t_s: f64,
}

/// A complete simulated run, ready to be written.
#[derive(Debug, Clone)]
pub struct SimRun {
    /// Configuration it came from.
    pub config: SimConfig,
    /// The device's timing and count scales.
    pub sensor: SensorSpec,
    /// IMU samples in order.
    pub records: Vec<SensorSample>,
    /// Marks, each with the index of the IMU sample it follows.
    pub marks: Vec<(usize, SensorMark)>,
    /// Where the log starts (the manifest's site).
    pub site: Geodetic,
    /// Control points, one per mark (a point visited twice is here twice, with the same
    /// coordinates; the manifest lists it once).
    pub control_points: Vec<SimControlPoint>,
    /// Truth.
    pub truth: Truth,
    /// True settings.
    pub settings: TrueSettings,
    /// Static start given in the manifest, s (a margin below the true one).
    pub manifest_static_s: f64,
    /// Rest intervals (start, end), s.
    pub rests: Vec<(f64, f64)>,
}

/// Gauss–Legendre two-point nodes on [0, 1].
const GL2: [f64; 2] = [0.5 - 0.288_675_134_594_812_9, 0.5 + 0.288_675_134_594_812_9];

/// Body rate (inertial) and specific force, body axes, at time `t` and position `(lat, h)`,
/// and the velocity in NED. `c_v_b` turns the vehicle's axes into the IMU's (`None`: the
/// IMU is aligned with the vehicle).
fn body_rate_and_force(
    motion: &route::Motion,
    t: f64,
    lat: f64,
    h: f64,
    c_v_b: Option<&UnitQuaternion<f64>>,
) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
    let k = motion.at(t);
    let q = k.euler.to_quat_b_to_n();
    let w_nb_b =
        k.euler
            .body_rate_from_euler_rates(k.euler_rates[0], k.euler_rates[1], k.euler_rates[2]);
    let v_b = Vector3::new(k.speed_mps, 0.0, 0.0);
    let v_n = q * v_b;
    let dv_n = q * (Vector3::new(k.accel_mps2, 0.0, 0.0) + w_nb_b.cross(&v_b));
    let w_ie_n = earth::earth_rate_ned(lat);
    let w_en_n = earth::transport_rate_ned(lat, h, &v_n);
    let g_n = Vector3::new(0.0, 0.0, earth::normal_gravity_mps2(lat, h));
    let f_n = dv_n + (2.0 * w_ie_n + w_en_n).cross(&v_n) - g_n;
    let qi = q.inverse();
    let (w_ib_v, f_v) = (w_nb_b + qi * (w_ie_n + w_en_n), qi * f_n);
    match c_v_b {
        Some(c) => (c * w_ib_v, c * f_v, v_n),
        None => (w_ib_v, f_v, v_n),
    }
}

/// The IMU's attitude on a vehicle with attitude `vehicle` (see [`body_rate_and_force`]).
fn imu_euler(vehicle: Euler, c_v_b: Option<&UnitQuaternion<f64>>) -> Euler {
    match c_v_b {
        Some(c) => Euler::from_quat_b_to_n(&(vehicle.to_quat_b_to_n() * c.inverse())),
        None => vehicle,
    }
}

/// Simulates one run.
pub fn simulate(config: &SimConfig) -> SimRun {
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
    let lat0_deg: f64 = rng.random_range(49.0..54.5);
    let lon0_deg: f64 = rng.random_range(14.5..24.0);
    let h0: f64 = rng.random_range(80.0..300.0);
    let heading0 = rng.random_range(0.0..std::f64::consts::TAU);
    let plan_with = if config.out_and_back {
        plan::plan_out_and_back
    } else {
        plan::plan_route
    };
    let mut plan = plan_with(
        &mut rng,
        config.duration_s,
        config.static_s,
        heading0,
        config.cp_at_every_stop,
    );
    // The vehicle stands and drives slightly tilted (parking slope, road camber); not
    // on a route driven back, whose grades change sign with the direction of travel.
    let tilt_rad: [f64; 2] = std::array::from_fn(|_| rng.random_range(-0.6f64..0.6).to_radians());
    if !config.out_and_back {
        [plan.motion.pitch0_rad, plan.motion.roll0_rad] = tilt_rad;
    }
    let e = config.errors;
    let mut uniform_signed =
        |lo: f64, hi: f64| rng.random_range(lo..hi) * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    let drift: [f64; 3] = std::array::from_fn(|_| uniform_signed(0.1, 1.0) * DEG_PER_H);
    let bias: [f64; 3] = std::array::from_fn(|_| uniform_signed(0.1, 0.5) * MILLI_G);
    let odo_err = uniform_signed(0.0005, 0.003);
    let az_err = uniform_signed(4.0, 8.0);
    let drift = if e.gyro_drift { drift } else { [0.0; 3] };
    let bias = if e.accel_bias { bias } else { [0.0; 3] };
    let header = SensorSpec::unz50(
        1_780_000_000_000_000 + (config.seed % 1000) as i64 * 86_400_000_000,
        "LN200-SIM",
    );
    let true_m_per_pulse = header.odo_lsb_m
        * if e.odo_scale_error {
            1.0 + odo_err
        } else {
            1.0
        };
    let az_err = config.azimuth_error_deg.unwrap_or(az_err);

    let dt = header.sample_period_s();
    let n = (config.duration_s / dt).round() as usize;
    let sub = config.substeps.max(1);
    let h_f = dt / sub as f64;
    let (mut lat, mut lon, mut h) = (lat0_deg.to_radians(), lon0_deg.to_radians(), h0);
    let mut distance = 0.0;
    let mut cum_theta = Vector3::<f64>::zeros();
    let mut cum_vel = Vector3::<f64>::zeros();
    let mut counts_theta = [0i64; 3];
    let mut counts_vel = [0i64; 3];
    // Zero-mean normal noise of these σ per sample (what `Normal` draws, without its
    // fallible constructor).
    let (arw, vrw) = (
        LN200_ARW_RAD_SQRT_S * dt.sqrt(),
        LN200_VRW_MPS_SQRT_S * dt.sqrt(),
    );
    let mut records = Vec::with_capacity(n);
    let mut truth = Truth::default();
    let motion = &plan.motion;
    // The vehicle's x seen from the IMU: turned by the yaw boresight, climbing by the
    // pitch one ((cos p cos y, cos p sin y, −sin p)).
    let c_v_b = (config.odo_boresight_deg != 0.0 || config.odo_pitch_deg != 0.0).then(|| {
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), config.odo_boresight_deg.to_radians())
            * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), config.odo_pitch_deg.to_radians())
    });
    for k in 0..n {
        let t_start = k as f64 * dt;
        let mut dtheta = Vector3::zeros();
        let mut dvel = Vector3::zeros();
        for j in 0..sub {
            let a = t_start + j as f64 * h_f;
            let mut dpos = Vector3::zeros();
            for node in GL2 {
                let t = a + node * h_f;
                let (w, f, v_n) = body_rate_and_force(motion, t, lat, h, c_v_b.as_ref());
                dtheta += w * (0.5 * h_f);
                dvel += f * (0.5 * h_f);
                dpos += v_n * (0.5 * h_f);
                distance += motion.accel.integral(t) * 0.5 * h_f;
            }
            let lat_mid = lat + 0.5 * dpos.x / (earth::meridian_radius_m(lat) + h);
            let h_mid = h - 0.5 * dpos.z;
            let (rm, rn) = earth::radii_m(lat_mid);
            lat += dpos.x / (rm + h_mid);
            lon += dpos.y / ((rn + h_mid) * lat_mid.cos());
            h -= dpos.z;
        }
        // Sensor errors, then quantisation with the residue carried forward.
        dtheta += Vector3::from(drift) * dt;
        dvel += Vector3::from(bias) * dt;
        if e.noise {
            for i in 0..3 {
                dtheta[i] += arw * rng.sample::<f64, _>(StandardNormal);
                dvel[i] += vrw * rng.sample::<f64, _>(StandardNormal);
            }
        }
        cum_theta += dtheta;
        cum_vel += dvel;
        let mut rec_theta = [0i32; 3];
        let mut rec_vel = [0i32; 3];
        for i in 0..3 {
            let ct = (cum_theta[i] / header.dtheta_lsb_rad).round() as i64;
            let cv = (cum_vel[i] / header.dvel_lsb_mps).round() as i64;
            rec_theta[i] = (ct - counts_theta[i]) as i32;
            rec_vel[i] = (cv - counts_vel[i]) as i32;
            counts_theta[i] = ct;
            counts_vel[i] = cv;
        }
        let t_end = (k + 1) as f64 * dt;
        let t_us = (k as u64 + 1) * u64::from(header.sample_period_us);
        records.push(SensorSample {
            seq: k as u32,
            t_us,
            dtheta_counts: config.imu_axes.to_log(rec_theta),
            dvel_counts: config.imu_axes.to_log(rec_vel),
            odo_count: 0, // below, from the truth's distance (and the odometer's lag)
            status: 0,
        });
        let kin = motion.at(t_end);
        truth.t_ns.push(t_us as i64 * 1000);
        truth.lat_rad.push(lat);
        truth.lon_rad.push(lon);
        truth.h_m.push(h);
        let v_n = kin.euler.to_quat_b_to_n() * Vector3::new(kin.speed_mps, 0.0, 0.0);
        truth.vel_ned_mps.push([v_n.x, v_n.y, v_n.z]);
        let imu = imu_euler(kin.euler, c_v_b.as_ref());
        truth.euler.push(Euler {
            heading_rad: imu.heading_rad.rem_euclid(std::f64::consts::TAU),
            ..imu
        });
        truth.distance_m.push(distance);
    }

    // The odometer logs, with IMU time t, the distance at t − lag (exactly the truth's
    // distance at t without a lag). `x` counts samples: truth.distance_m[k] is at x = k.
    let distance_at = |x: f64| {
        if x < 0.0 {
            return truth.distance_m[0] * (x + 1.0).max(0.0);
        }
        let k = (x.floor() as usize).min(n - 1);
        let next = truth.distance_m[(k + 1).min(n - 1)];
        truth.distance_m[k] + (next - truth.distance_m[k]) * (x - k as f64)
    };
    for (k, r) in records.iter_mut().enumerate() {
        let x = k as f64 - config.odo_lag_s / dt;
        r.odo_count = (distance_at(x) / true_m_per_pulse).floor() as u64 as u32;
    }

    // Control points at the planned stops, marked 5 s into the stop.
    let mut marks = Vec::new();
    let mut control_points = Vec::new();
    for stop in &plan.stops {
        let t_mark = (stop.start_s + 5.0).min(config.duration_s - dt);
        let k = ((t_mark / dt).round() as usize).clamp(1, n) - 1;
        marks.push((
            k,
            SensorMark {
                t_us: records[k].t_us,
                point_id: stop.id,
            },
        ));
        // A point visited again keeps where it was surveyed at its first visit.
        let surveyed = control_points
            .iter()
            .find(|c: &&SimControlPoint| c.id == stop.id)
            .map(|c| (c.latitude_deg, c.longitude_deg, c.height_m));
        let under_mark = mark_position(&truth, k, &config.mark_lever_arm_m);
        let (latitude_deg, longitude_deg, height_m) = surveyed.unwrap_or((
            under_mark.lat_rad.to_degrees(),
            under_mark.lon_rad.to_degrees(),
            under_mark.h_m,
        ));
        control_points.push(SimControlPoint {
            id: stop.id,
            latitude_deg,
            longitude_deg,
            height_m,
            t_s: records[k].t_us as f64 * 1e-6,
        });
    }
    // A log that begins in motion: drop what came before; the site and the true initial
    // settings are those at the start of the first record kept.
    let k0 = config
        .log_start_s
        .map_or(0, |s| ((s / dt).round() as usize).min(n - 1));
    let mut site = Geodetic::from_deg(lat0_deg, lon0_deg, h0);
    if k0 > 0 {
        site = Geodetic {
            lat_rad: truth.lat_rad[k0 - 1],
            lon_rad: truth.lon_rad[k0 - 1],
            h_m: truth.h_m[k0 - 1],
        };
        records.drain(..k0);
        truth.drain_front(k0);
        let kept: Vec<bool> = marks.iter().map(|(k, _)| *k >= k0).collect();
        marks.retain(|(k, _)| *k >= k0);
        for (k, _) in &mut marks {
            *k -= k0;
        }
        let mut keep = kept.into_iter();
        control_points.retain(|_| keep.next().unwrap_or(false));
    }
    let e0 = imu_euler(motion.at(k0 as f64 * dt).euler, c_v_b.as_ref());
    let azimuth_deg = e0.heading_rad.to_degrees().rem_euclid(360.0);
    SimRun {
        config: config.clone(),
        sensor: header,
        records,
        marks,
        site,
        control_points,
        truth,
        settings: TrueSettings {
            azimuth_deg,
            manifest_azimuth_deg: (azimuth_deg + az_err).rem_euclid(360.0),
            pitch_deg: e0.pitch_rad.to_degrees(),
            roll_deg: e0.roll_rad.to_degrees(),
            drift_rad_s: drift,
            accel_bias_mps2: bias,
            odo_scale_m_per_pulse: true_m_per_pulse,
            nominal_odo_m_per_pulse: 0.0125,
            odo_boresight_deg: config.odo_boresight_deg,
            odo_pitch_deg: config.odo_pitch_deg,
            odo_lag_s: config.odo_lag_s,
            arw_rad_sqrt_s: if e.noise { LN200_ARW_RAD_SQRT_S } else { 0.0 },
            vrw_mps_sqrt_s: if e.noise { LN200_VRW_MPS_SQRT_S } else { 0.0 },
            errors: e,
            seed: config.seed,
        },
        manifest_static_s: if k0 > 0 { 0.0 } else { config.static_s - 5.0 },
        rests: plan.rests,
    }
}

impl SimRun {
    /// The run manifest (`run.toml`) text for a raw log named `raw_file`.
    pub fn manifest_toml(&self, name: &str, raw_file: &str) -> String {
        let mut s = format!(
            "# Simulated by unz (seed {seed}). The azimuth below is the alignment's, off by\n\
             # several degrees; the true settings are in truth.parquet's metadata.\n\
             name = \"{name}\"\nraw = \"{raw_file}\"\nformat = \"unz-binary\"\n\n\
             [site]\nlatitude_deg = {lat:.9}\nlongitude_deg = {lon:.9}\nheight_m = {h:.3}\n\n\
             [initial]\nazimuth_deg = {az:.6}\nstatic_s = {st:.1}\n",
            seed = self.config.seed,
            lat = self.site.lat_rad.to_degrees(),
            lon = self.site.lon_rad.to_degrees(),
            h = self.site.h_m,
            az = self.settings.manifest_azimuth_deg,
            st = self.manifest_static_s,
        );
        let arm = self.config.mark_lever_arm_m;
        let axes = self.config.imu_axes;
        if arm != [0.0; 3] || !axes.is_frd() {
            s += "\n[params.vehicle]\n";
        }
        if arm != [0.0; 3] {
            s += &format!("mark_lever_arm_m = [{}, {}, {}]\n", arm[0], arm[1], arm[2]);
        }
        if !axes.is_frd() {
            s += &format!("imu_axes = \"{axes}\"\n");
        }
        let mut listed = std::collections::BTreeSet::new();
        for cp in self.control_points.iter().filter(|c| listed.insert(c.id)) {
            s += &format!(
                "\n[[control_point]]\nid = {}\nlatitude_deg = {:.9}\nlongitude_deg = {:.9}\nheight_m = {:.3}\n",
                cp.id, cp.latitude_deg, cp.longitude_deg, cp.height_m
            );
        }
        s
    }

    /// Index of the truth sample nearest to `t_s`.
    pub fn truth_index(&self, t_s: f64) -> usize {
        let dt = self.sensor.sample_period_s();
        ((t_s / dt).round() as usize).clamp(1, self.truth.t_ns.len()) - 1
    }
}
