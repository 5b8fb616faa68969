//! WGS-84 Earth model: radii of curvature, Earth rate, transport rate, normal gravity.
//! All vectors here are in the local-level NED frame.

use nalgebra::Vector3;

/// WGS-84 semi-major axis, m.
pub const A_M: f64 = 6_378_137.0;
/// WGS-84 flattening.
pub const F: f64 = 1.0 / 298.257_223_563;
/// First eccentricity squared.
pub const E2: f64 = F * (2.0 - F);
/// Earth rotation rate, rad/s.
pub const OMEGA_IE_RAD_S: f64 = 7.292_115e-5;
/// Normal gravity at the equator, m/s².
const GAMMA_E: f64 = 9.780_325_335_9;
/// Somigliana's constant.
const K_SOMIGLIANA: f64 = 0.001_931_852_652_41;
/// m = ω²a²b/GM.
const M_GRAV: f64 = 0.003_449_786_506_84;

/// Meridian (north-south) radius of curvature at latitude `lat_rad`, m.
pub fn meridian_radius_m(lat_rad: f64) -> f64 {
    let s = lat_rad.sin();
    let w = 1.0 - E2 * s * s;
    A_M * (1.0 - E2) / (w * w.sqrt())
}

/// Prime-vertical (east-west) radius of curvature at latitude `lat_rad`, m.
pub fn prime_vertical_radius_m(lat_rad: f64) -> f64 {
    let s = lat_rad.sin();
    A_M / (1.0 - E2 * s * s).sqrt()
}

/// Both radii at once: (meridian, prime vertical), m.
pub fn radii_m(lat_rad: f64) -> (f64, f64) {
    let s = lat_rad.sin();
    let w = 1.0 - E2 * s * s;
    let rn = A_M / w.sqrt();
    (rn * (1.0 - E2) / w, rn)
}

/// Earth rate in NED at latitude `lat_rad`, rad/s.
pub fn earth_rate_ned(lat_rad: f64) -> Vector3<f64> {
    Vector3::new(
        OMEGA_IE_RAD_S * lat_rad.cos(),
        0.0,
        -OMEGA_IE_RAD_S * lat_rad.sin(),
    )
}

/// Transport rate (rotation of NED over the Earth) for NED velocity `v_ned_mps`, rad/s.
pub fn transport_rate_ned(lat_rad: f64, h_m: f64, v_ned_mps: &Vector3<f64>) -> Vector3<f64> {
    let (rm, rn) = radii_m(lat_rad);
    Vector3::new(
        v_ned_mps.y / (rn + h_m),
        -v_ned_mps.x / (rm + h_m),
        -v_ned_mps.y * lat_rad.tan() / (rn + h_m),
    )
}

/// Normal gravity magnitude (Somigliana, with the second-order height correction), m/s².
/// It includes the centrifugal acceleration and points along the ellipsoid normal (down).
pub fn normal_gravity_mps2(lat_rad: f64, h_m: f64) -> f64 {
    let s2 = lat_rad.sin().powi(2);
    let g0 = GAMMA_E * (1.0 + K_SOMIGLIANA * s2) / (1.0 - E2 * s2).sqrt();
    g0 * (1.0 - 2.0 / A_M * (1.0 + F + M_GRAV - 2.0 * F * s2) * h_m + 3.0 * h_m * h_m / (A_M * A_M))
}

/// A geodetic position (WGS-84): a run's start, the origin of its local north and east.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Geodetic {
    /// Latitude, rad.
    pub lat_rad: f64,
    /// Longitude, rad.
    pub lon_rad: f64,
    /// Height above the ellipsoid, m.
    pub h_m: f64,
}

impl Geodetic {
    /// The position at `lat_deg`, `lon_deg` (degrees) and `h_m`.
    pub fn from_deg(lat_deg: f64, lon_deg: f64, h_m: f64) -> Self {
        Self {
            lat_rad: lat_deg.to_radians(),
            lon_rad: lon_deg.to_radians(),
            h_m,
        }
    }

    /// North and east offsets (m) of `(lat_rad, lon_rad)` from this origin
    /// ([`local_offset_m`]).
    pub fn offset_m(&self, lat_rad: f64, lon_rad: f64) -> (f64, f64) {
        local_offset_m(lat_rad, lon_rad, self.lat_rad, self.lon_rad, self.h_m)
    }

    /// This origin's local frame, for many offsets from it: [`Self::offset_m`], bit for
    /// bit, with the radii and the cosine taken once.
    pub fn local_frame(&self) -> LocalFrame {
        let (rm, rn) = radii_m(self.lat_rad);
        LocalFrame {
            lat0_rad: self.lat_rad,
            lon0_rad: self.lon_rad,
            rm_h_m: rm + self.h_m,
            rn_h_m: rn + self.h_m,
            cos_lat0: self.lat_rad.cos(),
        }
    }
}

/// North and east offsets from an origin ([`Geodetic::local_frame`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalFrame {
    lat0_rad: f64,
    lon0_rad: f64,
    rm_h_m: f64,
    rn_h_m: f64,
    cos_lat0: f64,
}

impl LocalFrame {
    /// North and east offsets (m) of `(lat_rad, lon_rad)` from the origin
    /// ([`local_offset_m`]).
    #[inline]
    pub fn offset_m(&self, lat_rad: f64, lon_rad: f64) -> (f64, f64) {
        (
            (lat_rad - self.lat0_rad) * self.rm_h_m,
            wrapped_dlon(lon_rad, self.lon0_rad) * self.rn_h_m * self.cos_lat0,
        )
    }
}

/// `lon − lon0` in [−π, π): `(lon − lon0 + π) mod 2π − π`
/// ([`crate::attitude::rem_euclid_turn`]: the remainder taken only when needed).
#[inline]
fn wrapped_dlon(lon_rad: f64, lon0_rad: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    crate::attitude::rem_euclid_turn(lon_rad - lon0_rad + PI, TAU) - PI
}

/// North and east offsets (m) of `(lat, lon)` from a reference, scaled by the WGS-84
/// meridian and prime-vertical radii at the reference (the paper's ΔX, ΔY).
pub fn local_offset_m(
    lat_rad: f64,
    lon_rad: f64,
    lat0_rad: f64,
    lon0_rad: f64,
    h0_m: f64,
) -> (f64, f64) {
    Geodetic {
        lat_rad: lat0_rad,
        lon_rad: lon0_rad,
        h_m: h0_m,
    }
    .local_frame()
    .offset_m(lat_rad, lon_rad)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_local_frame_gives_the_offsets_bit_for_bit() {
        let origin = Geodetic {
            lat_rad: 0.78,
            lon_rad: 3.1,
            h_m: 93.0,
        };
        let frame = origin.local_frame();
        for (lat, lon) in [
            (0.78, 3.1),
            (0.7801, 3.1002),
            (0.77, -3.0),
            (0.79, 3.2),
            (-0.5, 10.0),
            (0.78, 3.1 - std::f64::consts::PI),
        ] {
            let (a, b) = (origin.offset_m(lat, lon), frame.offset_m(lat, lon));
            assert_eq!(a.0.to_bits(), b.0.to_bits(), "{lat} {lon}");
            assert_eq!(a.1.to_bits(), b.1.to_bits(), "{lat} {lon}");
            // And the remainder, taken always, as before.
            let dlon = (lon - origin.lon_rad + std::f64::consts::PI)
                .rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            assert_eq!(wrapped_dlon(lon, origin.lon_rad).to_bits(), dlon.to_bits());
        }
    }

    #[test]
    fn normal_gravity_matches_published_values() {
        // WGS-84 (NIMA TR8350.2) normal gravity at the equator and at the pole.
        assert!((normal_gravity_mps2(0.0, 0.0) - 9.780_325_335_9).abs() < 1e-9);
        assert!(
            (normal_gravity_mps2(std::f64::consts::FRAC_PI_2, 0.0) - 9.832_184_937_8).abs() < 1e-7
        );
        // Free-air gradient ≈ 3.086e-6 s⁻².
        let grad = (normal_gravity_mps2(0.8, 0.0) - normal_gravity_mps2(0.8, 1000.0)) / 1000.0;
        assert!((grad - 3.086e-6).abs() < 1e-8, "{grad}");
    }

    #[test]
    fn radii_match_the_ellipsoid() {
        assert!((meridian_radius_m(0.0) - 6_335_439.327).abs() < 1e-2);
        assert!(
            (prime_vertical_radius_m(std::f64::consts::FRAC_PI_2) - 6_399_593.626).abs() < 1e-2
        );
        let (rm, rn) = radii_m(0.7);
        assert!(
            (rm - meridian_radius_m(0.7)).abs() < 1e-6
                && (rn - prime_vertical_radius_m(0.7)).abs() < 1e-6
        );
    }
}
