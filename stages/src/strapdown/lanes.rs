//! The kernel's state for `N` passes stepped side by side, one lane per pass, as a
//! structure of arrays: every per-lane loop is branch-free arithmetic over `[f64; N]`,
//! which the compiler turns into vector instructions. A lane computes exactly what a
//! pass alone computes (the same operations in the same order; Rust never fuses them),
//! so a batch of passes and the passes one by one agree bit for bit.

// Lane loops index several arrays by the lane: an index is clearer than zipped iterators.
#![allow(clippy::needless_range_loop)]

use super::{LAT_REFRESH_RAD, NavInputs, NavSettings};
use crate::angle_increments::Increment3;
use crate::attitude::{HALF_ANGLE_SERIES_LIMIT_RAD2, half_angle_exact, half_angle_series};
use crate::earth;

/// Samples between renormalisations of the attitude quaternion.
const RENORMALISE_EVERY: usize = 64;

/// Each lane's odometer increments.
pub(super) trait OdometerLanes<const N: usize> {
    /// The samples of `inputs` the passes run over (those the odometer covers).
    fn samples(&self, inputs: &NavInputs<'_>) -> usize;

    /// Each lane's increment at sample `k`, m; called for `k` = 0, 1, … in turn.
    fn at(&mut self, k: usize, inputs: &NavInputs<'_>) -> [f64; N];
}

/// The samples of `inputs` with an angle increment and an interval.
fn imu_samples(inputs: &NavInputs<'_>) -> usize {
    inputs.dt_s.len().min(inputs.dtheta_rad.len())
}

/// Every lane on the inputs' odometer increments.
pub(super) struct SharedOdometer;

impl<const N: usize> OdometerLanes<N> for SharedOdometer {
    fn samples(&self, inputs: &NavInputs<'_>) -> usize {
        inputs.pass_samples()
    }

    #[inline(always)]
    fn at(&mut self, k: usize, inputs: &NavInputs<'_>) -> [f64; N] {
        [inputs.odo_dist_m[k]; N]
    }
}

/// Each lane on its own odometer increments (derives at other odometer timings: the IMU's
/// increments are the same), each at least as long as the inputs.
pub(super) struct OdometerPerLane<'a, const N: usize>(pub [&'a [f64]; N]);

impl<const N: usize> OdometerLanes<N> for OdometerPerLane<'_, N> {
    fn samples(&self, inputs: &NavInputs<'_>) -> usize {
        imu_samples(inputs)
    }

    #[inline(always)]
    fn at(&mut self, k: usize, _inputs: &NavInputs<'_>) -> [f64; N] {
        std::array::from_fn(|l| self.0[l][k])
    }
}

/// Each lane on its own odometer increments as an iterator yields them (read as the pass
/// goes), each at least as long as the inputs.
pub(super) struct OdometerStreams<I, const N: usize>(pub [I; N]);

impl<I: Iterator<Item = f64>, const N: usize> OdometerLanes<N> for OdometerStreams<I, N> {
    fn samples(&self, inputs: &NavInputs<'_>) -> usize {
        imu_samples(inputs)
    }

    #[inline(always)]
    fn at(&mut self, _k: usize, _inputs: &NavInputs<'_>) -> [f64; N] {
        std::array::from_fn(|l| self.0[l].next().unwrap_or(0.0))
    }
}

/// What a run does with the lanes' state after each sample.
pub(super) trait Emit<const N: usize> {
    /// After sample `k`.
    fn emit(&mut self, k: usize, lanes: &Lanes<N>);
}

/// State of `N` passes between samples.
#[derive(Clone, Copy)]
pub(super) struct Lanes<const N: usize> {
    drift_rad_s: [[f64; N]; 3],
    odo_scale: [f64; N],
    odo_bias_mps: [f64; N],
    odo_sin: [f64; N],
    odo_cos: [f64; N],
    /// tan of the odometer's pitch boresight.
    odo_tan_pitch: [f64; N],
    /// Whether any lane has an odometer boresight (yaw or pitch).
    boresight: bool,
    /// Attitude quaternion `C_b^n` (w, x, y, z).
    pub q: [[f64; N]; 4],
    /// Latitude, rad.
    pub lat_rad: [f64; N],
    /// Longitude, rad.
    pub lon_rad: [f64; N],
    /// Height, m.
    pub h_m: [f64; N],
    /// Scaled odometer distance so far, m.
    pub distance_m: [f64; N],
    /// Drift-corrected angle increment of the previous sample (coning term), rad.
    prev_rad: [[f64; N]; 3],
    /// Odometer direction in NED at the start of the next interval.
    dir_start: [[f64; N]; 3],
    terms: LatTerms<N>,
}

/// Latitude-dependent terms per lane, refreshed when the lane's latitude moves by more
/// than [`LAT_REFRESH_RAD`].
#[derive(Clone, Copy)]
pub(super) struct LatTerms<const N: usize> {
    pub(super) lat_rad: [f64; N],
    pub(super) rm_m: [f64; N],
    pub(super) rn_m: [f64; N],
    pub(super) inv_cos: [f64; N],
    pub(super) tan: [f64; N],
    /// Earth rate, north and down components (east is zero), rad/s.
    pub(super) w_ie_north_rad_s: [f64; N],
    pub(super) w_ie_down_rad_s: [f64; N],
}

impl<const N: usize> LatTerms<N> {
    /// Terms not set yet (zero).
    pub(super) const ZERO: Self = Self {
        lat_rad: [0.0; N],
        rm_m: [0.0; N],
        rn_m: [0.0; N],
        inv_cos: [0.0; N],
        tan: [0.0; N],
        w_ie_north_rad_s: [0.0; N],
        w_ie_down_rad_s: [0.0; N],
    };

    /// Sets lane `l` at latitude `lat`. The terms are computed out of line and returned
    /// by value, so that the state never escapes to memory in the hot loop.
    #[inline(always)]
    pub(super) fn set(&mut self, l: usize, lat: f64) {
        let [rm, rn, inv_cos, tan, w_north, w_down] = lat_terms(lat);
        self.lat_rad[l] = lat;
        self.rm_m[l] = rm;
        self.rn_m[l] = rn;
        self.inv_cos[l] = inv_cos;
        self.tan[l] = tan;
        self.w_ie_north_rad_s[l] = w_north;
        self.w_ie_down_rad_s[l] = w_down;
    }
}

/// (R_M, R_N, 1/cos, tan, Earth rate north, Earth rate down) at latitude `lat`.
#[cold]
#[inline(never)]
fn lat_terms(lat: f64) -> [f64; 6] {
    let (rm, rn) = earth::radii_m(lat);
    let w_ie = earth::earth_rate_ned(lat);
    [rm, rn, 1.0 / lat.cos(), lat.tan(), w_ie.x, w_ie.z]
}

/// Direction of the odometer axis in NED, per metre of the odometer's distance: body x
/// turned by the yaw boresight (`sin`/`cos` of it), from the columns of `C_b^n` of
/// (w, x, y, z), without a full rotation; its down component also climbs `tan_pitch`
/// along body −z (the pitch boresight moves the height alone: its horizontal part, of
/// the order of the angle times the body's pitch, is the odometer scale's, which the
/// horizontal fit took). With no boresight in any lane (`boresight` false) the first
/// column alone, which is what the full formula gives with sin 0, cos 1 and tan 0.
#[inline(always)]
fn odo_dir_n(q: [f64; 4], sin: f64, cos: f64, tan_pitch: f64, boresight: bool) -> [f64; 3] {
    let [w, x, y, z] = q;
    let c1 = [
        1.0 - 2.0 * (y * y + z * z),
        2.0 * (x * y + w * z),
        2.0 * (x * z - w * y),
    ];
    if !boresight {
        return c1;
    }
    let c2 = [
        2.0 * (x * y - w * z),
        1.0 - 2.0 * (x * x + z * z),
        2.0 * (y * z + w * x),
    ];
    let c33 = 1.0 - 2.0 * (x * x + y * y);
    [
        c1[0] * cos + c2[0] * sin,
        c1[1] * cos + c2[1] * sin,
        c1[2] * cos + c2[2] * sin - c33 * tan_pitch,
    ]
}

/// Samples whose turns a single pass takes together, ahead of its steps.
const AHEAD: usize = 4;

/// One pass's turns over [`AHEAD`] consecutive samples, one sample a lane: what the first
/// part of [`Lanes::step`] computes at each, in turn. The same arithmetic is written out
/// there over the lanes: one function for both left the four-lane loop 14 % slower
/// (`unz bench navigate`, from its code generation alone).
struct TurnsAhead {
    phi: [[f64; AHEAD]; 3],
    s: [f64; AHEAD],
    c: [f64; AHEAD],
    /// The drift-corrected increments.
    d: [[f64; AHEAD]; 3],
}

/// One sample's turn of a single pass, taken ahead: its rotation vector, sin(a/2)/a and
/// cos(a/2) of it, and the drift-corrected increment (the next sample's coning reads).
#[derive(Clone, Copy)]
struct Turn {
    phi: [f64; 3],
    s: f64,
    c: f64,
    d: [f64; 3],
}

/// The turns of one pass with gyro drift `drift` (rad/s) over the samples of intervals
/// `dt_s` and angle increments `dtheta_rad` ([`AHEAD`] of each), the drift-corrected
/// increment of the sample before them being `prev`, which is left at their last's.
#[inline(always)]
fn turns_ahead(
    drift: &[f64; 3],
    prev: &mut [f64; 3],
    dt_s: &[f64],
    dtheta_rad: &[[f64; 3]; AHEAD],
) -> TurnsAhead {
    let d: [[f64; AHEAD]; 3] =
        std::array::from_fn(|i| std::array::from_fn(|j| dtheta_rad[j][i] - drift[i] * dt_s[j]));
    // The increment before each: the last one's before the first.
    let p: [[f64; AHEAD]; 3] = std::array::from_fn(|i| {
        std::array::from_fn(|j| if j == 0 { prev[i] } else { d[i][j - 1] })
    });
    *prev = [0, 1, 2].map(|i| d[i][AHEAD - 1]);
    let coning: [[f64; AHEAD]; 3] = [
        std::array::from_fn(|j| p[1][j] * d[2][j] - p[2][j] * d[1][j]),
        std::array::from_fn(|j| p[2][j] * d[0][j] - p[0][j] * d[2][j]),
        std::array::from_fn(|j| p[0][j] * d[1][j] - p[1][j] * d[0][j]),
    ];
    let phi: [[f64; AHEAD]; 3] =
        std::array::from_fn(|i| std::array::from_fn(|j| d[i][j] + coning[i][j] * (1.0 / 12.0)));
    let a2: [f64; AHEAD] = std::array::from_fn(|j| {
        phi[0][j] * phi[0][j] + phi[1][j] * phi[1][j] + phi[2][j] * phi[2][j]
    });
    let mut s = [0.0; AHEAD];
    let mut c = [0.0; AHEAD];
    for j in 0..AHEAD {
        (s[j], c[j]) = half_angle_series(a2[j]);
    }
    for j in 0..AHEAD {
        if a2[j] >= HALF_ANGLE_SERIES_LIMIT_RAD2 {
            (s[j], c[j]) = half_angle_exact(a2[j]);
        }
    }
    TurnsAhead { phi, s, c, d }
}

impl<const N: usize> Lanes<N> {
    /// The start of `N` passes.
    pub fn new(settings: &[NavSettings; N]) -> Self {
        let mut lanes = Self {
            drift_rad_s: [[0.0; N]; 3],
            odo_scale: [0.0; N],
            odo_bias_mps: [0.0; N],
            odo_sin: [0.0; N],
            odo_cos: [0.0; N],
            odo_tan_pitch: [0.0; N],
            boresight: settings
                .iter()
                .any(|s| s.odo_yaw_rad != 0.0 || s.odo_pitch_rad != 0.0),
            q: [[0.0; N]; 4],
            lat_rad: [0.0; N],
            lon_rad: [0.0; N],
            h_m: [0.0; N],
            distance_m: [0.0; N],
            prev_rad: [[0.0; N]; 3],
            dir_start: [[0.0; N]; 3],
            terms: LatTerms::ZERO,
        };
        for (l, s) in settings.iter().enumerate() {
            for i in 0..3 {
                lanes.drift_rad_s[i][l] = s.drift_rad_s[i];
            }
            lanes.odo_scale[l] = s.odo_scale;
            lanes.odo_bias_mps[l] = s.odo_bias_mps;
            (lanes.odo_sin[l], lanes.odo_cos[l]) = s.odo_yaw_rad.sin_cos();
            lanes.odo_tan_pitch[l] = s.odo_pitch_rad.tan();
            let q = s.initial.to_quat_b_to_n().into_inner();
            let (w, x, y, z) = (q.w, q.i, q.j, q.k);
            lanes.q[0][l] = w;
            lanes.q[1][l] = x;
            lanes.q[2][l] = y;
            lanes.q[3][l] = z;
            lanes.lat_rad[l] = s.lat0_rad;
            lanes.lon_rad[l] = s.lon0_rad;
            lanes.h_m[l] = s.h0_m;
            lanes.terms.set(l, s.lat0_rad);
            let dir = odo_dir_n(
                [w, x, y, z],
                lanes.odo_sin[l],
                lanes.odo_cos[l],
                lanes.odo_tan_pitch[l],
                lanes.boresight,
            );
            for i in 0..3 {
                lanes.dir_start[i][l] = dir[i];
            }
        }
        lanes
    }

    /// Steps every lane over all samples of `inputs`, calling `emit.emit(k, lanes)` after
    /// sample `k`. On x86-64 CPUs with AVX2 the loop runs in 4-wide vector registers,
    /// elsewhere in the target's baseline ones (SSE2's 2-wide on x86-64); the results are
    /// the same bit for bit.
    #[inline(always)]
    pub fn run(self, inputs: &NavInputs<'_>, emit: &mut impl Emit<N>) {
        self.run_on(inputs, &mut SharedOdometer, emit)
    }

    /// [`Self::run`] with each lane's odometer increments from `odometer`.
    #[inline(always)]
    pub fn run_on(
        self,
        inputs: &NavInputs<'_>,
        odometer: &mut impl OdometerLanes<N>,
        emit: &mut impl Emit<N>,
    ) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            #[allow(unsafe_code)]
            // SAFETY: `run_avx2` only needs AVX2, and this CPU has it (checked above).
            return unsafe { self.run_avx2(inputs, odometer, emit) };
        }
        self.run_portable(inputs, odometer, emit)
    }

    /// [`Self::run_portable`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn run_avx2(
        self,
        inputs: &NavInputs<'_>,
        odometer: &mut impl OdometerLanes<N>,
        emit: &mut impl Emit<N>,
    ) {
        self.run_portable(inputs, odometer, emit)
    }

    /// The sample loop, compiled once with and once without the boresight terms.
    #[inline(always)]
    fn run_portable(
        self,
        inputs: &NavInputs<'_>,
        odometer: &mut impl OdometerLanes<N>,
        emit: &mut impl Emit<N>,
    ) {
        crate::with_angle_slice!(inputs.dtheta_rad, |dtheta_rad| self
            .run_held(inputs, dtheta_rad, odometer, emit))
    }

    /// [`Self::run_portable`] with the angle increments in the form they are held.
    #[inline(always)]
    fn run_held<T: Increment3>(
        mut self,
        inputs: &NavInputs<'_>,
        dtheta_rad: &[T],
        odometer: &mut impl OdometerLanes<N>,
        emit: &mut impl Emit<N>,
    ) {
        let n = odometer.samples(inputs);
        let mut from = 0;
        if N == 1 {
            from = if self.boresight {
                self.run_one_ahead::<true, T>(inputs, dtheta_rad, n, odometer, emit)
            } else {
                self.run_one_ahead::<false, T>(inputs, dtheta_rad, n, odometer, emit)
            };
        }
        let samples = inputs.dt_s[..n]
            .iter()
            .zip(&dtheta_rad[..n])
            .enumerate()
            .skip(from);
        if self.boresight {
            for (k, (&dt, dtheta)) in samples {
                self.step::<true>(k, dt, &dtheta.rad(), odometer.at(k, inputs), None);
                emit.emit(k, &self);
            }
        } else {
            for (k, (&dt, dtheta)) in samples {
                self.step::<false>(k, dt, &dtheta.rad(), odometer.at(k, inputs), None);
                emit.emit(k, &self);
            }
        }
    }

    /// A single pass over the first `n` samples' whole groups of [`AHEAD`]: their turns
    /// (which read the inputs alone) side by side in vector lanes, ahead of the state's
    /// steps, whose chain of dependent operations they no longer lengthen. The same
    /// operations on each sample. The samples stepped.
    #[inline(always)]
    fn run_one_ahead<const BORESIGHT: bool, T: Increment3>(
        &mut self,
        inputs: &NavInputs<'_>,
        dtheta_rad: &[T],
        n: usize,
        odometer: &mut impl OdometerLanes<N>,
        emit: &mut impl Emit<N>,
    ) -> usize {
        let drift = [0, 1, 2].map(|i| self.drift_rad_s[i][0]);
        let mut prev = [0, 1, 2].map(|i| self.prev_rad[i][0]);
        let mut k = 0;
        for (dt4, dth4) in inputs.dt_s[..n]
            .chunks_exact(AHEAD)
            .zip(dtheta_rad[..n].chunks_exact(AHEAD))
        {
            // The samples' increments read once, for their turns and their steps.
            let dth4: [[f64; 3]; AHEAD] = std::array::from_fn(|j| dth4[j].rad());
            let turns = turns_ahead(&drift, &mut prev, dt4, &dth4);
            for (j, (&dt, dtheta)) in dt4.iter().zip(&dth4).enumerate() {
                let turn = Turn {
                    phi: [0, 1, 2].map(|i| turns.phi[i][j]),
                    s: turns.s[j],
                    c: turns.c[j],
                    d: [0, 1, 2].map(|i| turns.d[i][j]),
                };
                self.step::<BORESIGHT>(k, dt, dtheta, odometer.at(k, inputs), Some(turn));
                emit.emit(k, self);
                k += 1;
            }
        }
        k
    }

    /// Advances every lane over sample `k` (interval `dt_s`, measured angle increments,
    /// each lane's odometer distance at the nominal scale); `BORESIGHT` is whether any
    /// lane has one.
    #[inline(always)]
    fn step<const BORESIGHT: bool>(
        &mut self,
        k: usize,
        dt_s: f64,
        dtheta_rad: &[f64; 3],
        odo_m: [f64; N],
        ahead: Option<Turn>,
    ) {
        for l in 0..N {
            if (self.lat_rad[l] - self.terms.lat_rad[l]).abs() > LAT_REFRESH_RAD {
                self.terms.set(l, self.lat_rad[l]);
            }
        }

        // 1. Body rotation vector with the coning term, and sin(a/2)/a, cos(a/2): taken
        // ahead (a single pass), or here.
        let mut phi = [[0.0; N]; 3];
        let mut a2 = [0.0; N];
        let mut s = [0.0; N];
        let mut c = [0.0; N];
        if let Some(t) = ahead {
            for i in 0..3 {
                phi[i] = [t.phi[i]; N];
                self.prev_rad[i] = [t.d[i]; N];
            }
            (s, c) = ([t.s; N], [t.c; N]);
        }
        for l in 0..N {
            if ahead.is_some() {
                break;
            }
            let d = [
                dtheta_rad[0] - self.drift_rad_s[0][l] * dt_s,
                dtheta_rad[1] - self.drift_rad_s[1][l] * dt_s,
                dtheta_rad[2] - self.drift_rad_s[2][l] * dt_s,
            ];
            let p = [
                self.prev_rad[0][l],
                self.prev_rad[1][l],
                self.prev_rad[2][l],
            ];
            let coning = [
                p[1] * d[2] - p[2] * d[1],
                p[2] * d[0] - p[0] * d[2],
                p[0] * d[1] - p[1] * d[0],
            ];
            for i in 0..3 {
                phi[i][l] = d[i] + coning[i] * (1.0 / 12.0);
                self.prev_rad[i][l] = d[i];
            }
            let r2 = phi[0][l] * phi[0][l] + phi[1][l] * phi[1][l] + phi[2][l] * phi[2][l];
            a2[l] = r2;
            (s[l], c[l]) = half_angle_series(r2);
        }
        for l in 0..N {
            if ahead.is_none() && a2[l] >= HALF_ANGLE_SERIES_LIMIT_RAD2 {
                (s[l], c[l]) = half_angle_exact(a2[l]);
            }
        }

        // 2. Attitude, odometer dead reckoning, navigation-frame rotation.
        for l in 0..N {
            // The odometer bias acts over the samples in which the odometer moved.
            let moving_s = if odo_m[l] != 0.0 { dt_s } else { 0.0 };
            let [qw, qx, qy, qz] = [self.q[0][l], self.q[1][l], self.q[2][l], self.q[3][l]];
            let (bw, bx, by, bz) = (c[l], s[l] * phi[0][l], s[l] * phi[1][l], s[l] * phi[2][l]);
            // q ⊗ q(φ): the body factor.
            let w = qw * bw - qx * bx - qy * by - qz * bz;
            let x = qw * bx + qx * bw + qy * bz - qz * by;
            let y = qw * by - qx * bz + qy * bw + qz * bx;
            let z = qw * bz + qx * by - qy * bx + qz * bw;

            // Odometer dead reckoning along the mid-interval direction of travel.
            let ds = self.odo_scale[l] * odo_m[l] + self.odo_bias_mps[l] * moving_s;
            let dir_end = odo_dir_n(
                [w, x, y, z],
                self.odo_sin[l],
                self.odo_cos[l],
                self.odo_tan_pitch[l],
                BORESIGHT,
            );
            let half = 0.5 * ds;
            let dp = [
                (self.dir_start[0][l] + dir_end[0]) * half,
                (self.dir_start[1][l] + dir_end[1]) * half,
                (self.dir_start[2][l] + dir_end[2]) * half,
            ];
            let h_mid = self.h_m[l] - 0.5 * dp[2];
            let inv_rm_h = 1.0 / (self.terms.rm_m[l] + h_mid);
            let inv_rn_h = 1.0 / (self.terms.rn_m[l] + h_mid);
            self.lat_rad[l] += dp[0] * inv_rm_h;
            self.lon_rad[l] += dp[1] * inv_rn_h * self.terms.inv_cos[l];
            self.h_m[l] -= dp[2];
            self.distance_m[l] += ds;

            // Navigation-frame rotation over the interval (Earth rate plus transport
            // rate), ζ ~ 1e-6 rad: its quaternion (1, −ζ/2) is exact to ζ²/8 ~ 1e-13.
            let zeta = [
                self.terms.w_ie_north_rad_s[l] * dt_s + dp[1] * inv_rn_h,
                -dp[0] * inv_rm_h,
                self.terms.w_ie_down_rad_s[l] * dt_s - dp[1] * self.terms.tan[l] * inv_rn_h,
            ];
            // (1, v) ⊗ (w, u) = (w − v·u, u + w·v + v × u) with v = −ζ/2.
            let v = [-0.5 * zeta[0], -0.5 * zeta[1], -0.5 * zeta[2]];
            self.q[0][l] = w - (v[0] * x + v[1] * y + v[2] * z);
            self.q[1][l] = x + v[0] * w + (v[1] * z - v[2] * y);
            self.q[2][l] = y + v[1] * w + (v[2] * x - v[0] * z);
            self.q[3][l] = z + v[2] * w + (v[0] * y - v[1] * x);
            // The navigation frame turned by ζ: the next start direction is the end
            // direction seen from the new frame, exact to ζ² ~ 1e-12.
            self.dir_start[0][l] = dir_end[0] - (zeta[1] * dir_end[2] - zeta[2] * dir_end[1]);
            self.dir_start[1][l] = dir_end[1] - (zeta[2] * dir_end[0] - zeta[0] * dir_end[2]);
            self.dir_start[2][l] = dir_end[2] - (zeta[0] * dir_end[1] - zeta[1] * dir_end[0]);
        }
        if k % RENORMALISE_EVERY == RENORMALISE_EVERY - 1 {
            for l in 0..N {
                let q = [self.q[0][l], self.q[1][l], self.q[2][l], self.q[3][l]];
                let norm = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
                for (i, qi) in q.iter().enumerate() {
                    self.q[i][l] = qi / norm;
                }
            }
        }
    }

    /// The third row of `C_b^n` of every lane.
    #[inline(always)]
    pub fn dcm_row3(&self) -> [[f64; N]; 3] {
        let mut r = [[0.0; N]; 3];
        for l in 0..N {
            let row = super::dcm_row3(&self.q_of(l));
            for i in 0..3 {
                r[i][l] = row[i];
            }
        }
        r
    }

    /// Attitude quaternion (w, x, y, z) of lane `l`.
    #[inline(always)]
    pub fn q_of(&self, l: usize) -> [f64; 4] {
        [self.q[0][l], self.q[1][l], self.q[2][l], self.q[3][l]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::attitude::Euler;

    /// The final state of every lane, bit for bit.
    fn final_state<const N: usize>(lanes: &Lanes<N>) -> Vec<[u64; 8]> {
        (0..N)
            .map(|l| {
                let q = lanes.q_of(l);
                [
                    q[0],
                    q[1],
                    q[2],
                    q[3],
                    lanes.lat_rad[l],
                    lanes.lon_rad[l],
                    lanes.h_m[l],
                    lanes.distance_m[l],
                ]
                .map(f64::to_bits)
            })
            .collect()
    }

    struct Last<const N: usize>(Option<Lanes<N>>);

    impl<const N: usize> Emit<N> for Last<N> {
        fn emit(&mut self, _k: usize, lanes: &Lanes<N>) {
            self.0 = Some(*lanes);
        }
    }

    /// A turning, bumping drive with one violent sample (beyond the series).
    fn inputs() -> (Vec<f64>, Vec<[f64; 3]>, Vec<f64>) {
        let n = 5000;
        let dtheta = super::super::test_drive::turning_dtheta(n);
        (vec![0.01; n], dtheta, vec![0.2; n])
    }

    use super::super::test_drive::lane_settings as settings;

    /// Every lane's state after every sample, bit for bit.
    struct Every<const N: usize>(Vec<Vec<[u64; 8]>>);

    impl<const N: usize> Emit<N> for Every<N> {
        fn emit(&mut self, _k: usize, lanes: &Lanes<N>) {
            self.0.push(final_state(lanes));
        }
    }

    #[test]
    fn a_batch_of_lanes_is_each_pass_alone_bit_for_bit() {
        let (dt, dth, odo) = inputs();
        let inputs = NavInputs {
            dt_s: &dt,
            dtheta_rad: (&dth).into(),
            odo_dist_m: &odo,
        };
        let all: [NavSettings; 8] = std::array::from_fn(settings);
        let mut batch = Last(None);
        Lanes::new(&all).run(&inputs, &mut batch);
        let batch = final_state(&batch.0.unwrap());
        for (l, s) in all.iter().enumerate() {
            let mut alone = Last(None);
            Lanes::new(&[*s]).run(&inputs, &mut alone);
            assert_eq!(final_state(&alone.0.unwrap())[0], batch[l], "lane {l}");
        }
        // A pass alone (its turns taken four samples ahead, the last few one by one) at
        // every sample, whatever its length: what its lane in a batch gives.
        for n in [4999, 4998, 4997, 3, 0] {
            let short = NavInputs {
                dt_s: &dt[..n],
                dtheta_rad: dth[..n].into(),
                odo_dist_m: &odo[..n],
            };
            let mut batch = Every::<8>(Vec::new());
            Lanes::new(&all).run(&short, &mut batch);
            assert_eq!(batch.0.len(), n);
            for (l, s) in all.iter().enumerate() {
                let mut alone = Every::<1>(Vec::new());
                Lanes::new(&[*s]).run(&short, &mut alone);
                let want: Vec<[u64; 8]> = batch.0.iter().map(|lanes| lanes[l]).collect();
                let got: Vec<[u64; 8]> = alone.0.iter().map(|lanes| lanes[0]).collect();
                assert!(got == want, "lane {l}, {n} samples");
            }
        }
        // The vector loop the CPU supports and the portable one agree too.
        let mut portable = Last(None);
        Lanes::new(&all).run_portable(&inputs, &mut SharedOdometer, &mut portable);
        assert_eq!(final_state(&portable.0.unwrap()), batch);
        // Without a boresight anywhere, the loop without its terms gives the same.
        let plain: [NavSettings; 4] = std::array::from_fn(settings);
        let mut four = Last(None);
        Lanes::new(&plain).run(&inputs, &mut four);
        assert_eq!(final_state(&four.0.unwrap())[..], batch[..4]);
    }

    /// Angle increments held in f32 give every lane the pass the same values in f64 give,
    /// bit for bit, batched or alone (four samples ahead and one by one).
    #[test]
    fn increments_held_in_f32_give_the_f64_pass_bit_for_bit() {
        let (dt, dth, odo) = inputs();
        let exact: Vec<[f64; 3]> = dth.iter().map(|v| v.map(|x| f64::from(x as f32))).collect();
        let held = crate::angle_increments::AngleIncrements::compact(exact.clone());
        assert!(held.is_single());
        let all: [NavSettings; 8] = std::array::from_fn(settings);
        for n in [5000, 4997] {
            let pass = |dtheta_rad| {
                let inputs = NavInputs {
                    dt_s: &dt[..n],
                    dtheta_rad,
                    odo_dist_m: &odo[..n],
                };
                let (mut batch, mut alone) = (Every::<8>(Vec::new()), Every::<1>(Vec::new()));
                Lanes::new(&all).run(&inputs, &mut batch);
                Lanes::new(&[all[3]]).run(&inputs, &mut alone);
                (batch.0, alone.0)
            };
            assert!(
                pass(held.view().prefix(n)) == pass(exact[..n].into()),
                "{n} samples"
            );
        }
    }

    /// A drive straight north, level, with the Earth's rate taken out of the gyros: the
    /// odometer's pitch boresight climbs tan(angle) per metre of distance and leaves the
    /// horizontal route as it is (its distance is the horizontal one); a yaw boresight
    /// beside it turns the route and leaves the height.
    #[test]
    fn the_pitch_boresight_climbs_by_its_tangent_per_metre() {
        let n = 10_000;
        let lat0 = 0.78;
        let w_ie = earth::earth_rate_ned(lat0);
        let dt = vec![0.01; n];
        let odo = vec![0.1; n]; // 10 m/s: 1 km
        // The body's rate is the navigation frame's (Earth's and the transport rate going
        // north), so the body stays level and heading north.
        let rm = earth::radii_m(lat0).0;
        let dth = vec![[w_ie.x * 0.01, -(10.0 / rm) * 0.01, w_ie.z * 0.01]; n];
        let inputs = NavInputs {
            dt_s: &dt,
            dtheta_rad: (&dth).into(),
            odo_dist_m: &odo,
        };
        let base = NavSettings {
            initial: Euler {
                roll_rad: 0.0,
                pitch_rad: 0.0,
                heading_rad: 0.0,
            },
            drift_rad_s: [0.0; 3],
            odo_scale: 1.0,
            odo_yaw_rad: 0.0,
            odo_pitch_rad: 0.0,
            odo_bias_mps: 0.0,
            lat0_rad: lat0,
            lon0_rad: -1.33,
            h0_m: 90.0,
        };
        let pitch = 1f64.to_radians();
        let nose_down = Euler {
            pitch_rad: -2f64.to_radians(),
            ..base.initial
        };
        let all = [
            base,
            NavSettings {
                odo_pitch_rad: pitch,
                ..base
            },
            NavSettings {
                odo_pitch_rad: pitch,
                odo_yaw_rad: 0.02,
                ..base
            },
            // The body pitched 2° nose down, without and with the boresight.
            NavSettings {
                initial: nose_down,
                ..base
            },
            NavSettings {
                initial: nose_down,
                odo_pitch_rad: pitch,
                ..base
            },
        ];
        let mut last = Last(None);
        Lanes::new(&all).run(&inputs, &mut last);
        let l = last.0.unwrap();
        // Without a boresight: level, north only.
        assert!((l.h_m[0] - 90.0).abs() < 1e-3, "{}", l.h_m[0]);
        // Climbing tan(1°) per metre: 17.455 m over 1 km, with the same latitude and
        // longitude (but for the millimetres a metre of distance spans less latitude
        // higher up: 1 km × 9 m / 6.4e6 m).
        let climb = l.h_m[1] - l.h_m[0];
        assert!((climb - 1e3 * pitch.tan()).abs() < 1e-3, "{climb}");
        assert!((l.lat_rad[1] - l.lat_rad[0]).abs() * rm < 3e-3);
        assert!((l.lon_rad[1] - l.lon_rad[0]).abs() * rm < 1e-3);
        // The yaw boresight turns the route 0.02 rad east (20 m) and climbs the same.
        let east = (l.lon_rad[2] - l.lon_rad[0]) * earth::radii_m(lat0).1 * lat0.cos();
        assert!((east - 1e3 * 0.02f64.sin()).abs() < 0.05, "{east}");
        assert!(
            (l.h_m[2] - l.h_m[1]).abs() < 1e-3,
            "{}",
            l.h_m[2] - l.h_m[1]
        );
        assert_eq!(l.distance_m[1], l.distance_m[0]);
        // A pitched body: the boresight climbs by the cosine of the pitch more, and its
        // horizontal route is the one without it (but for the Earth's radii).
        let climb = l.h_m[4] - l.h_m[3];
        let want = 1e3 * pitch.tan() * 2f64.to_radians().cos();
        assert!((climb - want).abs() < 1e-3, "{climb} {want}");
        assert!((l.lat_rad[4] - l.lat_rad[3]).abs() * rm < 3e-3);
        assert!((l.lon_rad[4] - l.lon_rad[3]).abs() * rm < 1e-3);
    }

    #[test]
    fn lanes_on_their_own_odometers_are_each_pass_on_its_own_inputs_bit_for_bit() {
        let (dt, dth, odo) = inputs();
        // The odometer at other timings: scaled, stopped for a while, one sample moved.
        let mut stopped = odo.clone();
        stopped[1000..1800].fill(0.0);
        let mut moved = odo.iter().map(|d| d * 1.01).collect::<Vec<f64>>();
        moved[3000] += 0.05;
        let odometers: [&[f64]; 4] = [&odo, &stopped, &moved, &odo];
        let all: [NavSettings; 4] = std::array::from_fn(|l| settings(l + 2));
        let shared = NavInputs {
            dt_s: &dt,
            dtheta_rad: (&dth).into(),
            odo_dist_m: &odo,
        };
        let mut batch = Last(None);
        Lanes::new(&all).run_on(&shared, &mut OdometerPerLane(odometers), &mut batch);
        let batch = final_state(&batch.0.unwrap());
        // Read as the pass goes, over inputs without an odometer of their own: the same.
        let mut streamed = Last(None);
        let imu_only = NavInputs {
            odo_dist_m: &[],
            ..shared
        };
        let mut streams = OdometerStreams(odometers.map(|o| o.iter().copied()));
        Lanes::new(&all).run_on(&imu_only, &mut streams, &mut streamed);
        assert_eq!(final_state(&streamed.0.unwrap()), batch);
        for (l, (s, o)) in all.iter().zip(odometers).enumerate() {
            let own = NavInputs {
                odo_dist_m: o,
                ..shared
            };
            let mut alone = Last(None);
            Lanes::new(&[*s]).run(&own, &mut alone);
            assert_eq!(final_state(&alone.0.unwrap())[0], batch[l], "lane {l}");
        }
        assert_ne!(batch[0], batch[1], "the odometers differ, so do the passes");
    }

    #[test]
    fn review_lanes_keep_what_each_tracked_pass_gives_bit_for_bit() {
        use crate::strapdown::{CriteriaSink, NavTrack, navigate, run_criteria, run_review};
        let (dt, dth, odo) = inputs();
        let mut stopped = odo.clone();
        stopped[1000..1800].fill(0.0);
        let odometers: [&[f64]; 4] = [&odo, &stopped, &odo, &stopped];
        let all: [NavSettings; 4] = std::array::from_fn(|l| settings(l + 2));
        let shared = NavInputs {
            dt_s: &dt,
            dtheta_rad: (&dth).into(),
            odo_dist_m: &odo,
        };
        let keep = [0, 10, 2500, 4999];
        let fixes = [1200, 4000];
        let mut kept_track = NavTrack::default();
        kept_track.resize(shared.len());
        let passes = run_review(
            &shared,
            odometers,
            &all,
            10,
            &fixes,
            &keep,
            std::array::from_fn(|_| Vec::new()),
            1,
            &mut kept_track,
        );
        for (l, (s, o)) in all.iter().zip(odometers).enumerate() {
            let own = NavInputs {
                odo_dist_m: o,
                ..shared
            };
            let mut track = NavTrack::default();
            navigate(&own, s, &mut track);
            let want: Vec<_> = keep
                .iter()
                .map(|&k| {
                    (
                        track.lat_rad[k],
                        track.lon_rad[k],
                        track.h_m[k],
                        track.q_b_to_n[k],
                    )
                })
                .collect();
            assert_eq!(passes[l].rows, want, "lane {l}");
            let mut alone = [CriteriaSink::default()];
            run_criteria(&own, &[*s], 10, &fixes, &mut alone);
            assert_eq!(passes[l].criteria.blocks, alone[0].blocks, "lane {l}");
            assert_eq!(passes[l].criteria.positions, alone[0].positions, "lane {l}");
            if l == 1 {
                assert!(kept_track == track, "the tracked lane's whole track");
            }
        }
    }

    #[test]
    fn states_at_samples_side_by_side_are_the_tracked_passes_bit_for_bit() {
        let (dt, dth, odo) = inputs();
        let inputs = NavInputs {
            dt_s: &dt,
            dtheta_rad: (&dth).into(),
            odo_dist_m: &odo,
        };
        let all: [NavSettings; 4] = std::array::from_fn(|l| settings(l + 3));
        // Past the end (5000 samples) is left out.
        let samples = [0, 9, 2500, 4999, 5000];
        let states = crate::strapdown::run_states_at(&inputs, &all, &samples, |_, _, s| s);
        let mut track = crate::strapdown::NavTrack::default();
        for (s, got) in all.iter().zip(&states) {
            crate::strapdown::navigate(&inputs, s, &mut track);
            let want: Vec<_> = samples[..4]
                .iter()
                .map(|&k| (track.lat_rad[k], track.lon_rad[k], track.q_b_to_n[k]))
                .collect();
            assert_eq!(got, &want);
        }
    }
}
