//! Initial alignment over the static start: levelling from the accelerometers,
//! gyrocompassing (heading from the Earth rate) when no azimuth is given, and the
//! vertical gyro drift measured at rest.

use nalgebra::Vector3;

use crate::angle_increments::AngleSlice;
use crate::attitude::Euler;
use crate::earth;

/// Mean sensor outputs over the static start.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StaticMeans {
    /// Mean specific force, body, m/s².
    pub f_b_mps2: Vector3<f64>,
    /// Mean angular rate, body, rad/s.
    pub w_b_rad_s: Vector3<f64>,
    /// Length averaged, s.
    pub duration_s: f64,
}

/// Number of first samples whose intervals fit in `static_s` seconds: those
/// [`static_means`] averages (it reads no increment beyond them).
pub fn static_len(dt_s: &[f64], static_s: f64) -> usize {
    let mut t = 0.0;
    for (k, dt) in dt_s.iter().enumerate() {
        if t + dt > static_s + 1e-9 {
            return k;
        }
        t += dt;
    }
    dt_s.len()
}

/// Means of the first samples covering `static_s` seconds (`dt`-weighted). The
/// increments need only cover [`static_len`] samples.
pub fn static_means(
    dt_s: &[f64],
    dtheta_rad: AngleSlice<'_>,
    dvel_mps: &[[f64; 3]],
    static_s: f64,
) -> StaticMeans {
    let (mut th, mut dv, mut t) = (Vector3::zeros(), Vector3::zeros(), 0.0);
    for k in 0..static_len(dt_s, static_s) {
        th += Vector3::from(dtheta_rad.get(k));
        dv += Vector3::from(dvel_mps[k]);
        t += dt_s[k];
    }
    let inv = if t > 0.0 { 1.0 / t } else { 0.0 };
    StaticMeans {
        f_b_mps2: dv * inv,
        w_b_rad_s: th * inv,
        duration_s: t,
    }
}

/// Roll and pitch of a body at rest from its mean specific force.
pub fn level(f_b: &Vector3<f64>) -> (f64, f64) {
    let pitch = f_b.x.atan2((f_b.y * f_b.y + f_b.z * f_b.z).sqrt());
    let roll = (-f_b.y).atan2(-f_b.z);
    (roll, pitch)
}

/// Gyrocompass heading from the mean rate at rest (drift already removed), rad in [0, 2π).
pub fn gyrocompass(w_b: &Vector3<f64>, roll_rad: f64, pitch_rad: f64) -> f64 {
    let level_q = Euler {
        roll_rad,
        pitch_rad,
        heading_rad: 0.0,
    }
    .to_quat_b_to_n();
    let w_l = level_q * w_b;
    (-w_l.y).atan2(w_l.x).rem_euclid(std::f64::consts::TAU)
}

/// 1σ heading accuracy of a gyrocompass: horizontal drift uncertainty and angle random
/// walk over the static period, against the horizontal Earth rate, rad.
pub fn gyrocompass_sigma_rad(
    lat_rad: f64,
    drift_sigma_rad_s: f64,
    arw_rad_sqrt_s: f64,
    duration_s: f64,
) -> f64 {
    let noise = arw_rad_sqrt_s / duration_s.max(1e-9).sqrt();
    drift_sigma_rad_s.hypot(noise) / (earth::OMEGA_IE_RAD_S * lat_rad.cos())
}

/// Vertical (body z) drift measured at rest: the mean rate minus the Earth rate the body
/// should see with this attitude, rad/s.
pub fn drift_z_at_rest(w_b: &Vector3<f64>, attitude: Euler, lat_rad: f64) -> f64 {
    let expected_b = attitude.to_quat_b_to_n().inverse() * earth::earth_rate_ned(lat_rad);
    w_b.z - expected_b.z
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levelling_and_gyrocompass_invert_the_physics() {
        let lat = 0.9;
        let e = Euler {
            roll_rad: 0.02,
            pitch_rad: -0.015,
            heading_rad: 3.5,
        };
        let q = e.to_quat_b_to_n();
        let f_b = q.inverse() * Vector3::new(0.0, 0.0, -earth::normal_gravity_mps2(lat, 100.0));
        let w_earth_b = q.inverse() * earth::earth_rate_ned(lat);
        let w_b = w_earth_b + Vector3::new(0.0, 0.0, 1e-6);
        let (roll, pitch) = level(&f_b);
        assert!((roll - e.roll_rad).abs() < 1e-12 && (pitch - e.pitch_rad).abs() < 1e-12);
        // With the drift removed the Earth rate gives the heading exactly; a vertical drift
        // left in would leak through the tilt (0.02 rad × 1e-6 rad/s against 4.6e-5 rad/s).
        let heading = gyrocompass(&w_earth_b, roll, pitch);
        assert!((heading - 3.5).abs() < 1e-9, "{heading}");
        let dz = drift_z_at_rest(&w_b, e, lat);
        assert!((dz - 1e-6).abs() < 1e-12);
    }
}
