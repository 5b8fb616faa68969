//! Euler angles as the tables store them: f32 degrees of the angles
//! [`crate::strapdown::euler_of`] gives, computed without libm where the f32 is certain.
//!
//! A navigation table holds each sample's roll, pitch and heading as f32 degrees: the f64
//! angles of `C_b^n` (nalgebra's `euler_angles`: libm's `asin`, `cos` and two `atan2`
//! over quotients by the cosine), `.to_degrees()`, rounded to f32. Those libm calls were
//! most of what writing a 100-Hz table cost beside its encoding. Here each angle is
//! computed by a short series instead ([`atan_fast`]: a table of atan(k/32) and five
//! terms of atan's series, relative error a few units of f64's last place), and the
//! f32 kept when every f64 within [`MARGIN`] (relative) of it, which bounds how far the
//! libm route's value can be, rounds to the same f32 ([`certain`]); else (a value within
//! 2^-40 of an f32 rounding boundary, about one angle in 30 000, or a degenerate one)
//! the libm route is taken. The f32 is the libm route's, bit for bit.

use crate::attitude::rem_euclid_turn;
use crate::strapdown::euler_of;

/// The relative distance from an angle within which the libm route's value lies: 2^-40,
/// a thousand times the bound of either route's error (the series' few units of the last
/// place, libm's one, the quotients' two, the roundings to degrees).
pub const MARGIN: f64 = 1.0 / (1u64 << 40) as f64;

/// atan(k/32), k = 0..=32 (libm's, each within one unit of the last place).
const ATAN_K32: [f64; 33] = [
    0.0,
    0.031239833430268277,
    0.06241880999595735,
    0.09347678115858947,
    0.12435499454676144,
    0.15499674192394097,
    0.18534794999569476,
    0.21535769969773805,
    0.24497866312686414,
    0.2741674511196588,
    0.3028848683749714,
    0.3310960767041321,
    0.35877067027057225,
    0.38588266939807375,
    0.4124104415973873,
    0.43833655985795783,
    0.4636476090008061,
    0.48833395105640554,
    0.5123894603107377,
    0.5358112379604637,
    0.5585993153435624,
    0.5807563535676704,
    0.6022873461349642,
    0.6231993299340659,
    0.6435011087932844,
    0.6632029927060933,
    0.6823165548747481,
    0.7008544078844502,
    0.7188299996216245,
    0.7362574289814281,
    0.7531512809621944,
    0.7695264804056583,
    std::f64::consts::FRAC_PI_4,
];

/// atan(t) for t in [0, 1]: atan(c) + atan((t − c)/(1 + t c)) with c the nearest k/32,
/// the second by its series to u⁹ (|u| ≤ 1/64: the next term is under 1e-19 of u).
#[inline(always)]
fn atan_unit(t: f64) -> f64 {
    let k = (t * 32.0 + 0.5) as usize;
    let c = k as f64 / 32.0;
    let u = (t - c) / (1.0 + t * c);
    let u2 = u * u;
    let series =
        u + u * u2 * (-1.0 / 3.0 + u2 * (1.0 / 5.0 + u2 * (-1.0 / 7.0 + u2 * (1.0 / 9.0))));
    ATAN_K32[k.min(32)] + series
}

/// atan(t) for finite t ≥ 0.
#[inline(always)]
pub fn atan_fast(t: f64) -> f64 {
    if t <= 1.0 {
        atan_unit(t)
    } else {
        std::f64::consts::FRAC_PI_2 - atan_unit(1.0 / t)
    }
}

/// atan2(y, x) for finite, non-zero `y` and `x` (None otherwise), to a few units of the
/// last place.
#[inline(always)]
pub fn atan2_fast(y: f64, x: f64) -> Option<f64> {
    let (ay, ax) = (y.abs(), x.abs());
    if !(ay > 0.0 && ax > 0.0 && ay.is_finite() && ax.is_finite()) {
        return None;
    }
    let r = if ay <= ax {
        atan_unit(ay / ax)
    } else {
        std::f64::consts::FRAC_PI_2 - atan_unit(ax / ay)
    };
    let r = if x < 0.0 { std::f64::consts::PI - r } else { r };
    Some(r.copysign(y))
}

/// asin(x) for |x| ≤ 0.99 (None otherwise): atan(x / √((1 − x)(1 + x))).
#[inline(always)]
pub fn asin_fast(x: f64) -> Option<f64> {
    if x.is_nan() || x.abs() > 0.99 || x == 0.0 {
        return None;
    }
    let t = x.abs() / ((1.0 - x) * (1.0 + x)).sqrt();
    Some(atan_fast(t).copysign(x))
}

/// `then(z)` rounded to f32 when every value within [`MARGIN`] of `z` (relative) gives
/// the same f32 through `then` (monotone on that interval), and `z` is a normal f32's
/// size.
#[inline(always)]
pub fn certain(z: f64, then: impl Fn(f64) -> f64) -> Option<f32> {
    let e = z.abs() * MARGIN;
    let (lo, hi) = (then(z - e) as f32, then(z + e) as f32);
    (lo.to_bits() == hi.to_bits() && z.abs() > 1e-30).then_some(lo)
}

/// How a heading in degrees is stored: as is (`nav.parquet`: [0, 360]), or wrapped into
/// [0, 360) again (`tracks.parquet`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HeadingDeg {
    /// `.to_degrees()` of the heading in [0, 2π).
    AsIs,
    /// Then [`rem_euclid_turn`] by 360.
    Wrapped,
}

impl HeadingDeg {
    #[inline(always)]
    fn apply(self, deg: f64) -> f64 {
        match self {
            HeadingDeg::AsIs => deg,
            HeadingDeg::Wrapped => rem_euclid_turn(deg, 360.0),
        }
    }
}

/// Roll, pitch and heading of the quaternion `[w, x, y, z]` of `C_b^n` in f32 degrees:
/// exactly [`euler_of`]'s angles `.to_degrees()` (the heading through `heading`) `as
/// f32`.
#[inline]
pub fn euler_deg_f32(q: &[f64; 4], heading: HeadingDeg) -> [f32; 3] {
    fast(q, heading).unwrap_or_else(|| {
        let e = euler_of(q);
        [
            e.roll_rad.to_degrees() as f32,
            e.pitch_rad.to_degrees() as f32,
            heading.apply(e.heading_rad.to_degrees()) as f32,
        ]
    })
}

/// [`euler_deg_f32`] without libm, when each f32 is certain.
#[inline(always)]
fn fast(q: &[f64; 4], heading: HeadingDeg) -> Option<[f32; 3]> {
    let [m00, m10, m20, m21, m22] = matrix_entries(q);
    // nalgebra's: pitch −asin(m20), then roll and yaw from the atan2 of entries divided
    // by cos(pitch) > 0, which moves neither angle by more than two units of the last
    // place (relative).
    let pitch = -asin_fast(m20)?;
    let roll = atan2_fast(m21, m22)?;
    let yaw = rem_euclid_turn(atan2_fast(m10, m00)?, std::f64::consts::TAU);
    certain_row(
        [roll.to_degrees(), pitch.to_degrees(), yaw.to_degrees()],
        heading,
    )
}

/// The rotation matrix's entries (m00, m10, m20, m21, m22) of `q` (w, x, y, z) that the
/// angles read, as nalgebra's `to_rotation_matrix` forms them (i, j, k the vector part).
#[inline(always)]
fn matrix_entries(q: &[f64; 4]) -> [f64; 5] {
    let [w, i, j, k] = *q;
    let (ww, ii, jj, kk) = (w * w, i * i, j * j, k * k);
    let ij = i * j * 2.0;
    let wk = w * k * 2.0;
    let wj = w * j * 2.0;
    let ik = i * k * 2.0;
    let jk = j * k * 2.0;
    let wi = w * i * 2.0;
    [
        ww + ii - jj - kk,
        wk + ij,
        ik - wj,
        wi + jk,
        ww - ii - jj + kk,
    ]
}

/// Attitudes [`euler_deg_f32_into`] takes side by side: a block of them, each step over
/// the whole block before the next (eight AVX2 registers of f64 a step). With one
/// register's four, each attitude's chain of square root, divisions and series was
/// exposed; over a block the CPU overlaps the chains (measured: 21 → 13 ns an attitude).
/// A list's last attitudes short of a block are taken one at a time.
pub const SIDE_BY_SIDE: usize = 32;

/// [`euler_deg_f32`] of each of `q` into `out` (as long): blocks of [`SIDE_BY_SIDE`]
/// attitudes side by side, in vector registers on x86-64 CPUs with AVX2 (a table's rows
/// are independent: its divisions, square roots and polynomials then take a quarter of the
/// instructions), each lane with exactly its attitude's operations. The same f32, bit for
/// bit, as [`euler_deg_f32`] one at a time.
///
/// # Panics
/// If `out` is not as long as `q`.
pub fn euler_deg_f32_into(q: &[[f64; 4]], heading: HeadingDeg, out: &mut [[f32; 3]]) {
    assert_eq!(q.len(), out.len(), "attitudes and rows");
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        #[allow(unsafe_code)]
        // SAFETY: `into_avx2` only needs AVX2, and this CPU has it (checked above).
        return unsafe { into_avx2(q, heading, out) };
    }
    into_portable(q, heading, out)
}

/// [`into_portable`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn into_avx2(q: &[[f64; 4]], heading: HeadingDeg, out: &mut [[f32; 3]]) {
    into_portable(q, heading, out)
}

#[inline(always)]
fn into_portable(q: &[[f64; 4]], heading: HeadingDeg, out: &mut [[f32; 3]]) {
    let mut groups = q.chunks_exact(SIDE_BY_SIDE);
    let mut rows = out.chunks_exact_mut(SIDE_BY_SIDE);
    for (q, rows) in (&mut groups).zip(&mut rows) {
        let q: &[[f64; 4]; SIDE_BY_SIDE] = q.try_into().expect("a whole group");
        let (angles, sure) = certain_lanes(&fast_lanes(q), heading);
        for (l, row) in rows.iter_mut().enumerate() {
            *row = [angles[0][l], angles[1][l], angles[2][l]];
        }
        if sure.contains(&false) {
            uncertain_again(q, &sure, heading, rows);
        }
    }
    for (q, row) in groups.remainder().iter().zip(rows.into_remainder()) {
        *row = euler_deg_f32(q, heading);
    }
}

/// The rows of the attitudes not `sure`, again by [`euler_deg_f32`] (libm's route where
/// the fast one is not certain): one attitude in some 10 000 of a vehicle's.
#[cold]
#[inline(never)]
fn uncertain_again(q: &[[f64; 4]], sure: &[bool], heading: HeadingDeg, rows: &mut [[f32; 3]]) {
    for ((q, &sure), row) in q.iter().zip(sure).zip(rows) {
        if !sure {
            *row = euler_deg_f32(q, heading);
        }
    }
}

/// [`atan_unit`] of each lane (each `t` in [0, 1]; any value in a lane left out).
#[inline(always)]
fn atan_unit_lanes(t: [f64; SIDE_BY_SIDE]) -> [f64; SIDE_BY_SIDE] {
    let mut r = [0.0; SIDE_BY_SIDE];
    for l in 0..SIDE_BY_SIDE {
        // `as i32` truncates as `as usize` does over [0.5, 32.5]; a lane left out (NaN,
        // out of range) saturates, and is clamped to the table.
        let k = (t[l] * 32.0 + 0.5) as i32;
        let c = f64::from(k) / 32.0;
        let u = (t[l] - c) / (1.0 + t[l] * c);
        let u2 = u * u;
        let series =
            u + u * u2 * (-1.0 / 3.0 + u2 * (1.0 / 5.0 + u2 * (-1.0 / 7.0 + u2 * (1.0 / 9.0))));
        r[l] = ATAN_K32[k.clamp(0, 32) as usize] + series;
    }
    r
}

/// [`atan2_fast`] of each lane, NaN where it gives none.
#[inline(always)]
fn atan2_lanes(y: [f64; SIDE_BY_SIDE], x: [f64; SIDE_BY_SIDE]) -> [f64; SIDE_BY_SIDE] {
    let mut ratio = [0.0; SIDE_BY_SIDE];
    for l in 0..SIDE_BY_SIDE {
        // `if ay <= ax { ay / ax } else { ax / ay }` in one division (NaNs aside, whose
        // lanes are left out).
        let (ay, ax) = (y[l].abs(), x[l].abs());
        let (small, large) = if ay <= ax { (ay, ax) } else { (ax, ay) };
        ratio[l] = small / large;
    }
    let a = atan_unit_lanes(ratio);
    let mut out = [0.0; SIDE_BY_SIDE];
    for l in 0..SIDE_BY_SIDE {
        let (ay, ax) = (y[l].abs(), x[l].abs());
        let r = if ay <= ax {
            a[l]
        } else {
            std::f64::consts::FRAC_PI_2 - a[l]
        };
        let r = if x[l] < 0.0 {
            std::f64::consts::PI - r
        } else {
            r
        };
        let valid = ay > 0.0 && ax > 0.0 && ay.is_finite() && ax.is_finite();
        out[l] = if valid { r.copysign(y[l]) } else { f64::NAN };
    }
    out
}

/// [`asin_fast`] of each lane, NaN where it gives none.
#[inline(always)]
fn asin_lanes(x: [f64; SIDE_BY_SIDE]) -> [f64; SIDE_BY_SIDE] {
    let mut t = [0.0; SIDE_BY_SIDE];
    let mut unit = [0.0; SIDE_BY_SIDE];
    for l in 0..SIDE_BY_SIDE {
        t[l] = x[l].abs() / ((1.0 - x[l]) * (1.0 + x[l])).sqrt();
        unit[l] = if t[l] <= 1.0 { t[l] } else { 1.0 / t[l] };
    }
    let a = atan_unit_lanes(unit);
    let mut out = [0.0; SIDE_BY_SIDE];
    for l in 0..SIDE_BY_SIDE {
        let r = if t[l] <= 1.0 {
            a[l]
        } else {
            std::f64::consts::FRAC_PI_2 - a[l]
        };
        let valid = !x[l].is_nan() && x[l].abs() <= 0.99 && x[l] != 0.0;
        out[l] = if valid { r.copysign(x[l]) } else { f64::NAN };
    }
    out
}

/// [`fast`]'s f64 angles in degrees (roll, pitch, heading in [0, 360) before `heading`'s
/// storage) of each lane, NaN where it gives none.
#[inline(always)]
fn fast_lanes(q: &[[f64; 4]; SIDE_BY_SIDE]) -> [[f64; SIDE_BY_SIDE]; 3] {
    let mut m = [[0.0; SIDE_BY_SIDE]; 5];
    for l in 0..SIDE_BY_SIDE {
        for (e, v) in matrix_entries(&q[l]).into_iter().enumerate() {
            m[e][l] = v;
        }
    }
    let [m00, m10, m20, m21, m22] = m;
    let pitch = asin_lanes(m20);
    let roll = atan2_lanes(m21, m22);
    let yaw = atan2_lanes(m10, m00);
    let mut out = [[0.0; SIDE_BY_SIDE]; 3];
    for l in 0..SIDE_BY_SIDE {
        // `rem_euclid_turn` of an atan2 in (−π, π] (NaN stays NaN).
        let y = if yaw[l] < 0.0 {
            yaw[l] + std::f64::consts::TAU
        } else {
            yaw[l]
        };
        out[0][l] = roll[l].to_degrees();
        out[1][l] = (-pitch[l]).to_degrees();
        out[2][l] = y.to_degrees();
    }
    out
}

/// [`certain_row`] of each lane's angles in degrees ([`fast_lanes`]'), side by side: the
/// f32 angles, and whether each lane's three are certain. A lane's heading the storage
/// would wrap (outside [0, 360)) is left uncertain, as are NaNs and zeros: those lanes
/// take [`euler_deg_f32`], which gives the libm route's angles either way.
#[inline(always)]
fn certain_lanes(
    angles: &[[f64; SIDE_BY_SIDE]; 3],
    heading: HeadingDeg,
) -> ([[f32; SIDE_BY_SIDE]; 3], [bool; SIDE_BY_SIDE]) {
    let mut out = [[0.0f32; SIDE_BY_SIDE]; 3];
    let mut sure = [true; SIDE_BY_SIDE];
    for (a, (zs, out)) in angles.iter().zip(&mut out).enumerate() {
        let wraps = a == 2 && heading == HeadingDeg::Wrapped;
        for l in 0..SIDE_BY_SIDE {
            let z = zs[l];
            let e = z.abs() * MARGIN;
            let (lo, hi) = (z - e, z + e);
            // `Wrapped` leaves [0, 360) as it is.
            let kept = !wraps || (lo >= 0.0 && hi < 360.0);
            let (lo, hi) = (lo as f32, hi as f32);
            sure[l] &= kept && lo.to_bits() == hi.to_bits() && z.abs() > 1e-30;
            out[l] = lo;
        }
    }
    (out, sure)
}

/// The certainty step on one attitude's angles in degrees (roll, pitch, heading in
/// [0, 360) before `heading`'s storage; [`fast`]'s, [`fast_lanes`]'), None when an angle
/// is not a number or not certain.
#[inline(always)]
fn certain_row([roll, pitch, yaw]: [f64; 3], heading: HeadingDeg) -> Option<[f32; 3]> {
    if roll.is_nan() || pitch.is_nan() || yaw.is_nan() {
        return None;
    }
    Some([
        certain(roll, |d| d)?,
        certain(pitch, |d| d)?,
        certain(yaw, |d| heading.apply(d))?,
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The libm route: [`euler_of`]'s angles in degrees, through `heading`, as f32.
    fn reference(q: &[f64; 4], heading: HeadingDeg) -> [f32; 3] {
        let e = euler_of(q);
        [
            e.roll_rad.to_degrees() as f32,
            e.pitch_rad.to_degrees() as f32,
            heading.apply(e.heading_rad.to_degrees()) as f32,
        ]
    }

    /// A generator of uniform values in [0, 1) (SplitMix64).
    struct Uniform(u64);

    impl Uniform {
        fn next(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            (z >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// The table is libm's atan(k/32), within a unit of the last place.
    #[test]
    fn the_table_is_atan_of_k_over_32() {
        for (k, &a) in ATAN_K32.iter().enumerate() {
            let want = (k as f64 / 32.0).atan();
            assert!(
                (a - want).abs() <= f64::EPSILON * want,
                "k {k}: {a} vs {want}"
            );
        }
    }

    /// The series' atan2 and asin are within 8 units of the last place of libm's
    /// (relative) over every quadrant, ratios from 1e-9 to 1e9, and |x| up to 0.99 — far
    /// inside [`MARGIN`] (2^-40): the margin the f32's certainty rests on holds a
    /// thousandfold.
    #[test]
    fn the_series_are_within_a_few_units_of_libm() {
        let mut u = Uniform(7);
        let tol = 8.0 * f64::EPSILON;
        let mut worst: f64 = 0.0;
        for _ in 0..2_000_000 {
            let y = (u.next() - 0.5) * 10f64.powf(u.next() * 18.0 - 9.0);
            let x = (u.next() - 0.5) * 10f64.powf(u.next() * 18.0 - 9.0);
            let (fast, libm) = (atan2_fast(y, x).expect("finite"), y.atan2(x));
            worst = worst.max(((fast - libm) / libm).abs());
            let s = (u.next() * 2.0 - 1.0) * 0.99;
            let (fast, libm) = (asin_fast(s).expect("within"), s.asin());
            worst = worst.max(((fast - libm) / libm).abs());
        }
        assert!(worst < tol, "worst relative difference {worst:e}");
        // Outside their ranges: none.
        assert_eq!(atan2_fast(0.0, 1.0), None);
        assert_eq!(atan2_fast(1.0, -0.0), None);
        assert_eq!(atan2_fast(f64::NAN, 1.0), None);
        assert_eq!(atan2_fast(1.0, f64::INFINITY), None);
        assert_eq!(asin_fast(0.995), None);
        assert_eq!(asin_fast(0.0), None);
        assert_eq!(asin_fast(f64::NAN), None);
    }

    /// Attitudes the fast route must leave to libm, or at an edge of it: level, north,
    /// gimbal lock both ways, a quarter turn, NaN, a tiny w.
    const DEGENERATE: [[f64; 4]; 8] = {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [h, 0.0, h, 0.0],
            [h, 0.0, -h, 0.0],
            [0.5, 0.5, 0.5, 0.5],
            [h, h, 0.0, 0.0],
            [f64::NAN, 0.0, 0.0, 0.0],
            [1e-300, 1.0, 0.0, 1e-300],
        ]
    };

    /// A random attitude (w, x, y, z): a vehicle's (roll and pitch within 20°, any
    /// heading), or any (uniform over the unit quaternions' directions).
    fn attitude(u: &mut Uniform, vehicle: bool) -> [f64; 4] {
        if vehicle {
            let e = crate::attitude::Euler {
                roll_rad: (u.next() - 0.5) * 0.7,
                pitch_rad: (u.next() - 0.5) * 0.7,
                heading_rad: u.next() * std::f64::consts::TAU,
            };
            let q = e.to_quat_b_to_n();
            [q.w, q.i, q.j, q.k]
        } else {
            let v = [u.next(), u.next(), u.next(), u.next()].map(|c| c - 0.5);
            let norm = v.iter().map(|c| c * c).sum::<f64>().sqrt();
            v.map(|c| c / norm)
        }
    }

    /// The f32 angles are the libm route's, bit for bit: random attitudes of every kind
    /// (a land vehicle's, and any), headings as stored in both ways, and the attitudes
    /// the fast route must leave to libm (level, north, gimbal lock, zeros, a NaN).
    #[test]
    fn the_angles_are_the_libm_routes_bit_for_bit() {
        let mut u = Uniform(11);
        // Attitudes left to libm: a vehicle's, any.
        let mut fell_back = [0usize; 2];
        let n = 2_000_000;
        for i in 0..n {
            let q = attitude(&mut u, i % 2 == 0);
            for heading in [HeadingDeg::AsIs, HeadingDeg::Wrapped] {
                let (got, want) = (euler_deg_f32(&q, heading), reference(&q, heading));
                assert_eq!(got.map(f32::to_bits), want.map(f32::to_bits), "{q:?}");
                fell_back[i % 2] += usize::from(fast(&q, heading).is_none());
            }
        }
        // A vehicle's: about one in 10 000 (three angles, each within 2^-40 of a rounding
        // boundary once in some 30 000 of its f32 steps); any: about two in 100 more
        // (pitches beyond asin's range, 82°, in one of 100 random attitudes, for each
        // heading's way).
        assert!(fell_back[0] < n / 1000, "{fell_back:?} of {n}");
        assert!(fell_back[1] < n * 3 / 100, "{fell_back:?} of {n}");
        for q in DEGENERATE {
            for heading in [HeadingDeg::AsIs, HeadingDeg::Wrapped] {
                let (got, want) = (euler_deg_f32(&q, heading), reference(&q, heading));
                assert_eq!(got.map(f32::to_bits), want.map(f32::to_bits), "{q:?}");
            }
        }
    }

    /// Attitudes side by side give each one's angles, bit for bit: vehicle-like and
    /// uniform ones, those left to libm among them (pitches beyond 82°, zeros, a NaN), in
    /// lists shorter than a block, about one and two blocks long (the last attitudes one
    /// at a time).
    #[test]
    fn attitudes_side_by_side_are_each_ones_bit_for_bit() {
        let mut u = Uniform(12);
        let mut q: Vec<[f64; 4]> = DEGENERATE.to_vec();
        q.extend([[0.0, 0.0, 0.0, 0.0], [f64::INFINITY, 0.0, 1.0, 0.0]]);
        for i in 0..400_000 {
            q.push(attitude(&mut u, i % 2 == 0));
        }
        let bits = |rows: &[[f32; 3]]| -> Vec<[u32; 3]> {
            rows.iter().map(|r| r.map(f32::to_bits)).collect()
        };
        for heading in [HeadingDeg::AsIs, HeadingDeg::Wrapped] {
            let one_by_one: Vec<[f32; 3]> = q.iter().map(|q| euler_deg_f32(q, heading)).collect();
            let mut side_by_side = vec![[0.0; 3]; q.len()];
            euler_deg_f32_into(&q, heading, &mut side_by_side);
            assert_eq!(bits(&side_by_side), bits(&one_by_one), "{heading:?}");
            // The portable build of the lanes too (on an AVX2 CPU the call above took
            // the vector build).
            let mut portable = vec![[0.0; 3]; q.len()];
            into_portable(&q, heading, &mut portable);
            assert_eq!(bits(&portable), bits(&one_by_one), "{heading:?}");
            for n in (0..=13).chain([31, 32, 33, 64, 70]) {
                for from in [0, 1, 3, 6] {
                    let part = &q[from..from + n];
                    let mut rows = vec![[0.0; 3]; n];
                    euler_deg_f32_into(part, heading, &mut rows);
                    assert_eq!(
                        bits(&rows),
                        bits(&one_by_one[from..from + n]),
                        "{n} from {from}"
                    );
                }
            }
        }
    }

    /// The lanes' certainty is the one at a time's, or leaves the lane to it: a lane is
    /// sure only where [`certain_row`] gives an f32, and then gives that f32; every angle
    /// `certain_row` refuses (NaN, zero, at a rounding boundary, at the heading's wrap)
    /// the lanes refuse too. Random angles and those edges, both ways of storing the
    /// heading.
    #[test]
    fn the_lanes_certainty_is_certain_rows() {
        let half = 1.0 + f64::from(f32::EPSILON) / 2.0;
        let edges = [
            0.0,
            -0.0,
            1e-31,
            f64::NAN,
            f64::INFINITY,
            half,
            -half,
            half + 1e-9,
            1.5,
            360.0 - 1e-14,
            360.0,
            359.9,
            -1e-14,
            400.0,
        ];
        let mut u = Uniform(13);
        // Each edge as every angle of a row, then as each angle beside others.
        let mut values: Vec<f64> = edges.iter().flat_map(|&e| [e; 3]).collect();
        values.extend(
            edges
                .iter()
                .flat_map(|&e| [e, 1.5, 2.5, 3.5, e, 4.5, 5.5, 6.5, e]),
        );
        while values.len() < 3 * SIDE_BY_SIDE * 200 {
            values.push((u.next() - 0.1) * 400.0);
            // Near an f32 rounding boundary of a random f32.
            let f = ((u.next() - 0.5) * 720.0) as f32;
            let up = f64::from(f32::from_bits(f.to_bits() + 1));
            values.push((f64::from(f) + up) / 2.0 + (u.next() - 0.5) * 1e-12 * up.abs());
        }
        for heading in [HeadingDeg::AsIs, HeadingDeg::Wrapped] {
            for block in values.chunks_exact(3 * SIDE_BY_SIDE) {
                let mut angles = [[0.0; SIDE_BY_SIDE]; 3];
                for (i, &v) in block.iter().enumerate() {
                    angles[i % 3][i / 3] = v;
                }
                let (got, sure) = certain_lanes(&angles, heading);
                for l in 0..SIDE_BY_SIDE {
                    let row = [angles[0][l], angles[1][l], angles[2][l]];
                    match certain_row(row, heading) {
                        Some(want) if sure[l] => assert_eq!(
                            [got[0][l], got[1][l], got[2][l]].map(f32::to_bits),
                            want.map(f32::to_bits),
                            "{row:?}"
                        ),
                        Some(_) => {}
                        None => assert!(!sure[l], "{row:?} {heading:?}"),
                    }
                }
            }
        }
    }

    /// An f32 is certain only when the margin's ends round alike: not at a rounding
    /// boundary, at the heading's wrap, or at zero.
    #[test]
    fn certainty_needs_the_margins_ends_to_round_alike() {
        assert_eq!(certain(1.5, |d| d), Some(1.5));
        // Half-way between two f32 (1 and 1 + 2^-23): either way within the margin.
        let half = 1.0 + f64::from(f32::EPSILON) / 2.0;
        assert_eq!(certain(half, |d| d), None);
        assert_eq!(certain(half + 1e-9, |d| d), Some(1.0 + f32::EPSILON));
        let wrap = |d: f64| rem_euclid_turn(d, 360.0);
        assert_eq!(certain(360.0 - 1e-14, wrap), None);
        assert_eq!(certain(359.9, wrap), Some(359.9));
        assert_eq!(certain(0.0, |d| d), None);
    }
}
