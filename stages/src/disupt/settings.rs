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
    /// Joint fit only (when asked for): the vehicle's mark moved along the body's x and y
    /// from the configured lever arm, m.
    #[serde(default, skip_serializing_if = "is_zero2")]
    pub mark_arm_m: [f64; 2],
}

fn is_zero2(v: &[f64; 2]) -> bool {
    *v == [0.0; 2]
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
            Setting::MarkForward => self.mark_arm_m[0],
            Setting::MarkRight => self.mark_arm_m[1],
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
            Setting::MarkForward => self.mark_arm_m[0] = v,
            Setting::MarkRight => self.mark_arm_m[1] = v,
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
    /// How far the joint fit may move the odometer scale from its start, ppm. Wheel
    /// radius, tyre pressure and wear change a land vehicle's scale by a few per cent; a
    /// fit beyond this is the control points disagreeing with the log, not an estimate.
    pub odo_scale_bound_ppm: f64,
    /// Leave control points that disagree with the rest of the run out of the joint fit:
    /// the point whose hold-out error is the most inconsistent
    /// ([`super::HOLDOUT_INCONSISTENT_SIGMA`]) is excluded and the fit redone without it,
    /// one at a time, while at least [`super::HOLDOUT_MIN_POINTS`] points stay in the fit
    /// and at most a third of the run's points are excluded. Off: such points are named
    /// and kept.
    pub joint_exclude_inconsistent: bool,
    /// Estimate the vehicle's mark (its lever arm along the body's x and y, added to the
    /// configured one) in the joint fit: it moves each control point along the vehicle's
    /// heading at its stop. Needs [`super::MARK_ARM_MIN_POINTS`] points. Absent: the
    /// stage redoes the fit estimating it when the fit's control points show an arm
    /// ([`super::JointFit::mark_arm_seen`]); `false`: never (what they show is still
    /// reported).
    pub joint_mark_arm: Option<bool>,
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
            odo_scale_bound_ppm: 100_000.0,
            joint_exclude_inconsistent: true,
            joint_mark_arm: None,
        }
    }
}

/// Bound of the joint fit's odometer yaw boresight, degrees: a mounting error, not a
/// direction (the simulator's own limit).
pub const JOINT_ODO_YAW_BOUND_DEG: f64 = 10.0;
/// Bound of the joint fit's odometer speed bias, m/s: an OBD-II speed's bias is a few
/// hundredths to tenths (Kingston's: 0.1 m/s).
pub const JOINT_ODO_BIAS_BOUND_MPS: f64 = 2.0;
/// Bound of the joint fit's move of the mark, m: a vehicle's length.
pub const JOINT_MARK_ARM_BOUND_M: f64 = 10.0;
/// Bound of the joint fit's levelling corrections, mrad: an accelerometer bias of 50 mg
/// (far beyond a navigation-grade or even a consumer MEMS accelerometer's) levels the
/// start that far wrong.
pub const JOINT_TILT_BOUND_MRAD: f64 = 50.0;

impl DisuptParams {
    /// How far a method may move `s` from where it starts (in the optimisers' units): the
    /// half-width of the classic methods' searches for the azimuth and the drifts, and for
    /// the joint fit those and physical bounds for the rest.
    pub fn bound(&self, s: Setting) -> f64 {
        match s {
            Setting::Azimuth => self.azimuth_bound_deg,
            Setting::DriftX | Setting::DriftY | Setting::DriftZ => self.drift_bound_deg_h,
            Setting::TiltPitch | Setting::TiltRoll => JOINT_TILT_BOUND_MRAD,
            Setting::OdoScale => self.odo_scale_bound_ppm,
            Setting::OdoYaw => JOINT_ODO_YAW_BOUND_DEG,
            Setting::OdoBias => JOINT_ODO_BIAS_BOUND_MPS,
            Setting::MarkForward | Setting::MarkRight => JOINT_MARK_ARM_BOUND_M,
        }
    }

    /// The settings of `free` that `x` moved beyond [`Self::bound`] from `start`,
    /// each as (setting, how far it moved); the azimuth's move is taken modulo 360°
    /// (the same heading). Non-finite moves are out of bounds.
    pub fn joint_out_of_bounds(&self, start: &X, x: &X, free: &[Setting]) -> Vec<(Setting, f64)> {
        free.iter()
            .map(|&s| {
                let moved = x.get(s) - start.get(s);
                let moved = match s {
                    Setting::Azimuth => (moved + 180.0).rem_euclid(360.0) - 180.0,
                    _ => moved,
                };
                (s, moved)
            })
            .filter(|&(s, moved)| moved.is_nan() || moved.abs() > self.bound(s))
            .collect()
    }

    /// The settings of `moved` that a search from `input` left at the edge of its range
    /// (within 0.1 % of [`Self::bound`]): the criterion still fell there, so the value is
    /// where the search stopped, not a minimum it found.
    pub fn at_bound(&self, input: &X, output: &X, moved: &[Setting]) -> Vec<Setting> {
        moved
            .iter()
            .copied()
            .filter(|&s| (output.get(s) - input.get(s)).abs() >= self.bound(s) * (1.0 - 1e-3))
            .collect()
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Each setting against its own bound; the azimuth modulo 360° (−18 535° from 207.96°
    /// is −22.987°: a fit the fuzzed chain made); a non-finite move is out.
    #[test]
    fn joint_bounds_take_each_setting_and_the_azimuth_modulo_a_turn() {
        let p = DisuptParams::default();
        let start = X {
            azimuth_deg: 207.958,
            drift_deg_h: [0.0, 0.0, -0.96],
            ..X::default()
        };
        let free = &Setting::ALL[..7];
        let within = X {
            azimuth_deg: 207.958 + 14.9 - 720.0,
            drift_deg_h: [4.9, -4.9, -0.96 + 4.9],
            tilt_mrad: [49.0, -49.0],
            odo_ppm: -99_000.0,
            ..start
        };
        assert!(p.joint_out_of_bounds(&start, &within, free).is_empty());
        let fuzzed = X {
            azimuth_deg: -18_535.029,
            drift_deg_h: [179.1, 717.5, -0.957],
            tilt_mrad: [168.3, -332.0],
            odo_ppm: 9.524e9,
            ..start
        };
        let out = p.joint_out_of_bounds(&start, &fuzzed, free);
        let settings: Vec<Setting> = out.iter().map(|o| o.0).collect();
        assert_eq!(
            settings,
            [
                Setting::Azimuth,
                Setting::DriftX,
                Setting::DriftY,
                Setting::TiltPitch,
                Setting::TiltRoll,
                Setting::OdoScale
            ]
        );
        assert!((out[0].1 - -22.987).abs() < 1e-9, "{out:?}");
        // Only the free settings are checked: a fixed odometer scale is not the fit's.
        assert!(
            p.joint_out_of_bounds(&start, &fuzzed, &free[3..4])
                .is_empty()
        );
        let nan = X {
            odo_ppm: f64::NAN,
            ..start
        };
        assert_eq!(p.joint_out_of_bounds(&start, &nan, free).len(), 1);
    }

    /// A search that stopped at the edge of its range is said to, one inside it not
    /// (Kingston's OWPI: drift z from 2.1766 to 7.1766 °/h, its ±5 °/h searched through).
    #[test]
    fn a_search_stopped_at_its_range_is_at_its_bound() {
        let p = DisuptParams::default();
        let input = X {
            azimuth_deg: 201.85,
            drift_deg_h: [0.0, 0.0, 2.176_647_650_537_266],
            ..X::default()
        };
        let pinned = X {
            drift_deg_h: [0.0, 0.0, 7.176_646_603_937_24],
            ..input
        };
        let moved = [Setting::DriftZ];
        assert_eq!(p.at_bound(&input, &pinned, &moved), moved);
        let found = X {
            azimuth_deg: 201.85 - 14.9,
            drift_deg_h: [0.0, 0.0, 6.9],
            ..input
        };
        assert!(
            p.at_bound(&input, &found, &[Setting::Azimuth, Setting::DriftZ])
                .is_empty()
        );
    }
}
