//! Navigation and criteria against simulated truth (issue 3's accuracy cases).

mod common;

use common::case;
use rayon::prelude::*;
use unz_stages::attitude::wrap_pi;
use unz_stages::earth;
use unz_stages::simulate::SensorErrors;
use unz_stages::strapdown::NavSettings;
use unz_stages::units::DEG_PER_H;

#[test]
fn true_settings_without_noise_reproduce_truth() {
    for (label, errors) in [
        (
            "biases on",
            SensorErrors {
                noise: false,
                ..SensorErrors::ALL
            },
        ),
        (
            "biases off",
            SensorErrors {
                noise: false,
                accel_bias: false,
                ..SensorErrors::ALL
            },
        ),
    ] {
        let c = case(31, errors);
        let track = c.nav(&c.true_settings());
        let [roll, pitch, heading] = c.attitude_errors_deg(&track);
        let b = c.run.settings.accel_bias_mps2;
        let g = earth::normal_gravity_mps2(c.run.site.lat_rad, c.run.site.h_m);
        // Levelling leaves a tilt of |b_horizontal|/g, which turns move between roll and
        // pitch; biases off, only quantisation and the filter-free levelling remain.
        let tilt_deg = (b[0].hypot(b[1]) / g).to_degrees();
        let bound = if errors.accel_bias {
            tilt_deg + 0.002
        } else {
            0.005
        };
        let stop = c.final_error_m(&track);
        eprintln!(
            "{label}: max errors roll {roll:.4}°, pitch {pitch:.4}°, heading {heading:.4}° (tilt bound {bound:.4}°); final stop {stop:.2} m"
        );
        assert!(heading < 0.01, "{label}: heading {heading}");
        assert!(
            roll < bound && pitch < bound,
            "{label}: roll {roll}, pitch {pitch}, bound {bound}"
        );
        assert!(stop < 2.0, "{label}: final stop error {stop} m");
    }
}

#[test]
fn the_manifest_azimuth_costs_hundreds_of_metres() {
    let c = case(32, SensorErrors::ALL);
    let mut s = c.true_settings();
    let good = c.final_error_m(&c.nav(&s));
    let az_err =
        wrap_pi((c.run.settings.manifest_azimuth_deg - c.run.settings.azimuth_deg).to_radians());
    s.initial.heading_rad = c.run.settings.manifest_azimuth_deg.to_radians();
    let bad = c.final_error_m(&c.nav(&s));
    // The error is the displacement turned by the azimuth error.
    let n = c.run.truth.lat_rad.len() - 1;
    let (dn, de) = earth::local_offset_m(
        c.run.truth.lat_rad[n],
        c.run.truth.lon_rad[n],
        c.run.site.lat_rad,
        c.run.site.lon_rad,
        c.run.site.h_m,
    );
    let predicted = 2.0 * (0.5 * az_err).sin().abs() * dn.hypot(de);
    eprintln!(
        "final stop: {good:.1} m with the true azimuth, {bad:.1} m with the manifest's ({:.2}° off; predicted {predicted:.1} m)",
        az_err.to_degrees()
    );
    assert!(good < 10.0);
    assert!(
        bad > 100.0 && (bad - predicted).abs() < 0.1 * predicted + 2.0 * good,
        "{bad} vs {predicted}"
    );
}

/// Argmin of `f` over `grid` (evaluated in parallel).
fn argmin(grid: &[f64], f: impl Fn(f64) -> f64 + Sync) -> (f64, Vec<f64>) {
    let values: Vec<f64> = grid.par_iter().map(|&x| f(x)).collect();
    let i = values
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .unwrap()
        .0;
    (grid[i], values)
}

fn grid(center: f64, half: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| center - half + 2.0 * half * i as f64 / (n - 1) as f64)
        .collect()
}

#[test]
fn criteria_are_smallest_near_the_true_settings() {
    let c = case(33, SensorErrors::ALL);
    let truth = c.true_settings();
    let with = |f: &dyn Fn(&mut NavSettings)| {
        let mut s = truth;
        f(&mut s);
        s
    };
    let az0 = truth.initial.heading_rad.to_degrees();
    // Azimuth by Kryt2 (the paper's Fig. 2): a 1 m residual over kilometres is ~0.05°.
    let (az_k2, _) = argmin(&grid(az0, 2.0, 81), |az| {
        c.final_error_m(&c.nav(&with(&|s| s.initial.heading_rad = az.to_radians())))
    });
    // Azimuth by Kryt1: seen only through the Earth-rate coupling Ω·cos(lat)·sin(δψ).
    let (az_k1, _) = argmin(&grid(az0, 12.0, 49), |az| {
        c.kryt1(&c.nav(&with(&|s| s.initial.heading_rad = az.to_radians())))
    });
    let d = truth.drift_rad_s;
    let (dz_k2, _) = argmin(&grid(d[2], 2.0 * DEG_PER_H, 41), |z| {
        c.final_error_m(&c.nav(&with(&|s| s.drift_rad_s[2] = z)))
    });
    let (dx_k1, _) = argmin(&grid(d[0], 3.0 * DEG_PER_H, 41), |x| {
        c.kryt1(&c.nav(&with(&|s| s.drift_rad_s[0] = x)))
    });
    let (dy_k1, _) = argmin(&grid(d[1], 3.0 * DEG_PER_H, 41), |y| {
        c.kryt1(&c.nav(&with(&|s| s.drift_rad_s[1] = y)))
    });
    eprintln!(
        "argmin - truth: azimuth by Kryt2 {:.3}°, by Kryt1 {:.2}°; driftz by Kryt2 {:.3} °/h; driftx by Kryt1 {:.3} °/h; drifty by Kryt1 {:.3} °/h",
        az_k2 - az0,
        az_k1 - az0,
        (dz_k2 - d[2]) / DEG_PER_H,
        (dx_k1 - d[0]) / DEG_PER_H,
        (dy_k1 - d[1]) / DEG_PER_H
    );
    // Tolerances: the floor left by gyro random walk. 0.07°/√h over 40 min wanders the
    // heading by ~0.057° (1σ), the same as a vertical drift of ~0.17 °/h: 3σ ≈ 0.5 °/h.
    assert!(
        (az_k2 - az0).abs() <= 0.15,
        "azimuth by Kryt2 off by {}",
        az_k2 - az0
    );
    assert!(
        (az_k1 - az0).abs() <= 3.0,
        "azimuth by Kryt1 off by {}",
        az_k1 - az0
    );
    assert!(
        (dz_k2 - d[2]).abs() <= 0.5 * DEG_PER_H,
        "driftz off by {} °/h",
        (dz_k2 - d[2]) / DEG_PER_H
    );
    assert!(
        (dx_k1 - d[0]).abs() <= 0.5 * DEG_PER_H,
        "driftx off by {} °/h",
        (dx_k1 - d[0]) / DEG_PER_H
    );
    assert!(
        (dy_k1 - d[1]).abs() <= 0.5 * DEG_PER_H,
        "drifty off by {} °/h",
        (dy_k1 - d[1]) / DEG_PER_H
    );
}

/// An odometer logged 0.3 s late resolves each increment with the heading of another
/// moment (metres per turn) and shifts u̇ against the accelerometers. derive's
/// `odo_time_offset_s` = −0.3 s undoes both: the route and the pitch residuals come back
/// to those of an odometer on time.
#[test]
fn the_odometer_time_offset_undoes_a_lagging_odometer() {
    use unz_stages::criteria::{Kryt1Scratch, epoch_attitude};
    use unz_stages::derive::DeriveParams;
    use unz_stages::simulate::SimConfig;

    let mut config = SimConfig::new("nav", 45);
    config.odo_lag_s = 0.3;
    let on_time = common::case_of(&SimConfig {
        odo_lag_s: 0.0,
        ..config.clone()
    });
    let lagging = common::case_of(&config);
    let corrected = common::case_derived_with(
        &config,
        &DeriveParams {
            odo_time_offset_s: -0.3,
            ..DeriveParams::default()
        },
    );
    assert_eq!(lagging.run.settings.odo_lag_s, 0.3);
    // Route error with the true settings, and the RMS pitch residual of the valid epochs.
    let measure = |c: &common::Case| {
        let track = c.nav(&c.true_settings());
        let (mut theta, mut phi) = (Vec::new(), Vec::new());
        let e = &c.derived.epochs;
        epoch_attitude(
            e,
            &c.lowpass(),
            &track,
            &mut Kryt1Scratch::default(),
            &mut theta,
            &mut phi,
        );
        let r: Vec<f64> = (0..e.block.len())
            .filter(|&k| e.valid[k])
            .map(|k| theta[k] - e.theta_p_rad[k])
            .collect();
        let rms = (r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64).sqrt();
        (c.max_route_error_m(&track), rms)
    };
    let (route_on_time, rms_on_time) = measure(&on_time);
    let (route_lagging, rms_lagging) = measure(&lagging);
    let (route_corrected, rms_corrected) = measure(&corrected);
    eprintln!(
        "route error / pitch residual RMS: on time {route_on_time:.1} m / {:.2} mrad, lagging {route_lagging:.1} m / {:.2} mrad, offset −0.3 s {route_corrected:.1} m / {:.2} mrad",
        rms_on_time * 1e3,
        rms_lagging * 1e3,
        rms_corrected * 1e3
    );
    assert!(route_lagging > 3.0 * route_on_time.max(1.0));
    assert!((route_corrected - route_on_time).abs() < 0.5);
    assert!(rms_lagging > 1.1 * rms_on_time);
    assert!((rms_corrected / rms_on_time - 1.0).abs() < 0.05);
}

/// A unit mounted at an angle (`body_from_unit`): the manifest's roll, pitch, azimuth and
/// drifts are its own, turned into the body's; an override (the optimiser's) is the
/// body's already, and without a manifest value the levelled body's stays.
#[test]
fn a_mounted_units_manifest_settings_are_turned_into_the_bodys() {
    use unz_stages::attitude::Euler;
    use unz_stages::imu_mounting::{body_attitude, rotation, to_body};
    use unz_stages::initial::{InitialRequest, Source};
    let c = case(31, SensorErrors::ALL);
    let turn = rotation([1.0, -2.0, 12.0]).unwrap();
    let unit = Euler {
        roll_rad: 0.01,
        pitch_rad: -0.02,
        heading_rad: 1.5,
    };
    let drift = [1e-6, -2e-6, 3e-6];
    let manifest = InitialRequest {
        azimuth_deg: Some((unit.heading_rad.to_degrees(), Source::Manifest)),
        roll_deg: Some((unit.roll_rad.to_degrees(), Source::Manifest)),
        pitch_deg: Some((unit.pitch_rad.to_degrees(), Source::Manifest)),
        drift_rad_s: Some((drift, Source::Manifest)),
        static_s: Some(c.run.manifest_static_s),
        odo_scale: 1.0,
        body_from_unit: Some(turn),
    };
    let s = c.settings_for(&manifest);
    let body = body_attitude(unit, &turn);
    let close = |a: f64, b: f64| (wrap_pi(a - b)).abs() < 1e-9;
    assert!(close(s.initial.roll_rad, body.roll_rad), "{s:?} {body:?}");
    assert!(close(s.initial.pitch_rad, body.pitch_rad), "{s:?} {body:?}");
    assert!(
        close(s.initial.heading_rad, body.heading_rad),
        "{s:?} {body:?}"
    );
    assert_eq!(s.drift_rad_s, to_body(&turn, drift));
    // Overridden: the body's, untouched.
    let overridden = InitialRequest {
        azimuth_deg: Some((80.0, Source::Override)),
        drift_rad_s: Some((drift, Source::Override)),
        ..manifest
    };
    let s = c.settings_for(&overridden);
    assert!(close(s.initial.heading_rad, 80f64.to_radians()), "{s:?}");
    assert_eq!(s.drift_rad_s, drift);
    // Gyrocompassed (no azimuth given), the manifest's drifts are the guess in the body's
    // axes, as the same drifts given there.
    let gyrocompassed = InitialRequest {
        azimuth_deg: None,
        ..manifest
    };
    let in_body = InitialRequest {
        drift_rad_s: Some((to_body(&turn, drift), Source::Override)),
        ..gyrocompassed
    };
    assert_eq!(
        c.settings_for(&gyrocompassed).initial.heading_rad,
        c.settings_for(&in_body).initial.heading_rad
    );
    // The levelled tilt without the manifest's is the same with a mounting or without.
    let levelled = InitialRequest {
        roll_deg: None,
        pitch_deg: None,
        ..overridden
    };
    let without = c.settings_for(&InitialRequest {
        body_from_unit: None,
        ..levelled
    });
    let s = c.settings_for(&levelled);
    assert_eq!(
        (s.initial.roll_rad, s.initial.pitch_rad),
        (without.initial.roll_rad, without.initial.pitch_rad)
    );
}

/// The kernel over segments (0.1 s) against the kernel sample by sample, on a simulated
/// 40-minute drive with every sensor error, at settings with and without drifts,
/// odometer scale, speed bias and boresights: what the criteria read agrees far below
/// what they resolve.
#[test]
fn passes_over_segments_agree_with_passes_sample_by_sample() {
    use unz_stages::strapdown::segments::{SegmentPlan, integrate};
    use unz_stages::strapdown::{CriteriaSink, run_criteria, run_criteria_segments};
    let c = case(41, SensorErrors::ALL);
    let inputs = c.inputs();
    let block = c.lowpass().block;
    let reports: Vec<usize> = c.fixes.iter().map(|f| f.sample).collect();
    let base = c.true_settings();
    let mut variants = vec![base];
    let mut s = base;
    s.drift_rad_s = [3e-6, -2e-6, 5e-6];
    s.initial.heading_rad += 0.05;
    variants.push(s);
    s.odo_scale = 1.003;
    s.odo_yaw_rad = 0.01;
    s.odo_pitch_rad = 0.02;
    variants.push(s);
    s.odo_bias_mps = 0.05;
    variants.push(s);
    let plan = SegmentPlan::new(inputs.len(), block, reports.iter().copied());
    let (imu, odo) = integrate(
        inputs.dt_s,
        inputs.dtheta_rad,
        &plan,
        true,
        &mut [inputs.odo_dist_m.iter().copied()],
        unz_stages::strapdown::segments::OdoColumns {
            yaw: true,
            pitch: true,
            moving: true,
        },
    );
    let (imu, odo) = (imu.unwrap(), &odo[0]);
    for (v, s) in variants.iter().enumerate() {
        let mut exact = [CriteriaSink::default()];
        run_criteria(&inputs, &[*s], block, &reports, &mut exact);
        let mut fast = [CriteriaSink::default()];
        run_criteria_segments(&imu, [odo], &[*s], &reports, &mut fast);
        let (e, f) = (&exact[0], &fast[0]);
        assert_eq!(e.blocks.len(), f.blocks.len());
        let worst_att = e
            .blocks
            .roll_rad
            .iter()
            .zip(&f.blocks.roll_rad)
            .chain(e.blocks.pitch_rad.iter().zip(&f.blocks.pitch_rad))
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let mut worst_pos: f64 = 0.0;
        let mut worst_h: f64 = 0.0;
        let mut worst_q: f64 = 0.0;
        assert_eq!(e.positions.len(), f.positions.len());
        for ((ke, pe), (kf, pf)) in e.positions.iter().zip(&f.positions) {
            assert_eq!(ke, kf);
            let (dn, de) =
                earth::local_offset_m(pf.lat_rad, pf.lon_rad, pe.lat_rad, pe.lon_rad, pe.h_m);
            worst_pos = worst_pos.max(dn.hypot(de));
            worst_h = worst_h.max((pf.h_m - pe.h_m).abs());
            // The angle between the attitudes: twice the norm of the quaternions' difference
            // (of the same sign), to first order.
            let sign = if (0..4).map(|i| pe.q_b_to_n[i] * pf.q_b_to_n[i]).sum::<f64>() < 0.0 {
                -1.0
            } else {
                1.0
            };
            let diff: f64 = (0..4)
                .map(|i| (pe.q_b_to_n[i] - sign * pf.q_b_to_n[i]).powi(2))
                .sum::<f64>()
                .sqrt();
            worst_q = worst_q.max(2.0 * diff);
            assert!(
                (pe.distance_m - pf.distance_m).abs() < 1e-3,
                "{} {}",
                pe.distance_m,
                pf.distance_m
            );
        }
        eprintln!(
            "variant {v}: blocks' roll/pitch within {worst_att:.2e} rad, stops within {worst_pos:.2e} m horizontally, {worst_h:.2e} m in height, attitude {worst_q:.2e} rad"
        );
        // Kryt1 reads the blocks against accelerometer angles of 1e-3 rad noise, Kryt2
        // the stops against surveyed points to decimetres: the segments change both by
        // three orders of magnitude less (measured: 4e-7 rad, 3 mm).
        assert!(
            worst_att < 1e-6,
            "variant {v}: block attitude {worst_att} rad"
        );
        assert!(worst_pos < 0.01, "variant {v}: stops {worst_pos} m");
        assert!(worst_h < 0.01, "variant {v}: heights {worst_h} m");
        assert!(
            worst_q < 1e-6,
            "variant {v}: attitude at the stops {worst_q} rad"
        );
    }
}
