//! The criteria's view of a navigation pass, and its linearisation in the settings.
//!
//! Kryt1, Kryt2 and the joint fit's residuals read only two things from a pass: the
//! filtered gyro pitch Θ_N and roll Φ_N at every epoch and the horizontal errors at the
//! control points — an [`Observation`]. Around settings `x_ref`, one exact pass and one
//! forward-difference pass per setting give `y(x) ≈ y(x_ref) + J (x − x_ref)`
//! ([`Linearization`]). The optimisers search this affine model (microseconds per
//! evaluation instead of a navigation pass), an exact pass checks the optimum it finds,
//! and where the two disagree the model is rebuilt there, until an exact pass agrees.

use crate::criteria::{ControlPointFix, Kryt1Gains, Kryt2, kryt1_with};
use crate::derive::Epochs;

/// The settings a linearisation can move, by name; their order is that of the parameter
/// vector ([`Setting::index`]). Units are the optimisers': degrees, °/h, mrad, ppm, m/s,
/// m.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum Setting {
    /// Initial azimuth, degrees.
    Azimuth,
    /// Gyro drift about body x, °/h.
    DriftX,
    /// Gyro drift about body y, °/h.
    DriftY,
    /// Gyro drift about body z, °/h.
    DriftZ,
    /// Pitch levelling correction, mrad.
    TiltPitch,
    /// Roll levelling correction, mrad.
    TiltRoll,
    /// Odometer scale deviation, ppm.
    OdoScale,
    /// Odometer yaw boresight, degrees.
    OdoYaw,
    /// Odometer speed bias, m/s.
    OdoBias,
    /// The vehicle's mark along the body's x (forward), added to the configured lever
    /// arm, m.
    MarkForward,
    /// The vehicle's mark along the body's y (right), added to the configured lever arm,
    /// m.
    MarkRight,
}

/// Number of settings a linearisation can move.
pub const N_PARAMS: usize = Setting::ALL.len();

impl Setting {
    /// Every setting, in parameter-vector order.
    pub const ALL: [Setting; 11] = [
        Setting::Azimuth,
        Setting::DriftX,
        Setting::DriftY,
        Setting::DriftZ,
        Setting::TiltPitch,
        Setting::TiltRoll,
        Setting::OdoScale,
        Setting::OdoYaw,
        Setting::OdoBias,
        Setting::MarkForward,
        Setting::MarkRight,
    ];

    /// Position in the parameter vector.
    pub const fn index(self) -> usize {
        self as usize
    }

    /// Forward-difference step: 0.01°, 0.01 °/h, 0.01 mrad, 10 ppm, 0.01°, 1 mm/s. Small
    /// enough that curvature does not bias the slope (a 0.01° azimuth change moves a 10 km
    /// route by 1.7 m), large enough to stay far above rounding.
    pub const fn fd_step(self) -> f64 {
        match self {
            Setting::OdoScale => 10.0,
            Setting::OdoBias => 1e-3,
            _ => 1e-2,
        }
    }

    /// Its name and unit (the optimisers' units) for messages.
    pub const fn name_and_unit(self) -> (&'static str, &'static str) {
        match self {
            Setting::Azimuth => ("azimuth", "°"),
            Setting::DriftX => ("drift x", "°/h"),
            Setting::DriftY => ("drift y", "°/h"),
            Setting::DriftZ => ("drift z", "°/h"),
            Setting::TiltPitch => ("pitch levelling", "mrad"),
            Setting::TiltRoll => ("roll levelling", "mrad"),
            Setting::OdoScale => ("odometer scale", "ppm"),
            Setting::OdoYaw => ("odometer yaw boresight", "°"),
            Setting::OdoBias => ("odometer speed bias", "m/s"),
            Setting::MarkForward => ("mark forward", "m"),
            Setting::MarkRight => ("mark right", "m"),
        }
    }

    /// Whether it moves the vehicle's mark (the point compared with the control points)
    /// and nothing of the pass: its slope is the attitude at each stop, without a pass
    /// ([`Observation::cp_arm_ne`]).
    pub const fn is_mark_arm(self) -> bool {
        matches!(self, Setting::MarkForward | Setting::MarkRight)
    }

    /// Whether only control points see it (the odometer's settings move the route, not
    /// the attitude the gyros carry).
    pub const fn needs_control_points(self) -> bool {
        matches!(
            self,
            Setting::OdoScale
                | Setting::OdoYaw
                | Setting::OdoBias
                | Setting::MarkForward
                | Setting::MarkRight
        )
    }
}

/// Largest pitch/roll difference between a prediction and an exact pass that counts as
/// agreement, rad (2″: a hundredth of one epoch's 1 mrad residual noise).
pub const AGREE_ATTITUDE_RAD: f64 = 1e-5;
/// Largest control-point difference that counts as agreement, m (a tenth of the
/// control points' 1 m uncertainty).
pub const AGREE_POSITION_M: f64 = 0.1;

/// What the criteria read from one navigation pass.
#[derive(Debug, Default, PartialEq)]
pub struct Observation {
    /// Filtered gyro pitch Θ_N at every epoch, rad.
    pub theta_rad: Vec<f64>,
    /// Filtered gyro roll Φ_N at every epoch, rad.
    pub phi_rad: Vec<f64>,
    /// (ΔX north, ΔY east) at every control point, m.
    pub cp_m: Vec<[f64; 2]>,
    /// At every control point, how a mark's arm along the body's x and y moves its
    /// (north, east): the first two rows and columns of `C_b^n` at its stop (an exact
    /// pass's; a prediction keeps its reference's).
    pub cp_arm_ne: Vec<[[f64; 2]; 2]>,
}

/// Written out for `clone_from`, which the derived `Clone` would make a fresh clone: a
/// prediction into a kept observation ([`Linearization::predict_into`], at every
/// evaluation of the methods' searches) reuses its buffers instead of allocating four.
impl Clone for Observation {
    fn clone(&self) -> Self {
        Self {
            theta_rad: self.theta_rad.clone(),
            phi_rad: self.phi_rad.clone(),
            cp_m: self.cp_m.clone(),
            cp_arm_ne: self.cp_arm_ne.clone(),
        }
    }

    fn clone_from(&mut self, source: &Self) {
        self.theta_rad.clone_from(&source.theta_rad);
        self.phi_rad.clone_from(&source.phi_rad);
        self.cp_m.clone_from(&source.cp_m);
        self.cp_arm_ne.clone_from(&source.cp_arm_ne);
    }
}

impl Observation {
    /// Largest differences from `other`: (attitude rad, position m).
    pub fn max_diff(&self, other: &Self) -> (f64, f64) {
        let att = self
            .theta_rad
            .iter()
            .zip(&other.theta_rad)
            .chain(self.phi_rad.iter().zip(&other.phi_rad))
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let pos = self
            .cp_m
            .iter()
            .zip(&other.cp_m)
            .map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1]))
            .fold(0.0, f64::max);
        (att, pos)
    }

    /// Whether `self` (a prediction) agrees with `exact`.
    pub fn agrees_with(&self, exact: &Self) -> bool {
        let (att, pos) = self.max_diff(exact);
        att <= AGREE_ATTITUDE_RAD && pos <= AGREE_POSITION_M
    }

    /// Kryt1 of these series, with the filters' gains over `epochs` at hand.
    pub fn kryt1_with(&self, epochs: &Epochs, gains: &Kryt1Gains) -> f64 {
        kryt1_with(
            epochs,
            gains,
            |e| (self.theta_rad[e], self.phi_rad[e]),
            None,
        )
    }

    /// Kryt2 at every control point.
    pub fn kryt2(&self, fixes: &[ControlPointFix]) -> Vec<Kryt2> {
        fixes
            .iter()
            .zip(&self.cp_m)
            .map(|(f, c)| Kryt2::at(f, c[0], c[1]))
            .collect()
    }

    /// RMS horizontal error over the control points, m (NaN without any).
    pub fn kryt2_rms(&self) -> f64 {
        crate::criteria::kryt2_rms_m(self.cp_m.iter().copied())
    }

    fn axpy(&mut self, a: f64, d: &Self) {
        for (y, v) in self.theta_rad.iter_mut().zip(&d.theta_rad) {
            *y += a * v;
        }
        for (y, v) in self.phi_rad.iter_mut().zip(&d.phi_rad) {
            *y += a * v;
        }
        for (y, v) in self.cp_m.iter_mut().zip(&d.cp_m) {
            y[0] += a * v[0];
            y[1] += a * v[1];
        }
    }

    /// `(self − base) / h`.
    pub fn slope(&self, base: &Self, h: f64) -> Self {
        let d = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| (x - y) / h).collect();
        Self {
            theta_rad: d(&self.theta_rad, &base.theta_rad),
            phi_rad: d(&self.phi_rad, &base.phi_rad),
            cp_m: self
                .cp_m
                .iter()
                .zip(&base.cp_m)
                .map(|(a, b)| [(a[0] - b[0]) / h, (a[1] - b[1]) / h])
                .collect(),
            cp_arm_ne: Vec::new(),
        }
    }
}

/// `y(x) ≈ y_ref + Σ_j slope_j (p_j − p_ref,j)` over the settings that have a slope; the
/// others must stay at their reference values.
#[derive(Debug, Clone)]
pub struct Linearization {
    /// Parameters of the reference point.
    pub p_ref: [f64; N_PARAMS],
    /// The exact observation there.
    pub y_ref: Observation,
    /// Slopes per parameter (per unit of the optimisers' units).
    pub slopes: [Option<Observation>; N_PARAMS],
}

impl Linearization {
    /// Adds the slopes of the mark's arm among `which` ([`Setting::is_mark_arm`]): the
    /// reference's attitude at each stop, per metre; no pass. The attitude series do not
    /// move (empty slopes add nothing).
    pub fn add_mark_arm_slopes(&mut self, which: &[Setting]) {
        for &s in which.iter().filter(|s| s.is_mark_arm()) {
            let axis = usize::from(s == Setting::MarkRight);
            self.slopes[s.index()] = Some(Observation {
                cp_m: self
                    .y_ref
                    .cp_arm_ne
                    .iter()
                    .map(|m| [m[0][axis], m[1][axis]])
                    .collect(),
                ..Observation::default()
            });
        }
    }

    /// Whether the model has a slope for every setting in `which`.
    pub fn covers(&self, which: &[Setting]) -> bool {
        which.iter().all(|s| self.slopes[s.index()].is_some())
    }

    /// The predicted observation at `p`, into `out` (reusing its buffers).
    pub fn predict_into(&self, p: &[f64; N_PARAMS], out: &mut Observation) {
        out.clone_from(&self.y_ref);
        for (j, s) in self.slopes.iter().enumerate() {
            if let Some(s) = s {
                let d = p[j] - self.p_ref[j];
                if d != 0.0 {
                    out.axpy(d, s);
                }
            }
        }
    }

    /// The predicted observation at `p`.
    pub fn predict(&self, p: &[f64; N_PARAMS]) -> Observation {
        let mut out = Observation::default();
        self.predict_into(p, &mut out);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obs(a: f64) -> Observation {
        Observation {
            theta_rad: vec![a, 2.0 * a],
            phi_rad: vec![-a, 0.5],
            cp_m: vec![[a, 3.0 * a]],
            cp_arm_ne: Vec::new(),
        }
    }

    #[test]
    fn a_prediction_into_a_kept_observation_reuses_its_buffers() {
        let mut slopes: [Option<Observation>; N_PARAMS] = Default::default();
        slopes[0] = Some(obs(1.0));
        let mut y_ref = obs(0.5);
        y_ref.cp_arm_ne = vec![[[1.0, 0.0], [0.0, 1.0]]];
        let lin = Linearization {
            p_ref: [0.0; N_PARAMS],
            y_ref,
            slopes,
        };
        let mut out = lin.predict(&[0.0; N_PARAMS]);
        let buffers = |o: &Observation| {
            (
                o.theta_rad.as_ptr(),
                o.phi_rad.as_ptr(),
                o.cp_m.as_ptr(),
                o.cp_arm_ne.as_ptr(),
            )
        };
        let before = buffers(&out);
        let mut p = [0.0; N_PARAMS];
        p[0] = 2.0;
        lin.predict_into(&p, &mut out);
        assert_eq!(buffers(&out), before);
        assert_eq!(out, lin.predict(&p));
        assert_eq!(out.theta_rad, vec![2.5, 5.0]);
        assert_eq!(out.cp_arm_ne, lin.y_ref.cp_arm_ne);
    }

    #[test]
    fn an_affine_model_predicts_itself() {
        let mut slopes: [Option<Observation>; N_PARAMS] = Default::default();
        slopes[2] = Some(obs(1.0));
        let lin = Linearization {
            p_ref: [0.0; N_PARAMS],
            y_ref: obs(0.0),
            slopes,
        };
        let mut p = [0.0; N_PARAMS];
        p[2] = 0.25;
        let y = lin.predict(&p);
        assert_eq!(y.theta_rad, vec![0.25, 0.5]);
        assert_eq!(y.phi_rad, vec![-0.25, 0.625]);
        assert_eq!(y.cp_m, vec![[0.25, 0.75]]);
        assert!(
            lin.covers(&[Setting::DriftY]) && !lin.covers(&[Setting::Azimuth, Setting::DriftY])
        );
        let s = obs(1.0).slope(&obs(0.0), 0.5);
        assert_eq!(
            (s.theta_rad, s.phi_rad, s.cp_m),
            (vec![2.0, 4.0], vec![-2.0, 0.0], vec![[2.0, 6.0]])
        );
        assert!(y.agrees_with(&y));
        assert!(!y.agrees_with(&obs(0.0)));
    }
}
