//! √(x² + y²) as glibc's `hypot` (2.35 on, built without FMA, as x86-64's libm is)
//! computes it, inline: the same f64 for every input, without the call.
//!
//! Kryt1 sums one `hypot` per epoch of every evaluation, and the pitch of each block's
//! attitude takes one: libm's call was 3 % of a disupt process's CPU. The algorithm is
//! glibc's `sysdeps/ieee754/dbl-64/e_hypot.c` (C. F. Borges, "An Improved Algorithm for
//! hypot(a, b)", 2019): IEEE arithmetic only (no FMA, which Rust never contracts to), so
//! its results are glibc's bit for bit, which the tests check against the platform's libm
//! where that is glibc 2.35 or later.

/// Inputs above this are scaled down first (2^511).
const LARGE: f64 = 6.703903964971299e153;
/// Inputs below this are scaled up first (2^-459).
const TINY: f64 = 6.717876107567089e-139;
/// The scale (2^-600).
const SCALE: f64 = 2.409919865102884e-181;
/// Below this fraction of the larger input, the smaller one only rounds (2^-54).
const EPS: f64 = 5.551115123125783e-17;

/// √(x² + y²), rounded as glibc's `hypot` rounds it.
#[inline]
pub fn hypot(x: f64, y: f64) -> f64 {
    if !x.is_finite() || !y.is_finite() {
        // An infinity wins over a NaN (no signalling NaN reaches here from arithmetic).
        if x.is_infinite() || y.is_infinite() {
            return f64::INFINITY;
        }
        return x + y;
    }
    let (x, y) = (x.abs(), y.abs());
    let (ax, ay) = if x < y { (y, x) } else { (x, y) };
    if ax > LARGE {
        if ay <= ax * EPS {
            return ax + ay;
        }
        return kernel(ax * SCALE, ay * SCALE) / SCALE;
    }
    if ay < TINY {
        if ax >= ay / EPS {
            return ax + ay;
        }
        return kernel(ax / SCALE, ay / SCALE) * SCALE;
    }
    if ay <= ax * EPS {
        return ax + ay;
    }
    kernel(ax, ay)
}

/// `sum` plus [`hypot`]`(x[i], y[i])` for each `i`, added in order: bit for bit the
/// scalar loop's sum. The pairs in the common range (neither huge nor tiny, nor one
/// negligible against the other) are computed without branches, so the compiler runs
/// them in vector lanes (the kernel's two cases both computed and one chosen, as
/// IEEE arithmetic gives each lane what the scalar code gives it); the others, when a
/// group has any, again one at a time.
///
/// # Panics
/// If `x` and `y` differ in length.
pub fn add_hypots(mut sum: f64, x: &[f64], y: &[f64]) -> f64 {
    assert_eq!(x.len(), y.len(), "add_hypots: as many x as y");
    const GROUP: usize = 64;
    let mut h = [0.0; GROUP];
    for (xs, ys) in x.chunks(GROUP).zip(y.chunks(GROUP)) {
        let mut unusual = false;
        for ((h, &x), &y) in h.iter_mut().zip(xs).zip(ys) {
            let (x, y) = (x.abs(), y.abs());
            let (ax, ay) = if x < y { (y, x) } else { (x, y) };
            // False for NaNs and infinities too.
            let common = ax <= LARGE && ay >= TINY && ay > ax * EPS;
            unusual |= !common;
            *h = kernel_branchless(ax, ay);
        }
        let h = &mut h[..xs.len()];
        if unusual {
            for ((h, &x), &y) in h.iter_mut().zip(xs).zip(ys) {
                *h = hypot(x, y);
            }
        }
        for &v in h.iter() {
            sum += v;
        }
    }
    sum
}

/// [`kernel`] with both of its cases computed and one chosen (the same f64).
#[inline(always)]
fn kernel_branchless(ax: f64, ay: f64) -> f64 {
    let h = (ax * ax + ay * ay).sqrt();
    let near = h <= 2.0 * ay;
    let (delta_near, delta_far) = (h - ay, h - ax);
    let t1_near = ax * (2.0 * delta_near - ax);
    let t2_near = (delta_near - 2.0 * (ax - ay)) * delta_near;
    let t1_far = 2.0 * delta_far * (ax - 2.0 * ay);
    let t2_far = (4.0 * delta_far - ay) * ay + delta_far * delta_far;
    let (t1, t2) = if near {
        (t1_near, t2_near)
    } else {
        (t1_far, t2_far)
    };
    h - (t1 + t2) / (2.0 * h)
}

/// Borges' correction of √(ax² + ay²), for ax ≥ ay ≥ 0 whose squares neither overflow nor
/// underflow.
#[inline]
fn kernel(ax: f64, ay: f64) -> f64 {
    let h = (ax * ax + ay * ay).sqrt();
    let (t1, t2) = if h <= 2.0 * ay {
        let delta = h - ay;
        (ax * (2.0 * delta - ax), (delta - 2.0 * (ax - ay)) * delta)
    } else {
        let delta = h - ax;
        (
            2.0 * delta * (ax - 2.0 * ay),
            (4.0 * delta - ay) * ay + delta * delta,
        )
    };
    h - (t1 + t2) / (2.0 * h)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn the_constants_are_glibcs_powers_of_two() {
        assert_eq!(LARGE, 2f64.powi(511));
        assert_eq!(TINY, 2f64.powi(-459));
        assert_eq!(SCALE, 2f64.powi(-600));
        assert_eq!(EPS, 2f64.powi(-54));
    }

    #[test]
    fn special_values() {
        assert_eq!(hypot(3.0, 4.0), 5.0);
        assert_eq!(hypot(-3.0, 4.0), 5.0);
        assert_eq!(hypot(0.0, -0.0).to_bits(), 0);
        assert_eq!(hypot(f64::NEG_INFINITY, f64::NAN), f64::INFINITY);
        assert_eq!(hypot(f64::NAN, f64::INFINITY), f64::INFINITY);
        assert!(hypot(f64::NAN, 1.0).is_nan());
        assert_eq!(hypot(f64::MAX, f64::MAX), f64::INFINITY);
        assert_eq!(hypot(f64::MIN_POSITIVE / 4.0, 0.0), f64::MIN_POSITIVE / 4.0);
    }

    /// Whether this process's libm is glibc 2.35 or later (whose `hypot` this is).
    fn glibc_hypot() -> bool {
        #[cfg(all(target_os = "linux", target_env = "gnu", target_arch = "x86_64"))]
        {
            #[allow(unsafe_code)]
            // SAFETY: gnu_get_libc_version takes nothing and returns a pointer to a static
            // NUL-terminated string (gnu_get_libc_version(3)).
            let version = unsafe { std::ffi::CStr::from_ptr(libc::gnu_get_libc_version()) };
            let mut parts = version.to_str().unwrap_or("").split('.');
            let number = |p: Option<&str>| p.and_then(|s| s.parse::<u32>().ok()).unwrap_or(0);
            let (major, minor) = (number(parts.next()), number(parts.next()));
            (major, minor) >= (2, 35)
        }
        #[cfg(not(all(target_os = "linux", target_env = "gnu", target_arch = "x86_64")))]
        {
            false
        }
    }

    /// Pairs from every part of the range: both magnitudes drawn over all exponents, near
    /// each other (h near 2·ay, the kernel's branch), far apart (the EPS cut-offs), and
    /// the small angles Kryt1 sums.
    fn pairs(n: usize) -> Vec<(f64, f64)> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2035);
        let any = |rng: &mut rand_chacha::ChaCha8Rng| {
            let bits: u64 = rng.random::<u64>() & !(0x7ffu64 << 52);
            let exponent = rng.random_range(0u64..0x7ff);
            f64::from_bits(bits | (exponent << 52))
        };
        (0..n)
            .map(|k| {
                let x = any(&mut rng);
                let y = match k % 5 {
                    0 => any(&mut rng),
                    1 => x * rng.random_range(0.5..2.0),
                    2 => x * rng.random_range(0.99..1.01) * 0.5,
                    3 => x * 2f64.powi(-rng.random_range(20..60)),
                    _ => {
                        let a = rng.random_range(-1e-2..1e-2);
                        return (a, rng.random_range(-1e-2..1e-2));
                    }
                };
                (x, if rng.random_bool(0.5) { -y } else { y })
            })
            .collect()
    }

    #[test]
    fn sums_in_groups_are_the_scalar_loops() {
        // The pairs of every kind, in runs of usual ones and mixed, over several groups
        // and a short last one.
        let pairs = pairs(64 * 37 + 13);
        let (x, y): (Vec<f64>, Vec<f64>) = pairs.iter().copied().unzip();
        for n in [0, 1, 63, 64, 65, 64 * 37 + 13] {
            let scalar = x[..n]
                .iter()
                .zip(&y[..n])
                .fold(0.5, |sum, (&x, &y)| sum + hypot(x, y));
            let grouped = add_hypots(0.5, &x[..n], &y[..n]);
            assert!(
                scalar.to_bits() == grouped.to_bits() || (scalar.is_nan() && grouped.is_nan()),
                "{n} pairs: {scalar:e} against {grouped:e}"
            );
        }
        // Small angles only (Kryt1's filtered differences): every group in lanes.
        let small: Vec<(f64, f64)> = pairs.iter().filter(|p| p.0.abs() < 0.1).copied().collect();
        let (x, y): (Vec<f64>, Vec<f64>) = small.into_iter().unzip();
        let scalar = x
            .iter()
            .zip(&y)
            .fold(0.0, |sum, (&x, &y)| sum + hypot(x, y));
        assert_eq!(add_hypots(0.0, &x, &y).to_bits(), scalar.to_bits());
        for (&x, &y) in x.iter().zip(&y).take(2000) {
            let (ax, ay) = (x.abs().max(y.abs()), x.abs().min(y.abs()));
            if ay > ax * EPS && ay >= TINY {
                assert_eq!(
                    kernel_branchless(ax, ay).to_bits(),
                    kernel(ax, ay).to_bits()
                );
            }
        }
    }

    #[test]
    fn every_result_is_libms_bit_for_bit() {
        if !glibc_hypot() {
            eprintln!("libm is not glibc 2.35 or later: nothing to compare with");
            return;
        }
        let differ: Vec<(f64, f64)> = pairs(4_000_000)
            .into_iter()
            .filter(|&(x, y)| {
                let (ours, libm) = (hypot(x, y), x.hypot(y));
                ours.to_bits() != libm.to_bits() && !(ours.is_nan() && libm.is_nan())
            })
            .collect();
        assert!(
            differ.is_empty(),
            "{} pairs differ, the first {:?}",
            differ.len(),
            &differ[..differ.len().min(5)]
        );
    }
}
