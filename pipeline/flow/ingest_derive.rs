//! Stages 1 and 2: the ingest of the raw log, and the derive of its series.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Context, bail};
use unz_formats::manifest::RunManifest;
use unz_formats::raw::FaultKind;
use unz_formats::{IngestEvents, IngestReport};
use unz_stages::derive::Derived;
use unz_stages::earth;

use super::axes::check_axes;
use super::odometer_checks::{
    SMALLER_UNITS, check_clock, check_overlap, check_stand_flat, check_stand_speed, check_travel,
    stand_speed,
};
use super::{IngestedSeries, Params, RunCtx, ingested};
use crate::artifacts::{StageName, files};
use crate::campaign::read_report;
use crate::derive_io::{as_stored, write_derived};
use crate::ingest::{
    IngestOptions, KeptSample, OUTPUTS as INGEST_OUTPUTS, imu_sample_place, ingest, seconds,
};
use crate::review_sensors::{review_sensors, write_review_sensors};
use crate::stage::{Stage, params_hash};

/// Stage 1.
pub fn ensure_ingest(ctx: &RunCtx, params: &Params) -> anyhow::Result<PathBuf> {
    ingest_keeping(ctx, params, false)
}

/// Stage 1 when the derive follows in this process: the series the ingest writes, if it
/// runs, are kept for it ([`ensure_derive`] takes them instead of reading the files).
pub fn ensure_ingest_before_derive(ctx: &RunCtx, params: &Params) -> anyhow::Result<PathBuf> {
    ingest_keeping(ctx, params, true)
}

/// Stage 1, its series kept in `ctx` for the derive when it runs and `for_derive`;
/// checked once per context and parameters ([`RunCtx::ensured_with`]).
fn ingest_keeping(ctx: &RunCtx, params: &Params, for_derive: bool) -> anyhow::Result<PathBuf> {
    let ensured_with = params_hash(params)?;
    if ctx.ensured_with("ingest", &ensured_with) {
        return Ok(ctx.layout().dir(StageName::Ingest));
    }
    // Asked with other parameters, the ingest may run again: the derive read the old one.
    ctx.forget_ensured("derive");
    let m = &ctx.manifest;
    let dir = ctx.layout().create(StageName::Ingest)?;
    // The ingest reads the raw log and the odometer file front to back, hashing them.
    let mut hashed_as_read = vec![m.raw.clone()];
    hashed_as_read.extend(m.odometer.file.clone());
    let mut inputs = vec![m.path.clone()];
    inputs.extend(hashed_as_read.iter().cloned());
    let stage = Stage {
        dir: dir.clone(),
        name: "ingest",
        // 2: odometer steps beyond a land vehicle's speed replaced and counted; the
        // odometer file's lines accounted in `ingest.json`. 3: `ingest_events.json` names
        // the raw log as the manifest does, not as the path was given. 4: the odometer's
        // failures (status bit 1) bridged by the inertial along-track speed. 5: a count that
        // stands while the vehicle moves is a failure too; the bridge fits the odometer's
        // scale error and the x accelerometer's bias, and searches the lag about the
        // derive's configured odometer time offset. 6: `odometer.parquet`'s
        // `distance_source` says which distances are the odometer's readings, bridged or
        // held (the disupt stage bridges again at the lag it estimates). 7: a text log's
        // odometer speed file's gaps are bridged. 8: its stands (zero speeds) the IMU finds
        // moving are bridged too. 9: so are an 8th column's gaps and stands, as the log
        // streams. 10: a stand the vehicle moved into fails from its start when its
        // watch's reference may have been motion; a bridge whose speed no land vehicle
        // has is refused. 11: a stand's failure from its start ends where the vehicle
        // came to rest in it, and a drive-off from that rest is a failure of its own.
        // 12: that rest judged by the IMU's speed with gravity carried by the gyros.
        // 13: no bridge across IMU samples more than a second apart. 14: a text log's
        // speeds that jump faster than a land vehicle's and come back are left out.
        // 15: a UTF-8 byte-order mark opening a text file is no part of its first line.
        // 16: a comment line that is not UTF-8 is a comment, not a fault. 17: a rejected
        // line's reason (in `ingest_events.json`) names decimal commas in a speed file too.
        // 18: a text file's time tag beyond ±9e9 s is a rejected line, not a saturated
        // time. 19: a standing count's watch takes a sample period of 0.1 ms at least.
        // 20: a text file's time tags unwrapped over a GPS week's rollover. 21: and over
        // a day's (seconds of day, at midnight). 22: an odometer file begun across the
        // week's or the day's end from its log taken on the log's side. 23: an odometer
        // file's line whose time tag leapt forward alone is the line rejected, not the
        // lines after it. 24: a record or line repeating one of the last 8192 accepted
        // (a block sent again, logs joined over their overlap) is a duplicate. 25: a
        // text log's 8th column may be left blank on any line. 27: the manifest's
        // odometer file is the odometer over an 8th column, the column left unread said.
        // 28: an odometer file of more columns read at `[odometer] value_column`; a line
        // of more numbers without it names the setting. 29: the column named by the
        // file's header line too; a time tag in Unix ms, µs or ns named so (its reason in
        // `ingest_events.json`). 30: a binary log's time base follows `seq` across the
        // recorder's clock leaping (steps and lone tags off taken out, said and listed).
        // 31: a text log's first or last line apart from the others across an interval
        // longer than the derive's `max_gap_s` is reported so, not as lost samples.
        // 32: a binary log's tag off its `seq`'s time by more than half a period (or four
        // times the recorder's learnt jitter) is a leap, not 10 periods: a time sync's
        // tens of milliseconds taken out; the period a trimmed mean, not a median.
        // 33: a text log's line written late or early alone (off its slot by more than
        // half a period, between its neighbours, they a slot either side) takes its
        // slot's time, the middle of theirs: read as written, a late one closed a gap and
        // had its increments scaled. 34: a text log's clock set back while it logged (a
        // line less than half a period after the one before, or before it, its next
        // going on from it at a period) taken out of the time base: the derive failed.
        // 35: a text log's lines told by their slots on a clock that follows the tags
        // (`unz_formats::slot_clock`): its `seq` is the line's slot (lines lost its
        // steps), and lines late, early or set back are judged against the clock, not the
        // last line's tag (a log jittering by a quarter of a period read lines as set
        // back and lost). 36: a text log's clock set forward (a gap the run bridges
        // after which the slots' phase moved by more than a quarter of a period) taken
        // out of the time base, not read as lines lost; a separate odometer file follows
        // the log's steps where its tags show them. 37: a text log's lines that come in
        // bursts (a logger stamping them as it received them, several at once) spread
        // over the periods before each burst's first tag: a log wholly in bursts, or a
        // stall's three lines or more in any other. 38: a text log stamped by a clock
        // coarser than its period (several lines to a tag) has each line on its slot of
        // a clock following the ticks (`unz_formats::text_ticks`), not read as the clock
        // set back and lines lost. 39: a text log whose steps of one period and of two
        // come as regularly as a clock ticking finer than its period would stamp them is
        // read as losing lines regularly when its velocity increments span one step.
        version: 39,
        params_hash: params_hash(&(
            m.odometer.scale_m_per_pulse,
            params.ingest,
            params.derive.odo_time_offset_s,
            params.vehicle.imu_axes,
            params.vehicle.imu_mounting_deg,
            params.derive.max_gap_s,
        ))?,
        inputs,
        outputs: &INGEST_OUTPUTS,
        hashed_as_read,
    };
    let options = IngestOptions {
        mcap: Some(params.ingest.raw_mcap_compression),
        odo_lag_prior_s: -params.derive.odo_time_offset_s,
        imu_axes: params.vehicle.imu_axes,
        imu_mounting: unz_stages::imu_mounting::rotation(params.vehicle.imu_mounting_deg),
        // The derive that follows takes the series as they were written instead of
        // decoding the files again.
        keep_series: for_derive,
        max_gap_s: params.derive.max_gap_s,
    };
    ctx.run_stage(&stage, || {
        ctx.set_ingested(None);
        let outcome = ingest(m, &dir, options)?;
        if let Some(floor) = &outcome.report.speed_floor {
            ctx.say("ingest", &floor.said());
        }
        if let Some(unread) = outcome.report.speed_column_unread_said() {
            ctx.say("ingest", &unread);
        }
        if let Some(apart) = outcome.report.lines_apart_said() {
            ctx.say("ingest", &apart);
        }
        for said in outcome.report.time_base_said() {
            ctx.say("ingest", &said);
        }
        ctx.set_ingested(
            outcome
                .series
                .map(|written| IngestedSeries::from_written(written, ctx.manifest.format))
                .transpose()?,
        );
        Ok(())
    })?;
    ctx.set_ensured("ingest", ensured_with);
    Ok(dir)
}

/// The spans of `odometer.parquet` (in `ingest_dir`) whose rows are not the odometer's
/// readings (bridged or held over its failures), s from `d`'s first sample on the IMU's
/// clock (their tags moved by `offset_s`, the derive's `odo_time_offset_s`); read only
/// when the ingest's account has such rows.
fn not_readings_s(
    ingest_dir: &Path,
    report: &IngestReport,
    d: &Derived,
    offset_s: f64,
) -> anyhow::Result<Vec<[f64; 2]>> {
    let failed = report.odometer_failures.as_ref();
    if failed.is_none_or(|f| f.bridged_samples + f.not_bridged_samples == 0) {
        return Ok(Vec::new());
    }
    let (spans, _) = IngestedSeries::load_failed_rows(ingest_dir)?;
    let s = |t_ns: i64| t_ns.saturating_sub(d.t0_ns) as f64 * 1e-9 + offset_s;
    Ok(spans
        .iter()
        .map(|f| [s(f.first_t_ns), s(f.last_t_ns)])
        .collect())
}

/// An odometer file's clock failure `e`, told the log's clock was set back or forward
/// while it logged (`report`'s steps) and the file was left as written across some of
/// them (its tags did not show them, or they were longer than the file follows): a file
/// written on that clock needs its tags after each step moved by the step, which one shift
/// for the whole file does not do.
fn with_log_clock_stepped(
    e: anyhow::Error,
    report: &IngestReport,
    odometer_file: Option<&Path>,
) -> anyhow::Error {
    let not_shown = (report.odometer_file.as_ref()).map_or(0, |f| f.clock_steps_not_shown);
    let Some(file) = odometer_file.filter(|_| not_shown > 0) else {
        return e;
    };
    anyhow::anyhow!(
        "{e}. But the log's clock was stepped while it logged ({}), and {} was left as \
         written across {not_shown} of the steps (its tags did not show them, or they were \
         longer than {} s): if it was written on that clock, move its tags after each such \
         step by the step instead of one shift for the file",
        report.text_clock_steps_listed(),
        file.display(),
        unz_formats::followed_steps::MAX_FOLLOWED_STEP_S
    )
}

/// Fails when the IMU's samples cover under a quarter of the log's time: more samples
/// read as lost (`report`'s) than three times those kept (`d`'s). A log that lost most of
/// its samples has no dead reckoning to correct (each stretch lost is a guess from the
/// rates either side). It may also be a logger that stamped its lines as it received them,
/// several at once, in bursts the reader did not find (it spreads each burst over the
/// periods before it when the log's first lines come so, and any three lines or more
/// close together: `unz_formats::text_bursts`): the gap between bursts then reads as
/// samples lost, and the first sample after it stands for them (its increments over the
/// gap out of the IMU's range, or a heading turned at random). Before, such a log failed
/// as increments out of range ("degrees?"), or, with small enough scales, went on.
fn check_samples_cover_the_log(d: &Derived, report: &IngestReport) -> anyhow::Result<()> {
    let (kept, lost) = (d.t_s.len() as u64, report.lost_samples);
    if lost <= kept.saturating_mul(3) {
        return Ok(());
    }
    let span_s = d.t_s.last().unwrap_or(0.0) - d.t_s.first().unwrap_or(0.0);
    let per_sample_s = span_s / kept.saturating_sub(1).max(1) as f64;
    bail!(
        "{lost} IMU samples read as lost against {kept} kept: the log's samples span \
         {span_s:.1} s, {:.1} ms a sample, while its tags step by {:.3} ms (the period \
         taken from them): a log that lost most of its samples has no dead reckoning to \
         correct. If its lines came in bursts the reader did not find (a logger stamping \
         them as it received them; the reader spreads each burst when the log's first \
         lines come so, and any three lines or more close together), write the IMU's own \
         time, or the lines' time spread over each burst",
        per_sample_s * 1e3,
        d.nominal_dt_s * 1e3
    )
}

/// The ingest's account (`ingest.json`) in `ingest_dir`.
pub fn read_ingest_report(ingest_dir: &Path) -> anyhow::Result<IngestReport> {
    let path = ingest_dir.join(files::INGEST_REPORT);
    let bytes = std::fs::read(&path).with_context(|| format!("cannot read {}", path.display()))?;
    serde_json::from_slice(&bytes).with_context(|| format!("{}", path.display()))
}

/// Stage 2, checked once per context and parameters (`RunCtx::ensured_with`; a derive
/// that failed is asked again).
pub fn ensure_derive(ctx: &RunCtx, params: &Params) -> anyhow::Result<PathBuf> {
    let ensured_with = params_hash(params)?;
    if ctx.ensured_with("derive", &ensured_with) {
        return Ok(ctx.layout().dir(StageName::Derive));
    }
    let ingest_dir = ensure_ingest_before_derive(ctx, params)?;
    let m = &ctx.manifest;
    let dir = ctx.layout().create(StageName::Derive)?;
    let inputs = vec![
        ingest_dir.join(files::IMU),
        ingest_dir.join(files::ODOMETER),
        ingest_dir.join(files::INGEST_REPORT),
    ];
    let stage = Stage {
        dir: dir.clone(),
        name: "derive",
        // 7: an odometer count that stood while the vehicle moved counts with the
        // flagged samples against a tenth of the run. 8: the IMU's axes checked. 9: the
        // IMU's mounting measured, a yaw beyond 10° failed. 10: the IMU's increments not
        // stored again (the ingest's, but for imu_repairs.parquet's), r not stored. 11: a
        // time tag that leapt forward alone is repaired alone. 12: the odometer's scale
        // judged on the accelerometers' part it explains (an odometer reading 1/3.6 of
        // the truth was not judged). 13: the odometer's travel backward and its clock
        // judged (a file on another clock, a count reversed, speeds read as distances).
        // 14: an odometer without two rows within the IMU's log failed. 15: the clock's
        // reading kept (derived.parquet's metadata), F's start-up left out of it. 16: an
        // odometer file minutes off searched beyond the setting's reach. 17: the clock
        // read from the odometer's readings only (the ingest's bridges left out). 18: a
        // first or last IMU sample apart from the rest placed beside its neighbour. 19:
        // the time base judged before the odometer (a log in reverse order named so);
        // clocks whole GPS weeks apart named. 20: an odometer whose speed is flat while
        // the turns show it is not the vehicle's failed (a temperature's column); a speed
        // offset told from the gyros' scale (a failure either way: no output changes).
        // 21: a speed steady and not 0 over the static start given failed: an offset (a
        // run that went "ok" with 1 m/s of it is re-derived, and fails) or, barely
        // changing over the log, no speed; clocks in Unix time against GPS time named.
        // 22: a speed held through the stand while the drive reads 0 at its stops failed
        // (a run that went "ok" with its static start cut at once is re-derived, and
        // fails).
        // 23: a binary log's samples told by its `seq`: a sample's interval is its `seq`
        // step times the period (the tags' mean step per `seq` step), not its tags'
        // jittering interval, and a tag late within the recorder's jitter (past half a
        // period) is no gap filled.
        // 24: a text log's samples told by their `seq`, the ingest's slots, as a binary
        // log's: a jittering logger's samples each over the period; a first or last
        // sample apart closes no gap whatever `seq` says.
        // 25: more samples lost than three times those kept fails (tags in bursts): a run
        // that went "ok" so is re-derived, and fails. 26: a stretch of lost samples is
        // filled with the mean of the rates either side (the sample before's and the
        // closing sample's own), not the closing sample's rate held.
        version: 26,
        // The review's sensor blocks are taken here, at the recording's series rate.
        params_hash: params_hash(&(&params.derive, unz_viz::recording::SERIES_RATE_HZ))?,
        inputs,
        outputs: &[
            files::DERIVED,
            files::IMU_REPAIRS,
            files::EPOCHS,
            files::BLOCKS,
            files::SENSORS,
        ],
        hashed_as_read: vec![],
    };
    // What the ingest kept goes now, whether the derive runs or is up to date.
    let written = ctx.take_ingested();
    ctx.run_stage(&stage, || {
        ctx.set_derived(None);
        let raw = match written {
            Some(series) => series,
            None => IngestedSeries::load(&ingest_dir, m.format)?,
        };
        let counts = raw.failure_counts();
        let overlap = raw.odometer_overlap(params.derive.odo_time_offset_s);
        let mut d = raw.derive(&params.derive, site_gravity_mps2(m));
        (d.imu_failure_samples, d.odometer_failure_samples) = counts;
        // A run whose odometer failed over much of it (flagged, or a count that stood
        // while the vehicle moved) has no dead reckoning worth correcting; a short
        // failure is bridged or not, counted and reported (navigate.json, ingest.json).
        let report = read_ingest_report(&ingest_dir)?;
        // Which way the odometer runs and on which clock, before its stands are judged
        // against the vehicle's motion: an odometer on another clock stands while the
        // vehicle drives, and one counting backward turns the axes' check.
        // A few tags going back are repaired and counted; a time base that does not
        // advance (constant or saturated tags) is no time base: judged first, as the
        // odometer's checks read the log's span from its tags.
        if d.repaired_times * 100 > d.t_s.len() {
            // Where: the sample (the ingested tags read again: only a failing run pays for
            // it) and its place in the raw log; a binary log's account lists the faults.
            let first = ingested::first_time_tag_not_increasing(&ingest_dir, d.nominal_dt_s);
            let at = (first.map(|k| format!("the first at {}", sample_at(m, k))))
                .into_iter()
                .chain(time_faults_listed(&ingest_dir.join(files::INGEST_EVENTS)))
                .collect::<Vec<_>>();
            // Tags falling from the first to the last: a file sorted the wrong way.
            let [first_ns, last_ns] = overlap.imu_span_ns;
            let falling = if last_ns < first_ns {
                format!(
                    "; its tags fall from t_s = {:.2} to {:.2}: its lines in reverse order of \
                     time? (write them oldest first)",
                    first_ns as f64 * 1e-9,
                    last_ns as f64 * 1e-9
                )
            } else {
                String::new()
            };
            bail!(
                "{} of {} IMU time tags do not increase (constant, saturated or going back): \
                 the log's time base is broken{}{falling}",
                d.repaired_times,
                d.t_s.len(),
                if at.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", at.join("; "))
                }
            );
        }
        // Samples that cover too little of the log (tags in bursts, most samples lost):
        // a time base too, before the odometer is judged against the IMU's rates and the
        // scaled increments read as out of range.
        check_samples_cover_the_log(&d, &report)?;
        let odometer_file = (report.odometer_file.as_ref()).and(m.odometer.file.as_deref());
        let offset_s = params.derive.odo_time_offset_s;
        check_overlap(&overlap, offset_s, &report, m, odometer_file)?;
        let stand = stand_speed(&d, m, odometer_file);
        check_stand_speed(stand.as_ref(), m, odometer_file)?;
        check_travel(&d, m, odometer_file)?;
        let not_readings_s = not_readings_s(&ingest_dir, &report, &d, offset_s)?;
        d.odometer_clock = check_clock(&d, &params.derive, m, odometer_file, &not_readings_s)
            .map_err(|e| with_log_clock_stepped(e, &report, odometer_file))?;
        let stuck = report.odometer_failures.map_or(0, |f| f.stuck_samples) as usize;
        if (d.odometer_failure_samples + stuck) * 10 > d.t_s.len() {
            let (flagged, n) = (d.odometer_failure_samples, d.t_s.len());
            // Where the flags begin (the ingested flags read again, on this path only).
            let first_flagged = (flagged > 0)
                .then(|| ingested::first_odometer_flagged(&ingest_dir))
                .flatten()
                .map_or_else(String::new, |k| {
                    format!(" (the first at {})", sample_at(m, k))
                });
            match (flagged, stuck) {
                (_, 0) => bail!(
                    "the odometer is flagged failed (status bit 1) on {flagged} of {n} samples\
                     {first_flagged}"
                ),
                (0, _) => bail!(
                    "the odometer's distance stood while the vehicle moved (unflagged) on {stuck} \
                     of {n} samples{}",
                    first_failed_from(m, &ingest_dir)
                ),
                _ => bail!(
                    "the odometer is flagged failed (status bit 1) on {flagged} and its count \
                     stood while the vehicle moved (unflagged) on {stuck} of {n} samples\
                     {first_flagged}"
                ),
            }
        }
        // A corrupt sample that passed the CRC (a 2^-16 chance per damaged frame) or a
        // saturated one is replaced and counted; many are a broken instrument or log.
        if d.out_of_range_samples * 100 > d.t_s.len() {
            // Where: the first.
            let first = d.first_out_of_range;
            bail!(
                "{} of {} IMU samples exceed the IMU's range ({:.0} °/s, {:.0} m/s²): saturated \
                 or corrupt increments, or increments not in radians and m/s (degrees?){}",
                d.out_of_range_samples,
                d.t_s.len(),
                unz_stages::derive::GYRO_RANGE_RAD_S.to_degrees(),
                unz_stages::derive::ACCEL_RANGE_MPS2,
                first.map_or_else(String::new, |k| format!(
                    " (the first at {})",
                    sample_at(m, k)
                ))
            );
        }
        // A gap is bridged from the rates either side of it: beyond a few seconds, the turns
        // and the gyros' noise in it would be a step in the heading no setting explains.
        let max_gap_s = params.derive.max_gap_s;
        if d.nominal_dt_s > max_gap_s {
            bail!(
                "the IMU log's sample interval (the median step of its time tags) is {:.3} s, \
                 longer than derive.max_gap_s = {max_gap_s} s: no IMU's rate{}",
                d.nominal_dt_s,
                tag_unit_hint(d.nominal_dt_s)
            );
        }
        if let Some(k) = d.dt_s.iter().position(|&dt| dt > max_gap_s) {
            bail!(
                "the IMU log has a gap of {:.2} s after t = {:.2} s (before {}): dead \
                 reckoning does not bridge more than derive.max_gap_s = {max_gap_s} s (the \
                 turns and the gyros' noise in it are unknown); split the run there, or raise \
                 max_gap_s for a pause at rest",
                d.dt_s[k],
                d.t_s.get(k) - d.dt_s[k],
                sample_at(m, k)
            );
        }
        let (dtheta, dvel) = (d.dtheta_rad.view().iter(), d.dvel_mps.iter());
        ensure_finite(
            "angle increment",
            "sample",
            dtheta.map(|v| not_finite_of(&v)),
        )?;
        ensure_finite("velocity increment", "sample", dvel.map(not_finite_of))?;
        ensure_finite("odometer distance", "sample", d.odo_dist_m.iter().copied())?;
        let (pitch, roll) = (d.epochs.theta_p_rad.iter(), d.epochs.phi_p_rad.iter());
        ensure_finite("accelerometer pitch", "epoch", pitch.copied())?;
        ensure_finite("accelerometer roll", "epoch", roll.copied())?;
        let g_mps2 = site_gravity_mps2(m);
        let axes = check_axes(&d, &params.vehicle, g_mps2, m, odometer_file)?;
        check_stand_flat(stand.as_ref(), m, odometer_file)?;
        d.axes_check = Some(axes);
        write_derived(&d, &dir)?;
        let mut d = as_stored(d);
        // Beyond the static start (which the alignment reads from the file), only the
        // review reads the velocity increments: its blocks are taken now, and the chain
        // keeps the derive without them.
        write_review_sensors(&review_sensors(&d), &dir.join(files::SENSORS))?;
        d.dvel_mps = Arc::default();
        ctx.set_derived(Some(Arc::new(d)));
        Ok(())
    })?;
    ctx.set_ensured("derive", ensured_with);
    Ok(dir)
}

/// An IMU's sample interval, s: 1 kHz to 1 Hz.
const IMU_INTERVALS_S: std::ops::RangeInclusive<f64> = 1e-3..=1.0;

/// " (time tags in milliseconds?)" when a sample interval read as `interval_s` is an
/// IMU's in a smaller unit of time; empty otherwise.
fn tag_unit_hint(interval_s: f64) -> String {
    (SMALLER_UNITS.into_iter())
        .find(|(_, unit_s)| IMU_INTERVALS_S.contains(&(interval_s * unit_s)))
        .map_or_else(String::new, |(name, unit_s)| {
            format!(
                " (time tags in {name}? {} s then: the log's time tags must be in seconds)",
                interval_s * unit_s
            )
        })
}

/// " (the first from PLACE)": where the odometer's first failure (its first row of
/// `odometer.parquet` whose distance is not a reading) begins in the raw log, the IMU
/// sample that carries it ([`imu_sample_place`]) or its time tag; empty without one.
fn first_failed_from(m: &RunManifest, ingest_dir: &Path) -> String {
    let Some(t_ns) = IngestedSeries::load_failed_rows(ingest_dir)
        .ok()
        .and_then(|(spans, _)| spans.first().map(|s| s.first_t_ns))
    else {
        return String::new();
    };
    match imu_sample_place(m, KeptSample::TagNs(t_ns)) {
        Some(place) => format!(" (the first from {place})"),
        None => format!(" (the first from the time tag {} s)", seconds(t_ns)),
    }
}

/// "sample K" and, when the raw log can be read again, its place there ("sample K, byte
/// offset N of LOG" or "sample K, line N of LOG"): [`imu_sample_place`].
fn sample_at(m: &RunManifest, k: usize) -> String {
    match imu_sample_place(m, KeptSample::Row(k)) {
        Some(place) => format!("sample {k}, {place}"),
        None => format!("sample {k}"),
    }
}

/// "EVENTS lists the first faults" when the ingest's account (`ingest_events.json`) holds
/// a time tag that did not increase: a binary log's (a text log's tags are not events).
fn time_faults_listed(events_path: &Path) -> Option<String> {
    let events: IngestEvents = read_report(events_path)?;
    (events.events.iter())
        .any(|e| e.kind == FaultKind::TimeNotIncreasing)
        .then(|| format!("{} lists the first faults", events_path.display()))
}

/// Fails unless every value is finite, naming the quantity and the first `unit` (its
/// index: "sample", "epoch") that is not: a stage never records outputs that went to Inf
/// or NaN.
pub fn ensure_finite(
    what: &str,
    unit: &str,
    values: impl IntoIterator<Item = f64>,
) -> anyhow::Result<()> {
    if let Some((k, v)) = values.into_iter().enumerate().find(|(_, v)| !v.is_finite()) {
        bail!("{what} is {v} at {unit} {k}: the input's scales or values are not physical");
    }
    Ok(())
}

/// A vector's first component that is not finite, else 0: the vector as one value for
/// [`ensure_finite`], which then names its sample.
fn not_finite_of(v: &[f64; 3]) -> f64 {
    v.iter().copied().find(|x| !x.is_finite()).unwrap_or(0.0)
}

/// Normal gravity at the run's site, m/s² (derive's g).
pub fn site_gravity_mps2(m: &RunManifest) -> f64 {
    earth::normal_gravity_mps2(m.site.latitude_deg.to_radians(), m.site.height_m)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 100-Hz log's tags in milliseconds step by 10 (a 10-Hz one's by 100), in
    /// microseconds by 10 000: named; a long step in seconds is none of them.
    #[test]
    fn time_tags_in_a_smaller_unit_are_named() {
        assert_eq!(
            tag_unit_hint(10.0),
            " (time tags in milliseconds? 0.01 s then: the log's time tags must be in seconds)"
        );
        assert!(tag_unit_hint(100.0).contains("milliseconds? 0.1 s"));
        assert!(tag_unit_hint(10_000.0).contains("microseconds? 0.01 s"));
        assert!(tag_unit_hint(1e7).contains("nanoseconds? 0.01 s"));
        assert_eq!(tag_unit_hint(0.5), "");
    }

    /// A value that is not finite is named by its index in the unit given, a vector's by
    /// its sample (not by its component's place in the flattened values).
    #[test]
    fn the_first_value_not_finite_is_named_by_its_sample() {
        let v = [[0.0, 1.0, 2.0], [3.0, 4.0, 5.0], [6.0, f64::NAN, 8.0]];
        let err = ensure_finite("angle increment", "sample", v.iter().map(not_finite_of));
        let err = err.unwrap_err();
        assert_eq!(
            err.to_string(),
            "angle increment is NaN at sample 2: the input's scales or values are not physical"
        );
        let err = ensure_finite("roll", "epoch", [0.0, f64::INFINITY]).unwrap_err();
        assert!(
            err.to_string().starts_with("roll is inf at epoch 1:"),
            "{err}"
        );
        ensure_finite("roll", "epoch", [0.0, -1e308]).unwrap();
    }

    /// The stages of a chain each ask for the derive: one context checks it once for the
    /// same parameters, and again for others.
    #[test]
    fn the_derive_is_checked_once_per_context_and_parameters() {
        let tmp = tempfile::tempdir().unwrap();
        let ctx = crate::simulate_io::simulated_ctx(tmp.path(), "once", 5, 300.0).unwrap();
        let stages = |ctx: &RunCtx| -> Vec<(String, bool)> {
            let log = ctx.log.lock().unwrap();
            log.iter()
                .map(|(s, computed, _)| (s.clone(), *computed))
                .collect()
        };
        let params = Params::default();
        ensure_derive(&ctx, &params).unwrap();
        ensure_derive(&ctx, &params).unwrap();
        ensure_ingest(&ctx, &params).unwrap();
        let computed = vec![("ingest".to_owned(), true), ("derive".to_owned(), true)];
        assert_eq!(stages(&ctx), computed);
        // Other derive parameters: the derive again (the ingest's are the same, but it is
        // asked for the derive's new parameters).
        let mut other = params;
        other.derive.gate_long_mps2 *= 2.0;
        ensure_derive(&ctx, &other).unwrap();
        let log = stages(&ctx);
        assert_eq!(log.len(), 4, "{log:?}");
        assert_eq!(log[3], ("derive".to_owned(), true));
        // The ingest asked for with other parameters of its own runs again: the derive
        // after it is checked again (up to date: `raw.mcap`'s compression leaves the
        // tables it reads as they were).
        let mut zstd = other;
        zstd.ingest.raw_mcap_compression = unz_formats::mcap_io::McapCompression::Zstd;
        ensure_ingest(&ctx, &zstd).unwrap();
        ensure_derive(&ctx, &other).unwrap();
        let log = stages(&ctx);
        assert_eq!(
            log[4..],
            [
                ("ingest".to_owned(), true),
                ("ingest".to_owned(), true),
                ("derive".to_owned(), false)
            ],
            "{log:?}"
        );
        // A new context (another process) checks the records again.
        let again = RunCtx::new(ctx.manifest.clone(), ctx.out.clone(), false);
        ensure_derive(&again, &other).unwrap();
        assert_eq!(
            stages(&again),
            vec![("ingest".to_owned(), false), ("derive".to_owned(), false)]
        );
    }
}
