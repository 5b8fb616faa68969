//! Attitude conventions: body FRD relative to NED, Euler order yaw-pitch-roll (3-2-1),
//! heading clockwise from true north, pitch nose up, roll right wing down.
//! `C_b^n` (body to navigation) is a `Rotation3`; quaternions are `UnitQuaternion`.

use nalgebra::{Quaternion, Rotation3, UnitQuaternion, Vector3};

/// Euler angles (3-2-1), rad.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Euler {
    /// Roll Φ, rad.
    pub roll_rad: f64,
    /// Pitch Θ, rad.
    pub pitch_rad: f64,
    /// Heading ψ, rad.
    pub heading_rad: f64,
}

impl Euler {
    /// `C_b^n` of these angles.
    pub fn to_quat_b_to_n(self) -> UnitQuaternion<f64> {
        UnitQuaternion::from_euler_angles(self.roll_rad, self.pitch_rad, self.heading_rad)
    }

    /// The angles of `q` (= `C_b^n`), heading in [0, 2π).
    pub fn from_quat_b_to_n(q: &UnitQuaternion<f64>) -> Self {
        let (roll_rad, pitch_rad, heading_rad) = q.euler_angles();
        Self {
            roll_rad,
            pitch_rad,
            heading_rad: rem_euclid_turn(heading_rad, std::f64::consts::TAU),
        }
    }

    /// Body angular rate relative to NED, in body axes, from the Euler angle rates.
    pub fn body_rate_from_euler_rates(
        self,
        roll_rate: f64,
        pitch_rate: f64,
        heading_rate: f64,
    ) -> Vector3<f64> {
        let (sp, cp) = self.roll_rad.sin_cos();
        let (st, ct) = self.pitch_rad.sin_cos();
        Vector3::new(
            roll_rate - heading_rate * st,
            pitch_rate * cp + heading_rate * sp * ct,
            -pitch_rate * sp + heading_rate * cp * ct,
        )
    }
}

/// Below this squared rotation angle (a = 0.1 rad: 10 rad/s at 100 Hz) [`half_angle_series`]
/// is exact to machine precision.
pub const HALF_ANGLE_SERIES_LIMIT_RAD2: f64 = 1e-2;

/// sin(a/2)/a and cos(a/2) from a² by their series; below
/// [`HALF_ANGLE_SERIES_LIMIT_RAD2`] the first term left out is under 3e-20.
#[inline(always)]
pub fn half_angle_series(a2: f64) -> (f64, f64) {
    (
        0.5 + a2
            * (-1.0 / 48.0
                + a2 * (1.0 / 3840.0 + a2 * (-1.0 / 645_120.0 + a2 * (1.0 / 185_794_560.0)))),
        1.0 + a2
            * (-0.125 + a2 * (1.0 / 384.0 + a2 * (-1.0 / 46_080.0 + a2 * (1.0 / 10_321_920.0)))),
    )
}

/// sin(a/2)/a and cos(a/2) from a², for angles beyond the series: out of line and cold,
/// so that a hot loop keeps its registers.
#[cold]
#[inline(never)]
pub fn half_angle_exact(a2: f64) -> (f64, f64) {
    let a = a2.sqrt();
    ((0.5 * a).sin() / a, (0.5 * a).cos())
}

/// Rotation of a rotation vector `phi` (rad) as a unit quaternion, accurate to machine
/// precision.
#[inline]
pub fn quat_from_rotation_vector(phi: &Vector3<f64>) -> UnitQuaternion<f64> {
    let a2 = phi.norm_squared();
    let (s, c) = if a2 < HALF_ANGLE_SERIES_LIMIT_RAD2 {
        half_angle_series(a2)
    } else {
        half_angle_exact(a2)
    };
    UnitQuaternion::new_unchecked(Quaternion::new(c, s * phi.x, s * phi.y, s * phi.z))
}

/// `a.rem_euclid(m)` (`m` > 0), bit for bit, without the floating-point remainder (costly)
/// when `a` lies within one `m` of zero, where it is `a` or `a + m`: angles per row and per
/// epoch are.
#[inline]
pub fn rem_euclid_turn(a: f64, m: f64) -> f64 {
    if (0.0..m).contains(&a) {
        a
    } else if a < 0.0 && a > -m {
        a + m
    } else {
        a.rem_euclid(m)
    }
}

/// Smallest signed difference of two angles, rad, in (−π, π].
pub fn wrap_pi(a: f64) -> f64 {
    let w = rem_euclid_turn(a + std::f64::consts::PI, std::f64::consts::TAU) - std::f64::consts::PI;
    if w == -std::f64::consts::PI {
        std::f64::consts::PI
    } else {
        w
    }
}

/// Rotation matrix of `q`.
pub fn dcm(q: &UnitQuaternion<f64>) -> Rotation3<f64> {
    q.to_rotation_matrix()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_remainder_within_a_turn_is_rem_euclids_bit_for_bit() {
        use std::f64::consts::{PI, TAU};
        for a in [
            0.0,
            -0.0,
            1e-300,
            -1e-300,
            -1e-17,
            PI,
            -PI,
            TAU,
            -TAU,
            TAU - 1e-15,
            -TAU + 1e-15,
            7.0,
            -7.0,
            1e6,
            f64::NAN,
            f64::INFINITY,
        ] {
            for m in [TAU, 360.0] {
                let (got, want) = (rem_euclid_turn(a, m), a.rem_euclid(m));
                assert!(
                    got.to_bits() == want.to_bits(),
                    "{a} mod {m}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn euler_round_trip_and_conventions() {
        let e = Euler {
            roll_rad: 0.1,
            pitch_rad: -0.2,
            heading_rad: 4.0,
        };
        let q = e.to_quat_b_to_n();
        let back = Euler::from_quat_b_to_n(&q);
        assert!((back.roll_rad - 0.1).abs() < 1e-12 && (back.pitch_rad + 0.2).abs() < 1e-12);
        assert!((back.heading_rad - 4.0).abs() < 1e-12);
        // Heading 90° points body x east; pitch up points it up (negative down).
        let east = Euler {
            heading_rad: std::f64::consts::FRAC_PI_2,
            ..Default::default()
        }
        .to_quat_b_to_n();
        let x = east * Vector3::x();
        assert!((x - Vector3::y()).norm() < 1e-12);
        let up = Euler {
            pitch_rad: 0.3,
            ..Default::default()
        }
        .to_quat_b_to_n()
            * Vector3::x();
        assert!(up.z < 0.0);
        // Roll right wing down: body y points down.
        let rolled = Euler {
            roll_rad: 0.3,
            ..Default::default()
        }
        .to_quat_b_to_n()
            * Vector3::y();
        assert!(rolled.z > 0.0);
    }

    #[test]
    fn euler_rates_match_numerical_differentiation() {
        let e0 = Euler {
            roll_rad: 0.05,
            pitch_rad: 0.1,
            heading_rad: 1.0,
        };
        let rates = (0.01, -0.02, 0.3);
        let dt = 1e-6;
        let e1 = Euler {
            roll_rad: e0.roll_rad + rates.0 * dt,
            pitch_rad: e0.pitch_rad + rates.1 * dt,
            heading_rad: e0.heading_rad + rates.2 * dt,
        };
        // C(t+dt) = C(t) exp([w dt ×]): w = body rate relative to NED.
        let dq = e0.to_quat_b_to_n().inverse() * e1.to_quat_b_to_n();
        let w = dq.scaled_axis() / dt;
        let w_formula = e0.body_rate_from_euler_rates(rates.0, rates.1, rates.2);
        assert!((w - w_formula).norm() < 1e-6, "{w} vs {w_formula}");
    }

    #[test]
    fn rotation_vector_matches_nalgebra() {
        for phi in [
            Vector3::new(1e-5, -2e-5, 3e-6),
            Vector3::new(0.3, -0.2, 0.1),
            Vector3::zeros(),
        ] {
            let a = quat_from_rotation_vector(&phi);
            let b = UnitQuaternion::from_scaled_axis(phi);
            assert!(a.angle_to(&b) < 1e-15);
        }
    }
}
