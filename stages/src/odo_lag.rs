//! The odometer's lag, estimated with the joint fit.
//!
//! Odometer timing enters the dead-reckoned route (each distance increment is resolved
//! with the heading of another moment) and the accelerometer references Θ_p/Φ_p (through
//! u̇ and ru). Both are exact in a re-derive with the odometer's time tags shifted, at any
//! continuous shift (derive interpolates the cumulative distance); see [`Rederive::at`].
//!
//! The lag is found by an outer one-dimensional search over such re-derives (successive
//! parabolas: the score is near-quadratic in the lag). At each trial lag the joint fit
//! estimates every other setting from the attitude residuals and the control points (the
//! epochs' weight held at that of the fit without a lag), and the trial is scored by the
//! control points' part of its cost: what the route at the stops says of the timing.
//! Each trial's fit is solved on the lag-free fit's linearisation around one exact pass
//! on the trial's derive (the other settings move little with the lag, well within what
//! the linearisation holds for): one pass per trial, where a fit with its own exact
//! check took two, and every trial on the same model, so the score is smooth in the lag.
//! A parabola's three trials run side by side, each lane on its own derive's odometer
//! increments ([`crate::disupt::observe_each`]), and the score at its vertex is read off
//! the parabola: a round costs one batch of passes. The fit at the estimated lag is then
//! done in full, checked by exact passes. The attitude references are no judge of it:
//! eq 10's u̇ carries the odometer's pulse quantisation aliased to low frequencies, whose
//! pull on the lag is biased (measured on a simulated run with a 0.4 s lag: the whole
//! cost is smallest at 0.367 s, its control-point part at 0.400 s). Its 1σ comes from the
//! score's curvature at the optimum: the control points' residuals are weighted by their
//! σ, so the score rises by 1 at one σ of the lag, `σ_L² = 2 / (∂²score/∂L²)`, scaled by
//! the control points' misfit when that is worse than their σ says. The other settings'
//! σ are those at the optimum lag (conditional on it).
//!
//! Positive lag: the odometer reports late; derive's `odo_time_offset_s` is then lowered
//! by the lag.

use std::cell::RefCell;
use std::sync::{Mutex, OnceLock};

use crate::derive::{
    DeriveParams, Derived, MovedOdometer, OdoBlockSeries, OdoIncrements, OdoTimes, OdometerBlocks,
    RawSeries, derive, epochs_of, filtered_stretches, odometer_blocks_split, shifted_blocks,
};
use crate::disupt::{
    DisuptError, DisuptParams, JointFit, JointOptions, Problem, ProblemSpec, joint_fit,
    observe_each, x_of,
};
use crate::filter::LowPass;
use crate::linearized::{Linearization, Setting};
use crate::odo_rebridge::Rebridges;
use crate::strapdown::segments::{
    IncrementSource, OdoColumns, OdoSegments, SegmentPlan, integrate_split, integrate_split_aligned,
};

/// Half-width of the parabolas around the current vertex (and of the curvature), s.
const CURVATURE_STEP_S: f64 = 0.05;
/// The search stops when the vertex moves less than this, s.
const TOLERANCE_S: f64 = 2e-3;
/// Parabolas at most.
const MAX_ROUNDS: usize = 5;

/// Vertex and second derivative of the parabola through `(x_i, y_i)`, when it is convex.
pub(crate) fn parabola(x: [f64; 3], y: [f64; 3]) -> Option<(f64, f64)> {
    let d = (x[0] - x[1]) * (x[0] - x[2]) * (x[1] - x[2]);
    if d == 0.0 {
        return None;
    }
    let a = (x[2] * (y[1] - y[0]) + x[1] * (y[0] - y[2]) + x[0] * (y[2] - y[1])) / d;
    let b =
        (x[2] * x[2] * (y[0] - y[1]) + x[1] * x[1] * (y[2] - y[0]) + x[0] * x[0] * (y[1] - y[2]))
            / d;
    (a > 0.0 && a.is_finite()).then(|| (-b / (2.0 * a), 2.0 * a))
}

/// The value at `at` of the parabola through `(x_i, y_i)` (Lagrange's form).
fn through(x: [f64; 3], y: [f64; 3], at: f64) -> f64 {
    (0..3)
        .map(|i| {
            let (j, k) = ((i + 1) % 3, (i + 2) % 3);
            y[i] * (at - x[j]) * (at - x[k]) / ((x[i] - x[j]) * (x[i] - x[k]))
        })
        .sum()
}

/// The joint fit at the estimated lag.
#[derive(Debug, Clone)]
pub struct LagFit {
    /// Estimated lag, s (positive: the odometer reports late).
    pub lag_s: f64,
    /// Its 1σ, s; `None` where the cost profile has no curvature there.
    pub sigma_s: Option<f64>,
    /// The derive at the lag.
    pub derived: Derived,
    /// The joint fit there.
    pub fit: JointFit,
    /// Every trial (lag s, the control points' part of the fit's cost), in the order tried.
    pub profile: Vec<[f64; 2]>,
}

/// What a re-derive needs.
#[derive(Debug)]
pub struct Rederive<'a> {
    /// The ingested IMU and odometer series.
    pub raw: RawSeries<'a>,
    /// The derive parameters the cached derive used.
    pub params: DeriveParams,
    /// Normal gravity at the site, m/s².
    pub g_mps2: f64,
    /// The configured derive, when the caller has it (the derive stage's cache).
    configured: Option<&'a Derived>,
    base: OnceLock<Derived>,
    /// The odometer's bridged failures, bridged again at each lag.
    rebridges: Option<Rebridges<'a>>,
}

impl<'a> Rederive<'a> {
    /// Re-derives of `raw` around `params`.
    pub fn new(raw: RawSeries<'a>, params: DeriveParams, g_mps2: f64) -> Self {
        Self {
            raw,
            params,
            g_mps2,
            configured: None,
            base: OnceLock::new(),
            rebridges: None,
        }
    }

    /// Re-derives whose odometer's failures are bridged again at their lag
    /// ([`Rebridges`]).
    pub fn with_rebridges(self, rebridges: Option<Rebridges<'a>>) -> Self {
        Self { rebridges, ..self }
    }

    /// The odometer's bridged failures, bridged again at each lag, if any.
    pub fn rebridges(&self) -> Option<&Rebridges<'a>> {
        self.rebridges.as_ref()
    }

    /// Re-derives around `configured`, the derive of `raw` with `params` already at hand
    /// (the derive stage's output), instead of deriving it a second time.
    pub fn around(self, configured: &'a Derived) -> Self {
        Self {
            configured: Some(configured),
            ..self
        }
    }

    /// Re-derives around `configured` (the derive stage's output with `params`) from the
    /// ingested odometer alone (`odo_t_ns`, `odo_distance_m`): a re-derive moves only the
    /// odometer's part, and takes the IMU's from `configured`.
    pub fn of_odometer(
        configured: &'a Derived,
        odo_t_ns: impl Into<OdoTimes<'a>>,
        odo_distance_m: &'a [f64],
        params: DeriveParams,
        g_mps2: f64,
    ) -> Self {
        let raw = RawSeries {
            imu_t_ns: &[],
            dtheta_rad: &[],
            dvel_mps: &[],
            odo_t_ns: odo_t_ns.into(),
            odo_distance_m,
        };
        Self::new(raw, params, g_mps2).around(configured)
    }

    /// The configured derive: the caller's, else derived once.
    fn configured(&self) -> &Derived {
        match self.configured {
            Some(d) => d,
            None => self
                .base
                .get_or_init(|| derive(&self.raw, &self.params, self.g_mps2)),
        }
    }

    /// The derive with the odometer `lag_s` later than the configured offset says.
    ///
    /// The odometer increments the route integrates and `ru` (the yaw rate times the
    /// speed of another moment) are derived anew. F's `u̇` is the configured derive's,
    /// moved in time: F is linear and time-invariant, so filtering a shifted `u̇` is
    /// shifting the filtered one, and this keeps one realisation of the pulse
    /// quantisation for every lag (derived anew, each fraction of a sample would draw
    /// another, and the fit's cost would be rough in the lag).
    pub fn at(&self, lag_s: f64) -> Derived {
        // The increments, kept, are read once: the blocks take them from memory.
        let odo_dist_m: Vec<f64> = self.odometer_at(lag_s).increments().collect();
        let lp = self.low_pass();
        let blocks =
            odometer_blocks_split(self.configured(), &lp, OdoBlockSeries::moved(true), |k| {
                odo_dist_m.get(k..).unwrap_or_default().iter().copied()
            });
        let mut d = self.moved_derive_of(lag_s, blocks, &lp);
        d.odo_dist_m = odo_dist_m;
        d
    }

    /// [`Rederive::at`] without the odometer's increments (left empty): they are read
    /// from the returned odometer as a pass goes.
    pub fn at_moved(&self, lag_s: f64) -> (Derived, MovedOdometer<'_>) {
        let odometer = self.odometer_at(lag_s);
        let d = self.moved_derive(lag_s, &odometer, OdoBlockSeries::moved(true));
        (d, odometer)
    }

    /// The derive at `lag_s` (its block series and epochs) of `odometer`, the odometer
    /// `lag_s` later, with the odometer's block `series` ([`OdoBlockSeries::moved`]):
    /// [`Rederive::at_moved`]'s.
    fn moved_derive(
        &self,
        lag_s: f64,
        odometer: &MovedOdometer<'_>,
        series: OdoBlockSeries,
    ) -> Derived {
        let lp = self.low_pass();
        let blocks = odometer_blocks_split(self.configured(), &lp, series, |k| {
            odometer.increments_from(k)
        });
        self.moved_derive_of(lag_s, blocks, &lp)
    }

    /// F of the configured derive.
    fn low_pass(&self) -> LowPass {
        LowPass::new(&self.params.filter, self.configured().nominal_dt_s)
    }

    /// [`Rederive::moved_derive`] of the odometer's block series `blocks` filtered by
    /// `lp` ([`Rederive::low_pass`]; [`odometer_blocks_split`]'s without u̇'s).
    fn moved_derive_of(&self, lag_s: f64, blocks: [Vec<f64>; 4], lp: &LowPass) -> Derived {
        let base = self.configured();
        // The IMU's part is the configured derive's; the odometer's is derived anew, but
        // for u̇'s blocks: the configured derive's, moved in time.
        let mut d = base.without_odometer_series();
        [d.u_dot_f, d.ru_f, d.r_moving_f, d.moving_dot_f] = blocks;
        let block_s = lp.block as f64 * d.nominal_dt_s;
        d.u_dot_f = shifted_blocks(&base.u_dot_f, block_s, lag_s);
        d.epochs = epochs_of(&d, lp, &self.params, self.g_mps2);
        d
    }

    /// [`Rederive::at_moved`] at each of `lags` but for its block series (a trial's
    /// problem reads the epochs they make), with each odometer's segments over `plan`
    /// (the sums `columns` asks for), all of them in one walk over the IMU's samples.
    /// The epochs' odometer-bias sensitivities are made only when `bias` (else 0: a fit
    /// that holds the bias reads them times 0).
    /// With [`TrialWalks::Fused`], each odometer's increments, read once, feed its
    /// segments and its blocks (the walk's stretches start at block boundaries; should one
    /// not, or a stretch not follow on from the one before, that odometer's blocks are read
    /// in a walk of their own); with [`TrialWalks::Apart`], each trial's blocks are read in
    /// a walk of their own first. The same, bit for bit.
    pub fn at_moved_with_segments(
        &self,
        lags: &[f64],
        plan: &SegmentPlan,
        columns: OdoColumns,
        bias: bool,
        walks: TrialWalks,
    ) -> Vec<(Derived, MovedOdometer<'_>, OdoSegments)> {
        let series = OdoBlockSeries::moved(bias);
        if walks == TrialWalks::Apart {
            return self.at_moved_apart(lags, plan, columns, series);
        }
        let base = self.configured();
        let lp = self.low_pass();
        let n = base.t_s.len();
        let odometers: Vec<MovedOdometer<'_>> =
            lags.iter().map(|&lag_s| self.odometer_at(lag_s)).collect();
        let stretches: Vec<Mutex<Vec<BlockStretch<'_>>>> =
            odometers.iter().map(|_| Mutex::new(Vec::new())).collect();
        let (_, segments) = integrate_split_aligned(
            &base.dt_s,
            base.dtheta_rad.view(),
            plan,
            false,
            odometers.len(),
            |v, k| Tee::new(base, &lp, series, &odometers[v], k, &stretches[v]),
            columns,
            lp.block,
        );
        lags.iter()
            .zip(odometers)
            .zip(stretches)
            .zip(segments)
            .map(|(((&lag_s, odometer), stretches), segments)| {
                let stretches = stretches.into_inner().unwrap_or_else(|e| e.into_inner());
                let blocks = match whole_blocks(stretches, lp.block, n) {
                    Some(blocks) => {
                        filtered_stretches(blocks.into_iter().map(OdometerBlocks::means), &lp)
                    }
                    None => {
                        odometer_blocks_split(base, &lp, series, |k| odometer.increments_from(k))
                    }
                };
                // A trial's problem reads the epochs, not the block series (14 MB a
                // trial at 12 hours, let go trial by trial).
                let d = self
                    .moved_derive_of(lag_s, blocks, &lp)
                    .without_block_series();
                (d, odometer, segments)
            })
            .collect()
    }

    /// [`Rederive::at_moved_with_segments`] with [`TrialWalks::Apart`]: each trial's block
    /// series derived, and let go once its epochs are made, one trial after the other.
    fn at_moved_apart(
        &self,
        lags: &[f64],
        plan: &SegmentPlan,
        columns: OdoColumns,
        series: OdoBlockSeries,
    ) -> Vec<(Derived, MovedOdometer<'_>, OdoSegments)> {
        let base = self.configured();
        let (derives, odometers): (Vec<Derived>, Vec<MovedOdometer<'_>>) = lags
            .iter()
            .map(|&lag_s| {
                let odometer = self.odometer_at(lag_s);
                let d = self
                    .moved_derive(lag_s, &odometer, series)
                    .without_block_series();
                (d, odometer)
            })
            .unzip();
        let (_, segments) = integrate_split(
            &base.dt_s,
            base.dtheta_rad.view(),
            plan,
            false,
            odometers.len(),
            |v, k| odometers[v].increments_from(k),
            columns,
        );
        derives
            .into_iter()
            .zip(odometers)
            .zip(segments)
            .map(|((d, odometer), segments)| (d, odometer, segments))
            .collect()
    }

    /// The odometer `lag_s` later than the configured offset says, over the configured
    /// derive's samples: its increments read as a pass goes (its failures bridged at
    /// that lag).
    pub fn odometer_at(&self, lag_s: f64) -> MovedOdometer<'_> {
        MovedOdometer::new(
            self.configured(),
            &self.raw,
            self.params.odo_time_offset_s - lag_s,
        )
        .patched(self.rebridges.as_ref().map(|r| r.patch_at(lag_s)))
    }
}

/// How the trials of a lag search read their odometers
/// ([`Rederive::at_moved_with_segments`]); the same derives and segments either way.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrialWalks {
    /// Once, for their segments and their blocks together: every trial's unfiltered block
    /// series are held through the walk.
    Fused,
    /// Once for each trial's blocks, one trial after the other, then once more for the
    /// segments: a trial's block series at a time.
    Apart,
}

/// The unfiltered block series a round of trials may hold together for the lag search to
/// read their odometers once ([`TrialWalks::Fused`]), bytes. A 12-hour run at 100 Hz
/// holds 10.4 MB for three trials of ru's series alone (the disupt stage's peak, at the
/// hold-out after them, the same); with the odometer-bias sensitivities too it would hold
/// 31 MB (measured: 21 MiB more at the stage's peak), so those trials read their
/// odometers once up to 6.5 hours, and twice beyond.
pub const FUSED_WALK_MAX_BYTES: usize = 16 << 20;

impl TrialWalks {
    /// The walks for `trials` trials on a run of `blocks` blocks, each trial with the
    /// block `series` ([`FUSED_WALK_MAX_BYTES`]).
    pub fn for_trials(trials: usize, blocks: usize, series: OdoBlockSeries) -> Self {
        let held_bytes = trials
            .saturating_mul(series.count())
            .saturating_mul(blocks)
            .saturating_mul(std::mem::size_of::<f64>());
        if held_bytes <= FUSED_WALK_MAX_BYTES {
            TrialWalks::Fused
        } else {
            TrialWalks::Apart
        }
    }
}

/// The blocks of one stretch of the segments' walk from sample `start` on, and the
/// increments after what the walk read.
struct BlockStretch<'a> {
    start: usize,
    blocks: OdometerBlocks<'a>,
    rest: OdoIncrements<'a>,
}

/// One trial's odometer increments over one stretch of the segments' walk, each also
/// pushed into the stretch's blocks; on drop, the stretch goes to the trial's list.
struct Tee<'s, 'a> {
    stretch: Option<BlockStretch<'a>>,
    out: &'s Mutex<Vec<BlockStretch<'a>>>,
}

impl<'s, 'a> Tee<'s, 'a> {
    /// `odometer`'s increments from sample `start` on, for the block `series` of `base`'s
    /// IMU (F `lp`) and `out`.
    fn new(
        base: &'a Derived,
        lp: &LowPass,
        series: OdoBlockSeries,
        odometer: &MovedOdometer<'a>,
        start: usize,
        out: &'s Mutex<Vec<BlockStretch<'a>>>,
    ) -> Self {
        // The first stretch is sized for all the blocks (the others are appended to it,
        // [`whole_blocks`]); the others grow as they fill, the walk not saying where they
        // end. Each sized for the whole run, with a stretch for each of 16 threads the
        // 12-hour disupt's peak stood 125 MB higher (592 against 467 MB).
        let room = match start {
            0 => lp.blocks(base.t_s.len()),
            _ => 0,
        };
        let mut blocks = OdometerBlocks::sized(base, lp, series, room);
        // From the sample before, as the derive's stretches resume (the same increments,
        // bit for bit, from wherever they are read).
        let mut rest = odometer.increments_from(start.saturating_sub(1));
        if start > 0 {
            blocks.resume_after(start, rest.next().unwrap_or(0.0));
        }
        Self {
            stretch: Some(BlockStretch {
                start,
                blocks,
                rest,
            }),
            out,
        }
    }
}

impl IncrementSource for Tee<'_, '_> {
    /// The increments, each taken by the blocks too (the zeros past the end not).
    fn fill(&mut self, out: &mut Vec<f64>, n: usize) {
        let from = out.len();
        if let Some(stretch) = self.stretch.as_mut() {
            stretch.rest.fill(out, n.min(stretch.rest.len()));
            stretch.blocks.push_slice(&out[from..]);
        }
        out.resize(from + n, 0.0);
    }
}

impl Drop for Tee<'_, '_> {
    fn drop(&mut self) {
        if let Some(stretch) = self.stretch.take() {
            self.out
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .push(stretch);
        }
    }
}

/// The blocks of a run of `n` samples from its stretches, in order: each starting at a
/// block boundary where the one before stopped, the last read on to the end. None when
/// they do not so follow on.
fn whole_blocks(
    mut stretches: Vec<BlockStretch<'_>>,
    block: usize,
    n: usize,
) -> Option<Vec<OdometerBlocks<'_>>> {
    stretches.sort_by_key(|s| s.start);
    let mut next = 0;
    for s in &stretches {
        if s.start != next || s.start % block.max(1) != 0 {
            return None;
        }
        next = s.blocks.next_sample();
    }
    let last = stretches.last_mut()?;
    let left = n.saturating_sub(last.blocks.next_sample());
    for dd in last.rest.by_ref().take(left) {
        last.blocks.push(dd);
    }
    (last.blocks.next_sample() >= n).then(|| stretches.into_iter().map(|s| s.blocks).collect())
}

struct Profile<'r> {
    rederive: &'r Rederive<'r>,
    valid: Vec<bool>,
    spec: &'r ProblemSpec<'r>,
    /// The fit without a lag: its linearisation is every trial's model.
    fit0: &'r JointFit,
    trials: RefCell<Vec<[f64; 2]>>,
    /// The weighted residuals of the last round's trials at the fit's linearisation point
    /// (the lag's slope in the residuals comes from the final round's).
    residuals: RefCell<Vec<(f64, Vec<f64>)>>,
    /// Navigation passes of the trials.
    passes: std::cell::Cell<usize>,
}

impl Profile<'_> {
    /// The scores at `lags`: those not tried yet are tried side by side (each trial's
    /// pass in a lane on its own odometer increments).
    fn costs<const K: usize>(&self, lags: [f64; K]) -> Result<[f64; K], DisuptError> {
        let known = |lag: f64| {
            self.trials
                .borrow()
                .iter()
                .find(|t| t[0] == lag)
                .map(|t| t[1])
        };
        let mut new: Vec<f64> = Vec::new();
        for &lag in &lags {
            if known(lag).is_none() && !new.contains(&lag) {
                new.push(lag);
            }
        }
        // Each trial's odometer increments are read as they are needed, not stored: for
        // its blocks, then for its segments (all the trials' in one walk).
        let warm = self.fit0.linearization();
        let x = x_of(&warm.p_ref);
        let columns = OdoColumns::read_by(&[self.spec.settings_of(&x)]);
        let plan = self.spec.moved_segment_plan(self.rederive.configured());
        // The bias sensitivities only for a fit that frees the bias.
        let bias = self.fit0.free.contains(&Setting::OdoBias);
        let blocks = self
            .rederive
            .low_pass()
            .blocks(self.rederive.configured().t_s.len());
        let walks = TrialWalks::for_trials(new.len(), blocks, OdoBlockSeries::moved(bias));
        let (derives, segments): (Vec<(Derived, MovedOdometer<'_>)>, Vec<OdoSegments>) = self
            .rederive
            .at_moved_with_segments(&new, &plan, columns, bias, walks)
            .into_iter()
            .map(|(mut d, odometer, segments)| {
                // The same epochs at every trial: the gate moves with the lag, and an
                // epoch entering or leaving would make the costs incomparable.
                d.epochs.valid.clone_from(&self.valid);
                ((d, odometer), segments)
            })
            .unzip();
        let problems: Vec<Problem<'_>> = derives
            .iter()
            .zip(segments)
            .map(|((d, odometer), segments)| {
                self.spec
                    .on_moved(d, odometer.clone())
                    .with_moved_segments(segments)
            })
            .collect();
        let refs: Vec<&Problem<'_>> = problems.iter().collect();
        let tally = std::sync::atomic::AtomicUsize::new(0);
        let ys = observe_each(&refs, &x, &tally);
        self.residuals
            .borrow_mut()
            .retain(|(lag, _)| lags.contains(lag));
        for ((lag, problem), y) in new.iter().zip(&problems).zip(ys) {
            let lin = Linearization {
                p_ref: warm.p_ref,
                y_ref: y,
                slopes: warm.slopes.clone(),
            };
            let cost = self.fit0.linearised_cp_cost(problem, &lin)?;
            self.trials.borrow_mut().push([*lag, cost]);
            let r = self.fit0.linearised_residuals(problem, &lin);
            self.residuals.borrow_mut().push((*lag, r));
        }
        self.passes.set(self.passes.get() + new.len());
        Ok(lags.map(|lag| known(lag).unwrap_or(f64::NAN)))
    }
}

/// The joint fit with the odometer lag estimated within ±`params.odo_lag_bound_s`.
/// `base` is `spec` on the derive at lag zero (the cached one), the problem the other
/// methods share (its first linearisation is built once for all); `spec` is the DISUPT
/// problem to set on each re-derive.
pub fn joint_with_lag(
    rederive: &Rederive<'_>,
    base: &Problem<'_>,
    spec: &ProblemSpec<'_>,
    params: &DisuptParams,
) -> Result<LagFit, DisuptError> {
    let fit0 = joint_fit(base, params, &JointOptions::default())?;
    let profile = Profile {
        rederive,
        valid: base.epochs.valid.clone(),
        spec,
        fit0: &fit0,
        trials: RefCell::new(Vec::new()),
        residuals: RefCell::new(Vec::new()),
        passes: std::cell::Cell::new(fit0.result.evaluations),
    };
    let bound = params.odo_lag_bound_s;
    // The score is the control points' misfit, near-quadratic in the lag (the stops move
    // in proportion to it): successive parabolas, first over ±0.3 of the bound, then over
    // ±STEP around each vertex, until the vertex moves less than TOLERANCE_S.
    // The trial at lag zero is on the derive the fit was made on, whose pass at the
    // linearisation's point the linearisation holds: no pass.
    // With the odometer's failures bridged again at each lag, the lag zero's derive is
    // not the fit's (whose failures the ingest bridged): its trial is a pass like any,
    // beside the first parabola's others.
    if rederive.rebridges().is_none() {
        let cost_at_0 = fit0.linearised_cp_cost(base, fit0.linearization())?;
        profile.trials.borrow_mut().push([0.0, cost_at_0]);
    }
    let wide = 0.3 * bound;
    let mut points = [-wide, 0.0, wide];
    let mut lag_s = 0.0;
    let mut curvature = f64::NAN;
    let mut c0 = f64::NAN;
    let mut tried = points;
    for round in 0..MAX_ROUNDS {
        let costs = profile.costs(points)?;
        tried = points;
        let previous = lag_s;
        match parabola(points, costs) {
            Some((vertex, second)) => {
                lag_s = vertex.clamp(-bound, bound);
                curvature = second;
                // The score there, on the parabola (it is near-quadratic).
                c0 = through(points, costs, lag_s);
            }
            None => {
                // Not convex here: go on from the best trial so far.
                let best = (0..3)
                    .min_by(|&i, &j| costs[i].total_cmp(&costs[j]))
                    .unwrap_or(1);
                lag_s = points[best];
                curvature = f64::NAN;
                c0 = costs[best];
            }
        }
        if round > 0 && (lag_s - previous).abs() < TOLERANCE_S && curvature.is_finite() {
            break;
        }
        // The next parabola about the vertex: its three trials side by side.
        points = [lag_s - CURVATURE_STEP_S, lag_s, lag_s + CURVATURE_STEP_S];
    }
    // The fit and the passes after it read the derive's epochs, not its block series.
    let derived = rederive.at(lag_s).without_block_series();
    // Its segments with the odometer's yaw column too: the fit frees that boresight
    // (`joint_odo_yaw`), or its check ([`crate::disupt::JointFit::odo_yaw_seen`]) passes
    // with it moved. Integrated in the fit's walk, not in a walk of their own after it
    // (3 ms of the joint fit's chain at 40 minutes).
    let problem = spec.on(&derived);
    problem.integrate_segments_with(OdoColumns {
        yaw: true,
        ..OdoColumns::default()
    });
    let mut fit = joint_fit(
        &problem,
        params,
        &JointOptions {
            warm: Some(fit0.linearization()),
            ..JointOptions::default()
        },
    )?;
    // The control points' misfit per residual beyond the lag's one degree of freedom,
    // when it is worse than their σ.
    let cp_dof = (2 * spec.cps_used()).saturating_sub(
        fit.free
            .iter()
            .filter(|s| **s == Setting::Azimuth || s.needs_control_points())
            .count()
            + 1,
    );
    let s2 = (c0 / cp_dof.max(1) as f64).max(1.0);
    let mut sigma_s = (curvature > 0.0)
        .then(|| (2.0 * s2 / curvature).sqrt())
        .filter(|s| s.is_finite());
    // The settings' σ and the lag's with each other's uncertainty and the gyros' walk in
    // them, from the lag's slope in the residuals over the last parabola.
    if sigma_s.is_some() {
        let residuals = profile.residuals.borrow();
        let at = |lag: f64| {
            residuals
                .iter()
                .find(|(l, _)| *l == lag)
                .map(|(_, r)| r.clone())
                .or_else(|| {
                    (lag == 0.0 && rederive.rebridges().is_none())
                        .then(|| fit0.linearised_residuals(base, fit0.linearization()))
                })
        };
        let (lo, hi) = (tried[0], tried[2]);
        if let (Some(r_lo), Some(r_hi)) = (at(lo), at(hi))
            && r_lo.len() == r_hi.len()
            && hi > lo
        {
            let slope: Vec<f64> = (r_lo.iter().zip(&r_hi))
                .map(|(a, b)| (b - a) / (hi - lo))
                .collect();
            // The same settings free at every lag (so the covariance in the same order
            // as the final fit's): the σ, the mark's and the holdouts' figures alike.
            if fit.free == fit0.free
                && let Some(m) = fit0.lag_marginal(base, &slope, s2, fit.result.x.azimuth_deg)
            {
                fit.result.sigma = Some(m.sigma);
                fit.covariance = Some(m.covariance);
                fit.walk_uptake = m.walk_uptake;
                fit.lag_covariance = Some(m.lag_covariance);
                sigma_s = Some(m.lag_sigma_s);
            }
        }
    }
    // The method's passes: the search's as well as the final fit's.
    fit.result.evaluations += profile.passes.get();
    if let Some(step) = fit.result.steps.first_mut() {
        step.evaluations = fit.result.evaluations;
    }
    Ok(LagFit {
        lag_s,
        sigma_s,
        derived,
        fit,
        profile: profile.trials.into_inner(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fused walk's first stretch holds room for every block (the others are appended
    /// to it); a later one for its own (it grows as it fills), not for the whole run's.
    #[test]
    fn a_fused_walks_later_stretch_holds_room_for_its_own_blocks() {
        let n = 20_000;
        let imu_t: Vec<i64> = (0..n as i64).map(|k| k * 10_000_000).collect();
        let dtheta = vec![[0.0, 0.0, 1e-3]; n];
        let dvel = vec![[0.01, 0.0, -0.098]; n];
        let odo_d: Vec<f64> = (0..n).map(|k| k as f64 * 0.05).collect();
        let raw = RawSeries {
            imu_t_ns: &imu_t,
            dtheta_rad: &dtheta,
            dvel_mps: &dvel,
            odo_t_ns: (&imu_t).into(),
            odo_distance_m: &odo_d,
        };
        let params = DeriveParams::default();
        let d = derive(&raw, &params, 9.81);
        let lp = LowPass::new(&params.filter, d.nominal_dt_s);
        let odometer = MovedOdometer::new(&d, &raw, 0.0);
        let blocks = lp.blocks(n);
        // The stretch from the run's start, and its last eighth's.
        let last_eighth = (blocks - blocks / 8) * lp.block;
        for start in [0, last_eighth] {
            let out = Mutex::new(Vec::new());
            let mut tee = Tee::new(&d, &lp, OdoBlockSeries::moved(true), &odometer, start, &out);
            tee.fill(&mut Vec::new(), n - start);
            drop(tee);
            let stretch = out.into_inner().unwrap().pop().unwrap();
            let ru = &stretch.blocks.means()[1];
            let (held, room) = (ru.len(), ru.capacity());
            if start == 0 {
                assert_eq!(held, blocks);
                assert!(room >= blocks, "{room} for {blocks} blocks");
            } else {
                assert!(held >= blocks / 8, "{held} of {blocks} blocks");
                assert!(room <= 2 * held, "room for {room} blocks, {held} held");
            }
        }
    }
}
