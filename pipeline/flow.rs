//! The chain of stages for one run: each `ensure_*` brings the stages before it up to
//! date (through their stage records), then skips or runs its own.
//!
//! [`RunCtx`] is the run being processed; [`ingest_derive`] holds stages 1 and 2,
//! [`ingested`] what the derive reads of the ingest, [`case`] a navigation case (the
//! derive, the control points and the initial settings) and [`marks`] which mark stands
//! for a control point, then [`navigate`] and [`criteria`] stages 3a and 3b.

pub mod axes;
pub mod case;
pub mod criteria;
pub mod ingest_derive;
pub mod ingested;
pub mod marks;
pub mod navigate;
pub mod run_ctx;

use serde::{Deserialize, Serialize};
use unz_stages::criteria::KalmanParams;
use unz_stages::derive::DeriveParams;
use unz_stages::initial::AlignParams;

pub use case::{
    MatchedPoints, NavCase, VehicleParams, load_case, match_control_points, start_position,
};
pub use criteria::{CriteriaSummary, ensure_criteria, load_criteria};
pub use ingest_derive::{
    ensure_derive, ensure_finite, ensure_ingest, ensure_ingest_before_derive, site_gravity_mps2,
};
pub use ingested::{IngestedSeries, OdometerTags};
pub use navigate::{ImuAxesReport, NavigateSummary, ensure_navigate};
pub use run_ctx::{Cores, RunCtx};

/// Parameters of every stage (defaults built in).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Params {
    /// ingest.
    pub ingest: crate::ingest::IngestParams,
    /// derive.
    pub derive: DeriveParams,
    /// Alignment.
    pub align: AlignParams,
    /// Kalman filter of the criteria.
    pub kalman: KalmanParams,
    /// DISUPT methods.
    pub disupt: unz_stages::disupt::DisuptParams,
    /// The vehicle's installation.
    pub vehicle: VehicleParams,
}

/// Initial settings forced on the command line.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Overrides {
    /// Initial azimuth, degrees.
    pub azimuth_deg: Option<f64>,
    /// Gyro drifts, rad/s.
    pub drift_rad_s: Option<[f64; 3]>,
    /// Metres per odometer pulse.
    pub odo_scale_m_per_pulse: Option<f64>,
}
