//! A clock in Unix time against one in GPS time, named with the shift that brings one
//! onto the other to the second.
//!
//! KF-GINS logs and most GNSS-timed IMU logs keep GPS seconds of week; an OBD-II or CAN
//! logger beside them, a phone's survey app or a script's export keeps Unix time (UTC
//! seconds since 1 January 1970). The two differ by the 3 657 days from Unix time's start
//! to GPS time's (6 January 1980), the GPS weeks to the log's week, less the leap seconds
//! GPS time has run ahead of UTC since (14 s in 2008, 18 s since 2017): Kingston's speed
//! file in Unix time runs 1 211 068 786 s after its IMU log. No whole hour nor whole week
//! names that, and the run said only "not the IMU's clock".

use unz_formats::kfgins::GPS_WEEK_S;

/// Whole days from Unix time's start to GPS time's.
const GPS_EPOCH_DAYS: u64 = 3_657;

/// Unix time at GPS time's start (6 January 1980, 00:00 UTC), s: 315 964 800.
pub const GPS_EPOCH_UNIX_S: f64 = GPS_EPOCH_DAYS as f64 * 86_400.0;

/// The Unix times from which GPS time runs one more second ahead of UTC: the leap
/// seconds since GPS time's start (IERS Bulletin C; none after the end of 2016).
const LEAP_SECONDS_UNIX_S: [f64; 18] = [
    362_793_600.0,   // 1981-07-01
    394_329_600.0,   // 1982-07-01
    425_865_600.0,   // 1983-07-01
    489_024_000.0,   // 1985-07-01
    567_993_600.0,   // 1988-01-01
    631_152_000.0,   // 1990-01-01
    662_688_000.0,   // 1991-01-01
    709_948_800.0,   // 1992-07-01
    741_484_800.0,   // 1993-07-01
    773_020_800.0,   // 1994-07-01
    820_454_400.0,   // 1996-01-01
    867_715_200.0,   // 1997-07-01
    915_148_800.0,   // 1999-01-01
    1_136_073_600.0, // 2006-01-01
    1_230_768_000.0, // 2009-01-01
    1_341_100_800.0, // 2012-07-01
    1_435_708_800.0, // 2015-07-01
    1_483_228_800.0, // 2017-01-01
];

/// The most GPS weeks a GPS clock is taken to be in: a century of them.
const MAX_WEEKS: f64 = 5_300.0;

/// GPS time's lead over UTC at the Unix time `unix_s`, s.
pub fn gps_minus_utc_s(unix_s: f64) -> f64 {
    LEAP_SECONDS_UNIX_S.iter().filter(|&&t| t <= unix_s).count() as f64
}

/// Two clocks, one in Unix time and the other in GPS seconds of week (or since GPS
/// time's start), and the shift between them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnixAgainstGps {
    /// Added to the other clock's times, it brings them onto the reference's, s.
    pub shift_s: f64,
    /// Whether the other clock is the one in Unix time (else the reference is).
    pub other_is_unix: bool,
    /// The GPS clock's week: the GPS weeks between the clocks beside the epochs' days;
    /// 0 for a clock in GPS seconds since its start.
    pub weeks: u64,
    /// GPS time's lead over UTC at the Unix clock's times (its leap seconds), s.
    pub leap_s: f64,
    /// A time on the Unix clock (the middle of its span), s: its date is named.
    pub unix_s: f64,
}

impl UnixAgainstGps {
    /// The clocks of the span `other` (s; a single time when both ends are one) and the
    /// span `reference`, when one is in Unix time and the other in GPS time: the shift
    /// from the epochs' days, whole GPS weeks and the Unix clock's leap seconds that
    /// brings `other` onto `reference` (a single time within it, a span overlapping it by
    /// half the shorter or more); `None` for any other pair of clocks.
    pub fn between(other: [f64; 2], reference: [f64; 2]) -> Option<Self> {
        let mid = |s: [f64; 2]| 0.5 * (s[0] + s[1]);
        let apart_s = mid(other) - mid(reference);
        let other_is_unix = apart_s > 0.0;
        let unix_s = if other_is_unix {
            mid(other)
        } else {
            mid(reference)
        };
        let leap_s = gps_minus_utc_s(unix_s);
        let weeks = ((apart_s.abs() + leap_s - GPS_EPOCH_UNIX_S) / GPS_WEEK_S).round();
        if !(0.0..=MAX_WEEKS).contains(&weeks) {
            return None;
        }
        let unix_ahead_s = GPS_EPOCH_UNIX_S + weeks * GPS_WEEK_S - leap_s;
        let shift_s = if other_is_unix {
            -unix_ahead_s
        } else {
            unix_ahead_s
        };
        let overlap_s = reference[1].min(other[1] + shift_s) - reference[0].max(other[0] + shift_s);
        let shorter_s = (other[1] - other[0]).min(reference[1] - reference[0]);
        (overlap_s >= 0.5 * shorter_s).then_some(Self {
            shift_s,
            other_is_unix,
            weeks: weeks as u64,
            leap_s,
            unix_s,
        })
    }

    /// "Unix time (UTC seconds since 1 January 1970; 19 May 2008)".
    pub fn unix_clock(&self) -> String {
        let date = unz_formats::kfgins::unix_date(self.unix_s)
            .map(|d| format!("; {d}"))
            .unwrap_or_default();
        format!("Unix time (UTC seconds since 1 January 1970{date})")
    }

    /// "GPS seconds of week (week 1480)", or "GPS seconds since 6 January 1980".
    pub fn gps_clock(&self) -> String {
        match self.weeks {
            0 => "GPS seconds since 6 January 1980".to_owned(),
            w => format!("GPS seconds of week (week {w})"),
        }
    }

    /// What the shift is made of: "the 3657 days from 1 January 1970 to 6 January 1980
    /// and 1480 GPS weeks, less the 14 leap seconds GPS time then ran ahead of UTC".
    pub fn parts(&self) -> String {
        let weeks = match self.weeks {
            0 => String::new(),
            w => format!(" and {w} GPS weeks"),
        };
        format!(
            "the {GPS_EPOCH_DAYS} days from 1 January 1970 to 6 January 1980{weeks}, less the \
             {} leap seconds GPS time then ran ahead of UTC",
            self.leap_s
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// GPS time's lead over UTC: none at its start, 14 s in 2008, 18 s from 2017 on.
    #[test]
    fn leap_seconds_are_counted_to_the_date() {
        assert_eq!(gps_minus_utc_s(GPS_EPOCH_UNIX_S), 0.0);
        assert_eq!(gps_minus_utc_s(1_211_220_929.0), 14.0);
        assert_eq!(gps_minus_utc_s(1_230_767_999.0), 14.0);
        assert_eq!(gps_minus_utc_s(1_230_768_000.0), 15.0);
        assert_eq!(gps_minus_utc_s(1_764_600_000.0), 18.0);
        // 3 657 days, as the constant says.
        assert_eq!(GPS_EPOCH_UNIX_S, GPS_EPOCH_DAYS as f64 * 86_400.0);
    }

    /// Kingston's 876-s log in GPS seconds of week (week 1480, May 2008) against its
    /// speed file in Unix time, either way round, a control point's time, and GPS
    /// seconds since 1980 against Unix time; a clock a day off, or hours off Unix time,
    /// is no such pair.
    #[test]
    fn unix_time_against_gps_time_is_named_to_the_second() {
        let imu = [152_143.09, 153_018.99];
        let unix_ahead_s = GPS_EPOCH_UNIX_S + 1480.0 * GPS_WEEK_S - 14.0;
        let unix = imu.map(|t| t + unix_ahead_s);
        let odo = UnixAgainstGps::between(unix, imu).unwrap();
        assert_eq!(
            (odo.shift_s, odo.other_is_unix, odo.weeks, odo.leap_s),
            (-1_211_068_786.0, true, 1480, 14.0)
        );
        assert_eq!(
            odo.unix_clock(),
            "Unix time (UTC seconds since 1 January 1970; 19 May 2008)"
        );
        assert_eq!(odo.gps_clock(), "GPS seconds of week (week 1480)");
        assert!(odo.parts().starts_with("the 3657 days from 1 January 1970"));
        let imu_unix = UnixAgainstGps::between(imu, unix).unwrap();
        assert_eq!(
            (imu_unix.shift_s, imu_unix.other_is_unix),
            (1_211_068_786.0, false)
        );
        // A control point's time in Unix time, the log's in seconds of week.
        let point = 152_825.0 + unix_ahead_s;
        let cp = UnixAgainstGps::between([point; 2], imu).unwrap();
        assert_eq!(point + cp.shift_s, 152_825.0);
        // GPS seconds since 1980 (2017 on: 18 leap seconds) against Unix time.
        let since_1980 = [1_500_000_000.0, 1_500_003_600.0];
        let utc = since_1980.map(|t| t + GPS_EPOCH_UNIX_S - 18.0);
        let g = UnixAgainstGps::between(utc, since_1980).unwrap();
        assert_eq!((g.shift_s, g.weeks), (-(GPS_EPOCH_UNIX_S - 18.0), 0));
        assert_eq!(g.gps_clock(), "GPS seconds since 6 January 1980");
        // A day off, or Unix time three hours off the week: no such pair.
        assert_eq!(
            UnixAgainstGps::between(imu.map(|t| t + 86_400.0), imu),
            None
        );
        let off = unix.map(|t| t + 3.0 * 3600.0);
        assert_eq!(UnixAgainstGps::between(off, imu), None);
    }
}
