//! Stage 5, export: the corrected navigation as `corrected_nav.parquet` and
//! `corrected.mcap` for Foxglove — `foxglove.LocationFix` (map panel) and
//! `foxglove.PoseInFrame` (3D panel, local east-north-up frame, body forward-left-up) at
//! 10 Hz, attitude at 10 Hz and the criteria at 1 Hz, as JSON with JSON Schema.

use std::path::PathBuf;

use anyhow::Context;
use serde::Serialize;
use serde_json::json;
use unz_formats::mcap_io::{JsonMcap, numeric_object_schema};
use unz_formats::parquet_io::{read_schema, read_table};
use unz_formats::schema::META_TIME_ORIGIN;
use unz_formats::tables::{f64_column, i64_column};
use unz_stages::attitude::Euler;
use unz_viz::frames::enu_flu;

use crate::artifacts::{StageName, files};
use crate::disupt_stage::{Method, ensure_disupt};
use crate::flow::{Overrides, Params, RunCtx, ensure_criteria};
use crate::stage::{Stage, params_hash};

/// Output rate of the navigation channels, Hz.
const NAV_RATE_HZ: f64 = 10.0;

const LOCATION_FIX_SCHEMA: &str = r#"{"title":"foxglove.LocationFix","type":"object","properties":{
"timestamp":{"type":"object","properties":{"sec":{"type":"integer"},"nsec":{"type":"integer"}}},
"frame_id":{"type":"string"},"latitude":{"type":"number"},"longitude":{"type":"number"},"altitude":{"type":"number"},
"position_covariance":{"type":"array","items":{"type":"number"},"minItems":9,"maxItems":9},
"position_covariance_type":{"type":"integer"}}}"#;

const POSE_IN_FRAME_SCHEMA: &str = r#"{"title":"foxglove.PoseInFrame","type":"object","properties":{
"timestamp":{"type":"object","properties":{"sec":{"type":"integer"},"nsec":{"type":"integer"}}},
"frame_id":{"type":"string"},
"pose":{"type":"object","properties":{
"position":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"}}},
"orientation":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"},"w":{"type":"number"}}}}}}}"#;

#[derive(Clone, Copy, Serialize)]
struct Stamp {
    sec: i64,
    nsec: i64,
}

#[derive(Serialize)]
struct LocationFix {
    timestamp: Stamp,
    frame_id: &'static str,
    latitude: f64,
    longitude: f64,
    altitude: f64,
    position_covariance: [f64; 9],
    position_covariance_type: u8,
}

#[derive(Serialize)]
struct Xyz {
    x: f64,
    y: f64,
    z: f64,
}

#[derive(Serialize)]
struct Xyzw {
    x: f64,
    y: f64,
    z: f64,
    w: f64,
}

#[derive(Serialize)]
struct Pose {
    position: Xyz,
    orientation: Xyzw,
}

#[derive(Serialize)]
struct PoseInFrame {
    timestamp: Stamp,
    frame_id: &'static str,
    pose: Pose,
}

#[derive(Serialize)]
struct Attitude {
    roll_deg: f64,
    pitch_deg: f64,
    heading_deg: f64,
}

/// Copies `src` to `dest` under a temporary name (`.<name>.<pid>.tmp`, which the stage
/// records clear if a killed run left it), then renames it into place.
fn copy_atomic(src: &std::path::Path, dest: &std::path::Path) -> anyhow::Result<()> {
    let mut name = std::ffi::OsString::from(".");
    name.push(dest.file_name().unwrap_or_default());
    name.push(format!(".{}.tmp", std::process::id()));
    let tmp = dest.with_file_name(name);
    std::fs::copy(src, &tmp)
        .with_context(|| format!("cannot copy {} to {}", src.display(), tmp.display()))?;
    std::fs::rename(&tmp, dest)
        .with_context(|| format!("cannot rename {} to {}", tmp.display(), dest.display()))?;
    Ok(())
}

/// Stage 5.
pub fn ensure_export(ctx: &RunCtx, params: &Params) -> anyhow::Result<PathBuf> {
    let disupt_dir = ensure_disupt(ctx, params, Method::All)?;
    let (criteria_dir, _) = ensure_criteria(ctx, params, &Overrides::default())?;
    let dir = ctx.layout().create(StageName::Export)?;
    let nav_path = disupt_dir.join(files::CORRECTED_NAV);
    let crit_path = criteria_dir.join(files::CRITERIA);
    // The log's UTC origin, when its header gave one, is in the ingested tables' schema.
    let imu_path = ctx.layout().file(StageName::Ingest, files::IMU);
    let stage = Stage {
        dir: dir.clone(),
        name: "export",
        version: 2,
        params_hash: params_hash(&NAV_RATE_HZ)?,
        inputs: vec![nav_path.clone(), crit_path.clone(), imu_path.clone()],
        outputs: &[files::CORRECTED_NAV, "corrected.mcap"],
    };
    ctx.run_stage(&stage, || {
        copy_atomic(&nav_path, &dir.join(files::CORRECTED_NAV))?;
        // MCAP log times in UTC when the log gives it (Foxglove shows the drive's date,
        // not 1970), as raw.mcap's; the messages keep the run's own time.
        let origin_ns: i64 = read_schema(&imu_path)?
            .metadata()
            .get(META_TIME_ORIGIN)
            .and_then(|v| v.parse().ok())
            .unwrap_or(0);
        let log_time_of = |t_ns: i64| u64::try_from(origin_ns.saturating_add(t_ns)).unwrap_or(0);
        let (_, b) = read_table(&nav_path)?;
        let t = i64_column(&b, "t_ns")?;
        let col = |n: &str| f64_column(&b, n);
        let (lat, lon, h, north, east) = (
            col("lat_deg")?,
            col("lon_deg")?,
            col("h_m")?,
            col("north_m")?,
            col("east_m")?,
        );
        let (roll, pitch, heading) = (col("roll_deg")?, col("pitch_deg")?, col("heading_deg")?);
        let mut mcap = JsonMcap::create(&dir.join("corrected.mcap"))?;
        let mut fix = mcap.add_channel(
            "/corrected/fix",
            "foxglove.LocationFix",
            LOCATION_FIX_SCHEMA,
        )?;
        let mut pose = mcap.add_channel(
            "/corrected/pose",
            "foxglove.PoseInFrame",
            POSE_IN_FRAME_SCHEMA,
        )?;
        let mut att = mcap.add_channel(
            "/corrected/attitude",
            "unz.Attitude",
            &numeric_object_schema(
                "Attitude, degrees",
                &["roll_deg", "pitch_deg", "heading_deg"],
                &[],
            ),
        )?;
        let step_ns = (1e9 / NAV_RATE_HZ) as i64;
        let mut next = t.first().copied().unwrap_or(0);
        for k in 0..t.len() {
            if t[k] < next {
                continue;
            }
            next = t[k] + step_ns;
            let log_time = log_time_of(t[k]);
            let timestamp = Stamp {
                sec: t[k].div_euclid(1_000_000_000),
                nsec: t[k].rem_euclid(1_000_000_000),
            };
            let fix_msg = LocationFix {
                timestamp,
                frame_id: "wgs84",
                latitude: lat[k],
                longitude: lon[k],
                altitude: h[k],
                position_covariance: [0.0; 9],
                position_covariance_type: 0,
            };
            mcap.write(&mut fix, log_time, &fix_msg)?;
            // Body forward-left-up in local east-north-up, as Foxglove's 3D panel expects.
            let q = enu_flu(
                &Euler {
                    roll_rad: roll[k].to_radians(),
                    pitch_rad: pitch[k].to_radians(),
                    heading_rad: heading[k].to_radians(),
                }
                .to_quat_b_to_n(),
            );
            let pose_msg = PoseInFrame {
                timestamp,
                frame_id: "local_enu",
                pose: Pose {
                    position: Xyz {
                        x: east[k],
                        y: north[k],
                        z: h[k] - h[0],
                    },
                    orientation: Xyzw {
                        x: q.i,
                        y: q.j,
                        z: q.k,
                        w: q.w,
                    },
                },
            };
            mcap.write(&mut pose, log_time, &pose_msg)?;
            mcap.write(
                &mut att,
                log_time,
                &Attitude {
                    roll_deg: roll[k],
                    pitch_deg: pitch[k],
                    heading_deg: heading[k],
                },
            )?;
        }
        let (_, c) = read_table(&crit_path)?;
        let names = [
            "theta_n_rad",
            "phi_n_rad",
            "theta_p_rad",
            "phi_p_rad",
            "d_theta_rad",
            "d_phi_rad",
            "kf_d_theta_rad",
            "kf_d_phi_rad",
            "kryt1_cum",
        ];
        let mut crit = mcap.add_channel(
            "/criteria",
            "unz.Criteria",
            &numeric_object_schema("Criteria at 1 s epochs (initial settings)", &names, &[]),
        )?;
        let cols: Vec<Vec<f64>> = names
            .iter()
            .map(|n| f64_column(&c, n))
            .collect::<Result<_, _>>()?;
        for (k, tk) in i64_column(&c, "t_ns")?.into_iter().enumerate() {
            let msg: serde_json::Map<String, serde_json::Value> = names
                .iter()
                .zip(&cols)
                .map(|(n, v)| ((*n).to_owned(), json!(v[k])))
                .collect();
            mcap.write(&mut crit, log_time_of(tk), &msg)?;
        }
        mcap.finish()?;
        Ok(())
    })?;
    Ok(dir)
}
