//! The derive's check of the log's IMU axes against the vehicle's (FRD), with the
//! setting that fixes a log written in other axes, and of the scales the same fit shows
//! (the odometer's distance in metres, the gyros' increments in radians).

use std::path::Path;

use anyhow::bail;
use unz_formats::manifest::{LogFormat, OdometerKind, RunManifest};
use unz_stages::derive::Derived;
use unz_stages::imu_axes::{
    AxesCheck, AxesVerdict, GRAVITY_TOLERANCE, ImuAxes, MAX_TILT_DEG, SCALE_GAIN_RANGE, SpeedOffset,
};
use unz_stages::imu_mounting::{self, MAX_MOUNTING_YAW_DEG};
use unz_stages::units::UnitRatio;

use super::odometer_checks::Source;
use crate::flow::VehicleParams;

/// Checks `d` (ingested in the axes and mounting `vehicle` names, from the run
/// `manifest` with its `odometer_file` when the ingest read one) against gravity
/// `g_mps2`: fails when its gravity or its odometer says its axes are not the vehicle's,
/// or its IMU is yawed on its mount more than the joint fit takes, naming the setting
/// that fixes it, or its units are not metres, seconds and radians, naming where to fix
/// them. A log shorter than [`unz_stages::imu_axes::CHECK_MIN_S`] is not judged.
pub fn check_axes(
    d: &Derived,
    vehicle: &VehicleParams,
    g_mps2: f64,
    manifest: &RunManifest,
    odometer_file: Option<&Path>,
) -> anyhow::Result<AxesCheck> {
    let declared = vehicle.imu_axes;
    let check = AxesCheck::of(d);
    // The settings that would take what the drive shows: the turn the increments still
    // show, after the mounting and the axes named.
    let settings = check.mounting_deg.map(|seen| {
        let named = imu_mounting::rotation(vehicle.imu_mounting_deg).unwrap_or_default();
        let seen = imu_mounting::rotation(seen).unwrap_or_default();
        settings_for(seen * named * declared.body_from_log())
    });
    let mounting_setting = |(axes, m): (ImuAxes, [f64; 3])| {
        let axes = if axes == declared {
            String::new()
        } else {
            format!("[vehicle] imu_axes = \"{axes}\" and ")
        };
        format!(
            "{axes}[vehicle] imu_mounting_deg = [{:.1}, {:.1}, {:.1}] (roll, pitch, yaw; in \
             the campaign's --config, or the run's [params.vehicle])",
            m[0], m[1], m[2]
        )
    };
    let mean = check
        .mean_specific_force_mps2
        .map(|v| format!("{v:.2}"))
        .join(", ");
    let as_named = if declared.is_frd() {
        String::new()
    } else {
        format!(" as [vehicle] imu_axes = \"{declared}\" turned them")
    };
    match check.verdict(g_mps2) {
        AxesVerdict::Agree | AxesVerdict::TooShort => Ok(check),
        AxesVerdict::Mounted => {
            let seen = check.mounting_deg.unwrap_or_default();
            let side = if seen[2] > 0.0 { "right" } else { "left" };
            let fix =
                settings.map_or_else(String::new, |s| format!(": set {}", mounting_setting(s)));
            bail!(
                "the odometer's accelerations show the IMU{as_named} yawed {:.1}° on the \
                 vehicle (its x that far to the {side} of forward; rolled {:.1}°, pitched \
                 {:.1}°), more than the {MAX_MOUNTING_YAW_DEG}° the joint fit takes{fix}",
                seen[2].abs(),
                seen[0],
                seen[1],
            )
        }
        AxesVerdict::OdometerScale => {
            let (along, across) = (check.along, check.across);
            bail!(
                "the odometer's accelerations are {:.2} times the accelerometers' along x \
                 (gain {:.2}, correlation {:.2}; across, with the gyros' rate: {:.2}; \
                 {:.1}–{:.1} in a log's own units): \
                 the odometer's distance is not in metres{}. {}",
                1.0 / along.gain,
                along.gain,
                along.correlation,
                across.gain,
                SCALE_GAIN_RANGE.start(),
                SCALE_GAIN_RANGE.end(),
                // A pulse scale is no unit of speed.
                if manifest.format == LogFormat::UnzBinary {
                    String::new()
                } else {
                    known_unit(
                        1.0 / along.gain,
                        manifest.odometer.kind == Some(OdometerKind::SpeedKmh),
                    )
                },
                odometer_fix(manifest, odometer_file)
            )
        }
        AxesVerdict::OdometerFlat => {
            let (along, across) = (check.along, check.across);
            let source = Source::of(manifest, odometer_file);
            let distance_m: f64 = d.odo_dist_m.iter().sum();
            let mean_mps = distance_m / check.duration_s.max(f64::MIN_POSITIVE);
            // Gyros in degrees scale the gain across alone, by 1/57.3.
            let degrees = if (1.0 / across.gain / 57.3 - 1.0).abs() < 0.15 {
                " (or, its speeds right, the log's angle increments in degrees: 57.3 times \
                 radians)"
            } else {
                ""
            };
            bail!(
                "{} reads {mean_mps:.2} m/s on average and barely changes (its accelerations \
                 along x sum to {:.2} (m/s²)² over the log's 1-s blocks, where pulling away \
                 and braking give tens), while in the vehicle's turns the accelerometers' y \
                 is {:.2} times its speed times the gyros' yaw rate (correlation {:.2}; \
                 {:.1}–{:.1} for the vehicle's speed): it is not the vehicle's speed{degrees}. \
                 {}",
                source.name(),
                along.excitation,
                across.gain,
                across.correlation,
                SCALE_GAIN_RANGE.start(),
                SCALE_GAIN_RANGE.end(),
                not_speed_fix(&source, &manifest.odometer.value_column_said())
            )
        }
        AxesVerdict::OdometerOffset => {
            let (along, across) = (check.along, check.across);
            let offset = check.speed_offset.unwrap_or(SpeedOffset {
                gain: across.gain,
                offset_mps: 0.0,
            });
            let source = Source::of(manifest, odometer_file);
            let (c, side) = if offset.offset_mps > 0.0 {
                (offset.offset_mps, "more")
            } else {
                (-offset.offset_mps, "less")
            };
            bail!(
                "{} reads about {c:.0} m/s {side} than the vehicle's speed: in its turns the \
                 accelerometers' y is {:.2} times (u {} {c:.1} m/s) times the gyros' yaw \
                 rate, where u times it alone gives {:.2} (correlation {:.2}), and along x \
                 its u̇ agrees (gain {:.2}): its readings' zero is off (a speed decoded with \
                 a wrong offset?), where it must read 0 at rest. {}",
                source.name(),
                offset.gain,
                if offset.offset_mps > 0.0 { "−" } else { "+" },
                across.gain,
                across.correlation,
                along.gain,
                offset_fix(&source)
            )
        }
        AxesVerdict::GyroScale => {
            let (along, across) = (check.along, check.across);
            bail!(
                "the accelerometers' y is {:.3} times the odometer's speed times the gyros' \
                 yaw rate (ru; correlation {:.2}) while along x the odometer's u̇ agrees \
                 (gain {:.2}): the gyros' rate is {:.1} times the vehicle's turn{}; the log's \
                 angle increments must be in radians",
                across.gain,
                across.correlation,
                along.gain,
                1.0 / across.gain,
                if (1.0 / across.gain / 57.3 - 1.0).abs() < 0.15 {
                    " (angle increments in degrees are 57.3 times radians)"
                } else {
                    ""
                }
            )
        }
        AxesVerdict::NotGravity => bail!(
            "the accelerometers' mean over the log is [{mean}] m/s²{as_named}, {:.2} m/s² in \
             size where gravity is {g_mps2:.2} m/s² (±{:.0} %): the log's velocity \
             increments are not in m/s (g·s, or rates instead of increments?){}",
            check.mean_specific_force_size_mps2(),
            GRAVITY_TOLERANCE * 100.0,
            kept_one_in(check.mean_specific_force_size_mps2() / g_mps2).map_or_else(
                String::new,
                |m| format!(
                    ", or each line's increments span 1/{m} of the step between its tags: \
                     the log keeps one sample in {m} (lines lost regularly, or a logger \
                     writing one sample in {m} without summing the increments of those it \
                     leaves out)"
                )
            )
        ),
        AxesVerdict::Tilted => {
            let fix = match (settings, check.mounting_deg) {
                (Some(setting), Some(m)) => format!(
                    ": the odometer's accelerations show the IMU turned by [{:.1}, {:.1}, \
                     {:.1}]° (roll, pitch, yaw); set {}",
                    m[0],
                    m[1],
                    m[2],
                    mounting_setting(setting)
                ),
                _ => ": the IMU is mounted at an angle [vehicle] imu_axes cannot name (right \
                      angles only) and the drive does not show its mounting, or the log is not \
                      a land vehicle's"
                    .to_owned(),
            };
            bail!(
                "the accelerometers' mean over the log, [{mean}] m/s² in the body's \
                 axes{as_named}, is {:.0}° from the body's down and more than \
                 {MAX_TILT_DEG}° from every right angle{fix}",
                check.tilt_deg
            )
        }
        AxesVerdict::Other {
            found,
            forward_shown,
        } => {
            let log_axes = declared.then(found);
            let down = if check.tilt_deg > MAX_TILT_DEG {
                format!("({})", down_words(found))
            } else {
                "as it should be".to_owned()
            };
            let gravity = format!(
                "its accelerometers' mean over the log, [{mean}] m/s², is {:.0}° from the \
                 body's down {down}",
                check.tilt_deg,
            );
            let setting = "in the campaign's --config, or the run's [params.vehicle]";
            if forward_shown {
                let odometer = if check.tilt_deg <= MAX_TILT_DEG {
                    // Forward lies the turn from x towards y: to the right when positive.
                    let side = if check.forward_turn_deg > 0.0 {
                        "right"
                    } else {
                        "left"
                    };
                    format!(
                        "and the odometer's accelerations put the vehicle's forward {:.0}° to \
                         the {side} of its x (correlation {:.2})",
                        check.forward_turn_deg.abs(),
                        check.forward_correlation
                    )
                } else {
                    format!(
                        "and the odometer's accelerations (correlation {:.2}) place forward",
                        check.forward_correlation
                    )
                };
                bail!(
                    "the log's IMU axes{as_named} are not the vehicle's x forward, y right, z \
                     down: {gravity}, {odometer}. The log's axes are {}: set [vehicle] \
                     imu_axes = \"{log_axes}\" ({setting})",
                    log_axes.words()
                )
            }
            bail!(
                "the log's IMU axes{as_named} are not the vehicle's x forward, y right, z \
                 down: {gravity}; the drive does not show which way is forward (the \
                 odometer's accelerations too few or not correlated with the accelerometers'). \
                 Set [vehicle] imu_axes to the log's axes ({setting}): \"{log_axes}\" if they \
                 are {}",
                log_axes.words()
            )
        }
    }
}

/// The settings that turn a log by `body_from_log`: the right-angle axes nearest it, and
/// the mounting (roll, pitch, yaw, degrees) the rest is (up to 63° about a diagonal: so
/// far from every right angle a turn can be).
fn settings_for(body_from_log: nalgebra::Rotation3<f64>) -> (ImuAxes, [f64; 3]) {
    let (axes, rest) = ImuAxes::all()
        .map(|a| (a, body_from_log * a.body_from_log().inverse()))
        .min_by(|x, y| x.1.angle().total_cmp(&y.1.angle()))
        .unwrap_or((ImuAxes::FRD, body_from_log));
    (axes, imu_mounting::angles_deg(&rest))
}

/// The ratio of units the odometer's `factor` (its accelerations over the
/// accelerometers') is near, for the message ([`UnitRatio::near`]), the nearest first:
/// " (near 3.6, the ratio of km/h to m/s)", " (near 3.28084, the ratio of feet to metres,
/// or 3.6, of km/h to m/s)"; empty when none is. Below 1 (the file's unit smaller than
/// the one read) only when the speeds are `declared_kmh`: no other unit a manifest names
/// is larger than the log's own.
fn known_unit(factor: f64, declared_kmh: bool) -> String {
    let near: Vec<UnitRatio> = (UnitRatio::near(factor).into_iter())
        .filter(|u| !u.inverse || declared_kmh)
        .collect();
    match near.split_first() {
        None => String::new(),
        Some((first, others)) => {
            let others: String = (others.iter())
                .map(|u| format!(", or {}, of {}", u.shown(), u.of))
                .collect();
            format!(
                " (near {}, the ratio of {}{others})",
                first.shown(),
                first.of
            )
        }
    }
}

/// Where the odometer's distance is set or written, and how to fix it: `file` is the
/// odometer file the ingest read (none for a binary log or an 8th column).
fn odometer_fix(m: &RunManifest, file: Option<&Path>) -> String {
    match Source::of(m, file) {
        Source::Count => "Set the metres per pulse in the manifest's [odometer] \
             scale_m_per_pulse (it overrides the header's odo_lsb_m)"
            .to_owned(),
        Source::File(file, OdometerKind::DistanceM) => {
            format!("Write the distances of {} in metres", file.display())
        }
        Source::File(file, OdometerKind::SpeedKmh) => format!(
            "Check the speeds of {} (read as km/h: [odometer] kind = \"speed_kmh\")",
            file.display()
        ),
        Source::File(file, OdometerKind::SpeedMps) => format!(
            "Write the speeds of {} in m/s, or name their unit in the manifest's [odometer] \
             kind (\"speed_kmh\" for km/h)",
            file.display()
        ),
        Source::Column if m.odometer.kind == Some(OdometerKind::SpeedKmh) => {
            "Check the log's 8th column's speeds (read as km/h: [odometer] kind = \
             \"speed_kmh\")"
                .to_owned()
        }
        Source::Column => "Write the log's 8th column's speeds in m/s, or name their unit in \
             the manifest's [odometer] kind (\"speed_kmh\" for km/h)"
            .to_owned(),
    }
}

/// Where an odometer whose speed is offset (`source`) is written, and what to mend.
pub(crate) fn offset_fix(source: &Source) -> String {
    match source {
        Source::Count => {
            "Check the log's odometer count: its steps at rest must be none".to_owned()
        }
        Source::Column => "Write the log's 8th column's speeds from 0 at rest".to_owned(),
        Source::File(file, kind) if kind.is_speed() => {
            format!("Write the speeds of {} from 0 at rest", file.display())
        }
        Source::File(file, _) => format!(
            "Write the distances of {} standing still at rest",
            file.display()
        ),
    }
}

/// Where an odometer that is no speed (`source`) comes from, and what to check: a file's
/// `column` (as said: "column 3", [`unz_formats::manifest::Odometer::value_column_said`]).
pub(crate) fn not_speed_fix(source: &Source, column: &str) -> String {
    match source {
        Source::Count => "Check what the log's odometer count counts: the wheels' pulses, \
                          or the odometer's wiring"
            .to_owned(),
        Source::Column => "Name the odometer's file in the manifest's [odometer] file (it is \
                           read over the column), or write the vehicle's speeds in the log's \
                           8th column"
            .to_owned(),
        Source::File(file, kind) => format!(
            "Check that {column} of {} is the vehicle's {} ([odometer] value_column)",
            file.display(),
            if kind.is_speed() { "speed" } else { "distance" }
        ),
    }
}

/// "z points up", of the axis that points up or down.
fn down_words(axes: ImuAxes) -> String {
    use unz_stages::imu_axes::Direction::{Down, Up};
    let names = ["x", "y", "z"];
    axes.directions()
        .iter()
        .zip(names)
        .find_map(|(d, n)| match d {
            Down => Some(format!("{n} points down")),
            Up => Some(format!("{n} points up")),
            _ => None,
        })
        .unwrap_or_default()
}

/// The `m` of a log that keeps one IMU sample in `m` (2 to 10), from its accelerometers'
/// mean over gravity, `ratio`: each line's increments span its own sample's interval
/// while its tags step by `m` of them, so the mean reads `1/m` of gravity (to 3 %).
/// Such a log's tags step evenly, so neither the reader nor the derive sees a line lost.
fn kept_one_in(ratio: f64) -> Option<u32> {
    (2..=10).find(|&m| (ratio * f64::from(m) - 1.0).abs() < 0.03)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, Vector3};

    /// A unit named above 1 whatever the kind; below 1 only for speeds declared in km/h
    /// (m/s read as km/h: 1/3.6), the one unit a manifest names larger than a log's own.
    #[test]
    fn a_unit_below_one_is_named_for_speeds_declared_in_kmh_only() {
        assert_eq!(
            known_unit(3.6, false),
            " (near 3.6, the ratio of km/h to m/s)"
        );
        assert_eq!(
            known_unit(3.36, false),
            " (near 3.28084, the ratio of feet to metres, or 3.6, of km/h to m/s)"
        );
        assert_eq!(
            known_unit(0.27, true),
            " (near 1/3.6, the ratio of km/h to m/s)"
        );
        // A pulse or distance reading half the truth is no unit's (1/1.94 would be knots').
        assert_eq!(known_unit(0.5, false), "");
        assert_eq!(known_unit(1.0, true), "");
    }

    /// The settings that name a turn: a yaw within 45° is a mounting of the axes as they
    /// are; a roll of 50° is a right angle's axes and the 40° back; a turn 60° about a
    /// diagonal, far from every right angle, the nearest one's and the rest.
    #[test]
    fn the_nearest_right_angle_and_the_rest() {
        let yaw = Rotation3::from_euler_angles(0.0, 0.0, 20f64.to_radians());
        let (axes, m) = settings_for(yaw);
        assert_eq!(axes, ImuAxes::FRD);
        assert!((m[2] - 20.0).abs() < 1e-9 && m[0].abs() < 1e-9 && m[1].abs() < 1e-9);
        let roll = Rotation3::from_euler_angles(50f64.to_radians(), 0.0, 0.0);
        let (axes, m) = settings_for(roll);
        assert_eq!(axes.to_string(), "FDL");
        assert!((m[0] + 40.0).abs() < 1e-9, "{m:?}");
        // The named axes, then the mounting: the whole turn.
        let whole = imu_mounting::rotation(m).unwrap() * axes.body_from_log();
        assert!((whole.angle_to(&roll)).abs() < 1e-12);
        let diagonal = Vector3::new(1.0, 1.0, 1.0).normalize();
        let far = Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(diagonal), 1.05);
        let (axes, m) = settings_for(far);
        let whole = imu_mounting::rotation(m).unwrap() * axes.body_from_log();
        assert!((whole.angle_to(&far)).abs() < 1e-12);
    }
}
