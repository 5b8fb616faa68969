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
//! 2. the odometer increment, times the scale setting, is resolved along body x (turned
//!    by the odometer's boresights, when set) with the attitude at the middle of the
//!    interval and accumulated on WGS-84 (lat, lon, h);
//! 3. the navigation frame's rotation `ζ = (ω_ie^n + ω_en^n)·Δt` at the mid-interval
//!    position is removed: `q ← q(ζ)* ⊗ q ⊗ q(φ)`.
//!
//! Splitting the update into a body factor and a navigation-frame factor is exact
//! (`Ċ = C[ω_ib×] − [ω_in×]C` has the solution `L·C₀·R`), so no commutation error builds up.
//!
//! Optimisers and sweeps run many passes over the same inputs: [`run_criteria`] steps up
//! to eight of them side by side in vector lanes (`lanes`), keeping only what the criteria
//! read, and gives each exactly what it would give alone.

mod lanes;
pub mod lanes_in_flight;
mod segment_lanes;
pub mod segments;
#[cfg(test)]
mod test_drive;

pub use segment_lanes::run_criteria_segments;

use nalgebra::UnitQuaternion;

use crate::angle_increments::AngleSlice;
use crate::attitude::Euler;
use crate::criteria::{BlockAttitude, FixPose};
use crate::earth::Geodetic;
use lanes::{Emit, Lanes, OdometerLanes, OdometerPerLane, OdometerStreams, SharedOdometer};

/// Per-sample navigation inputs; all slices have the same length.
#[derive(Debug, Clone, Copy)]
pub struct NavInputs<'a> {
    /// Length of each sample's interval, s.
    pub dt_s: &'a [f64],
    /// Angle increments, rad, body FRD (as held: [`AngleSlice`]).
    pub dtheta_rad: AngleSlice<'a>,
    /// Odometer distance travelled over each interval at the nominal scale, m.
    pub odo_dist_m: &'a [f64],
}

impl NavInputs<'_> {
    /// Whether `other` reads the very same series (not equal copies).
    pub fn same_as(&self, other: &NavInputs<'_>) -> bool {
        std::ptr::eq(self.dt_s, other.dt_s)
            && self.dtheta_rad.same_as(&other.dtheta_rad)
            && std::ptr::eq(self.odo_dist_m, other.odo_dist_m)
    }

    /// Whether `other` reads the very same IMU series (its odometer's may differ: a
    /// derive at another odometer timing).
    pub fn same_imu_as(&self, other: &NavInputs<'_>) -> bool {
        std::ptr::eq(self.dt_s, other.dt_s) && self.dtheta_rad.same_as(&other.dtheta_rad)
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.dt_s.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.dt_s.is_empty()
    }

    /// The samples [`run`] steps over (and hands its sink): those with an interval, an
    /// angle increment and an odometer increment.
    pub fn pass_samples(&self) -> usize {
        self.dt_s
            .len()
            .min(self.dtheta_rad.len())
            .min(self.odo_dist_m.len())
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
    /// Odometer-to-body pitch boresight, rad: the path climbs above the body's x by this
    /// angle (positive: up, towards −z). Each metre of the odometer's distance also moves
    /// the height by tan(angle) along body −z (the cosine of the body's pitch and roll).
    /// It moves the height alone: its horizontal part, of the order of the angle times
    /// the body's pitch, is the odometer scale's, which the horizontal fit took.
    pub odo_pitch_rad: f64,
    /// Odometer speed bias, m/s: added to the speed over every sample in which the
    /// odometer moved (an OBD-II speed's offset; a stopped car still reads zero).
    pub odo_bias_mps: f64,
    /// Start latitude, rad.
    pub lat0_rad: f64,
    /// Start longitude, rad.
    pub lon0_rad: f64,
    /// Start height, m.
    pub h0_m: f64,
}

impl NavSettings {
    /// Where the pass starts.
    pub fn start(&self) -> Geodetic {
        Geodetic {
            lat_rad: self.lat0_rad,
            lon_rad: self.lon0_rad,
            h_m: self.h0_m,
        }
    }
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
    (c32.atan2(c33), (-c31).atan2(crate::hypot::hypot(c32, c33)))
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

/// The rows of `C_b^n` of a unit quaternion (w, x, y, z).
#[inline(always)]
pub fn dcm_rows(q: [f64; 4]) -> [[f64; 3]; 3] {
    let [w, x, y, z] = q;
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// Euler angles of the quaternion `[w, x, y, z]` of `C_b^n`.
pub fn euler_of(q: &[f64; 4]) -> Euler {
    let [w, x, y, z] = *q;
    Euler::from_quat_b_to_n(&UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(
        w, x, y, z,
    )))
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

    /// Empties every column, keeping their room.
    pub fn clear(&mut self) {
        for v in [
            &mut self.lat_rad,
            &mut self.lon_rad,
            &mut self.h_m,
            &mut self.distance_m,
        ] {
            v.clear();
        }
        self.q_b_to_n.clear();
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
        euler_of(&self.q_b_to_n[k])
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

/// Latitude change that refreshes the latitude-dependent terms (Earth radii and rate,
/// 1/cos, tan), rad: 6 m, over which they change by less than 1e-8 relative.
const LAT_REFRESH_RAD: f64 = 1e-6;

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

/// A sink that may be absent: the samples go to it when it is there.
impl<S: PassSink> PassSink for Option<S> {
    #[inline(always)]
    fn sample(&mut self, k: usize, lat: f64, lon: f64, h: f64, q: &[f64; 4], distance_m: f64) {
        if let Some(s) = self {
            s.sample(k, lat, lon, h, q, distance_m);
        }
    }
}

/// Runs the navigation over all samples, writing `track` (resized to the input length).
pub fn navigate(inputs: &NavInputs<'_>, s: &NavSettings, track: &mut NavTrack) {
    track.resize(inputs.len());
    run(inputs, s, track);
}

/// The attitude per block of `block` samples, and the positions at chosen samples: all
/// that the criteria read from a pass, without storing the track.
#[derive(Debug, Clone, Default)]
pub struct CriteriaSink {
    /// Samples per block.
    pub block: usize,
    /// Roll and pitch of each block's sum of the samples' third rows of `C_b^n`.
    pub blocks: BlockAttitude,
    /// The pose at each requested sample, in sample order.
    pub positions: Vec<(usize, FixPose)>,
    wanted: Vec<usize>,
}

impl CriteriaSink {
    /// Clears the sink for a pass over `len` samples in blocks of `block`, recording the
    /// positions at `samples`.
    fn reset(&mut self, len: usize, block: usize, samples: impl IntoIterator<Item = usize>) {
        self.block = block.max(1);
        self.blocks.clear_for(len, self.block);
        self.positions.clear();
        self.wanted.clear();
        self.wanted.extend(samples);
        self.wanted.sort_unstable();
        self.wanted.dedup();
        self.wanted.reverse(); // popped from the end, in sample order
    }

    /// The pose recorded at `sample`.
    pub fn position_at(&self, sample: usize) -> Option<FixPose> {
        self.positions
            .binary_search_by_key(&sample, |p| p.0)
            .ok()
            .map(|i| self.positions[i].1)
    }
}

/// Runs the navigation over all samples into `sink`.
pub fn run(inputs: &NavInputs<'_>, s: &NavSettings, sink: &mut impl PassSink) {
    Lanes::<1>::new(&[*s]).run(inputs, &mut ToPassSink(sink));
}

/// A [`PassSink`] fed from a single lane.
struct ToPassSink<'a, S>(&'a mut S);

impl<S: PassSink> Emit<1> for ToPassSink<'_, S> {
    #[inline(always)]
    fn emit(&mut self, k: usize, lane: &Lanes<1>) {
        self.0.sample(
            k,
            lane.lat_rad[0],
            lane.lon_rad[0],
            lane.h_m[0],
            &lane.q_of(0),
            lane.distance_m[0],
        );
    }
}

/// Most passes stepped side by side in one batch of vector lanes.
pub const MAX_LANES: usize = 8;

/// Work on a few points (passes) that runs them side by side in `N` lanes, for any `N`
/// [`in_lanes`] picks.
pub trait LaneBatch {
    /// What one point gives.
    type Out;
    /// The points `points` (indices; the last one repeated to fill the lanes) side by
    /// side.
    fn run<const N: usize>(&mut self, points: [usize; N]) -> [Self::Out; N];
}

/// The `n` ≤ [`MAX_LANES`] points of `batch` in one batch of 1, 4 or 8 lanes (a partial
/// batch repeats its last point), their results in order. Two points run in four lanes:
/// two lanes cost more than four (`unz bench navigate`: a 100-Hz pass 8.5 ms a lane two
/// side by side against 3.5–4 four side by side, a segment pass 1.63–1.68 ms against
/// 0.65–0.68).
///
/// # Panics
/// If `n` exceeds [`MAX_LANES`].
pub fn in_lanes<B: LaneBatch>(n: usize, batch: &mut B) -> Vec<B::Out> {
    assert!(n <= MAX_LANES, "{n} points for {MAX_LANES} lanes");
    fn points<const N: usize>(n: usize) -> [usize; N] {
        std::array::from_fn(|l| l.min(n - 1))
    }
    let out: Vec<B::Out> = match batch_lanes(n) {
        0 => return Vec::new(),
        1 => batch.run::<1>(points(n)).into(),
        4 => batch.run::<4>(points(n)).into(),
        _ => batch.run::<8>(points(n)).into(),
    };
    out.into_iter().take(n).collect()
}

/// The lanes [`in_lanes`] runs `n` points in: 0, 1, 4 or 8 (past [`MAX_LANES`], `n`).
pub fn batch_lanes(n: usize) -> usize {
    match n {
        0 | 1 => n,
        2..=4 => 4,
        5..=MAX_LANES => MAX_LANES,
        _ => n,
    }
}

/// Runs `N` passes side by side (one per settings) into `sinks`, each reset first for
/// blocks of `block` samples and the positions at `positions_at`: what the optimisers
/// and sweeps read, several passes per vector instruction. Each sink ends exactly as a
/// pass alone would leave it.
pub fn run_criteria<const N: usize>(
    inputs: &NavInputs<'_>,
    settings: &[NavSettings; N],
    block: usize,
    positions_at: &[usize],
    sinks: &mut [CriteriaSink; N],
) {
    run_criteria_on(
        inputs,
        &mut SharedOdometer,
        settings,
        block,
        positions_at,
        sinks,
    );
}

/// [`run_criteria`] with each lane on the odometer increments `odometers[l]` yields (at
/// least as many as `inputs` has samples; `inputs.odo_dist_m` is not read): passes over
/// derives at several odometer timings side by side, each as it would run alone, their
/// increments stored or read as the passes go.
///
/// # Panics
/// If an odometer yields fewer increments than `inputs` has samples.
pub fn run_criteria_streams<const N: usize, I: ExactSizeIterator<Item = f64>>(
    inputs: &NavInputs<'_>,
    odometers: [I; N],
    settings: &[NavSettings; N],
    block: usize,
    positions_at: &[usize],
    sinks: &mut [CriteriaSink; N],
) {
    assert!(
        odometers.iter().all(|o| o.len() >= inputs.len()),
        "an odometer series shorter than the IMU's"
    );
    let mut odometer = OdometerStreams(odometers);
    run_criteria_on(inputs, &mut odometer, settings, block, positions_at, sinks);
}

/// [`run_criteria`] with the lanes' odometer increments from `odometer`.
fn run_criteria_on<const N: usize>(
    inputs: &NavInputs<'_>,
    odometer: &mut impl OdometerLanes<N>,
    settings: &[NavSettings; N],
    block: usize,
    positions_at: &[usize],
    sinks: &mut [CriteriaSink; N],
) {
    let mut lanes_sink = CriteriaLanes::new(sinks, inputs.len(), block, positions_at);
    Lanes::<N>::new(settings).run_on(inputs, odometer, &mut lanes_sink);
    lanes_sink.close_block();
}

/// Of a run of `n` samples, every `step`-th (from the first; a step of 0 counts as 1)
/// and the last, in a vector sized to them.
pub fn samples_every(n: usize, step: usize) -> Vec<usize> {
    let step = step.max(1);
    let mut out = Vec::with_capacity(n.div_ceil(step) + 1);
    out.extend((0..n).step_by(step));
    if n > 0 && out.last() != Some(&(n - 1)) {
        out.push(n - 1);
    }
    out
}

/// Position and attitude of a pass at one sample: latitude, longitude (rad) and the
/// quaternion `C_b^n` (w, x, y, z).
pub type StateAt = (f64, f64, [f64; 4]);

/// One pass's state at a kept sample: latitude, longitude (rad), height (m) and the
/// quaternion of `C_b^n` (w, x, y, z).
pub type TrackRow = (f64, f64, f64, [f64; 4]);

/// Where a review pass's states at its kept samples go, as the pass reaches them.
pub trait KeepRows {
    /// The state `row` at sample `k`.
    fn keep(&mut self, k: usize, row: TrackRow);
}

/// The rows as they are.
impl KeepRows for Vec<TrackRow> {
    fn keep(&mut self, _k: usize, row: TrackRow) {
        self.push(row);
    }
}

/// Rows that may go nowhere (a lane that repeats another).
impl<R: KeepRows> KeepRows for Option<R> {
    #[inline]
    fn keep(&mut self, k: usize, row: TrackRow) {
        if let Some(r) = self {
            r.keep(k, row);
        }
    }
}

/// What [`run_review`] keeps of one pass.
#[derive(Debug, Clone, Default)]
pub struct ReviewPass<R> {
    /// What the criteria read (the sums per block, the positions at the control points).
    pub criteria: CriteriaSink,
    /// The states at the kept samples.
    pub rows: R,
}

/// Passes for review side by side, each lane on its own odometer increments
/// (`odometers[l]`, as long as `inputs`): each keeps what the criteria read (blocks of
/// `block` samples, positions at `positions_at`) and hands its states at `keep`
/// (increasing) to `rows[l]` as it reaches them, and lane `tracked` also feeds every
/// sample to `track` (a [`NavTrack`] sized to the input, or a sink that keeps less). Each
/// is exactly what the pass alone, tracked, gives.
///
/// # Panics
/// If an odometer series is shorter than `inputs`, or `tracked` is not a lane.
#[allow(clippy::too_many_arguments)]
pub fn run_review<const N: usize, R: KeepRows>(
    inputs: &NavInputs<'_>,
    odometers: [&[f64]; N],
    settings: &[NavSettings; N],
    block: usize,
    positions_at: &[usize],
    keep: &[usize],
    rows: [R; N],
    tracked: usize,
    track: &mut impl PassSink,
) -> [ReviewPass<R>; N] {
    assert!(tracked < N, "lane {tracked} of {N}");
    assert!(
        odometers.iter().all(|o| o.len() >= inputs.len()),
        "an odometer series shorter than the IMU's"
    );
    let mut sinks: [CriteriaSink; N] = std::array::from_fn(|_| CriteriaSink::default());
    let mut review = ReviewLanes {
        criteria: CriteriaLanes::new(&mut sinks, inputs.len(), block, positions_at),
        keep,
        next: 0,
        rows,
        tracked,
        track,
    };
    Lanes::<N>::new(settings).run_on(inputs, &mut OdometerPerLane(odometers), &mut review);
    review.criteria.close_block();
    let mut rows = review.rows.into_iter();
    sinks.map(|criteria| ReviewPass {
        criteria,
        rows: rows.next().expect("one row sink per lane"),
    })
}

/// [`run_review`]'s sink.
struct ReviewLanes<'a, const N: usize, R, S> {
    criteria: CriteriaLanes<'a, N>,
    keep: &'a [usize],
    next: usize,
    rows: [R; N],
    tracked: usize,
    track: &'a mut S,
}

impl<const N: usize, R: KeepRows, S: PassSink> Emit<N> for ReviewLanes<'_, N, R, S> {
    #[inline(always)]
    fn emit(&mut self, k: usize, lanes: &Lanes<N>) {
        self.criteria.emit(k, lanes);
        if self.keep.get(self.next) == Some(&k) {
            self.next += 1;
            for (l, rows) in self.rows.iter_mut().enumerate() {
                rows.keep(
                    k,
                    (
                        lanes.lat_rad[l],
                        lanes.lon_rad[l],
                        lanes.h_m[l],
                        lanes.q_of(l),
                    ),
                );
            }
        }
        let t = self.tracked;
        self.track.sample(
            k,
            lanes.lat_rad[t],
            lanes.lon_rad[t],
            lanes.h_m[t],
            &lanes.q_of(t),
            lanes.distance_m[t],
        );
    }
}

/// Runs `N` passes side by side (one per settings) and returns each one's state at
/// `samples` (increasing; samples past the end are left out), as `map(lane, i, state)`
/// makes of the state at `samples[i]`: what a covariance propagated along the route
/// reads, without storing `N` tracks (nor `N` series of whole states, where the caller
/// keeps less).
pub fn run_states_at<const N: usize, T>(
    inputs: &NavInputs<'_>,
    settings: &[NavSettings; N],
    samples: &[usize],
    mut map: impl FnMut(usize, usize, StateAt) -> T,
) -> [Vec<T>; N] {
    let mut out: [Vec<T>; N] = std::array::from_fn(|_| Vec::with_capacity(samples.len()));
    let odometers = [(); N].map(|()| inputs.odo_dist_m.iter().copied());
    run_states_each(inputs, odometers, settings, samples, |i, states| {
        for (l, (out, state)) in out.iter_mut().zip(states).enumerate() {
            out.push(map(l, i, state));
        }
    });
    out
}

/// Runs `N` passes side by side, each lane on the odometer increments `odometers[l]`
/// yields (stored or read as the pass goes; at least as many as `inputs` has samples;
/// `inputs.odo_dist_m` is not read), and hands `each(i, states)` every lane's state at
/// `samples[i]` (increasing; samples past the end are left out): what combines the passes
/// sample by sample reads, without storing any pass's states.
///
/// # Panics
/// If an odometer yields fewer increments than `inputs` has samples.
pub fn run_states_each<const N: usize, I: ExactSizeIterator<Item = f64>>(
    inputs: &NavInputs<'_>,
    odometers: [I; N],
    settings: &[NavSettings; N],
    samples: &[usize],
    each: impl FnMut(usize, [StateAt; N]),
) {
    assert!(
        odometers.iter().all(|o| o.len() >= inputs.len()),
        "an odometer series shorter than the IMU's"
    );
    let mut sink = StatesEach {
        samples,
        next: 0,
        each,
    };
    Lanes::<N>::new(settings).run_on(inputs, &mut OdometerStreams(odometers), &mut sink);
}

/// [`run_states_each`]'s sink.
struct StatesEach<'a, F> {
    samples: &'a [usize],
    next: usize,
    each: F,
}

impl<const N: usize, F: FnMut(usize, [StateAt; N])> Emit<N> for StatesEach<'_, F> {
    #[inline(always)]
    fn emit(&mut self, k: usize, lanes: &Lanes<N>) {
        if self.samples.get(self.next) == Some(&k) {
            let i = self.next;
            self.next += 1;
            (self.each)(
                i,
                std::array::from_fn(|l| (lanes.lat_rad[l], lanes.lon_rad[l], lanes.q_of(l))),
            );
        }
    }
}

/// `N` [`CriteriaSink`]s fed side by side: the block sums are accumulated in vector
/// lanes and handed to each sink when a block closes.
struct CriteriaLanes<'a, const N: usize> {
    sinks: &'a mut [CriteriaSink; N],
    block: usize,
    acc: [[f64; N]; 3],
    in_block: usize,
    next_wanted: Option<usize>,
}

impl<'a, const N: usize> CriteriaLanes<'a, N> {
    /// Feeds `sinks`, each reset first for a pass over `len` samples in blocks of `block`
    /// and the positions at `positions_at`.
    fn new(
        sinks: &'a mut [CriteriaSink; N],
        len: usize,
        block: usize,
        positions_at: &[usize],
    ) -> Self {
        for sink in sinks.iter_mut() {
            sink.reset(len, block, positions_at.iter().copied());
        }
        Self {
            next_wanted: sinks.first().and_then(|s| s.wanted.last().copied()),
            sinks,
            block: block.max(1),
            acc: [[0.0; N]; 3],
            in_block: 0,
        }
    }

    fn close_block(&mut self) {
        if self.in_block > 0 {
            for (l, sink) in self.sinks.iter_mut().enumerate() {
                sink.blocks
                    .push_row3_sum([self.acc[0][l], self.acc[1][l], self.acc[2][l]]);
            }
            self.acc = [[0.0; N]; 3];
            self.in_block = 0;
        }
    }
}

impl<const N: usize> Emit<N> for CriteriaLanes<'_, N> {
    #[inline(always)]
    fn emit(&mut self, k: usize, lanes: &Lanes<N>) {
        let r = lanes.dcm_row3();
        for (a, ri) in self.acc.iter_mut().zip(&r) {
            for l in 0..N {
                a[l] += ri[l];
            }
        }
        self.in_block += 1;
        if self.in_block == self.block {
            self.close_block();
        }
        if self.next_wanted == Some(k) {
            for (l, sink) in self.sinks.iter_mut().enumerate() {
                sink.wanted.pop();
                let pose = FixPose {
                    lat_rad: lanes.lat_rad[l],
                    lon_rad: lanes.lon_rad[l],
                    h_m: lanes.h_m[l],
                    distance_m: lanes.distance_m[l],
                    q_b_to_n: lanes.q_of(l),
                };
                sink.positions.push((k, pose));
            }
            self.next_wanted = self.sinks.first().and_then(|s| s.wanted.last().copied());
        }
    }
}
