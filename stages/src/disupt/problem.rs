//! One run's optimisation problem: exact navigation passes of settings, side by side in
//! vector lanes, and the linearisations the searches run on.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use either::Either;
use rayon::prelude::*;

use super::gap_tilts::GapTilts;
use super::gyro_walk::GyroWalk;
use super::settings::{BASE_SETTINGS, X, params_of, x_of};
use crate::criteria::{self, ControlPointFix, FilteredBlocks, KalmanParams, Kryt1Gains, Kryt2};
use crate::derive::{Epochs, MovedOdometer, OdoIncrements};
use crate::filter::LowPass;
use crate::linearized::{Linearization, N_PARAMS, Observation, Setting};
use crate::strapdown::lanes_in_flight::{
    BLOCKS_IN_FLIGHT_BUDGET_BYTES, batch_within, lanes_within, wave_len,
};
use crate::strapdown::segments::{
    ImuSegments, OdoColumns, OdoSegments, SegmentMemo, SegmentPlan, integrate_split,
};
use crate::strapdown::{
    self, CriteriaSink, LaneBatch, NavInputs, NavSettings, batch_lanes, in_lanes,
};
use crate::units::DEG_PER_H;

/// One run's optimisation problem: everything is derived once; each evaluation is one
/// navigation pass and the criteria, without I/O or allocation.
pub struct Problem<'a> {
    /// Navigation inputs.
    pub inputs: NavInputs<'a>,
    /// Settings before DISUPT (`x_pocz`).
    pub base: NavSettings,
    /// Epochs of the criteria.
    pub epochs: &'a Epochs,
    /// The filter F.
    pub lp: LowPass,
    /// Kalman filter of Kryt1.
    pub kalman: KalmanParams,
    /// Control points.
    pub fixes: &'a [ControlPointFix],
    /// Control points (indices into `fixes`) the joint fit leaves out: their errors are
    /// still observed by every pass, but the fit does not weigh them (points found
    /// inconsistent with the rest of the run).
    pub excluded_cps: &'a [usize],
    /// Prior on the vertical drift from the static start: (value, 1σ), °/h.
    pub drift_z_prior_deg_h: Option<(f64, f64)>,
    /// The tilt steps the joint fit gives the derive's gaps ([`GapTilts`]); `None` without
    /// a gap that leaves one.
    pub gap_tilts: Option<Arc<GapTilts>>,
    /// The gyros' angle random walk the joint fit's covariance takes ([`GyroWalk`]);
    /// `None`: the residuals' scatter alone.
    pub gyro_walk: Option<&'a GyroWalk>,
    /// The odometer increments, when they are read as a pass goes instead of from
    /// `inputs` (a derive at another odometer timing: [`ProblemSpec::on_moved`]).
    moved_odometer: Option<MovedOdometer<'a>>,
    /// The segments the passes run over: the derive's memo (the IMU's, and its stored
    /// odometer's), and those of the moved odometer, integrated on first use.
    segments: SegmentMemo,
    moved_segments: Arc<Mutex<Option<Arc<OdoSegments>>>>,
    passes: AtomicUsize,
    base_lin: std::sync::OnceLock<Linearization>,
    /// Kryt1's filter gains over `epochs` with `kalman`, computed on first use.
    kryt1_gains: std::sync::OnceLock<Arc<Kryt1Gains>>,
}

/// Everything of a DISUPT problem but the derive it runs on, so that the same problem
/// can be set on another derive (the odometer-lag search re-derives).
#[derive(Debug, Clone, Copy)]
pub struct ProblemSpec<'a> {
    /// Settings before DISUPT (the searches' start).
    pub settings: NavSettings,
    /// The filter F's parameters.
    pub filter: crate::filter::FilterParams,
    /// Kalman filter of Kryt1.
    pub kalman: KalmanParams,
    /// Control points.
    pub fixes: &'a [ControlPointFix],
    /// Control points the joint fit leaves out ([`Problem::excluded_cps`]).
    pub excluded_cps: &'a [usize],
    /// Prior on the vertical drift from the static start: (value, 1σ), °/h.
    pub drift_z_prior_deg_h: Option<(f64, f64)>,
    /// The gyros' angle random walk ([`Problem::gyro_walk`]).
    pub gyro_walk: Option<&'a GyroWalk>,
}

impl<'a> ProblemSpec<'a> {
    /// How many control points the joint fit weighs ([`Problem::cps_used`]).
    pub fn cps_used(&self) -> usize {
        cps_used(self.fixes, self.excluded_cps)
    }

    /// The problem on the derive `d`.
    pub fn on<'b>(self, d: &'b crate::derive::Derived) -> Problem<'b>
    where
        'a: 'b,
    {
        let mut p = Problem::new(
            d.nav_inputs(),
            self.settings,
            &d.epochs,
            LowPass::new(&self.filter, d.nominal_dt_s),
            self.kalman,
            self.fixes,
        );
        p.drift_z_prior_deg_h = self.drift_z_prior_deg_h;
        p.excluded_cps = self.excluded_cps;
        p.gyro_walk = self.gyro_walk;
        p.segments = d.segments.clone();
        let cp_samples: Vec<usize> = self.fixes.iter().map(|f| f.sample).collect();
        p.gap_tilts = GapTilts::of(
            d,
            self.settings.lat0_rad,
            self.settings.drift_rad_s[2],
            self.settings.initial.heading_rad,
            &cp_samples,
        )
        .map(Arc::new);
        p
    }

    /// The navigation settings of `x` in this problem (what [`Problem::settings`] gives).
    pub fn settings_of(&self, x: &X) -> NavSettings {
        settings_of(&self.settings, x)
    }

    /// The segments the passes of [`Self::on_moved`]`(d, …)` run over.
    pub fn moved_segment_plan(&self, d: &crate::derive::Derived) -> SegmentPlan {
        let lp = LowPass::new(&self.filter, d.nominal_dt_s);
        segment_plan_of(&d.nav_inputs(), true, lp.block, self.fixes)
    }

    /// The problem on the derive `d` whose odometer increments are not stored but read
    /// from `odometer` as each pass goes (the odometer-lag search's trials).
    pub fn on_moved<'b>(
        self,
        d: &'b crate::derive::Derived,
        odometer: MovedOdometer<'b>,
    ) -> Problem<'b>
    where
        'a: 'b,
    {
        let mut p = self.on(d);
        p.moved_odometer = Some(odometer);
        p
    }
}

/// The navigation settings of `x` around `base` (the settings before DISUPT).
fn settings_of(base: &NavSettings, x: &X) -> NavSettings {
    let mut s = *base;
    s.initial.heading_rad = x.azimuth_deg.to_radians();
    s.drift_rad_s = x.drift_deg_h.map(|d| d * DEG_PER_H);
    s.odo_scale = base.odo_scale * (1.0 + x.odo_ppm * 1e-6);
    s.odo_yaw_rad = base.odo_yaw_rad + x.odo_yaw_deg.to_radians();
    s.odo_bias_mps = base.odo_bias_mps + x.odo_bias_mps;
    s.initial.pitch_rad -= x.tilt_mrad[0] * 1e-3;
    s.initial.roll_rad -= x.tilt_mrad[1] * 1e-3;
    s
}

/// The segments of passes over `inputs` (blocks of `block` samples, cut after the fixes'
/// samples), over the samples its odometer covers: the IMU's alone when the odometer is
/// `moved` (read as the passes go), else its stored increments' too.
fn segment_plan_of(
    inputs: &NavInputs<'_>,
    moved: bool,
    block: usize,
    fixes: &[ControlPointFix],
) -> SegmentPlan {
    let mut n = inputs.dt_s.len().min(inputs.dtheta_rad.len());
    if !moved {
        n = n.min(inputs.odo_dist_m.len());
    }
    SegmentPlan::new(n, block, fixes.iter().map(|f| f.sample))
}

/// Each distinct point's first fix (indices into `fixes`, ascending): a point the route
/// came back to has a fix per visit.
pub fn points_of(fixes: &[ControlPointFix]) -> Vec<usize> {
    let mut seen = std::collections::BTreeSet::new();
    (0..fixes.len())
        .filter(|&i| seen.insert(fixes[i].id))
        .collect()
}

/// How many distinct points the fixes `among` (indices into `fixes`) are.
pub fn points_among(fixes: &[ControlPointFix], among: &[usize]) -> usize {
    among
        .iter()
        .map(|&i| fixes[i].id)
        .collect::<std::collections::BTreeSet<u32>>()
        .len()
}

/// Every visit of fix `i`'s point (indices into `fixes`, ascending).
pub fn visits_of(fixes: &[ControlPointFix], i: usize) -> Vec<usize> {
    (0..fixes.len())
        .filter(|&j| fixes[j].id == fixes[i].id)
        .collect()
}

/// How many of `fixes` are not among `excluded` (indices into them).
fn cps_used(fixes: &[ControlPointFix], excluded: &[usize]) -> usize {
    (0..fixes.len()).filter(|i| !excluded.contains(i)).count()
}

/// Criteria of one pass.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    /// Kryt1, rad.
    pub kryt1: f64,
    /// Kryt2 at each control point.
    pub kryt2: Vec<Kryt2>,
}

impl Evaluation {
    /// RMS Kryt2 over the control points, m (NaN without control points).
    pub fn kryt2_rms(&self) -> f64 {
        criteria::kryt2_rms_m(self.kryt2.iter().map(|k| [k.dx_m, k.dy_m]))
    }

    /// (ΔX, ΔY) at the last control point.
    pub fn last_error(&self) -> (f64, f64) {
        self.kryt2
            .last()
            .map_or((f64::NAN, f64::NAN), |k| (k.dx_m, k.dy_m))
    }
}

/// Most passes stepped side by side in vector lanes by [`Problem::observe_many_by`]: one
/// AVX2 register's four (a segment pass keeps its blocks, 6.9 MB a lane at 12 hours, while
/// its batch runs: eight lanes on each of two threads held 55 MB more).
pub const LANES: usize = 4;

impl<'a> Problem<'a> {
    /// A problem around `base`.
    pub fn new(
        inputs: NavInputs<'a>,
        base: NavSettings,
        epochs: &'a Epochs,
        lp: LowPass,
        kalman: KalmanParams,
        fixes: &'a [ControlPointFix],
    ) -> Self {
        Self {
            inputs,
            base,
            epochs,
            lp,
            kalman,
            fixes,
            excluded_cps: &[],
            drift_z_prior_deg_h: None,
            gap_tilts: None,
            gyro_walk: None,
            moved_odometer: None,
            segments: SegmentMemo::default(),
            moved_segments: Arc::default(),
            passes: AtomicUsize::new(0),
            base_lin: std::sync::OnceLock::new(),
            kryt1_gains: std::sync::OnceLock::new(),
        }
    }

    /// This problem with the joint fit leaving `excluded` out (indices into `fixes`;
    /// [`Self::excluded_cps`]). The first linearisation, once built, is shared: it does not
    /// depend on the fit's weights.
    pub fn excluding<'b>(&'b self, excluded: &'b [usize]) -> Problem<'b>
    where
        'a: 'b,
    {
        let base_lin = std::sync::OnceLock::new();
        if let Some(lin) = self.base_lin.get() {
            let _ = base_lin.set(lin.clone());
        }
        let kryt1_gains = std::sync::OnceLock::new();
        if let Some(gains) = self.kryt1_gains.get() {
            let _ = kryt1_gains.set(Arc::clone(gains));
        }
        Problem {
            inputs: self.inputs,
            base: self.base,
            epochs: self.epochs,
            lp: self.lp,
            kalman: self.kalman,
            fixes: self.fixes,
            excluded_cps: excluded,
            drift_z_prior_deg_h: self.drift_z_prior_deg_h,
            gap_tilts: self.gap_tilts.clone(),
            gyro_walk: self.gyro_walk,
            moved_odometer: self.moved_odometer.clone(),
            segments: self.segments.clone(),
            moved_segments: Arc::clone(&self.moved_segments),
            passes: AtomicUsize::new(0),
            base_lin,
            kryt1_gains,
        }
    }

    /// The segments of this problem's passes: blocks of F cut after the control points'
    /// samples, over the samples its odometer covers.
    fn segment_plan(&self) -> SegmentPlan {
        segment_plan_of(
            &self.inputs,
            self.moved_odometer.is_some(),
            self.lp.block,
            self.fixes,
        )
    }

    /// This problem with its moved odometer's segments given (integrated beside other
    /// work on its increments: [`ProblemSpec::moved_segment_plan`]'s).
    pub fn with_moved_segments(self, segments: OdoSegments) -> Self {
        *self
            .moved_segments
            .lock()
            .unwrap_or_else(|e| e.into_inner()) = Some(Arc::new(segments));
        self
    }

    /// Integrates the segments the passes at the problem's start read (the IMU's and its
    /// odometer's, with the columns its settings read), unless they are already: a caller
    /// with both cores free does it first, where the first pass would do it beside other
    /// work, and the passes then find them (the same segments either way).
    pub fn integrate_segments(&self) {
        self.integrate_segments_with(OdoColumns::default());
    }

    /// [`Self::integrate_segments`] with the odometer's columns `also` beside those its
    /// start reads, for passes to come that read them: integrated in the same walk, not in
    /// a walk of their own when those passes come (each column's sums are the same
    /// either way).
    pub fn integrate_segments_with(&self, also: OdoColumns) {
        let columns = OdoColumns::read_by(&[self.settings(&self.x0())]).union(&also);
        self.segments_of(columns);
    }

    /// The IMU's segments, and this problem's odometer's (with at least `columns`),
    /// integrated on first use: the derive's own through its memo, a moved odometer's
    /// here.
    fn segments_of(&self, columns: OdoColumns) -> (Arc<ImuSegments>, Arc<OdoSegments>) {
        let plan = self.segment_plan();
        let stored = self.moved_odometer.is_none();
        let (imu, odo) = self.segments.segments(&self.inputs, &plan, stored, columns);
        if let Some(odo) = odo {
            return (imu, odo);
        }
        ensure_moved_segments(&[self], columns);
        let odo = self
            .moved_segments
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
            .expect("integrated just now");
        (imu, odo)
    }

    /// The odometer increments a pass of this problem reads, sample by sample, from
    /// sample `k` on.
    fn odometer_increments_from(&self, k: usize) -> LaneIncrements<'a> {
        match &self.moved_odometer {
            Some(moved) => Either::Right(moved.increments_from(k)),
            None => {
                let d = self.inputs.odo_dist_m;
                Either::Left(d[k.min(d.len())..].iter().copied())
            }
        }
    }

    /// Whether the joint fit weighs control point `i` (not in [`Self::excluded_cps`]).
    pub fn cp_used(&self, i: usize) -> bool {
        !self.excluded_cps.contains(&i)
    }

    /// How many control points the joint fit weighs (a visit each: a point the route
    /// came back to counts once per visit).
    pub fn cps_used(&self) -> usize {
        cps_used(self.fixes, self.excluded_cps)
    }

    /// How many distinct points (ids) among them: what judges a point against the others.
    pub fn points_used(&self) -> usize {
        let used: Vec<usize> = (0..self.fixes.len()).filter(|&i| self.cp_used(i)).collect();
        points_among(self.fixes, &used)
    }

    /// Whether fixes `i` and `j` are visits of the same point (the same id): a point
    /// left out of a fit, or held out, is left out at every visit, as its coordinates
    /// are.
    pub fn same_point(&self, i: usize, j: usize) -> bool {
        self.fixes[i].id == self.fixes[j].id
    }

    /// Whether a fit holding out `skip` (a fix, with its point's other visits) leaves
    /// fix `i` out too.
    pub fn held_out(&self, skip: Option<usize>, i: usize) -> bool {
        skip.is_some_and(|s| self.same_point(s, i))
    }

    /// Navigation passes so far.
    pub fn passes(&self) -> usize {
        self.passes.load(Ordering::Relaxed)
    }

    /// The base settings in optimiser units.
    pub fn x0(&self) -> X {
        X {
            azimuth_deg: self.base.initial.heading_rad.to_degrees(),
            drift_deg_h: self.base.drift_rad_s.map(|d| d / DEG_PER_H),
            odo_ppm: 0.0,
            tilt_mrad: [0.0; 2],
            odo_yaw_deg: 0.0,
            odo_bias_mps: 0.0,
            mark_arm_m: [0.0; 2],
        }
    }

    /// Navigation settings of `x`.
    pub fn settings(&self, x: &X) -> NavSettings {
        settings_of(&self.base, x)
    }

    /// Kryt1 and Kryt2 of `x` (one exact pass).
    pub fn evaluate(&self, x: &X) -> Evaluation {
        self.evaluation_of(&self.observe(x))
    }

    /// What the criteria read from the pass of `x` (one exact pass).
    pub fn observe(&self, x: &X) -> Observation {
        self.observe_by(x, &AtomicUsize::new(0))
    }

    /// [`Self::observe`], counted in `tally` too (a method's own passes). The pass keeps
    /// no track: it sums what the criteria need as it goes ([`CriteriaSink`]).
    pub fn observe_by(&self, x: &X, tally: &AtomicUsize) -> Observation {
        let mut y = self.observe_batch(&[*x], tally);
        y.pop().expect("one observation of one point")
    }

    /// The observations of several settings (in their order), each what
    /// [`Self::observe`] gives, bit for bit; counted in `tally` too. Up to [`LANES`]
    /// passes run side by side in vector lanes, and the batches in parallel: points few
    /// enough for one each go one to a thread (two points on two cores), else in full
    /// batches (a batch of two to four lanes costs about what one of four does, in CPU and
    /// in time: three or four points in one batch, not two half-empty ones side by side).
    ///
    /// The passes over the run in flight hold their Kryt1 blocks
    /// ([`LanesInFlight`](crate::strapdown::lanes_in_flight::LanesInFlight)): the
    /// points go in waves of as many as the budget leaves room for beside the others, at
    /// least one at a time. Only a long run's on many threads wait for room: a 12-hour
    /// run's budget holds nine passes, more than two threads run at once.
    pub fn observe_many_by(&self, xs: &[X], tally: &AtomicUsize) -> Vec<Observation> {
        self.observe_many_within(xs, tally, self.lanes_cap())
    }

    /// [`Self::observe_many_by`] with at most `cap` lanes in flight over the run (beside
    /// one wave's batch, which always runs).
    fn observe_many_within(&self, xs: &[X], tally: &AtomicUsize, cap: usize) -> Vec<Observation> {
        let threads = rayon::current_num_threads().max(1);
        let mut out = Vec::with_capacity(xs.len());
        for wave in self.segments.lanes_in_flight().slices(xs, cap, wave_len) {
            let chunk = if wave.len().div_ceil(threads) > 1 {
                LANES
            } else {
                1
            };
            out.par_extend(
                wave.par_chunks(chunk)
                    .flat_map_iter(|chunk| self.observe_batch(chunk, tally)),
            );
        }
        out
    }

    /// [`Self::observe_many_by`] on the calling thread only, in as few batches of lanes as
    /// the points fill: the least CPU for a few points, where the caller's own concurrency
    /// keeps the cores busy.
    ///
    /// Its batches are as full as the passes over the run in flight leave room for
    /// ([`Self::observe_many_by`]), down to one point at a time.
    pub fn observe_batched_by(&self, xs: &[X], tally: &AtomicUsize) -> Vec<Observation> {
        self.observe_batched_within(xs, tally, self.lanes_cap())
    }

    /// [`Self::observe_batched_by`] with at most `cap` lanes in flight over the run (but
    /// one point at a time, which always runs).
    fn observe_batched_within(
        &self,
        xs: &[X],
        tally: &AtomicUsize,
        cap: usize,
    ) -> Vec<Observation> {
        self.segments
            .lanes_in_flight()
            .slices(xs, cap, batches_of_lanes)
            .flat_map(|batch| self.observe_batch(batch, tally))
            .collect()
    }

    /// The lanes the passes over this problem's run may hold at once
    /// ([`BLOCKS_IN_FLIGHT_BUDGET_BYTES`]), a batch at least.
    fn lanes_cap(&self) -> usize {
        lanes_within(
            BLOCKS_IN_FLIGHT_BUDGET_BYTES,
            self.inputs.len(),
            self.lp.block,
            LANES,
        )
    }

    /// At most [`LANES`] points in one batch of lanes.
    fn observe_batch(&self, xs: &[X], tally: &AtomicUsize) -> Vec<Observation> {
        tally.fetch_add(xs.len(), Ordering::Relaxed);
        self.passes.fetch_add(xs.len(), Ordering::Relaxed);
        let _held = self.segments.lanes_in_flight().hold(batch_lanes(xs.len()));
        in_lanes(
            xs.len(),
            &mut OnDerives {
                problems: &[self],
                xs,
            },
        )
    }

    /// What the criteria read from a pass's sink, its blocks filtered (`blocks`, taken
    /// from the sink).
    fn observation_of_sink(
        &self,
        blocks: &FilteredBlocks,
        sink: &CriteriaSink,
        x: &X,
    ) -> Observation {
        let mut y = Observation::default();
        blocks.at_epochs(self.epochs, &mut y.theta_rad, &mut y.phi_rad);
        y.cp_m = self
            .fixes
            .iter()
            .filter_map(|f| {
                let pose = sink.position_at(f.sample)?;
                let [n, e] = pose.body_to_ne();
                y.cp_arm_ne.push([[n[0], n[1]], [e[0], e[1]]]);
                // The mark moved by the fit (none but the joint's), on the configured arm.
                if x.mark_arm_m == [0.0; 2] {
                    return Some(f.offset_m(&pose));
                }
                let mut moved = *f;
                moved.mark_lever_arm_m[0] += x.mark_arm_m[0];
                moved.mark_lever_arm_m[1] += x.mark_arm_m[1];
                Some(moved.offset_m(&pose))
            })
            .map(|(dx, dy)| [dx, dy])
            .collect();
        y
    }

    /// The criteria of an observation.
    pub fn evaluation_of(&self, y: &Observation) -> Evaluation {
        Evaluation {
            kryt1: self.kryt1(y),
            kryt2: y.kryt2(self.fixes),
        }
    }

    /// The linearisation around `x` (whose exact observation is `y`) in the settings
    /// `which`: one forward-difference pass per setting, counted in `tally`, but the
    /// mark's, whose slopes are `y`'s attitude at the stops.
    pub fn linearize_by(
        &self,
        x: &X,
        y: Observation,
        which: &[Setting],
        tally: &AtomicUsize,
    ) -> Linearization {
        let by_pass: Vec<Setting> = which.iter().copied().filter(|s| !s.is_mark_arm()).collect();
        let ys = self.observe_many_by(&moved_by_steps(x, &by_pass), tally);
        let mut lin = linearization_of(x, y, &by_pass, ys);
        lin.add_mark_arm_slopes(which);
        lin
    }

    /// Passes of the shared first linearisation (0 before it is built).
    pub fn base_passes(&self) -> usize {
        self.base_lin
            .get()
            .map_or(0, |l| 1 + l.slopes.iter().flatten().count())
    }

    /// Kryt1 of an observation of this problem's passes (its filters' gains computed once
    /// for all of them).
    pub fn kryt1(&self, y: &Observation) -> f64 {
        let gains = self
            .kryt1_gains
            .get_or_init(|| Arc::new(Kryt1Gains::new(self.epochs, &self.kalman)));
        y.kryt1_with(self.epochs, gains)
    }

    /// The linearisation around `x0` in every parameter but the odometer boresight,
    /// built once and shared by the methods (each starts there; its passes are counted in
    /// [`Self::base_passes`]).
    pub fn base_linearization(&self) -> &Linearization {
        self.base_lin.get_or_init(|| {
            let x0 = self.x0();
            let mut xs = vec![x0];
            xs.extend(moved_by_steps(&x0, BASE_SETTINGS));
            let mut ys = self.observe_many_by(&xs, &AtomicUsize::new(0));
            let y0 = ys.remove(0);
            linearization_of(&x0, y0, BASE_SETTINGS, ys)
        })
    }

    /// `lin` with the slopes it lacks among `which` added (one pass each, counted in
    /// `tally`).
    pub fn completed(
        &self,
        lin: &Linearization,
        which: &[Setting],
        tally: &AtomicUsize,
    ) -> Linearization {
        let missing: Vec<Setting> = which
            .iter()
            .copied()
            .filter(|s| lin.slopes[s.index()].is_none())
            .collect();
        let mut out = self.linearize_by(&x_of(&lin.p_ref), lin.y_ref.clone(), &missing, tally);
        for (j, slope) in lin.slopes.iter().enumerate() {
            if slope.is_some() {
                out.slopes[j].clone_from(slope);
            }
        }
        out
    }
}

/// The exact observation of `x` on each of `problems`, derives of one run at other
/// odometer timings (the same IMU series, control points and blocks), in batches of
/// lanes each on its own odometer increments; each what [`Problem::observe`] gives, bit
/// for bit. Counted in `tally` and each problem's passes.
///
/// # Panics
/// If the problems do not share their IMU series, control points and blocks.
pub fn observe_each(problems: &[&Problem<'_>], x: &X, tally: &AtomicUsize) -> Vec<Observation> {
    let Some(first) = problems.first() else {
        return Vec::new();
    };
    assert!(
        problems.iter().all(|p| p.inputs.same_imu_as(&first.inputs)
            && p.inputs.len() == first.inputs.len()
            && std::ptr::eq(p.fixes, first.fixes)
            && p.lp.block == first.lp.block),
        "derives of different runs or filters"
    );
    tally.fetch_add(problems.len(), Ordering::Relaxed);
    // In batches as full as the passes over the run in flight leave room for.
    let in_flight = first.segments.lanes_in_flight();
    in_flight
        .slices(problems, first.lanes_cap(), batches_of_lanes)
        .flat_map(|chunk| {
            for p in chunk {
                p.passes.fetch_add(1, Ordering::Relaxed);
            }
            let _held = in_flight.hold(batch_lanes(chunk.len()));
            let xs = vec![*x; chunk.len()];
            in_lanes(
                chunk.len(),
                &mut OnDerives {
                    problems: chunk,
                    xs: &xs,
                },
            )
        })
        .collect()
}

/// A walk's next batch of [`LANES`] points at most, `room` lanes free ([`batch_within`]).
fn batches_of_lanes(left: usize, room: usize) -> usize {
    batch_within(left, room, LANES)
}

/// Points side by side: the `i`-th at `xs[i]` on `problems[i]`, or all on the only
/// problem. The problems share their IMU series, control points and blocks; each lane
/// runs on its own problem's odometer increments.
struct OnDerives<'p, 'a> {
    problems: &'p [&'p Problem<'a>],
    xs: &'p [X],
}

impl<'a> OnDerives<'_, 'a> {
    fn problem(&self, i: usize) -> &Problem<'a> {
        self.problems[i.min(self.problems.len() - 1)]
    }
}

impl LaneBatch for OnDerives<'_, '_> {
    type Out = Observation;

    fn run<const N: usize>(&mut self, points: [usize; N]) -> [Observation; N] {
        let settings = points.map(|i| self.problem(i).settings(&self.xs[i]));
        // The odometers' sums the passes read (boresights, a speed bias).
        let columns = OdoColumns::read_by(&settings);
        ensure_moved_segments(self.problems, columns);
        let segments = points.map(|i| self.problem(i).segments_of(columns));
        let at: Vec<usize> = self.problems[0].fixes.iter().map(|f| f.sample).collect();
        // The sinks live for this batch only: each holds its pass's blocks (a run's
        // length), so none is kept once the observations are taken.
        let mut sinks: [CriteriaSink; N] = std::array::from_fn(|_| CriteriaSink::default());
        strapdown::run_criteria_segments(
            &segments[0].0,
            std::array::from_fn(|l| &*segments[l].1),
            &settings,
            &at,
            &mut sinks,
        );
        // F on the lanes' blocks side by side when they share it (the problems of a batch
        // do: they differ in their odometers only), else on each lane's.
        let blocks = sinks.each_mut().map(|s| std::mem::take(&mut s.blocks));
        let lps = points.map(|i| &self.problem(i).lp);
        let filtered = if lps.iter().all(|lp| *lp == lps[0]) {
            criteria::filtered_side_by_side(lps[0], blocks)
        } else {
            let mut lps = lps.into_iter();
            blocks.map(|b| b.filtered(lps.next().expect("one filter per lane")))
        };
        std::array::from_fn(|l| {
            self.problem(points[l]).observation_of_sink(
                &filtered[l],
                &sinks[l],
                &self.xs[points[l]],
            )
        })
    }
}

/// Integrates the moved odometers of `problems` that have no segments yet (or none with
/// `columns`), in one walk over the IMU's samples for all of them.
fn ensure_moved_segments(problems: &[&Problem<'_>], columns: OdoColumns) {
    let lacking = |p: &&&Problem<'_>| {
        p.moved_odometer.is_some()
            && !p
                .moved_segments
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .as_ref()
                .is_some_and(|s| s.columns.cover(&columns))
    };
    let mut todo: Vec<&&Problem<'_>> = problems.iter().filter(lacking).collect();
    // A problem given twice is integrated once.
    todo.dedup_by(|a, b| std::ptr::eq(**a, **b));
    let Some(first) = todo.first() else {
        return;
    };
    // Integrated again, an odometer keeps the columns it had.
    let columns = todo.iter().fold(columns, |c, p| {
        p.moved_segments
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .as_ref()
            .map_or(c, |s| c.union(&s.columns))
    });
    let plan = first.segment_plan();
    let (_, odo) = integrate_split(
        first.inputs.dt_s,
        first.inputs.dtheta_rad,
        &plan,
        false,
        todo.len(),
        |v, k| todo[v].odometer_increments_from(k),
        columns,
    );
    for (p, segs) in todo.iter().zip(odo) {
        *p.moved_segments.lock().unwrap_or_else(|e| e.into_inner()) = Some(Arc::new(segs));
    }
}

/// A lane's odometer increments: a derive's stored ones, or read from the ingested
/// odometer as the pass goes.
type LaneIncrements<'a> = Either<std::iter::Copied<std::slice::Iter<'a, f64>>, OdoIncrements<'a>>;

/// `x` moved by one finite-difference step in each setting of `which`, in turn.
pub fn moved_by_steps(x: &X, which: &[Setting]) -> Vec<X> {
    which
        .iter()
        .map(|&s| {
            let mut xs = *x;
            xs.set(s, x.get(s) + s.fd_step());
            xs
        })
        .collect()
}

/// The linearisation around `x` (observed `y`) from the observations `moved` of
/// [`moved_by_steps`]`(x, which)`.
pub(super) fn linearization_of(
    x: &X,
    y: Observation,
    which: &[Setting],
    moved: Vec<Observation>,
) -> Linearization {
    let mut slopes: [Option<Observation>; N_PARAMS] = Default::default();
    for (&s, ys) in which.iter().zip(moved) {
        slopes[s.index()] = Some(ys.slope(&y, s.fd_step()));
    }
    Linearization {
        p_ref: params_of(x),
        y_ref: y,
        slopes,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::attitude::Euler;
    use crate::derive::{DeriveParams, RawSeries, derive};

    /// A 200-second drive at 100 Hz turning gently, its odometer at 5 m/s.
    struct Drive {
        t_ns: Vec<i64>,
        dtheta_rad: Vec<[f64; 3]>,
        dvel_mps: Vec<[f64; 3]>,
        odo_m: Vec<f64>,
    }

    impl Drive {
        fn new() -> Self {
            let n = 20_000;
            Self {
                t_ns: (0..n as i64).map(|k| k * 10_000_000).collect(),
                dtheta_rad: (0..n)
                    .map(|k| [0.0, 0.0, 2e-4 * (k as f64 * 1e-3).sin()])
                    .collect(),
                dvel_mps: vec![[0.0, 0.0, -0.0981]; n],
                odo_m: (0..n).map(|k| k as f64 * 0.05).collect(),
            }
        }

        fn raw(&self) -> RawSeries<'_> {
            RawSeries {
                imu_t_ns: &self.t_ns,
                dtheta_rad: &self.dtheta_rad,
                dvel_mps: &self.dvel_mps,
                odo_t_ns: (&self.t_ns).into(),
                odo_distance_m: &self.odo_m,
            }
        }
    }

    /// The derive of [`Drive`].
    fn derived() -> crate::derive::Derived {
        derive(&Drive::new().raw(), &DeriveParams::default(), 9.81)
    }

    fn spec() -> ProblemSpec<'static> {
        ProblemSpec {
            settings: NavSettings {
                initial: Euler {
                    roll_rad: 0.0,
                    pitch_rad: 0.0,
                    heading_rad: 0.3,
                },
                drift_rad_s: [0.0; 3],
                odo_scale: 1.0,
                odo_yaw_rad: 0.0,
                odo_pitch_rad: 0.0,
                odo_bias_mps: 0.0,
                lat0_rad: 0.77,
                lon0_rad: -1.33,
                h0_m: 90.0,
            },
            filter: DeriveParams::default().filter,
            kalman: KalmanParams::default(),
            fixes: &[],
            excluded_cps: &[],
            drift_z_prior_deg_h: None,
            gyro_walk: None,
        }
    }

    /// Six points near the start: its azimuth and drifts moved.
    fn points(p: &Problem<'_>) -> Vec<X> {
        let x0 = p.x0();
        (0..6)
            .map(|i| {
                let mut x = x0;
                x.azimuth_deg += 0.1 * i as f64;
                x.drift_deg_h[i % 3] += 0.05 * i as f64;
                x
            })
            .collect()
    }

    /// Many threads' fan-out and a walk in batches keep to the lanes the budget leaves
    /// (beside those another search holds), and each observation is the pass's alone,
    /// bit for bit.
    #[test]
    fn passes_in_flight_keep_to_the_budget_and_each_is_its_pass_alone() {
        let d = derived();
        let p = spec().on(&d);
        let xs = points(&p);
        let alone: Vec<Observation> = xs.iter().map(|x| p.observe(x)).collect();
        // Observations of many epochs, each point's its own.
        assert!(alone.iter().all(|y| y.theta_rad.len() > 100));
        assert!(alone.windows(2).all(|w| w[0] != w[1]));
        let in_flight = p.segments.lanes_in_flight();
        assert_eq!((in_flight.now(), in_flight.peak()), (0, 1));
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(8)
            .build()
            .unwrap();
        let tally = AtomicUsize::new(0);
        // Eight threads for six points: one each, but two lanes at a time.
        let fanned = pool.install(|| p.observe_many_within(&xs, &tally, 2));
        assert!(fanned == alone, "the fan-out's observations");
        assert!(in_flight.peak() <= 2, "{} lanes at once", in_flight.peak());
        // A walk in batches of four with three lanes of five held elsewhere: one point at
        // a time.
        let held = in_flight.hold(3);
        let walked = p.observe_batched_within(&xs, &tally, 5);
        assert!(walked == alone, "the walk's observations");
        assert_eq!(in_flight.peak(), 4);
        // With the room, in batches of four lanes.
        drop(held);
        let walked = p.observe_batched_within(&xs, &tally, 5);
        assert!(walked == alone, "the full batches' observations");
        assert_eq!(in_flight.peak(), 4);
        assert_eq!(tally.load(Ordering::Relaxed), 3 * xs.len());
        // Derives of the run at another odometer timing share the count.
        assert!(std::ptr::eq(
            d.segments.for_other_odometer().lanes_in_flight(),
            in_flight
        ));
        assert_eq!(in_flight.now(), 0);
    }

    /// The lag search's passes of one point on several derives keep to the budget too.
    #[test]
    fn the_lag_searchs_passes_keep_to_the_budget() {
        let d = derived();
        let p = spec().on(&d);
        let x = p.x0();
        let alone = p.observe(&x);
        let refs = vec![&p; 5];
        let tally = AtomicUsize::new(0);
        // A budget of a batch of four with four lanes held elsewhere: one at a time.
        let in_flight = p.segments.lanes_in_flight();
        let cap = p.lanes_cap();
        let held = in_flight.hold(cap.saturating_sub(1));
        let ys = observe_each(&refs, &x, &tally);
        assert!(ys.iter().all(|y| *y == alone), "each derive's observation");
        assert_eq!(in_flight.peak(), cap);
        drop(held);
        assert_eq!(in_flight.now(), 0);
    }
}
