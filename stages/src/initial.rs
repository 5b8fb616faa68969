//! The initial settings of a navigation pass: attitude from the static start (levelled,
//! heading given or gyrocompassed), drifts given or measured at rest, odometer scale.

use serde::Serialize;

use crate::align;
use crate::attitude::Euler;
use crate::derive::Derived;
use crate::earth::Geodetic;
use crate::imu_mounting;
use crate::strapdown::NavSettings;

/// Where a setting came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Source {
    /// The run manifest.
    Manifest,
    /// A command-line override or the optimiser.
    Override,
    /// Computed from the static start.
    Static,
    /// Levelled in motion: from the accelerometer pitch and roll references (eqs 7–8,
    /// odometer acceleration and centripetal terms removed) of the first epoch, then
    /// fitted over the log's first minute ([`crate::in_motion_level`]).
    InMotion,
    /// Default value.
    Default,
}

/// What the caller asks for; `None` means "manifest, else from the static start".
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct InitialRequest {
    /// Initial azimuth, degrees.
    pub azimuth_deg: Option<(f64, Source)>,
    /// Initial pitch, degrees.
    pub pitch_deg: Option<(f64, Source)>,
    /// Initial roll, degrees.
    pub roll_deg: Option<(f64, Source)>,
    /// Gyro drifts, rad/s.
    pub drift_rad_s: Option<([f64; 3], Source)>,
    /// Static start, s.
    pub static_s: Option<f64>,
    /// Multiplier on the odometer distance.
    pub odo_scale: f64,
    /// The turn from the unit's axes into the body's (`[vehicle] imu_mounting_deg`), when
    /// the IMU is mounted at an angle: the manifest's angles and drifts
    /// ([`Source::Manifest`]) are then the unit's own, its alignment's in its axes, and
    /// are turned into the body's.
    pub body_from_unit: Option<nalgebra::Rotation3<f64>>,
}

/// Parameters of the alignment.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AlignParams {
    /// Assumed 1σ of the horizontal gyro drifts left after the drift guess, rad/s.
    pub drift_sigma_rad_s: f64,
    /// Angle random walk of the gyros, rad/√s.
    pub arw_rad_sqrt_s: f64,
    /// Without given drifts, take the vertical drift measured at rest.
    pub drift_z_from_static: bool,
}

impl Default for AlignParams {
    fn default() -> Self {
        Self {
            drift_sigma_rad_s: crate::units::DEG_PER_H,
            arw_rad_sqrt_s: 0.07 * crate::units::DEG_PER_SQRT_H,
            drift_z_from_static: true,
        }
    }
}

/// Why an alignment step was skipped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Skipped {
    /// The run has no static start (logging began in motion): gyrocompassing needs one.
    /// The azimuth then comes from the manifest or, without it, from DISUPT's search over
    /// the control points.
    NoStaticStart,
}

/// What the alignment found and used.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct InitialReport {
    /// Static period averaged, s.
    pub static_s: f64,
    /// Initial roll, degrees.
    pub roll_deg: f64,
    /// Its source.
    pub roll_source: Source,
    /// Initial pitch, degrees.
    pub pitch_deg: f64,
    /// Its source.
    pub pitch_source: Source,
    /// Initial heading (azpocz), degrees.
    pub azimuth_deg: f64,
    /// Its source.
    pub azimuth_source: Source,
    /// The manifest's azimuth as given, degrees, when it was a unit's mounted at an angle
    /// (`[vehicle] imu_mounting_deg`): its own x's heading, which `azimuth_deg` is the
    /// body's of.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unit_azimuth_deg: Option<f64>,
    /// Gyrocompass heading, degrees (computed whenever there is a static start).
    pub gyrocompass_deg: Option<f64>,
    /// Why there is no gyrocompass heading, when there is none.
    pub gyrocompass_skipped: Option<Skipped>,
    /// Expected 1σ accuracy of the gyrocompass heading, degrees.
    pub gyrocompass_sigma_deg: Option<f64>,
    /// Drifts used, rad/s.
    pub drift_rad_s: [f64; 3],
    /// Their source.
    pub drift_source: Source,
    /// Vertical drift measured at rest, rad/s.
    pub drift_z_at_rest_rad_s: Option<f64>,
    /// Odometer multiplier.
    pub odo_scale: f64,
    /// A start levelled in motion: how the pitch and roll above were fitted over the
    /// log's first minute; absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub in_motion_level: Option<InMotionLevelReport>,
    /// The static start given, cut where the odometer shows the vehicle moving within
    /// it; absent when it stood through it (or none was given).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub static_cut: Option<StaticCut>,
    /// No static start given where the vehicle stood a minute or more at the log's
    /// start ([`StaticUnused`]); absent otherwise. The run keeps what was given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub static_unused: Option<StaticUnused>,
    /// A roll or pitch given more than [`LEVEL_APART_DEG`] from the static start's
    /// levelling; absent otherwise. The run keeps what was given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub level_apart: Option<LevelApart>,
    /// The odometer's travel over the stand at the log's start, when it is
    /// [`STAND_TRAVEL_SAID_M`] or more ([`StandTravel`]); absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stand_travel: Option<StandTravel>,
    /// An azimuth given far from the static start's gyrocompassing ([`AzimuthApart`]);
    /// absent otherwise. The run keeps what was given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub azimuth_apart: Option<AzimuthApart>,
}

/// How far an azimuth given may be from the static start's gyrocompassing before it is
/// said, degrees, or [`AZIMUTH_APART_SIGMAS`] of the gyrocompassing's σ if more: an
/// alignment's azimuth is degrees off (DISUPT's to correct), tens of degrees a setting
/// written wrong.
pub const AZIMUTH_APART_DEG: f64 = 10.0;

/// How many of the gyrocompassing's σ an azimuth given may be from it before it is said:
/// an LN-200's 1 °/h of drift gives 6.5–7.2° over 85 s at 52° of latitude, and 50
/// simulated runs' manifest azimuths (the alignment's, degrees off) were within 2.7σ of
/// theirs (a run in 16 000 is past 4σ by chance).
pub const AZIMUTH_APART_SIGMAS: f64 = 4.0;

/// An azimuth given (by the manifest, or on the command line) far from the static
/// start's gyrocompassing: a setting in radians, another run's, or another convention's.
/// Kingston with `azimuth_deg = 3.523` (its heading, 201.85°, in radians) ran "ok" with
/// nothing said: DISUPT's coarse search turned it by 162°.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct AzimuthApart {
    /// The azimuth given, degrees.
    pub given_deg: f64,
    /// The body's heading with it, degrees (the given one, but for an IMU mounted at an
    /// angle).
    pub heading_deg: f64,
    /// The static start's gyrocompassing of the body's heading, degrees.
    pub gyrocompass_deg: f64,
    /// Its σ, degrees.
    pub gyrocompass_sigma_deg: f64,
}

impl AzimuthApart {
    /// Of an azimuth `given_deg` (the body heading `heading_deg`) on a static start whose
    /// gyrocompassing gives `gyrocompass_deg` ± `sigma_deg`: `None` within
    /// [`AZIMUTH_APART_DEG`] and [`AZIMUTH_APART_SIGMAS`].
    pub fn of(
        given_deg: f64,
        heading_deg: f64,
        gyrocompass_deg: f64,
        sigma_deg: f64,
    ) -> Option<Self> {
        let apart = Self {
            given_deg,
            heading_deg,
            gyrocompass_deg,
            gyrocompass_sigma_deg: sigma_deg,
        };
        (apart.apart_deg() > reach_deg(sigma_deg)).then_some(apart)
    }

    /// How far the heading is from the gyrocompassing's, degrees (0–180).
    pub fn apart_deg(&self) -> f64 {
        apart_deg(self.heading_deg, self.gyrocompass_deg)
    }

    /// What it is, for the run's log and its row of the campaign summary.
    pub fn said(&self) -> String {
        // The value given, read as the radians it may have been written in.
        let as_radians = self.given_deg.to_degrees();
        let radians = if apart_deg(as_radians, self.gyrocompass_deg)
            <= reach_deg(self.gyrocompass_sigma_deg)
        {
            format!(
                " ({} read as radians is {:.2}°: azimuth_deg is in degrees)",
                self.given_deg,
                as_radians.rem_euclid(360.0)
            )
        } else {
            String::new()
        };
        format!(
            "the azimuth given ({}°) is {:.1}° from the static start's gyrocompassing \
             ({:.2}° ± {:.2}°){radians}: DISUPT corrects the run from it, but the manifest's \
             azimuth_deg may be wrong (the run keeps it)",
            self.given_deg,
            self.apart_deg(),
            self.gyrocompass_deg,
            self.gyrocompass_sigma_deg
        )
    }
}

/// How far an azimuth may be from a gyrocompassing of σ `sigma_deg` and agree with it,
/// degrees.
fn reach_deg(sigma_deg: f64) -> f64 {
    AZIMUTH_APART_DEG.max(AZIMUTH_APART_SIGMAS * sigma_deg)
}

/// Degrees between two angles (0–180).
fn apart_deg(a_deg: f64, b_deg: f64) -> f64 {
    crate::attitude::wrap_pi((a_deg - b_deg).to_radians())
        .abs()
        .to_degrees()
}

/// How far a tilt given may be from the static start's levelling before it is said to be
/// off, degrees: a milli-g of accelerometer bias tilts the levelling by 0.057°, and 1° is
/// 17 mg, beyond any navigation-grade IMU's bias.
pub const LEVEL_APART_DEG: f64 = 1.0;

/// A roll or pitch given (by the manifest) far from what the static start's
/// accelerometers level the body at: a setting typed wrong, or another run's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct LevelApart {
    /// The body's roll and pitch with what was given, degrees.
    pub given_deg: [f64; 2],
    /// The static start's levelling of the body, roll and pitch, degrees.
    pub levelled_deg: [f64; 2],
}

impl LevelApart {
    /// Of a body at `given_deg` (roll, pitch) that the static start levels at
    /// `levelled_deg`: `None` when they are within [`LEVEL_APART_DEG`].
    pub fn of(given_deg: [f64; 2], levelled_deg: [f64; 2]) -> Option<Self> {
        let apart = Self {
            given_deg,
            levelled_deg,
        };
        (apart.apart_deg() > LEVEL_APART_DEG).then_some(apart)
    }

    /// The larger of the roll's and the pitch's difference, degrees.
    pub fn apart_deg(&self) -> f64 {
        let d = |k: usize| apart_deg(self.given_deg[k], self.levelled_deg[k]);
        d(0).max(d(1))
    }

    /// What it is, for the run's log and its row of the campaign summary.
    pub fn said(&self) -> String {
        let [r, p] = self.given_deg;
        let [lr, lp] = self.levelled_deg;
        format!(
            "the roll and pitch given ({r:.2}°, {p:.2}°) are {:.2}° from the static start's \
             levelling ({lr:.2}°, {lp:.2}°), where the accelerometers' biases move it by a \
             tenth of a degree: the manifest's roll_deg or pitch_deg may be wrong (the run \
             keeps them)",
            self.apart_deg()
        )
    }
}

/// A static start given (by the manifest) longer than the vehicle stood: the alignment
/// would have averaged a drive.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct StaticCut {
    /// The static start given, s.
    pub given_s: f64,
    /// When the odometer's net travel from the log's start first passed [`MOVED_M`], s
    /// from the first sample; the static start then ends [`MOVE_MARGIN_S`] before.
    pub moved_s: f64,
}

impl StaticCut {
    /// What the cut was, for the run's log and its row of the campaign summary.
    pub fn said(&self) -> String {
        format!(
            "the static start given (static_s = {} s) runs past the vehicle's first move, \
             {:.2} s in by its odometer: the alignment averaged the first {:.2} s (set \
             static_s to the time the vehicle stood)",
            self.given_s,
            self.moved_s,
            self.static_s()
        )
    }

    /// The static start averaged, s: the one detected (`stood_until_s`).
    pub fn static_s(&self) -> f64 {
        stood_until_s(self.moved_s)
    }
}

/// Shortest stand at a log's start worth an alignment, s: a minute of gyrocompassing
/// gives a heading; the levelling takes seconds.
pub const STAND_WORTH_ALIGNING_S: f64 = 60.0;

/// Shortest static start the alignment takes, s: below, the run has none.
pub const MIN_STATIC_S: f64 = 5.0;

/// A static start given (by the manifest) shorter than the alignment takes
/// ([`MIN_STATIC_S`]: none), or shorter than half the stand, on a log that begins with a
/// stand of a minute or more: `static_s = 0` on a log that begins at rest leaves the
/// alignment's heading and levelling out (Kingston's 527-s stand unused: the joint fit's
/// azimuth σ 0.69° against 0.06°, its hold-out errors 16 and 29 m against 2.2 and 3.0 m);
/// `static_s = 8` (minutes meant) gyrocompasses over 8 s of it (σ 9.5° against 5.4°;
/// the joint fit's azimuth σ 0.27°, hold-outs 2.9 and 4.1 m). Said, not acted on: a
/// vehicle carried (on a ship, a train) stands on its odometer while the IMU moves.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct StaticUnused {
    /// The static start given, s.
    pub given_s: f64,
    /// How long the odometer stood at the log's start ([`detect_static_s`]), s.
    pub stood_s: f64,
}

impl StaticUnused {
    /// Of a static start `given_s` on a log whose odometer stood `stood_s` at its start,
    /// then moved (`drove`) or not. Less than half the stand is said only before a drive:
    /// a log that never moves is all stand, and how much of it the crew aligned over is
    /// theirs to choose.
    pub fn of(given_s: f64, stood_s: f64, drove: bool) -> Option<Self> {
        let part = drove && given_s < stood_s / 2.0;
        (stood_s >= STAND_WORTH_ALIGNING_S && (given_s < MIN_STATIC_S || part))
            .then_some(Self { given_s, stood_s })
    }

    /// What it is, for the run's log and its row of the campaign summary.
    pub fn said(&self) -> String {
        let (given_s, stood_s) = (self.given_s, self.stood_s);
        let used = if given_s < MIN_STATIC_S {
            "leaves it out of the alignment".to_owned()
        } else {
            format!("aligns over its first {given_s} s only")
        };
        // Minutes meant: the stand is about as many minutes as seconds were given.
        let minutes = if (given_s * 60.0 - stood_s).abs() <= 0.2 * stood_s {
            format!(
                " ({given_s} minutes would be {:.0} s: static_s is in seconds)",
                given_s * 60.0
            )
        } else {
            String::new()
        };
        format!(
            "the vehicle stood {stood_s:.0} s at the log's start by its odometer, but the \
             static start given (static_s = {given_s} s) {used}{minutes}: set static_s (or \
             leave it out for the stand detected) to gyrocompass the heading and level over \
             it, unless the vehicle was carried (a ship, a train), its odometer still and its \
             IMU moving (the run keeps what was given)",
        )
    }
}

/// Odometer travel over the stand at the log's start from which it is said, m: a
/// count's jitter at rest nets a few centimetres, where a speed sensor's floor at rest
/// (2 cm/s) nets metres over minutes.
pub const STAND_TRAVEL_SAID_M: f64 = 1.0;

/// The odometer's net travel over the stand detected at the log's start (below
/// [`MOVED_M`] a second throughout): a speed sensor's noise at rest, never negative (a
/// GNSS ground speed: a few cm/s), which the dead reckoning takes for travel along the
/// heading. Kingston's speeds with 0–4 cm/s at rest counted 10 m over its 527-s stand,
/// and its hold-out errors were 25 and 37 m against 2.2 and 3.0 m. Said, with the speed
/// floor (the run manifest's `[odometer] speed_floor_mps`) that would read the stand's
/// speeds as 0: the run reads them as logged until the manifest sets one.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct StandTravel {
    /// How long the odometer stood at the log's start ([`detect_static_s`]), s.
    pub stood_s: f64,
    /// The odometer's net travel over it, m.
    pub travel_m: f64,
    /// The floor that reads every speed over the stand as 0, m/s: the fastest of its
    /// samples' speeds (each the mean over its sample's interval), up to the next whole
    /// cm/s. `None` beyond a move's speed (`MOVED_M` over its second: the vehicle crept),
    /// and for an odometer that gives no speeds (a count, a file of distances).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub floor_mps: Option<f64>,
}

impl StandTravel {
    /// Of `d`'s odometer over its first `stood_s`, when its net travel is
    /// [`STAND_TRAVEL_SAID_M`] or more either way.
    pub fn of(d: &Derived, stood_s: f64) -> Option<Self> {
        let stood = d.t_s.iter().take_while(|&t_s| t_s <= stood_s).count();
        let travel_m: f64 = d.odo_dist_m.iter().take(stood).sum();
        let fastest_mps = (d.odo_dist_m.iter().take(stood).zip(d.dt_s.iter()))
            .map(|(dd_m, dt_s)| (dd_m / dt_s).abs())
            .fold(0.0, f64::max);
        // Whole cm/s, rounded at a micrometre per second first: 0.04 m/s is 4 cm/s, not
        // its float's 4.000000000000001.
        let floor_mps = ((fastest_mps * 1e6).round() / 1e4).ceil() / 100.0;
        (travel_m.abs() >= STAND_TRAVEL_SAID_M).then_some(Self {
            stood_s,
            travel_m,
            floor_mps: (floor_mps <= MOVED_M / MOVE_WINDOW_S).then_some(floor_mps),
        })
    }

    /// What it is, for the run's log and its row of the campaign summary.
    pub fn said(&self) -> String {
        let mend = match self.floor_mps {
            Some(floor_mps) => format!(
                "set [odometer] speed_floor_mps = {floor_mps} in the run's manifest to read \
                 its speeds at or below it as 0, or write them as 0"
            ),
            None => "write them as 0".to_owned(),
        };
        format!(
            "the odometer counted {:.1} m over the {:.0} s the vehicle stood at the log's \
             start ({:.1} cm/s, below the {} m/s of a move): if it stood, its speeds at rest \
             are a sensor's noise, which the dead reckoning takes for travel along the \
             heading ({mend})",
            self.travel_m,
            self.stood_s,
            100.0 * self.travel_m / self.stood_s.max(f64::MIN_POSITIVE),
            MOVED_M / MOVE_WINDOW_S,
        )
    }
}

/// Net odometer travel over [`MOVE_WINDOW_S`], m, past which the vehicle moves (0.1 m/s):
/// a count's jitter at rest goes back and forth, and a speed sensor's noise at rest (a
/// GNSS ground speed's few cm/s, never negative) stays below it, where a drive's does
/// not: a vehicle pulling away at 0.5 m/s² passes it 0.6 s in. Taken from the log's
/// start, 5 cm of such noise ended Kingston's 527-s stand 3.3 s in, and its alignment
/// with it.
pub const MOVED_M: f64 = 0.1;
/// The window over which [`MOVED_M`] is judged, s.
pub const MOVE_WINDOW_S: f64 = 1.0;
/// Time, s, between the end of a static start and the odometer's first sign of motion
/// (the vehicle creeps, and the odometer may lag).
pub const MOVE_MARGIN_S: f64 = 1.0;

/// How a start levelled in motion was fitted ([`crate::in_motion_level`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct InMotionLevelReport {
    /// Seconds from the first epoch whose valid epochs were read.
    pub window_s: f64,
    /// Valid epochs read.
    pub epochs: usize,
    /// RMS of their pitch and roll residuals at the fitted angles, degrees.
    pub residual_rms_deg: f64,
}

/// The end of a static start whose odometer first shows the vehicle moving at
/// `moved_s`, s: [`MOVE_MARGIN_S`] before it, and not before the log.
fn stood_until_s(moved_s: f64) -> f64 {
    (moved_s - MOVE_MARGIN_S).max(0.0)
}

/// Length of the static start detected from the odometer, s: up to [`MOVE_MARGIN_S`]
/// before it first shows the vehicle moving ([`first_moved_s`]), the whole log if it
/// never does.
pub fn detect_static_s(d: &Derived) -> f64 {
    first_moved_s(d).map_or_else(|| d.t_s.last().unwrap_or(0.0), stood_until_s)
}

/// When the odometer's net travel over the last [`MOVE_WINDOW_S`] first passes
/// [`MOVED_M`], s from the first sample; `None` if it never does.
pub fn first_moved_s(d: &Derived) -> Option<f64> {
    let mut window = std::collections::VecDeque::new();
    let mut net_m = 0.0;
    for (t_s, &dd_m) in d.t_s.iter().zip(&d.odo_dist_m) {
        window.push_back((t_s, dd_m));
        net_m += dd_m;
        while let Some(&(t_first, dd_first)) = window.front() {
            if t_first > t_s - MOVE_WINDOW_S {
                break;
            }
            net_m -= dd_first;
            window.pop_front();
        }
        if net_m.abs() > MOVED_M {
            return Some(t_s);
        }
    }
    None
}

/// The request's static start when it runs past the one detected (the odometer shows
/// the vehicle moving within it); `None` when the vehicle stood through it, or none was
/// given.
pub fn static_cut(d: &Derived, req: &InitialRequest) -> Option<StaticCut> {
    static_start(d, req).cut
}

/// Length of the static start `initial_settings` averages over, s: the request's, cut
/// to the one detected where the vehicle moved within it ([`static_cut`]), else the one
/// detected; at most the run.
pub fn static_start_s(d: &Derived, req: &InitialRequest) -> f64 {
    static_start(d, req).static_s
}

/// What the odometer says of the static start asked for.
struct StaticStart {
    /// The static start averaged, s ([`static_start_s`]).
    static_s: f64,
    /// [`static_cut`].
    cut: Option<StaticCut>,
    /// The one given, when it leaves a stand of a minute or more out of the alignment
    /// ([`StaticUnused`]).
    unused: Option<StaticUnused>,
    /// How long the odometer stood at the log's start ([`detect_static_s`]), s.
    stood_s: f64,
}

/// [`static_start_s`], [`static_cut`] and [`StaticUnused`], from one search of the
/// odometer.
fn static_start(d: &Derived, req: &InitialRequest) -> StaticStart {
    let log_s = d.t_s.last().unwrap_or(0.0);
    let moved_s = first_moved_s(d);
    let detected_s = moved_s.map_or(log_s, stood_until_s);
    let cut = (req.static_s)
        .zip(moved_s)
        .filter(|&(given_s, _)| detected_s < given_s)
        .map(|(given_s, moved_s)| StaticCut { given_s, moved_s });
    let unused =
        (req.static_s).and_then(|given_s| StaticUnused::of(given_s, detected_s, moved_s.is_some()));
    let static_s = (req.static_s).map_or(detected_s, |given_s| given_s.min(detected_s));
    StaticStart {
        static_s: static_s.min(log_s),
        cut,
        unused,
        stood_s: detected_s,
    }
}

/// Samples of the static start (the only velocity increments [`initial_settings`] reads).
pub fn static_samples(d: &Derived, req: &InitialRequest) -> usize {
    crate::align::static_len(&d.dt_s, static_start_s(d, req))
}

/// Resolves the initial settings of a pass that starts at `start`.
pub fn initial_settings(
    d: &Derived,
    req: &InitialRequest,
    p: &AlignParams,
    start: Geodetic,
) -> (NavSettings, InitialReport) {
    initial_settings_with_velocity(d, &d.dvel_mps, req, p, start)
}

/// [`initial_settings`] with the velocity increments given apart from the derive: only
/// the first [`static_samples`] are read, so a derive loaded without them needs no more.
pub fn initial_settings_with_velocity(
    d: &Derived,
    dvel_mps: &[[f64; 3]],
    req: &InitialRequest,
    p: &AlignParams,
    start: Geodetic,
) -> (NavSettings, InitialReport) {
    let Geodetic {
        lat_rad: lat0,
        lon_rad: lon0,
        h_m: h0,
    } = start;
    let StaticStart {
        static_s,
        cut: static_cut,
        unused: static_unused,
        stood_s,
    } = static_start(d, req);
    let means = align::static_means(&d.dt_s, d.dtheta_rad.view(), dvel_mps, static_s);
    let has_static = means.duration_s >= MIN_STATIC_S;
    let (lev_roll, lev_pitch) = align::level(&means.f_b_mps2);
    // Without a static start, level in motion from the accelerometer references of the
    // first epoch (the filter's delay is zero; the joint fit's levelling corrections take
    // what the first second's motion leaves).
    let in_motion = d.epochs.theta_p_rad.first().zip(d.epochs.phi_p_rad.first());
    let levelled_roll = match in_motion {
        _ if has_static => (lev_roll, Source::Static),
        Some((_, &phi)) => (phi, Source::InMotion),
        None => (0.0, Source::Default),
    };
    let levelled_pitch = match in_motion {
        _ if has_static => (lev_pitch, Source::Static),
        Some((&theta, _)) => (theta, Source::InMotion),
        None => (0.0, Source::Default),
    };
    let given = |v: Option<(f64, Source)>| v.map(|(v, s)| (v.to_radians(), s));
    let (mut roll, roll_source) = given(req.roll_deg).unwrap_or(levelled_roll);
    let (mut pitch, pitch_source) = given(req.pitch_deg).unwrap_or(levelled_pitch);
    // A unit mounted at an angle: the manifest's roll and pitch are its own. The body's
    // tilt is the unit's (the manifest's where given, else the levelled body's turned into
    // the unit's axes) turned back.
    let manifest = |v: Option<(f64, Source)>| {
        v.filter(|(_, s)| *s == Source::Manifest)
            .map(|(v, _)| v.to_radians())
    };
    let turn = req.body_from_unit.as_ref();
    let (unit_roll, unit_pitch) = (manifest(req.roll_deg), manifest(req.pitch_deg));
    if let Some(turn) = turn.filter(|_| unit_roll.is_some() || unit_pitch.is_some()) {
        let body = Euler {
            roll_rad: if unit_roll.is_some() {
                levelled_roll.0
            } else {
                roll
            },
            pitch_rad: if unit_pitch.is_some() {
                levelled_pitch.0
            } else {
                pitch
            },
            heading_rad: 0.0,
        };
        let levelled_unit = imu_mounting::unit_attitude(body, turn);
        let unit = Euler {
            roll_rad: unit_roll.unwrap_or(levelled_unit.roll_rad),
            pitch_rad: unit_pitch.unwrap_or(levelled_unit.pitch_rad),
            heading_rad: 0.0,
        };
        let body = imu_mounting::body_attitude(unit, turn);
        (roll, pitch) = (body.roll_rad, body.pitch_rad);
    }
    // A unit's drifts, per its gyros, in the body's axes (the gyrocompass's guess too).
    let req_drift = req.drift_rad_s.map(|(v, s)| match turn {
        Some(t) if s == Source::Manifest => (imu_mounting::to_body(t, v), s),
        _ => (v, s),
    });
    let guess = req_drift.map_or([0.0; 3], |(v, _)| v);
    let (gc, gc_sigma) = if has_static {
        let w = means.w_b_rad_s - nalgebra::Vector3::from(guess);
        (
            Some(align::gyrocompass(&w, roll, pitch)),
            Some(align::gyrocompass_sigma_rad(
                lat0,
                p.drift_sigma_rad_s,
                p.arw_rad_sqrt_s,
                means.duration_s,
            )),
        )
    } else {
        (None, None)
    };
    let (mut heading, azimuth_source) = match (req.azimuth_deg, gc) {
        (Some((v, s)), _) => (v.to_radians(), s),
        (None, Some(h)) => (h, Source::Static),
        (None, None) => (0.0, Source::Default),
    };
    // The manifest's azimuth of a unit mounted at an angle is its own x's heading: the
    // body's is where the unit's attitude with it, turned back, heads.
    let unit_azimuth = turn.zip(manifest(req.azimuth_deg));
    if let Some((turn, unit_heading)) = unit_azimuth {
        let body = Euler {
            roll_rad: roll,
            pitch_rad: pitch,
            heading_rad: 0.0,
        };
        let unit = Euler {
            heading_rad: unit_heading,
            ..imu_mounting::unit_attitude(body, turn)
        };
        heading = imu_mounting::body_attitude(unit, turn).heading_rad;
    }
    let attitude = Euler {
        roll_rad: roll,
        pitch_rad: pitch,
        heading_rad: heading,
    };
    let dz = has_static.then(|| align::drift_z_at_rest(&means.w_b_rad_s, attitude, lat0));
    let (drift, drift_source) = match (req_drift, dz) {
        (Some((v, s)), _) => (v, s),
        (None, Some(z)) if p.drift_z_from_static => ([0.0, 0.0, z], Source::Static),
        _ => ([0.0; 3], Source::Default),
    };
    let settings = NavSettings {
        initial: attitude,
        drift_rad_s: drift,
        odo_scale: req.odo_scale,
        odo_yaw_rad: 0.0,
        odo_pitch_rad: 0.0,
        odo_bias_mps: 0.0,
        lat0_rad: lat0,
        lon0_rad: lon0,
        h0_m: h0,
    };
    let report = InitialReport {
        static_s: means.duration_s,
        roll_deg: roll.to_degrees(),
        roll_source,
        pitch_deg: pitch.to_degrees(),
        pitch_source,
        azimuth_deg: heading.to_degrees().rem_euclid(360.0),
        azimuth_source,
        unit_azimuth_deg: unit_azimuth.map(|(_, h)| h.to_degrees().rem_euclid(360.0)),
        gyrocompass_deg: gc.map(f64::to_degrees),
        gyrocompass_skipped: (!has_static).then_some(Skipped::NoStaticStart),
        gyrocompass_sigma_deg: gc_sigma.map(f64::to_degrees),
        drift_rad_s: drift,
        drift_source,
        drift_z_at_rest_rad_s: dz,
        odo_scale: req.odo_scale,
        in_motion_level: None,
        static_cut,
        static_unused,
        // Walked here only: the static start's other callers do not report it.
        stand_travel: StandTravel::of(d, stood_s),
        azimuth_apart: (req.azimuth_deg.zip(gc).zip(gc_sigma)).and_then(|(((given, _), gc), s)| {
            AzimuthApart::of(given, heading.to_degrees(), gc.to_degrees(), s.to_degrees())
        }),
        level_apart: (has_static && (req.roll_deg.is_some() || req.pitch_deg.is_some()))
            .then(|| {
                LevelApart::of(
                    [roll, pitch].map(f64::to_degrees),
                    [lev_roll, lev_pitch].map(f64::to_degrees),
                )
            })
            .flatten(),
    };
    (settings, report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::time_base::TimeBase;

    /// A log at 100 Hz whose odometer gives `step_m(k)` at sample `k`.
    fn log(n: usize, step_m: impl Fn(usize) -> f64) -> Derived {
        Derived {
            t_s: TimeBase::from((0..n).map(|k| k as f64 * 0.01).collect::<Vec<_>>()),
            odo_dist_m: (0..n).map(step_m).collect(),
            dt_s: std::sync::Arc::new(vec![0.01; n]),
            ..Derived::default()
        }
    }

    fn given(static_s: f64) -> InitialRequest {
        InitialRequest {
            static_s: Some(static_s),
            ..InitialRequest::default()
        }
    }

    /// A count's jitter at rest: 2 cm forward and back, sample after sample.
    fn jitter_m(k: usize) -> f64 {
        if k.is_multiple_of(2) { 0.02 } else { -0.02 }
    }

    #[test]
    fn a_static_start_given_past_the_first_move_ends_a_second_before_it() {
        // At rest for 30 s, the count jittering, then driving at 1.2 m/s: the net travel
        // over the last second passes 10 cm at the drive's tenth sample (12 cm; at the
        // ninth, 10.8 cm less the jitter's 2 cm back still in the window). The jitter's
        // sum of steps passed 5 cm at the log's third, where detection once ended the
        // static start.
        let d = log(6000, |k| if k < 3000 { jitter_m(k) } else { 0.012 });
        let moved_s = first_moved_s(&d).unwrap();
        assert!((moved_s - 30.09).abs() < 1e-9, "{moved_s}");
        assert!((detect_static_s(&d) - 29.09).abs() < 1e-9);
        // Given 45 s: cut to a second before the move, and said.
        let cut = static_cut(&d, &given(45.0)).unwrap();
        assert_eq!(
            cut,
            StaticCut {
                given_s: 45.0,
                moved_s
            }
        );
        assert!((static_start_s(&d, &given(45.0)) - 29.09).abs() < 1e-9);
        assert!(
            cut.said()
                .contains("(static_s = 45 s) runs past the vehicle's first move, 30.09 s in")
                && cut.said().contains("averaged the first 29.09 s"),
            "{}",
            cut.said()
        );
        // Within the stand, or within a second of the move: as given.
        for s in [25.0, 29.0] {
            assert_eq!(static_cut(&d, &given(s)), None);
            assert_eq!(static_start_s(&d, &given(s)), s);
        }
        // Past it by a hair: cut.
        assert!(static_cut(&d, &given(29.1)).is_some());
        // A move in the first second: no static start left. None given (a log begun
        // while driving): none cut.
        let early = log(1000, |k| if k < 50 { 0.0 } else { 0.012 });
        assert_eq!(static_start_s(&early, &given(60.0)), 0.0);
        assert_eq!(static_cut(&early, &given(0.0)), None);
        assert_eq!(static_cut(&early, &InitialRequest::default()), None);
    }

    #[test]
    fn an_azimuth_given_far_from_the_gyrocompassing_is_said() {
        // Within 10° or 4σ: nothing, across north too.
        assert_eq!(AzimuthApart::of(195.0, 195.0, 201.85, 5.41), None);
        assert_eq!(AzimuthApart::of(355.0, 355.0, 5.0, 0.5), None);
        assert_eq!(AzimuthApart::of(182.0, 182.0, 201.85, 5.41), None);
        assert!(AzimuthApart::of(180.0, 180.0, 201.85, 5.41).is_some());
        // Beyond: how far, and a value that is the heading in radians named so.
        let rad = AzimuthApart::of(3.523, 3.523, 201.85, 5.41).unwrap();
        assert!((rad.apart_deg() - 161.67).abs() < 0.01, "{rad:?}");
        assert!(
            rad.said().starts_with(
                "the azimuth given (3.523°) is 161.7° from the static start's gyrocompassing \
                 (201.85° ± 5.41°) (3.523 read as radians is 201.85°: azimuth_deg is in \
                 degrees)"
            ),
            "{}",
            rad.said()
        );
        let off = AzimuthApart::of(150.0, 150.0, 201.85, 5.41).unwrap();
        assert!(!off.said().contains("radians"), "{}", off.said());
        assert!(AzimuthApart::of(12.0, 12.0, 0.0, 0.5).is_some());
    }

    #[test]
    fn a_tilt_given_far_from_the_levelling_is_said() {
        // Within a degree: nothing; beyond, on either angle: said, with how far.
        assert_eq!(LevelApart::of([-0.3, -0.3], [-0.25, -0.34]), None);
        let apart = LevelApart::of([-0.25, 5.0], [-0.25, -0.34]).unwrap();
        assert!((apart.apart_deg() - 5.34).abs() < 1e-9);
        assert!(
            apart.said().starts_with(
                "the roll and pitch given (-0.25°, 5.00°) are 5.34° from the static start's \
                 levelling (-0.25°, -0.34°)"
            ),
            "{}",
            apart.said()
        );
        assert!(LevelApart::of([1.2, 0.0], [0.0, 0.0]).is_some());
        // A roll of 179.5° given for a levelling of −179.9°: 0.6° apart, not 359.4°.
        assert_eq!(LevelApart::of([179.5, 0.0], [-179.9, 0.0]), None);
    }

    #[test]
    fn a_stand_left_out_of_the_alignment_is_said() {
        // At rest for 90 s, then driving: the stand detected ends at 89.09 s.
        let d = log(12_000, |k| if k < 9000 { jitter_m(k) } else { 0.012 });
        let unused = |s: f64| static_start(&d, &given(s)).unused;
        let none = unused(0.0).unwrap();
        assert!((none.stood_s - 89.09).abs() < 1e-9, "{none:?}");
        assert!(
            none.said().starts_with(
                "the vehicle stood 89 s at the log's start by its odometer, but the static start \
                 given (static_s = 0 s) leaves it out"
            ),
            "{}",
            none.said()
        );
        assert!(unused(4.0).is_some());
        // Less than half the stand given: said, minutes named where they fit.
        let part = unused(40.0).unwrap();
        assert!(
            part.said()
                .contains("(static_s = 40 s) aligns over its first 40 s only: set"),
            "{}",
            part.said()
        );
        let minutes = unused(1.5).map(|u| u.said()).unwrap();
        assert!(
            minutes.contains("(1.5 minutes would be 90 s: static_s is in seconds)"),
            "{minutes}"
        );
        // A static start the alignment takes over half the stand or more, or none given
        // (the stand detected): nothing said.
        assert_eq!(unused(45.0), None);
        assert_eq!(static_start(&d, &InitialRequest::default()).unused, None);
        // A stand shorter than a minute is no loss.
        let short = log(6000, |k| if k < 3000 { 0.0 } else { 0.012 });
        assert_eq!(static_start(&short, &given(0.0)).unused, None);
        // A log that never moves: none given is said, part of it given is the crew's.
        let still = log(12_000, jitter_m);
        assert!(static_start(&still, &given(0.0)).unused.is_some());
        assert_eq!(static_start(&still, &given(40.0)).unused, None);
    }

    #[test]
    fn a_static_start_given_past_a_log_at_rest_is_the_log() {
        let d = log(1000, jitter_m);
        assert_eq!(first_moved_s(&d), None);
        assert_eq!(static_cut(&d, &given(86_400.0)), None);
        assert_eq!(static_start_s(&d, &given(86_400.0)), 9.99);
        assert_eq!(detect_static_s(&d), 9.99);
        // Backwards counts are travel too: a vehicle that rolled back moved.
        let back = log(1000, |k| if k < 500 { 0.0 } else { -0.012 });
        assert!((first_moved_s(&back).unwrap() - 5.08).abs() < 1e-9);
    }

    /// A speed sensor's noise at rest (never negative, a few cm/s) is no move, however
    /// long it runs; the drive after it is.
    #[test]
    fn a_speeds_noise_at_rest_is_no_move() {
        // 0–4 cm/s at rest for 500 s (2 cm/s on average: 10 m of "travel"), then 1.2 m/s.
        let noise = |k: usize| 0.0004 * ((k * 7919) % 101) as f64 / 100.0;
        let d = log(60_000, |k| if k < 50_000 { noise(k) } else { 0.012 });
        let moved_s = first_moved_s(&d).unwrap();
        assert!((500.0..500.1).contains(&moved_s), "{moved_s}");
        assert_eq!(static_cut(&d, &given(450.0)), None);
    }

    /// The stand's travel is said from 1 m, with the floor that reads its fastest sample
    /// (4 cm/s, up to the next cm/s) as 0; none past a move's speed, nor under a metre.
    #[test]
    fn a_stands_travel_names_the_floor_that_reads_it_as_zero() {
        let noise = |k: usize| 0.0004 * ((k * 7919) % 101) as f64 / 100.0;
        let d = log(60_000, |k| if k < 50_000 { noise(k) } else { 0.012 });
        let travel = StandTravel::of(&d, 499.0).expect("10 m said");
        assert!((travel.travel_m - 9.98).abs() < 0.2, "{travel:?}");
        assert_eq!(travel.floor_mps, Some(0.04));
        assert!(
            travel.said().contains("speed_floor_mps = 0.04 in"),
            "{}",
            travel.said()
        );
        // 3.01 cm/s at most: 4 cm/s.
        let d = log(60_000, |k| if k < 50_000 { 0.000301 } else { 0.012 });
        assert_eq!(StandTravel::of(&d, 499.0).unwrap().floor_mps, Some(0.04));
        // 12 cm/s now and then: crept, no floor named.
        let d = log(60_000, |k| match k {
            _ if k >= 50_000 => 0.012,
            _ if k % 1000 == 0 => 0.0012,
            _ => noise(k),
        });
        let travel = StandTravel::of(&d, 499.0).unwrap();
        assert_eq!(travel.floor_mps, None);
        assert!(
            travel.said().ends_with("(write them as 0)"),
            "{}",
            travel.said()
        );
        // 0.1 cm/s: 0.5 m, not said.
        assert_eq!(StandTravel::of(&log(60_000, |_| 0.00001), 499.0), None);
    }
}
