//! The simulator against itself: integrating its own increments with the true settings
//! must reproduce its truth, which validates the kinematics, the quadrature and the
//! navigator's attitude and position updates together.

use unz_stages::attitude::{Euler, wrap_pi};
use unz_stages::earth;
use unz_stages::simulate::{SensorErrors, SimConfig, SimRun, simulate};
use unz_stages::strapdown::{NavInputs, NavSettings, NavTrack, navigate};

struct Inputs {
    dt: Vec<f64>,
    dtheta: Vec<[f64; 3]>,
    dist: Vec<f64>,
}

fn inputs(run: &SimRun) -> Inputs {
    let lsb = run.sensor.dtheta_lsb_rad;
    let m_per_pulse = run.settings.odo_scale_m_per_pulse;
    let mut prev_odo = 0i64;
    let mut out = Inputs {
        dt: Vec::new(),
        dtheta: Vec::new(),
        dist: Vec::new(),
    };
    for r in &run.records {
        out.dt.push(run.sensor.sample_period_s());
        out.dtheta.push(r.dtheta_counts.map(|c| f64::from(c) * lsb));
        let odo = i64::from(r.odo_count);
        out.dist.push((odo - prev_odo) as f64 * m_per_pulse);
        prev_odo = odo;
    }
    out
}

fn true_settings(run: &SimRun) -> NavSettings {
    NavSettings {
        initial: Euler {
            roll_rad: run.settings.roll_deg.to_radians(),
            pitch_rad: run.settings.pitch_deg.to_radians(),
            heading_rad: run.settings.azimuth_deg.to_radians(),
        },
        drift_rad_s: run.settings.drift_rad_s,
        odo_scale: 1.0,
        odo_yaw_rad: 0.0,
        odo_pitch_rad: 0.0,
        odo_bias_mps: 0.0,
        lat0_rad: run.site.lat_rad,
        lon0_rad: run.site.lon_rad,
        h0_m: run.site.h_m,
    }
}

fn max_attitude_error_deg(run: &SimRun, track: &NavTrack) -> [f64; 3] {
    let mut worst = [0f64; 3];
    for (k, e) in run.truth.euler.iter().enumerate() {
        let t = track.euler(k);
        let d = [
            wrap_pi(t.roll_rad - e.roll_rad),
            wrap_pi(t.pitch_rad - e.pitch_rad),
            wrap_pi(t.heading_rad - e.heading_rad),
        ];
        for i in 0..3 {
            worst[i] = worst[i].max(d[i].abs().to_degrees());
        }
    }
    worst
}

#[test]
fn own_increments_with_true_settings_reproduce_truth_over_40_minutes() {
    let mut config = SimConfig::new("sim-check", 11);
    config.errors = SensorErrors {
        noise: false,
        ..SensorErrors::ALL
    };
    let run = simulate(&config);
    let total = *run.truth.distance_m.last().unwrap();
    let inp = inputs(&run);
    let mut track = NavTrack::default();
    navigate(
        &NavInputs {
            dt_s: &inp.dt,
            dtheta_rad: (&inp.dtheta).into(),
            odo_dist_m: &inp.dist,
        },
        &true_settings(&run),
        &mut track,
    );
    let worst = max_attitude_error_deg(&run, &track);
    eprintln!("max attitude error over 40 min (roll, pitch, heading): {worst:?} deg");
    assert!(worst.iter().all(|&w| w < 0.001), "{worst:?}");
    let n = track.len() - 1;
    let (dn, de) = earth::local_offset_m(
        track.lat_rad[n],
        track.lon_rad[n],
        run.truth.lat_rad[n],
        run.truth.lon_rad[n],
        run.truth.h_m[n],
    );
    eprintln!("final position error: north {dn:.3} m, east {de:.3} m after {total:.0} m");
    // Odometer pulses of 12.5 mm and mid-interval direction: centimetres at most.
    assert!(dn.hypot(de) < 0.5, "{dn} {de}");
    assert!(
        (9_000.0..14_000.0).contains(&total),
        "route length {total} m for 40 min"
    );
}

#[test]
fn a_wrong_azimuth_really_moves_the_stop() {
    let mut config = SimConfig::new("sim-az", 12);
    config.duration_s = 900.0;
    config.errors = SensorErrors::NONE;
    config.azimuth_error_deg = Some(7.0);
    let run = simulate(&config);
    let inp = inputs(&run);
    let mut settings = true_settings(&run);
    settings.initial.heading_rad = run.settings.manifest_azimuth_deg.to_radians();
    let mut track = NavTrack::default();
    navigate(
        &NavInputs {
            dt_s: &inp.dt,
            dtheta_rad: (&inp.dtheta).into(),
            odo_dist_m: &inp.dist,
        },
        &settings,
        &mut track,
    );
    let n = track.len() - 1;
    let (dn, de) = earth::local_offset_m(
        track.lat_rad[n],
        track.lon_rad[n],
        run.truth.lat_rad[n],
        run.truth.lon_rad[n],
        run.truth.h_m[n],
    );
    // A 7° heading error rotates the whole displacement: |error| = 2 sin(3.5°)·|displacement|.
    let (nn, ee) = earth::local_offset_m(
        run.truth.lat_rad[n],
        run.truth.lon_rad[n],
        run.site.lat_rad,
        run.site.lon_rad,
        run.site.h_m,
    );
    let expected = 2.0 * (3.5f64).to_radians().sin() * nn.hypot(ee);
    let got = dn.hypot(de);
    assert!(
        (got - expected).abs() < 0.02 * expected + 1.0,
        "error {got} m, expected {expected} m"
    );
}

#[test]
fn simulation_is_deterministic_and_seed_dependent() {
    let mut config = SimConfig::new("det", 5);
    config.duration_s = 200.0;
    let a = simulate(&config);
    let b = simulate(&config);
    assert_eq!(a.records, b.records);
    config.seed = 6;
    assert_ne!(simulate(&config).records, a.records);
}

#[test]
fn an_out_and_back_route_comes_back_over_its_points_and_ends_at_its_start() {
    let mut c = SimConfig::new("back", 71);
    c.duration_s = 1800.0;
    c.cp_at_every_stop = true;
    c.out_and_back = true;
    let run = simulate(&c);
    let t = &run.truth;
    let at = |k: usize| {
        let (rm, rn) = earth::radii_m(t.lat_rad[k]);
        [
            t.lat_rad[k] * (rm + t.h_m[k]),
            t.lon_rad[k] * (rn + t.h_m[k]) * t.lat_rad[k].cos(),
            t.h_m[k],
        ]
    };
    let apart_m = |a: [f64; 3], b: [f64; 3]| (a[0] - b[0]).hypot(a[1] - b[1]);
    // Each id's marks: the first and the last.
    let mut visits = std::collections::BTreeMap::<u32, Vec<usize>>::new();
    for (k, m) in &run.marks {
        visits.entry(m.point_id).or_default().push(*k);
    }
    let twice: Vec<&Vec<usize>> = visits.values().filter(|v| v.len() == 2).collect();
    // Every point out but the far one is visited again; the start has its own, once.
    assert_eq!(twice.len() + 2, visits.len(), "{visits:?}");
    assert!(twice.len() >= 3, "{visits:?}");
    let mut out_and_back_m = 0.0_f64;
    for v in &twice {
        let (a, b) = (at(v[0]), at(v[1]));
        out_and_back_m = out_and_back_m.max(apart_m(a, b)).max((a[2] - b[2]).abs());
        // Far apart in the drive: out to the far end and back (a drive of 30 s at least).
        assert!(t.distance_m[v[1]] - t.distance_m[v[0]] > 200.0, "{v:?}");
    }
    // The same path: the quadrature's error, well below a millimetre.
    assert!(out_and_back_m < 1e-3, "{out_and_back_m} m");
    // Home: the last sample over the first, after kilometres.
    let n = t.h_m.len() - 1;
    assert!(t.distance_m[n] > 5_000.0, "{} m", t.distance_m[n]);
    assert!(apart_m(at(0), at(n)) < 1e-3 && (t.h_m[0] - t.h_m[n]).abs() < 1e-3);
    // Turned about at the far end: home facing the other way.
    let heading = |k: usize| t.euler[k].heading_rad;
    assert!((wrap_pi(heading(n) - heading(0)).abs() - std::f64::consts::PI).abs() < 1e-6);
    // The manifest lists each point once.
    let manifest = run.manifest_toml("back", "back.unz");
    assert_eq!(manifest.matches("[[control_point]]").count(), visits.len());
}
