//! A control point's or the site's coordinates written in another way than the manifest
//! reads them: latitude and longitude swapped, a sign lost (west or south written
//! positive), radians or degrees and minutes written as degrees. A point so written lies
//! hundreds or thousands of kilometres from the start, and the run fails on it (no
//! setting DISUPT moves reaches it); the failure names the reading that, undone, would
//! bring the point within the odometer's reach, so the user mends the right field.

use unz_formats::manifest::RunManifest;
use unz_stages::criteria::ControlPointFix;
use unz_stages::earth::Geodetic;

/// A way of writing coordinates (latitude, longitude in degrees) that the manifest read
/// as decimal degrees, and the coordinates meant (`None`: no such reading of them).
type Reading = fn([f64; 2]) -> Option<[f64; 2]>;

/// The readings tried, each named as the message says it.
const READINGS: [(&str, Reading); 5] = [
    ("latitude and longitude swapped", |[lat, lon]| {
        Some([lon, lat])
    }),
    (
        "longitude's sign reversed (west is negative)",
        |[lat, lon]| Some([lat, -lon]),
    ),
    (
        "latitude's sign reversed (south is negative)",
        |[lat, lon]| Some([-lat, lon]),
    ),
    ("coordinates in radians, not degrees", |[lat, lon]| {
        Some([lat.to_degrees(), lon.to_degrees()])
    }),
    (
        "coordinates in degrees and minutes (DD.MMmm), not decimal degrees",
        |[lat, lon]| Some([minutes_read(lat)?, minutes_read(lon)?]),
    ),
];

/// Decimal degrees meant by `dd_mm` written as degrees and minutes (44.1423 for
/// 44° 14.23'); `None` when its minutes pass 60.
fn minutes_read(dd_mm: f64) -> Option<f64> {
    let degrees = dd_mm.trunc();
    let minutes = (dd_mm - degrees).abs() * 100.0;
    (minutes < 60.0).then(|| degrees + dd_mm.signum() * minutes / 60.0)
}

/// The first reading of the point `f`'s coordinates, or else of the site's, that brings
/// the point within `reach_m` of the start: "its latitude and longitude swapped? (read
/// so, it lies 505 m from the start)"; the site's first when `site_first` (every point
/// out of reach: one site misread, not each point alike). `None` when none does.
pub fn misreading_that_reaches(
    m: &RunManifest,
    f: &ControlPointFix,
    reach_m: f64,
    site_first: bool,
) -> Option<String> {
    let point = [f.lat_rad.to_degrees(), f.lon_rad.to_degrees()];
    let site = [m.site.latitude_deg, m.site.longitude_deg];
    let away_m = |[site_lat, site_lon]: [f64; 2], [lat, lon]: [f64; 2]| {
        if site_lat.abs() > 90.0 || lat.abs() > 90.0 {
            return f64::INFINITY;
        }
        let start = Geodetic::from_deg(site_lat, site_lon, m.site.height_m);
        let (north_m, east_m) = start.offset_m(lat.to_radians(), lon.to_radians());
        north_m.hypot(east_m)
    };
    READINGS.iter().find_map(|(what, read)| {
        let said = |whose: &str, away_m: f64| {
            format!("{whose} {what}? (read so, it lies {away_m:.0} m from the start)")
        };
        // A reading is a gross one (it moves the coordinates more than twice the
        // reach): a point merely out of reach near the equator or Greenwich is no sign
        // lost.
        let gross = |from: [f64; 2], to: [f64; 2]| away_m(from, to) > 2.0 * reach_m;
        let of_point = (read(point).filter(|&p| gross(point, p))).map(|p| away_m(site, p));
        let of_site = (read(site).filter(|&s| gross(site, s))).map(|s| away_m(s, point));
        let mut tried = [("its", of_point), ("the site's", of_site)];
        if site_first {
            tried.reverse();
        }
        (tried.into_iter())
            .find_map(|(whose, d)| d.filter(|&d| d <= reach_m).map(|d| said(whose, d)))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A point 176 m east of a site by Greenwich's meridian, out of a reach of 100 m: its
    /// longitude's sign reversed would bring it within (16 m), but moves it only 192 m:
    /// no misreading named. A point at 76° W written with its longitude positive is
    /// named so.
    #[test]
    fn only_a_gross_misreading_is_named() {
        let manifest = |lon_deg: f64| {
            let text = format!(
                "name = \"r\"\nraw = \"r.unz\"\nformat = \"unz-binary\"\n[site]\n\
                 latitude_deg = 44.0\nlongitude_deg = {lon_deg}\nheight_m = 0.0\n"
            );
            RunManifest::parse(&text, std::path::Path::new("run.toml")).unwrap()
        };
        let fix = |lat_deg: f64, lon_deg: f64| ControlPointFix {
            id: 1,
            sample: 0,
            t_s: 0.0,
            lat_rad: lat_deg.to_radians(),
            lon_rad: lon_deg.to_radians(),
            h_m: 0.0,
            mark_lever_arm_m: [0.0; 3],
        };
        // 0.001° of longitude at 44° N is 80 m.
        let near = fix(44.0, 0.0012);
        assert_eq!(
            misreading_that_reaches(&manifest(-0.001), &near, 100.0, false),
            None
        );
        let west = fix(44.0, 76.0);
        let named = misreading_that_reaches(&manifest(-76.0), &west, 100.0, false).unwrap();
        assert!(
            named.starts_with("its longitude's sign reversed"),
            "{named}"
        );
    }

    /// Degrees and minutes read back: 44.1423 is 44° 14.23', -76.2800 is -76° 28'; a
    /// value whose "minutes" pass 60 is no such reading.
    #[test]
    fn degrees_and_minutes_are_read_back() {
        assert!((minutes_read(44.1423).unwrap() - (44.0 + 14.23 / 60.0)).abs() < 1e-9);
        assert!((minutes_read(-76.28).unwrap() + (76.0 + 28.0 / 60.0)).abs() < 1e-9);
        assert_eq!(minutes_read(44.75), None);
    }
}
