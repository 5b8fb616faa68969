//! Stage 5, export: the corrected navigation as `corrected.mcap` for Foxglove and Rerun,
//! ROS 2 messages: `sensor_msgs/msg/NavSatFix` (map panel; geographic points in Rerun) and
//! `geometry_msgs/msg/PoseStamped` (3D panel, local east-north-up frame, body
//! forward-left-up) at 10 Hz, attitude at 10 Hz and the criteria at 1 Hz.
//!
//! The corrected trajectory at the full rate is written once, by the disupt stage
//! (`disupt/corrected_nav.parquet`); nothing here copies it.

use std::path::PathBuf;

use unz_formats::mcap_io::{McapCompression, Ros2Mcap};
use unz_formats::parquet_io::read_schema;
use unz_formats::ros2_msgs::{
    Attitude, Criteria, Header, NavSatFix, NavSatStatus, Point, Pose, PoseStamped, Quaternion, Time,
};
use unz_formats::schema::{META_TIME_ORIGIN, NAV_STATE};
use unz_stages::attitude::Euler;
use unz_viz::frames::enu_flu;

use crate::artifacts::{StageName, files};
use crate::disupt_stage::{Method, ensure_disupt};
use crate::flow::{Overrides, Params, RunCtx, ensure_criteria, load_criteria};
use crate::picked_rows::{picked_columns, picked_times};
use crate::stage::{Stage, params_hash};

/// Output rate of the navigation channels, Hz.
const NAV_RATE_HZ: f64 = 10.0;

/// Parameters of the export stage (`[export]` in a config file or a run's `[params]`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ExportParams {
    /// Compression of `corrected.mcap`'s chunks: `lz4` (default: about 4.2 MB a 40-min
    /// run), `zstd` (3.5 MB, and the export's CPU 15 % more) or `none` (9.4 MB).
    pub mcap_compression: McapCompression,
}

impl Default for ExportParams {
    fn default() -> Self {
        Self {
            mcap_compression: McapCompression::Lz4,
        }
    }
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
        version: 3,
        params_hash: params_hash(&(NAV_RATE_HZ, params.export))?,
        inputs: vec![nav_path.clone(), crit_path.clone(), imu_path.clone()],
        outputs: &["corrected.mcap"],
        hashed_as_read: vec![],
    };
    ctx.run_stage(&stage, || {
        // MCAP log times in UTC when the log gives it (Foxglove shows the drive's date,
        // not 1970), as raw.mcap's; the messages keep the run's own time.
        let origin_ns: i64 = read_schema(&imu_path)?
            .metadata()
            .get(META_TIME_ORIGIN)
            .and_then(|v| v.parse().ok())
            .unwrap_or(0);
        let log_time_of = |t_ns: i64| u64::try_from(origin_ns.saturating_add(t_ns)).unwrap_or(0);
        // The corrected navigation at NAV_RATE_HZ: the first row at or after each step, and
        // of those rows only the columns the messages carry.
        let step_ns = (1e9 / NAV_RATE_HZ) as i64;
        let mut next: Option<i64> = None;
        let (t, rows, _) = picked_times(&nav_path, |_, tk| {
            if next.is_some_and(|n| tk < n) {
                return false;
            }
            next = Some(tk + step_ns);
            true
        })?;
        let columns: [Vec<f64>; 8] = picked_columns(&nav_path, &NAV_STATE, &rows)?
            .try_into()
            .map_err(|_| anyhow::anyhow!("{}: a column missing", nav_path.display()))?;
        let [lat, lon, h, north, east, roll, pitch, heading] = columns;
        // The heights from the route's first row (always kept).
        let h0 = h.first().copied().unwrap_or(0.0);
        let mut mcap =
            Ros2Mcap::create(&dir.join("corrected.mcap"), params.export.mcap_compression)?;
        let mut fix = mcap.add_channel::<NavSatFix>("/corrected/fix")?;
        let mut pose = mcap.add_channel::<PoseStamped>("/corrected/pose")?;
        let mut att = mcap.add_channel::<Attitude>("/corrected/attitude")?;
        for k in 0..t.len() {
            let log_time = log_time_of(t[k]);
            let stamp = Time::from_ns(t[k]);
            let fix_msg = NavSatFix {
                header: Header {
                    stamp,
                    frame_id: "wgs84",
                },
                status: NavSatStatus {
                    status: 0,
                    service: 0,
                },
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
            let pose_msg = PoseStamped {
                header: Header {
                    stamp,
                    frame_id: "local_enu",
                },
                pose: Pose {
                    position: Point {
                        x: east[k],
                        y: north[k],
                        z: h[k] - h0,
                    },
                    orientation: Quaternion {
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
        let c = load_criteria(&crit_path)?;
        let mut crit = mcap.add_channel::<Criteria>("/criteria")?;
        for (k, &tk) in c.t_ns.iter().enumerate() {
            let msg = Criteria {
                theta_n_rad: c.theta_n_rad[k],
                phi_n_rad: c.phi_n_rad[k],
                theta_p_rad: c.theta_p_rad[k],
                phi_p_rad: c.phi_p_rad[k],
                d_theta_rad: c.d_theta_rad[k],
                d_phi_rad: c.d_phi_rad[k],
                kf_d_theta_rad: c.kf_d_theta_rad[k],
                kf_d_phi_rad: c.kf_d_phi_rad[k],
                kryt1_cum: c.kryt1_cum[k],
            };
            mcap.write(&mut crit, log_time_of(tk), &msg)?;
        }
        mcap.finish()?;
        Ok(())
    })?;
    Ok(dir)
}
