//! The kernel over segments ([`super::segments`]): `N` passes side by side, each stepping
//! once per segment (0.1 s) instead of once per sample, with what the criteria read.
//!
//! Over a segment of length `T`, with the segment's body turn `q_seg`, sums `m` and
//! odometer sums `S`, `dist` (and `S_mov`, `t_mov` for a speed bias), a pass with drift
//! `b`, odometer scale `κ`, bias `β`, yaw boresight `δ` and pitch boresight `ε`:
//! 1. turns the body by `E(−bT/2) ⊗ q_seg ⊗ E(−bT/2)`: the drift's rotation (some 1e-6
//!    rad a segment) split about the segment's turn, exact to second order in the
//!    segment's turn times the drift's;
//! 2. turns the navigation frame by half its rotation over the segment (Earth rate, and
//!    the previous segment's transport rate) before resolving the segment's distance,
//!    and the rest after, so that the distance is resolved in the frame of the
//!    segment's middle;
//! 3. moves by `C_b^n · (κ S + β S_mov) · (cos δ, sin δ, 0)`, its height also by
//!    `tan ε` times the third row of `C_b^n` times the sums' third column (the kernel's
//!    pitch boresight), on WGS-84 as the kernel does, and adds `κ dist + β t_mov` to the
//!    distance;
//! 4. adds the third row of `C_b^n` (at the segment's middle frame) times `m` to its
//!    block's sum of `C_b^n`'s third row, whose roll and pitch close the block
//!    ([`BlockAngles`]).
//!
//! Against the kernel sample by sample, the attitude at each segment's end is exact
//! (the body's and the navigation frame's turns are factors on either side of `C_b^n`)
//! but for the drift's second order; a block's sum of third rows differs by the
//! navigation frame's and the drift's turns within the segment (about 1e-6 rad); the
//! route by the second order of the navigation frame's turn over a segment. Measured on
//! a simulated 40-minute drive with every sensor error: stops within 3 mm, block
//! attitudes within 4e-7 rad (`stages/tests/navigation.rs`, which bounds them at 1 cm
//! and 1e-6 rad).

// Lane loops index several arrays by the lane: an index is clearer than zipped iterators.
#![allow(clippy::needless_range_loop)]

use super::lanes::LatTerms;
use super::segments::{ImuSegment, ImuSegments, OdoColumns, OdoSegments, OdoSums, qmul, turns};
use super::{CriteriaSink, NavSettings, dcm_rows};
use crate::criteria::FixPose;
use crate::earth::{A_M, E2, OMEGA_IE_RAD_S};

/// Latitude moves beyond which its sine and cosine are computed anew rather than turned
/// by the move (a segment moves some 3e-7 rad).
const LAT_TURN_LIMIT_RAD: f64 = 1e-3;

/// Each lane's latitude-dependent terms, brought to its latitude before every segment
/// by turning the latitude's sine and cosine by its move (a few multiplications where
/// the kernel's refresh every 6 m calls sin, cos and tan: most of a segment pass's
/// time, at ten times fewer steps).
#[derive(Clone, Copy)]
struct LatLanes<const N: usize> {
    /// The terms, and the latitude they are at.
    at: LatTerms<N>,
    sin: [f64; N],
    cos: [f64; N],
}

impl<const N: usize> LatLanes<N> {
    const ZERO: Self = Self {
        at: LatTerms::ZERO,
        sin: [0.0; N],
        cos: [0.0; N],
    };

    /// Lane `l` at `lat`, its sine and cosine computed.
    #[cold]
    #[inline(never)]
    fn set(&mut self, l: usize, lat: f64) {
        self.at.lat_rad[l] = lat;
        (self.sin[l], self.cos[l]) = lat.sin_cos();
        self.derive(l);
    }

    /// The terms of lane `l` from its sine and cosine.
    #[inline(always)]
    fn derive(&mut self, l: usize) {
        let (s, c) = (self.sin[l], self.cos[l]);
        let w = 1.0 - E2 * s * s;
        let rn = A_M / w.sqrt();
        let at = &mut self.at;
        at.rn_m[l] = rn;
        at.rm_m[l] = rn * (1.0 - E2) / w;
        at.inv_cos[l] = 1.0 / c;
        at.tan[l] = s * at.inv_cos[l];
        at.w_ie_north_rad_s[l] = OMEGA_IE_RAD_S * c;
        at.w_ie_down_rad_s[l] = -OMEGA_IE_RAD_S * s;
    }

    /// Every lane's terms at its latitude `lat`: each lane's sine and cosine turned by
    /// its move since they were (or computed anew past [`LAT_TURN_LIMIT_RAD`]), lane by
    /// lane, so that a lane's terms never depend on the lanes beside it.
    #[inline(always)]
    fn update(&mut self, lat: &[f64; N]) {
        let mut d = [0.0; N];
        let mut far = false;
        for l in 0..N {
            d[l] = lat[l] - self.at.lat_rad[l];
            far |= d[l].abs() > LAT_TURN_LIMIT_RAD;
        }
        for l in 0..N {
            let d2 = d[l] * d[l];
            let sin_d = d[l] * (1.0 - d2 * (1.0 / 6.0) * (1.0 - d2 * (1.0 / 20.0)));
            let cos_d = 1.0 - 0.5 * d2 * (1.0 - d2 * (1.0 / 12.0));
            let (s, c) = (self.sin[l], self.cos[l]);
            self.sin[l] = s * cos_d + c * sin_d;
            self.cos[l] = c * cos_d - s * sin_d;
            self.at.lat_rad[l] = lat[l];
            self.derive(l);
        }
        if far {
            for l in 0..N {
                if d[l].abs() > LAT_TURN_LIMIT_RAD {
                    self.set(l, lat[l]);
                }
            }
        }
    }
}

/// Segments between updates of the latitude's terms: every lane's on the same
/// schedule, whatever the lanes beside it (a segment moves some 3e-7 rad of latitude,
/// over which the terms change by under 1e-9).
const LAT_UPDATE_EVERY: usize = 2;

/// Segments between renormalisations of the attitude quaternion.
const RENORMALISE_EVERY: usize = 16;

/// The unit quaternion of the small turn whose half rotation vector is `v` (|v| ~ 1e-6):
/// (1 − |v|²/2, v), unit to |v|⁴.
#[inline(always)]
fn small_turn(v: [f64; 3]) -> [f64; 4] {
    [
        1.0 - 0.5 * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]),
        v[0],
        v[1],
        v[2],
    ]
}

/// State of `N` passes between segments.
struct SegmentLanes<const N: usize> {
    drift_rad_s: [[f64; N]; 3],
    odo_scale: [f64; N],
    odo_bias_mps: [f64; N],
    odo_sin: [f64; N],
    odo_cos: [f64; N],
    odo_tan_pitch: [f64; N],
    /// Attitude quaternion `C_b^n` (w, x, y, z).
    q: [[f64; N]; 4],
    lat_rad: [f64; N],
    lon_rad: [f64; N],
    h_m: [f64; N],
    distance_m: [f64; N],
    /// The navigation frame's transport turn over the previous segment, rad.
    rho_prev: [[f64; N]; 3],
    terms: LatLanes<N>,
    /// The current block's sum of `C_b^n`'s third row.
    acc: [[f64; N]; 3],
}

impl<const N: usize> SegmentLanes<N> {
    fn new(settings: &[NavSettings; N]) -> Self {
        let mut lanes = Self {
            drift_rad_s: [[0.0; N]; 3],
            odo_scale: [0.0; N],
            odo_bias_mps: [0.0; N],
            odo_sin: [0.0; N],
            odo_cos: [0.0; N],
            odo_tan_pitch: [0.0; N],
            q: [[0.0; N]; 4],
            lat_rad: [0.0; N],
            lon_rad: [0.0; N],
            h_m: [0.0; N],
            distance_m: [0.0; N],
            rho_prev: [[0.0; N]; 3],
            terms: LatLanes::ZERO,
            acc: [[0.0; N]; 3],
        };
        for (l, s) in settings.iter().enumerate() {
            for i in 0..3 {
                lanes.drift_rad_s[i][l] = s.drift_rad_s[i];
            }
            lanes.odo_scale[l] = s.odo_scale;
            lanes.odo_bias_mps[l] = s.odo_bias_mps;
            (lanes.odo_sin[l], lanes.odo_cos[l]) = s.odo_yaw_rad.sin_cos();
            lanes.odo_tan_pitch[l] = s.odo_pitch_rad.tan();
            let q = s.initial.to_quat_b_to_n().into_inner();
            for (i, v) in [q.w, q.i, q.j, q.k].into_iter().enumerate() {
                lanes.q[i][l] = v;
            }
            lanes.lat_rad[l] = s.lat0_rad;
            lanes.lon_rad[l] = s.lon0_rad;
            lanes.h_m[l] = s.h0_m;
            lanes.terms.set(l, s.lat0_rad);
        }
        lanes
    }

    /// Advances every lane over one segment, with its odometer sums `sums`; `BORESIGHT`
    /// is whether any lane has an odometer boresight, `BIAS` whether any has a speed bias.
    /// Written as a few loops over the lanes, each straight-line arithmetic over
    /// `[f64; N]`, so that they run in vector registers.
    #[inline(always)]
    fn step<const BORESIGHT: bool, const BIAS: bool>(
        &mut self,
        seg: &ImuSegment,
        sums: &LaneSums<N>,
        update_terms: bool,
    ) {
        if update_terms {
            self.terms.update(&self.lat_rad);
        }
        let t = f64::from(seg.t_s);
        let qs = seg.q;
        let m = seg.m.map(f64::from);

        // Each lane's odometer sums along its direction of travel (u), and the third
        // column's (w3) for the pitch boresight: κ S + β S_mov.
        let mut u = [[0.0; N]; 3];
        let mut w3 = [[0.0; N]; 3];
        let mut ds = [0.0; N];
        for l in 0..N {
            let k = self.odo_scale[l];
            let (sc, ss) = (self.odo_cos[l], self.odo_sin[l]);
            for i in 0..3 {
                let (x, y) = (sums.x[i][l], sums.y[i][l]);
                u[i][l] = if BORESIGHT {
                    k * (x * sc + y * ss)
                } else {
                    k * x
                };
                if BORESIGHT {
                    w3[i][l] = k * sums.z[i][l];
                }
            }
            ds[l] = k * sums.x[3][l];
            if BIAS {
                let b = self.odo_bias_mps[l];
                for i in 0..3 {
                    let (x, y) = (sums.mx[i][l], sums.my[i][l]);
                    u[i][l] += if BORESIGHT {
                        b * (x * sc + y * ss)
                    } else {
                        b * x
                    };
                    if BORESIGHT {
                        w3[i][l] += b * sums.mz[i][l];
                    }
                }
                ds[l] += b * sums.mx[3][l];
            }
        }

        // 1. The drift's half turns on either side of the segment's.
        let mut a = [[0.0; N]; 3];
        for l in 0..N {
            for i in 0..3 {
                a[i][l] = -0.5 * self.drift_rad_s[i][l] * t;
            }
        }
        let e = turns(&a);

        // 2. The body's turn, and the attitude at the segment's middle frame: half the
        //    navigation frame's turn (Earth rate, the previous segment's transport
        //    rate) before the segment's distance.
        let mut qb = [[0.0; N]; 4];
        let mut qm = [[0.0; N]; 4];
        let mut ze = [[0.0; N]; 2];
        for l in 0..N {
            let el = [e[0][l], e[1][l], e[2][l], e[3][l]];
            let b = qmul(qmul(el, qs), el);
            ze[0][l] = self.terms.at.w_ie_north_rad_s[l] * t;
            ze[1][l] = self.terms.at.w_ie_down_rad_s[l] * t;
            let v1 = [
                -0.25 * (ze[0][l] + self.rho_prev[0][l]),
                -0.25 * self.rho_prev[1][l],
                -0.25 * (ze[1][l] + self.rho_prev[2][l]),
            ];
            let q = [self.q[0][l], self.q[1][l], self.q[2][l], self.q[3][l]];
            let mid = qmul(small_turn(v1), q);
            for i in 0..4 {
                qb[i][l] = b[i];
                qm[i][l] = mid[i];
            }
        }

        // 3. The route, and 4. the block's sum of third rows.
        for l in 0..N {
            let c = dcm_rows([qm[0][l], qm[1][l], qm[2][l], qm[3][l]]);
            let ul = [u[0][l], u[1][l], u[2][l]];
            let mut dp = [0.0; 3];
            for r in 0..3 {
                dp[r] = c[r][0] * ul[0] + c[r][1] * ul[1] + c[r][2] * ul[2];
            }
            if BORESIGHT {
                dp[2] -= self.odo_tan_pitch[l]
                    * (c[2][0] * w3[0][l] + c[2][1] * w3[1][l] + c[2][2] * w3[2][l]);
            }
            let h_mid = self.h_m[l] - 0.5 * dp[2];
            // Both radii's inverses by one division.
            let (rm_h, rn_h) = (self.terms.at.rm_m[l] + h_mid, self.terms.at.rn_m[l] + h_mid);
            let inv = 1.0 / (rm_h * rn_h);
            let (inv_rm_h, inv_rn_h) = (rn_h * inv, rm_h * inv);
            self.lat_rad[l] += dp[0] * inv_rm_h;
            self.lon_rad[l] += dp[1] * inv_rn_h * self.terms.at.inv_cos[l];
            self.h_m[l] -= dp[2];
            self.distance_m[l] += ds[l];
            // The rest of the navigation frame's turn: half the Earth rate's, this
            // segment's transport turn less the half taken of the previous one.
            let rho = [
                dp[1] * inv_rn_h,
                -dp[0] * inv_rm_h,
                -dp[1] * self.terms.at.tan[l] * inv_rn_h,
            ];
            let v2 = [
                -0.5 * (0.5 * ze[0][l] + rho[0] - 0.5 * self.rho_prev[0][l]),
                -0.5 * (rho[1] - 0.5 * self.rho_prev[1][l]),
                -0.5 * (0.5 * ze[1][l] + rho[2] - 0.5 * self.rho_prev[2][l]),
            ];
            for i in 0..3 {
                self.rho_prev[i][l] = rho[i];
            }
            let mid = [qm[0][l], qm[1][l], qm[2][l], qm[3][l]];
            let qn = qmul(
                qmul(small_turn(v2), mid),
                [qb[0][l], qb[1][l], qb[2][l], qb[3][l]],
            );
            for i in 0..4 {
                self.q[i][l] = qn[i];
            }
            for j in 0..3 {
                self.acc[j][l] += c[2][0] * m[j] + c[2][1] * m[3 + j] + c[2][2] * m[6 + j];
            }
        }
    }

    /// Brings every lane's quaternion back to unit norm (its products drift from it by
    /// rounding alone: some 1e-16 a segment).
    #[inline(always)]
    fn renormalise(&mut self) {
        for l in 0..N {
            let q = self.q_of(l);
            let inv = 1.0 / (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
            for i in 0..4 {
                self.q[i][l] = q[i] * inv;
            }
        }
    }

    #[inline(always)]
    fn q_of(&self, l: usize) -> [f64; 4] {
        [self.q[0][l], self.q[1][l], self.q[2][l], self.q[3][l]]
    }

    /// Steps every lane over all segments, handing `emit` the blocks and the states
    /// after the samples `reports` (increasing, each a segment's last). On x86-64 CPUs
    /// with AVX2 the loop runs in its vector registers.
    fn run(
        self,
        imu: &ImuSegments,
        odometers: [&OdoSegments; N],
        reports: &[usize],
        emit: &mut impl SegmentEmit<N>,
    ) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            #[allow(unsafe_code)]
            // SAFETY: `run_avx2` only needs AVX2, and this CPU has it (checked above).
            return unsafe { self.run_avx2(imu, odometers, reports, emit) };
        }
        self.run_portable(imu, odometers, reports, emit)
    }

    /// [`Self::run_portable`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn run_avx2(
        self,
        imu: &ImuSegments,
        odometers: [&OdoSegments; N],
        reports: &[usize],
        emit: &mut impl SegmentEmit<N>,
    ) {
        self.run_portable(imu, odometers, reports, emit)
    }

    #[inline(always)]
    fn run_portable(
        self,
        imu: &ImuSegments,
        odometers: [&OdoSegments; N],
        reports: &[usize],
        emit: &mut impl SegmentEmit<N>,
    ) {
        let boresight = (0..N).any(|l| self.odo_sin[l] != 0.0 || self.odo_tan_pitch[l] != 0.0);
        let bias = (0..N).any(|l| self.odo_bias_mps[l] != 0.0);
        match (boresight, bias) {
            (false, false) => self.run_with::<false, false>(imu, odometers, reports, emit),
            (true, false) => self.run_with::<true, false>(imu, odometers, reports, emit),
            (false, true) => self.run_with::<false, true>(imu, odometers, reports, emit),
            (true, true) => self.run_with::<true, true>(imu, odometers, reports, emit),
        }
    }

    #[inline(always)]
    fn run_with<const BORESIGHT: bool, const BIAS: bool>(
        mut self,
        imu: &ImuSegments,
        odometers: [&OdoSegments; N],
        reports: &[usize],
        emit: &mut impl SegmentEmit<N>,
    ) {
        let distance: [&OdoSums; N] = std::array::from_fn(|l| &odometers[l].distance);
        let moving: [&OdoSums; N] = std::array::from_fn(|l| {
            if BIAS {
                odometers[l]
                    .moving
                    .as_ref()
                    .expect("a speed bias reads the odometer's moving time")
            } else {
                &odometers[l].distance
            }
        });
        let mut sums = LaneSums::ZERO;
        let mut next_report = reports.iter().peekable();
        for (i, (seg, end)) in imu.segments.iter().zip(imu.plan.ends()).enumerate() {
            sums.gather::<BORESIGHT, BIAS>(i, &distance, &moving);
            self.step::<BORESIGHT, BIAS>(seg, &sums, i % LAT_UPDATE_EVERY == 0);
            let report = next_report.next_if(|&&k| k + 1 == end.end).is_some();
            if i % RENORMALISE_EVERY == RENORMALISE_EVERY - 1 || report {
                self.renormalise();
            }
            if end.closes_block {
                emit.block(&self.acc);
                self.acc = [[0.0; N]; 3];
            }
            if report {
                emit.report(end.end - 1, &self);
            }
        }
        emit.finish();
    }

    /// Lane `l`'s pose.
    #[inline(always)]
    fn pose(&self, l: usize) -> FixPose {
        FixPose {
            lat_rad: self.lat_rad[l],
            lon_rad: self.lon_rad[l],
            h_m: self.h_m[l],
            distance_m: self.distance_m[l],
            q_b_to_n: self.q_of(l),
        }
    }
}

/// Each lane's odometer sums over one segment, as [`SegmentLanes::step`] reads them.
struct LaneSums<const N: usize> {
    /// `S`'s first column and the distance.
    x: [[f64; N]; 4],
    /// `S`'s second column (zero where not integrated).
    y: [[f64; N]; 3],
    /// `S`'s third column (zero where not integrated).
    z: [[f64; N]; 3],
    /// The same over the moving time.
    mx: [[f64; N]; 4],
    my: [[f64; N]; 3],
    mz: [[f64; N]; 3],
}

impl<const N: usize> LaneSums<N> {
    const ZERO: Self = Self {
        x: [[0.0; N]; 4],
        y: [[0.0; N]; 3],
        z: [[0.0; N]; 3],
        mx: [[0.0; N]; 4],
        my: [[0.0; N]; 3],
        mz: [[0.0; N]; 3],
    };

    /// Segment `i`'s sums of each lane's odometer: the columns the step reads (a
    /// column an odometer lacks is read as zero, as its lane's settings never weigh it).
    #[inline(always)]
    fn gather<const BORESIGHT: bool, const BIAS: bool>(
        &mut self,
        i: usize,
        distance: &[&OdoSums; N],
        moving: &[&OdoSums; N],
    ) {
        fn read<const N: usize>(
            sums: &OdoSums,
            i: usize,
            l: usize,
            x: &mut [[f64; N]; 4],
            y: &mut [[f64; N]; 3],
            z: &mut [[f64; N]; 3],
            boresight: bool,
        ) {
            let c = sums.x[i];
            for r in 0..4 {
                x[r][l] = f64::from(c[r]);
            }
            if boresight {
                let cy = sums.y.get(i).copied().unwrap_or_default();
                let cz = sums.z.get(i).copied().unwrap_or_default();
                for r in 0..3 {
                    y[r][l] = f64::from(cy[r]);
                    z[r][l] = f64::from(cz[r]);
                }
            }
        }
        for l in 0..N {
            read(
                distance[l],
                i,
                l,
                &mut self.x,
                &mut self.y,
                &mut self.z,
                BORESIGHT,
            );
            if BIAS {
                read(
                    moving[l],
                    i,
                    l,
                    &mut self.mx,
                    &mut self.my,
                    &mut self.mz,
                    BORESIGHT,
                );
            }
        }
    }
}

/// What a run over segments does with the lanes' blocks and reported states.
trait SegmentEmit<const N: usize> {
    /// A block of F closed: each lane's sum of `C_b^n`'s third row over it.
    fn block(&mut self, row3: &[[f64; N]; 3]);
    /// The lanes' states after sample `k`.
    fn report(&mut self, k: usize, lanes: &SegmentLanes<N>);
    /// The run ended.
    fn finish(&mut self);
}

/// What the criteria read, into each lane's sink.
struct CriteriaEmit<'s, const N: usize> {
    angles: BlockAngles<N>,
    sinks: &'s mut [CriteriaSink; N],
}

impl<const N: usize> SegmentEmit<N> for CriteriaEmit<'_, N> {
    #[inline(always)]
    fn block(&mut self, row3: &[[f64; N]; 3]) {
        self.angles.push(row3, self.sinks);
    }

    fn report(&mut self, k: usize, lanes: &SegmentLanes<N>) {
        for (l, sink) in self.sinks.iter_mut().enumerate() {
            sink.wanted.pop();
            sink.positions.push((k, lanes.pose(l)));
        }
    }

    fn finish(&mut self) {
        self.angles.flush(self.sinks);
    }
}

/// Blocks between angles taken anew from their sums (libm's atan2) rather than turned
/// from the block before's.
const ANGLE_ANCHOR_EVERY: usize = 256;

/// Angle steps beyond which a block's angle is taken anew (libm's atan2) rather than by
/// the step's series, rad (a block's roll or pitch moves by some 1e-3 rad).
const ANGLE_STEP_SERIES_LIMIT: f64 = 0.1;

/// atan(δ) for |δ| ≤ [`ANGLE_STEP_SERIES_LIMIT`] by its series (the first term left out,
/// δ¹⁹/19, is under 6e-21).
#[inline(always)]
fn atan_small(d: f64) -> f64 {
    let d2 = d * d;
    d * (1.0
        + d2 * (-1.0 / 3.0
            + d2 * (1.0 / 5.0
                + d2 * (-1.0 / 7.0
                    + d2 * (1.0 / 9.0
                        + d2 * (-1.0 / 11.0
                            + d2 * (1.0 / 13.0 + d2 * (-1.0 / 15.0 + d2 * (1.0 / 17.0)))))))))
}

/// `a` wrapped into (−π, π], for an angle at most a step beyond it.
#[inline(always)]
fn wrap_step(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    if a > PI {
        a - TAU
    } else if a <= -PI {
        a + TAU
    } else {
        a
    }
}

/// Each lane's roll (atan2(C32, C33)) and pitch (atan2(−C31, √(C32² + C33²))) of its
/// blocks' sums of `C_b^n`'s third row, into its sink. A block's angle is the block
/// before's turned by the angle between their (x, y): atan((y x′ − x y′)/(x x′ + y y′)),
/// a step of some 1e-3 rad, by its series — a division and a few multiplications in
/// vector registers where libm's atan2 takes most of a pass's time. The first block, one
/// in [`ANGLE_ANCHOR_EVERY`] and any whose step exceeds [`ANGLE_STEP_SERIES_LIMIT`] are
/// taken by libm's atan2. Rounding adds about an ulp a block between anchors (under 1e-13
/// rad). Every decision is the lane's own or the block's index: a lane's angles are the
/// same whatever lanes run beside it.
struct BlockAngles<const N: usize> {
    /// The previous block's (x, y) of the roll and of the pitch, and its angles.
    roll_xy: [[f64; N]; 2],
    pitch_xy: [[f64; N]; 2],
    roll: [f64; N],
    pitch: [f64; N],
    blocks: usize,
}

impl<const N: usize> BlockAngles<N> {
    fn new() -> Self {
        Self {
            roll_xy: [[0.0; N]; 2],
            pitch_xy: [[0.0; N]; 2],
            roll: [0.0; N],
            pitch: [0.0; N],
            blocks: 0,
        }
    }

    /// Each lane's next block (its sum of third rows, `row3[.][l]`), into its sink.
    #[inline(always)]
    fn push(&mut self, row3: &[[f64; N]; 3], sinks: &mut [CriteriaSink; N]) {
        let anchor = self.blocks.is_multiple_of(ANGLE_ANCHOR_EVERY);
        self.blocks += 1;
        let mut xy = [[[0.0; N]; 2]; 2];
        let mut step = [[0.0; N]; 2];
        let mut exact = [[false; N]; 2];
        for l in 0..N {
            let (c31, c32, c33) = (row3[0][l], row3[1][l], row3[2][l]);
            xy[0][0][l] = c33;
            xy[0][1][l] = c32;
            xy[1][0][l] = (c32 * c32 + c33 * c33).sqrt();
            xy[1][1][l] = -c31;
            for (a, prev) in [&self.roll_xy, &self.pitch_xy].into_iter().enumerate() {
                let (x, y) = (xy[a][0][l], xy[a][1][l]);
                let (xp, yp) = (prev[0][l], prev[1][l]);
                let d = (y * xp - x * yp) / (x * xp + y * yp);
                step[a][l] = atan_small(d);
                // Past the limit, or not a number (a zero sum).
                exact[a][l] = !matches!(
                    d.abs().partial_cmp(&ANGLE_STEP_SERIES_LIMIT),
                    Some(std::cmp::Ordering::Less | std::cmp::Ordering::Equal)
                );
            }
        }
        for l in 0..N {
            self.roll[l] = wrap_step(self.roll[l] + step[0][l]);
            self.pitch[l] = wrap_step(self.pitch[l] + step[1][l]);
        }
        for l in 0..N {
            if anchor || exact[0][l] {
                self.roll[l] = xy[0][1][l].atan2(xy[0][0][l]);
            }
            if anchor || exact[1][l] {
                self.pitch[l] = xy[1][1][l].atan2(xy[1][0][l]);
            }
        }
        self.roll_xy = xy[0];
        self.pitch_xy = xy[1];
        for (l, sink) in sinks.iter_mut().enumerate() {
            sink.blocks.push(self.roll[l], self.pitch[l]);
        }
    }

    /// Nothing is held back.
    fn flush(&mut self, _sinks: &mut [CriteriaSink; N]) {}
}

/// Runs `N` passes side by side over a run's segments (`imu`, and each lane's odometer
/// `odometers[l]` over the same segments, with the columns its lane's settings read)
/// into `sinks`, each reset first: the blocks of F's sums of `C_b^n`'s third row and the
/// states after the samples `reports` (each a segment's last; any order, repeats left
/// out), what [`super::run_criteria`] gives to within what the criteria resolve (the
/// module's documentation), at a tenth of its cost.
///
/// # Panics
/// If an odometer has another number of segments than `imu` or lacks a column its lane
/// reads ([`OdoColumns::read_by`]), or a report is not a segment's last sample.
pub fn run_criteria_segments<const N: usize>(
    imu: &ImuSegments,
    odometers: [&OdoSegments; N],
    settings: &[NavSettings; N],
    reports: &[usize],
    sinks: &mut [CriteriaSink; N],
) {
    check_odometers(imu, &odometers, settings);
    for sink in sinks.iter_mut() {
        sink.reset(imu.plan.samples, imu.plan.block, reports.iter().copied());
    }
    let mut reports: Vec<usize> = reports
        .iter()
        .copied()
        .filter(|&k| k < imu.plan.samples)
        .collect();
    reports.sort_unstable();
    reports.dedup();
    assert!(
        reports.iter().all(|&k| imu.plan.ends_after(k)),
        "a report within a segment"
    );
    let mut emit = CriteriaEmit {
        angles: BlockAngles::new(),
        sinks,
    };
    SegmentLanes::new(settings).run(imu, odometers, &reports, &mut emit);
}

/// Panics unless every odometer has `imu`'s segments and the columns its lane reads.
fn check_odometers<const N: usize>(
    imu: &ImuSegments,
    odometers: &[&OdoSegments; N],
    settings: &[NavSettings; N],
) {
    for (o, s) in odometers.iter().zip(settings) {
        assert_eq!(
            o.distance.x.len(),
            imu.segments.len(),
            "odometer segments of another plan"
        );
        assert!(
            o.columns
                .cover(&OdoColumns::read_by(std::slice::from_ref(s))),
            "an odometer without the columns its pass reads"
        );
    }
}

#[cfg(test)]
mod tests {
    use super::super::segments::{SegmentPlan, integrate};
    use super::*;

    /// A turning, bumping drive with a stop and a violent sample.
    fn inputs() -> (Vec<f64>, Vec<[f64; 3]>, Vec<f64>) {
        let n = 5003;
        let dtheta = super::super::test_drive::turning_dtheta(n);
        let odo = (0..n)
            .map(|k| if (1000..1800).contains(&k) { 0.0 } else { 0.2 })
            .collect();
        (vec![0.01; n], dtheta, odo)
    }

    use super::super::test_drive::lane_settings as settings;

    fn bits(sink: &CriteriaSink) -> (Vec<u64>, Vec<u64>, Vec<[u64; 8]>) {
        let b = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect();
        let poses = sink
            .positions
            .iter()
            .map(|(k, p)| {
                let q = p.q_b_to_n;
                [
                    *k as f64,
                    p.lat_rad,
                    p.lon_rad,
                    p.h_m,
                    p.distance_m,
                    q[0],
                    q[1],
                    q[3],
                ]
                .map(f64::to_bits)
            })
            .collect();
        (b(&sink.blocks.roll_rad), b(&sink.blocks.pitch_rad), poses)
    }

    /// Whatever runs beside it (boresights, a speed bias, other drifts), and however many
    /// lanes, a lane gives what its pass alone gives, bit for bit: the methods' results
    /// never depend on how their passes were batched.
    #[test]
    fn a_batch_of_segment_lanes_is_each_pass_alone_bit_for_bit() {
        let (dt, dth, odo) = inputs();
        let reports = [1200, 4000, 5002];
        let plan = SegmentPlan::new(dt.len(), 10, reports);
        let all_columns = OdoColumns {
            yaw: true,
            pitch: true,
            moving: true,
        };
        let (imu, odos) = integrate(
            &dt,
            (&dth).into(),
            &plan,
            true,
            &mut [odo.iter().copied()],
            all_columns,
        );
        let (imu, odo) = (imu.unwrap(), &odos[0]);
        let all: [NavSettings; 8] = std::array::from_fn(settings);
        let mut batch: [CriteriaSink; 8] = Default::default();
        run_criteria_segments(&imu, [odo; 8], &all, &reports, &mut batch);
        for (l, s) in all.iter().enumerate() {
            let mut alone = [CriteriaSink::default()];
            run_criteria_segments(&imu, [odo], &[*s], &reports, &mut alone);
            assert_eq!(bits(&alone[0]), bits(&batch[l]), "lane {l}");
            // Four lanes beside it, without a boresight or bias elsewhere.
            let mut four: [CriteriaSink; 4] = Default::default();
            let beside = [*s, settings(0), settings(1), settings(2)];
            run_criteria_segments(&imu, [odo; 4], &beside, &reports, &mut four);
            assert_eq!(bits(&four[0]), bits(&batch[l]), "lane {l} among four");
        }
        // The vector loop the CPU supports and the portable one agree too.
        let mut portable: [CriteriaSink; 8] = Default::default();
        for sink in portable.iter_mut() {
            sink.reset(plan.samples, plan.block, reports);
        }
        let mut emit = CriteriaEmit {
            angles: BlockAngles::new(),
            sinks: &mut portable,
        };
        SegmentLanes::new(&all).run_portable(&imu, [odo; 8], &reports, &mut emit);
        for l in 0..8 {
            assert_eq!(bits(&portable[l]), bits(&batch[l]), "portable lane {l}");
        }
        assert_eq!(batch[0].blocks.len(), dt.len().div_ceil(10));
        assert_eq!(batch[0].positions.len(), 3);
        assert_ne!(bits(&batch[0]), bits(&batch[1]));
    }
}

#[cfg(test)]
mod angle_tests {
    use super::*;

    /// The blocks' angles turned step by step stay within 1e-13 rad of libm's atan2 of
    /// each block's sums, through steps past the series' limit, a roll through ±π and
    /// the anchors.
    #[test]
    fn block_angles_are_each_blocks_atan2() {
        let n = 3000;
        let mut sinks: [CriteriaSink; 2] = Default::default();
        let mut angles = BlockAngles::<2>::new();
        let mut want = [Vec::new(), Vec::new()];
        for j in 0..n {
            let t = j as f64 * 0.1;
            // Lane 0: a vehicle's few degrees; lane 1: rolling over through ±π, with a
            // jump past the series' limit.
            let rolls = [
                0.05 * (0.3 * t).sin(),
                3.0 + 0.01 * t + if j == 1500 { 0.5 } else { 0.0 },
            ];
            let pitches = [0.03 * (0.2 * t).cos(), -0.4 + 0.0005 * t];
            let mut row3 = [[0.0; 2]; 3];
            for l in 0..2 {
                // Ten samples' third rows summed: the row times ten, the norm slightly
                // less than ten.
                let (r, p) = (rolls[l], pitches[l]);
                let scale = 9.99;
                row3[0][l] = -p.sin() * scale;
                row3[1][l] = p.cos() * r.sin() * scale;
                row3[2][l] = p.cos() * r.cos() * scale;
                want[l].push((
                    row3[1][l].atan2(row3[2][l]),
                    (-row3[0][l]).atan2(row3[1][l].hypot(row3[2][l])),
                ));
            }
            angles.push(&row3, &mut sinks);
        }
        for l in 0..2 {
            let blocks = &sinks[l].blocks;
            assert_eq!(blocks.len(), n);
            for (j, (r, p)) in want[l].iter().enumerate() {
                assert!(
                    (blocks.roll_rad[j] - r).abs() < 1e-13,
                    "lane {l} block {j} roll"
                );
                assert!(
                    (blocks.pitch_rad[j] - p).abs() < 1e-13,
                    "lane {l} block {j} pitch"
                );
            }
        }
    }
}
