//! What the methods report: the rows of the paper's tables and each method's result.

use serde::{Deserialize, Serialize};

use super::settings::{BASE_SETTINGS, X};
use crate::linearized::{Observation, Setting};

/// Which criterion a search minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Criterion {
    /// Kryt1.
    Kryt1,
    /// Kryt2 (RMS over the control points).
    Kryt2,
    /// Both at once, as weighted least squares (joint).
    LeastSquares,
}

/// Which component(s) a step moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Component {
    /// azpocz.
    Azimuth,
    /// driftx.
    DriftX,
    /// drifty.
    DriftY,
    /// driftz.
    DriftZ,
    /// (azpocz, driftx, drifty) together.
    AzimuthDriftXy,
    /// Every estimated setting at once (joint).
    All,
}

/// One row of the paper's tables.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Step {
    /// Step number, from 1.
    pub step: usize,
    /// What moved.
    pub component: Component,
    /// By which criterion.
    pub criterion: Criterion,
    /// Settings before the step.
    pub input: X,
    /// Settings after it.
    pub output: X,
    /// ΔX at the last control point after the step, m.
    #[serde(
        skip_serializing_if = "crate::finite::is_absent",
        default = "crate::finite::absent"
    )]
    pub dx_m: f64,
    /// ΔY at the last control point after the step, m.
    #[serde(
        skip_serializing_if = "crate::finite::is_absent",
        default = "crate::finite::absent"
    )]
    pub dy_m: f64,
    /// Navigation passes of the step.
    pub evaluations: usize,
    /// Settings the step left at the edge of its search range
    /// ([`super::DisuptParams::at_bound`]): clipped, not found.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub at_bound: Vec<crate::linearized::Setting>,
}

/// The result of one method.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MethodResult {
    /// Optimised settings.
    pub x: X,
    /// 1σ of each optimised component (joint only), same units.
    pub sigma: Option<X>,
    /// ΔX at the last control point with `x`, m.
    pub dx_m: f64,
    /// ΔY at the last control point with `x`, m.
    pub dy_m: f64,
    /// Kryt1 with `x`, rad.
    pub kryt1: f64,
    /// The table rows.
    pub steps: Vec<Step>,
    /// The method's own navigation passes (the shared first linearisation, see
    /// [`Problem::base_passes`](super::Problem::base_passes), aside).
    pub evaluations: usize,
    /// Wall time, s.
    pub wall_s: f64,
}

impl Component {
    /// The settings a step moves.
    pub(super) fn settings(self) -> &'static [Setting] {
        match self {
            Component::Azimuth => &[Setting::Azimuth],
            Component::DriftX => &[Setting::DriftX],
            Component::DriftY => &[Setting::DriftY],
            Component::DriftZ => &[Setting::DriftZ],
            Component::AzimuthDriftXy => &[Setting::Azimuth, Setting::DriftX, Setting::DriftY],
            Component::All => BASE_SETTINGS,
        }
    }
}

/// (ΔX, ΔY) at the last control point of an observation, m (NaN without one).
pub(super) fn last_cp(y: &Observation) -> (f64, f64) {
    y.cp_m.last().map_or((f64::NAN, f64::NAN), |c| (c[0], c[1]))
}
