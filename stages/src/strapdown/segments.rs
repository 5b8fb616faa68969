//! The IMU's and the odometer's increments integrated once over short stretches of a run
//! (segments), so that the many passes an optimiser runs step once per segment instead
//! of once per sample ([`super::run_criteria_segments`]).
//!
//! A segment is a block of F (`block` samples: 0.1 s at 100 Hz), cut after each sample
//! a pass reports (a control point's stop). With `R_k` the body's turn from the
//! segment's start to the end of its `k`-th sample (`R_0 = I`: the product of the
//! kernel's rotation vectors, coning term included, at zero drift), a segment keeps
//! - `q`: `R_K`, the body's turn over the whole segment, as a quaternion;
//! - `m`: `Σ_k R_k`: the sum over the segment's samples of `C_b^n`'s third row (what
//!   Kryt1 reads per block) is the third row of `C_b^n` at the segment's start times it;
//! - `t_s`: its length;
//!
//! and, of an odometer with increments `d_k`,
//! - `s`: `Σ_k d_k (R_{k−1} + R_k)/2`: the increments in the start's body axes, each
//!   resolved with the attitude at the middle of its interval as the kernel resolves it;
//!   the route moves by `C_b^n · s · (the odometer's direction in the body)`;
//! - `dist_m`: `Σ_k d_k`;
//! - for an odometer speed bias, the same with `dt_k` for `d_k` over the samples in
//!   which the odometer moved (`mov`).
//!
//! None of these depends on a pass's settings (azimuth, drifts, odometer scale, bias and
//! boresights), which act on them as `block_lanes` says. `m` and `s` are kept in f32:
//! their rounding (6e-8 of a block's sums) moves a block's attitude by under 1e-7 rad and
//! the route by under a micrometre a segment, far below what the criteria resolve.

// Lane loops index several arrays by the lane: an index is clearer than zipped iterators.
#![allow(clippy::needless_range_loop)]

use std::sync::{Arc, Mutex};

use crate::attitude::{HALF_ANGLE_SERIES_LIMIT_RAD2, half_angle_exact, half_angle_series};

/// Where a run's segments end: blocks of `block` samples, cut after each reported sample.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SegmentPlan {
    /// Samples the segments cover.
    pub samples: usize,
    /// Samples per block of F (at least one).
    pub block: usize,
    /// The samples after which a pass reports its state (increasing, each below
    /// `samples`).
    pub reports: Vec<usize>,
}

/// The end of one segment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SegmentEnd {
    /// The sample after the segment's last (exclusive end).
    pub end: usize,
    /// Whether it closes a block of F.
    pub closes_block: bool,
    /// Whether the pass reports its state there (after sample `end − 1`).
    pub report: bool,
}

impl SegmentPlan {
    /// Segments over `samples` samples in blocks of `block`, cut after each of `reports`
    /// (any order; repeats and samples past the end are left out).
    pub fn new(samples: usize, block: usize, reports: impl IntoIterator<Item = usize>) -> Self {
        let mut reports: Vec<usize> = reports.into_iter().filter(|&k| k < samples).collect();
        reports.sort_unstable();
        reports.dedup();
        Self {
            samples,
            block: block.max(1),
            reports,
        }
    }

    /// The segments' ends, in order.
    pub fn ends(&self) -> Vec<SegmentEnd> {
        let n = self.samples;
        let mut out = Vec::with_capacity(n.div_ceil(self.block) + self.reports.len());
        let mut block_end = self.block.min(n);
        let mut reports = self.reports.iter().map(|k| k + 1).peekable();
        let mut at = 0;
        while at < n {
            let report_end = reports.peek().copied().unwrap_or(usize::MAX);
            let end = block_end.min(report_end);
            let closes_block = end == block_end;
            let report = end == report_end;
            if report {
                reports.next();
            }
            if closes_block {
                block_end = (block_end + self.block).min(n);
            }
            out.push(SegmentEnd {
                end,
                closes_block,
                report,
            });
            at = end;
        }
        out
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

/// One segment of an odometer's increments.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdoSegment {
    /// `Σ_k d_k (R_{k−1} + R_k)/2`, row-major, m (or s, for the moving time).
    pub s: [f32; 9],
    /// `Σ_k d_k`, m (or s).
    pub dist: f32,
}

/// A run's IMU increments over its segments.
#[derive(Debug, Clone, PartialEq)]
pub struct ImuSegments {
    /// The plan they follow.
    pub plan: SegmentPlan,
    /// Each segment's end.
    pub ends: Vec<SegmentEnd>,
    /// Each segment.
    pub segments: Vec<ImuSegment>,
}

/// An odometer's increments over a run's segments.
#[derive(Debug, Clone, PartialEq)]
pub struct OdoSegments {
    /// Each segment's distances.
    pub segments: Vec<OdoSegment>,
    /// Each segment's moving time, when integrated (for an odometer speed bias).
    pub moving: Option<Vec<OdoSegment>>,
}

impl OdoSegments {
    /// Whether the moving time was integrated.
    pub fn has_moving(&self) -> bool {
        self.moving.is_some()
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
/// `plan.samples` of them; missing ones count as 0), with its moving time when
/// `moving` is set: one walk over the samples for all of them.
///
/// [`WIDTH`] consecutive segments are integrated side by side in vector lanes (each
/// segment's products are a chain of dependent operations; four chains keep the CPU's
/// units busy), each lane exactly as a segment alone would be.
pub fn integrate<I: Iterator<Item = f64>>(
    dt_s: &[f64],
    dtheta_rad: &[[f64; 3]],
    plan: &SegmentPlan,
    imu: bool,
    odometers: &mut [I],
    moving: bool,
) -> (Option<ImuSegments>, Vec<OdoSegments>) {
    let ends = plan.ends();
    let count = ends.len();
    let n = plan.samples.min(dt_s.len()).min(dtheta_rad.len());
    let mut imu_out = imu.then(|| Vec::with_capacity(count));
    let mut odo_out: Vec<OdoSegments> = odometers
        .iter()
        .map(|_| OdoSegments {
            segments: Vec::with_capacity(count),
            moving: moving.then(|| Vec::with_capacity(count)),
        })
        .collect();
    let mut buffers: Vec<Vec<f64>> = vec![Vec::new(); odometers.len()];
    let mut group = Group::<WIDTH>::new(odometers.len());
    let mut start = 0;
    for first in (0..count).step_by(WIDTH) {
        let lanes = WIDTH.min(count - first);
        let mut bounds = [(0, 0); WIDTH];
        for (l, b) in bounds.iter_mut().enumerate().take(lanes) {
            let end = ends[first + l].end.min(n);
            *b = (start.min(end), end);
            start = ends[first + l].end;
        }
        // Each odometer's increments over the group's samples, read in order.
        let (span_from, span_to) = (bounds[0].0, bounds[lanes - 1].1);
        for (buffer, odometer) in buffers.iter_mut().zip(odometers.iter_mut()) {
            buffer.clear();
            buffer.extend((span_from..span_to).map(|_| odometer.next().unwrap_or(0.0)));
        }
        group.run(&GroupInputs {
            dt_s,
            dtheta_rad,
            bounds: &bounds,
            span: span_from,
            buffers: &buffers,
            moving,
        });
        for l in 0..lanes {
            if let Some(out) = imu_out.as_mut() {
                out.push(group.imu_segment(l));
            }
            for (v, out) in odo_out.iter_mut().enumerate() {
                let (segment, mov) = group.odo_segments(v, l);
                out.segments.push(segment);
                if let Some(m) = out.moving.as_mut() {
                    m.push(mov);
                }
            }
        }
    }
    let imu = imu_out.map(|segments| ImuSegments {
        plan: plan.clone(),
        ends,
        segments,
    });
    (imu, odo_out)
}

/// What a group of `W` segments is integrated from.
#[derive(Clone, Copy)]
struct GroupInputs<'a, const W: usize> {
    dt_s: &'a [f64],
    dtheta_rad: &'a [[f64; 3]],
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
        let GroupInputs {
            dt_s,
            dtheta_rad,
            bounds,
            span,
            buffers,
            moving,
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
                for i in 0..3 {
                    prev[i][l] = dtheta_rad[from - 1][i];
                }
            }
        }
        let longest = len.iter().copied().max().unwrap_or(0);
        let mut d = vec![[0.0; W]; odometers];
        for j in 0..longest {
            // This step's samples, zero past a lane's segment (no turn, no time, no
            // distance: its sums stay as they are).
            let mut th = [[0.0; W]; 3];
            let mut dt = [0.0; W];
            let mut active = [0.0; W];
            for l in 0..W {
                if j < len[l] {
                    let k = bounds[l].0 + j;
                    for i in 0..3 {
                        th[i][l] = dtheta_rad[k][i];
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
            for v in 0..odometers {
                for l in 0..W {
                    let dv = d[v][l];
                    for i in 0..9 {
                        self.s[v][i][l] += dv * mid[i][l];
                    }
                    self.dist[v][l] += dv;
                    if moving {
                        let mv = if dv != 0.0 { dt[l] } else { 0.0 };
                        for i in 0..9 {
                            self.s_mov[v][i][l] += mv * mid[i][l];
                        }
                        self.t_mov[v][l] += mv;
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

    /// Lane `l`'s segment of odometer `v`, and of its moving time.
    fn odo_segments(&self, v: usize, l: usize) -> (OdoSegment, OdoSegment) {
        (
            OdoSegment {
                s: std::array::from_fn(|i| self.s[v][i][l] as f32),
                dist: self.dist[v][l] as f32,
            },
            OdoSegment {
                s: std::array::from_fn(|i| self.s_mov[v][i][l] as f32),
                dist: self.t_mov[v][l] as f32,
            },
        )
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
/// compare equal whatever their memos hold.
#[derive(Debug, Default, Clone)]
pub struct SegmentMemo {
    imu: Arc<Mutex<ImuEntry>>,
    odo: Arc<Mutex<OdoEntry>>,
}

impl PartialEq for SegmentMemo {
    fn eq(&self, _other: &Self) -> bool {
        true
    }
}

impl SegmentMemo {
    /// The memo of a re-derive at another odometer timing: the IMU's segments shared,
    /// the odometer's its own.
    pub fn for_other_odometer(&self) -> Self {
        Self {
            imu: Arc::clone(&self.imu),
            odo: Arc::default(),
        }
    }

    /// The IMU's segments of `inputs` over `plan`, and those of its stored odometer when
    /// `stored_odometer` is set (with the moving time when `moving` is): integrated on
    /// first use (in one walk for both), then kept.
    pub fn segments(
        &self,
        inputs: &super::NavInputs<'_>,
        plan: &SegmentPlan,
        stored_odometer: bool,
        moving: bool,
    ) -> (Arc<ImuSegments>, Option<Arc<OdoSegments>>) {
        let imu_key = SeriesKey {
            dt: inputs.dt_s.as_ptr() as usize,
            dtheta: inputs.dtheta_rad.as_ptr() as usize,
            len: inputs.dt_s.len().min(inputs.dtheta_rad.len()),
        };
        let odo_key = SeriesKey {
            dt: inputs.odo_dist_m.as_ptr() as usize,
            dtheta: 0,
            len: inputs.odo_dist_m.len(),
        };
        // Both held while integrating: a second caller waits for the first's segments
        // instead of integrating them again.
        let mut imu_memo = self.imu.lock().unwrap_or_else(|e| e.into_inner());
        let mut odo_memo = self.odo.lock().unwrap_or_else(|e| e.into_inner());
        let imu_cached = imu_memo
            .as_ref()
            .filter(|(key, segs)| *key == imu_key && segs.plan == *plan)
            .map(|(_, segs)| Arc::clone(segs));
        let odo_cached = odo_memo
            .as_ref()
            .filter(|(key, p, segs)| *key == odo_key && p == plan && (segs.has_moving() || !moving))
            .map(|(_, _, segs)| Arc::clone(segs));
        let need_odo = stored_odometer && odo_cached.is_none();
        let mut odometers: Vec<_> = if need_odo {
            vec![inputs.odo_dist_m.iter().copied()]
        } else {
            Vec::new()
        };
        let imu = match imu_cached {
            Some(cached) if !need_odo => {
                return (cached, odo_cached.filter(|_| stored_odometer));
            }
            Some(cached) => {
                let (_, mut odo) = integrate(
                    inputs.dt_s,
                    inputs.dtheta_rad,
                    plan,
                    false,
                    &mut odometers,
                    moving,
                );
                let fresh = Arc::new(odo.pop().expect("one odometer integrated"));
                *odo_memo = Some((odo_key, plan.clone(), Arc::clone(&fresh)));
                return (cached, Some(fresh));
            }
            None => {
                let (imu, mut odo) = integrate(
                    inputs.dt_s,
                    inputs.dtheta_rad,
                    plan,
                    true,
                    &mut odometers,
                    moving,
                );
                if need_odo {
                    let fresh = Arc::new(odo.pop().expect("one odometer integrated"));
                    *odo_memo = Some((odo_key, plan.clone(), Arc::clone(&fresh)));
                }
                let fresh = Arc::new(imu.expect("the IMU's segments integrated"));
                *imu_memo = Some((imu_key, Arc::clone(&fresh)));
                fresh
            }
        };
        let odo = if stored_odometer {
            odo_memo.as_ref().map(|(_, _, segs)| Arc::clone(segs))
        } else {
            None
        };
        (imu, odo)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The segments one at a time, sample by sample: what the lanes must give.
    fn integrate_one_by_one(
        dt_s: &[f64],
        dtheta_rad: &[[f64; 3]],
        plan: &SegmentPlan,
        odometer: &[f64],
    ) -> (Vec<ImuSegment>, Vec<OdoSegment>, Vec<OdoSegment>) {
        let (mut imu, mut odo, mut mov) = (Vec::new(), Vec::new(), Vec::new());
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
            odo.push(OdoSegment {
                s: s.map(|v| v as f32),
                dist: dist as f32,
            });
            mov.push(OdoSegment {
                s: s_mov.map(|v| v as f32),
                dist: t_mov as f32,
            });
        }
        (imu, odo, mov)
    }

    #[test]
    fn segments_side_by_side_are_each_segment_alone_bit_for_bit() {
        // A turning, bumping drive with a violent sample (beyond the series), stops, and
        // segments cut short by reports.
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
            &dth,
            &plan,
            true,
            &mut [odo.iter().copied(), doubled.iter().copied()],
            true,
        );
        let (want_imu, want_odo, want_mov) = integrate_one_by_one(&dt, &dth, &plan, &odo);
        assert_eq!(imu.unwrap().segments, want_imu);
        assert_eq!(odos[0].segments, want_odo);
        assert_eq!(odos[0].moving.as_ref().unwrap(), &want_mov);
        let (_, want_doubled, _) = integrate_one_by_one(&dt, &dth, &plan, &doubled);
        assert_eq!(odos[1].segments, want_doubled);
    }

    #[test]
    fn segments_are_blocks_cut_after_the_reported_samples() {
        let plan = SegmentPlan::new(25, 10, [9, 3, 3, 14, 40, 24]);
        assert_eq!(plan.reports, vec![3, 9, 14, 24]);
        let ends: Vec<(usize, bool, bool)> = plan
            .ends()
            .iter()
            .map(|e| (e.end, e.closes_block, e.report))
            .collect();
        assert_eq!(
            ends,
            vec![
                (4, false, true),
                (10, true, true),
                (15, false, true),
                (20, true, false),
                (25, true, true),
            ]
        );
        assert!(SegmentPlan::new(0, 10, [0]).ends().is_empty());
    }

    #[test]
    fn a_segment_holds_its_samples_turns_and_distances() {
        // Ten samples turning about z at 0.01 rad each, 0.5 m each.
        let dt = vec![0.01; 10];
        let dth = vec![[0.0, 0.0, 0.01]; 10];
        let plan = SegmentPlan::new(10, 10, []);
        let (imu, odo) = integrate(
            &dt,
            &dth,
            &plan,
            true,
            &mut [std::iter::repeat_n(0.5, 10)],
            true,
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
        let o = odo[0].segments[0];
        assert!((o.dist - 5.0).abs() < 1e-6);
        let want_x: f64 = (1..=10)
            .map(|k| 0.25 * ((0.01 * (k - 1) as f64).cos() + (0.01 * k as f64).cos()))
            .sum();
        assert!((o.s[0] as f64 - want_x).abs() < 1e-5);
        let mov = odo[0].moving.as_ref().unwrap()[0];
        assert!((mov.dist - 0.1).abs() < 1e-7);
    }
}
