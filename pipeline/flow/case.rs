//! A navigation case: the derive, the control points matched to its samples, and the
//! initial settings of the pass (overrides, the manifest, else the alignment).

use std::sync::Arc;

use anyhow::{Context, bail};
use unz_formats::manifest::RunManifest;
use unz_formats::parquet_io::read_schema;
use unz_formats::schema::META_ODO_M_PER_PULSE;
use unz_formats::tables::MarksTable;
use unz_stages::criteria::ControlPointFix;
use unz_stages::derive::Derived;
use unz_stages::earth::Geodetic;
use unz_stages::initial::{
    InitialReport, InitialRequest, Source, initial_settings_with_velocity, static_samples,
};
use unz_stages::strapdown::{NavInputs, NavSettings, NavTrack, navigate};

use super::ingested::load_table;
use super::{Overrides, Params, RunCtx, ensure_derive};
use crate::artifacts::{StageName, files};
use crate::derive_io::read_velocity_prefix;

/// Everything a navigation pass needs, loaded once.
pub struct NavCase {
    /// Derived series (shared with the run's other stages in this process).
    pub derived: Arc<Derived>,
    /// Control points matched to samples.
    pub fixes: Vec<ControlPointFix>,
    /// Settings of the pass.
    pub settings: NavSettings,
    /// How they were found.
    pub initial: InitialReport,
}

impl NavCase {
    /// The navigation inputs.
    pub fn inputs(&self) -> NavInputs<'_> {
        NavInputs {
            dt_s: &self.derived.dt_s,
            dtheta_rad: &self.derived.dtheta_rad,
            odo_dist_m: &self.derived.odo_dist_m,
        }
    }

    /// Runs the navigation into `track`.
    pub fn navigate(&self, track: &mut NavTrack) {
        navigate(&self.inputs(), &self.settings, track);
    }
}

/// Matches the manifest's control points: by their mark record, else by `t_s`.
pub fn match_control_points(
    m: &RunManifest,
    marks: &MarksTable,
    d: &Derived,
) -> anyhow::Result<Vec<ControlPointFix>> {
    let log_t_s = |t_ns: i64| t_ns as f64 * 1e-9;
    // The first mark of each point id.
    let mut first_mark = std::collections::HashMap::new();
    for (i, &id) in marks.point_id.iter().enumerate() {
        first_mark.entry(id).or_insert(i);
    }
    m.control_points
        .iter()
        .map(|cp| {
            let t_s = first_mark
                .get(&cp.id)
                .map(|&i| log_t_s(marks.t_ns[i]))
                .or(cp.t_s)
                .with_context(|| {
                    format!(
                        "control point {} matches no mark record and has no t_s",
                        cp.id
                    )
                })?;
            let rel = t_s - log_t_s(d.t0_ns);
            let Some(last) = d.t_s.last() else {
                bail!("no samples")
            };
            if rel < 0.0 || rel > last + d.nominal_dt_s {
                bail!("control point {} at t_s = {t_s} is outside the log", cp.id);
            }
            let sample = d.t_s.partition_point(|t| t < rel).min(d.t_s.len() - 1);
            Ok(ControlPointFix {
                id: cp.id,
                sample,
                t_s,
                lat_rad: cp.position.latitude_deg.to_radians(),
                lon_rad: cp.position.longitude_deg.to_radians(),
                h_m: cp.position.height_m,
            })
        })
        .collect()
}

/// Where the run starts: the manifest's site.
pub fn start_position(m: &RunManifest) -> Geodetic {
    Geodetic::from_deg(m.site.latitude_deg, m.site.longitude_deg, m.site.height_m)
}

/// Loads a navigation case of the run with `overrides` (derive must be up to date).
pub fn load_case(ctx: &RunCtx, params: &Params, overrides: &Overrides) -> anyhow::Result<NavCase> {
    let derive_dir = ensure_derive(ctx, params)?;
    let m = &ctx.manifest;
    let ingest_dir = ctx.layout().dir(StageName::Ingest);
    let derived = ctx.derived(&derive_dir)?;
    let (marks, _) = load_table::<MarksTable>(
        &ingest_dir.join(files::MARKS),
        MarksTable::extend_from_batch,
    )?;
    let odo_schema = read_schema(&ingest_dir.join(files::ODOMETER))?;
    let fixes = match_control_points(m, &marks, &derived)
        .with_context(|| format!("in {}", m.path.display()))?;
    let ingest_scale: Option<f64> = odo_schema
        .metadata()
        .get(META_ODO_M_PER_PULSE)
        .and_then(|s| s.parse().ok());
    let odo_scale = match (overrides.odo_scale_m_per_pulse, ingest_scale) {
        (Some(s), Some(used)) => s / used,
        (Some(s), None) => s,
        (None, _) => 1.0,
    };
    let i = &m.initial;
    let req = InitialRequest {
        azimuth_deg: overrides
            .azimuth_deg
            .map(|v| (v, Source::Override))
            .or(i.azimuth_deg.map(|v| (v, Source::Manifest))),
        pitch_deg: i.pitch_deg.map(|v| (v, Source::Manifest)),
        roll_deg: i.roll_deg.map(|v| (v, Source::Manifest)),
        drift_rad_s: overrides
            .drift_rad_s
            .map(|v| (v, Source::Override))
            .or(i.drift_rad_s.map(|v| (v, Source::Manifest))),
        static_s: i.static_s,
        odo_scale,
    };
    // The alignment reads the velocity increments of the static start only: read apart
    // when the derive was loaded without them.
    let prefix;
    let dvel_mps: &[[f64; 3]] = if derived.dvel_mps.len() == derived.t_s.len() {
        &derived.dvel_mps
    } else {
        prefix = read_velocity_prefix(&derive_dir, static_samples(&derived, &req))?;
        &prefix
    };
    let (settings, initial) =
        initial_settings_with_velocity(&derived, dvel_mps, &req, &params.align, start_position(m));
    if initial.gyrocompass_skipped.is_some() && fixes.is_empty() {
        bail!(
            "the run has neither a static start nor a control point: without a static start \
             there is no gyrocompass heading, and without a control point DISUPT cannot find \
             the azimuth (in {})",
            m.path.display()
        );
    }
    Ok(NavCase {
        derived,
        fixes,
        settings,
        initial,
    })
}
