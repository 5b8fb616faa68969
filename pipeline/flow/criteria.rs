//! Stage 3b: the criteria of the navigated track, Kryt1 from its attitude per block and
//! Kryt2 at the control points (`criteria.parquet`, `criteria.json`).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::Context;
use serde::{Deserialize, Serialize};
use unz_formats::atomic::write_json_atomic;
use unz_formats::parquet_io::{for_each_batch_of, row_capacity_hint, write_batch};
use unz_formats::schema;
use unz_formats::tables::{CriteriaTable, MarksTable, f64_column};
use unz_stages::criteria::{self, BlockAttitude, FixPose, Kryt1Series, Kryt2, Row3Blocks};
use unz_stages::derive::Derived;
use unz_stages::earth::Geodetic;
use unz_stages::filter::LowPass;

use super::ingest_derive::read_ingest_report;
use super::ingested::load_table;
use super::{Overrides, Params, RunCtx, ensure_navigate, match_control_points, start_position};
use crate::artifacts::{StageName, files};
use crate::derive_io::load_derived_times;
use crate::picked_rows::{picked_columns, rows_among};
use crate::stage::{Stage, params_hash};

/// `criteria.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CriteriaSummary {
    /// Kryt1, rad.
    pub kryt1_rad: f64,
    /// Epochs.
    pub epochs: usize,
    /// Epochs used (not gated).
    pub valid_epochs: usize,
    /// Kryt2 at every control point.
    pub control_points: Vec<Kryt2>,
    /// Kryt2 at the last control point, m.
    pub kryt2_m: Option<f64>,
    /// Where the vehicle's mark, whose errors at the control points these are, lies from
    /// the navigated point (`[vehicle] mark_lever_arm_m`, IMU body axes, m); absent when
    /// it is the navigated point.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mark_lever_arm_m: Option<[f64; 3]>,
}

/// A sample and its pose.
type Position = (usize, FixPose);

/// The attitude `C_b^n` of a navigation table's roll, pitch and heading (degrees, as
/// stored), as (w, x, y, z).
fn q_of_degrees(roll_deg: f64, pitch_deg: f64, heading_deg: f64) -> [f64; 4] {
    let q = unz_stages::attitude::Euler {
        roll_rad: roll_deg.to_radians(),
        pitch_rad: pitch_deg.to_radians(),
        heading_rad: heading_deg.to_radians(),
    }
    .to_quat_b_to_n();
    [q.w, q.i, q.j, q.k]
}

/// What the criteria read of `nav.parquet` (`samples` rows): the attitude per block of
/// `block` samples, batch by batch (the track is never held whole), and the poses at the
/// samples `at`, of their rows alone ([`picked_columns`]).
fn read_nav_for_criteria(
    path: &Path,
    samples: usize,
    block: usize,
    at: &[usize],
) -> anyhow::Result<(BlockAttitude, Vec<Position>)> {
    use unz_formats::schema::DISTANCE_M;
    use unz_formats::schema::nav_cols::{H_M, HEADING_DEG, LAT_DEG, LON_DEG, PITCH_DEG, ROLL_DEG};
    let mut blocks = Row3Blocks::for_samples(samples, block);
    let mut rows = 0;
    for_each_batch_of(path, &[ROLL_DEG, PITCH_DEG, HEADING_DEG], |b| {
        let (roll, pitch, heading) = (
            f64_column(b, ROLL_DEG)?,
            f64_column(b, PITCH_DEG)?,
            f64_column(b, HEADING_DEG)?,
        );
        for k in 0..roll.len() {
            blocks.push(&q_of_degrees(roll[k], pitch[k], heading[k]));
        }
        rows += roll.len();
        Ok(())
    })?;
    let picked = rows_among(at, rows);
    let columns = [
        LAT_DEG,
        LON_DEG,
        H_M,
        DISTANCE_M,
        ROLL_DEG,
        PITCH_DEG,
        HEADING_DEG,
    ];
    let c = picked_columns(path, &columns, &picked)?;
    let positions = picked
        .iter()
        .enumerate()
        .map(|(i, &s)| {
            let pose = FixPose {
                lat_rad: c[0][i].to_radians(),
                lon_rad: c[1][i].to_radians(),
                h_m: c[2][i],
                distance_m: c[3][i],
                q_b_to_n: q_of_degrees(c[4][i], c[5][i], c[6][i]),
            };
            (s, pose)
        })
        .collect();
    Ok((blocks.finish(), positions))
}

/// The navigated north and east (m, from `origin`) at each of `samples`, of their rows
/// of `nav.parquet` alone (NaN past its end).
fn read_nav_places(
    path: &Path,
    origin: Geodetic,
    samples: &[usize],
) -> anyhow::Result<Vec<[f64; 2]>> {
    use unz_formats::schema::nav_cols::{LAT_DEG, LON_DEG};
    // The rows its footer states (one that lies fails the pick, naming the file).
    let picked = rows_among(samples, row_capacity_hint(path)?);
    let c = picked_columns(path, &[LAT_DEG, LON_DEG], &picked)?;
    Ok(samples
        .iter()
        .map(|s| match picked.binary_search(s) {
            Ok(i) => {
                let (north_m, east_m) = origin.offset_m(c[0][i].to_radians(), c[1][i].to_radians());
                [north_m, east_m]
            }
            Err(_) => [f64::NAN; 2],
        })
        .collect())
}

/// Stage 3b: the criteria of the navigated track.
pub fn ensure_criteria(
    ctx: &RunCtx,
    params: &Params,
    overrides: &Overrides,
) -> anyhow::Result<(PathBuf, CriteriaSummary)> {
    let nav_dir = ensure_navigate(ctx, params, overrides)?;
    let m = &ctx.manifest;
    let derive_dir = ctx.layout().dir(StageName::Derive);
    let ingest_dir = ctx.layout().dir(StageName::Ingest);
    let dir = ctx.layout().create(StageName::Criteria)?;
    let inputs = vec![
        m.path.clone(),
        nav_dir.join(files::NAV),
        derive_dir.join(files::DERIVED),
        derive_dir.join(files::EPOCHS),
        ingest_dir.join(files::MARKS),
        ingest_dir.join(files::ODOMETER),
    ];
    let stage = Stage {
        dir: dir.clone(),
        name: "criteria",
        // 2: of a control point marked more than once, the last mark at rest.
        // 3: control points compared at the vehicle's mark.
        // 4: a point the route comes back to is compared at each visit.
        version: 4,
        params_hash: params_hash(&(params.kalman, params.derive.filter, params.vehicle))?,
        inputs,
        outputs: &[files::CRITERIA, files::CRITERIA_REPORT],
        hashed_as_read: vec![],
    };
    ctx.run_stage(&stage, || {
        // The criteria read the derive's times and epochs only: without the chain's derive
        // in memory, only those are loaded.
        let d = match ctx.kept_derived() {
            Some(d) => d,
            None => Arc::new(load_derived_times(&derive_dir)?),
        };
        let (marks, _) = load_table::<MarksTable>(
            &ingest_dir.join(files::MARKS),
            MarksTable::extend_from_batch,
        )?;
        let fixes = match_control_points(
            m,
            &marks,
            &d,
            &read_ingest_report(&ingest_dir)?,
            &ingest_dir.join(files::ODOMETER),
            &params.vehicle,
            // The navigation's places, as the navigate stage matched them.
            |samples| read_nav_places(&nav_dir.join(files::NAV), start_position(m), samples),
        )
        .with_context(|| format!("in {}", m.path.display()))?
        .fixes;
        let lp = LowPass::new(&params.derive.filter, d.nominal_dt_s);
        let fix_samples: Vec<usize> = fixes.iter().map(|f| f.sample).collect();
        let (blocks, positions) = read_nav_for_criteria(
            &nav_dir.join(files::NAV),
            d.t_s.len(),
            lp.block,
            &fix_samples,
        )?;
        let mut series = Kryt1Series::default();
        let k1 =
            criteria::kryt1_from_blocks(&d.epochs, &lp, blocks, &params.kalman, Some(&mut series));
        write_criteria_parquet(&dir.join(files::CRITERIA), &d, &series)?;
        let cps = criteria::kryt2_at(&fixes, |k| {
            positions.iter().find(|p| p.0 == k).map(|&(_, pose)| pose)
        });
        let summary = CriteriaSummary {
            kryt1_rad: k1,
            epochs: d.epochs.t_s.len(),
            valid_epochs: d.epochs.valid.iter().filter(|v| **v).count(),
            kryt2_m: cps.last().map(|c| c.kryt2_m),
            control_points: cps,
            mark_lever_arm_m: params.vehicle.mark_arm(),
        };
        write_json_atomic(&dir.join(files::CRITERIA_REPORT), &summary)?;
        Ok(())
    })?;
    let summary = serde_json::from_slice(&std::fs::read(dir.join(files::CRITERIA_REPORT))?)?;
    Ok((dir, summary))
}

fn write_criteria_parquet(path: &Path, d: &Derived, s: &Kryt1Series) -> anyhow::Result<()> {
    let e = &d.epochs;
    let table = CriteriaTable {
        t_ns: d.epoch_t_ns(),
        theta_n_rad: s.theta_n_rad.clone(),
        phi_n_rad: s.phi_n_rad.clone(),
        theta_p_rad: e.theta_p_rad.clone(),
        phi_p_rad: e.phi_p_rad.clone(),
        d_theta_rad: s.d_theta_rad.clone(),
        d_phi_rad: s.d_phi_rad.clone(),
        kf_d_theta_rad: s.kf_theta_rad.clone(),
        kf_d_phi_rad: s.kf_phi_rad.clone(),
        kryt1_cum: s.kryt1_cum.clone(),
        valid: e.valid.clone(),
    };
    write_batch(path, &table.to_batch(schema::criteria())?)?;
    Ok(())
}

/// Loads `criteria.parquet`.
pub fn load_criteria(path: &Path) -> anyhow::Result<CriteriaTable> {
    let (table, _) = load_table::<CriteriaTable>(path, CriteriaTable::extend_from_batch)?;
    Ok(table)
}
