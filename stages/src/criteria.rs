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

impl Kryt1Series {
    /// Empty series with room for `n` epochs each.
    fn with_capacity(n: usize) -> Self {
        let v = || Vec::with_capacity(n);
        Self {
            theta_n_rad: v(),
            phi_n_rad: v(),
            d_theta_rad: v(),
            d_phi_rad: v(),
            kf_theta_rad: v(),
            kf_phi_rad: v(),
            kryt1_cum: v(),
        }
    }
}

/// Reusable buffers of [`kryt1`] and [`epoch_attitude`], so repeated evaluations of
/// stored tracks allocate nothing.
#[derive(Debug, Clone, Default)]
pub struct Kryt1Scratch {
    blocks: BlockAttitude,
}

/// The gyro roll Φ_N and pitch Θ_N of each block of F (`lp.block` samples): the angles of
/// the sum of `C_b^n`'s third row over the block, the last (shorter) block included. Within
/// a block (0.1 s) the attitude moves by far less than a degree, so the angles of the mean
/// third row equal the mean angles to second order (< 1e-8 rad), at one asin and one atan2
/// per block instead of per sample (and the angles of a sum are those of the mean). This is
/// all Kryt1 reads of a pass; its `filter` turns it into F(Φ_N) and F(Θ_N) in place.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BlockAttitude {
    /// Roll Φ_N per block, rad.
    pub roll_rad: Vec<f64>,
    /// Pitch Θ_N per block, rad.
    pub pitch_rad: Vec<f64>,
}

impl BlockAttitude {
    /// Empty, with room for the blocks of `samples` samples in blocks of `block`.
    pub fn for_samples(samples: usize, block: usize) -> Self {
        let mut blocks = Self::default();
        blocks.clear_for(samples, block);
        blocks
    }

    /// Appends the block whose samples' third rows of `C_b^n` sum to `row3_sum`.
    pub fn push_row3_sum(&mut self, row3_sum: [f64; 3]) {
        let (roll, pitch) = roll_pitch_from_row3(row3_sum[0], row3_sum[1], row3_sum[2]);
        self.roll_rad.push(roll);
        self.pitch_rad.push(pitch);
    }

    /// Appends a block of roll `roll_rad` and pitch `pitch_rad`.
    pub fn push(&mut self, roll_rad: f64, pitch_rad: f64) {
        self.roll_rad.push(roll_rad);
        self.pitch_rad.push(pitch_rad);
    }

    /// Blocks so far.
    pub fn len(&self) -> usize {
        self.roll_rad.len()
    }

    /// Whether there is no block.
    pub fn is_empty(&self) -> bool {
        self.roll_rad.is_empty()
    }

    /// Removes every block, keeping the room.
    pub fn clear(&mut self) {
        self.roll_rad.clear();
        self.pitch_rad.clear();
    }

    /// [`Self::clear`], with room made for the blocks of `samples` samples in blocks of
    /// `block`.
    pub fn clear_for(&mut self, samples: usize, block: usize) {
        self.clear();
        let n = samples.div_ceil(block.max(1));
        self.roll_rad.reserve_exact(n);
        self.pitch_rad.reserve_exact(n);
    }

    /// The blocks filtered with F ([`FilteredBlocks`]).
    pub fn filtered(mut self, lp: &LowPass) -> FilteredBlocks {
        self.filter(lp);
        FilteredBlocks(self)
    }

    /// Filters both series with F, in place: they become F(Φ_N) and F(Θ_N).
    fn filter(&mut self, lp: &LowPass) {
        lp.filter_blocks_each(&mut [&mut self.pitch_rad, &mut self.roll_rad]);
    }

    /// The filtered blocks' (Θ, Φ) at each epoch into `theta` and `phi`.
    fn at_epochs(&self, epochs: &Epochs, theta: &mut Vec<f64>, phi: &mut Vec<f64>) {
        theta.clear();
        phi.clear();
        theta.reserve_exact(epochs.block.len());
        phi.reserve_exact(epochs.block.len());
        for &j in &epochs.block {
            theta.push(self.pitch_rad[j]);
            phi.push(self.roll_rad[j]);
        }
    }
}

/// One axis's Kalman filter: its state (the error and its rate), which its steps' gains
/// ([`Kryt1Gains`]) update.
#[derive(Debug, Clone, Copy, Default)]
struct Kf2 {
    x: [f64; 2],
}

impl Kf2 {
    /// Starts at the measurement `z`, at rest.
    fn start(z: f64) -> Self {
        Self { x: [z, 0.0] }
    }

    /// Predicts over `dt` and, given `update` (the gain and the measurement `z`), updates
    /// by `z`; returns the error estimate.
    #[inline(always)]
    fn step(&mut self, dt: f64, update: Option<([f64; 2], f64)>) -> f64 {
        let [x0, x1] = self.x;
        self.x = [x0 + dt * x1, x1];
        if let Some((k, z)) = update {
            let innov = z - self.x[0];
            self.x = [self.x[0] + k[0] * innov, self.x[1] + k[1] * innov];
        }
        self.x[0]
    }
}

/// The covariance of one axis's filter, which depends on the epochs' times and validity
/// and on the filter's parameters only, not on what it filters.
#[derive(Debug, Clone, Copy)]
struct Kf2Cov {
    p: [[f64; 2]; 2],
}

impl Kf2Cov {
    /// At the filter's start.
    fn start(kp: &KalmanParams) -> Self {
        Self {
            p: [[kp.r_rad * kp.r_rad, 0.0], [0.0, 1e-8]],
        }
    }

    /// Predicts over `dt` and, when the epoch is measured, updates; returns the update's
    /// gain.
    fn step(&mut self, dt: f64, measured: bool, kp: &KalmanParams) -> Option<[f64; 2]> {
        let r2 = kp.r_rad * kp.r_rad;
        let q = kp.rate_walk_rad_s_sqrt_s * kp.rate_walk_rad_s_sqrt_s;
        let [[p00, p01], [p10, p11]] = self.p;
        let p00n = p00 + dt * (p01 + p10) + dt * dt * p11 + q * dt * dt * dt / 3.0;
        let p01n = p01 + dt * p11 + q * dt * dt / 2.0;
        let p11n = p11 + q * dt;
        self.p = [[p00n, p01n], [p01n, p11n]];
        if !measured {
            return None;
        }
        let s = self.p[0][0] + r2;
        let k = [self.p[0][0] / s, self.p[1][0] / s];
        let [[a, b], [_, d]] = self.p;
        self.p = [
            [(1.0 - k[0]) * a, (1.0 - k[0]) * b],
            [(1.0 - k[0]) * b, d - k[1] * b],
        ];
        Some(k)
    }
}

/// The gains of Kryt1's Kalman filters at each epoch of `epochs`.
///
/// A filter's covariance, hence its gains, depends on the epochs' times and validity and
/// on [`KalmanParams`] only: both axes' filters have the same gains, and so does every
/// pass over the same epochs. Computed once, they leave each evaluation of Kryt1 the
/// filters' states alone (the covariance's chain of dependent divisions set the pace of
/// an evaluation), with the same numbers, bit for bit.
#[derive(Debug, Clone, PartialEq)]
pub struct Kryt1Gains {
    /// The first valid epoch, where the filters start (the epochs' count when none is).
    start: usize,
    /// The update's gain at each epoch from `start` on (zero where the epoch is not valid,
    /// which the filters do not update at; the first is the start's, not used).
    k: Vec<[f64; 2]>,
}

impl Kryt1Gains {
    /// The gains over `epochs` of filters with parameters `kp`.
    pub fn new(epochs: &Epochs, kp: &KalmanParams) -> Self {
        let n = epochs
            .block
            .len()
            .min(epochs.t_s.len())
            .min(epochs.valid.len());
        let start = epochs.valid[..n].iter().position(|&v| v).unwrap_or(n);
        let mut k = Vec::with_capacity(n - start);
        if start < n {
            k.push([0.0; 2]);
            let mut cov = Kf2Cov::start(kp);
            for e in start + 1..n {
                let dt = epochs.t_s[e] - epochs.t_s[e - 1];
                k.push(cov.step(dt, epochs.valid[e], kp).unwrap_or([0.0; 2]));
            }
        }
        Self { start, k }
    }

    /// Epochs these gains are for.
    fn epochs(&self) -> usize {
        self.start + self.k.len()
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
    kryt1_of_blocks(epochs, kp, &scratch.blocks, series)
}

/// [`kryt1`] of a pass given by its attitude per block of F ([`BlockAttitude`], from a
/// [`Row3Blocks`] or a [`crate::strapdown::CriteriaSink`]), which it filters in place.
pub fn kryt1_from_blocks(
    epochs: &Epochs,
    lp: &LowPass,
    mut blocks: BlockAttitude,
    kp: &KalmanParams,
    series: Option<&mut Kryt1Series>,
) -> f64 {
    blocks.filter(lp);
    kryt1_of_blocks(epochs, kp, &blocks, series)
}

/// Kryt1 of the filtered blocks `blocks`.
fn kryt1_of_blocks(
    epochs: &Epochs,
    kp: &KalmanParams,
    blocks: &BlockAttitude,
    series: Option<&mut Kryt1Series>,
) -> f64 {
    let (th, ph) = (&blocks.pitch_rad, &blocks.roll_rad);
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
    scratch.blocks.at_epochs(epochs, theta, phi);
}

/// A pass's attitude per block of F filtered with F: F(Φ_N) and F(Θ_N), all that Kryt1
/// and the attitude residuals read of a pass ([`BlockAttitude::filtered`],
/// [`filtered_side_by_side`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FilteredBlocks(BlockAttitude);

impl FilteredBlocks {
    /// [`epoch_attitude`] of the pass: its filtered (Θ, Φ) at each epoch into `theta` and
    /// `phi` — the same numbers, without the stored track.
    pub fn at_epochs(&self, epochs: &Epochs, theta: &mut Vec<f64>, phi: &mut Vec<f64>) {
        self.0.at_epochs(epochs, theta, phi);
    }
}

/// The attitude per block of F of several passes (what their
/// [`crate::strapdown::CriteriaSink`]s collected), each [`BlockAttitude::filtered`], side
/// by side: their pitch and roll series four at a time ([`LowPass::filter_blocks_each`]),
/// where a pass alone fills two of the four lanes. Each the same, bit for bit, as alone.
pub fn filtered_side_by_side<const N: usize>(
    lp: &LowPass,
    mut blocks: [BlockAttitude; N],
) -> [FilteredBlocks; N] {
    let mut series: Vec<&mut [f64]> = blocks
        .iter_mut()
        .flat_map(|b| [&mut b.pitch_rad[..], &mut b.roll_rad[..]])
        .collect();
    lp.filter_blocks_each(&mut series);
    blocks.map(FilteredBlocks)
}

/// Kryt1 from the filtered gyro (pitch, roll) of each epoch, given by `attitude(e)`;
/// fills `series` when given. Its filters' gains are computed for the call: a caller
/// evaluating Kryt1 over the same epochs again keeps them ([`kryt1_with`]).
pub fn kryt1_of(
    epochs: &Epochs,
    kp: &KalmanParams,
    attitude: impl FnMut(usize) -> (f64, f64),
    series: Option<&mut Kryt1Series>,
) -> f64 {
    kryt1_with(epochs, &Kryt1Gains::new(epochs, kp), attitude, series)
}

/// [`kryt1_of`] with the filters' gains at hand (`gains`, of `epochs`).
///
/// # Panics
/// If `gains` are not of as many epochs as `epochs` has.
pub fn kryt1_with(
    epochs: &Epochs,
    gains: &Kryt1Gains,
    mut attitude: impl FnMut(usize) -> (f64, f64),
    mut series: Option<&mut Kryt1Series>,
) -> f64 {
    let n = gains.epochs();
    if let Some(s) = series.as_deref_mut() {
        // Room for each series' values made once: grown value by value, each doubling
        // copied them under the allocator's lock, which the other core's work waited on.
        *s = Kryt1Series::with_capacity(n);
    }
    assert_eq!(
        n,
        epochs
            .block
            .len()
            .min(epochs.t_s.len())
            .min(epochs.valid.len()),
        "Kryt1's gains are of other epochs"
    );
    let (mut kf_t, mut kf_p) = (Kf2::default(), Kf2::default());
    let mut sum = 0.0;
    // Without the series, the valid epochs' estimates are summed at the end, their norms
    // in vector lanes ([`crate::hypot::add_hypots`], the same sum bit for bit): libm's
    // `hypot` one epoch at a time was 3 % of a disupt process's CPU.
    let in_lanes = series.is_none();
    let (mut valid_t, mut valid_p) = VALID_ESTIMATES.take();
    valid_t.clear();
    valid_p.clear();
    for e in 0..n {
        let (th, ph) = attitude(e);
        let d_th = th - epochs.theta_p_rad[e];
        let d_ph = crate::attitude::wrap_pi(ph - epochs.phi_p_rad[e]);
        let valid = epochs.valid[e];
        let (est_t, est_p) = match e.cmp(&gains.start) {
            // Before the first valid epoch the filters have not started: no estimate.
            std::cmp::Ordering::Less => (0.0, 0.0),
            std::cmp::Ordering::Equal => {
                (kf_t, kf_p) = (Kf2::start(d_th), Kf2::start(d_ph));
                (d_th, d_ph)
            }
            std::cmp::Ordering::Greater => {
                let dt = epochs.t_s[e] - epochs.t_s[e - 1];
                let k = gains.k[e - gains.start];
                (
                    kf_t.step(dt, valid.then_some((k, d_th))),
                    kf_p.step(dt, valid.then_some((k, d_ph))),
                )
            }
        };
        if valid {
            if in_lanes {
                valid_t.push(est_t);
                valid_p.push(est_p);
            } else {
                sum += crate::hypot::hypot(est_t, est_p);
            }
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
    if in_lanes {
        sum = crate::hypot::add_hypots(sum, &valid_t, &valid_p);
    }
    VALID_ESTIMATES.set((valid_t, valid_p));
    sum
}

thread_local! {
    /// [`kryt1_with`]'s estimates at the valid epochs (θ, φ), kept for the thread's next
    /// evaluation.
    static VALID_ESTIMATES: std::cell::Cell<(Vec<f64>, Vec<f64>)> =
        const { std::cell::Cell::new((Vec::new(), Vec::new())) };
}

/// F(Φ_N) and F(Θ_N) per block of a stored track into the scratch's blocks.
fn filtered_roll_pitch(lp: &LowPass, track: &NavTrack, scratch: &mut Kryt1Scratch) {
    let mut blocks = Row3Blocks::new(lp.block);
    blocks.blocks = std::mem::take(&mut scratch.blocks);
    blocks.blocks.clear();
    for q in &track.q_b_to_n {
        blocks.push(q);
    }
    scratch.blocks = blocks.finish();
    scratch.blocks.filter(lp);
}

/// A pass's [`BlockAttitude`], taken sample by sample from its attitude (a track read
/// batch by batch is never held whole).
#[derive(Debug, Clone, Default)]
pub struct Row3Blocks {
    block: usize,
    acc: [f64; 3],
    in_block: usize,
    blocks: BlockAttitude,
}

impl Row3Blocks {
    /// Blocks of `block` samples (at least one).
    pub fn new(block: usize) -> Self {
        Self {
            block: block.max(1),
            ..Self::default()
        }
    }

    /// [`Self::new`] with room for the blocks of `samples` samples.
    pub fn for_samples(samples: usize, block: usize) -> Self {
        Self {
            blocks: BlockAttitude::for_samples(samples, block),
            ..Self::new(block)
        }
    }

    /// The next sample's attitude quaternion `C_b^n` (w, x, y, z).
    pub fn push(&mut self, q: &[f64; 4]) {
        let r = dcm_row3(q);
        let m = self.acc;
        self.acc = [m[0] + r[0], m[1] + r[1], m[2] + r[2]];
        self.in_block += 1;
        if self.in_block == self.block {
            self.blocks.push_row3_sum(self.acc);
            (self.acc, self.in_block) = ([0.0; 3], 0);
        }
    }

    /// The blocks, the last (shorter) one included.
    pub fn finish(mut self) -> BlockAttitude {
        if self.in_block > 0 {
            self.blocks.push_row3_sum(self.acc);
        }
        self.blocks
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
    /// Where the vehicle's control-point mark (the point held over the surveyed one) lies
    /// from the navigated point, in the IMU's body axes (x forward, y right, z down), m.
    /// The navigated point is the odometer's: its distance is carried along the body's x.
    pub mark_lever_arm_m: [f64; 3],
}

/// A navigated pose at a control point's sample: what its Kryt2 needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixPose {
    /// Latitude, rad.
    pub lat_rad: f64,
    /// Longitude, rad.
    pub lon_rad: f64,
    /// Height, m.
    pub h_m: f64,
    /// Travelled distance (scaled odometer), m.
    pub distance_m: f64,
    /// Attitude `C_b^n` (w, x, y, z).
    pub q_b_to_n: [f64; 4],
}

impl FixPose {
    /// The first two rows of `C_b^n`: how a body-axes vector moves north and east.
    pub fn body_to_ne(&self) -> [[f64; 3]; 2] {
        let [north, east, _] = crate::strapdown::dcm_rows(self.q_b_to_n);
        [north, east]
    }
}

impl ControlPointFix {
    /// ΔX (north) and ΔY (east), m: the navigated position of the vehicle's mark, at the
    /// navigated `pose`, minus the surveyed point. The mark's arm turns with the body;
    /// without one, this is the navigated point's offset itself, bit for bit.
    pub fn offset_m(&self, pose: &FixPose) -> (f64, f64) {
        let (dx, dy) = earth::local_offset_m(
            pose.lat_rad,
            pose.lon_rad,
            self.lat_rad,
            self.lon_rad,
            self.h_m,
        );
        if self.mark_lever_arm_m == [0.0; 3] {
            return (dx, dy);
        }
        let a = self.mark_lever_arm_m;
        let [n, e] = pose.body_to_ne();
        let north = n[0] * a[0] + n[1] * a[1] + n[2] * a[2];
        let east = e[0] * a[0] + e[1] * a[1] + e[2] * a[2];
        (dx + north, dy + east)
    }

    /// Height of the vehicle's mark at the navigated `pose` minus the surveyed height, m
    /// (the mark's arm, turned by the attitude, moves it along the down axis).
    pub fn height_error_m(&self, pose: &FixPose) -> f64 {
        let a = self.mark_lever_arm_m;
        let [c31, c32, c33] = crate::strapdown::dcm_row3(&pose.q_b_to_n);
        pose.h_m - (c31 * a[0] + c32 * a[1] + c33 * a[2]) - self.h_m
    }
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
        (k < track.len()).then(|| FixPose {
            lat_rad: track.lat_rad[k],
            lon_rad: track.lon_rad[k],
            h_m: track.h_m[k],
            distance_m: track.distance_m[k],
            q_b_to_n: track.q_b_to_n[k],
        })
    })
}

/// Kryt2 at every control point whose sample `pose` gives; the others are left out.
pub fn kryt2_at(fixes: &[ControlPointFix], pose: impl Fn(usize) -> Option<FixPose>) -> Vec<Kryt2> {
    fixes
        .iter()
        .filter_map(|f| {
            let (dx, dy) = f.offset_m(&pose(f.sample)?);
            Some(Kryt2::at(f, dx, dy))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Kryt1 as the paper's filters run it: each axis's filter with its own covariance,
    /// predicted at every epoch after its start and updated at the valid ones.
    fn kryt1_two_full_filters(
        epochs: &Epochs,
        kp: &KalmanParams,
        attitude: impl Fn(usize) -> (f64, f64),
    ) -> (f64, Vec<[f64; 3]>) {
        #[derive(Clone, Copy)]
        struct Full {
            x: [f64; 2],
            p: [[f64; 2]; 2],
            started: bool,
        }
        let step = |f: &mut Full, dt: f64, z: Option<f64>| -> f64 {
            let r2 = kp.r_rad * kp.r_rad;
            if !f.started {
                if let Some(z) = z {
                    f.x = [z, 0.0];
                    f.p = [[r2, 0.0], [0.0, 1e-8]];
                    f.started = true;
                }
                return f.x[0];
            }
            let q = kp.rate_walk_rad_s_sqrt_s * kp.rate_walk_rad_s_sqrt_s;
            f.x = [f.x[0] + dt * f.x[1], f.x[1]];
            let [[p00, p01], [p10, p11]] = f.p;
            let p00n = p00 + dt * (p01 + p10) + dt * dt * p11 + q * dt * dt * dt / 3.0;
            let p01n = p01 + dt * p11 + q * dt * dt / 2.0;
            f.p = [[p00n, p01n], [p01n, p11 + q * dt]];
            if let Some(z) = z {
                let s = f.p[0][0] + r2;
                let k = [f.p[0][0] / s, f.p[1][0] / s];
                let innov = z - f.x[0];
                f.x = [f.x[0] + k[0] * innov, f.x[1] + k[1] * innov];
                let [[a, b], [_, d]] = f.p;
                f.p = [
                    [(1.0 - k[0]) * a, (1.0 - k[0]) * b],
                    [(1.0 - k[0]) * b, d - k[1] * b],
                ];
            }
            f.x[0]
        };
        let mut filters = [Full {
            x: [0.0; 2],
            p: [[0.0; 2]; 2],
            started: false,
        }; 2];
        let (mut sum, mut rows) = (0.0, Vec::new());
        let mut prev_t = epochs.t_s[0];
        for e in 0..epochs.block.len() {
            let (th, ph) = attitude(e);
            let d = [
                th - epochs.theta_p_rad[e],
                crate::attitude::wrap_pi(ph - epochs.phi_p_rad[e]),
            ];
            let dt = epochs.t_s[e] - prev_t;
            prev_t = epochs.t_s[e];
            let valid = epochs.valid[e];
            let est = [0, 1].map(|a| step(&mut filters[a], dt, valid.then_some(d[a])));
            if valid && filters[0].started {
                sum += est[0].hypot(est[1]);
            }
            rows.push([est[0], est[1], sum]);
        }
        (sum, rows)
    }

    /// Kryt1 with its gains computed once is the two filters run in full, bit for bit:
    /// over epochs that start invalid, with invalid stretches and uneven intervals, and
    /// none valid at all; its series too.
    #[test]
    fn kryt1_with_shared_gains_is_both_full_filters_bit_for_bit() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(14);
        let kp = KalmanParams {
            r_rad: 2e-3,
            rate_walk_rad_s_sqrt_s: 3e-6,
        };
        for (n, first_valid, none_valid) in [(5000, 37, false), (300, 0, false), (50, 0, true)] {
            let mut t = 0.05;
            let epochs = Epochs {
                block: (0..n).collect(),
                t_s: (0..n)
                    .map(|_| {
                        t += if rng.random_bool(0.1) { 0.3 } else { 0.1 };
                        t
                    })
                    .collect(),
                theta_p_rad: (0..n).map(|_| rng.random_range(-0.02..0.02)).collect(),
                phi_p_rad: (0..n).map(|_| rng.random_range(-3.2..3.2)).collect(),
                valid: (0..n)
                    .map(|e| !none_valid && e >= first_valid && !rng.random_bool(0.2))
                    .collect(),
                ..Epochs::default()
            };
            let att: Vec<(f64, f64)> = (0..n)
                .map(|_| (rng.random_range(-0.03..0.03), rng.random_range(-3.2..3.2)))
                .collect();
            let (want, rows) = kryt1_two_full_filters(&epochs, &kp, |e| att[e]);
            let gains = Kryt1Gains::new(&epochs, &kp);
            let mut series = Kryt1Series::default();
            let got = kryt1_with(&epochs, &gains, |e| att[e], Some(&mut series));
            assert_eq!(got.to_bits(), want.to_bits(), "{n} epochs");
            assert_eq!(
                kryt1_of(&epochs, &kp, |e| att[e], None).to_bits(),
                want.to_bits()
            );
            for (e, row) in rows.iter().enumerate() {
                let have = [
                    series.kf_theta_rad[e],
                    series.kf_phi_rad[e],
                    series.kryt1_cum[e],
                ];
                assert_eq!(have.map(f64::to_bits), row.map(f64::to_bits), "epoch {e}");
            }
            assert_eq!(want == 0.0, none_valid);
        }
    }

    /// The mark's arm, turned by the attitude, moves the compared point north and east;
    /// without an arm the offset is the navigated point's, bit for bit.
    #[test]
    fn the_marks_arm_turns_with_the_body() {
        let fix = |arm: [f64; 3]| ControlPointFix {
            id: 1,
            sample: 0,
            t_s: 0.0,
            lat_rad: 0.9,
            lon_rad: 0.3,
            h_m: 100.0,
            mark_lever_arm_m: arm,
        };
        let pose = |roll_deg: f64, pitch_deg: f64, heading_deg: f64| {
            let q = crate::attitude::Euler {
                roll_rad: roll_deg.to_radians(),
                pitch_rad: pitch_deg.to_radians(),
                heading_rad: heading_deg.to_radians(),
            }
            .to_quat_b_to_n();
            FixPose {
                lat_rad: 0.9 + 2e-7,
                lon_rad: 0.3 - 1e-7,
                h_m: 101.0,
                distance_m: 500.0,
                q_b_to_n: [q.w, q.i, q.j, q.k],
            }
        };
        let p = pose(3.0, -2.0, 57.0);
        // The mark's height: 1 m above the surveyed one without an arm, and 0.5·cos
        // (roll)·cos(pitch) m higher with the mark 0.5 m above the navigated point.
        assert_eq!(fix([0.0; 3]).height_error_m(&p), 1.0);
        let up = fix([0.0, 0.0, -0.5]).height_error_m(&p);
        let tilt = 3f64.to_radians().cos() * 2f64.to_radians().cos();
        assert!((up - (1.0 + 0.5 * tilt)).abs() < 1e-12, "{up}");
        let bare = earth::local_offset_m(p.lat_rad, p.lon_rad, 0.9, 0.3, 100.0);
        assert_eq!(fix([0.0; 3]).offset_m(&p), bare);
        let moved = |arm: [f64; 3], p: &FixPose| {
            let (dx, dy) = fix(arm).offset_m(p);
            (dx - bare.0, dy - bare.1)
        };
        let close = |a: (f64, f64), b: (f64, f64)| {
            assert!(
                (a.0 - b.0).abs() < 1e-12 && (a.1 - b.1).abs() < 1e-12,
                "{a:?} {b:?}"
            )
        };
        // Heading east: forward is east, right is south.
        let east = pose(0.0, 0.0, 90.0);
        close(moved([2.0, 0.0, 0.0], &east), (0.0, 2.0));
        close(moved([0.0, 1.5, 0.0], &east), (-1.5, 0.0));
        // Nose up by 10° heading north: the down axis leans forward.
        let up = pose(0.0, 10.0, 0.0);
        let s = 10f64.to_radians().sin();
        close(moved([0.0, 0.0, 1.0], &up), (s, 0.0));
        // Rolled right by 20° heading north: the down axis leans left (west).
        let rolled = pose(20.0, 0.0, 0.0);
        close(
            moved([0.0, 0.0, 1.0], &rolled),
            (0.0, -20f64.to_radians().sin()),
        );
    }

    #[test]
    fn block_attitude_is_the_angles_of_each_block_sum_the_last_block_short() {
        let q: Vec<[f64; 4]> = (0..23)
            .map(|k| {
                let a = 0.01 * k as f64;
                let (s, c) = (0.5 * a).sin_cos();
                [c, s * 0.6, s * 0.8, 0.0]
            })
            .collect();
        let mut blocks = Row3Blocks::for_samples(q.len(), 10);
        q.iter().for_each(|qk| blocks.push(qk));
        let blocks = blocks.finish();
        assert_eq!(blocks.len(), 3);
        let mut want_roll = Vec::new();
        let mut want_pitch = Vec::new();
        for c in q.chunks(10) {
            let mut sum = [0.0; 3];
            for qk in c {
                let r = dcm_row3(qk);
                sum = [sum[0] + r[0], sum[1] + r[1], sum[2] + r[2]];
            }
            let (roll, pitch) = roll_pitch_from_row3(sum[0], sum[1], sum[2]);
            want_roll.push(roll);
            want_pitch.push(pitch);
        }
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&blocks.roll_rad), bits(&want_roll));
        assert_eq!(bits(&blocks.pitch_rad), bits(&want_pitch));

        // Kryt1 of the blocks, of the stored track, and of the blocks filtered by hand
        // are one number.
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
        let from_blocks = kryt1_from_blocks(&epochs, &lp, blocks, &kp, None);
        lp.filter_blocks(&mut want_roll);
        lp.filter_blocks(&mut want_pitch);
        let by_hand = kryt1_of(&epochs, &kp, |e| (want_pitch[e], want_roll[e]), None);
        assert_eq!(whole.to_bits(), by_hand.to_bits());
        assert_eq!(from_blocks.to_bits(), by_hand.to_bits());
        assert!(whole > 0.0);
    }

    /// Several passes' blocks filtered side by side are each pass's filtered alone, bit
    /// for bit, at every epoch: one to five passes (a group of four series and its
    /// remainder), of one length and of two.
    #[test]
    fn blocks_filtered_side_by_side_are_each_alone_bit_for_bit() {
        let lp = LowPass::new(&crate::filter::FilterParams::default(), 0.01);
        let pass = |p: usize, n: usize| BlockAttitude {
            roll_rad: (0..n)
                .map(|j| (0.01 * (j * (p + 1)) as f64).sin())
                .collect(),
            pitch_rad: (0..n)
                .map(|j| 0.02 * (0.003 * (j + p) as f64).cos())
                .collect(),
        };
        let epochs = |n: usize| Epochs {
            block: (0..n).collect(),
            ..Epochs::default()
        };
        let angles = |f: &FilteredBlocks, n: usize| {
            let (mut theta, mut phi) = (Vec::new(), Vec::new());
            f.at_epochs(&epochs(n), &mut theta, &mut phi);
            assert_eq!(theta.len(), n);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            (bits(&theta), bits(&phi))
        };
        fn check<const N: usize>(
            lens: [usize; N],
            lp: &LowPass,
            pass: impl Fn(usize, usize) -> BlockAttitude,
            angles: impl Fn(&FilteredBlocks, usize) -> (Vec<u64>, Vec<u64>),
        ) {
            let together: [FilteredBlocks; N] =
                filtered_side_by_side(lp, std::array::from_fn(|p| pass(p, lens[p])));
            for (p, f) in together.iter().enumerate() {
                let alone = pass(p, lens[p]).filtered(lp);
                assert_eq!(angles(f, lens[p]), angles(&alone, lens[p]), "{lens:?} {p}");
                assert_ne!(f, &FilteredBlocks(pass(p, lens[p])), "filtered");
            }
        }
        check([500], &lp, pass, angles);
        check([500, 500], &lp, pass, angles);
        check([500, 500, 500], &lp, pass, angles);
        check([500, 500, 500, 500], &lp, pass, angles);
        check([500, 500, 500, 500, 500], &lp, pass, angles);
        check([500, 300, 500], &lp, pass, angles);
    }
}
