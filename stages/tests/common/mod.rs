//! Simulated runs as the pipeline sees them after ingest and derive (shared by tests).
#![allow(dead_code)]

use unz_stages::attitude::wrap_pi;
use unz_stages::criteria::{self, ControlPointFix, KalmanParams, Kryt1Scratch};
use unz_stages::derive::{DeriveParams, Derived, RawSeries, derive};
use unz_stages::earth;
use unz_stages::filter::LowPass;
use unz_stages::initial::{AlignParams, InitialRequest, Source, initial_settings};
use unz_stages::simulate::{SensorErrors, SimConfig, SimRun, simulate};
use unz_stages::strapdown::{NavInputs, NavSettings, NavTrack, navigate};

/// The simulated run as the pipeline sees it after ingest and derive.
pub struct Case {
    pub run: SimRun,
    pub derived: Derived,
    pub fixes: Vec<ControlPointFix>,
}

pub fn case(seed: u64, errors: SensorErrors) -> Case {
    case_with(seed, errors, None)
}

pub fn case_with(seed: u64, errors: SensorErrors, azimuth_error_deg: Option<f64>) -> Case {
    let mut config = SimConfig::new("nav", seed);
    config.errors = errors;
    config.azimuth_error_deg = azimuth_error_deg;
    case_of(&config)
}

/// A simulated run of `config`, derived.
pub fn case_of(config: &SimConfig) -> Case {
    case_derived_with(config, &DeriveParams::default())
}

/// A simulated run of `config`, derived with `params`.
pub fn case_derived_with(config: &SimConfig, params: &DeriveParams) -> Case {
    let run = simulate(config);
    let lsb = (run.sensor.dtheta_lsb_rad, run.sensor.dvel_lsb_mps);
    let t_ns: Vec<i64> = run.records.iter().map(|r| r.t_us as i64 * 1000).collect();
    let dtheta: Vec<[f64; 3]> = run
        .records
        .iter()
        .map(|r| r.dtheta_counts.map(|c| f64::from(c) * lsb.0))
        .collect();
    let dvel: Vec<[f64; 3]> = run
        .records
        .iter()
        .map(|r| r.dvel_counts.map(|c| f64::from(c) * lsb.1))
        .collect();
    let odo: Vec<f64> = run
        .records
        .iter()
        .map(|r| f64::from(r.odo_count) * run.sensor.odo_lsb_m)
        .collect();
    let raw = RawSeries {
        imu_t_ns: &t_ns,
        dtheta_rad: &dtheta,
        dvel_mps: &dvel,
        odo_t_ns: (&t_ns).into(),
        odo_distance_m: &odo,
    };
    let g = earth::normal_gravity_mps2(run.site.lat_rad, run.site.h_m);
    let derived = derive(&raw, params, g);
    let fixes = run
        .marks
        .iter()
        .zip(&run.control_points)
        .map(|((k, _), cp)| ControlPointFix {
            id: cp.id,
            sample: *k,
            t_s: cp.t_s,
            lat_rad: cp.latitude_deg.to_radians(),
            lon_rad: cp.longitude_deg.to_radians(),
            h_m: cp.height_m,
            mark_lever_arm_m: run.config.mark_lever_arm_m,
        })
        .collect();
    Case {
        run,
        derived,
        fixes,
    }
}

impl Case {
    /// Settings with the true azimuth, drifts and odometer scale; attitude levelled.
    pub fn true_settings(&self) -> NavSettings {
        let s = &self.run.settings;
        let req = InitialRequest {
            azimuth_deg: Some((s.azimuth_deg, Source::Override)),
            drift_rad_s: Some((s.drift_rad_s, Source::Override)),
            static_s: Some(self.run.manifest_static_s),
            odo_scale: s.odo_scale_m_per_pulse / s.nominal_odo_m_per_pulse,
            ..InitialRequest::default()
        };
        self.settings_for(&req)
    }

    pub fn nav(&self, s: &NavSettings) -> NavTrack {
        let mut t = NavTrack::default();
        let d = &self.derived;
        navigate(
            &NavInputs {
                dt_s: &d.dt_s,
                dtheta_rad: d.dtheta_rad.view(),
                odo_dist_m: &d.odo_dist_m,
            },
            s,
            &mut t,
        );
        t
    }

    /// The largest horizontal error against truth along the whole route (every second), m.
    pub fn max_route_error_m(&self, t: &NavTrack) -> f64 {
        let truth = &self.run.truth;
        (0..t.len())
            .step_by(100)
            .map(|k| {
                let (dn, de) = unz_stages::earth::local_offset_m(
                    t.lat_rad[k],
                    t.lon_rad[k],
                    truth.lat_rad[k],
                    truth.lon_rad[k],
                    truth.h_m[k],
                );
                dn.hypot(de)
            })
            .fold(0.0, f64::max)
    }

    pub fn final_error_m(&self, t: &NavTrack) -> f64 {
        criteria::kryt2(t, &self.fixes).last().unwrap().kryt2_m
    }

    pub fn kryt1(&self, t: &NavTrack) -> f64 {
        let lp = LowPass::new(&DeriveParams::default().filter, self.derived.nominal_dt_s);
        criteria::kryt1(
            &self.derived.epochs,
            &lp,
            t,
            &KalmanParams::default(),
            &mut Kryt1Scratch::default(),
            None,
        )
    }

    /// Max |error| over the run of roll, pitch, heading, degrees.
    pub fn attitude_errors_deg(&self, t: &NavTrack) -> [f64; 3] {
        let mut worst = [0f64; 3];
        for (k, e) in self.run.truth.euler.iter().enumerate() {
            let n = t.euler(k);
            let d = [
                n.roll_rad - e.roll_rad,
                n.pitch_rad - e.pitch_rad,
                n.heading_rad - e.heading_rad,
            ];
            for i in 0..3 {
                worst[i] = worst[i].max(wrap_pi(d[i]).abs().to_degrees());
            }
        }
        worst
    }
}

impl Case {
    /// The settings before DISUPT: the manifest's azimuth, the drift measured at rest,
    /// the nominal odometer scale, attitude levelled.
    pub fn manifest_settings(&self) -> NavSettings {
        let req = InitialRequest {
            azimuth_deg: Some((self.run.settings.manifest_azimuth_deg, Source::Manifest)),
            static_s: Some(self.run.manifest_static_s),
            odo_scale: 1.0,
            ..InitialRequest::default()
        };
        self.settings_for(&req)
    }

    /// Initial settings for `req` at the run's site, levelled over the static start.
    pub fn settings_for(&self, req: &InitialRequest) -> NavSettings {
        let site = self.run.site;
        initial_settings(&self.derived, req, &AlignParams::default(), site).0
    }

    pub fn inputs(&self) -> NavInputs<'_> {
        NavInputs {
            dt_s: &self.derived.dt_s,
            dtheta_rad: self.derived.dtheta_rad.view(),
            odo_dist_m: &self.derived.odo_dist_m,
        }
    }

    /// The ingested odometer the case was derived from: time tags (ns) and cumulative
    /// distances (m).
    pub fn raw_odometer(&self) -> (Vec<i64>, Vec<f64>) {
        self.run
            .records
            .iter()
            .map(|r| {
                (
                    r.t_us as i64 * 1000,
                    f64::from(r.odo_count) * self.run.sensor.odo_lsb_m,
                )
            })
            .unzip()
    }

    pub fn lowpass(&self) -> LowPass {
        LowPass::new(&DeriveParams::default().filter, self.derived.nominal_dt_s)
    }
}
