//! The chain of stages for one run: each `ensure_*` brings the stages before it up to
//! date (through their stage records), then skips or runs its own.
//!
//! [`RunCtx`] is the run being processed; [`ingest_derive`] holds stages 1 and 2,
//! [`ingested`] what the derive reads of the ingest, [`case`] a navigation case (the
//! derive, the control points and the initial settings) and [`marks`] which mark stands
//! for a control point, then [`navigate`] and [`criteria`] stages 3a and 3b.

pub mod axes;
pub mod case;
pub mod coordinates_misread;
pub mod criteria;
pub mod ingest_derive;
pub mod ingested;
pub mod marks;
pub mod moving_marks;
pub mod navigate;
pub mod odometer_checks;
pub mod run_ctx;
pub mod site_apart;
pub mod unix_clock;

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
    /// export.
    pub export: crate::export::ExportParams,
}

/// Every parameter of [`Params`] but the export's, serialised as `Params` is (the same
/// names, in the same order): what the records of the stages that read them all (disupt,
/// sweep) hash, so that an export setting re-runs the export alone.
#[derive(Serialize)]
pub struct BeforeExport<'p> {
    ingest: &'p crate::ingest::IngestParams,
    derive: &'p DeriveParams,
    align: &'p AlignParams,
    kalman: &'p KalmanParams,
    disupt: &'p unz_stages::disupt::DisuptParams,
    vehicle: &'p VehicleParams,
}

impl Params {
    /// The parameters but the export's ([`BeforeExport`]).
    pub fn before_export(&self) -> BeforeExport<'_> {
        let Self {
            ingest,
            derive,
            align,
            kalman,
            disupt,
            vehicle,
            export: _,
        } = self;
        BeforeExport {
            ingest,
            derive,
            align,
            kalman,
            disupt,
            vehicle,
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The parameters but the export's are the parameters' own JSON less the export's
    /// key, byte for byte (the disupt stage's records made before `[export]` existed keep
    /// their hash), whatever the export's setting.
    #[test]
    fn before_export_is_the_params_json_less_the_export() {
        let mut params = Params::default();
        params.disupt.azimuth_bound_deg = 7.5;
        for compression in [
            unz_formats::mcap_io::McapCompression::None,
            unz_formats::mcap_io::McapCompression::Zstd,
            unz_formats::mcap_io::McapCompression::Lz4,
        ] {
            params.export.mcap_compression = compression;
            let whole = serde_json::to_string(&params).unwrap();
            let export = format!(
                ",\"export\":{}}}",
                serde_json::to_string(&params.export).unwrap()
            );
            let want = format!("{}}}", whole.strip_suffix(&export).expect("export last"));
            assert_eq!(
                serde_json::to_string(&params.before_export()).unwrap(),
                want
            );
        }
    }
}
