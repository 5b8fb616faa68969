//! The IMU's axes on the vehicle.
//!
//! The method reads a log's increments in the vehicle's body axes, FRD: x forward, y
//! right, z down (method.md). Kryt1's accelerometer pitch and roll take the odometer's
//! acceleration off x and its centripetal term off y, and assume the vehicle upright;
//! dead reckoning carries the odometer's distance along x. A log written in the IMU's own
//! axes, with the IMU mounted sideways or upside down (or in ROS's x forward, y left,
//! z up), breaks all three. [`ImuAxes`] names such a log's axes (`[vehicle] imu_axes`),
//! and the ingest turns its increments into FRD; [`AxesCheck`] tells from the log's own
//! data whether the axes it was ingested in are the vehicle's: gravity's direction says
//! which way is down, and the odometer's accelerations which way is forward. The same fit
//! shows the log's scales: gravity's size those of the velocity increments, and the
//! odometer's accelerations against the accelerometers' those of the odometer's distance
//! and of the gyros' rate (a speed file in km/h, angle increments in degrees).

use std::cmp::Ordering;
use std::fmt;
use std::str::FromStr;

use crate::derive::Derived;

/// A direction on the vehicle, as a log's axis may point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Forward (the body's +x).
    Forward,
    /// Backward (−x).
    Backward,
    /// Right (+y).
    Right,
    /// Left (−y).
    Left,
    /// Down (+z).
    Down,
    /// Up (−z).
    Up,
}

impl Direction {
    const ALL: [Self; 6] = [
        Self::Forward,
        Self::Backward,
        Self::Right,
        Self::Left,
        Self::Down,
        Self::Up,
    ];

    /// The body axis (0 x, 1 y, 2 z) and its sign.
    fn body_axis(self) -> (usize, f64) {
        match self {
            Self::Forward => (0, 1.0),
            Self::Backward => (0, -1.0),
            Self::Right => (1, 1.0),
            Self::Left => (1, -1.0),
            Self::Down => (2, 1.0),
            Self::Up => (2, -1.0),
        }
    }

    fn of(axis: usize, negative: bool) -> Self {
        let i = 2 * axis + usize::from(negative);
        Self::ALL[i]
    }

    fn letter(self) -> char {
        match self {
            Self::Forward => 'F',
            Self::Backward => 'B',
            Self::Right => 'R',
            Self::Left => 'L',
            Self::Down => 'D',
            Self::Up => 'U',
        }
    }

    fn word(self) -> &'static str {
        match self {
            Self::Forward => "forward",
            Self::Backward => "back",
            Self::Right => "right",
            Self::Left => "left",
            Self::Down => "down",
            Self::Up => "up",
        }
    }
}

/// Where a log's x, y and z axes point on the vehicle, written as three letters (`"FRD"`,
/// the default and the method's body axes; `"FLU"`, ROS's x forward, y left, z up;
/// `"RFU"`, x right, y forward, z up): F/B forward/back, R/L right/left, D/U down/up.
/// Only right angles, and only right-handed axes: a left-handed set is a log with one
/// axis's sign flipped, which no mounting makes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "String", into = "String")]
pub struct ImuAxes([Direction; 3]);

impl Default for ImuAxes {
    fn default() -> Self {
        Self::FRD
    }
}

/// Why three letters name no IMU axes.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum AxesError {
    /// Not three of F, B, R, L, D, U.
    #[error(
        "\"{0}\" is not three of F, B, R, L, D, U (where the log's x, y and z point on the \
         vehicle: forward/back, right/left, down/up; \"FRD\" is the method's body axes)"
    )]
    Letters(String),
    /// Two axes along the same vehicle direction.
    #[error("\"{0}\" points two of the log's axes along the same line")]
    Repeated(String),
    /// A left-handed set.
    #[error(
        "\"{0}\" is left-handed: no mounting gives it (one of the log's axes has its sign \
         flipped; \"{1}\" is the right-handed set with the same x and y)"
    )]
    LeftHanded(String, String),
}

impl ImuAxes {
    /// The method's body axes: x forward, y right, z down.
    pub const FRD: Self = Self([Direction::Forward, Direction::Right, Direction::Down]);

    /// Every right-handed set at right angles (24).
    pub fn all() -> impl Iterator<Item = Self> {
        (0..216).filter_map(|k: usize| {
            let d = [k % 6, k / 6 % 6, k / 36].map(|i| Direction::ALL[i]);
            Self::new(d).ok()
        })
    }

    /// The set `dirs`, if right-handed at right angles.
    pub fn new(dirs: [Direction; 3]) -> Result<Self, AxesError> {
        let m = Self(dirs).matrix();
        let text = || dirs.iter().map(|d| d.letter()).collect::<String>();
        let axes = dirs.map(|d| d.body_axis().0);
        if axes[0] == axes[1] || axes[1] == axes[2] || axes[0] == axes[2] {
            return Err(AxesError::Repeated(text()));
        }
        if m.determinant() < 0.0 {
            let (a, s) = dirs[2].body_axis();
            let flipped = Direction::of(a, s > 0.0);
            let mut right = dirs;
            right[2] = flipped;
            let right = right.iter().map(|d| d.letter()).collect();
            return Err(AxesError::LeftHanded(text(), right));
        }
        Ok(Self(dirs))
    }

    /// Whether these are the method's body axes (nothing to turn).
    pub fn is_frd(&self) -> bool {
        *self == Self::FRD
    }

    /// The direction each of the log's axes points on the vehicle.
    pub fn directions(&self) -> [Direction; 3] {
        self.0
    }

    /// `v` given in the log's axes, in the body's (FRD): exact, as only signs and places
    /// change.
    pub fn to_body<T: Copy + std::ops::Neg<Output = T>>(&self, v: [T; 3]) -> [T; 3] {
        // The common case, a log in the body's axes, without the loop's places and signs
        // (the ingest turns every sample's increments: 56 instructions a sample).
        if *self == Self::FRD {
            return v;
        }
        let mut out = v;
        for (i, d) in self.0.iter().enumerate() {
            let (axis, sign) = d.body_axis();
            out[axis] = if sign > 0.0 { v[i] } else { -v[i] };
        }
        out
    }

    /// `v` given in the body's axes, in the log's ([`Self::to_body`] undone).
    pub fn to_log<T: Copy + std::ops::Neg<Output = T>>(&self, v: [T; 3]) -> [T; 3] {
        self.inverse().to_body(v)
    }

    /// Where the body's x, y and z point in the log's axes.
    fn inverse(&self) -> Self {
        let mut dirs = self.0;
        for (i, d) in self.0.iter().enumerate() {
            let (axis, sign) = d.body_axis();
            dirs[axis] = Direction::of(i, sign < 0.0);
        }
        Self(dirs)
    }

    /// The log's axes when it was ingested in `self` and those axes are `then` on the
    /// vehicle.
    pub fn then(&self, then: Self) -> Self {
        Self(self.0.map(|d| {
            let (axis, sign) = d.body_axis();
            let (to, to_sign) = then.0[axis].body_axis();
            Direction::of(to, sign * to_sign < 0.0)
        }))
    }

    /// In words: "x right, y forward, z up".
    pub fn words(&self) -> String {
        let [x, y, z] = self.0.map(Direction::word);
        format!("x {x}, y {y}, z {z}")
    }

    /// The turn from the log's axes into the body's.
    pub fn body_from_log(&self) -> nalgebra::Rotation3<f64> {
        nalgebra::Rotation3::from_matrix_unchecked(self.matrix())
    }

    /// Rows: the body axes; columns: the log's.
    fn matrix(&self) -> nalgebra::Matrix3<f64> {
        nalgebra::Matrix3::from_fn(|row, i| {
            let (axis, sign) = self.0[i].body_axis();
            if axis == row { sign } else { 0.0 }
        })
    }
}

impl fmt::Display for ImuAxes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.0.iter().try_for_each(|d| write!(f, "{}", d.letter()))
    }
}

impl FromStr for ImuAxes {
    type Err = AxesError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        // Four at most: enough to tell three from more.
        let letters: Vec<char> = s.trim().chars().take(4).collect();
        let dirs: Option<Vec<Direction>> = letters
            .iter()
            .map(|c| {
                let i = "FBRLDU".find(c.to_ascii_uppercase())?;
                Some(Direction::ALL[i])
            })
            .collect();
        match dirs.as_deref() {
            Some(&[x, y, z]) => Self::new([x, y, z]),
            _ => Err(AxesError::Letters(s.chars().take(16).collect())),
        }
    }
}

impl TryFrom<String> for ImuAxes {
    type Error = AxesError;

    fn try_from(s: String) -> Result<Self, Self::Error> {
        s.parse()
    }
}

impl From<ImuAxes> for String {
    fn from(a: ImuAxes) -> Self {
        a.to_string()
    }
}

/// Shortest log the check judges, s: over a minute, the vehicle's own accelerations
/// average below 0.5 m/s² (30 m/s gained or lost), 3° of the gravity's direction.
pub const CHECK_MIN_S: f64 = 60.0;

/// Largest angle between the mean specific force and the body's up (−z), degrees: a
/// whole run's slope (58 %) no road has; an IMU mounted on its side or upside down is
/// 90° or 180° off.
pub const MAX_TILT_DEG: f64 = 30.0;

/// The mean specific force's magnitude must be within this fraction of gravity: the
/// log's increments are then in m/s, not in g·s or ft/s.
pub const GRAVITY_TOLERANCE: f64 = 0.2;

/// Least correlation between the odometer's and the accelerometers' horizontal
/// accelerations for the drive to show which way is forward.
pub const MIN_FORWARD_CORRELATION: f64 = 0.5;

/// Least sum of the odometer's squared horizontal accelerations over 1-s blocks, (m/s²)²:
/// twenty seconds of 1 m/s² (pulling away, braking, turning).
pub const MIN_FORWARD_EXCITATION: f64 = 20.0;

/// Least sum of the squared accelerations along one axis for its gain to be judged
/// ([`ScaleFit::explained`]), (m/s²)²: ten seconds of 1 m/s².
pub const MIN_SCALE_EXCITATION: f64 = 10.0;

/// The gains a log in its own units gives: 0.98–1.03 on 21 simulated runs, 1.04 along
/// and 1.09 across on Kingston (a car leans out of its turns, which adds g·roll to the
/// lateral specific force). Speeds in km/h give 0.28, mph 0.45, knots 0.51, angle
/// increments in degrees 0.017 across.
pub const SCALE_GAIN_RANGE: std::ops::RangeInclusive<f64> = 0.7..=1.4;

/// Largest ratio of the gains along and across for them to be one scale's (the
/// odometer's distance scales both alike): 1.05 on Kingston, 1.02–1.04 on its speeds in
/// km/h or mph and on a simulated pulse scale doubled; a damaged odometer's speeds
/// dropping to zero gave 0.49 along against 1.08 across.
pub const SCALE_GAINS_ALIKE: f64 = 1.3;

/// Largest sum of the odometer's squared accelerations along x over 1-s blocks, scaled to
/// the vehicle's speed by the gain across, (m/s²)², for its speed to be flat
/// ([`AxesCheck::odometer_flat`]): one second of 1 m/s² over the whole log, where pulling
/// away from one stop and braking at the next give tens. Kingston's speed file gives 74
/// (63 in its own units); its speed column replaced by a constant 21.5 (a temperature,
/// say) 0.0, by a temperature drifting 1.5° over the log 0.03 (0.7 in its own), by a
/// voltage stepping with the engine 0.2 (1.7 in its own).
pub const FLAT_ODOMETER_EXCITATION: f64 = 1.0;

/// What a log's data, in the axes it was ingested in, say of those axes and its scales.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AxesCheck {
    /// Length of the log, s.
    pub duration_s: f64,
    /// The mean specific force over the log, m/s² (body axes as ingested): gravity's
    /// opposite, as the vehicle's own accelerations average out.
    pub mean_specific_force_mps2: [f64; 3],
    /// Angle between it and the body's up (−z), degrees.
    pub tilt_deg: f64,
    /// Turn of the horizontal axes that best carries the odometer's accelerations (u̇
    /// along, ru across) onto the accelerometers', degrees, positive from x towards y
    /// (the IMU's x this far to the vehicle's left of forward): about 0 for the
    /// vehicle's axes. With the log's z not down, taken in the axes turned to have it so.
    pub forward_turn_deg: f64,
    /// Correlation of that fit (0–1).
    pub forward_correlation: f64,
    /// Sum of the odometer's squared horizontal accelerations over 1-s blocks, (m/s²)².
    pub forward_excitation: f64,
    /// The accelerometers' x against the odometer's u̇: 1 when the odometer's distance
    /// is in metres.
    pub along: ScaleFit,
    /// The accelerometers' y against ru: 1 when the odometer's distance is in metres and
    /// the gyros' increments in radians.
    pub across: ScaleFit,
    /// The IMU's mounting the drive shows, as `[vehicle] imu_mounting_deg` would set it
    /// (roll, pitch, yaw, degrees, of the axes as ingested;
    /// [`crate::imu_mounting::seen`]): when the odometer's accelerations along and
    /// across are each [`MIN_SCALE_EXCITATION`] or more and the fit's correlation
    /// [`MIN_FORWARD_CORRELATION`] or more.
    #[serde(default)]
    pub mounting_deg: Option<[f64; 3]>,
    /// The odometer's speed offset the turns show, when the gain across is shown and off
    /// ([`SpeedOffset`]); absent otherwise (a log whose gain across is off fails the
    /// derive, so no stored report holds one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_offset: Option<SpeedOffset>,
}

/// Least speed offset named, m/s: a sensor's bias at rest is centimetres per second.
pub const MIN_SPEED_OFFSET_MPS: f64 = 1.0;

/// The accelerometers' y fitted on the odometer's speed times the yaw rate and on the yaw
/// rate, f_y = gain·r·(u − offset): a speed read `offset_mps` too high (a CAN signal
/// decoded with a wrong offset) lowers the gain on ru alone as the gyros' scale does, but
/// by v/(v + c), which changes with the speed, where the gyros' is one factor (which
/// scales both terms alike, and leaves the offset). Kingston's own speeds give 0.80 and
/// −1.7 m/s (its car's tight turns at low speed pull more than v·r, its highway curves
/// less: the fit's own bias on real data, which an offset adds to): read 3 and 10 m/s
/// high (gains on ru alone 0.66 and 0.33), 0.80 and 1.3, 8.3 m/s; its gyros reading
/// double (0.54 on ru alone), 0.40 and −1.7 m/s, the gyros' verdict. Simulated runs:
/// [`AxesVerdict::OdometerOffset`]'s test.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SpeedOffset {
    /// Gain of the accelerometers' y on r·(u − offset).
    pub gain: f64,
    /// The speed's offset, m/s: positive when it reads high.
    pub offset_mps: f64,
}

impl SpeedOffset {
    /// Whether it, not the gyros' scale, is what the gain across shows: its gain a
    /// right one's, and the offset [`MIN_SPEED_OFFSET_MPS`] or more.
    pub fn explains(&self) -> bool {
        SCALE_GAIN_RANGE.contains(&self.gain) && self.offset_mps.abs() >= MIN_SPEED_OFFSET_MPS
    }
}

/// One of the accelerometers' horizontal axes against the odometer's acceleration along
/// it (1-s means, in the axes [`AxesCheck::forward_turn_deg`] is taken in: those
/// ingested, when their z is down).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ScaleFit {
    /// Least-squares gain of the accelerometer on the odometer's acceleration (slopes'
    /// gravity and vibration are noise in the accelerometer, which leaves it unbiased).
    pub gain: f64,
    /// Their correlation (−1 to 1).
    pub correlation: f64,
    /// Sum of the odometer's squared accelerations, (m/s²)².
    pub excitation: f64,
}

impl ScaleFit {
    /// The accelerometer's sum of squares the odometer's accelerations explain, (m/s²)²:
    /// the odometer's own ([`Self::excitation`]) times the gain squared, the same whatever
    /// the odometer's unit (speeds in m/s read as km/h have 1/13 of the odometer's sum).
    pub fn explained(&self) -> f64 {
        self.excitation * self.gain * self.gain
    }

    /// Whether the drive shows the gain: enough acceleration (the accelerometer's the
    /// odometer explains), well correlated.
    pub fn shown(&self) -> bool {
        self.explained() >= MIN_SCALE_EXCITATION && self.correlation >= MIN_FORWARD_CORRELATION
    }

    /// Whether the gain is shown and beyond what units or scales that are right give.
    fn wrong(&self) -> bool {
        self.shown() && !SCALE_GAIN_RANGE.contains(&self.gain)
    }
}

/// What the check finds wrong.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AxesVerdict {
    /// The axes are the vehicle's, as far as the data show.
    Agree,
    /// Too short a log to tell.
    TooShort,
    /// The mean specific force is not gravity's size.
    NotGravity,
    /// Gravity or the odometer says the axes are other than the vehicle's: the axes the
    /// data show, when they show them all (the drive shows forward), else those with
    /// the right down and x forward as far as known.
    Other {
        /// The log's axes as far as the data show them.
        found: ImuAxes,
        /// Whether the drive showed which way is forward.
        forward_shown: bool,
    },
    /// The mean specific force is tilted from every right angle beyond
    /// [`MAX_TILT_DEG`].
    Tilted,
    /// Neither of the accelerometers' horizontal axes follows the odometer's acceleration
    /// with a gain in [`SCALE_GAIN_RANGE`], and the two gains are alike
    /// ([`SCALE_GAINS_ALIKE`]): the odometer's distance is not in metres (a speed in
    /// km/h, a wrong pulse scale). Judged only when the drive shows both gains.
    OdometerScale,
    /// The odometer's speed barely changes ([`FLAT_ODOMETER_EXCITATION`]) while the
    /// vehicle's turns show a gain across beyond [`SCALE_GAIN_RANGE`]: it is not the
    /// vehicle's speed (a log's extra column of a temperature or a voltage read as one).
    /// Judged when the drive does not show the gain along (a flat speed has nothing the
    /// accelerometers follow); one shown is the other verdicts'.
    OdometerFlat,
    /// The accelerometers' y does not follow ru while x follows u̇: the gyros' rate is
    /// not in radians.
    GyroScale,
    /// As [`AxesVerdict::GyroScale`], but the accelerometers' y follows r·(u − c): the
    /// odometer's speed reads c too high or low ([`AxesCheck::speed_offset`]).
    OdometerOffset,
    /// The drive shows the IMU yawed on its mount beyond
    /// [`crate::imu_mounting::MAX_MOUNTING_YAW_DEG`] (and less than 45°: beyond, another
    /// right angle is nearer forward, [`AxesVerdict::Other`]):
    /// [`AxesCheck::mounting_deg`] gives the setting.
    Mounted,
}

impl AxesCheck {
    /// The check of `d`'s increments, with its odometer's distance per sample.
    pub fn of(d: &Derived) -> Self {
        let sums = BlockSums::of(d);
        let (sum_v, duration_s) = (sums.dvel_mps, sums.duration_s);
        let mean = sum_v.map(|s| s / duration_s.max(f64::MIN_POSITIVE));
        let tilt_deg = angle_deg(mean, [0.0, 0.0, -1.0]);
        // The horizontal, in the axes turned (a right angle) to have down nearest z.
        let down = nearest_down(mean);
        let blocks = Blocks::of(&sums.blocks, down, mean);
        let fit = blocks.fit();
        // The mounting of the axes as ingested, when the drive shows it (accelerations
        // along and across, correlated): the blocks' axes are those turned by `down`
        // (v_blocks = D·v_ingested), so body ← ingested is body ← blocks times D.
        let mounting_deg = crate::imu_mounting::seen(&blocks.mounting_rows)
            .filter(|s| {
                s.correlation >= MIN_FORWARD_CORRELATION
                    && s.excitation.iter().all(|&e| e >= MIN_SCALE_EXCITATION)
            })
            .map(|s| crate::imu_mounting::angles_deg(&(s.body_from_imu * down.body_from_log())));
        Self {
            duration_s,
            mean_specific_force_mps2: mean,
            tilt_deg,
            forward_turn_deg: fit.q.atan2(fit.p).to_degrees(),
            forward_correlation: fit.correlation,
            forward_excitation: fit.excitation,
            along: fit.along,
            across: fit.across,
            mounting_deg,
            speed_offset: fit.speed_offset.filter(|_| fit.across.wrong()),
        }
    }

    /// The mean specific force's size, m/s²: gravity's, in a log in m/s.
    pub fn mean_specific_force_size_mps2(&self) -> f64 {
        norm(self.mean_specific_force_mps2)
    }

    /// Whether the data show the forward direction.
    pub fn forward_shown(&self) -> bool {
        self.forward_excitation >= MIN_FORWARD_EXCITATION
            && self.forward_correlation >= MIN_FORWARD_CORRELATION
    }

    /// Whether the odometer's speed is flat while the vehicle's turns show it is not
    /// the vehicle's: the gain across shown and beyond [`SCALE_GAIN_RANGE`], the gain
    /// along not shown, and the odometer's accelerations along, scaled to the vehicle's
    /// speed by the gain across, under [`FLAT_ODOMETER_EXCITATION`]. A speed in other
    /// units is not flat so scaled (in km/h, its accelerations are 3.6 times, the gain
    /// across 1/3.6). Angle increments in degrees scale the gain across alone, by 1/57.3:
    /// a drive's accelerations so scaled are flat, so the odometer's own must be under
    /// [`MIN_SCALE_EXCITATION`] too (a drive of any length that shows them is the gain
    /// along's, [`AxesVerdict::GyroScale`]).
    pub fn odometer_flat(&self) -> bool {
        let (along, across) = (&self.along, &self.across);
        let scaled = along.excitation * across.gain * across.gain;
        across.wrong()
            && !along.shown()
            && scaled < FLAT_ODOMETER_EXCITATION
            && along.excitation < MIN_SCALE_EXCITATION
    }

    /// The verdict against gravity `g_mps2`.
    pub fn verdict(&self, g_mps2: f64) -> AxesVerdict {
        // NaN is neither long enough nor gravity's size.
        let long_enough = self.duration_s >= CHECK_MIN_S;
        if !long_enough {
            return AxesVerdict::TooShort;
        }
        let size = self.mean_specific_force_size_mps2();
        let gravity_sized = (size - g_mps2).abs() <= GRAVITY_TOLERANCE * g_mps2;
        if !gravity_sized {
            return AxesVerdict::NotGravity;
        }
        let down = nearest_down(self.mean_specific_force_mps2);
        if angle_deg(
            down.to_body(self.mean_specific_force_mps2),
            [0.0, 0.0, -1.0],
        ) > MAX_TILT_DEG
        {
            return AxesVerdict::Tilted;
        }
        let shown = self.forward_shown();
        // Quarter turns about the (turned) z that bring x nearest forward.
        let quarters = if shown {
            (self.forward_turn_deg / 90.0).round().rem_euclid(4.0) as usize
        } else {
            0
        };
        let found = down.then(yaw_quarters(quarters));
        if !found.is_frd() {
            return AxesVerdict::Other {
                found,
                forward_shown: shown,
            };
        }
        // The odometer's distance scales both gains alike; the gyros' rate the one across
        // alone. A gain along alone off is a damaged odometer's (its speed dropping to
        // zero and back while driving makes a u̇ the accelerometers do not follow), not a
        // scale: the ingest's judgements and the joint fit deal with it.
        let (along, across) = (&self.along, &self.across);
        if self.odometer_flat() {
            return AxesVerdict::OdometerFlat;
        }
        if !(along.shown() && across.shown()) {
            return AxesVerdict::Agree;
        }
        // Both off and alike: off on the same side.
        let alike = (along.gain / across.gain).ln().abs() <= SCALE_GAINS_ALIKE.ln();
        if along.wrong() && across.wrong() && alike {
            AxesVerdict::OdometerScale
        } else if across.wrong() && !along.wrong() {
            if self.speed_offset.is_some_and(|o| o.explains()) {
                AxesVerdict::OdometerOffset
            } else {
                AxesVerdict::GyroScale
            }
        } else if self
            .mounting_deg
            .is_some_and(|[_, _, yaw]| yaw.abs() > crate::imu_mounting::MAX_MOUNTING_YAW_DEG)
        {
            AxesVerdict::Mounted
        } else {
            AxesVerdict::Agree
        }
    }
}

/// The right-angle turn of the body axes by `k` quarter turns about z, x towards y: the
/// axes of an IMU whose x points k·90° to the vehicle's left of forward.
fn yaw_quarters(k: usize) -> ImuAxes {
    use Direction::*;
    let dirs = [
        [Forward, Right, Down],
        [Left, Forward, Down],
        [Backward, Left, Down],
        [Right, Backward, Down],
    ];
    ImuAxes(dirs[k % 4])
}

/// The right-angle axes, among those keeping x where it can, that put the log's axis
/// nearest to the mean specific force's opposite down.
fn nearest_down(mean: [f64; 3]) -> ImuAxes {
    // Down first (the body's z along the mean's opposite); among the four sets with it,
    // the one with x forward, else the one with y forward.
    let key = |a: &ImuAxes| {
        let b = a.to_body(mean);
        (
            -b[2],
            a.0[0] == Direction::Forward,
            a.0[1] == Direction::Forward,
        )
    };
    ImuAxes::all()
        .max_by(|a, b| key(a).partial_cmp(&key(b)).unwrap_or(Ordering::Equal))
        .unwrap_or(ImuAxes::FRD)
}

fn norm(v: [f64; 3]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

fn angle_deg(a: [f64; 3], b: [f64; 3]) -> f64 {
    let dot: f64 = a.iter().zip(b).map(|(x, y)| x * y).sum();
    (dot / (norm(a) * norm(b)))
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

/// The sums of one second of samples.
#[derive(Default)]
struct BlockSum {
    /// Time of its first sample, s.
    t_s: f64,
    dt_s: f64,
    dvel_mps: [f64; 3],
    dtheta_rad: [f64; 3],
    /// The odometer's distance over it, m.
    distance_m: f64,
}

/// One pass over a derive's samples: the sums of each second, and of the whole log.
struct BlockSums {
    blocks: Vec<BlockSum>,
    /// Σ of the velocity increments, m/s (sample by sample, in order).
    dvel_mps: [f64; 3],
    duration_s: f64,
}

impl BlockSums {
    fn of(d: &Derived) -> Self {
        let n = d.dt_s.len().min(d.dvel_mps.len()).min(d.dtheta_rad.len());
        let per = ((1.0 / d.nominal_dt_s).round() as usize).max(1);
        let mut out = Self {
            blocks: Vec::with_capacity(n / per + 1),
            dvel_mps: [0.0; 3],
            duration_s: 0.0,
        };
        for start in (0..n).step_by(per) {
            let mut b = BlockSum {
                t_s: d.t_s.get(start),
                ..BlockSum::default()
            };
            for k in start..(start + per).min(n) {
                let (dtheta_rad, dvel_mps) = (d.dtheta_rad.get(k), d.dvel_mps[k]);
                for i in 0..3 {
                    b.dvel_mps[i] += dvel_mps[i];
                    b.dtheta_rad[i] += dtheta_rad[i];
                    out.dvel_mps[i] += dvel_mps[i];
                }
                b.dt_s += d.dt_s[k];
                out.duration_s += d.dt_s[k];
                b.distance_m += d.odo_dist_m.get(k).copied().unwrap_or(0.0);
            }
            out.blocks.push(b);
        }
        out
    }
}

/// The horizontal fit of [`Blocks`].
struct Fit {
    /// Σ f·a and Σ (f_y a_x − f_x a_y): the turn is atan2(q, p).
    p: f64,
    q: f64,
    /// Σ |a|², (m/s²)².
    excitation: f64,
    /// Correlation of the best turn.
    correlation: f64,
    /// f_x on u̇ and f_y on ru.
    along: ScaleFit,
    across: ScaleFit,
    /// f_y on ru and r.
    speed_offset: Option<SpeedOffset>,
}

/// One-second means of the specific force and of the odometer's horizontal acceleration
/// (u̇, ru), in axes whose down is the log's as turned.
struct Blocks {
    /// Per block: specific force x, y, z; u̇, ru, r (r: the rate about the turned z).
    rows: Vec<[f64; 6]>,
    /// The same with r the rate about gravity's direction, wherever the IMU's z points
    /// (the mounting's fit).
    mounting_rows: Vec<[f64; 5]>,
}

impl Blocks {
    /// The rows of the 1-s `blocks` (in the log's axes as ingested), their increments
    /// turned by `turn` (exact: a block's sum turned is its samples' turned, summed).
    /// `mean` is the log's mean specific force as ingested (gravity's opposite).
    fn of(blocks: &[BlockSum], turn: ImuAxes, mean: [f64; 3]) -> Self {
        let u = |b: &BlockSum| b.distance_m / b.dt_s;
        // Down (gravity's direction) in the turned axes: the mean specific force's
        // opposite.
        let size = norm(mean).max(f64::MIN_POSITIVE);
        let down = turn.to_body(mean).map(|x| -x / size);
        let (rows, mounting_rows) = blocks
            .windows(3)
            .filter(|w| w.iter().all(|b| b.dt_s > 0.0))
            .map(|w| {
                let c = &w[1];
                let (v, theta) = (turn.to_body(c.dvel_mps), turn.to_body(c.dtheta_rad));
                let dt = (w[2].t_s - w[0].t_s).max(f64::MIN_POSITIVE);
                let u_dot = (u(&w[2]) - u(&w[0])) / dt;
                let r = theta[2] / c.dt_s;
                let r_down = (0..3).map(|i| theta[i] * down[i]).sum::<f64>() / c.dt_s;
                let f = [v[0] / c.dt_s, v[1] / c.dt_s, v[2] / c.dt_s];
                (
                    [f[0], f[1], f[2], u_dot, r * u(c), r],
                    [f[0], f[1], f[2], u_dot, r_down * u(c)],
                )
            })
            .filter(|(r, m)| r.iter().chain(m).all(|v| v.is_finite()))
            .unzip();
        Self {
            rows,
            mounting_rows,
        }
    }

    /// P = Σ f·a, Q = Σ (f_y a_x − f_x a_y) (the turn is atan2(Q, P)), Σ|a|², and the
    /// correlation of the best turn.
    fn fit(&self) -> Fit {
        let n = self.rows.len().max(1) as f64;
        let mean_f = [0, 1].map(|i| self.rows.iter().map(|r| r[i]).sum::<f64>() / n);
        let (mut p, mut q) = (0.0, 0.0);
        // Per axis: Σ a², Σ f², Σ f·a.
        let mut sums = [[0.0; 3]; 2];
        // f_y on ru and r: Σ (ru)², Σ ru·r, Σ r², Σ f·ru, Σ f·r.
        let mut turns = [0.0; 5];
        for r in &self.rows {
            let fy = r[1] - mean_f[1];
            turns[0] += r[4] * r[4];
            turns[1] += r[4] * r[5];
            turns[2] += r[5] * r[5];
            turns[3] += fy * r[4];
            turns[4] += fy * r[5];
            let f = [r[0] - mean_f[0], r[1] - mean_f[1]];
            let a = [r[3], r[4]];
            p += f[0] * a[0] + f[1] * a[1];
            q += f[1] * a[0] - f[0] * a[1];
            for i in 0..2 {
                sums[i][0] += a[i] * a[i];
                sums[i][1] += f[i] * f[i];
                sums[i][2] += f[i] * a[i];
            }
        }
        let tiny = f64::MIN_POSITIVE;
        let [along, across] = sums.map(|[aa, ff, fa]| ScaleFit {
            gain: fa / aa.max(tiny),
            correlation: fa / (aa * ff).sqrt().max(tiny),
            excitation: aa,
        });
        let (aa, ff) = (sums[0][0] + sums[1][0], sums[0][1] + sums[1][1]);
        // f_y = gain·ru − gain·offset·r; no offset where ru and r are one (a flat speed).
        let det = turns[0] * turns[2] - turns[1] * turns[1];
        let speed_offset = (det > 1e-9 * turns[0] * turns[2]).then(|| {
            let gain = (turns[3] * turns[2] - turns[4] * turns[1]) / det;
            let b = (turns[0] * turns[4] - turns[1] * turns[3]) / det;
            SpeedOffset {
                gain,
                offset_mps: -b / gain,
            }
        });
        Fit {
            p,
            q,
            excitation: aa,
            correlation: p.hypot(q) / (aa * ff).sqrt().max(tiny),
            along,
            across,
            speed_offset: speed_offset.filter(|o| o.gain.is_finite() && o.offset_mps.is_finite()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn letters_name_right_handed_right_angles_only() {
        assert_eq!("FRD".parse::<ImuAxes>(), Ok(ImuAxes::FRD));
        assert_eq!(ImuAxes::default().to_string(), "FRD");
        let flu: ImuAxes = "flu".parse().unwrap();
        assert_eq!(flu.to_string(), "FLU");
        assert_eq!(flu.words(), "x forward, y left, z up");
        assert_eq!(ImuAxes::all().count(), 24);
        assert!(matches!("FRU".parse::<ImuAxes>(), Err(AxesError::LeftHanded(_, r)) if r == "FRD"));
        assert!(matches!(
            "FFD".parse::<ImuAxes>(),
            Err(AxesError::Repeated(_))
        ));
        assert!(matches!(
            "FBD".parse::<ImuAxes>(),
            Err(AxesError::Repeated(_))
        ));
        for bad in ["", "FR", "FRDX", "XYZ", "F R D"] {
            assert!(
                matches!(bad.parse::<ImuAxes>(), Err(AxesError::Letters(_))),
                "{bad}"
            );
        }
        // Every set's text reads back, and its turn is undone exactly.
        let v = [1.5, -2.25, 9.75];
        for a in ImuAxes::all() {
            assert_eq!(a.to_string().parse::<ImuAxes>(), Ok(a));
            assert_eq!(a.to_log(a.to_body(v)), v);
            assert_eq!(a.to_body(a.to_log(v)), v);
        }
    }

    /// RFU: the log's x is the vehicle's right, y forward, z up.
    #[test]
    fn a_vector_turns_into_the_body_axes() {
        let rfu: ImuAxes = "RFU".parse().unwrap();
        // Gravity's opposite at rest, level: the body reads (0, 0, −g); this log +g on z.
        assert_eq!(rfu.to_log([0.0, 0.0, -9.8]), [0.0, 0.0, 9.8]);
        // Accelerating forward: the body's x, the log's y.
        assert_eq!(rfu.to_log([2.0, 0.0, 0.0]), [0.0, 2.0, 0.0]);
        assert_eq!(rfu.to_body([0.0, 2.0, 9.8]), [2.0, 0.0, -9.8]);
        // Ingested as FLU, found to be "x back, y left, z down" relative to that: the
        // log itself is x back, y right, z up.
        let flu: ImuAxes = "FLU".parse().unwrap();
        let rel: ImuAxes = "BLD".parse().unwrap();
        let total = flu.then(rel);
        assert_eq!(total.to_string(), "BRU");
        let v = [0.5, 1.0, 2.0];
        assert_eq!(total.to_body(v), rel.to_body(flu.to_body(v)));
    }
}
