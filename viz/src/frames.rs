//! Attitude in the frames the viewers expect.

use nalgebra::{Matrix3, Rotation3, UnitQuaternion};
use unz_stages::attitude::Euler;

/// Body forward-right-down relative to north-east-down (`C_b^n`, the attitude convention
/// of [`unz_stages::attitude`]) → body forward-left-up relative to local east-north-up,
/// the frames Rerun's and Foxglove's 3D views expect.
pub fn enu_flu(c_b_n: &UnitQuaternion<f64>) -> UnitQuaternion<f64> {
    let ned_to_enu = Matrix3::new(0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0);
    let flu_to_frd = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0);
    let c = ned_to_enu * c_b_n.to_rotation_matrix().into_inner() * flu_to_frd;
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(c))
}

/// [`enu_flu`] of the attitude `e`, as `[x, y, z, w]` in single precision (Rerun's
/// layout, at the edge only).
pub fn enu_flu_xyzw(e: Euler) -> [f32; 4] {
    let q = enu_flu(&e.to_quat_b_to_n());
    [q.i as f32, q.j as f32, q.k as f32, q.w as f32]
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use std::f64::consts::FRAC_PI_2;

    fn enu_flu_of(roll_rad: f64, pitch_rad: f64, heading_rad: f64) -> UnitQuaternion<f64> {
        enu_flu(
            &Euler {
                roll_rad,
                pitch_rad,
                heading_rad,
            }
            .to_quat_b_to_n(),
        )
    }

    #[test]
    fn heading_east_faces_enu_x_and_north_faces_enu_y() {
        let q = enu_flu_of(0.0, 0.0, FRAC_PI_2);
        assert!((q * Vector3::x() - Vector3::x()).norm() < 1e-12);
        let q = enu_flu_of(0.0, 0.0, 0.0);
        assert!((q * Vector3::x() - Vector3::y()).norm() < 1e-12);
        assert!((q * Vector3::z() - Vector3::z()).norm() < 1e-12);
    }

    #[test]
    fn nose_up_pitch_raises_forward_and_right_roll_lowers_left() {
        let q = enu_flu_of(0.0, 0.1, 0.0);
        assert!(((q * Vector3::x()).z - 0.1f64.sin()).abs() < 1e-12);
        // Roll right (positive): the left side (FLU +y) goes up.
        let q = enu_flu_of(0.1, 0.0, 0.0);
        assert!(((q * Vector3::y()).z - 0.1f64.sin()).abs() < 1e-12);
    }
}
