//! The tilt a lost sample leaves, as a nuisance of the joint fit.
//!
//! A lost IMU sample's increments are filled from the rates either side
//! ([`crate::derive`]); what the gyros turned through in it is not known, and the dead
//! reckoning carries the fill's error in pitch and roll for the rest of the run (it has no
//! levelling). On a car the pitch and roll rates vibrate from sample to sample: on
//! Kingston's drive (10 Hz) a fill is about 1 mrad off about x and y, the tilt a drift of
//! 1 °/h makes in four minutes. Kingston losing one sample in a hundred (eight patterns)
//! took the joint fit's horizontal drifts up to 1.18 °/h off, up to 7.5 of their σ, the
//! fit reading the fills' random walk of tilt as drift; with the steps, 0.25 °/h and
//! 1.32σ at most (`tests/kingston.rs`).
//!
//! So the joint fit gives each gap a step of tilt, from the first epoch after it on, with
//! a prior σ from the run's own rates there: how far the fill's rule (the rates either
//! side) misses each sample around the gap that was not lost, times the samples lost. A
//! step is a rotation error in the body frame at the gap, fixed in the navigation frame
//! afterwards; at an epoch whose heading has turned by Δ from the gap's, it reads in roll
//! and pitch as the error turned by −Δ. The steps are linear in the residuals and never
//! change a pass: the fit profiles them out of its residuals (each residual vector
//! replaced by its least-squares remainder with the steps' priors appended), so its
//! Jacobian, cost and covariance are the marginal ones: the settings' σ carry the fills'
//! uncertainty. The navigation frame's steps read through two series per epoch, its
//! heading's cosine and sine, so the normal matrix and the products are suffix and prefix
//! sums: the work is linear in the epochs and cubic in the steps only (at most
//! [`MAX_STEPS`]).
//!
//! The fill's turn in heading (z) moves the route, not the tilt: the same gaps' turns are
//! profiled out of the control points' rows ([`super::gap_turns`]).

use std::sync::{Arc, Mutex};

use nalgebra::{Cholesky, DMatrix, DVector, Dyn, Matrix2};

use super::gap_turns::{TurnGap, TurnSteps};
use crate::derive::Derived;
use crate::earth::OMEGA_IE_RAD_S;

/// At most this many steps: gaps beyond it are gathered, in order, into as many groups,
/// each a step at its first gap's epoch with the group's variances summed.
pub const MAX_STEPS: usize = 128;

/// A step whose prior σ (the larger axis's) is below this, rad, is left out: a drift of
/// 0.01 °/h turns further in four minutes. A simulated LN-200's fill at 100 Hz misses by
/// about 2 µrad.
pub const MIN_STEP_SIGMA_RAD: f64 = 1e-5;

/// Samples each side of a gap whose rates tell how far the fill misses there.
const WINDOW_SAMPLES: usize = 16;

/// Fewest samples with both neighbours kept (triples) that tell the fill's miss
/// ([`miss_sigma`]); with fewer, consecutive pairs tell it.
const MIN_TRIPLES: usize = 4;

/// One step of tilt: its first epoch (row among the valid epochs) and its prior
/// covariance in the navigation frame's pair of directions, rad².
#[derive(Debug, Clone, Copy, PartialEq)]
struct TiltStep {
    first: usize,
    cov: Matrix2<f64>,
}

/// A normal matrix's Cholesky factors, each with the weights it was made at (the few a
/// fit's calls use, the latest kept).
#[derive(Debug)]
pub(super) struct FactorCache<K>(Mutex<Vec<(K, Factor)>>);

/// A normal matrix's Cholesky factor, shared by the fits that weigh alike.
type Factor = Arc<Cholesky<f64, Dyn>>;

impl<K> FactorCache<K> {
    /// Factors kept at most.
    const KEPT: usize = 4;

    pub(super) fn new() -> Self {
        Self(Mutex::new(Vec::new()))
    }

    /// The factor at `key`, made by `normal` when not kept; `None` where floating point
    /// finds the matrix not positive definite.
    pub(super) fn get<Q>(&self, key: &Q, normal: impl FnOnce() -> DMatrix<f64>) -> Option<Factor>
    where
        K: std::borrow::Borrow<Q>,
        Q: ToOwned<Owned = K> + PartialEq + ?Sized,
    {
        let mut kept = self.0.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, f)) = kept.iter().find(|(k, _)| k.borrow() == key) {
            return Some(Arc::clone(f));
        }
        let f = Arc::new(normal().cholesky()?);
        if kept.len() >= Self::KEPT {
            kept.remove(0);
        }
        kept.push((key.to_owned(), Arc::clone(&f)));
        Some(f)
    }
}

/// What the joint fit took of a run's gaps (`disupt.json`'s `joint_gap_tilts`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GapTiltSteps {
    /// Gaps (a sample closing a stretch of lost ones, or one replaced) whose fill left a
    /// tilt step of [`MIN_STEP_SIGMA_RAD`] or more.
    pub gaps: usize,
    /// The steps the fit took (a valid epoch's gaps one step; beyond [`MAX_STEPS`],
    /// gathered).
    pub steps: usize,
    /// The largest step's prior σ (its larger axis), mrad.
    pub largest_sigma_mrad: f64,
    /// The prior σ of the tilt all the steps leave together by the run's end (the larger
    /// axis of their summed covariance), mrad.
    pub end_sigma_mrad: f64,
    /// The turns in heading the fit took before the last control point
    /// (profiled out of the control points' rows; gathered beyond
    /// [`MAX_GAP_TURN_STEPS`](crate::disupt::MAX_GAP_TURN_STEPS)).
    #[serde(default)]
    pub turn_steps: usize,
    /// The prior σ of the heading all those turns leave together by the last control
    /// point, mrad.
    #[serde(default)]
    pub turn_end_sigma_mrad: f64,
}

/// The gaps' tilt steps over a problem's valid epochs ([`Self::of`]), and what profiles
/// them out of the joint fit's residuals ([`Self::profile`]).
#[derive(Debug)]
pub struct GapTilts {
    /// Per valid epoch: cosine and sine of its heading (from the start's).
    cos_sin: Vec<[f64; 2]>,
    steps: Vec<TiltStep>,
    /// The gaps the steps came from.
    gaps: usize,
    /// The gaps' turns over the control points.
    turns: Option<TurnSteps>,
    /// The normal matrix's factor at the last few attitude σ the fits weighed with.
    factors: FactorCache<f64>,
}

impl GapTilts {
    /// The tilt steps of `d`'s lost and replaced samples over its valid epochs, and
    /// their turns over the control points at samples `cp_samples`: its headings from its
    /// z gyro less the drift `drift_z_rad_s` and the Earth's rate at `lat_rad`, its route
    /// from its odometer from the heading `heading0_rad`. `None` when no gap leaves a
    /// step of [`MIN_STEP_SIGMA_RAD`] or more.
    pub fn of(
        d: &Derived,
        lat_rad: f64,
        drift_z_rad_s: f64,
        heading0_rad: f64,
        cp_samples: &[usize],
    ) -> Option<Self> {
        if d.replaced_increments.is_empty() || d.block == 0 {
            return None;
        }
        let n = d.dt_s.len().min(d.dtheta_rad.len());
        let nominal = d.nominal_dt_s;
        if n < 3 || nominal.is_nan() || nominal <= 0.0 {
            return None;
        }
        let replaced = &d.replaced_increments;
        let is_replaced = |j: usize| replaced.binary_search(&j).is_ok();
        let rate = |j: usize| {
            let th = d.dtheta_rad.get(j);
            let dt = d.dt_s[j];
            th.map(|v| v / dt)
        };
        // The valid epochs' middle samples, in order.
        let e = &d.epochs;
        let mids: Vec<usize> = (0..e.block.len())
            .filter(|&k| e.valid[k])
            .map(|k| (e.block[k] * d.block + d.block / 2).min(n - 1))
            .collect();
        if mids.is_empty() {
            return None;
        }
        // Heading from the start at each valid epoch's middle and at each gap, and the
        // route (north, east) at each gap and control point.
        let turn_rad_s = drift_z_rad_s - OMEGA_IE_RAD_S * lat_rad.sin();
        let mut cps: Vec<(usize, usize)> = cp_samples.iter().copied().zip(0..).collect();
        cps.sort_unstable();
        let mut cp_ne_m = vec![[0.0; 2]; cp_samples.len()];
        // The heading turned sample by sample ([`Turning`]): a sine and cosine each, not
        // two per sample (a 40-minute run's 240 000 took 13 % of its disupt stage).
        let mut heading = Turning::default();
        let (h0_sin, h0_cos) = heading0_rad.sin_cos();
        let mut ne_m = [0.0; 2];
        let mut cos_sin = Vec::with_capacity(mids.len());
        let mut at_gaps = Vec::with_capacity(replaced.len());
        let (mut next_mid, mut next_gap, mut next_cp) = (0, 0, 0);
        for j in 0..n {
            heading.turn(d.dtheta_rad.get(j)[2] - turn_rad_s * d.dt_s[j]);
            let moved_m = d.odo_dist_m.get(j).copied().unwrap_or(0.0);
            if moved_m != 0.0 {
                // The course: the heading from the start's, turned by the start's.
                let [c, s] = heading.cos_sin;
                ne_m[0] += moved_m * (c * h0_cos - s * h0_sin);
                ne_m[1] += moved_m * (s * h0_cos + c * h0_sin);
            }
            while next_gap < replaced.len() && replaced[next_gap] == j {
                at_gaps.push((heading.cos_sin, ne_m));
                next_gap += 1;
            }
            while next_mid < mids.len() && mids[next_mid] == j {
                cos_sin.push(heading.cos_sin);
                next_mid += 1;
            }
            while next_cp < cps.len() && cps[next_cp].0 == j {
                cp_ne_m[cps[next_cp].1] = ne_m;
                next_cp += 1;
            }
        }
        let mut steps: Vec<TiltStep> = Vec::new();
        let mut turns: Vec<TurnGap> = Vec::new();
        let mut gaps = 0;
        for (&k, &([c, s], at_ne_m)) in replaced.iter().zip(&at_gaps) {
            let closes = d.dt_s[k] > 1.5 * nominal;
            let lost = if closes {
                ((d.dt_s[k] / nominal).round() - 1.0).max(1.0)
            } else {
                1.0
            };
            let [sx, sy, sz] =
                miss_sigma(k, n, closes, &rate, &is_replaced, nominal).map(|s| s * lost);
            if sz >= MIN_STEP_SIGMA_RAD {
                turns.push(TurnGap {
                    sample: k,
                    at_ne_m,
                    var_rad2: sz * sz,
                });
            }
            // The first valid epoch whose middle is after the gap.
            let first = mids.partition_point(|&m| m < k);
            if first == mids.len() || sx.max(sy) < MIN_STEP_SIGMA_RAD {
                continue;
            }
            // Neither axis's variance quite zero: the prior stays invertible.
            let floor = 1e-3 * sx.max(sy);
            let (vx, vy) = (sx.max(floor).powi(2), sy.max(floor).powi(2));
            // (a, b) = R(h) e, R = [[c, −s], [s, c]]: cov = R diag(vx, vy) Rᵀ.
            let rot = Matrix2::new(c, -s, s, c);
            let cov =
                rot * Matrix2::from_diagonal(&nalgebra::Vector2::new(vx, vy)) * rot.transpose();
            gaps += 1;
            match steps.last_mut() {
                Some(last) if last.first == first => last.cov += cov,
                _ => steps.push(TiltStep { first, cov }),
            }
        }
        let turns = TurnSteps::new(turns, cp_samples, &cp_ne_m);
        if steps.is_empty() && turns.is_none() {
            return None;
        }
        Some(Self {
            cos_sin,
            steps: gathered(steps, MAX_STEPS, |into, s| into.cov += s.cov),
            gaps,
            turns,
            factors: FactorCache::new(),
        })
    }

    /// What the fit takes: gaps, steps and their priors' σ.
    pub fn summary(&self) -> GapTiltSteps {
        let larger_eigenvalue = |m: Matrix2<f64>| m.symmetric_eigenvalues().max();
        let mut end = Matrix2::zeros();
        let mut largest: f64 = 0.0;
        for st in &self.steps {
            largest = largest.max(larger_eigenvalue(st.cov));
            end += st.cov;
        }
        let turn_var: f64 = self.turns.iter().flat_map(|t| t.variances()).sum();
        GapTiltSteps {
            gaps: self.gaps,
            steps: self.steps.len(),
            largest_sigma_mrad: largest.sqrt() * 1e3,
            end_sigma_mrad: larger_eigenvalue(end).sqrt() * 1e3,
            turn_steps: self.turns.as_ref().map_or(0, |t| t.len()),
            turn_end_sigma_mrad: turn_var.sqrt() * 1e3,
        }
    }

    /// The rows the steps' priors append to the residuals: two a tilt step, one a turn.
    pub fn prior_rows(&self) -> usize {
        2 * self.steps.len() + self.turns.as_ref().map_or(0, |t| t.len())
    }

    /// What the turns before control point `i`, as the points weighed with `cp_weights`
    /// leave them, add to the spread (north, east; m²) of its error.
    pub fn turn_spread_at(&self, i: usize, cp_weights: &[f64]) -> Option<nalgebra::Matrix2<f64>> {
        self.turns.as_ref()?.spread_at(i, cp_weights)
    }

    /// Profiles the steps out of `r`, whose head holds the valid epochs' (ΔΘ, ΔΦ)
    /// interleaved, each over `sigma_rad`, then the control points' (ΔX, ΔY), each times
    /// its weight in `cp_weights`: the steps δ that minimise `‖r + B δ‖² + δᵀ P⁻¹ δ` are
    /// taken into those rows, and their prior's whitened rows `L⁻¹ δ` (`P = L Lᵀ`, per
    /// step) appended, the tilts' then the turns'. Linear in `r`.
    pub fn profile(&self, r: &mut Vec<f64>, sigma_rad: f64, cp_weights: &[f64]) {
        let mut tail = Vec::with_capacity(self.prior_rows());
        self.profile_tilts(r, sigma_rad, &mut tail);
        if let Some(turns) = &self.turns {
            let head = 2 * self.cos_sin.len();
            let rows = head..head + 2 * cp_weights.len();
            match r.get_mut(rows) {
                Some(rows) => turns.profile(rows, cp_weights, &mut tail),
                None => tail.extend(std::iter::repeat_n(0.0, turns.len())),
            }
        }
        r.extend(tail);
    }

    /// The tilt steps of [`Self::profile`]: the epochs' rows at the head of `r`, the
    /// priors' rows onto `tail`.
    fn profile_tilts(&self, r: &mut [f64], sigma_rad: f64, tail: &mut Vec<f64>) {
        let n_epochs = self.cos_sin.len();
        let m = self.steps.len();
        if m == 0 {
            return;
        }
        if r.len() < 2 * n_epochs || sigma_rad.is_nan() || sigma_rad <= 0.0 {
            // Not the epochs these steps were made for, or no weight: no step taken, the
            // rows kept so that every call has as many.
            tail.extend(std::iter::repeat_n(0.0, 2 * m));
            return;
        }
        // Bᵀ r through suffix sums of the two basis series (u: ΔΘ −s, ΔΦ c; v: ΔΘ c,
        // ΔΦ s).
        let mut suffix = vec![[0.0; 2]; n_epochs + 1];
        for k in (0..n_epochs).rev() {
            let [c, s] = self.cos_sin[k];
            let (rt, rp) = (r[2 * k], r[2 * k + 1]);
            suffix[k] = [
                suffix[k + 1][0] - s * rt + c * rp,
                suffix[k + 1][1] + c * rt + s * rp,
            ];
        }
        let mut rhs = DVector::zeros(2 * m);
        for (j, st) in self.steps.iter().enumerate() {
            rhs[2 * j] = -suffix[st.first][0] / sigma_rad;
            rhs[2 * j + 1] = -suffix[st.first][1] / sigma_rad;
        }
        let Some(factor) = self.factor(sigma_rad) else {
            // Not positive definite in floating point (a prior far below the epochs'
            // weight): no step taken, the rows kept so that every call has as many.
            tail.extend(std::iter::repeat_n(0.0, 2 * m));
            return;
        };
        let delta = factor.solve(&rhs);
        // B δ through prefix sums of the steps.
        let mut at = [0.0; 2];
        let mut next = 0;
        for k in 0..n_epochs {
            while next < m && self.steps[next].first == k {
                at[0] += delta[2 * next];
                at[1] += delta[2 * next + 1];
                next += 1;
            }
            let [c, s] = self.cos_sin[k];
            r[2 * k] += (-s * at[0] + c * at[1]) / sigma_rad;
            r[2 * k + 1] += (c * at[0] + s * at[1]) / sigma_rad;
        }
        for (j, st) in self.steps.iter().enumerate() {
            // P = L Lᵀ: the prior's row L⁻¹ δ.
            let d = nalgebra::Vector2::new(delta[2 * j], delta[2 * j + 1]);
            let w = (st.cov.cholesky())
                .and_then(|c| c.l().solve_lower_triangular(&d))
                .unwrap_or_else(nalgebra::Vector2::zeros);
            tail.extend([w[0], w[1]]);
        }
    }

    /// The Cholesky factor of `BᵀB / σ² + P⁻¹` at `sigma_rad`, kept for the next calls;
    /// `None` where floating point finds it not positive definite.
    fn factor(&self, sigma_rad: f64) -> Option<Arc<Cholesky<f64, Dyn>>> {
        self.factors.get(&sigma_rad, || {
            let m = self.steps.len();
            let n_epochs = self.cos_sin.len();
            let w = 1.0 / (sigma_rad * sigma_rad);
            // u and v are orthonormal at each epoch: (BᵀB) between steps i and j is the
            // count of epochs both move, times the identity.
            let mut normal = DMatrix::from_fn(2 * m, 2 * m, |a, b| {
                if a % 2 != b % 2 {
                    return 0.0;
                }
                let later = self.steps[a / 2].first.max(self.steps[b / 2].first);
                w * (n_epochs - later) as f64
            });
            // Positive definite in exact arithmetic: the priors alone are.
            for (j, st) in self.steps.iter().enumerate() {
                let inv = st.cov.try_inverse().unwrap_or_else(Matrix2::zeros);
                let mut block = normal.fixed_view_mut::<2, 2>(2 * j, 2 * j);
                block += inv;
            }
            normal
        })
    }
}

/// A heading turned by small angles, as its cosine and sine: each turn under 0.02 rad (a
/// sample's at up to 115 °/s at 100 Hz) by its Taylor series (the sine to Δ⁵, the cosine
/// to Δ⁴: errors under 10⁻¹³ a turn), a larger one exactly, and the pair brought back to
/// unit length every 4096 turns.
#[derive(Debug, Clone, Copy)]
struct Turning {
    cos_sin: [f64; 2],
    turns: u32,
}

impl Default for Turning {
    fn default() -> Self {
        Self {
            cos_sin: [1.0, 0.0],
            turns: 0,
        }
    }
}

impl Turning {
    fn turn(&mut self, delta_rad: f64) {
        let (sin, cos) = if delta_rad.abs() < 0.02 {
            let d2 = delta_rad * delta_rad;
            (
                delta_rad * (1.0 - d2 / 6.0 * (1.0 - d2 / 20.0)),
                1.0 - d2 / 2.0 * (1.0 - d2 / 12.0),
            )
        } else {
            delta_rad.sin_cos()
        };
        let [c, s] = self.cos_sin;
        self.cos_sin = [c * cos - s * sin, s * cos + c * sin];
        self.turns += 1;
        if self.turns.is_multiple_of(4096) {
            let norm = self.cos_sin[0].hypot(self.cos_sin[1]);
            if norm > 0.0 {
                self.cos_sin = self.cos_sin.map(|v| v / norm);
            }
        }
    }
}

/// How far the fill's rule misses a sample near `k`, per axis (x, y, z), rad over one
/// nominal period: the RMS over the samples within [`WINDOW_SAMPLES`] of `k` whose
/// neighbours were not lost either, of the rate less the mean of its neighbours' (the
/// fill of a gap `k` closes: `closes`), or less the rate before it (a sample replaced by
/// the rates before it).
///
/// A log losing lines regularly (one in three, say) has no sample with both neighbours
/// kept: with fewer than [`MIN_TRIPLES`] such, the miss is told by consecutive pairs
/// kept, their rates' steps `d`: a sample replaced by the one before misses by `d`; a
/// fill by the mean of its neighbours misses by `(d₁ − d₂) / 2`, at most `√0.75` times
/// the steps' RMS (rates of white noise about a smooth motion; `√0.5` for a random
/// walk's). Where every other sample closes a gap (one line in three lost, each gap's
/// fill in the sample after it) no pair is kept either, and the steps of every pair
/// tell it, a closing sample's rate the mean of its fill's and its own. Without a pair
/// (a run of three samples or fewer), no miss is told (0).
fn miss_sigma(
    k: usize,
    n: usize,
    closes: bool,
    rate: &impl Fn(usize) -> [f64; 3],
    is_replaced: &impl Fn(usize) -> bool,
    nominal_s: f64,
) -> [f64; 3] {
    let rms = |sum: [f64; 3], count: usize| sum.map(|s| (s / count as f64).sqrt());
    let add = |sum: &mut [f64; 3], miss: [f64; 3]| {
        for (s, m) in sum.iter_mut().zip(miss) {
            let m = m * nominal_s;
            if m.is_finite() {
                *s += m * m;
            }
        }
    };
    let lo = k.saturating_sub(WINDOW_SAMPLES).max(1);
    let hi = (k + WINDOW_SAMPLES).min(n - 2);
    let (mut triples, mut triple_count) = ([0.0; 3], 0_usize);
    let (mut pairs, mut pair_count) = ([0.0; 3], 0_usize);
    let (mut any_pairs, mut any_pair_count) = ([0.0; 3], 0_usize);
    for j in lo..=hi {
        if j == k {
            continue;
        }
        let (a, b) = (rate(j - 1), rate(j));
        let step: [f64; 3] = std::array::from_fn(|i| b[i] - a[i]);
        add(&mut any_pairs, step);
        any_pair_count += 1;
        if is_replaced(j - 1) || is_replaced(j) {
            continue;
        }
        add(&mut pairs, step);
        pair_count += 1;
        if is_replaced(j + 1) {
            continue;
        }
        let c = rate(j + 1);
        add(
            &mut triples,
            std::array::from_fn(|i| b[i] - if closes { (a[i] + c[i]) / 2.0 } else { a[i] }),
        );
        triple_count += 1;
    }
    if triple_count >= MIN_TRIPLES {
        return rms(triples, triple_count);
    }
    let scale = if closes { 0.75_f64.sqrt() } else { 1.0 };
    if pair_count > 0 {
        return rms(pairs, pair_count).map(|v| v * scale);
    }
    if any_pair_count > 0 {
        return rms(any_pairs, any_pair_count).map(|v| v * scale);
    }
    [0.0; 3]
}

/// `items` gathered into at most `max` groups of consecutive items (as equal in count as
/// they divide), each its first item with the rest merged into it by `merge`.
pub(super) fn gathered<T: Copy>(items: Vec<T>, max: usize, merge: impl Fn(&mut T, &T)) -> Vec<T> {
    if items.len() <= max {
        return items;
    }
    let n = items.len();
    (0..max)
        .map(|g| {
            let (lo, hi) = (g * n / max, (g + 1) * n / max);
            let mut first = items[lo];
            for item in &items[lo + 1..hi] {
                merge(&mut first, item);
            }
            first
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::derive::Epochs;

    /// A 10-Hz drive of 200 s in 1-s epochs: straight north for 100 s, a right turn of
    /// 90° over 10 s, then straight east; pitch and roll rates vibrating (±0.01 rad/s,
    /// a fixed pseudo-random series); sample 500 (50 s in) replaced.
    fn drive() -> Derived {
        let n = 2000;
        let dt = 0.1;
        let mut state = 7_u64;
        let mut noise = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.02
        };
        let dtheta: Vec<[f64; 3]> = (0..n)
            .map(|k| {
                let turning = (1000..1100).contains(&k);
                let yaw = if turning {
                    std::f64::consts::FRAC_PI_2 / 10.0
                } else {
                    0.0
                };
                [noise() * dt, noise() * dt, yaw * dt]
            })
            .collect();
        let epochs = 200;
        Derived {
            nominal_dt_s: dt,
            dt_s: Arc::new(vec![dt; n]),
            dtheta_rad: Arc::new(dtheta.into()),
            replaced_increments: vec![500],
            block: 10,
            epochs: Epochs {
                block: (0..epochs).collect(),
                t_s: (0..epochs).map(|b| b as f64 + 0.5).collect(),
                theta_p_rad: vec![0.0; epochs],
                phi_p_rad: vec![0.0; epochs],
                theta_p_per_yaw: vec![0.0; epochs],
                phi_p_per_yaw: vec![0.0; epochs],
                theta_p_per_bias: vec![0.0; epochs],
                phi_p_per_bias: vec![0.0; epochs],
                valid: vec![true; epochs],
            },
            ..Derived::default()
        }
    }

    /// A log losing one line in three closes a gap at every other sample: no sample has
    /// both neighbours kept, and the fill's miss was told as none (0: no step, the tilts
    /// read as drift, Kingston's joint azimuth 4σ off). The steps of consecutive pairs
    /// tell it instead, within a fifth of what the rule misses with every sample kept
    /// (rates of white noise: √1.5 of their σ either way).
    #[test]
    fn a_fill_among_gaps_at_every_other_sample_is_told_by_the_pairs() {
        let d = drive();
        let n = d.dt_s.len();
        let rate = |j: usize| d.dtheta_rad.get(j).map(|v| v / d.dt_s[j]);
        let none = |_: usize| false;
        let every_other = |j: usize| j % 2 == 1;
        let kept = miss_sigma(501, n, true, &rate, &none, d.nominal_dt_s);
        let lossy = miss_sigma(501, n, true, &rate, &every_other, d.nominal_dt_s);
        for axis in 0..2 {
            assert!(kept[axis] > 1e-4, "{kept:?}");
            assert!(
                (lossy[axis] / kept[axis] - 1.0).abs() < 0.2,
                "axis {axis}: {lossy:?} against {kept:?}"
            );
        }
        // A sample replaced by the one before misses by the step from it: the pairs tell
        // that rule's miss as the triples do.
        let kept = miss_sigma(501, n, false, &rate, &none, d.nominal_dt_s);
        let lossy = miss_sigma(501, n, false, &rate, &every_other, d.nominal_dt_s);
        for axis in 0..2 {
            assert!(
                (lossy[axis] / kept[axis] - 1.0).abs() < 0.2,
                "axis {axis}: {lossy:?} against {kept:?}"
            );
        }
    }

    /// The residuals (ΔΘ, ΔΦ interleaved, over `sigma`) of a pitch error `e_rad` from
    /// epoch 50 on, as the body sees it after turning: ΔΘ e cos Δ, ΔΦ ± e sin Δ for a
    /// heading Δ from the gap's (`handed` +1: the error turned by −Δ, as a frame fixed in
    /// the navigation frame reads from the turning body).
    fn pitch_step(e_rad: f64, sigma: f64, handed: f64) -> Vec<f64> {
        (0..200)
            .flat_map(|k| {
                // Epoch k's middle is sample 10 k + 5; the turn runs over samples 1000–1099.
                let turned = ((10 * k + 5) as f64 - 1000.0).clamp(0.0, 100.0) / 100.0;
                let delta = turned * std::f64::consts::FRAC_PI_2;
                if k < 50 {
                    [0.0, 0.0]
                } else {
                    [
                        e_rad * delta.cos() / sigma,
                        handed * e_rad * delta.sin() / sigma,
                    ]
                }
            })
            .collect()
    }

    #[test]
    fn a_pitch_step_before_a_right_turn_reads_as_roll_after_it() {
        let g = GapTilts::of(&drive(), 0.0, 0.0, 0.0, &[]).expect("a step");
        let s = g.summary();
        assert_eq!((s.gaps, s.steps), (1, 1));
        // The vibration's fill misses by about 1 mrad (a rate's error from its
        // neighbours' mean, 1.22 × 0.0058 rad/s over 0.1 s).
        assert!(
            (2e-4..3e-3).contains(&(s.largest_sigma_mrad * 1e-3)),
            "{s:?}"
        );
        let sigma = 1e-3;
        let e = 2e-3;
        // A step the fit can hold: what is left is the prior's pull only (a few per cent).
        let mut r = pitch_step(e, sigma, 1.0);
        g.profile(&mut r, sigma, &[]);
        assert_eq!(r.len(), 400 + 2);
        let left = r[..400].iter().fold(0f64, |m, v| m.max(v.abs()));
        assert!(left < 0.05 * e / sigma, "{left}");
        // Mirrored (the roll after the turn of the wrong sign): most of it stays.
        let mut r = pitch_step(e, sigma, -1.0);
        g.profile(&mut r, sigma, &[]);
        let left = r[..400].iter().fold(0f64, |m, v| m.max(v.abs()));
        assert!(left > 0.5 * e / sigma, "{left}");
    }

    #[test]
    fn the_profile_is_linear_and_leaves_rows_before_the_gap_alone_when_they_are_zero() {
        let g = GapTilts::of(&drive(), 0.7, 1e-6, 0.3, &[]).expect("a step");
        let mut state = 3_u64;
        let mut noise = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let a: Vec<f64> = (0..400).map(|_| noise()).collect();
        let b: Vec<f64> = (0..400).map(|_| noise()).collect();
        let sum: Vec<f64> = a.iter().zip(&b).map(|(x, y)| 2.0 * x - 3.0 * y).collect();
        let profiled = |mut r: Vec<f64>| {
            g.profile(&mut r, 2e-3, &[]);
            r
        };
        let (pa, pb, ps) = (profiled(a), profiled(b), profiled(sum));
        for k in 0..ps.len() {
            assert!((ps[k] - (2.0 * pa[k] - 3.0 * pb[k])).abs() < 1e-12);
        }
        // The step moves epochs 50 on only.
        let mut r = vec![0.0; 400];
        r[150] = 1.0;
        let p = profiled(r);
        assert!(p[..100].iter().all(|v| *v == 0.0));
        assert!(p[100..400].iter().any(|v| *v != 0.0));
    }

    #[test]
    fn residuals_not_of_these_epochs_keep_their_count_of_rows() {
        let g = GapTilts::of(&drive(), 0.0, 0.0, 0.0, &[]).expect("a step");
        // Too few rows, no weight, a weight not a number: no step taken, the priors' rows
        // appended at zero, so that every call of a fit has as many rows.
        for (len, sigma) in [(10, 1e-3), (400, 0.0), (400, f64::NAN)] {
            let mut r = vec![0.5; len];
            g.profile(&mut r, sigma, &[]);
            assert_eq!(r.len(), len + g.prior_rows());
            assert!(r[len..].iter().all(|v| *v == 0.0));
            assert!(r[..len].iter().all(|v| *v == 0.5));
        }
    }

    #[test]
    fn no_gap_or_a_calm_one_takes_no_step() {
        let mut d = drive();
        d.replaced_increments.clear();
        assert!(GapTilts::of(&d, 0.0, 0.0, 0.0, &[]).is_none());
        // At rest (rates of a few µrad a sample), a fill misses by less than the floor.
        let calm: Vec<[f64; 3]> = (0..d.dt_s.len())
            .map(|k| [1e-7 * (k % 3) as f64, 0.0, 0.0])
            .collect();
        d.dtheta_rad = Arc::new(calm.into());
        d.replaced_increments = vec![500];
        assert!(GapTilts::of(&d, 0.0, 0.0, 0.0, &[]).is_none());
    }

    #[test]
    fn a_heading_turned_by_small_and_large_angles_keeps_its_cosine_and_sine() {
        let mut t = Turning::default();
        let mut heading = 0.0;
        for k in 0..1_000_000 {
            let delta = if k % 1000 == 0 {
                0.3
            } else {
                1e-3 * ((k % 7) as f64 - 3.0) + 4e-4
            };
            t.turn(delta);
            heading += delta;
        }
        assert!(
            (t.cos_sin[0] - heading.cos()).abs() < 1e-9,
            "{:?}",
            t.cos_sin
        );
        assert!(
            (t.cos_sin[1] - heading.sin()).abs() < 1e-9,
            "{:?}",
            t.cos_sin
        );
    }

    #[test]
    fn gaps_beyond_the_cap_are_gathered_with_their_variances() {
        let steps: Vec<TiltStep> = (0..300)
            .map(|k| TiltStep {
                first: k,
                cov: Matrix2::new(1.0, 0.0, 0.0, 2.0),
            })
            .collect();
        let g = gathered(steps, MAX_STEPS, |into, s| into.cov += s.cov);
        assert_eq!(g.len(), MAX_STEPS);
        let total: f64 = g.iter().map(|s| s.cov[(0, 0)]).sum();
        assert_eq!(total, 300.0);
        assert!(g.windows(2).all(|w| w[0].first < w[1].first));
    }
}
