//! Stage 3a: the navigation pass of a case, written to `nav.parquet` as it runs, and its
//! summary (`navigate.json`).

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use unz_formats::atomic::write_json_atomic;
use unz_stages::criteria::{self, Kryt2};
use unz_stages::imu_axes::{AxesCheck, ImuAxes};
use unz_stages::initial::InitialReport;
use unz_stages::odo_clock::ClockFit;

use super::marks::{RepeatedMark, UnknownMarks};
use super::moving_marks::MovingMark;
use super::site_apart::SiteApart;
use super::{Overrides, Params, RunCtx, ensure_derive, load_case};
use crate::artifacts::{StageName, files};
use crate::nav_writer::{NavWriter, SigmaColumns};
use crate::stage::{Stage, params_hash};

/// Summary of a navigation pass (`navigate.json`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct NavigateSummary {
    /// Initial settings and alignment.
    pub initial: InitialReport,
    /// Samples navigated.
    pub samples: usize,
    /// Duration, s.
    pub duration_s: f64,
    /// Distance travelled, m.
    pub distance_m: f64,
    /// Position errors at the control points.
    pub control_points: Vec<Kryt2>,
    /// Where the vehicle's mark, whose errors at the control points these are, lies from
    /// the navigated point (`[vehicle] mark_lever_arm_m`, IMU body axes, m); absent when
    /// it is the navigated point.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mark_lever_arm_m: Option<[f64; 3]>,
    /// Control points whose id was marked more than once, and the mark used (absent
    /// when none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub repeated_marks: Vec<RepeatedMark>,
    /// Control points passed at speed, not stood at, and the nearest stop (absent when
    /// none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub moving_marks: Vec<MovingMark>,
    /// Every control point's error before DISUPT one shift: the site off, or the points
    /// in another datum (absent otherwise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub site_apart: Option<SiteApart>,
    /// Marks whose id no control point of the manifest has: a key pressed wrong, or a
    /// point missing from the manifest (absent when none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unknown_marks: Option<UnknownMarks>,
    /// Time tags derive repaired (not after the previous one).
    pub repaired_times: usize,
    /// Samples that closed a gap in the log and were scaled to it.
    pub filled_gaps: usize,
    /// Samples whose status flags an IMU built-in-test failure.
    #[serde(default)]
    pub imu_failure_samples: usize,
    /// Samples whose status flags an odometer failure (a run fails above a tenth).
    #[serde(default)]
    pub odometer_failure_samples: usize,
    /// Samples whose increments exceeded the IMU's range, replaced by the previous
    /// sample's rates (a run fails above a hundredth).
    #[serde(default)]
    pub out_of_range_samples: usize,
    /// The IMU's axes: as named, and what the log's data say of them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub imu_axes: Option<ImuAxesReport>,
    /// What the drive says of the odometer's clock at `[derive] odo_time_offset_s`: the
    /// shift of its time tags (`lag_s`, positive late) at which its u̇ follows the
    /// accelerometers' x best, and the correlation there; judged when `shown`
    /// (correlation ≥ 0.5 over enough driving). The joint fit estimates the lag with the
    /// route; this reading is the drive's alone. Absent for a log with too little.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub odometer_clock: Option<OdometerClock>,
}

/// [`NavigateSummary::odometer_clock`]: the derive's [`ClockFit`], and whether the drive
/// shows the clock ([`ClockFit::shown`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OdometerClock {
    /// The derive's reading.
    #[serde(flatten)]
    pub fit: ClockFit,
    /// Whether the drive shows the clock: enough of the odometer's accelerations, well
    /// enough followed.
    pub shown: bool,
}

/// The log's IMU axes and mounting as named (`[vehicle] imu_axes`, `imu_mounting_deg`;
/// the ingest turned the increments from them into the body's FRD), and the derive's
/// check of the turned increments and of the log's scales.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ImuAxesReport {
    /// The log's axes as named.
    pub named: ImuAxes,
    /// The IMU's mounting as named (roll, pitch, yaw, degrees); absent when none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub named_mounting_deg: Option<[f64; 3]>,
    /// What the increments, turned, say of the body's axes: gravity's direction
    /// (`tilt_deg` from down) and the odometer's accelerations' (`forward_turn_deg` from
    /// x; judged when `forward_correlation` ≥ 0.5 over enough driving), the mounting
    /// they still show (`mounting_deg`); and of the scales: the accelerometers' gains on
    /// the odometer's u̇ (`along`) and ru (`across`), 1 in SI units.
    pub check: AxesCheck,
}

/// Stage 3a: navigation.
pub fn ensure_navigate(
    ctx: &RunCtx,
    params: &Params,
    overrides: &Overrides,
) -> anyhow::Result<PathBuf> {
    let derive_dir = ensure_derive(ctx, params)?;
    let m = &ctx.manifest;
    let dir = ctx.layout().create(StageName::Navigate)?;
    let ingest_dir = ctx.layout().dir(StageName::Ingest);
    // The derive's increments are the ingest's IMU table's, repaired.
    let inputs = vec![
        m.path.clone(),
        derive_dir.join(files::DERIVED),
        derive_dir.join(files::IMU_REPAIRS),
        ingest_dir.join(files::IMU),
        ingest_dir.join(files::MARKS),
        ingest_dir.join(files::ODOMETER),
    ];
    let stage = Stage {
        dir: dir.clone(),
        name: "navigate",
        // 4: control points the log cannot reach fail the stage (case::check_reach).
        // 5: of a control point marked more than once, the last mark at rest.
        // 6: a start levelled in motion is fitted over the log's first minute.
        // 7: control points compared at the vehicle's mark; marks of ids no control point
        //    has are said.
        // 8: a point the route comes back to is compared at each visit.
        // 9: a mounted unit's manifest angles and drifts are turned into the body's.
        // 10: a static start given past the odometer's first sign of motion is cut there.
        // 11: a roll or pitch given far from the static start's levelling is said.
        // 12: control points passed at speed, not stood at, are said; so are a stand at
        //     the log's start the static start given leaves out, and every point's error
        //     one shift (the site off).
        // 13: the derive's reading of the odometer's clock reported. 14: the stand at the
        //     log's start judged by the odometer's travel over each second (a speed
        //     sensor's noise at rest ended it), and its travel said. 15: a text log's
        //     control point timed after a GPS week's rollover taken a week on. 16: an
        //     azimuth given far from the static start's gyrocompassing said. 17: the
        //     stand's travel said with the speed floor that reads it as 0. 18: a static
        //     start given shorter than half the stand said (minutes meant named); a
        //     control point out of reach named the misreading of its coordinates. 19: a
        //     control point's time whole GPS weeks off the log named.
        version: 19,
        params_hash: params_hash(&(params.align, overrides, params.vehicle))?,
        inputs,
        outputs: &[files::NAV, files::NAVIGATE_REPORT],
        hashed_as_read: vec![],
    };
    ctx.run_stage(&stage, || {
        let case = load_case(ctx, params, overrides)?;
        if let Some(unused) = &case.initial.static_unused {
            ctx.say("navigate", &unused.said());
        }
        if let Some(travel) = &case.initial.stand_travel {
            ctx.say("navigate", &travel.said());
        }
        if let Some(cut) = &case.initial.static_cut {
            ctx.say("navigate", &cut.said());
        }
        for moving in &case.moving_marks {
            ctx.say("navigate", &moving.said());
        }
        if let Some(apart) = &case.initial.azimuth_apart {
            ctx.say("navigate", &apart.said());
        }
        if let Some(apart) = &case.initial.level_apart {
            ctx.say("navigate", &apart.said());
        }
        // The pass writes nav.parquet as it runs (the other core encoding its batches),
        // keeping the positions at the control points.
        let fix_samples: Vec<usize> = case.fixes.iter().map(|f| f.sample).collect();
        let mut nav = NavWriter::create(
            &dir.join(files::NAV),
            &case.derived,
            case.settings.start(),
            SigmaColumns::Without,
            &fix_samples,
        )?;
        nav.run_helped(|sink| unz_stages::strapdown::run(&case.inputs(), &case.settings, sink));
        let nav = nav.finish("navigated")?;
        let control_points = criteria::kryt2_at(&case.fixes, |k| nav.at(k).map(|s| s.pose));
        let site = case.settings.start();
        let site_apart = SiteApart::of(&control_points, &case.fixes, site);
        if let Some(apart) = &site_apart {
            ctx.say("navigate", &apart.said());
        }
        let summary = NavigateSummary {
            initial: case.initial,
            samples: nav.samples,
            duration_s: case.derived.t_s.last().unwrap_or(0.0),
            distance_m: nav.distance_m,
            control_points,
            site_apart,
            mark_lever_arm_m: params.vehicle.mark_arm(),
            repeated_marks: case.repeated_marks.clone(),
            moving_marks: case.moving_marks.clone(),
            unknown_marks: case.unknown_marks.clone(),
            repaired_times: case.derived.repaired_times,
            filled_gaps: case.derived.filled_gaps,
            imu_failure_samples: case.derived.imu_failure_samples,
            out_of_range_samples: case.derived.out_of_range_samples,
            odometer_failure_samples: case.derived.odometer_failure_samples,
            imu_axes: case.derived.axes_check.map(|check| ImuAxesReport {
                named: params.vehicle.imu_axes,
                named_mounting_deg: Some(params.vehicle.imu_mounting_deg)
                    .filter(|m| *m != [0.0; 3]),
                check,
            }),
            odometer_clock: (case.derived.odometer_clock).map(|fit| OdometerClock {
                fit,
                shown: fit.shown(),
            }),
        };
        write_json_atomic(&dir.join(files::NAVIGATE_REPORT), &summary)?;
        Ok(())
    })?;
    Ok(dir)
}
