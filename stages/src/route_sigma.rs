//! The joint fit's uncertainty carried along the corrected route.
//!
//! Two parts, added as variances:
//! - **The settings.** Their covariance `C` (in the optimisers' units, over the estimated
//!   parameters) is propagated to each epoch's north and east position and heading
//!   through their sensitivities `g_k = ∂(north, east, heading)_k / ∂p`, one exact tracked
//!   pass per parameter moved by its finite-difference step: `σ_k² = g_kᵀ C g_k`. The
//!   odometer lag, estimated by its own search, is one more parameter from a pass over
//!   the derive at the moved lag (its covariance with the settings the search's).
//! - **The gyros' heading walk,** which the settings do not model. A heading that walks
//!   with density `N` (rad/√s) turns every later displacement, so that at `T` the position
//!   is off by `Σ_i w_i J (p_T − p_i)` (`J` a quarter turn, `w_i` the walk's increment
//!   over sample `i`): variance `N² Σ_i dt_i (e_T − e_i)²` north and
//!   `N² Σ_i dt_i (n_T − n_i)²` east, and `N² T` in heading, from the start. The fit
//!   answers much of that turn through the control points the walk moved too, and `C`
//!   holds that answer's own spread: with the fit's [`WalkUptake`], the walk's share is
//!   `Σ_i q dt_i (b_Ti + g_T u_i)²` (the turn and the answer together, `WalkCross`), in
//!   place of the turn and `C`'s heading share apart (which ignored their covariance and
//!   so overstated the σ where control points pin the route: metres where the errors are
//!   centimetres). Without an uptake (no walk, no control point weighed) the turn from the
//!   start is added alone.

use rayon::prelude::*;

use crate::attitude::wrap_pi;
use crate::disupt::WalkUptake;
use crate::earth::LocalFrame;
use crate::strapdown::{
    LaneBatch, MAX_LANES, NavInputs, NavSettings, PassSink, StateAt, in_lanes, run_states_at,
    run_states_each, samples_every,
};

/// σ of the corrected route at every `stride`-th sample (and the last).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RouteSigma {
    /// Sample index of each value.
    pub sample: Vec<usize>,
    /// σ of the north position, m.
    pub north_m: Vec<f64>,
    /// σ of the east position, m.
    pub east_m: Vec<f64>,
    /// σ of the heading, rad.
    pub heading_rad: Vec<f64>,
}

impl RouteSigma {
    /// The three σ linearly interpolated to the samples `range` of the run.
    pub fn at_samples(&self, range: std::ops::Range<usize>) -> [Vec<f64>; 3] {
        if self.sample.is_empty() {
            let zeros = vec![0.0; range.len()];
            return [zeros.clone(), zeros.clone(), zeros];
        }
        // The last value at or before the range's first sample (the first value before
        // it).
        let first = self
            .sample
            .partition_point(|&s| s <= range.start)
            .saturating_sub(1);
        // The samples between two of the σ's, each σ interpolated over them in one loop
        // (the weight `(k − a) / (b − a)`, clamped, the same expression at every sample).
        let last = self.sample.len() - 1;
        let mut out: [Vec<f64>; 3] = std::array::from_fn(|_| Vec::with_capacity(range.len()));
        let mut j = first;
        let mut k = range.start;
        while k < range.end {
            while j < last && self.sample[j + 1] <= k {
                j += 1;
            }
            let (a, b) = (self.sample[j], self.sample[(j + 1).min(last)]);
            // Up to the next σ's sample (past `k`, by the loop above), else to the end.
            let until = if j < last {
                b.min(range.end)
            } else {
                range.end
            };
            for (o, v) in out
                .iter_mut()
                .zip([&self.north_m, &self.east_m, &self.heading_rad])
            {
                let (v_a, v_b) = (v[j], v[(j + 1).min(v.len() - 1)]);
                o.extend((k..until).map(|s| {
                    let w = if b > a {
                        ((s as f64 - a as f64) / (b - a) as f64).clamp(0.0, 1.0)
                    } else {
                        0.0
                    };
                    v_a + w * (v_b - v_a)
                }));
            }
            k = until;
        }
        out
    }
}

/// Heading of a quaternion `C_b^n` (w, x, y, z), rad.
fn heading_of(q: &[f64; 4]) -> f64 {
    let [w, x, y, z] = *q;
    (2.0 * (x * y + w * z)).atan2(w * w + x * x - y * y - z * z)
}

/// (north m, east m in `frame`, the local frame of a pass's start, heading rad) of a
/// pass's state. The frame is taken once per pass, not per sample (its radii and
/// cosine cost more than the offsets): the same values, bit for bit
/// ([`crate::earth::Geodetic::local_frame`]).
fn state(frame: &LocalFrame, lat_rad: f64, lon_rad: f64, q: &[f64; 4]) -> [f64; 3] {
    let (n, e) = frame.offset_m(lat_rad, lon_rad);
    [n, e, heading_of(q)]
}

/// A moved pass's sensitivity at one sample: its (north, east, heading) in `state` (in
/// `frame`, its start's local frame) minus the corrected pass's `y0` there, over its step.
fn sensitivity(
    mv: &Moved<'_>,
    frame: &LocalFrame,
    y0: &[f64; 3],
    (lat, lon, q): StateAt,
) -> [f64; 3] {
    sensitivity_of(&state(frame, lat, lon, &q), y0, mv.step)
}

/// A moved pass's sensitivity from its (north, east, heading) `y` at a sample, the
/// corrected pass's `y0` there and its step.
fn sensitivity_of(y: &[f64; 3], y0: &[f64; 3], step: f64) -> [f64; 3] {
    let d = [y[0] - y0[0], y[1] - y0[1], wrap_pi(y[2] - y0[2])];
    d.map(|v| v / step)
}

/// Each moved pass's sensitivities at `samples`. Consecutive passes on the same inputs
/// run side by side in vector lanes (at most eight), the batches in parallel; no track is
/// stored, nor a pass's states. Each value is what the pass alone, tracked, gives bit for
/// bit.
fn sensitivities(moved: &[Moved<'_>], samples: &[usize], y0: &[[f64; 3]]) -> Vec<Vec<[f64; 3]>> {
    let mut batches: Vec<&[Moved<'_>]> = Vec::new();
    let mut start = 0;
    for j in 1..=moved.len() {
        if j == moved.len()
            || j - start == MAX_LANES
            || !moved[j].inputs.same_as(&moved[start].inputs)
        {
            batches.push(&moved[start..j]);
            start = j;
        }
    }
    batches
        .par_iter()
        .flat_map_iter(|batch| in_lanes(batch.len(), &mut SensitivitiesOf { batch, samples, y0 }))
        .collect()
}

/// Moved passes on the same inputs, their sensitivities at `samples`.
struct SensitivitiesOf<'m, 'a> {
    batch: &'m [Moved<'a>],
    samples: &'m [usize],
    y0: &'m [[f64; 3]],
}

impl LaneBatch for SensitivitiesOf<'_, '_> {
    type Out = Vec<[f64; 3]>;

    fn run<const N: usize>(&mut self, points: [usize; N]) -> [Vec<[f64; 3]>; N] {
        let settings = points.map(|i| self.batch[i].settings);
        let frames = settings.map(|s| s.start().local_frame());
        let (batch, y0) = (self.batch, self.y0);
        run_states_at(&self.batch[0].inputs, &settings, self.samples, |l, i, s| {
            sensitivity(&batch[points[l]], &frames[l], &y0[i], s)
        })
    }
}

/// The moved passes in one batch of lanes, each on its own odometer increments, and the
/// passes already run: at each sample their sensitivities go straight into the σ (none is
/// stored).
struct SigmaInOneBatch<'m, 'a> {
    moved: &'m [Moved<'a>],
    ran: &'m [Ran<'a>],
    base: &'m RouteBase<'a>,
    covariance: &'m nalgebra::DMatrix<f64>,
    cross: &'m mut Option<WalkCross<'a>>,
    out: &'m mut RouteSigma,
}

impl LaneBatch for SigmaInOneBatch<'_, '_> {
    type Out = ();

    fn run<const N: usize>(&mut self, points: [usize; N]) -> [(); N] {
        let settings = points.map(|i| self.moved[i].settings);
        let frames = settings.map(|s| s.start().local_frame());
        let odometers = points.map(|i| self.moved[i].inputs.odo_dist_m.iter().copied());
        let (moved, ran, base, covariance) = (self.moved, self.ran, self.base, self.covariance);
        let samples = &base.samples[..base.y0.len()];
        let out = &mut *self.out;
        let cross = &mut *self.cross;
        let m = moved.len();
        // Lane `a` runs moved pass `a` (the lanes past the last repeat it: not read); the
        // passes already run follow. Each sensitivity is taken once per sample.
        let mut g = Vec::with_capacity(m + ran.len());
        run_states_each(
            &moved[0].inputs,
            odometers,
            &settings,
            samples,
            |i, states| {
                let y0 = &base.y0[i];
                g.clear();
                g.extend((0..m).map(|a| sensitivity(&moved[points[a]], &frames[a], y0, states[a])));
                g.extend(ran.iter().map(|r| r.sensitivity(i, y0)));
                let walk = cross
                    .as_mut()
                    .map_or(base.walk[i], |x| x.next(base.t_s[i], y0, &g));
                out.push(walk, covariance, &g);
            },
        );
        [(); N]
    }
}

/// A moved pass already run ([`states_along`]): its (north, east, heading) at the
/// route's samples, and the step that moved it (in the covariance's units).
pub struct Ran<'a> {
    /// (north m, east m from the start, heading rad) at each of the route's samples.
    pub states: &'a [[f64; 3]],
    /// The step, in the covariance's units.
    pub step: f64,
}

impl Ran<'_> {
    /// Its sensitivity at the route's `i`-th sample, where the corrected pass is at `y0`.
    fn sensitivity(&self, i: usize, y0: &[f64; 3]) -> [f64; 3] {
        sensitivity_of(&self.states[i], y0, self.step)
    }
}

/// The route's samples of a run of `n` samples: every `stride`-th, and the last.
pub fn route_samples(n: usize, stride: usize) -> Vec<usize> {
    samples_every(n, stride)
}

/// One pass with `settings` over `inputs`' IMU series and the odometer increments
/// `odometer` yields (stored or read as the pass goes): its (north, east, heading) at
/// `samples` ([`route_samples`]), for [`Ran`]. Taken where the odometer is at hand, it
/// spares keeping its increments until the route's σ.
///
/// # Panics
/// If the odometer yields fewer increments than `inputs` has samples.
pub fn states_along(
    inputs: &NavInputs<'_>,
    odometer: impl ExactSizeIterator<Item = f64>,
    settings: &NavSettings,
    samples: &[usize],
) -> Vec<[f64; 3]> {
    let mut out = Vec::with_capacity(samples.len());
    let frame = settings.start().local_frame();
    run_states_each(
        inputs,
        [odometer],
        &[*settings],
        samples,
        |_, [(lat, lon, q)]| {
            out.push(state(&frame, lat, lon, &q));
        },
    );
    out
}

/// One moved parameter: the settings of the pass and the inputs it runs on, the step
/// that moved it (in the covariance's units), and its column in the covariance.
pub struct Moved<'a> {
    /// Inputs of the pass (its odometer increments may be another timing's).
    pub inputs: NavInputs<'a>,
    /// Settings of the pass.
    pub settings: NavSettings,
    /// The step, in the covariance's units.
    pub step: f64,
}

/// What the route's σ reads of the corrected pass, taken as the pass runs (a
/// [`PassSink`]; no track is stored): its (north, east, heading) and the angle random
/// walk's variances at every `stride`-th sample and the last.
#[derive(Debug, Clone)]
pub struct RouteBase<'a> {
    /// The local frame of the pass's start.
    start: LocalFrame,
    dt_s: &'a [f64],
    arw_q: f64,
    samples: Vec<usize>,
    next: usize,
    /// Running sums over the samples so far: Σdt, Σdt·n, Σdt·n², Σdt·e, Σdt·e².
    sums: [f64; 5],
    /// Time of each of the samples reached, s from the first (its interval included).
    t_s: Vec<f64>,
    y0: Vec<[f64; 3]>,
    walk: Vec<[f64; 3]>,
}

impl<'a> RouteBase<'a> {
    /// For a pass with `settings` over the samples whose intervals are `dt_s`, and the
    /// gyros' angle random walk `arw_rad_sqrt_s`.
    pub fn new(
        settings: &NavSettings,
        dt_s: &'a [f64],
        arw_rad_sqrt_s: f64,
        stride: usize,
    ) -> Self {
        let samples = route_samples(dt_s.len(), stride);
        Self {
            start: settings.start().local_frame(),
            dt_s,
            arw_q: arw_rad_sqrt_s * arw_rad_sqrt_s,
            t_s: Vec::with_capacity(samples.len()),
            y0: Vec::with_capacity(samples.len()),
            walk: Vec::with_capacity(samples.len()),
            samples,
            next: 0,
            sums: [0.0; 5],
        }
    }
}

impl PassSink for RouteBase<'_> {
    #[inline]
    fn sample(&mut self, k: usize, lat: f64, lon: f64, _h: f64, q: &[f64; 4], _d: f64) {
        // The random walk's share (see the module documentation).
        let (n, e) = self.start.offset_m(lat, lon);
        let dt = self.dt_s.get(k).copied().unwrap_or(0.0);
        let sums = &mut self.sums;
        sums[0] += dt;
        sums[1] += dt * n;
        sums[2] += dt * n * n;
        sums[3] += dt * e;
        sums[4] += dt * e * e;
        if self.samples.get(self.next) == Some(&k) {
            self.next += 1;
            let north = e * e * sums[0] - 2.0 * e * sums[3] + sums[4];
            let east = n * n * sums[0] - 2.0 * n * sums[1] + sums[2];
            let q2 = self.arw_q;
            self.walk
                .push([q2 * north.max(0.0), q2 * east.max(0.0), q2 * sums[0]]);
            self.t_s.push(sums[0]);
            self.y0.push(state(&self.start, lat, lon, q));
        }
    }
}

impl RouteSigma {
    /// Appends the σ at one sample: `g[a]` is moved pass `a`'s sensitivity there, `walk`
    /// what the random walk adds to the variances (north m², east m², heading rad²) beyond
    /// the covariance's share: its turn from the start, or [`WalkCross`]'s.
    fn push(&mut self, walk: [f64; 3], covariance: &nalgebra::DMatrix<f64>, g: &[[f64; 3]]) {
        // gᵀ C g of the three quantities, each summed over (a, b) in the same order, the
        // three side by side (three chains of additions where one at a time waited on each).
        let n = g.len();
        assert!(
            covariance.nrows() >= n && covariance.ncols() >= n,
            "a covariance smaller than the sensitivities"
        );
        let mut v = [0.0; 3];
        for (a, ga) in g.iter().enumerate() {
            for (b, gb) in g.iter().enumerate() {
                let c = covariance[(a, b)];
                for q in 0..3 {
                    v[q] += ga[q] * c * gb[q];
                }
            }
        }
        let [n, e, h] = v.map(|v: f64| v.max(0.0));
        self.north_m.push((n + walk[0]).max(0.0).sqrt());
        self.east_m.push((e + walk[1]).max(0.0).sqrt());
        self.heading_rad.push((h + walk[2]).max(0.0).sqrt());
    }
}

/// The heading's walk along the route, weighed against the fit's uptake of it
/// ([`WalkUptake`]), each route sample's interval a kick at its position (one grid and
/// one set of positions for every term, so that they cancel where they should). A kick
/// `δ_j` moves the route at a later sample `k` by `δ_j b_kj`, `b_kj = (J (p_k − p_j), 1)`
/// (north, east, heading), and the settings by `δ_j u_j`, so the walk's share of the
/// route's variance is `Σ_j q Δt_j (b_kj + S_k u_j)²` (`b_kj` zero for the kicks after
/// `k`, `S_k` the route's sensitivities): a sum of squares, which the fit's covariance held
/// only in part (`S_k W S_kᵀ`, its heading share `W`, on its own epochs; that part is
/// taken out of it here). Expanded, `Σ_{j≤k} q Δt_j b_kj² + 2 S_k X_k + S_k W_r S_kᵀ`, with
/// `X_k = Σ_{j≤k} q Δt_j b_kj u_jᵀ` from the running sums `U0 = Σ q Δt u_j` and
/// `U1 = Σ q Δt (J p_j) u_jᵀ` (position rows `J p_k U0ᵀ − U1`, heading row `U0ᵀ`) and
/// `W_r = Σ_j q Δt_j u_j u_jᵀ` over the whole route, summed before: linear in the run.
struct WalkCross<'u> {
    uptake: &'u WalkUptake,
    /// `W_r`, row by row.
    route_share: Vec<f64>,
    /// `U0`, then `U1`'s north and east rows: three rows of the uptake's settings.
    sums: Vec<f64>,
    /// Σ q Δt, Σ q Δt n, Σ q Δt n², Σ q Δt e, Σ q Δt e² over the kicks so far.
    turns: [f64; 5],
    /// `u_j` of the latest kick.
    u: Vec<f64>,
    /// Time of the latest sample, s.
    t_s: f64,
}

impl<'u> WalkCross<'u> {
    /// For the route's samples at times `t_s` and states `y` (north, east, heading).
    fn new(uptake: &'u WalkUptake, t_s: &[f64], y: &[[f64; 3]]) -> Self {
        let p = uptake.settings;
        let mut u = vec![0.0; p];
        let mut route_share = vec![0.0; p * p];
        let mut before = 0.0;
        for (&t, y) in t_s.iter().zip(y) {
            let q_dt = uptake.q_rad2_s * (t - before).max(0.0);
            before = t;
            uptake.step_per_kick(t, y[0], y[1], &mut u);
            for a in 0..p {
                for b in 0..p {
                    route_share[a * p + b] += q_dt * u[a] * u[b];
                }
            }
        }
        Self {
            uptake,
            route_share,
            sums: vec![0.0; 3 * p],
            turns: [0.0; 5],
            u,
            t_s: 0.0,
        }
    }

    /// The kick over the interval to the route's sample at `t_s`, `y` (north, east,
    /// heading); then the walk's share of the variances there (north m², east m², heading
    /// rad²) less the fit's heading share's, with `g[a]` the sensitivity to parameter `a`
    /// (the uptake's settings first).
    fn next(&mut self, t_s: f64, y: &[f64; 3], g: &[[f64; 3]]) -> [f64; 3] {
        let p = self.uptake.settings;
        let (n, e) = (y[0], y[1]);
        let q_dt = self.uptake.q_rad2_s * (t_s - self.t_s).max(0.0);
        self.t_s = t_s;
        self.uptake.step_per_kick(t_s, n, e, &mut self.u);
        let (u0, u1) = self.sums.split_at_mut(p);
        let (u1_n, u1_e) = u1.split_at_mut(p);
        // J p = (−e, n).
        for a in 0..p {
            let w = q_dt * self.u[a];
            u0[a] += w;
            u1_n[a] -= e * w;
            u1_e[a] += n * w;
        }
        let t = &mut self.turns;
        t[0] += q_dt;
        t[1] += q_dt * n;
        t[2] += q_dt * n * n;
        t[3] += q_dt * e;
        t[4] += q_dt * e * e;
        // Σ_{j≤k} q Δt b_kj²: the north moves by −(e_k − e_j), the east by n_k − n_j.
        let mut own = [
            e * e * t[0] - 2.0 * e * t[3] + t[4],
            n * n * t[0] - 2.0 * n * t[1] + t[2],
            t[0],
        ];
        let (route, fit) = (&self.route_share, &self.uptake.heading_share);
        let mut fit_share = [0.0; 3];
        for (a, ga) in g.iter().enumerate().take(p) {
            let x = [-e * u0[a] - u1_n[a], n * u0[a] - u1_e[a], u0[a]];
            for (b, gb) in g.iter().enumerate().take(p) {
                for q in 0..3 {
                    own[q] += ga[q] * route[a * p + b] * gb[q];
                    fit_share[q] += ga[q] * fit[a * p + b] * gb[q];
                }
            }
            for q in 0..3 {
                own[q] += 2.0 * x[q] * ga[q];
            }
        }
        std::array::from_fn(|q| own[q].max(0.0) - fit_share[q])
    }
}

/// σ along the route of the corrected pass `base` took. `moved[j]` is parameter j moved
/// by its step, and `ran[j]` parameter `moved.len() + j`, its pass already run;
/// `covariance` is over the same parameters, in their step units. `uptake`, over the first
/// of those parameters, is how the fit took up the heading's walk: with it, the walk's
/// share is the route's turn less what the fit answered it with (see the module
/// documentation); without it, the turn from the start alone. When the moved passes fit
/// in one batch of lanes (the same IMU series, at most eight), their sensitivities are
/// combined at each sample as they run; else each pass's are kept.
pub fn route_sigma(
    base: &RouteBase<'_>,
    moved: &[Moved<'_>],
    ran: &[Ran<'_>],
    covariance: &nalgebra::DMatrix<f64>,
    uptake: Option<&WalkUptake>,
) -> RouteSigma {
    // The samples the pass reached (all of them, once it has run).
    let samples = &base.samples[..base.y0.len()];
    let m = moved.len();
    if samples.is_empty()
        || m + ran.len() == 0
        || ran.iter().any(|r| r.states.len() < samples.len())
    {
        return RouteSigma::default();
    }
    let mut cross = uptake
        .filter(|u| u.settings <= m + ran.len() && u.q_rad2_s > 0.0)
        .map(|u| WalkCross::new(u, &base.t_s, &base.y0));
    let mut out = RouteSigma {
        sample: samples.to_vec(),
        north_m: Vec::with_capacity(samples.len()),
        east_m: Vec::with_capacity(samples.len()),
        heading_rad: Vec::with_capacity(samples.len()),
    };
    if (1..=MAX_LANES).contains(&m)
        && moved
            .iter()
            .all(|mv| mv.inputs.same_imu_as(&moved[0].inputs))
    {
        in_lanes(
            m,
            &mut SigmaInOneBatch {
                moved,
                ran,
                base,
                covariance,
                cross: &mut cross,
                out: &mut out,
            },
        );
    } else {
        // Sensitivities: per parameter, per sample, the 3 quantities'.
        let by_pass = sensitivities(moved, samples, &base.y0);
        let mut g = Vec::with_capacity(m + ran.len());
        for (i, walk) in base.walk.iter().enumerate() {
            let y0 = &base.y0[i];
            g.clear();
            g.extend(by_pass.iter().map(|p| p[i]));
            g.extend(ran.iter().map(|r| r.sensitivity(i, y0)));
            let walk = (cross.as_mut()).map_or(*walk, |x| x.next(base.t_s[i], y0, &g));
            out.push(walk, covariance, &g);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::attitude::Euler;
    use crate::strapdown::{self, NavTrack};

    /// A turning drive: 0.01 s samples, the odometer at two timings.
    fn drive(n: usize) -> (Vec<f64>, Vec<[f64; 3]>, Vec<f64>, Vec<f64>) {
        let dtheta = (0..n)
            .map(|k| {
                let t = k as f64 * 0.01;
                [
                    1e-4 * (t * 3.0).sin(),
                    2e-4 * (t * 2.0).cos(),
                    3e-3 * (t * 0.5).sin(),
                ]
            })
            .collect();
        let later = (0..n)
            .map(|k| 0.2 + 1e-3 * (k as f64 * 0.05).sin())
            .collect();
        (vec![0.01; n], dtheta, vec![0.2; n], later)
    }

    /// The corrected pass's settings moved by `j`-th steps.
    fn settings(j: usize) -> NavSettings {
        let f = j as f64;
        NavSettings {
            initial: Euler {
                roll_rad: 0.01,
                pitch_rad: -0.02,
                heading_rad: 0.3 + 1e-4 * f,
            },
            drift_rad_s: [1e-6 * f, -2e-7, 3e-6 + 1e-8 * f],
            odo_scale: 1.0 + 1e-5 * f,
            odo_yaw_rad: if j == 4 { 1e-3 } else { 0.0 },
            odo_pitch_rad: 0.0,
            odo_bias_mps: if j == 6 { -0.01 } else { 0.0 },
            lat0_rad: 0.78,
            lon0_rad: -1.33,
            h0_m: 90.0,
        }
    }

    /// A covariance with every pair correlated, positive definite.
    fn covariance(m: usize) -> nalgebra::DMatrix<f64> {
        let a = nalgebra::DMatrix::from_fn(m, m, |i, j| ((i * 7 + j * 3) % 5) as f64 * 0.3 - 0.5);
        &a * a.transpose() + nalgebra::DMatrix::identity(m, m)
    }

    /// σ by its definition, from every pass alone and tracked (without the random walk).
    fn sigma_by_hand(
        base: (&NavInputs<'_>, &NavSettings),
        moved: &[Moved<'_>],
        covariance: &nalgebra::DMatrix<f64>,
        samples: &[usize],
    ) -> [Vec<f64>; 3] {
        let track = |inputs: &NavInputs<'_>, s: &NavSettings| {
            let mut t = NavTrack::default();
            t.resize(inputs.len());
            strapdown::run(inputs, s, &mut t);
            t
        };
        // The offsets from the start itself (not a local frame taken once).
        let y = |t: &NavTrack, s: &NavSettings, k: usize| {
            let (n, e) = s.start().offset_m(t.lat_rad[k], t.lon_rad[k]);
            [n, e, heading_of(&t.q_b_to_n[k])]
        };
        let t0 = track(base.0, base.1);
        let tracks: Vec<NavTrack> = moved
            .iter()
            .map(|mv| track(&mv.inputs, &mv.settings))
            .collect();
        let mut out = [Vec::new(), Vec::new(), Vec::new()];
        for &k in samples {
            let y0 = y(&t0, base.1, k);
            let g: Vec<[f64; 3]> = moved
                .iter()
                .zip(&tracks)
                .map(|(mv, t)| {
                    let yj = y(t, &mv.settings, k);
                    [yj[0] - y0[0], yj[1] - y0[1], wrap_pi(yj[2] - y0[2])].map(|v| v / mv.step)
                })
                .collect();
            for (q, out) in out.iter_mut().enumerate() {
                let mut v = 0.0;
                for a in 0..g.len() {
                    for b in 0..g.len() {
                        v += g[a][q] * covariance[(a, b)] * g[b][q];
                    }
                }
                out.push(v.max(0.0).sqrt());
            }
        }
        out
    }

    #[test]
    fn the_route_sigma_is_its_definition_bit_for_bit_in_one_batch_or_more_or_run_before() {
        let n = 2003;
        let (dt, dtheta, odo, later) = drive(n);
        let inputs = NavInputs {
            dt_s: &dt,
            dtheta_rad: (&dtheta).into(),
            odo_dist_m: &odo,
        };
        let at_lag = NavInputs {
            odo_dist_m: &later,
            ..inputs
        };
        let corrected = settings(0);
        let mut base = RouteBase::new(&corrected, &dt, 0.0, 10);
        strapdown::run(&inputs, &corrected, &mut base);
        let samples = route_samples(n, 10);
        assert_eq!(*samples.last().unwrap(), n - 1);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        // Six moved passes, the last at another odometer timing, fit in one batch of
        // lanes; ten (nine settings and the lag) do not. The pass at the other timing
        // either runs beside the others or has run before (its states kept).
        for (m, lag_ran) in [(6, false), (6, true), (10, false), (10, true)] {
            let moved: Vec<Moved<'_>> = (1..=m)
                .map(|j| Moved {
                    inputs: if j == m { at_lag } else { inputs },
                    settings: settings(j),
                    step: 0.5 + 0.1 * j as f64,
                })
                .collect();
            let c = covariance(m);
            let states = states_along(&inputs, later.iter().copied(), &settings(m), &samples);
            let sigma = if lag_ran {
                let ran = [Ran {
                    states: &states,
                    step: moved[m - 1].step,
                }];
                route_sigma(&base, &moved[..m - 1], &ran, &c, None)
            } else {
                route_sigma(&base, &moved, &[], &c, None)
            };
            assert_eq!(sigma.sample, samples);
            let want = sigma_by_hand((&inputs, &corrected), &moved, &c, &samples);
            assert!(
                want[0].iter().all(|v| *v > 0.0),
                "the passes move the route"
            );
            let case = format!("{m} moved, the lag's run before: {lag_ran}");
            assert_eq!(bits(&sigma.north_m), bits(&want[0]), "{case}");
            assert_eq!(bits(&sigma.east_m), bits(&want[1]), "{case}");
            assert_eq!(bits(&sigma.heading_rad), bits(&want[2]), "{case}");
        }
    }

    #[test]
    fn a_range_interpolates_as_the_whole_run_does() {
        let sigma = RouteSigma {
            sample: vec![0, 10, 20, 25],
            north_m: vec![1.0, 2.0, 4.0, 8.0],
            east_m: vec![0.5, 0.25, 3.0, 1.0],
            heading_rad: vec![0.0, 0.1, 0.2, 0.3],
        };
        let whole = sigma.at_samples(0..27);
        // Values between the samples, and held after the last.
        assert_eq!(whole[0][5], 1.5);
        assert_eq!(whole[0][26], 8.0);
        // Each σ with its own values, at the same weights.
        assert_eq!(whole[1][15], 1.625);
        assert_eq!(whole[2][10], 0.1);
        assert_eq!(whole[2][26], 0.3);
        for lo in 0..27 {
            for hi in lo..=27 {
                let part = sigma.at_samples(lo..hi);
                for q in 0..3 {
                    assert_eq!(part[q], whole[q][lo..hi], "{lo}..{hi}");
                }
            }
        }
        let none = RouteSigma::default().at_samples(3..7);
        assert_eq!(none[1], vec![0.0; 4]);
        // Before the first σ's sample: its value held. Every sample, bit for bit, as
        // each one's own weight between the σ's on either side gives.
        let later = RouteSigma {
            sample: vec![3, 13, 20, 23],
            ..sigma
        };
        let all = later.at_samples(0..40);
        for (k, n) in all[0].iter().enumerate() {
            let j = later.sample.partition_point(|&s| s <= k).saturating_sub(1);
            let (a, b) = (later.sample[j], later.sample[(j + 1).min(3)]);
            let w = if b > a {
                ((k as f64 - a as f64) / (b - a) as f64).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let v = &later.north_m;
            let want = v[j] + w * (v[(j + 1).min(3)] - v[j]);
            assert_eq!(n.to_bits(), want.to_bits(), "sample {k}");
        }
        assert_eq!(all[0][..4], [1.0; 4]);
    }

    /// The walk's share along the route by its running sums is its definition's sum of
    /// squares (`Σ_j q Δt_j (b_kj + S_k u_j)²`, each kick's own turn of the route and the
    /// settings' answer to it), less the fit's heading share, at every sample: three
    /// stretches, settings sensitivities that vary along the route.
    #[test]
    fn the_walks_share_by_running_sums_is_its_sum_of_squares() {
        let p = 3;
        let stretches: Vec<f64> = (0..3 * p * 3)
            .map(|i| ((i * 37 % 17) as f64 - 8.0) * 0.013)
            .collect();
        let heading_share: Vec<f64> = (0..p * p)
            .map(|i| 1e-4 * (1.0 + (i % (p + 1) == 0) as u8 as f64))
            .collect();
        let uptake = WalkUptake {
            q_rad2_s: 4e-10,
            settings: p,
            bounds_s: vec![3.0, 7.5],
            stretches,
            heading_share,
        };
        let n = 120;
        let t_s: Vec<f64> = (1..=n).map(|k| 0.1 * k as f64).collect();
        let y: Vec<[f64; 3]> = (0..n)
            .map(|k| {
                let t = 0.1 * k as f64;
                [
                    100.0 * t.sin() + 20.0 * t,
                    80.0 * (0.7 * t).cos() - 5.0 * t,
                    0.3 * t,
                ]
            })
            .collect();
        let sens = |k: usize| -> Vec<[f64; 3]> {
            (0..p + 1)
                .map(|a| {
                    let f = (a + 1) as f64 * (1.0 + 0.01 * k as f64);
                    [3.0 * f, -2.0 * f + 0.5, 0.01 * f]
                })
                .collect()
        };
        let mut cross = WalkCross::new(&uptake, &t_s, &y);
        let u_at = |j: usize| {
            let mut u = vec![0.0; p];
            uptake.step_per_kick(t_s[j], y[j][0], y[j][1], &mut u);
            u
        };
        for k in 0..n {
            let g = sens(k);
            let got = cross.next(t_s[k], &y[k], &g);
            for q in 0..3 {
                let mut want = 0.0;
                for j in 0..n {
                    let dt = t_s[j] - if j > 0 { t_s[j - 1] } else { 0.0 };
                    let u = u_at(j);
                    let su: f64 = (0..p).map(|a| g[a][q] * u[a]).sum();
                    let b = if j <= k {
                        [-(y[k][1] - y[j][1]), y[k][0] - y[j][0], 1.0][q]
                    } else {
                        0.0
                    };
                    want += uptake.q_rad2_s * dt * (b + su) * (b + su);
                }
                let fit: f64 = (0..p)
                    .flat_map(|a| (0..p).map(move |b| (a, b)))
                    .map(|(a, b)| g[a][q] * uptake.heading_share[a * p + b] * g[b][q])
                    .sum();
                want -= fit;
                let scale = want.abs().max(fit.abs()).max(1e-12);
                assert!(
                    (got[q] - want).abs() <= 1e-9 * scale,
                    "sample {k}, quantity {q}: {} against {want}",
                    got[q]
                );
            }
        }
    }
}
