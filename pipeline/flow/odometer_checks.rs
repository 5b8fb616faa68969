//! The derive's checks of the odometer against the IMU's log: whether it has readings
//! within the log ([`check_overlap`]), which way its distance runs ([`Travel`]) and which
//! clock its time tags keep ([`ClockFit`]). Each names the setting or the file that fixes
//! what it finds; all come before the watch of its stands and the axes' check, whose
//! verdicts an odometer outside the log, counting backward or on another clock would
//! mislead.

use std::path::Path;

use anyhow::bail;
use unz_formats::IngestReport;
use unz_formats::kfgins::GPS_WEEK_S;
use unz_formats::manifest::{LogFormat, OdometerKind, RunManifest};
use unz_stages::derive::{DeriveParams, Derived, ODO_TIME_OFFSET_RANGE_S};
use unz_stages::odo_clock::{ClockFit, MAX_ODOMETER_LAG_S};
use unz_stages::odo_travel::{Travel, TravelVerdict};
use unz_stages::stand_speed::{MIN_DRIVE_SIGMA_MPS, StandSpeed};

use super::axes::{not_speed_fix, offset_fix};
use super::ingested::OdometerOverlap;
use super::unix_clock::UnixAgainstGps;

/// Where the odometer's distance comes from, in `m`'s log: `file` is the odometer file
/// the ingest read (none for a binary log or an 8th column).
pub(crate) enum Source<'a> {
    /// A binary log's pulse count.
    Count,
    /// A text log's 8th column.
    Column,
    /// An odometer file of the kind given.
    File(&'a Path, OdometerKind),
}

impl<'a> Source<'a> {
    pub(crate) fn of(m: &RunManifest, file: Option<&'a Path>) -> Self {
        match (m.format, file) {
            (LogFormat::UnzBinary, _) => Self::Count,
            (LogFormat::KfGins, None) => Self::Column,
            (LogFormat::KfGins, Some(f)) => {
                Self::File(f, m.odometer.kind.unwrap_or(OdometerKind::SpeedMps))
            }
        }
    }

    /// "the odometer file odometer.txt".
    pub(crate) fn name(&self) -> String {
        match self {
            Self::Count => "the log's odometer count".to_owned(),
            Self::Column => "the log's 8th column (the odometer's speed)".to_owned(),
            Self::File(f, _) => format!("the odometer file {}", f.display()),
        }
    }
}

/// The speed of `d`'s odometer over the static start the manifest gives, when it reads
/// steady and not 0 there ([`StandSpeed`]); none for an odometer of counts or distances.
/// Read once, for [`check_stand_speed`] and [`check_stand_flat`].
pub fn stand_speed(d: &Derived, m: &RunManifest, file: Option<&Path>) -> Option<StandSpeed> {
    let speeds = match Source::of(m, file) {
        Source::Column => true,
        Source::File(_, kind) => kind.is_speed(),
        Source::Count => false,
    };
    (m.initial.static_s)
        .filter(|_| speeds)
        .and_then(|given_s| StandSpeed::of(d, given_s))
}

/// Fails when the odometer's speed reads steady and not 0 over the static start the
/// manifest gives (`stand`), as an offset of every reading ([`StandSpeed::is_offset`]):
/// its readings' zero is off (a speed decoded with a wrong offset), named with the speed
/// to subtract; or as a reading held while the drive reads 0 at its stops
/// ([`StandSpeed::is_held`]), named with the stretch to write 0 over. Before the travel's
/// check, which an offset below zero turns into backward travel.
pub fn check_stand_speed(
    stand: Option<&StandSpeed>,
    m: &RunManifest,
    file: Option<&Path>,
) -> anyhow::Result<()> {
    let source = Source::of(m, file);
    if let Some(s) = stand.filter(|s| s.is_held()) {
        bail!(
            "{}, yet the log reads 0 at the drive's stops ({:.1} % of its readings): the \
             stand's speed is a reading held (a logger repeating its last one?), or the \
             vehicle drove where it stood, and the alignment has no stand (the odometer \
             moves from the log's first second). {}, or set static_s to the time the \
             vehicle stood if it drove",
            stand_read(&source, s),
            100.0 * s.stopped_share,
            held_fix(&source, s),
        );
    }
    let Some(s) = stand.filter(|s| s.is_offset()) else {
        return Ok(());
    };
    let offset_mps = s.mean_mps.abs();
    let read = stand_read(&source, s);
    let (adds, mend) = if s.mean_mps > 0.0 {
        ("adds", format!("subtract {offset_mps:.2} m/s from each"))
    } else {
        ("takes", format!("add {offset_mps:.2} m/s to each"))
    };
    bail!(
        "{read}: its readings' zero is off (a speed decoded with a wrong offset?), which \
         {adds} {offset_mps:.2} m/s to every reading of the drive. {} ({mend}), or set \
         static_s to the time the vehicle stood if it drove",
        offset_fix(&source),
    )
}

/// Fails when the odometer's speed reads steady and not 0 over the static start the
/// manifest gives (`stand`) and barely changes over the whole log ([`StandSpeed::drove`] not): no
/// speed at all (a column of a temperature, or flat near the vehicle's speed in its
/// turns, which the axes' check takes for one). After the axes' check, whose verdict on
/// a flat column names the gain its turns show.
pub fn check_stand_flat(
    stand: Option<&StandSpeed>,
    m: &RunManifest,
    file: Option<&Path>,
) -> anyhow::Result<()> {
    let source = Source::of(m, file);
    let Some(s) = stand.filter(|s| !s.drove()) else {
        return Ok(());
    };
    bail!(
        "{}, and barely changes over the whole log (σ {:.2} m/s, where a drive's speeds \
         spread {MIN_DRIVE_SIGMA_MPS} m/s or more): it is not the vehicle's speed. {}",
        stand_read(&source, s),
        s.log_sigma_mps,
        not_speed_fix(&source, &m.odometer.value_column_said()),
    )
}

/// What to write where `source` held the stand's speed `s` (from the log's start until it
/// left it).
fn held_fix(source: &Source, s: &StandSpeed) -> String {
    let over = format!(
        "over the log's first {:.0} s, where it reads {:.2} m/s, if the vehicle stood",
        s.left_s, s.mean_mps
    );
    match source {
        Source::File(file, _) => format!("Write 0 for the speeds of {} {over}", file.display()),
        _ => format!("Write 0 in the log's 8th column {over}"),
    }
}

/// What `source` read over the static start given: "the odometer file … reads 1.00 m/s,
/// steady (σ 0.000 m/s), over the first 250 s of the static start given (static_s = 500
/// s), where the vehicle stood".
fn stand_read(source: &Source, s: &StandSpeed) -> String {
    format!(
        "{} reads {:.2} m/s, steady (σ {:.3} m/s), over the first {:.0} s of the static start \
         given (static_s = {} s), where the vehicle stood",
        source.name(),
        s.mean_mps,
        s.sigma_mps,
        s.read_s,
        s.given_s,
    )
}

/// Fails `d` when its odometer's distance runs backward over most of its travel (its sign
/// reversed) or about as much as ahead (no distance: speeds read as distances), naming
/// where to fix it.
pub fn check_travel(d: &Derived, m: &RunManifest, file: Option<&Path>) -> anyhow::Result<()> {
    let travel = Travel::of(d);
    let source = Source::of(m, file);
    let share = format!(
        "{} runs backward over {:.0} % of its travel ({:.0} m back, {:.0} m ahead)",
        source.name(),
        100.0 * travel.backward_share(),
        travel.back_m,
        travel.ahead_m
    );
    match travel.verdict() {
        TravelVerdict::Ahead => Ok(()),
        TravelVerdict::Reversed => {
            let fix = match source {
                Source::Count => "the count must rise as the vehicle drives ahead (the \
                                  counter's direction is wired reversed)"
                    .to_owned(),
                Source::Column => "write the column's speeds positive ahead".to_owned(),
                Source::File(f, kind) if kind.is_speed() => {
                    format!("write the speeds of {} positive ahead", f.display())
                }
                Source::File(f, _) => format!(
                    "write the distances of {} rising as the vehicle drives ahead",
                    f.display()
                ),
            };
            bail!(
                "{share}: its sign is reversed; {fix}. (Its accelerations are then the \
                 accelerometers' turned by 180°, as an IMU facing backwards would make them: \
                 mend the odometer's sign before the IMU's axes.)"
            )
        }
        TravelVerdict::BackAndForth => {
            let hint = match source {
                Source::File(f, OdometerKind::DistanceM) => format!(
                    ": are the values of {} speeds? They are read as distances ([odometer] \
                     kind = \"distance_m\"); name their kind (\"speed_mps\", \"speed_kmh\")",
                    f.display()
                ),
                Source::File(f, _) => format!(": check the sign of the speeds of {}", f.display()),
                Source::Column => ": check the sign of the column's speeds".to_owned(),
                Source::Count => ": a count that runs back and forth".to_owned(),
            };
            bail!(
                "{share}, {:.0} m net: no distance a vehicle drives (it reverses metres in \
                 kilometres){hint}",
                travel.ahead_m - travel.back_m
            )
        }
    }
}

/// What `d`'s drive says of its odometer's clock at the derive's `params`'
/// `odo_time_offset_s` (searched over the lags the setting then takes,
/// ±[`ODO_TIME_OFFSET_RANGE_S`]); fails when it shows the odometer's time tags on another
/// clock than the IMU's (a lag beyond [`MAX_ODOMETER_LAG_S`]), naming the offset that
/// aligns them. An odometer file whose drive the setting's reach shows nowhere is
/// searched beyond it ([`ClockFit::far`]): a logger's clock set minutes off.
pub fn check_clock(
    d: &Derived,
    params: &DeriveParams,
    m: &RunManifest,
    file: Option<&Path>,
    not_readings_s: &[[f64; 2]],
) -> anyhow::Result<Option<ClockFit>> {
    let offset_s = params.odo_time_offset_s;
    let lags = offset_s - ODO_TIME_OFFSET_RANGE_S..=offset_s + ODO_TIME_OFFSET_RANGE_S;
    // F's start-up is left out: a log begun while driving starts its u̇ from one
    // block's pulses (0.46–0.67 s of lag read on 5 of 14 simulated such logs).
    let edge_s = params.filter.settling_s();
    // So are the ingest's bridges: the inertial speed's, at no shift whatever the clock.
    let fit = ClockFit::of_readings(d, lags, edge_s, not_readings_s);
    let source = Source::of(m, file);
    if let Some(f) = fit.filter(ClockFit::off) {
        bail!(another_clock(&source, f, f.correlation_as_given, offset_s));
    }
    if let (Source::File(..), Some(near)) = (&source, fit)
        && let Some(f) = far_clock(d, near, edge_s, not_readings_s)
    {
        bail!(another_clock(
            &source,
            f,
            near.correlation_as_given,
            offset_s
        ));
    }
    Ok(fit)
}

/// The clock of an odometer file beyond the setting's reach: when the drive shows it
/// nowhere within the reach (`near`, the fit there), the far fit, when it is shown
/// beyond the odometer's own delay and at least twice as well as anything within the
/// reach (the clock as given included, either sign: an IMU facing backwards correlates
/// −0.9 there, and is the axes' check's). A file whose driving the shift moves out of
/// the IMU's log (Kingston's 300 s late: its stand of 527 s where the IMU drives) has
/// too little left to show it; its stands while the vehicle moves fail the run.
fn far_clock(
    d: &Derived,
    near: ClockFit,
    edge_s: f64,
    not_readings_s: &[[f64; 2]],
) -> Option<ClockFit> {
    if near.shown() {
        return None;
    }
    let near_best = near.correlation.max(near.correlation_as_given.abs());
    ClockFit::far(d, edge_s, not_readings_s).filter(|f| f.off() && f.correlation >= 2.0 * near_best)
}

/// The failure of an odometer (`source`) whose drive `f` shows on another clock: its
/// correlation `as_given` (at the offset `offset_s` configured) and the offset that
/// aligns it; beyond the ±[`ODO_TIME_OFFSET_RANGE_S`] the setting takes, the shift to
/// write into the file's time tags.
fn another_clock(source: &Source, f: ClockFit, as_given: f64, offset_s: f64) -> String {
    let (late, moved) = if f.lag_s > 0.0 {
        ("late", "earlier")
    } else {
        ("early", "later")
    };
    let configured = if offset_s == 0.0 {
        String::new()
    } else {
        format!(", with [derive] odo_time_offset_s = {offset_s}")
    };
    // A binary log's count rides in the IMU's records: one clock, a counter's delay.
    let runs = match source {
        Source::Count => format!(
            "{} runs {:.1} s {late} against the IMU's increments in the same records",
            source.name(),
            f.lag_s.abs()
        ),
        _ => format!(
            "{}'s time tags run {:.1} s {late} against the IMU's, another clock's",
            source.name(),
            f.lag_s.abs()
        ),
    };
    let aligning_s = offset_s - f.lag_s;
    let fix = match source {
        Source::File(file, _) if aligning_s.abs() > ODO_TIME_OFFSET_RANGE_S => format!(
            "Add {:.1} s to each of the time tags of {} (beyond the ±{ODO_TIME_OFFSET_RANGE_S} \
             s [derive] odo_time_offset_s takes)",
            -f.lag_s,
            file.display()
        ),
        _ => format!(
            "Set [derive] odo_time_offset_s = {aligning_s:.1} (in the campaign's --config, or \
             the run's [params.derive])"
        ),
    };
    format!(
        "{runs}: the accelerometers' x follows the odometer's accelerations best with the \
         odometer {:.1} s {moved} (correlation {:.2}, against {as_given:.2} as it \
         is{configured}), beyond the ±{MAX_ODOMETER_LAG_S} s of an odometer's own delay. \
         {fix}",
        f.lag_s.abs(),
        f.correlation,
    )
}

/// Least odometer rows within the IMU's log for a distance to be derived: two readings
/// make an interval.
pub const MIN_ROWS_WITHIN: usize = 2;

/// Fails a run whose odometer has fewer than [`MIN_ROWS_WITHIN`] rows within the IMU's
/// log (with the offset `offset_s` configured): the derive would hold its distance over
/// the whole log, and the navigate blame the control points. Names why, as far as the
/// ingest's account (`report`) and the two spans tell: the file's lines rejected, time
/// tags in a smaller unit, or another clock.
pub fn check_overlap(
    o: &OdometerOverlap,
    offset_s: f64,
    report: &IngestReport,
    m: &RunManifest,
    file: Option<&Path>,
) -> anyhow::Result<()> {
    if o.within >= MIN_ROWS_WITHIN {
        return Ok(());
    }
    let s = |t_ns: i64| t_ns as f64 * 1e-9;
    let [i0, i1] = o.imu_span_ns.map(s);
    let [o0, o1] = o.odometer_span_ns.map(s);
    let offset = if offset_s == 0.0 {
        String::new()
    } else {
        format!(", before [derive] odo_time_offset_s = {offset_s} is added")
    };
    let lines = report.odometer_file.as_ref();
    // A file that rolled over itself has tags the ingest moved: one shift written into
    // the file would not bring its rows before and after the rollover alike, and none is
    // named.
    let rolled_over = lines.is_some_and(|l| l.week_rollovers + l.day_rollovers > 0);
    let why = if let Some(l) = lines.filter(|l| l.lines_rejected >= l.lines_accepted) {
        format!(
            "the ingest rejected {} of its {} lines (ingest_events.json gives their lines and \
             reasons)",
            l.lines_rejected, l.lines_read
        )
    } else if let Some((log, name, [a, b])) =
        SMALLER_UNITS.into_iter().find_map(|(name, unit_s)| {
            let (odo, imu) = ([o0, o1].map(|t| t * unit_s), [i0, i1].map(|t| t * unit_s));
            if spans_meet(odo, [i0, i1]) {
                Some(("its", name, odo))
            } else if spans_meet(imu, [o0, o1]) {
                Some(("the IMU log's", name, imu))
            } else {
                None
            }
        })
    {
        format!(
            "{log} time tags read in {name} would run t_s = {a:.2} to {b:.2}: write them in seconds"
        )
    } else if let Some(said) = on_unix_clock([o0, o1], [i0, i1])
        && !rolled_over
    {
        said
    } else if let Some(shift_s) = whole_hours_apart_s([o0, o1], [i0, i1])
        && !rolled_over
    {
        let (apart, in_weeks) = shift_named(shift_s);
        let (to_hour, why) = if in_weeks {
            (
                "",
                "GPS seconds of week against GPS seconds since the weeks' start (6 January \
                 1980), the one clock counted from two starts?",
            )
        } else {
            (
                ", to the hour",
                "a time zone's or a day's difference, or UTC seconds of day against the \
                 IMU's GPS seconds of week?",
            )
        };
        format!(
            "its time tags run {apart} {} the IMU's{to_hour} ({why}): add {shift_s} s to each \
             of its time tags, and the clock check will read the seconds left (GPS time runs \
             18 s ahead of UTC)",
            if shift_s > 0.0 { "before" } else { "after" },
        )
    } else {
        "its time tags are not the IMU's clock (another day's, a time zone's, or counted \
         from another start?): write them on the IMU's clock ([derive] odo_time_offset_s \
         shifts them by a minute at most)"
            .to_owned()
    };
    bail!(
        "{} has {} of its {} rows within the IMU log (t_s = {i0:.2} to {i1:.2}), where it \
         runs t_s = {o0:.2} to {o1:.2}{offset}: no distance to derive; {why}",
        Source::of(m, file).name(),
        o.within,
        o.rows
    )
}

/// Why the odometer's time tags (spanning `odo`, s) miss the IMU log's (`imu`) when one
/// of them is Unix time and the other GPS time ([`UnixAgainstGps`]), with the shift that
/// brings them onto the IMU's clock; `None` for other clocks. In seconds only: a
/// logger's Unix milliseconds are beyond the times the ingest takes, which names them.
fn on_unix_clock(odo: [f64; 2], imu: [f64; 2]) -> Option<String> {
    let u = UnixAgainstGps::between(odo, imu)?;
    let (unix, gps) = (u.unix_clock(), u.gps_clock());
    let clocks = if u.other_is_unix {
        format!("its time tags are {unix} and the IMU's {gps}")
    } else {
        format!("the IMU log's time tags are {unix} and its {gps}")
    };
    Some(format!(
        "{clocks}: add {} s to each of its time tags ({})",
        u.shift_s,
        u.parts()
    ))
}

/// Farthest apart, s, two clocks are named a whole number of hours apart: a week (a log
/// in seconds of week against one in seconds of day on the week's last day).
pub(crate) const WHOLE_HOURS_REACH_S: f64 = 7.0 * 86_400.0;

/// The whole number of hours, s, that added to the odometer's span `odo` (s) brings it
/// onto the IMU's `imu`: the spans' starts, ends and middles, each brought together to
/// the hour, must agree on it (a file covering part of the log: its start's or its
/// end's), and overlap the spans by half the shorter or more; `None` when they do not,
/// for no hour, or beyond [`WHOLE_HOURS_REACH_S`]. A short file in a long log lies hours
/// apart from each end: no hour is named. To the hour only: what is left (a minute's
/// clock error, UTC's 18 s behind GPS time) is the clock check's to read. Beyond a week,
/// a whole number of GPS weeks ([`whole_weeks`]): one log in seconds of week, the other
/// in seconds since GPS time's start.
fn whole_hours_apart_s(odo: [f64; 2], imu: [f64; 2]) -> Option<f64> {
    let to_hour = |s: f64| (s / 3600.0).round() * 3600.0;
    let overlap = |shift_s: f64| imu[1].min(odo[1] + shift_s) - imu[0].max(odo[0] + shift_s);
    let shorter = (odo[1] - odo[0]).min(imu[1] - imu[0]);
    let mid = |s: [f64; 2]| 0.5 * (s[0] + s[1]);
    let [a, b, c] = [mid(imu) - mid(odo), imu[0] - odo[0], imu[1] - odo[1]].map(to_hour);
    let reach = a.abs() <= WHOLE_HOURS_REACH_S || whole_weeks(a).is_some();
    (a == b && b == c && a != 0.0 && reach)
        .then_some(a)
        .filter(|&s| overlap(s) >= 0.5 * shorter)
}

/// The number of GPS weeks in `shift_s` when it is two or more whole weeks (up to
/// [`MAX_GPS_WEEKS`]): a clock in GPS seconds of week against one in seconds since GPS
/// time's start (6 January 1980), which differ by the week number's weeks exactly.
pub(crate) fn whole_weeks(shift_s: f64) -> Option<u64> {
    let weeks = (shift_s / GPS_WEEK_S).round();
    (weeks.abs() >= 2.0 && weeks.abs() <= MAX_GPS_WEEKS && weeks * GPS_WEEK_S == shift_s)
        .then_some(weeks.abs() as u64)
}

/// A whole shift between two clocks as said, and whether in weeks: "1480 GPS weeks"
/// ([`whole_weeks`]), else "1 day and 2 hours" ([`hours_and_days`]).
pub(crate) fn shift_named(shift_s: f64) -> (String, bool) {
    match whole_weeks(shift_s) {
        Some(weeks) => (format!("{weeks} GPS weeks"), true),
        None => (hours_and_days(shift_s.abs()), false),
    }
}

/// The most GPS weeks a shift is named in: a century of them.
const MAX_GPS_WEEKS: f64 = 5_300.0;

/// "1 day and 2 hours" of `s` seconds, a whole number of hours.
pub(crate) fn hours_and_days(s: f64) -> String {
    let hours = (s / 3600.0).round() as u64;
    let plural = |n: u64, what: &str| format!("{n} {what}{}", if n == 1 { "" } else { "s" });
    match (hours / 24, hours % 24) {
        (0, h) => plural(h, "hour"),
        (d, 0) => plural(d, "day"),
        (d, h) => format!("{} and {}", plural(d, "day"), plural(h, "hour")),
    }
}

/// Units of time a log's tags may be written in instead of seconds, with their size in
/// seconds.
pub(crate) const SMALLER_UNITS: [(&str, f64); 3] = [
    ("milliseconds", 1e-3),
    ("microseconds", 1e-6),
    ("nanoseconds", 1e-9),
];

/// Whether the spans `a` and `b` (s) overlap by half of `b` or more.
fn spans_meet(a: [f64; 2], b: [f64; 2]) -> bool {
    let overlap = a[1].min(b[1]) - a[0].max(b[0]);
    overlap >= 0.5 * (b[1] - b[0])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two clocks a whole number of hours apart (a day and 18 s, a time zone's 5 hours)
    /// are named to the hour when the shift brings the spans together; none for spans
    /// that do not meet so, nor beyond a week.
    #[test]
    fn clocks_whole_hours_apart_are_named_to_the_hour() {
        let imu: [f64; 2] = [152_143.09, 153_018.99];
        let odo = |shift_s: f64| imu.map(|t| t.round() + shift_s);
        assert_eq!(whole_hours_apart_s(odo(-86_418.0), imu), Some(86_400.0));
        assert_eq!(whole_hours_apart_s(odo(5.0 * 3600.0), imu), Some(-18_000.0));
        assert_eq!(whole_hours_apart_s(odo(-1_800.0), imu), None);
        assert_eq!(whole_hours_apart_s(odo(-8.0 * 86_400.0), imu), None);
        assert_eq!(whole_hours_apart_s(odo(100.0), imu), None);
        // A file that covers the log's last two minutes, written after midnight in
        // seconds of day beside the log's tags unwrapped past it.
        let log = [85_650.09, 86_525.99];
        assert_eq!(whole_hours_apart_s([0.0, 126.0], log), Some(86_400.0));
        // A two-minute file a day off in a 10-hour log: its start and its end disagree.
        let long = [0.0, 36_000.0];
        assert_eq!(whole_hours_apart_s([-86_400.0, -86_280.0], long), None);
        // GPS seconds since 1980 against seconds of week: 1480 weeks, not a day or an hour
        // more.
        let weeks = 1480.0 * GPS_WEEK_S;
        assert_eq!(whole_hours_apart_s(odo(-weeks), imu), Some(weeks));
        assert_eq!(whole_hours_apart_s(odo(-weeks - 86_400.0), imu), None);
        assert_eq!(
            (whole_weeks(weeks), whole_weeks(GPS_WEEK_S)),
            (Some(1480), None)
        );
        assert_eq!(hours_and_days(86_400.0), "1 day");
        assert_eq!(hours_and_days(5.0 * 3600.0), "5 hours");
        assert_eq!(hours_and_days(2.0 * 86_400.0 + 3600.0), "2 days and 1 hour");
    }

    /// The overlap's failure names a day's shift for a file written a day off, and none
    /// for one whose own rollover the ingest unwrapped (a single shift written into it
    /// would move its rows before and after the rollover apart).
    #[test]
    fn no_shift_is_named_for_a_file_that_rolled_over_itself() {
        let text = "name = \"r\"\nraw = \"imu.txt\"\nformat = \"kf-gins\"\n\
                    [site]\nlatitude_deg = 44.2\nlongitude_deg = -76.5\nheight_m = 40.0\n\
                    [odometer]\nfile = \"odometer.txt\"\nkind = \"speed_mps\"\n";
        let m = RunManifest::parse(text, Path::new("/c/r/run.toml")).unwrap();
        let ns = |s: f64| (s * 1e9) as i64;
        let overlap = OdometerOverlap {
            rows: 900,
            within: 0,
            odometer_span_ns: [ns(86_390.0), ns(87_290.0)],
            imu_span_ns: [ns(0.0), ns(890.0)],
        };
        let said = |day_rollovers: u64| {
            let report = IngestReport {
                odometer_file: Some(unz_formats::OdometerFileReport {
                    lines_read: 900,
                    lines_accepted: 900,
                    day_rollovers,
                    ..Default::default()
                }),
                ..IngestReport::default()
            };
            let file = Some(Path::new("/c/r/odometer.txt"));
            check_overlap(&overlap, 0.0, &report, &m, file)
                .unwrap_err()
                .to_string()
        };
        assert!(
            said(0).contains("add -86400 s to each of its time tags"),
            "{}",
            said(0)
        );
        assert!(
            said(1).contains("its time tags are not the IMU's clock"),
            "{}",
            said(1)
        );
    }
}
