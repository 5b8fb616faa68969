//! The UNZ algorithm: odometer-aided strapdown dead reckoning.
//!
//! Inputs are per-sample slices (sample `k` covers the interval ending at `t_k`), the
//! output a [`NavTrack`] the caller owns and reuses: the kernel allocates nothing, so an
//! optimiser can call it hundreds of times.
//!
//! Per sample:
//! 1. body rotation vector `φ = Δθ' + (Δθ'_{k−1} × Δθ'_k)/12` with `Δθ' = Δθ − drift·Δt`
//!    (the drift is subtracted from the measured rate; the coning term is exact for a
//!    linearly varying rate);
//! 2. the odometer increment, times the scale setting, is resolved along body x with the
//!    attitude at the middle of the interval and accumulated on WGS-84 (lat, lon, h);
//! 3. the navigation frame's rotation `ζ = (ω_ie^n + ω_en^n)·Δt` at the mid-interval
//!    position is removed: `q ← q(ζ)* ⊗ q ⊗ q(φ)`.
//!
//! Splitting the update into a body factor and a navigation-frame factor is exact
//! (`Ċ = C[ω_ib×] − [ω_in×]C` has the solution `L·C₀·R`), so no commutation error builds up.

use nalgebra::{UnitQuaternion, Vector3};

use crate::attitude::{Euler, quat_from_rotation_vector};
use crate::earth;

/// Per-sample navigation inputs; all slices have the same length.
#[derive(Debug, Clone, Copy)]
pub struct NavInputs<'a> {
    /// Length of each sample's interval, s.
    pub dt_s: &'a [f64],
    /// Angle increments, rad, body FRD.
    pub dtheta_rad: &'a [[f64; 3]],
    /// Odometer distance travelled over each interval at the nominal scale, m.
    pub odo_dist_m: &'a [f64],
}

impl NavInputs<'_> {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.dt_s.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.dt_s.is_empty()
    }
}

/// Initial settings and constants of one navigation pass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavSettings {
    /// Initial attitude; its heading is azpocz.
    pub initial: Euler,
    /// Gyro drifts (x, y, z body), rad/s, subtracted from the measured rates.
    pub drift_rad_s: [f64; 3],
    /// Multiplier applied to the odometer distance (1 = as given).
    pub odo_scale: f64,
    /// Odometer-to-body yaw boresight, rad: the odometer direction is body x turned by it.
    pub odo_yaw_rad: f64,
    /// Start latitude, rad.
    pub lat0_rad: f64,
    /// Start longitude, rad.
    pub lon0_rad: f64,
    /// Start height, m.
    pub h0_m: f64,
}

/// The navigated track, one entry per sample (the state at the end of its interval).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct NavTrack {
    /// Latitude, rad.
    pub lat_rad: Vec<f64>,
    /// Longitude, rad.
    pub lon_rad: Vec<f64>,
    /// Height, m.
    pub h_m: Vec<f64>,
    /// Roll Φ_N, rad.
    pub roll_rad: Vec<f64>,
    /// Pitch Θ_N, rad.
    pub pitch_rad: Vec<f64>,
    /// Heading, rad in [0, 2π).
    pub heading_rad: Vec<f64>,
    /// Travelled distance (scaled odometer), m.
    pub distance_m: Vec<f64>,
}

impl NavTrack {
    /// Sizes every column to `n` (allocates only when growing).
    pub fn resize(&mut self, n: usize) {
        for v in [
            &mut self.lat_rad,
            &mut self.lon_rad,
            &mut self.h_m,
            &mut self.roll_rad,
            &mut self.pitch_rad,
            &mut self.heading_rad,
            &mut self.distance_m,
        ] {
            v.resize(n, 0.0);
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.lat_rad.len()
    }

    /// Whether the track is empty.
    pub fn is_empty(&self) -> bool {
        self.lat_rad.is_empty()
    }
}

/// Runs the navigation over all samples, writing `track` (resized to the input length).
pub fn navigate(inputs: &NavInputs<'_>, s: &NavSettings, track: &mut NavTrack) {
    let n = inputs.len();
    track.resize(n);
    let drift = Vector3::from(s.drift_rad_s);
    let odo_dir_b = Vector3::new(s.odo_yaw_rad.cos(), s.odo_yaw_rad.sin(), 0.0);
    let mut q: UnitQuaternion<f64> = s.initial.to_quat_b_to_n();
    let (mut lat, mut lon, mut h) = (s.lat0_rad, s.lon0_rad, s.h0_m);
    let mut distance = 0.0;
    let mut prev = Vector3::zeros();
    for k in 0..n {
        let dt = inputs.dt_s[k];
        let dth = Vector3::from(inputs.dtheta_rad[k]) - drift * dt;
        let phi = dth + prev.cross(&dth) / 12.0;
        prev = dth;
        let q_body = q * quat_from_rotation_vector(&phi);

        // Odometer dead reckoning along the mid-interval direction of travel.
        let ds = s.odo_scale * inputs.odo_dist_m[k];
        let dir_n = (q * odo_dir_b + q_body * odo_dir_b) * 0.5;
        let dp_n = dir_n * ds;
        let lat_mid = lat + 0.5 * dp_n.x / (earth::meridian_radius_m(lat) + h);
        let h_mid = h - 0.5 * dp_n.z;
        let (rm, rn) = earth::radii_m(lat_mid);
        lat += dp_n.x / (rm + h_mid);
        lon += dp_n.y / ((rn + h_mid) * lat_mid.cos());
        h -= dp_n.z;
        distance += ds;

        // Navigation-frame rotation over the interval, at the mid-interval state.
        let zeta = if dt > 0.0 {
            let v_n = dp_n / dt;
            (earth::earth_rate_ned(lat_mid) + earth::transport_rate_ned(lat_mid, h_mid, &v_n)) * dt
        } else {
            Vector3::zeros()
        };
        q = quat_from_rotation_vector(&(-zeta)) * q_body;
        q.renormalize_fast();

        let e = Euler::from_quat_b_to_n(&q);
        track.lat_rad[k] = lat;
        track.lon_rad[k] = lon;
        track.h_m[k] = h;
        track.roll_rad[k] = e.roll_rad;
        track.pitch_rad[k] = e.pitch_rad;
        track.heading_rad[k] = e.heading_rad;
        track.distance_m[k] = distance;
    }
}
