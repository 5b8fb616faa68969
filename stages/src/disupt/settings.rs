//! The settings DISUPT corrects, in the optimisers' units, and the methods' bounds and
//! switches.

use serde::{Deserialize, Serialize};

use crate::linearized::{N_PARAMS, Setting};

/// Settings in the optimisers' units.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct X {
    /// Initial azimuth, degrees.
    pub azimuth_deg: f64,
    /// Gyro drifts (x, y, z), °/h.
    pub drift_deg_h: [f64; 3],
    /// Odometer scale deviation from the base, ppm.
    pub odo_ppm: f64,
    /// Joint fit only (when asked for): odometer yaw boresight added to the base's,
    /// degrees. The odometer's direction of travel is body x turned by it.
    #[serde(default)]
    pub odo_yaw_deg: f64,
    /// Joint fit only (when asked for): odometer speed bias added to the base's, m/s.
    #[serde(default)]
    pub odo_bias_mps: f64,
    /// Joint fit only: pitch and roll levelling corrections, mrad. The accelerometer
    /// biases enter the levelled initial attitude and the accelerometer pitch/roll alike;
    /// the levelling error then turns with the heading, the accelerometer one does not.
    pub tilt_mrad: [f64; 2],
}

impl X {
    /// The value of one setting, in the optimisers' units.
    pub fn get(&self, s: Setting) -> f64 {
        match s {
            Setting::Azimuth => self.azimuth_deg,
            Setting::DriftX => self.drift_deg_h[0],
            Setting::DriftY => self.drift_deg_h[1],
            Setting::DriftZ => self.drift_deg_h[2],
            Setting::TiltPitch => self.tilt_mrad[0],
            Setting::TiltRoll => self.tilt_mrad[1],
            Setting::OdoScale => self.odo_ppm,
            Setting::OdoYaw => self.odo_yaw_deg,
            Setting::OdoBias => self.odo_bias_mps,
        }
    }

    /// Sets one setting, in the optimisers' units.
    pub fn set(&mut self, s: Setting, v: f64) {
        match s {
            Setting::Azimuth => self.azimuth_deg = v,
            Setting::DriftX => self.drift_deg_h[0] = v,
            Setting::DriftY => self.drift_deg_h[1] = v,
            Setting::DriftZ => self.drift_deg_h[2] = v,
            Setting::TiltPitch => self.tilt_mrad[0] = v,
            Setting::TiltRoll => self.tilt_mrad[1] = v,
            Setting::OdoScale => self.odo_ppm = v,
            Setting::OdoYaw => self.odo_yaw_deg = v,
            Setting::OdoBias => self.odo_bias_mps = v,
        }
    }
}

/// Bounds and switches of the methods.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DisuptParams {
    /// Half-width of the azimuth search around its start, degrees.
    pub azimuth_bound_deg: f64,
    /// Half-width of each drift search around its start, °/h.
    pub drift_bound_deg_h: f64,
    /// 1σ of one epoch's pitch/roll residual in the joint fit's first round, rad; the
    /// second round uses the residuals' RMS at the first solution when it is larger.
    pub attitude_sigma_rad: f64,
    /// 1σ of a control point's coordinates in the joint fit, m.
    pub position_sigma_m: f64,
    /// Estimate the odometer scale in the joint fit (needs control points).
    pub joint_odo_scale: bool,
    /// Estimate the odometer yaw boresight in the joint fit (needs control points). It
    /// turns the route like the initial azimuth does, so only the attitude residuals
    /// (Kryt1's information) tell the two apart: the azimuth's σ grows to what they
    /// give. Off by default.
    pub joint_odo_yaw: bool,
    /// Estimate an odometer speed bias in the joint fit (needs control points): what an
    /// OBD-II speed has, a pulse odometer has not. Absent: the stage decides by the kind
    /// of odometer (on for speed logs, off for pulse counts and distances).
    pub joint_odo_bias: Option<bool>,
    /// Estimate the odometer's lag with the joint fit (needs two control points or more:
    /// it moves the route at the stops by the lag times the velocity change from turns).
    pub joint_odo_lag: bool,
    /// Half-width of the lag search, s.
    pub odo_lag_bound_s: f64,
}

impl Default for DisuptParams {
    fn default() -> Self {
        Self {
            azimuth_bound_deg: 15.0,
            drift_bound_deg_h: 5.0,
            attitude_sigma_rad: 2e-3,
            position_sigma_m: 1.0,
            joint_odo_scale: true,
            joint_odo_yaw: false,
            joint_odo_bias: None,
            joint_odo_lag: true,
            odo_lag_bound_s: 1.0,
        }
    }
}

/// `X` as the linearisation's parameter vector (in [`Setting::ALL`] order).
pub fn params_of(x: &X) -> [f64; N_PARAMS] {
    Setting::ALL.map(|s| x.get(s))
}

/// The inverse of [`params_of`].
pub fn x_of(p: &[f64; N_PARAMS]) -> X {
    let mut x = X::default();
    for s in Setting::ALL {
        x.set(s, p[s.index()]);
    }
    x
}

/// Settings of the shared first linearisation: all but the odometer boresight and bias,
/// which only the joint fit moves, and only when asked.
pub(super) const BASE_SETTINGS: &[Setting] = Setting::ALL.split_at(Setting::OdoYaw.index()).0;
