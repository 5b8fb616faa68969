//! The criteria (paper eqs 1–4).
//!
//! Kryt1: at every epoch, ΔΘ = F(Θ_N) − Θ_p and ΔΦ = F(Φ_N) − Φ_p (F the filter the
//! accelerometer terms went through), smoothed per axis by a Kalman filter whose state is
//! the error and its rate; Kryt1 = Σ √(ΔΘ̂² + ΔΦ̂²) over the valid epochs, in rad.
//! Kryt2: horizontal distance between the navigated and the surveyed position at a
//! control point's stop, with ΔX north and ΔY east (navigated minus known), m.

use crate::derive::Epochs;
use crate::earth;
use crate::filter::LowPass;
use crate::strapdown::{NavTrack, dcm_row3, roll_pitch_from_row3};

/// Kalman filter of the pitch/roll errors (per axis; state: error, rate).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct KalmanParams {
    /// Measurement noise, rad (1σ of one epoch's ΔΘ).
    pub r_rad: f64,
    /// Rate random walk driving the error's rate, rad/s/√s.
    pub rate_walk_rad_s_sqrt_s: f64,
}

impl Default for KalmanParams {
    fn default() -> Self {
        Self {
            r_rad: 1e-3,
            rate_walk_rad_s_sqrt_s: 1e-6,
        }
    }
}

/// Per-epoch criteria series (for `criteria.parquet` and the review).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Kryt1Series {
    /// Filtered gyro pitch Θ_N, rad.
    pub theta_n_rad: Vec<f64>,
    /// Filtered gyro roll Φ_N, rad.
    pub phi_n_rad: Vec<f64>,
    /// ΔΘ, rad.
    pub d_theta_rad: Vec<f64>,
    /// ΔΦ, rad.
    pub d_phi_rad: Vec<f64>,
    /// Kalman estimate of ΔΘ, rad.
    pub kf_theta_rad: Vec<f64>,
    /// Kalman estimate of ΔΦ, rad.
    pub kf_phi_rad: Vec<f64>,
    /// Cumulative Kryt1, rad.
    pub kryt1_cum: Vec<f64>,
}

/// Reusable buffers of [`kryt1`], so repeated evaluations allocate nothing.
#[derive(Debug, Clone, Default)]
pub struct Kryt1Scratch {
    theta_blocks: Vec<f64>,
    phi_blocks: Vec<f64>,
    row3_sums: Vec<[f64; 3]>,
}

impl Kryt1Scratch {
    /// The filtered blocks' values at each epoch into `theta` and `phi`.
    fn at_epochs(&self, epochs: &Epochs, theta: &mut Vec<f64>, phi: &mut Vec<f64>) {
        theta.clear();
        phi.clear();
        for &j in &epochs.block {
            theta.push(self.theta_blocks[j]);
            phi.push(self.phi_blocks[j]);
        }
    }
}

/// One axis's Kalman filter.
#[derive(Debug, Clone, Copy)]
struct Kf2 {
    x: [f64; 2],
    p: [[f64; 2]; 2],
    started: bool,
}

impl Kf2 {
    fn new() -> Self {
        Self {
            x: [0.0; 2],
            p: [[0.0; 2]; 2],
            started: false,
        }
    }

    /// Predicts over `dt` and, when `z` is given, updates; returns the error estimate.
    fn step(&mut self, dt: f64, z: Option<f64>, kp: &KalmanParams) -> f64 {
        let r2 = kp.r_rad * kp.r_rad;
        if !self.started {
            if let Some(z) = z {
                self.x = [z, 0.0];
                self.p = [[r2, 0.0], [0.0, 1e-8]];
                self.started = true;
            }
            return self.x[0];
        }
        let q = kp.rate_walk_rad_s_sqrt_s * kp.rate_walk_rad_s_sqrt_s;
        let [x0, x1] = self.x;
        self.x = [x0 + dt * x1, x1];
        let [[p00, p01], [p10, p11]] = self.p;
        let p00n = p00 + dt * (p01 + p10) + dt * dt * p11 + q * dt * dt * dt / 3.0;
        let p01n = p01 + dt * p11 + q * dt * dt / 2.0;
        let p11n = p11 + q * dt;
        self.p = [[p00n, p01n], [p01n, p11n]];
        let _ = p10;
        if let Some(z) = z {
            let s = self.p[0][0] + r2;
            let k = [self.p[0][0] / s, self.p[1][0] / s];
            let innov = z - self.x[0];
            self.x = [self.x[0] + k[0] * innov, self.x[1] + k[1] * innov];
            let [[a, b], [_, d]] = self.p;
            self.p = [
                [(1.0 - k[0]) * a, (1.0 - k[0]) * b],
                [(1.0 - k[0]) * b, d - k[1] * b],
            ];
        }
        self.x[0]
    }
}

/// Kryt1 of a navigated track; fills `series` when given.
pub fn kryt1(
    epochs: &Epochs,
    lp: &LowPass,
    track: &NavTrack,
    kp: &KalmanParams,
    scratch: &mut Kryt1Scratch,
    series: Option<&mut Kryt1Series>,
) -> f64 {
    filtered_roll_pitch(lp, track, scratch);
    kryt1_of_blocks(epochs, kp, scratch, series)
}

/// [`kryt1`] of a track given by its sums of `C_b^n`'s third row per block of F
/// ([`Row3Blocks`]).
pub fn kryt1_from_sums(
    epochs: &Epochs,
    lp: &LowPass,
    row3_sums: &[[f64; 3]],
    kp: &KalmanParams,
    scratch: &mut Kryt1Scratch,
    series: Option<&mut Kryt1Series>,
) -> f64 {
    filtered_roll_pitch_from_sums(lp, row3_sums, scratch);
    kryt1_of_blocks(epochs, kp, scratch, series)
}

/// Kryt1 of the filtered blocks in `scratch`.
fn kryt1_of_blocks(
    epochs: &Epochs,
    kp: &KalmanParams,
    scratch: &Kryt1Scratch,
    series: Option<&mut Kryt1Series>,
) -> f64 {
    let (th, ph) = (&scratch.theta_blocks, &scratch.phi_blocks);
    kryt1_of(
        epochs,
        kp,
        |e| (th[epochs.block[e]], ph[epochs.block[e]]),
        series,
    )
}

/// The filtered gyro pitch Θ_N and roll Φ_N at every epoch of a stored track, into
/// `theta` and `phi`: everything Kryt1 and the attitude residuals read from a pass.
pub fn epoch_attitude(
    epochs: &Epochs,
    lp: &LowPass,
    track: &NavTrack,
    scratch: &mut Kryt1Scratch,
    theta: &mut Vec<f64>,
    phi: &mut Vec<f64>,
) {
    filtered_roll_pitch(lp, track, scratch);
    scratch.at_epochs(epochs, theta, phi);
}

/// [`epoch_attitude`] from the per-block sums of `C_b^n`'s third row that a
/// [`crate::strapdown::CriteriaSink`] collected (blocks of `lp.block` samples) — the
/// same numbers, without the stored track.
pub fn epoch_attitude_from_sums(
    epochs: &Epochs,
    lp: &LowPass,
    row3_sums: &[[f64; 3]],
    scratch: &mut Kryt1Scratch,
    theta: &mut Vec<f64>,
    phi: &mut Vec<f64>,
) {
    filtered_roll_pitch_from_sums(lp, row3_sums, scratch);
    scratch.at_epochs(epochs, theta, phi);
}

/// Kryt1 from the filtered gyro (pitch, roll) of each epoch, given by `attitude(e)`;
/// fills `series` when given.
pub fn kryt1_of(
    epochs: &Epochs,
    kp: &KalmanParams,
    mut attitude: impl FnMut(usize) -> (f64, f64),
    mut series: Option<&mut Kryt1Series>,
) -> f64 {
    if let Some(s) = series.as_deref_mut() {
        *s = Kryt1Series::default();
    }
    let (mut kf_t, mut kf_p) = (Kf2::new(), Kf2::new());
    let mut sum = 0.0;
    let mut prev_t = epochs.t_s.first().copied().unwrap_or(0.0);
    for e in 0..epochs.block.len() {
        let (th, ph) = attitude(e);
        let d_th = th - epochs.theta_p_rad[e];
        let d_ph = crate::attitude::wrap_pi(ph - epochs.phi_p_rad[e]);
        let dt = epochs.t_s[e] - prev_t;
        prev_t = epochs.t_s[e];
        let valid = epochs.valid[e];
        let est_t = kf_t.step(dt, valid.then_some(d_th), kp);
        let est_p = kf_p.step(dt, valid.then_some(d_ph), kp);
        if valid && kf_t.started {
            sum += est_t.hypot(est_p);
        }
        if let Some(s) = series.as_deref_mut() {
            s.theta_n_rad.push(th);
            s.phi_n_rad.push(ph);
            s.d_theta_rad.push(d_th);
            s.d_phi_rad.push(d_ph);
            s.kf_theta_rad.push(est_t);
            s.kf_phi_rad.push(est_p);
            s.kryt1_cum.push(sum);
        }
    }
    sum
}

/// F(Φ_N) and F(Θ_N) per block of a stored track into the scratch buffers.
fn filtered_roll_pitch(lp: &LowPass, track: &NavTrack, scratch: &mut Kryt1Scratch) {
    let mut sums = std::mem::take(&mut scratch.row3_sums);
    block_row3_sums(&track.q_b_to_n, lp.block, &mut sums);
    filtered_roll_pitch_from_sums(lp, &sums, scratch);
    scratch.row3_sums = sums;
}

/// F(Φ_N) and F(Θ_N) per block from the blocks' sums of `C_b^n`'s third row. Within a
/// block (0.1 s) the attitude moves by far less than a degree, so the angles of the mean
/// third row equal the mean angles to second order (< 1e-8 rad), at one asin and one
/// atan2 per block instead of per sample (and the angles of a sum are those of the mean).
fn filtered_roll_pitch_from_sums(lp: &LowPass, row3_sums: &[[f64; 3]], scratch: &mut Kryt1Scratch) {
    scratch.phi_blocks.clear();
    scratch.theta_blocks.clear();
    for m in row3_sums {
        let (r, p) = roll_pitch_from_row3(m[0], m[1], m[2]);
        scratch.phi_blocks.push(r);
        scratch.theta_blocks.push(p);
    }
    lp.filter_blocks(&mut scratch.theta_blocks);
    lp.filter_blocks(&mut scratch.phi_blocks);
}

/// Sums of `C_b^n`'s third row over blocks of `block` samples.
fn block_row3_sums(q: &[[f64; 4]], block: usize, out: &mut Vec<[f64; 3]>) {
    let mut blocks = Row3Blocks::new(block);
    blocks.sums = std::mem::take(out);
    blocks.sums.clear();
    for qk in q {
        blocks.push(qk);
    }
    *out = blocks.finish();
}

/// Sums of `C_b^n`'s third row over blocks of samples, taken sample by sample (a track
/// read batch by batch is never held whole).
#[derive(Debug, Clone, Default)]
pub struct Row3Blocks {
    block: usize,
    acc: [f64; 3],
    in_block: usize,
    sums: Vec<[f64; 3]>,
}

impl Row3Blocks {
    /// Blocks of `block` samples (at least one).
    pub fn new(block: usize) -> Self {
        Self {
            block: block.max(1),
            ..Self::default()
        }
    }

    /// The next sample's attitude quaternion `C_b^n` (w, x, y, z).
    pub fn push(&mut self, q: &[f64; 4]) {
        let r = dcm_row3(q);
        let m = self.acc;
        self.acc = [m[0] + r[0], m[1] + r[1], m[2] + r[2]];
        self.in_block += 1;
        if self.in_block == self.block {
            self.sums.push(self.acc);
            (self.acc, self.in_block) = ([0.0; 3], 0);
        }
    }

    /// The sums, the last (shorter) block's included.
    pub fn finish(mut self) -> Vec<[f64; 3]> {
        if self.in_block > 0 {
            self.sums.push(self.acc);
        }
        self.sums
    }
}

/// A control point matched to a sample of the run.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ControlPointFix {
    /// Id.
    pub id: u32,
    /// Index of the sample at the stop.
    pub sample: usize,
    /// Time of the stop, s in the log's time base.
    pub t_s: f64,
    /// Surveyed latitude, rad.
    pub lat_rad: f64,
    /// Surveyed longitude, rad.
    pub lon_rad: f64,
    /// Surveyed height, m.
    pub h_m: f64,
}

/// Kryt2 at one control point.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Kryt2 {
    /// Control-point id.
    pub id: u32,
    /// Time of the stop, s in the log's time base.
    pub t_s: f64,
    /// ΔX: navigated minus known, north, m.
    pub dx_m: f64,
    /// ΔY: navigated minus known, east, m.
    pub dy_m: f64,
    /// Horizontal distance, m.
    pub kryt2_m: f64,
}

impl Kryt2 {
    /// Kryt2 at the control point `f` for the navigated-minus-known offsets `dx_m`
    /// (north) and `dy_m` (east).
    pub fn at(f: &ControlPointFix, dx_m: f64, dy_m: f64) -> Self {
        Self {
            id: f.id,
            t_s: f.t_s,
            dx_m,
            dy_m,
            kryt2_m: dx_m.hypot(dy_m),
        }
    }
}

/// RMS horizontal error over control points given as (ΔX, ΔY), m (NaN without any):
/// the Kryt2 of a whole run.
pub fn kryt2_rms_m(errors: impl ExactSizeIterator<Item = [f64; 2]>) -> f64 {
    let n = errors.len() as f64;
    (errors.map(|[dx, dy]| dx * dx + dy * dy).sum::<f64>() / n).sqrt()
}

/// Kryt2 at every control point.
pub fn kryt2(track: &NavTrack, fixes: &[ControlPointFix]) -> Vec<Kryt2> {
    kryt2_at(fixes, |k| {
        (k < track.len()).then(|| (track.lat_rad[k], track.lon_rad[k]))
    })
}

/// Kryt2 at every control point whose sample `position` gives (latitude, longitude,
/// rad); the others are left out.
pub fn kryt2_at(
    fixes: &[ControlPointFix],
    position: impl Fn(usize) -> Option<(f64, f64)>,
) -> Vec<Kryt2> {
    fixes
        .iter()
        .filter_map(|f| {
            let (lat, lon) = position(f.sample)?;
            let (dx, dy) = earth::local_offset_m(lat, lon, f.lat_rad, f.lon_rad, f.h_m);
            Some(Kryt2::at(f, dx, dy))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn row3_blocks_sum_each_block_in_order_the_last_one_short() {
        let q: Vec<[f64; 4]> = (0..23)
            .map(|k| {
                let a = 0.01 * k as f64;
                let (s, c) = (0.5 * a).sin_cos();
                [c, s * 0.6, s * 0.8, 0.0]
            })
            .collect();
        let mut sums = Vec::new();
        block_row3_sums(&q, 10, &mut sums);
        assert_eq!(sums.len(), 3);
        for (j, c) in q.chunks(10).enumerate() {
            let mut want = [0.0; 3];
            for qk in c {
                let r = dcm_row3(qk);
                want = [want[0] + r[0], want[1] + r[1], want[2] + r[2]];
            }
            assert_eq!(
                sums[j].map(f64::to_bits),
                want.map(f64::to_bits),
                "block {j}"
            );
        }
        // Kryt1 from the sums is Kryt1 of the track.
        let track = NavTrack {
            lat_rad: vec![0.8; q.len()],
            lon_rad: vec![0.5; q.len()],
            h_m: vec![0.0; q.len()],
            q_b_to_n: q.clone(),
            distance_m: vec![0.0; q.len()],
        };
        let epochs = Epochs {
            block: vec![0, 1, 2],
            t_s: vec![0.05, 0.15, 0.22],
            theta_p_rad: vec![0.0, 0.01, 0.02],
            phi_p_rad: vec![0.0, 0.0, 0.01],
            valid: vec![true; 3],
            ..Epochs::default()
        };
        let lp = LowPass::new(&crate::filter::FilterParams::default(), 0.01);
        let kp = KalmanParams::default();
        let whole = kryt1(
            &epochs,
            &lp,
            &track,
            &kp,
            &mut Kryt1Scratch::default(),
            None,
        );
        let mut blocks = Row3Blocks::new(lp.block);
        q.iter().for_each(|qk| blocks.push(qk));
        let summed = kryt1_from_sums(
            &epochs,
            &lp,
            &blocks.finish(),
            &kp,
            &mut Kryt1Scratch::default(),
            None,
        );
        assert_eq!(whole.to_bits(), summed.to_bits());
        assert!(whole > 0.0);
    }
}
