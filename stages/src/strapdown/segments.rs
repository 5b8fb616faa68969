//! The IMU's and the odometer's increments integrated once over short stretches of a run
//! (segments), so that the many passes an optimiser runs step once per segment instead
//! of once per sample ([`super::run_criteria_segments`]).
//!
//! A segment is a block of F (`block` samples: 0.1 s at 100 Hz), cut after each sample
//! a pass must report that is not a block's last (a control point's stop). With `R_k` the body's turn from the
//! segment's start to the end of its `k`-th sample (`R_0 = I`: the product of the
//! kernel's rotation vectors, coning term included, at zero drift), a segment keeps
//! - `q`: `R_K`, the body's turn over the whole segment, as a quaternion;
//! - `m`: `Σ_k R_k`: the sum over the segment's samples of `C_b^n`'s third row (what
//!   Kryt1 reads per block) is the third row of `C_b^n` at the segment's start times it;
//! - `t_s`: its length;
//!
//! and, of an odometer with increments `d_k`,
//! - `S = Σ_k d_k (R_{k−1} + R_k)/2`: the increments in the start's body axes, each
//!   resolved with the attitude at the middle of its interval as the kernel resolves it;
//!   the route moves by `C_b^n · S · (the odometer's direction in the body)`. Its first
//!   column (along the body's x) always, with `Σ_k d_k`; its second (y) when a yaw
//!   boresight turns the odometer towards it, its third (z) when a pitch boresight
//!   climbs by it ([`OdoColumns`]: a pass reads no more, and a 12-hour run keeps 7 MB
//!   where the whole matrix took 17 MB);
//! - for an odometer speed bias, the same with `dt_k` for `d_k` over the samples in
//!   which the odometer moved.
//!
//! None of these depends on a pass's settings (azimuth, drifts, odometer scale, bias and
//! boresights), which act on them as `segment_lanes` says. `m` and `S` are kept in f32:
//! their rounding (6e-8 of a block's sums) moves a block's attitude by under 1e-7 rad and
//! the route by under a micrometre a segment, far below what the criteria resolve.

// Lane loops index several arrays by the lane: an index is clearer than zipped iterators.
#![allow(clippy::needless_range_loop)]

use std::sync::{Arc, Mutex};

use rayon::prelude::*;

use super::lanes_in_flight::LanesInFlight;
use crate::angle_increments::{AngleSlice, Increment3};
use crate::attitude::{HALF_ANGLE_SERIES_LIMIT_RAD2, half_angle_exact, half_angle_series};

/// Where a run's segments end: blocks of `block` samples, cut after each of `cuts`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SegmentPlan {
    /// Samples the segments cover.
    pub samples: usize,
    /// Samples per block of F (at least one).
    pub block: usize,
    /// The samples after which a segment ends besides the blocks' last (increasing, each
    /// below `samples`).
    pub cuts: Vec<usize>,
}

/// The end of one segment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SegmentEnd {
    /// The sample after the segment's last (exclusive end).
    pub end: usize,
    /// Whether it closes a block of F.
    pub closes_block: bool,
}

impl SegmentPlan {
    /// Segments over `samples` samples in blocks of `block`, cut after each of `cuts` (any
    /// order; repeats, blocks' last samples and samples past the end are left out).
    pub fn new(samples: usize, block: usize, cuts: impl IntoIterator<Item = usize>) -> Self {
        let block = block.max(1);
        let mut cuts: Vec<usize> = cuts
            .into_iter()
            .filter(|&k| k + 1 < samples && !(k + 1).is_multiple_of(block))
            .collect();
        cuts.sort_unstable();
        cuts.dedup();
        Self {
            samples,
            block,
            cuts,
        }
    }

    /// The segments' ends, in order.
    pub fn ends(&self) -> impl Iterator<Item = SegmentEnd> + '_ {
        let n = self.samples;
        let mut block_end = self.block.min(n);
        let mut cuts = self.cuts.iter().map(|k| k + 1).peekable();
        let mut at = 0;
        std::iter::from_fn(move || {
            if at >= n {
                return None;
            }
            let cut = cuts.peek().copied().unwrap_or(usize::MAX);
            let end = block_end.min(cut);
            if end == cut {
                cuts.next();
            }
            let closes_block = end == block_end;
            if closes_block {
                block_end = (block_end + self.block).min(n);
            }
            at = end;
            Some(SegmentEnd { end, closes_block })
        })
    }

    /// How many segments.
    pub fn count(&self) -> usize {
        self.samples.div_ceil(self.block) + self.cuts.len()
    }

    /// Whether a pass can report its state after sample `k` (a segment ends there).
    pub fn ends_after(&self, k: usize) -> bool {
        k < self.samples
            && ((k + 1).is_multiple_of(self.block)
                || k + 1 == self.samples
                || self.cuts.binary_search(&k).is_ok())
    }
}

/// One segment of the IMU's increments.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSegment {
    /// The body's turn over the segment, `C_{b_end}^{b_start}` as (w, x, y, z).
    pub q: [f64; 4],
    /// `Σ_k R_k`, row-major.
    pub m: [f32; 9],
    /// Length, s.
    pub t_s: f32,
}

/// A run's IMU increments over its segments.
#[derive(Debug, Clone, PartialEq)]
pub struct ImuSegments {
    /// The plan they follow.
    pub plan: SegmentPlan,
    /// Each segment.
    pub segments: Vec<ImuSegment>,
}

/// Which of an odometer's sums are integrated beyond its first column and distance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct OdoColumns {
    /// The second column (along the body's y): a yaw boresight reads it.
    pub yaw: bool,
    /// The third column (along the body's z): a pitch boresight reads it.
    pub pitch: bool,
    /// The same over the moving time: a speed bias reads it.
    pub moving: bool,
}

impl OdoColumns {
    /// What passes with `settings` read.
    pub fn read_by(settings: &[super::NavSettings]) -> Self {
        Self {
            yaw: settings.iter().any(|s| s.odo_yaw_rad != 0.0),
            pitch: settings.iter().any(|s| s.odo_pitch_rad != 0.0),
            moving: settings.iter().any(|s| s.odo_bias_mps != 0.0),
        }
    }

    /// Whether these hold all of `other`.
    pub fn cover(&self, other: &Self) -> bool {
        (self.yaw || !other.yaw) && (self.pitch || !other.pitch) && (self.moving || !other.moving)
    }

    /// Both's.
    pub fn union(&self, other: &Self) -> Self {
        Self {
            yaw: self.yaw || other.yaw,
            pitch: self.pitch || other.pitch,
            moving: self.moving || other.moving,
        }
    }
}

/// One odometer series' sums over each segment: `S`'s columns (f32).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OdoSums {
    /// `S`'s first column, and `Σ_k d_k`: m (s for the moving time).
    pub x: Vec<[f32; 4]>,
    /// `S`'s second column, when integrated (else empty).
    pub y: Vec<[f32; 3]>,
    /// `S`'s third column, when integrated (else empty).
    pub z: Vec<[f32; 3]>,
}

impl OdoSums {
    /// `count` segments' sums of `columns`, zero until a walk writes them (zeroed pages:
    /// no memory is touched before it).
    fn zeroed(count: usize, columns: &OdoColumns) -> Self {
        Self {
            x: vec![[0.0; 4]; count],
            y: vec![[0.0; 3]; if columns.yaw { count } else { 0 }],
            z: vec![[0.0; 3]; if columns.pitch { count } else { 0 }],
        }
    }

    /// Room to write all the segments in.
    fn room(&mut self) -> OdoSumsRoom<'_> {
        OdoSumsRoom {
            x: &mut self.x,
            y: &mut self.y,
            z: &mut self.z,
        }
    }
}

/// Room in a run's [`OdoSums`] for a stretch of its segments (the columns not integrated
/// empty).
struct OdoSumsRoom<'a> {
    x: &'a mut [[f32; 4]],
    y: &'a mut [[f32; 3]],
    z: &'a mut [[f32; 3]],
}

impl<'a> OdoSumsRoom<'a> {
    /// The room of the first `k` segments, and of the rest.
    fn split_at(self, k: usize) -> (Self, Self) {
        let (x, x_rest) = self.x.split_at_mut(k);
        let (y, y_rest) = self.y.split_at_mut(k.min(self.y.len()));
        let (z, z_rest) = self.z.split_at_mut(k.min(self.z.len()));
        (
            Self { x, y, z },
            Self {
                x: x_rest,
                y: y_rest,
                z: z_rest,
            },
        )
    }

    /// Writes segment `i`'s sums (`s` row-major, `dist`), the columns there is room for.
    fn set(&mut self, i: usize, s: &[f64; 9], dist: f64) {
        let column = |j: usize| [s[j] as f32, s[3 + j] as f32, s[6 + j] as f32];
        let [x0, x1, x2] = column(0);
        self.x[i] = [x0, x1, x2, dist as f32];
        if let Some(y) = self.y.get_mut(i) {
            *y = column(1);
        }
        if let Some(z) = self.z.get_mut(i) {
            *z = column(2);
        }
    }
}

/// An odometer's increments over a run's segments.
#[derive(Debug, Clone, PartialEq)]
pub struct OdoSegments {
    /// The columns integrated.
    pub columns: OdoColumns,
    /// The distances' sums.
    pub distance: OdoSums,
    /// The moving time's sums, when integrated (`columns.moving`).
    pub moving: Option<OdoSums>,
}

impl OdoSegments {
    /// `count` segments of `columns`, zero until a walk writes them.
    fn zeroed(count: usize, columns: OdoColumns) -> Self {
        Self {
            columns,
            distance: OdoSums::zeroed(count, &columns),
            moving: columns.moving.then(|| OdoSums::zeroed(count, &columns)),
        }
    }

    /// Room to write all the segments in.
    fn room(&mut self) -> OdoSegmentsRoom<'_> {
        OdoSegmentsRoom {
            distance: self.distance.room(),
            moving: self.moving.as_mut().map(OdoSums::room),
        }
    }
}

/// Room in a run's [`OdoSegments`] for a stretch of its segments.
struct OdoSegmentsRoom<'a> {
    distance: OdoSumsRoom<'a>,
    moving: Option<OdoSumsRoom<'a>>,
}

impl<'a> OdoSegmentsRoom<'a> {
    /// The room of the first `k` segments, and of the rest.
    fn split_at(self, k: usize) -> (Self, Self) {
        let (distance, distance_rest) = self.distance.split_at(k);
        let (moving, moving_rest) = match self.moving.map(|m| m.split_at(k)) {
            Some((m, rest)) => (Some(m), Some(rest)),
            None => (None, None),
        };
        (
            Self { distance, moving },
            Self {
                distance: distance_rest,
                moving: moving_rest,
            },
        )
    }
}

/// A walk's results over a run's segments, written in place: each stretch of a split walk
/// writes its own part of them, so the walk holds the run's segments once (not each
/// stretch's as well until they are joined).
struct WalkOutputs {
    imu: Option<Vec<ImuSegment>>,
    odo: Vec<OdoSegments>,
}

impl WalkOutputs {
    /// `count` segments of the IMU's (when `imu`) and of `odometers` odometers' sums of
    /// `columns`, to be written.
    fn zeroed(count: usize, imu: bool, odometers: usize, columns: OdoColumns) -> Self {
        const UNWRITTEN: ImuSegment = ImuSegment {
            q: [0.0; 4],
            m: [0.0; 9],
            t_s: 0.0,
        };
        Self {
            imu: imu.then(|| vec![UNWRITTEN; count]),
            odo: (0..odometers)
                .map(|_| OdoSegments::zeroed(count, columns))
                .collect(),
        }
    }

    /// The results, written, as the segments of `plan`.
    fn over(self, plan: &SegmentPlan) -> (Option<ImuSegments>, Vec<OdoSegments>) {
        let imu = self.imu.map(|segments| ImuSegments {
            plan: plan.clone(),
            segments,
        });
        (imu, self.odo)
    }

    /// Room to write all the segments in.
    fn room(&mut self) -> WalkRoom<'_> {
        WalkRoom {
            imu: self.imu.as_deref_mut(),
            odo: self.odo.iter_mut().map(OdoSegments::room).collect(),
        }
    }
}

/// Room in a walk's results for a stretch of its segments.
struct WalkRoom<'a> {
    imu: Option<&'a mut [ImuSegment]>,
    odo: Vec<OdoSegmentsRoom<'a>>,
}

impl<'a> WalkRoom<'a> {
    /// The room of the first `k` segments, and of the rest.
    fn split_at(self, k: usize) -> (Self, Self) {
        let (imu, imu_rest) = match self.imu.map(|s| s.split_at_mut(k)) {
            Some((s, rest)) => (Some(s), Some(rest)),
            None => (None, None),
        };
        let (odo, odo_rest) = self.odo.into_iter().map(|o| o.split_at(k)).unzip();
        (
            Self { imu, odo },
            Self {
                imu: imu_rest,
                odo: odo_rest,
            },
        )
    }
}

/// The rotation matrix (row-major) of a unit quaternion (w, x, y, z).
#[inline(always)]
fn dcm(q: [f64; 4]) -> [f64; 9] {
    let [r0, r1, r2] = super::dcm_rows(q);
    [
        r0[0], r0[1], r0[2], r1[0], r1[1], r1[2], r2[0], r2[1], r2[2],
    ]
}

/// The unit quaternions (w, x, y, z) of each lane's rotation vector `v[.][l]`, rad:
/// sin(a/2)/a and cos(a/2) by their series, and exactly for the lanes beyond it.
#[inline(always)]
pub(super) fn turns<const N: usize>(v: &[[f64; N]; 3]) -> [[f64; N]; 4] {
    let mut a2 = [0.0; N];
    let mut e = [[0.0; N]; 4];
    for l in 0..N {
        a2[l] = v[0][l] * v[0][l] + v[1][l] * v[1][l] + v[2][l] * v[2][l];
        let (s, c) = half_angle_series(a2[l]);
        e[0][l] = c;
        for i in 0..3 {
            e[i + 1][l] = s * v[i][l];
        }
    }
    for l in 0..N {
        if a2[l] >= HALF_ANGLE_SERIES_LIMIT_RAD2 {
            let (s, c) = half_angle_exact(a2[l]);
            e[0][l] = c;
            for i in 0..3 {
                e[i + 1][l] = s * v[i][l];
            }
        }
    }
    e
}

/// `a ⊗ b` of quaternions (w, x, y, z).
#[inline(always)]
pub(super) fn qmul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    let [aw, ax, ay, az] = a;
    let [bw, bx, by, bz] = b;
    [
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ]
}

/// Segments integrated side by side, one per vector lane.
const WIDTH: usize = 4;

/// Integrates the IMU's increments (`dt_s`, `dtheta_rad`) over `plan`'s segments when
/// `imu` is set, and each of `odometers` (increments per sample, at least
/// `plan.samples` of them; missing ones count as 0), the sums `columns` asks for: one walk
/// over the samples for all of them.
///
/// Four consecutive segments are integrated side by side in vector lanes (each
/// segment's products are a chain of dependent operations; four chains keep the CPU's
/// units busy), each lane exactly as a segment alone would be.
pub fn integrate<I: Iterator<Item = f64>>(
    dt_s: &[f64],
    dtheta_rad: AngleSlice<'_>,
    plan: &SegmentPlan,
    imu: bool,
    odometers: &mut [I],
    columns: OdoColumns,
) -> (Option<ImuSegments>, Vec<OdoSegments>) {
    let mut out = WalkOutputs::zeroed(plan.count(), imu, odometers.len(), columns);
    Part::new(dt_s, dtheta_rad, plan, imu, columns).integrate(
        plan.ends(),
        0,
        odometers,
        out.room(),
    );
    out.over(plan)
}

/// Where a walk's odometer increments come from, a span of samples at a time: any
/// iterator of them, or a source that also takes them for other sums as they are read.
pub trait IncrementSource {
    /// Appends the next `n` increments to `out` (zeros past the source's end).
    fn fill(&mut self, out: &mut Vec<f64>, n: usize);
}

impl<I: Iterator<Item = f64>> IncrementSource for I {
    #[inline]
    fn fill(&mut self, out: &mut Vec<f64>, n: usize) {
        out.extend((0..n).map(|_| self.next().unwrap_or(0.0)));
    }
}

/// Segments a run must have before [`integrate_split`] splits it between threads (about
/// 14 minutes at 100 Hz): below, one walk costs less than a millisecond or two.
pub const SPLIT_SEGMENTS: usize = 8192;

/// [`integrate`], the run split into consecutive stretches of segments integrated side by
/// side on rayon's threads (a segment's sums depend on its own samples and the one
/// before only, so the result is the same, bit for bit). Odometer `v`'s increments from
/// sample `k` on are `odometer(v, k)`.
pub fn integrate_split<I, F>(
    dt_s: &[f64],
    dtheta_rad: AngleSlice<'_>,
    plan: &SegmentPlan,
    imu: bool,
    odometers: usize,
    odometer: F,
    columns: OdoColumns,
) -> (Option<ImuSegments>, Vec<OdoSegments>)
where
    I: Iterator<Item = f64>,
    F: Fn(usize, usize) -> I + Sync,
{
    integrate_split_aligned(dt_s, dtheta_rad, plan, imu, odometers, odometer, columns, 1)
}

/// [`integrate_split`] with every stretch but the first starting at a multiple of
/// `align` samples (the first segment end from each even share on that is one; fewer
/// stretches when none is): for a walk whose odometer increments also feed series of
/// `align`-sample blocks, each stretch then holds whole blocks.
#[allow(clippy::too_many_arguments)]
pub fn integrate_split_aligned<I, F>(
    dt_s: &[f64],
    dtheta_rad: AngleSlice<'_>,
    plan: &SegmentPlan,
    imu: bool,
    odometers: usize,
    odometer: F,
    columns: OdoColumns,
    align: usize,
) -> (Option<ImuSegments>, Vec<OdoSegments>)
where
    I: IncrementSource,
    F: Fn(usize, usize) -> I + Sync,
{
    let parts = rayon::current_num_threads().min(plan.count() / SPLIT_SEGMENTS);
    Part::new(dt_s, dtheta_rad, plan, imu, columns).in_stretches(
        plan,
        odometers,
        odometer,
        parts,
        align.max(1),
    )
}

/// What every stretch of a run's segments is integrated from.
#[derive(Clone, Copy)]
struct Part<'a> {
    dt_s: &'a [f64],
    dtheta_rad: AngleSlice<'a>,
    /// Samples there are increments for.
    n: usize,
    imu: bool,
    columns: OdoColumns,
}

impl<'a> Part<'a> {
    fn new(
        dt_s: &'a [f64],
        dtheta_rad: AngleSlice<'a>,
        plan: &SegmentPlan,
        imu: bool,
        columns: OdoColumns,
    ) -> Self {
        Self {
            dt_s,
            dtheta_rad,
            n: plan.samples.min(dt_s.len()).min(dtheta_rad.len()),
            imu,
            columns,
        }
    }

    /// [`integrate_split`] of `plan` in `parts` stretches (at least one, at most one a
    /// segment), each but the first starting at a multiple of `align` samples.
    fn in_stretches<I, F>(
        &self,
        plan: &SegmentPlan,
        odometers: usize,
        odometer: F,
        parts: usize,
        align: usize,
    ) -> (Option<ImuSegments>, Vec<OdoSegments>)
    where
        I: IncrementSource,
        F: Fn(usize, usize) -> I + Sync,
    {
        let count = plan.count();
        let parts = parts.min(count).max(1);
        // Each stretch's first segment and the sample it starts at.
        let mut starts = vec![(0, 0)];
        for (i, e) in plan.ends().enumerate() {
            if starts.len() == parts {
                break;
            }
            // The first end from this stretch's share on at a multiple of `align` (with
            // `align` 1, the share's own).
            if i + 1 >= count * starts.len() / parts && i + 1 < count && e.end % align == 0 {
                starts.push((i + 1, e.end));
            }
        }
        // Each stretch writes its segments in its own part of the run's.
        let mut out = WalkOutputs::zeroed(count, self.imu, odometers, self.columns);
        let mut rest = out.room();
        let mut stretches = Vec::with_capacity(starts.len());
        for (p, &(first, sample)) in starts.iter().enumerate() {
            let segments = starts.get(p + 1).map_or(count, |s| s.0) - first;
            let (room, after) = rest.split_at(segments);
            stretches.push((first, sample, segments, room));
            rest = after;
        }
        stretches
            .into_par_iter()
            .for_each(|(first, sample, segments, room)| {
                let mut odos: Vec<I> = (0..odometers).map(|v| odometer(v, sample)).collect();
                let ends = plan.ends().skip(first).take(segments);
                self.integrate(ends, sample, &mut odos, room);
            });
        out.over(plan)
    }

    /// The segments `ends`, the first starting at sample `start` (where `odometers`
    /// start), written in `room` in order (room for each of them).
    fn integrate<I: IncrementSource>(
        &self,
        ends: impl Iterator<Item = SegmentEnd>,
        mut start: usize,
        odometers: &mut [I],
        mut room: WalkRoom<'_>,
    ) {
        let Self {
            dt_s,
            dtheta_rad,
            n,
            imu,
            columns,
        } = *self;
        debug_assert_eq!(room.imu.is_some(), imu);
        debug_assert_eq!(room.odo.len(), odometers.len());
        let mut written = 0;
        let mut buffers: Vec<Vec<f64>> = vec![Vec::new(); odometers.len()];
        let mut group = Group::<WIDTH>::new(odometers.len());
        let mut ends = ends.peekable();
        while ends.peek().is_some() {
            let mut bounds = [(0, 0); WIDTH];
            let mut lanes = 0;
            for b in bounds.iter_mut() {
                let Some(e) = ends.next() else {
                    break;
                };
                let end = e.end.min(n);
                *b = (start.min(end), end);
                start = e.end;
                lanes += 1;
            }
            // Each odometer's increments over the group's samples, read in order.
            let (span_from, span_to) = (bounds[0].0, bounds[lanes - 1].1);
            for (buffer, odometer) in buffers.iter_mut().zip(odometers.iter_mut()) {
                buffer.clear();
                odometer.fill(buffer, span_to - span_from);
            }
            group.run(&GroupInputs {
                dt_s,
                dtheta_rad,
                bounds: &bounds,
                span: span_from,
                buffers: &buffers,
                moving: columns.moving,
            });
            for l in 0..lanes {
                if let Some(out) = room.imu.as_deref_mut() {
                    out[written] = group.imu_segment(l);
                }
                for (v, out) in room.odo.iter_mut().enumerate() {
                    group.set_odo(v, l, written, out);
                }
                written += 1;
            }
        }
    }
}

/// What a group of `W` segments is integrated from.
#[derive(Clone, Copy)]
struct GroupInputs<'a, const W: usize> {
    dt_s: &'a [f64],
    dtheta_rad: AngleSlice<'a>,
    /// Each lane's segment (sample range `from..to`; empty for lanes past the last).
    bounds: &'a [(usize, usize); W],
    /// The first sample `buffers` hold.
    span: usize,
    /// Each odometer's increments over the group's samples.
    buffers: &'a [Vec<f64>],
    /// Whether the moving time is integrated.
    moving: bool,
}

/// `W` segments' sums as they are integrated side by side (structure of arrays over the
/// lanes).
struct Group<const W: usize> {
    q: [[f64; W]; 4],
    m: [[f64; W]; 9],
    t: [f64; W],
    /// Per odometer: Σ d·mid (9), Σ d, Σ dt·mid over moving samples (9), Σ moving dt.
    s: Vec<[[f64; W]; 9]>,
    dist: Vec<[f64; W]>,
    s_mov: Vec<[[f64; W]; 9]>,
    t_mov: Vec<[f64; W]>,
    /// Per odometer: the current step's increments in each lane (scratch kept between
    /// groups: allocated per group, it made the walk's threads wait on the allocator's
    /// lock).
    step_d: Vec<[f64; W]>,
}

impl<const W: usize> Group<W> {
    fn new(odometers: usize) -> Self {
        Self {
            q: [[0.0; W]; 4],
            m: [[0.0; W]; 9],
            t: [0.0; W],
            s: vec![[[0.0; W]; 9]; odometers],
            dist: vec![[0.0; W]; odometers],
            s_mov: vec![[[0.0; W]; 9]; odometers],
            t_mov: vec![[0.0; W]; odometers],
            step_d: vec![[0.0; W]; odometers],
        }
    }

    /// Integrates the group's segments (`x.bounds`).
    #[inline(never)]
    fn run(&mut self, x: &GroupInputs<'_, W>) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            #[allow(unsafe_code)]
            // SAFETY: `run_avx2` only needs AVX2, and this CPU has it (checked above).
            return unsafe { self.run_avx2(x) };
        }
        self.run_portable(x)
    }

    /// [`Self::run_portable`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn run_avx2(&mut self, x: &GroupInputs<'_, W>) {
        self.run_portable(x)
    }

    #[inline(always)]
    fn run_portable(&mut self, x: &GroupInputs<'_, W>) {
        crate::with_angle_slice!(x.dtheta_rad, |dtheta_rad| self.run_on(x, dtheta_rad))
    }

    /// [`Self::run_portable`] with the angle increments in the form they are held.
    #[inline(always)]
    fn run_on<T: Increment3>(&mut self, x: &GroupInputs<'_, W>, dtheta_rad: &[T]) {
        let GroupInputs {
            dt_s,
            bounds,
            span,
            buffers,
            moving,
            ..
        } = *x;
        let odometers = buffers.len();
        let identity = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        self.q = [[1.0; W], [0.0; W], [0.0; W], [0.0; W]];
        self.m = [[0.0; W]; 9];
        self.t = [0.0; W];
        for v in 0..odometers {
            self.s[v] = [[0.0; W]; 9];
            self.dist[v] = [0.0; W];
            self.s_mov[v] = [[0.0; W]; 9];
            self.t_mov[v] = [0.0; W];
        }
        let mut r_prev: [[f64; W]; 9] = std::array::from_fn(|i| [identity[i]; W]);
        // The coning term reads the sample before each segment's first.
        let mut prev = [[0.0; W]; 3];
        let mut len = [0; W];
        for l in 0..W {
            let (from, to) = bounds[l];
            len[l] = to - from;
            if from > 0 && len[l] > 0 {
                let before = dtheta_rad[from - 1].rad();
                for i in 0..3 {
                    prev[i][l] = before[i];
                }
            }
        }
        let longest = len.iter().copied().max().unwrap_or(0);
        // Every lane of every odometer is written at each step before it is read.
        let d = &mut self.step_d;
        debug_assert_eq!(d.len(), odometers);
        for j in 0..longest {
            // This step's samples, zero past a lane's segment (no turn, no time, no
            // distance: its sums stay as they are).
            let mut th = [[0.0; W]; 3];
            let mut dt = [0.0; W];
            let mut active = [0.0; W];
            for l in 0..W {
                if j < len[l] {
                    let k = bounds[l].0 + j;
                    let sample = dtheta_rad[k].rad();
                    for i in 0..3 {
                        th[i][l] = sample[i];
                    }
                    dt[l] = dt_s[k];
                    active[l] = 1.0;
                    for (dv, buffer) in d.iter_mut().zip(buffers) {
                        dv[l] = buffer[k - span];
                    }
                } else {
                    for dv in d.iter_mut() {
                        dv[l] = 0.0;
                    }
                }
            }
            // The kernel's rotation vector with its coning term (at zero drift).
            let mut phi = [[0.0; W]; 3];
            for l in 0..W {
                let p = [prev[0][l], prev[1][l], prev[2][l]];
                let x = [th[0][l], th[1][l], th[2][l]];
                let coning = [
                    p[1] * x[2] - p[2] * x[1],
                    p[2] * x[0] - p[0] * x[2],
                    p[0] * x[1] - p[1] * x[0],
                ];
                for i in 0..3 {
                    phi[i][l] = x[i] + coning[i] * (1.0 / 12.0);
                    prev[i][l] = x[i];
                }
            }
            let e = turns(&phi);
            let mut mid = [[0.0; W]; 9];
            for l in 0..W {
                let q = qmul(
                    [self.q[0][l], self.q[1][l], self.q[2][l], self.q[3][l]],
                    [e[0][l], e[1][l], e[2][l], e[3][l]],
                );
                let r = dcm(q);
                for i in 0..4 {
                    self.q[i][l] = q[i];
                }
                for i in 0..9 {
                    self.m[i][l] += active[l] * r[i];
                    mid[i][l] = 0.5 * (r_prev[i][l] + r[i]);
                    r_prev[i][l] = r[i];
                }
                self.t[l] += dt[l];
            }
            // Lane by lane within each sum (the lanes side by side in vector registers).
            for (v, dv) in d.iter().enumerate() {
                accumulate(&mut self.s[v], dv, &mid);
                for l in 0..W {
                    self.dist[v][l] += dv[l];
                }
                if moving {
                    let mv: [f64; W] =
                        std::array::from_fn(|l| if dv[l] != 0.0 { dt[l] } else { 0.0 });
                    accumulate(&mut self.s_mov[v], &mv, &mid);
                    for l in 0..W {
                        self.t_mov[v][l] += mv[l];
                    }
                }
            }
        }
    }

    /// Lane `l`'s IMU segment.
    fn imu_segment(&self, l: usize) -> ImuSegment {
        let q = [self.q[0][l], self.q[1][l], self.q[2][l], self.q[3][l]];
        let norm = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
        ImuSegment {
            q: q.map(|v| v / norm),
            m: std::array::from_fn(|i| self.m[i][l] as f32),
            t_s: self.t[l] as f32,
        }
    }

    /// Writes lane `l`'s sums of odometer `v` as segment `i` of `out`.
    fn set_odo(&self, v: usize, l: usize, i: usize, out: &mut OdoSegmentsRoom<'_>) {
        let s: [f64; 9] = std::array::from_fn(|i| self.s[v][i][l]);
        out.distance.set(i, &s, self.dist[v][l]);
        if let Some(moving) = out.moving.as_mut() {
            let s: [f64; 9] = std::array::from_fn(|i| self.s_mov[v][i][l]);
            moving.set(i, &s, self.t_mov[v][l]);
        }
    }
}

/// `sums[i][l] += weight[l] · mid[i][l]` for the nine entries of each lane.
#[inline(always)]
fn accumulate<const W: usize>(sums: &mut [[f64; W]; 9], weight: &[f64; W], mid: &[[f64; W]; 9]) {
    for (sum, m) in sums.iter_mut().zip(mid) {
        let s = *sum;
        *sum = std::array::from_fn(|l| s[l] + weight[l] * m[l]);
    }
}

/// What identifies the series segments were integrated from: their addresses and
/// lengths (a memo is shared only by derives that share the series themselves).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct SeriesKey {
    dt: usize,
    dtheta: usize,
    len: usize,
}

/// The IMU's segments of some series, memoised.
type ImuEntry = Option<(SeriesKey, Arc<ImuSegments>)>;

/// A stored odometer's segments over some plan, memoised.
type OdoEntry = Option<(SeriesKey, SegmentPlan, Arc<OdoSegments>)>;

/// The segments a derive's passes read, integrated once and kept with it: the IMU's,
/// shared by the re-derives at other odometer timings (which share its IMU series), and
/// those of its own stored odometer. A memo, not part of the derive's value: two derives
/// compare equal whatever their memos hold. It also counts the passes over the run in
/// flight ([`LanesInFlight`]), shared with the re-derives like the IMU's segments.
#[derive(Debug, Default, Clone)]
pub struct SegmentMemo {
    imu: Arc<Mutex<ImuEntry>>,
    odo: Arc<Mutex<OdoEntry>>,
    lanes: Arc<LanesInFlight>,
}

impl PartialEq for SegmentMemo {
    fn eq(&self, _other: &Self) -> bool {
        true
    }
}

impl SegmentMemo {
    /// Lets the segments go (those shared with re-derives too): passes after this
    /// integrate them again.
    pub fn clear(&self) {
        *self.imu.lock().unwrap_or_else(|e| e.into_inner()) = None;
        *self.odo.lock().unwrap_or_else(|e| e.into_inner()) = None;
    }

    /// The memo of a re-derive at another odometer timing: the IMU's segments shared,
    /// the odometer's its own.
    pub fn for_other_odometer(&self) -> Self {
        Self {
            imu: Arc::clone(&self.imu),
            odo: Arc::default(),
            lanes: Arc::clone(&self.lanes),
        }
    }

    /// The passes over the run in flight, counted by every problem on it and its
    /// re-derives.
    pub fn lanes_in_flight(&self) -> &LanesInFlight {
        &self.lanes
    }

    /// The IMU's segments of `inputs` over `plan`, and those of its stored odometer with
    /// (at least) `columns` when `stored_odometer` is set: integrated on first use (in one
    /// walk for both), then kept; an odometer's kept with fewer columns is integrated again
    /// with theirs and these.
    pub fn segments(
        &self,
        inputs: &super::NavInputs<'_>,
        plan: &SegmentPlan,
        stored_odometer: bool,
        columns: OdoColumns,
    ) -> (Arc<ImuSegments>, Option<Arc<OdoSegments>>) {
        let imu_key = SeriesKey {
            dt: inputs.dt_s.as_ptr() as usize,
            dtheta: inputs.dtheta_rad.addr(),
            len: inputs.dt_s.len().min(inputs.dtheta_rad.len()),
        };
        let odo_key = SeriesKey {
            dt: inputs.odo_dist_m.as_ptr() as usize,
            dtheta: 0,
            len: inputs.odo_dist_m.len(),
        };
        // The IMU's lock is held while its segments are integrated (a second caller
        // waits for them rather than integrating them again), and always taken before
        // the odometer's; it is let go while a stored odometer alone is integrated (the
        // IMU's segments are shared with the re-derives, whose passes go on meanwhile).
        let mut imu_memo = Some(self.imu.lock().unwrap_or_else(|e| e.into_inner()));
        let imu_cached = imu_memo
            .as_ref()
            .and_then(|m| m.as_ref())
            .filter(|(key, segs)| *key == imu_key && segs.plan == *plan)
            .map(|(_, segs)| Arc::clone(segs));
        if imu_cached.is_some() {
            imu_memo = None;
        }
        let mut odo_memo = self.odo.lock().unwrap_or_else(|e| e.into_inner());
        let odo_same = odo_memo
            .as_ref()
            .filter(|(key, p, _)| *key == odo_key && p == plan);
        let odo_cached = odo_same
            .filter(|(_, _, segs)| segs.columns.cover(&columns))
            .map(|(_, _, segs)| Arc::clone(segs));
        // Integrated again, the odometer keeps the columns it had.
        let columns = odo_same.map_or(columns, |(_, _, segs)| segs.columns.union(&columns));
        let need_odo = stored_odometer && odo_cached.is_none();
        let odometers = usize::from(need_odo);
        let odometer = |_: usize, k: usize| {
            let d = inputs.odo_dist_m;
            d[k.min(d.len())..].iter().copied()
        };
        let (imu, mut odo) = match imu_cached {
            Some(imu) if !need_odo => return (imu, odo_cached.filter(|_| stored_odometer)),
            Some(imu) => {
                let (_, odo) = integrate_split(
                    inputs.dt_s,
                    inputs.dtheta_rad,
                    plan,
                    false,
                    odometers,
                    odometer,
                    columns,
                );
                (imu, odo)
            }
            None => {
                let (imu, odo) = integrate_split(
                    inputs.dt_s,
                    inputs.dtheta_rad,
                    plan,
                    true,
                    odometers,
                    odometer,
                    columns,
                );
                let imu = Arc::new(imu.expect("the IMU's segments integrated"));
                if let Some(memo) = imu_memo.as_mut() {
                    **memo = Some((imu_key, Arc::clone(&imu)));
                }
                (imu, odo)
            }
        };
        let odo = if need_odo {
            let fresh = Arc::new(odo.pop().expect("one odometer integrated"));
            *odo_memo = Some((odo_key, plan.clone(), Arc::clone(&fresh)));
            Some(fresh)
        } else {
            odo_cached.filter(|_| stored_odometer)
        };
        (imu, odo)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: OdoColumns = OdoColumns {
        yaw: true,
        pitch: true,
        moving: true,
    };

    /// The segments one at a time, sample by sample: what the lanes must give (every
    /// column of the odometer's sums, and of its moving time's).
    fn integrate_one_by_one(
        dt_s: &[f64],
        dtheta_rad: &[[f64; 3]],
        plan: &SegmentPlan,
        odometer: &[f64],
    ) -> (Vec<ImuSegment>, OdoSums, OdoSums) {
        let mut imu = Vec::new();
        let (mut odo, mut mov) = (Vec::new(), Vec::new());
        let mut prev = [0.0; 3];
        let mut k = 0;
        for end in plan.ends() {
            let mut q = [1.0, 0.0, 0.0, 0.0];
            let mut r_prev = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
            let (mut m, mut t) = ([0.0; 9], 0.0);
            let (mut s, mut dist, mut s_mov, mut t_mov) = ([0.0; 9], 0.0, [0.0; 9], 0.0);
            while k < end.end {
                let th = dtheta_rad[k];
                let coning = [
                    prev[1] * th[2] - prev[2] * th[1],
                    prev[2] * th[0] - prev[0] * th[2],
                    prev[0] * th[1] - prev[1] * th[0],
                ];
                let phi: [f64; 3] = std::array::from_fn(|i| th[i] + coning[i] * (1.0 / 12.0));
                prev = th;
                let a2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2];
                let (sn, c) = if a2 < HALF_ANGLE_SERIES_LIMIT_RAD2 {
                    half_angle_series(a2)
                } else {
                    half_angle_exact(a2)
                };
                q = qmul(q, [c, sn * phi[0], sn * phi[1], sn * phi[2]]);
                let r = dcm(q);
                let d = odometer[k];
                for i in 0..9 {
                    m[i] += r[i];
                    let mid = 0.5 * (r_prev[i] + r[i]);
                    s[i] += d * mid;
                    if d != 0.0 {
                        s_mov[i] += dt_s[k] * mid;
                    }
                }
                t += dt_s[k];
                dist += d;
                if d != 0.0 {
                    t_mov += dt_s[k];
                }
                r_prev = r;
                k += 1;
            }
            let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
            imu.push(ImuSegment {
                q: q.map(|v| v / norm),
                m: m.map(|v| v as f32),
                t_s: t as f32,
            });
            odo.push((s, dist));
            mov.push((s_mov, t_mov));
        }
        let sums = |rows: Vec<([f64; 9], f64)>| {
            let mut sums = OdoSums::zeroed(rows.len(), &ALL);
            let mut room = sums.room();
            for (i, (s, sum)) in rows.iter().enumerate() {
                room.set(i, s, *sum);
            }
            sums
        };
        (imu, sums(odo), sums(mov))
    }

    /// A run split into stretches integrated on their own (each odometer read from the
    /// stretch's first sample) gives the whole walk's segments, bit for bit: stretches
    /// starting at a cut, inside a stop, with every column, and more stretches than the
    /// pool has threads; the IMU's segments alone, and odometers alone.
    /// Angle increments held in f32 give the segments the same values in f64 give, bit
    /// for bit, in one walk or in stretches.
    #[test]
    fn segments_of_increments_held_in_f32_are_the_f64s() {
        let n = 40_000;
        let dt = vec![0.01; n];
        let exact: Vec<[f64; 3]> = crate::strapdown::test_drive::turning_dtheta(n)
            .iter()
            .map(|v| v.map(|x| f64::from(x as f32)))
            .collect();
        let held = crate::angle_increments::AngleIncrements::compact(exact.clone());
        assert!(held.is_single());
        let odo: Vec<f64> = (0..n).map(|k| if k % 5 == 0 { 0.0 } else { 0.1 }).collect();
        let from = |_: usize, k: usize| odo[k..].iter().copied();
        let plan = SegmentPlan::new(n, 10, [12_345]);
        for parts in [1, 4] {
            let walk = |dtheta_rad| {
                let part = Part::new(&dt, dtheta_rad, &plan, true, ALL);
                part.in_stretches(&plan, 1, from, parts, 1)
            };
            assert!(
                walk(held.view()) == walk((&exact).into()),
                "{parts} stretches"
            );
        }
    }

    #[test]
    fn stretches_of_a_run_are_the_whole_walk_bit_for_bit() {
        let n = 20_011;
        let dt: Vec<f64> = (0..n).map(|k| 0.01 + 1e-5 * (k % 7) as f64).collect();
        let dth: Vec<[f64; 3]> = super::super::test_drive::turning_dtheta(n);
        let odo = |scale: f64| -> Vec<f64> {
            (0..n)
                .map(|k| {
                    if (6000..7300).contains(&k) {
                        0.0
                    } else {
                        scale * (0.2 + 0.01 * (k % 3) as f64)
                    }
                })
                .collect()
        };
        let (a, b) = (odo(1.0), odo(1.3));
        let plan = SegmentPlan::new(n, 10, [5_003, 6_668, 13_337, 19_999]);
        let whole = integrate(
            &dt,
            (&dth).into(),
            &plan,
            true,
            &mut [a.iter().copied(), b.iter().copied()],
            ALL,
        );
        let from = |v: usize, k: usize| {
            let d = if v == 0 { &a } else { &b };
            d[k.min(n)..].iter().copied()
        };
        let in_parts = |imu: bool, odometers: usize, columns: OdoColumns, parts: usize| {
            Part::new(&dt, (&dth).into(), &plan, imu, columns)
                .in_stretches(&plan, odometers, from, parts, 1)
        };
        for parts in [1, 2, 3, 7] {
            let split = in_parts(true, 2, ALL, parts);
            assert!(split == whole, "{parts} stretches");
            // Stretches starting at multiples of 50 samples only (the plan's ends around
            // its control points are not), and of a length no end is a multiple of.
            for align in [50, 7_000_000] {
                let starts = std::sync::Mutex::new(Vec::new());
                let aligned = Part::new(&dt, (&dth).into(), &plan, true, ALL).in_stretches(
                    &plan,
                    2,
                    |v, k| {
                        starts.lock().unwrap().push(k);
                        from(v, k)
                    },
                    parts,
                    align,
                );
                assert!(
                    aligned == whole,
                    "{parts} stretches at multiples of {align}"
                );
                let starts = starts.into_inner().unwrap();
                assert!(starts.iter().all(|&k| k % align == 0), "{starts:?}");
                if align == 50 {
                    assert_eq!(starts.len(), 2 * parts, "{starts:?}");
                }
            }
            let (imu, none) = in_parts(true, 0, ALL, parts);
            assert!(imu == whole.0 && none.is_empty(), "{parts} stretches, IMU");
            let (no_imu, odos) = in_parts(false, 2, OdoColumns::default(), parts);
            let plain = integrate(
                &dt,
                (&dth).into(),
                &plan,
                false,
                &mut [a.iter().copied(), b.iter().copied()],
                OdoColumns::default(),
            );
            assert!(
                no_imu.is_none() && odos == plain.1,
                "{parts} stretches, plain"
            );
        }
        // A column integrated beside others holds the sums it holds alone (what the joint
        // fit's segments with the yaw column rely on), and none it was not asked for.
        let with = |columns: OdoColumns| {
            let (_, odos) = in_parts(false, 1, columns, 2);
            odos.into_iter().next().expect("one odometer")
        };
        let (plain, yaw) = (
            with(OdoColumns::default()),
            with(OdoColumns {
                yaw: true,
                ..OdoColumns::default()
            }),
        );
        let all = with(ALL);
        assert_eq!(yaw.distance.x, plain.distance.x);
        assert_eq!(yaw.distance.y, all.distance.y);
        assert!(plain.distance.y.is_empty() && yaw.distance.z.is_empty());
        assert!(yaw.moving.is_none() && all.moving.is_some());
        assert_eq!(yaw.distance.y.len(), plan.count());
        assert_eq!(whole.0.expect("IMU").segments.len(), plan.count());
        // The public entry splits by the pool's threads beyond its size, the same.
        let long = SegmentPlan::new(n, 2, []);
        assert!(long.count() >= SPLIT_SEGMENTS);
        let whole = integrate(
            &dt,
            (&dth).into(),
            &long,
            true,
            &mut [a.iter().copied()],
            ALL,
        );
        assert!(integrate_split(&dt, (&dth).into(), &long, true, 1, from, ALL) == whole);
    }

    /// A walk split between threads holds the run's segments once at its peak (what it
    /// returns, and each stretch's scratch), not each stretch's segments besides, and gives
    /// the whole walk's, bit for bit.
    #[test]
    fn a_split_walk_holds_the_runs_segments_once() {
        let n = 40_000;
        let dt: Vec<f64> = (0..n).map(|k| 0.01 + 1e-5 * (k % 7) as f64).collect();
        let dth: Vec<[f64; 3]> = super::super::test_drive::turning_dtheta(n);
        let odo: Vec<f64> = (0..n).map(|k| 0.2 + 0.01 * (k % 3) as f64).collect();
        let from = |v: usize, k: usize| odo[k.min(n)..].iter().map(move |d| d * (1 + v) as f64);
        // Segments of a sample: four stretches of 10 000.
        let plan = SegmentPlan::new(n, 1, []);
        assert!(plan.count() >= 4 * SPLIT_SEGMENTS);
        let ((imu, odos), peak) = crate::counted_heap::peak_heap_bytes(4, || {
            integrate_split(&dt, (&dth).into(), &plan, true, 2, from, ALL)
        });
        let sums = |s: &OdoSums| {
            s.x.capacity() * size_of::<[f32; 4]>()
                + (s.y.capacity() + s.z.capacity()) * size_of::<[f32; 3]>()
        };
        let imu = imu.expect("the IMU's segments");
        let held = imu.segments.capacity() * size_of::<ImuSegment>()
            + odos
                .iter()
                .map(|o| sums(&o.distance) + o.moving.as_ref().map_or(0, sums))
                .sum::<usize>();
        assert_eq!(held, plan.count() * (72 + 2 * 2 * 40));
        // Within 64 KiB below (rayon's own blocks, taken before the count and let go
        // during it, are counted off it) and 5 % above (each stretch's scratch); stretches
        // of their own joined at the end held 1.75 times as much.
        assert!(
            peak + (64 << 10) >= held && peak < held + held / 20,
            "{peak} B, {held} B held"
        );
        let whole = integrate(
            &dt,
            (&dth).into(),
            &plan,
            true,
            &mut [from(0, 0), from(1, 0)],
            ALL,
        );
        assert!(whole == (Some(imu), odos));
    }

    #[test]
    fn segments_side_by_side_are_each_segment_alone_bit_for_bit() {
        // A turning, bumping drive with a violent sample (beyond the series), stops, and
        // segments cut short.
        let n = 5003;
        let dt: Vec<f64> = (0..n).map(|k| 0.01 + 1e-5 * (k % 7) as f64).collect();
        let dth: Vec<[f64; 3]> = super::super::test_drive::turning_dtheta(n);
        let odo: Vec<f64> = (0..n)
            .map(|k| {
                if (1000..1800).contains(&k) {
                    0.0
                } else {
                    0.2 + 0.01 * (k % 3) as f64
                }
            })
            .collect();
        let plan = SegmentPlan::new(n, 10, [3, 57, 58, 999, 2500, 4321, 5002]);
        let doubled: Vec<f64> = odo.iter().map(|d| 2.0 * d).collect();
        let (imu, odos) = integrate(
            &dt,
            (&dth).into(),
            &plan,
            true,
            &mut [odo.iter().copied(), doubled.iter().copied()],
            ALL,
        );
        let (want_imu, want_odo, want_mov) = integrate_one_by_one(&dt, &dth, &plan, &odo);
        assert_eq!(imu.unwrap().segments, want_imu);
        assert_eq!(odos[0].distance, want_odo);
        assert_eq!(odos[0].moving.as_ref().unwrap(), &want_mov);
        let (_, want_doubled, _) = integrate_one_by_one(&dt, &dth, &plan, &doubled);
        assert_eq!(odos[1].distance, want_doubled);
        // Without the columns no pass reads: the first column alone, the same.
        let (_, plain) = integrate(
            &dt,
            (&dth).into(),
            &plan,
            false,
            &mut [odo.iter().copied()],
            OdoColumns::default(),
        );
        assert_eq!(plain[0].distance.x, want_odo.x);
        assert!(plain[0].distance.y.is_empty() && plain[0].distance.z.is_empty());
        assert!(plain[0].moving.is_none());
    }

    #[test]
    fn segments_are_blocks_cut_after_the_samples_asked() {
        let plan = SegmentPlan::new(25, 10, [9, 3, 3, 14, 40, 24]);
        // A block's last sample and the run's are ends already.
        assert_eq!(plan.cuts, vec![3, 14]);
        let ends: Vec<(usize, bool)> = plan.ends().map(|e| (e.end, e.closes_block)).collect();
        assert_eq!(
            ends,
            vec![(4, false), (10, true), (15, false), (20, true), (25, true)]
        );
        assert_eq!(plan.count(), ends.len());
        for k in [3, 9, 14, 19, 24] {
            assert!(plan.ends_after(k), "{k}");
        }
        for k in [0, 4, 10, 25] {
            assert!(!plan.ends_after(k), "{k}");
        }
        assert_eq!(SegmentPlan::new(0, 10, [0]).ends().count(), 0);
    }

    #[test]
    fn a_segment_holds_its_samples_turns_and_distances() {
        // Ten samples turning about z at 0.01 rad each, 0.5 m each.
        let dt = vec![0.01; 10];
        let dth = vec![[0.0, 0.0, 0.01]; 10];
        let plan = SegmentPlan::new(10, 10, []);
        let (imu, odo) = integrate(
            &dt,
            (&dth).into(),
            &plan,
            true,
            &mut [std::iter::repeat_n(0.5, 10)],
            ALL,
        );
        let imu = imu.unwrap();
        let seg = imu.segments[0];
        // A turn of 0.1 rad about z (no coning about one axis).
        assert!((seg.q[0] - 0.05f64.cos()).abs() < 1e-15);
        assert!((seg.q[3] - 0.05f64.sin()).abs() < 1e-15);
        assert!((seg.t_s - 0.1).abs() < 1e-7);
        // Σ cos(0.01 k) on the diagonal's first entry.
        let sum_cos: f64 = (1..=10).map(|k| (0.01 * k as f64).cos()).sum();
        assert!((seg.m[0] as f64 - sum_cos).abs() < 1e-5);
        assert!((seg.m[8] - 10.0).abs() < 1e-6);
        // The distance resolved at each interval's middle: x forward by Σ 0.5 cos.
        let x = odo[0].distance.x[0];
        assert!((x[3] - 5.0).abs() < 1e-6);
        let want_x: f64 = (1..=10)
            .map(|k| 0.25 * ((0.01 * (k - 1) as f64).cos() + (0.01 * k as f64).cos()))
            .sum();
        assert!((x[0] as f64 - want_x).abs() < 1e-5);
        let mov = odo[0].moving.as_ref().unwrap().x[0];
        assert!((mov[3] - 0.1).abs() < 1e-7);
    }
}
