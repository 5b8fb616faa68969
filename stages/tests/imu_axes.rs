//! The check of a log's IMU axes on simulated runs logged in each of the 24 right-angle
//! mountings.

mod common;

use std::sync::Arc;

use unz_stages::derive::Derived;
use unz_stages::earth;
use unz_stages::imu_axes::{AxesCheck, AxesVerdict, ImuAxes};
use unz_stages::simulate::SimConfig;

/// A 10-minute simulated run whose IMU logs in `axes`, derived as if they were the
/// body's, and its site's gravity.
fn logged_in(axes: ImuAxes) -> (Derived, f64) {
    let mut config = SimConfig::new("axes", 31);
    config.duration_s = 600.0;
    config.imu_axes = axes;
    let case = common::case_of(&config);
    let g = earth::normal_gravity_mps2(case.run.site.lat_rad, case.run.site.h_m);
    (case.derived, g)
}

/// Every right-angle mounting is found, by gravity (which way is down) and the
/// odometer's accelerations (which way is forward): the body's own axes agree, each of
/// the other 23 is named. The vehicle's axes are within 5° of down and of forward, with a
/// correlation above 0.8 (the threshold is 0.5).
#[test]
fn each_mounting_is_found_by_gravity_and_the_odometer() {
    for axes in ImuAxes::all() {
        let (d, g) = logged_in(axes);
        let check = AxesCheck::of(&d);
        let verdict = check.verdict(g);
        if axes.is_frd() {
            assert_eq!(verdict, AxesVerdict::Agree, "{check:?}");
            assert!(check.tilt_deg < 3.0, "{check:?}");
            assert!(check.forward_turn_deg.abs() < 5.0, "{check:?}");
            assert!(check.forward_correlation > 0.8, "{check:?}");
        } else {
            assert_eq!(
                verdict,
                AxesVerdict::Other {
                    found: axes,
                    forward_shown: true
                },
                "{axes}: {check:?}"
            );
        }
    }
}

/// What the check cannot judge, or finds wrong beyond a right angle: a short log, units
/// other than m/s, radians and metres, an IMU rolled 45°, a log without odometer.
#[test]
fn a_short_log_units_a_tilt_and_a_log_without_odometer() {
    let (d, g) = logged_in(ImuAxes::FRD);
    let with = |f: &dyn Fn(&mut Derived)| {
        let mut d = d.clone();
        f(&mut d);
        AxesCheck::of(&d).verdict(g)
    };
    // Increments in g·s, not m/s.
    let in_g = |d: &mut Derived| {
        d.dvel_mps = Arc::new(d.dvel_mps.iter().map(|v| v.map(|x| x / g)).collect());
    };
    assert_eq!(with(&in_g), AxesVerdict::NotGravity);
    // The IMU rolled 45° on the vehicle: no right angle names it.
    let rolled = |d: &mut Derived| {
        let (s, c) = 45f64.to_radians().sin_cos();
        let roll = |v: &[f64; 3]| [v[0], c * v[1] + s * v[2], -s * v[1] + c * v[2]];
        d.dvel_mps = Arc::new(d.dvel_mps.iter().map(roll).collect());
        d.dtheta_rad = Arc::new(d.dtheta_rad.iter().map(roll).collect());
    };
    assert_eq!(with(&rolled), AxesVerdict::Tilted);
    // The first 50 s: too short to judge.
    let short = |d: &mut Derived| {
        let n = (50.0 / d.nominal_dt_s) as usize;
        d.dt_s = Arc::new(d.dt_s[..n].to_vec());
    };
    assert_eq!(with(&short), AxesVerdict::TooShort);

    // The odometer's distance in other units than metres (a speed file in km/h, a pulse
    // scale twice the true one): both gains fall by the factor. The gyros' increments in
    // degrees: the gain across falls by 57.3 while along stays 1.
    let check = AxesCheck::of(&d);
    for fit in [check.along, check.across] {
        assert!((0.95..=1.05).contains(&fit.gain), "{check:?}");
    }
    for factor in [3.6, 2.0, 1.0 / 1.6] {
        let scaled = |d: &mut Derived| d.odo_dist_m.iter_mut().for_each(|x| *x *= factor);
        assert_eq!(with(&scaled), AxesVerdict::OdometerScale, "×{factor}");
    }
    let near = |d: &mut Derived| d.odo_dist_m.iter_mut().for_each(|x| *x *= 1.2);
    assert_eq!(
        with(&near),
        AxesVerdict::Agree,
        "an odometer 20 % off is the fit's scale"
    );
    let degrees = |d: &mut Derived| {
        d.dtheta_rad = Arc::new(
            d.dtheta_rad
                .iter()
                .map(|v| v.map(f64::to_degrees))
                .collect(),
        );
    };
    assert_eq!(with(&degrees), AxesVerdict::GyroScale);

    // Without the odometer's distance, gravity still finds an upside-down IMU, but not
    // which way is forward; an IMU turned about the vertical alone is not seen.
    let no_odometer = |d: &mut Derived| d.odo_dist_m.iter_mut().for_each(|x| *x = 0.0);
    let flu: ImuAxes = "FLU".parse().unwrap();
    let (d_flu, _) = logged_in(flu);
    let mut d = d_flu.clone();
    no_odometer(&mut d);
    assert_eq!(
        AxesCheck::of(&d).verdict(g),
        AxesVerdict::Other {
            found: flu,
            forward_shown: false
        }
    );
    let (d_lfd, _) = logged_in("LFD".parse().unwrap());
    let mut d = d_lfd.clone();
    no_odometer(&mut d);
    assert_eq!(AxesCheck::of(&d).verdict(g), AxesVerdict::Agree);
}
