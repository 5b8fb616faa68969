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

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

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
/// Attitude is kept as the quaternion `C_b^n`; Euler angles are derived on demand, so
/// the kernel spends no transcendental functions on outputs nobody reads.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct NavTrack {
    /// Latitude, rad.
    pub lat_rad: Vec<f64>,
    /// Longitude, rad.
    pub lon_rad: Vec<f64>,
    /// Height, m.
    pub h_m: Vec<f64>,
    /// Attitude quaternion `C_b^n` as (w, x, y, z).
    pub q_b_to_n: Vec<[f64; 4]>,
    /// Travelled distance (scaled odometer), m.
    pub distance_m: Vec<f64>,
}

/// Roll (atan2(C32, C33)) and pitch (−asin C31) from the third row of `C_b^n`, given up
/// to a positive scale (a sum of rows works as well as their mean).
#[inline]
pub fn roll_pitch_from_row3(c31: f64, c32: f64, c33: f64) -> (f64, f64) {
    (c32.atan2(c33), (-c31).atan2(c32.hypot(c33)))
}

/// The third row of `C_b^n` of a quaternion (w, x, y, z).
#[inline]
pub fn dcm_row3(q: &[f64; 4]) -> [f64; 3] {
    let [w, x, y, z] = *q;
    [
        2.0 * (x * z - w * y),
        2.0 * (y * z + w * x),
        w * w - x * x - y * y + z * z,
    ]
}

impl NavTrack {
    /// Sizes every column to `n` (allocates only when growing).
    pub fn resize(&mut self, n: usize) {
        for v in [
            &mut self.lat_rad,
            &mut self.lon_rad,
            &mut self.h_m,
            &mut self.distance_m,
        ] {
            v.resize(n, 0.0);
        }
        self.q_b_to_n.resize(n, [1.0, 0.0, 0.0, 0.0]);
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.lat_rad.len()
    }

    /// Whether the track is empty.
    pub fn is_empty(&self) -> bool {
        self.lat_rad.is_empty()
    }

    /// Euler angles of sample `k`.
    pub fn euler(&self, k: usize) -> Euler {
        let [w, x, y, z] = self.q_b_to_n[k];
        Euler::from_quat_b_to_n(&UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(
            w, x, y, z,
        )))
    }

    /// Euler angles of every sample: (roll, pitch, heading) columns, rad.
    pub fn euler_columns(&self) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let mut out = (
            Vec::with_capacity(self.len()),
            Vec::with_capacity(self.len()),
            Vec::with_capacity(self.len()),
        );
        for k in 0..self.len() {
            let e = self.euler(k);
            out.0.push(e.roll_rad);
            out.1.push(e.pitch_rad);
            out.2.push(e.heading_rad);
        }
        out
    }
}

/// Latitude-dependent terms, refreshed when the latitude moves by more than
/// [`LAT_REFRESH_RAD`] (6 m): their change below that is under 1e-8 relative.
#[derive(Clone, Copy)]
struct LatTerms {
    lat: f64,
    rm: f64,
    rn: f64,
    inv_cos: f64,
    tan: f64,
    w_ie_n: Vector3<f64>,
}

/// Latitude change that refreshes [`LatTerms`], rad.
const LAT_REFRESH_RAD: f64 = 1e-6;

impl LatTerms {
    fn at(lat: f64) -> Self {
        let (rm, rn) = earth::radii_m(lat);
        Self {
            lat,
            rm,
            rn,
            inv_cos: 1.0 / lat.cos(),
            tan: lat.tan(),
            w_ie_n: earth::earth_rate_ned(lat),
        }
    }
}

/// What a pass does with each sample's state.
pub trait PassSink {
    /// Sample `k`: position (rad, rad, m), attitude quaternion `[w, x, y, z]` of `C_b^n`
    /// and odometer distance so far (m).
    fn sample(&mut self, k: usize, lat: f64, lon: f64, h: f64, q: &[f64; 4], distance_m: f64);
}

impl PassSink for NavTrack {
    #[inline(always)]
    fn sample(&mut self, k: usize, lat: f64, lon: f64, h: f64, q: &[f64; 4], distance_m: f64) {
        self.lat_rad[k] = lat;
        self.lon_rad[k] = lon;
        self.h_m[k] = h;
        self.q_b_to_n[k] = *q;
        self.distance_m[k] = distance_m;
    }
}

/// Runs the navigation over all samples, writing `track` (resized to the input length).
pub fn navigate(inputs: &NavInputs<'_>, s: &NavSettings, track: &mut NavTrack) {
    track.resize(inputs.len());
    run(inputs, s, track);
}

/// Sums of the third row of `C_b^n` per block of `block` samples, and the positions at
/// chosen samples: all that the criteria read from a pass, without storing the track.
#[derive(Debug, Clone, Default)]
pub struct CriteriaSink {
    /// Samples per block.
    pub block: usize,
    /// Per block: the sum of the samples' third rows of `C_b^n`.
    pub row3_sums: Vec<[f64; 3]>,
    /// (sample, latitude rad, longitude rad) at the requested samples, in sample order.
    pub positions: Vec<(usize, f64, f64)>,
    wanted: Vec<usize>,
    acc: [f64; 3],
    in_block: usize,
}

impl CriteriaSink {
    /// Clears the sink for a pass with blocks of `block` samples, recording the positions
    /// at `samples`.
    pub fn reset(&mut self, block: usize, samples: impl IntoIterator<Item = usize>) {
        self.block = block.max(1);
        self.row3_sums.clear();
        self.positions.clear();
        self.wanted.clear();
        self.wanted.extend(samples);
        self.wanted.sort_unstable();
        self.wanted.dedup();
        self.wanted.reverse(); // popped from the end, in sample order
        self.acc = [0.0; 3];
        self.in_block = 0;
    }

    /// Closes the last, partial block.
    pub fn finish(&mut self) {
        if self.in_block > 0 {
            self.row3_sums.push(self.acc);
            self.acc = [0.0; 3];
            self.in_block = 0;
        }
    }

    /// Latitude and longitude recorded at `sample`.
    pub fn position_at(&self, sample: usize) -> Option<(f64, f64)> {
        self.positions
            .binary_search_by_key(&sample, |p| p.0)
            .ok()
            .map(|i| (self.positions[i].1, self.positions[i].2))
    }
}

impl PassSink for CriteriaSink {
    #[inline(always)]
    fn sample(&mut self, k: usize, lat: f64, lon: f64, _h: f64, q: &[f64; 4], _d: f64) {
        let r = dcm_row3(q);
        self.acc = [self.acc[0] + r[0], self.acc[1] + r[1], self.acc[2] + r[2]];
        self.in_block += 1;
        if self.in_block == self.block {
            self.row3_sums.push(self.acc);
            self.acc = [0.0; 3];
            self.in_block = 0;
        }
        if self.wanted.last() == Some(&k) {
            self.wanted.pop();
            self.positions.push((k, lat, lon));
        }
    }
}

/// The state of one pass between samples.
#[derive(Clone, Copy)]
struct Lane {
    drift: Vector3<f64>,
    odo_scale: f64,
    odo_sin: f64,
    odo_cos: f64,
    q: Quaternion<f64>,
    lat: f64,
    lon: f64,
    h: f64,
    terms: LatTerms,
    distance: f64,
    prev: Vector3<f64>,
    dir_start: Vector3<f64>,
}

impl Lane {
    fn new(s: &NavSettings) -> Self {
        let (odo_sin, odo_cos) = s.odo_yaw_rad.sin_cos();
        let mut lane = Self {
            drift: Vector3::from(s.drift_rad_s),
            odo_scale: s.odo_scale,
            odo_sin,
            odo_cos,
            q: s.initial.to_quat_b_to_n().into_inner(),
            lat: s.lat0_rad,
            lon: s.lon0_rad,
            h: s.h0_m,
            terms: LatTerms::at(s.lat0_rad),
            distance: 0.0,
            prev: Vector3::zeros(),
            dir_start: Vector3::zeros(),
        };
        lane.dir_start = lane.odo_dir_n(&lane.q);
        lane
    }

    /// Direction of the odometer axis (body x turned by the boresight) in NED: the first
    /// two columns of C_b^n, without a full vector rotation.
    #[inline(always)]
    fn odo_dir_n(&self, q: &Quaternion<f64>) -> Vector3<f64> {
        let (w, x, y, z) = (q.w, q.i, q.j, q.k);
        let c1 = Vector3::new(
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y + w * z),
            2.0 * (x * z - w * y),
        );
        if self.odo_sin == 0.0 {
            return c1;
        }
        let c2 = Vector3::new(
            2.0 * (x * y - w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z + w * x),
        );
        c1 * self.odo_cos + c2 * self.odo_sin
    }

    /// Advances over sample `k` (interval `dt`, angle increments, odometer distance).
    #[inline(always)]
    fn step(&mut self, k: usize, dt: f64, dtheta: &[f64; 3], odo: f64) {
        let dth = Vector3::from(*dtheta) - self.drift * dt;
        let phi = dth + self.prev.cross(&dth) * (1.0 / 12.0);
        self.prev = dth;
        let q_body = self.q * quat_from_rotation_vector(&phi).into_inner();

        // Odometer dead reckoning along the mid-interval direction of travel.
        let ds = self.odo_scale * odo;
        let dir_end = self.odo_dir_n(&q_body);
        let dp_n = (self.dir_start + dir_end) * (0.5 * ds);
        if (self.lat - self.terms.lat).abs() > LAT_REFRESH_RAD {
            self.terms = LatTerms::at(self.lat);
        }
        let terms = &self.terms;
        let inv_rm_h = 1.0 / (terms.rm + self.h - 0.5 * dp_n.z);
        let inv_rn_h = 1.0 / (terms.rn + self.h - 0.5 * dp_n.z);
        self.lat += dp_n.x * inv_rm_h;
        self.lon += dp_n.y * inv_rn_h * terms.inv_cos;
        self.h -= dp_n.z;
        self.distance += ds;

        // Navigation-frame rotation over the interval (Earth rate plus transport rate),
        // ζ ~ 1e-6 rad: its quaternion (1, −ζ/2) is exact to ζ²/8 ~ 1e-13.
        let zeta = Vector3::new(
            terms.w_ie_n.x * dt + dp_n.y * inv_rn_h,
            -dp_n.x * inv_rm_h,
            terms.w_ie_n.z * dt - dp_n.y * terms.tan * inv_rn_h,
        );
        // (1, v) ⊗ (w, u) = (w − v·u, u + w·v + v × u) with v = −ζ/2.
        let v = zeta * -0.5;
        let u = q_body.imag();
        let w = q_body.w;
        let qv = u + v * w + v.cross(&u);
        self.q = Quaternion::new(w - v.dot(&u), qv.x, qv.y, qv.z);
        if k % 64 == 63 {
            self.q /= self.q.norm();
        }
        // The navigation frame turned by ζ: the next start direction is the end direction
        // seen from the new frame, exact to ζ² ~ 1e-12.
        self.dir_start = dir_end - zeta.cross(&dir_end);
    }

    #[inline(always)]
    fn emit(&self, k: usize, sink: &mut impl PassSink) {
        let q = &self.q;
        sink.sample(
            k,
            self.lat,
            self.lon,
            self.h,
            &[q.w, q.i, q.j, q.k],
            self.distance,
        );
    }
}

/// Runs the navigation over all samples into `sink`.
pub fn run(inputs: &NavInputs<'_>, s: &NavSettings, sink: &mut impl PassSink) {
    let mut lane = Lane::new(s);
    let samples = inputs
        .dt_s
        .iter()
        .zip(inputs.dtheta_rad)
        .zip(inputs.odo_dist_m);
    for (k, ((&dt, dtheta), &odo)) in samples.enumerate() {
        lane.step(k, dt, dtheta, odo);
        lane.emit(k, sink);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Regression: block means summed the third rows and took asin of the sum.
    #[test]
    fn roll_pitch_from_a_sum_of_rows_equals_the_mean_angles() {
        let e = Euler {
            roll_rad: 0.03,
            pitch_rad: -0.02,
            heading_rad: 2.0,
        };
        let q = e.to_quat_b_to_n();
        let r = dcm_row3(&[q.w, q.i, q.j, q.k]);
        let (roll, pitch) = roll_pitch_from_row3(10.0 * r[0], 10.0 * r[1], 10.0 * r[2]);
        assert!(
            (roll - 0.03).abs() < 1e-14 && (pitch + 0.02).abs() < 1e-14,
            "{roll} {pitch}"
        );
    }
}
