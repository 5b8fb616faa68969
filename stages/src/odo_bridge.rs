//! An odometer failure bridged by the inertial along-track speed.
//!
//! A land vehicle moves along its body x axis (no side-slip, no lift), so its along-track
//! speed v obeys `v̇ = f_x + g·(u·x)`: the accelerometer's specific force along x plus
//! gravity's part along x, with `u` the direction of gravity (down) and `x` the body's x
//! axis in one frame. The gyros carry the body's axes across the failure, relative to the
//! body's axes at the window's first sample (frame 0): `x_k = R_k·e_x`, with `R_k` the
//! product of the angle increments' rotations. Gravity's direction in frame 0 is then
//! what is unknown: two tilt angles, plus a slow turn of it at a constant rate (the Earth's
//! rate and the gyros' drift, which frame 0 — fixed to inertial space — does not follow).
//!
//! The odometer's distances around the failure determine those, with the speed at the
//! window's start: up to [`WINDOW_S`] of the odometer working before the failure (its
//! distances are the route's) and after it (the count may have held, jumped or restarted
//! meanwhile, so those are off the route's by an unknown offset). Two more unknowns the
//! tilt cannot stand for once the vehicle turns: the x accelerometer's bias (fixed to the
//! body, where a tilt is fixed to frame 0) and the odometer's scale error (its readings
//! are in its nominal metres per pulse, the inertial speed in metres; the bridge is given
//! in the readings' metres, as the rest of the route is). The model is linear in the start
//! distance, the start speed, the tilt's two angles and two drift rates, the bias, the
//! scale error (which scales the inertial distance's every term; the others' columns
//! absorb its product with them) and the offset, given gravity's direction around which
//! the angles are taken; it is solved by least squares and re-centred on the new direction
//! until the angles vanish (Gauss–Newton). The tilt's angles and rates, the bias and the
//! scale error get priors, for what a window does not see (the cross-track tilt of a
//! straight drive, the drift of a short window, the scale at a constant speed).
//!
//! Two windows, at both ends of the failure, see the speed and the tilt along the track
//! at both ends, which is what errors of the start's tilt, of the accelerometer biases
//! (they cancel with the tilt that absorbs them) and of the Earth's rate would otherwise
//! integrate into the distance across it.
//!
//! The odometer may be late (the joint fit estimates its lag later, from the whole run):
//! its reading at t is the route at t − lag, while the IMU's increments are on time. A
//! bridge that took it on time put the inertial speed's changes a lag early against the
//! readings, and the tilt it fitted to them was off: a 0.4-s lag made 30-s bridges 13 m
//! rms off (69 m at most). So each failure's fit is made at lags on a 0.2-s grid over
//! ±1 s (the joint's bound; each fit starts from its neighbour's gravity direction) and
//! at the vertex of the parabola through the best three, with a prior that holds the lag
//! near zero where the readings do not see it; the bridge is then in the odometer's time
//! base, as the readings are. A lag the readings around a failure do not show (the
//! vehicle at rest on one side, at a constant speed on the other) is not found here: the
//! bridge is then off by the lag times the change of speed, until the disupt stage
//! bridges the failure again at the lags its joint fit tries ([`bridge_at_lag`],
//! [`crate::odo_rebridge`]).
//!
//! Measured against truth on 30 simulated failures of each length (every sensor error
//! on, hills and turns, readings in the nominal metres per pulse;
//! `stages/tests/odo_bridge.rs`), rms (max) in the odometer's metres: on time, 0.015 m
//! (0.032) over 10 s, 0.13 m (0.33) over 30 s, 0.69 m (1.6) over 60 s, 4.4 m (17) over
//! 120 s; 0.4 s late, 0.022 m (0.089), 0.92 m (4.3), 1.1 m (3.0). With the odometer's
//! scale 1 % off (the simulator's are 0.05–0.3 %): 0.014 m (0.032), 0.39 m (1.5), 1.1 m
//! (3.1); 0.4 s late 0.022 m (0.088), 0.97 m (4.3), 1.6 m (3.7). Without the scale error
//! and the bias among the unknowns the same 60-s failures were 1.1 m (4.8) off, and
//! 4.4 m (23) with the scale 1 % off.
//!
//! Neglected: the IMU's lever arm and its yaw on the vehicle (a 1° boresight scales the
//! along-track acceleration by 0.99985). The Coriolis acceleration (2Ω × v, ≤ 3 mm/s² at
//! 20 m/s) is across the velocity, never along the track.

use nalgebra::{DMatrix, DVector, Rotation3, Vector3};

/// The odometer's working time used at each end of a failure, s.
pub const WINDOW_S: f64 = 10.0;

/// Odometer distance noise the fit weighs the readings by, m: a pulse of 1–2 cm and
/// the wheel's slip.
const DISTANCE_SIGMA_M: f64 = 0.02;
/// Prior σ of the tilt angles' correction, rad: weak (the first guess is within a few
/// degrees), it holds only what the readings do not see.
const TILT_SIGMA_RAD: f64 = 0.1;
/// Prior σ of the tilt's drift rate, rad/s: twice the horizontal Earth rate.
const TILT_RATE_SIGMA_RAD_S: f64 = 1.5e-4;
/// Prior σ of the x accelerometer's bias, m/s² (1 mg; an LN-200's is a few tenths).
const ACCEL_BIAS_SIGMA_MPS2: f64 = 0.01;
/// Prior σ of the odometer's scale error against its nominal metres per pulse. A tyre's
/// radius is known to a percent or so, but a window of 10 s sees the scale only through
/// its changes of speed, where the lag is seen too: of 0.3, 0.5 and 1 %, 0.5 % did best
/// on scale errors of 0.05–1.3 % with and without a lag.
const ODO_SCALE_SIGMA: f64 = 0.005;
/// Prior σs of the unknowns from the tilt on: α, β, α̇, β̇, the bias, the scale error.
const PRIOR_SIGMAS: [f64; 6] = [
    TILT_SIGMA_RAD,
    TILT_SIGMA_RAD,
    TILT_RATE_SIGMA_RAD_S,
    TILT_RATE_SIGMA_RAD_S,
    ACCEL_BIAS_SIGMA_MPS2,
    ODO_SCALE_SIGMA,
];
/// Gauss–Newton iterations at most.
const MAX_ITERATIONS: usize = 8;
/// Iterations of an SVD at most (nine columns converge in a few dozen).
const SVD_MAX_ITERATIONS: usize = 1000;
/// Fastest a bridge may say the vehicle drove, m/s (360 km/h, the ingest's range of a
/// land vehicle's odometer).
const MAX_SPEED_MPS: f64 = 100.0;
/// Fastest a bridge may say the vehicle reversed, m/s: a fit that runs the route
/// backwards faster is no bridge (a failure at a log's end, fitted from one side over
/// half a minute, ran it back 1.7 km).
const MAX_REVERSE_MPS: f64 = 10.0;
/// The longest interval between the window's IMU samples bridged across, s.
const MAX_SAMPLE_INTERVAL_S: f64 = 1.0;
/// Readings a fit needs at least.
const MIN_READINGS: usize = 10;
/// The odometer's lag is searched over ±this about its prior, s: the joint fit's bound.
const MAX_LAG_S: f64 = 1.0;
/// Grid steps each side of the prior (0.2 s; the vertex of a parabola refines it).
const LAG_STEPS: i32 = 5;
/// Prior σ of the lag, s: holds it near its prior (zero unless configured) where the
/// readings do not see it (a constant speed about the failure, where it does not matter
/// either). Of 0.2, 0.5 and
/// 2 s, 0.2 s did best on failures without a lag and about as well with 0.4 s.
const LAG_SIGMA_S: f64 = 0.2;

/// What the odometer said at one sample of a bridge's window.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Reading {
    /// Working before the failure: the route's distance, m.
    Before(f64),
    /// Flagged failed: no distance.
    Failed,
    /// Working again after the failure: a distance, m, off the route's by an offset.
    After(f64),
}

/// One IMU sample of a bridge's window.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BridgeSample {
    /// Time tag at the end of the sample's interval, s (any origin).
    pub t_s: f64,
    /// Angle increments over the interval, body FRD, rad.
    pub dtheta_rad: [f64; 3],
    /// Velocity increments over the interval, body FRD, m/s.
    pub dvel_mps: [f64; 3],
    /// The odometer's reading at the sample.
    pub reading: Reading,
}

/// A failure bridged.
#[derive(Debug, Clone, PartialEq)]
pub struct Bridge {
    /// The route's distance at each [`Reading::Failed`] sample, in order, m: continuous
    /// with the last [`Reading::Before`] reading (with none, the window's first sample is
    /// at 0).
    pub failed_distance_m: Vec<f64>,
    /// Added to the [`Reading::After`] readings, m, so that the first of them continues
    /// the bridge; 0 with none.
    pub after_offset_m: f64,
    /// The distance the bridge adds across the failure, m: from the last reading before
    /// it to the first after it (or to the last failed sample).
    pub across_m: f64,
    /// Root-mean-square residual of the readings the fit used, m.
    pub rms_residual_m: f64,
    /// The odometer's lag the readings around the failure show, s (positive: late):
    /// the bridge is in the odometer's time base, the inertial speed moved by it.
    pub lag_s: f64,
}

/// Terms of the model's distance: the constant part, then one per unknown from the speed
/// onwards.
const TERMS: usize = 7;

/// The along-track speed and distance over a window, each as an affine function of the
/// unknowns `[d0, v0, α, β, α̇, β̇, b]` (start distance, start speed, tilt angles about
/// the two axes across gravity, their rates, and the x accelerometer's bias): column 0
/// the constant part, then one column per unknown from the speed onwards (the distance's
/// own unknown is added by the caller).
struct Model {
    /// Distance at each sample: constant, then ∂/∂[v0, α, β, α̇, β̇, b].
    distance: Vec<[f64; TERMS]>,
}

impl Model {
    fn new(window: &[BridgeSample], axes: &[Vector3<f64>], u: Vector3<f64>, g_mps2: f64) -> Self {
        let (p, q) = across(&u);
        let t0 = window[0].t_s;
        let mut speed = [0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let mut distance = Vec::with_capacity(window.len());
        distance.push([0.0; TERMS]);
        for k in 1..window.len() {
            let dt = (window[k].t_s - window[k - 1].t_s).max(0.0);
            let tau = 0.5 * (window[k].t_s + window[k - 1].t_s) - t0;
            let x = 0.5 * (axes[k - 1] + axes[k]);
            let g_dt = g_mps2 * dt;
            let step = [
                window[k].dvel_mps[0] + g_dt * u.dot(&x),
                0.0,
                g_dt * p.dot(&x),
                g_dt * q.dot(&x),
                g_dt * tau * p.dot(&x),
                g_dt * tau * q.dot(&x),
                -dt,
            ];
            let last = distance[k - 1];
            let mut d = [0.0; TERMS];
            for i in 0..TERMS {
                let v_before = speed[i];
                speed[i] += step[i];
                d[i] = last[i] + 0.5 * (v_before + speed[i]) * dt;
            }
            distance.push(d);
        }
        Self { distance }
    }

    /// The model at a time given by [`between`].
    fn at(&self, (k, w): Between) -> [f64; TERMS] {
        let (a, b) = (&self.distance[k - 1], &self.distance[k]);
        std::array::from_fn(|i| a[i] + w * (b[i] - a[i]))
    }
}

/// A time between samples `k − 1` and `k`, at weight `w` from the first (linear, and
/// beyond the ends).
type Between = (usize, f64);

/// Where each of `times` less `lag_s` falls among `times` (increasing, at least two).
fn between(times: &[f64], lag_s: f64) -> Vec<Between> {
    let n = times.len();
    let mut k = 1;
    times
        .iter()
        .map(|&t| {
            let t_s = t - lag_s;
            // The times are increasing, and so are these: a forward walk.
            while k < n - 1 && times[k] <= t_s {
                k += 1;
            }
            while k > 1 && times[k - 1] > t_s {
                k -= 1;
            }
            let (t0, t1) = (times[k - 1], times[k]);
            (k, if t1 > t0 { (t_s - t0) / (t1 - t0) } else { 0.0 })
        })
        .collect()
}

/// Two unit vectors across `u`, and across each other.
fn across(u: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let helper = if u.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let p = u.cross(&helper).normalize();
    (p, u.cross(&p))
}

/// Bridges the failure in `window` (its failed samples between the odometer's readings
/// before and after them) with the along-track speed the IMU gives; `g_mps2` is gravity
/// at the site, `lag_prior_s` the odometer's lag as far as it is known (a user's
/// configured time offset, negated; 0 without), around which the lag is searched.
/// `None` when the window has fewer than 10 readings, IMU samples more than a second
/// apart (samples lost), a fit that is not finite, or a speed across the failure that is
/// no land vehicle's (beyond 100 m/s ahead or 10 m/s backwards).
pub fn bridge(window: &[BridgeSample], g_mps2: f64, lag_prior_s: f64) -> Option<Bridge> {
    let lag_prior_s = if lag_prior_s.is_finite() {
        lag_prior_s
    } else {
        0.0
    };
    let prepared = Prepared::of(window)?;
    let problem = prepared.fit(window, g_mps2, lag_prior_s);
    // The odometer's lag: on a grid over ±MAX_LAG_S about the prior, then at the vertex
    // of the parabola through the best and its neighbours. Each fit starts from
    // gravity's direction at the lag before it (from the prior out).
    let zero = problem.solve(prepared.u0, lag_prior_s)?;
    let mut grid: Vec<(f64, Solved)> = Vec::with_capacity(2 * LAG_STEPS as usize + 1);
    for side in [-1.0, 1.0] {
        let mut u = zero.u;
        for i in 1..=LAG_STEPS {
            let lag_s = lag_prior_s + side * MAX_LAG_S * f64::from(i) / f64::from(LAG_STEPS);
            if let Some(f) = problem.solve(u, lag_s) {
                u = f.u;
                grid.push((lag_s, f));
            }
        }
    }
    grid.push((lag_prior_s, zero));
    grid.sort_by(|a, b| a.0.total_cmp(&b.0));
    let best = (0..grid.len()).min_by(|&i, &j| grid[i].1.cost.total_cmp(&grid[j].1.cost))?;
    let mut solved = grid[best].1.clone();
    let mut lag_s = grid[best].0;
    if best > 0 && best + 1 < grid.len() {
        // Through three points of any spacing (a failed fit may have left the grid
        // uneven).
        let x: [f64; 3] = std::array::from_fn(|i| grid[best - 1 + i].0);
        let y: [f64; 3] = std::array::from_fn(|i| grid[best - 1 + i].1.cost);
        if let Some((vertex, _)) = crate::odo_lag::parabola(x, y) {
            let vertex = vertex.clamp(x[0], x[2]);
            if let Some(f) = problem
                .solve(solved.u, vertex)
                .filter(|f| f.cost < solved.cost)
            {
                solved = f;
                lag_s = vertex;
            }
        }
    }
    bridge_of(window, solved, prepared.readings, lag_s)
}

/// Bridges the failure in `window` as [`bridge`] does, with the odometer's lag known:
/// `lag_s` late (its reading at t is the route at t − lag). One fit, without a search:
/// what the disupt stage does at each lag it tries, once the whole run shows the lag
/// (the readings around a failure from a stop do not).
pub fn bridge_at_lag(window: &[BridgeSample], g_mps2: f64, lag_s: f64) -> Option<Bridge> {
    if !lag_s.is_finite() {
        return None;
    }
    let prepared = Prepared::of(window)?;
    let solved = prepared
        .fit(window, g_mps2, lag_s)
        .solve(prepared.u0, lag_s)?;
    bridge_of(window, solved, prepared.readings, lag_s)
}

/// What a window's fits start from.
struct Prepared {
    /// The body's x axis at each sample, in frame 0.
    axes: Vec<Vector3<f64>>,
    /// Gravity's direction, a first guess.
    u0: Vector3<f64>,
    /// The odometer's readings (samples not failed).
    readings: usize,
    /// Unknowns.
    n_x: usize,
}

impl Prepared {
    /// `None` when the window has fewer than [`MIN_READINGS`] readings, or samples
    /// further apart than [`MAX_SAMPLE_INTERVAL_S`].
    fn of(window: &[BridgeSample]) -> Option<Self> {
        let readings = window
            .iter()
            .filter(|s| !matches!(s.reading, Reading::Failed))
            .count();
        if readings < MIN_READINGS || window.len() < 2 {
            return None;
        }
        // The IMU's increments must cover the window: across samples lost, the inertial
        // speed is unknown.
        if window
            .windows(2)
            .any(|w| w[1].t_s - w[0].t_s > MAX_SAMPLE_INTERVAL_S)
        {
            return None;
        }
        let has_before = window
            .iter()
            .any(|s| matches!(s.reading, Reading::Before(_)));
        let has_after = window
            .iter()
            .any(|s| matches!(s.reading, Reading::After(_)));
        // The body's x axis at each sample, in frame 0; gravity's direction from the
        // summed specific force (in frame 0 it is the change of velocity less g·u·T: a
        // vehicle's change of speed over the window tilts the guess by a few degrees at
        // most).
        let mut axes = Vec::with_capacity(window.len());
        let mut r = Rotation3::identity();
        let mut force = Vector3::zeros();
        axes.push(Vector3::x());
        for s in &window[1..] {
            let r_before = r;
            r *= Rotation3::from_scaled_axis(Vector3::from(s.dtheta_rad));
            force += (r_before * Rotation3::from_scaled_axis(0.5 * Vector3::from(s.dtheta_rad)))
                * Vector3::from(s.dvel_mps);
            axes.push(r * Vector3::x());
        }
        let u0 = -force.try_normalize(f64::MIN_POSITIVE)?;
        // Unknowns: [d0, v0, α, β, α̇, β̇, b, κ] and, with readings after, their offset.
        let n_x = if has_after && has_before { 9 } else { 8 };
        Some(Self {
            axes,
            u0,
            readings,
            n_x,
        })
    }

    /// The window's fits, the lag's prior at `lag_prior_s`.
    fn fit<'a>(&'a self, window: &'a [BridgeSample], g_mps2: f64, lag_prior_s: f64) -> Fit<'a> {
        Fit {
            window,
            times: window.iter().map(|s| s.t_s).collect(),
            axes: &self.axes,
            g_mps2,
            n_x: self.n_x,
            readings: self.readings,
            lag_prior_s,
        }
    }
}

/// The bridge of `window` from its fit at `lag_s`.
fn bridge_of(
    window: &[BridgeSample],
    solved: Solved,
    readings: usize,
    lag_s: f64,
) -> Option<Bridge> {
    let Solved { route, squares, .. } = solved;
    // Continuous with the last reading before (else the first sample at 0), and the
    // readings after continuous with the bridge.
    let last_before = window
        .iter()
        .rposition(|s| matches!(s.reading, Reading::Before(_)));
    let shift = match last_before.map(|k| (k, window[k].reading)) {
        Some((k, Reading::Before(given))) => given - route[k],
        _ => -route[0],
    };
    let failed_distance_m: Vec<f64> = window
        .iter()
        .zip(&route)
        .filter(|(s, _)| matches!(s.reading, Reading::Failed))
        .map(|(_, d)| d + shift)
        .collect();
    let first_after = window
        .iter()
        .zip(&route)
        .find_map(|(s, d)| match s.reading {
            Reading::After(given) => Some((d + shift, given)),
            _ => None,
        });
    let start = last_before.map_or(0.0, |k| route[k] + shift);
    let (after_offset_m, end) = match first_after {
        Some((d, given)) => (d - given, d),
        None => (0.0, failed_distance_m.last().copied().unwrap_or(start)),
    };
    let bridge = Bridge {
        failed_distance_m,
        after_offset_m,
        across_m: end - start,
        rms_residual_m: (squares / readings as f64).sqrt(),
        lag_s,
    };
    let finite = bridge.failed_distance_m.iter().all(|d| d.is_finite())
        && bridge.after_offset_m.is_finite()
        && bridge.rms_residual_m.is_finite();
    // A land vehicle's speed across the failure, into and out of it.
    let driven = (1..window.len())
        .filter(|&k| {
            matches!(window[k].reading, Reading::Failed)
                || matches!(window[k - 1].reading, Reading::Failed)
        })
        .all(|k| {
            let dt = window[k].t_s - window[k - 1].t_s;
            let step_m = route[k] - route[k - 1];
            dt <= 0.0 || (-MAX_REVERSE_MPS * dt..=MAX_SPEED_MPS * dt).contains(&step_m)
        });
    (finite && driven).then_some(bridge)
}

/// A window's fit at one odometer lag.
#[derive(Debug, Clone)]
struct Solved {
    /// The route's distance at each sample's time less the lag (the odometer's time
    /// base), before the anchoring shift, m.
    route: Vec<f64>,
    /// Sum of the readings' squared residuals, m².
    squares: f64,
    /// The readings' χ² plus the lag's prior.
    cost: f64,
    /// Gravity's direction it converged to (a start for the fit at a nearby lag).
    u: Vector3<f64>,
}

/// What a window's fits share.
struct Fit<'a> {
    window: &'a [BridgeSample],
    /// The window's time tags, s.
    times: Vec<f64>,
    axes: &'a [Vector3<f64>],
    g_mps2: f64,
    n_x: usize,
    readings: usize,
    /// The lag's prior, s.
    lag_prior_s: f64,
}

impl Fit<'_> {
    /// The fit with the odometer `lag_s` late (its reading at t is the route at
    /// t − lag), Gauss–Newton from gravity's direction `u0`.
    fn solve(&self, u0: Vector3<f64>, lag_s: f64) -> Option<Solved> {
        let (window, n_x) = (self.window, self.n_x);
        let at = between(&self.times, lag_s);
        let rows = self.readings + PRIOR_SIGMAS.len();
        let mut u = u0;
        for iteration in 0.. {
            let model = Model::new(window, self.axes, u, self.g_mps2);
            // The model at each sample's time less the lag.
            let lagged: Vec<[f64; TERMS]> = at.iter().map(|&b| model.at(b)).collect();
            let mut a = DMatrix::zeros(rows, n_x);
            let mut b = DVector::zeros(rows);
            let mut row = 0;
            for (s, d) in window.iter().zip(&lagged) {
                let (given, offset) = match s.reading {
                    Reading::Failed => continue,
                    Reading::Before(given) => (given, 0.0),
                    Reading::After(given) => (given, -1.0),
                };
                a[(row, 0)] = 1.0;
                a.view_mut((row, 1), (1, TERMS - 1))
                    .iter_mut()
                    .zip(&d[1..])
                    .for_each(|(a, d)| *a = *d);
                a[(row, TERMS)] = d[0];
                if n_x == TERMS + 2 {
                    a[(row, TERMS + 1)] = offset;
                }
                b[row] = given - d[0];
                row += 1;
            }
            a.rows_mut(0, row).scale_mut(1.0 / DISTANCE_SIGMA_M);
            b.rows_mut(0, row).scale_mut(1.0 / DISTANCE_SIGMA_M);
            for (i, sigma) in PRIOR_SIGMAS.into_iter().enumerate() {
                a[(row + i, 2 + i)] = 1.0 / sigma;
            }
            let solution = solve_scaled(a, b)?;
            let (p, q) = across(&u);
            let turn = solution[2] * p + solution[3] * q;
            if turn.norm() < 1e-10 || iteration + 1 == MAX_ITERATIONS {
                let route: Vec<f64> = lagged
                    .iter()
                    .map(|d| {
                        d[0] * (1.0 + solution[TERMS])
                            + solution[0]
                            + (1..TERMS).map(|i| d[i] * solution[i]).sum::<f64>()
                    })
                    .collect();
                let offset = if n_x == TERMS + 2 {
                    solution[TERMS + 1]
                } else {
                    0.0
                };
                let mut squares = 0.0;
                for (s, d) in window.iter().zip(&route) {
                    match s.reading {
                        Reading::Before(given) => squares += (d - given).powi(2),
                        Reading::After(given) => squares += (d - offset - given).powi(2),
                        Reading::Failed => {}
                    }
                }
                let cost = squares / DISTANCE_SIGMA_M.powi(2)
                    + ((lag_s - self.lag_prior_s) / LAG_SIGMA_S).powi(2);
                return cost.is_finite().then_some(Solved {
                    route,
                    squares,
                    cost,
                    u,
                });
            }
            // Re-centre gravity's direction on the angles found, and take them again
            // around it.
            u = (u + turn).try_normalize(f64::MIN_POSITIVE)?;
        }
        None
    }
}

/// Least squares of `a·x ≈ b`, its columns scaled to unit length first (the unknowns'
/// columns span ten orders of magnitude), by singular values.
fn solve_scaled(mut a: DMatrix<f64>, b: DVector<f64>) -> Option<DVector<f64>> {
    let scales: Vec<f64> = a
        .column_iter()
        .map(|c| {
            let n = c.norm();
            if n > 0.0 { 1.0 / n } else { 1.0 }
        })
        .collect();
    for (j, s) in scales.iter().enumerate() {
        a.column_mut(j).scale_mut(*s);
    }
    // A log's values are untrusted: a matrix that is not finite, or an SVD that does not
    // converge within its iterations, is no bridge (never an endless loop).
    if !a.iter().chain(b.iter()).all(|v| v.is_finite()) {
        return None;
    }
    let x = a
        .try_svd(true, true, f64::EPSILON, SVD_MAX_ITERATIONS)?
        .solve(&b, 1e-12)
        .ok()?;
    Some(DVector::from_iterator(
        x.len(),
        x.iter().zip(&scales).map(|(x, s)| x * s),
    ))
}
