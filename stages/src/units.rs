//! Unit conversions used across the stages: one definition each.

/// One degree per hour in rad/s (gyro drifts are reported in °/h).
pub const DEG_PER_H: f64 = std::f64::consts::PI / 180.0 / 3600.0;

/// One milli-g in m/s² (accelerometer biases).
pub const MILLI_G: f64 = 9.806_65e-3;

/// One degree per square-root hour in rad/√s (angle random walk).
pub const DEG_PER_SQRT_H: f64 = std::f64::consts::PI / 180.0 / 60.0;

/// Ratios between units an odometer's speeds, distances or pulse scale may be written in
/// by mistake, each with what it is the ratio of (the larger number's unit first).
pub const UNIT_RATIOS: [(f64, &str); 6] = [
    (3.6, "km/h to m/s"),
    (3.280_84, "feet to metres"),
    (2.236_936, "mph to m/s"),
    (1.943_844, "knots to m/s"),
    (1.609_344, "miles to kilometres"),
    (1000.0, "kilometres to metres"),
];

/// The gains a log in its own units gives (0.98–1.09), with a percent of room either
/// side: what a factor leaves when a unit's ratio is taken out of it.
pub const OWN_GAIN_NEAR: std::ops::RangeInclusive<f64> = 0.97..=1.10;

/// A ratio of [`UNIT_RATIOS`] a `factor` is near, either way.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnitRatio {
    /// The ratio, > 1.
    pub ratio: f64,
    /// What it is the ratio of.
    pub of: &'static str,
    /// The factor is near 1 / `ratio`.
    pub inverse: bool,
}

impl UnitRatio {
    /// Every ratio of [`UNIT_RATIOS`] that `factor` (the odometer's accelerations over
    /// the accelerometers') may be, or its inverse, the nearest first. A log in its own
    /// units gives the accelerometers' gain 0.98–1.09 over the odometer's
    /// ([`crate::imu_axes::SCALE_GAIN_RANGE`]; Kingston on its own clock 1.08), so speeds
    /// r times too large read r/1.09 to r/0.98, and r times too small 1/(1.09·r) to
    /// 1/(0.98·r): a ratio is named when the gain it leaves is within [`OWN_GAIN_NEAR`]
    /// (that band with a percent of room either side). Feet to metres and km/h to m/s are
    /// 9.7 % apart, so a factor between them may be either's, and both are named
    /// (Kingston's km/h on its own clock: 3.32, a gain of 1.08 in km/h and 0.99 in feet).
    /// A right scale is no ratio's (the nearest, miles to kilometres, is 1.61).
    pub fn near(factor: f64) -> Vec<Self> {
        let f = factor.abs();
        let inverse = f < 1.0;
        // The gain in the log's own units were the speeds `ratio` times off.
        let own_gain = |ratio: f64| {
            if inverse {
                1.0 / (f * ratio)
            } else {
                ratio / f
            }
        };
        let mut near: Vec<(f64, &'static str)> = (UNIT_RATIOS.into_iter())
            .filter(|&(ratio, _)| OWN_GAIN_NEAR.contains(&own_gain(ratio)))
            .collect();
        near.sort_by(|a, b| {
            own_gain(a.0)
                .ln()
                .abs()
                .total_cmp(&own_gain(b.0).ln().abs())
        });
        (near.into_iter())
            .map(|(ratio, of)| Self { ratio, of, inverse })
            .collect()
    }

    /// The ratio as a factor: `3.6`, or `1/3.6` when inverse.
    pub fn shown(&self) -> String {
        if self.inverse {
            format!("1/{}", self.ratio)
        } else {
            format!("{}", self.ratio)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::UnitRatio;

    #[test]
    fn a_factor_near_ratios_of_units_finds_them_the_nearest_first() {
        let near = |f: f64| {
            (UnitRatio::near(f).iter())
                .map(|u| (u.shown(), u.of))
                .collect::<Vec<_>>()
        };
        let one = |shown: &str, of| vec![(shown.to_owned(), of)];
        assert_eq!(near(3.6), one("3.6", "km/h to m/s"));
        assert_eq!(near(0.27), one("1/3.6", "km/h to m/s"));
        assert_eq!(near(3.15), one("3.28084", "feet to metres"));
        assert_eq!(near(0.62), one("1/1.609344", "miles to kilometres"));
        assert_eq!(near(2.3), one("2.236936", "mph to m/s"));
        assert_eq!(near(1.9), one("1.943844", "knots to m/s"));
        assert_eq!(near(1e-3), one("1/1000", "kilometres to metres"));
        // Between feet to metres and km/h to m/s (9.7 % apart), both, the nearest first:
        // Kingston's speeds in km/h read 3.32 on its own clock (a gain of 1.08 left in
        // km/h, 0.99 in feet).
        assert_eq!(
            near(3.32),
            [
                ("3.28084".to_owned(), "feet to metres"),
                ("3.6".to_owned(), "km/h to m/s")
            ]
        );
        // 3.45 (Kingston's km/h in session 60) leaves feet a gain of 0.95: km/h only.
        assert_eq!(near(3.45), one("3.6", "km/h to m/s"));
        assert_eq!(
            near(1.0 / 3.5),
            [
                ("1/3.6".to_owned(), "km/h to m/s"),
                ("1/3.28084".to_owned(), "feet to metres")
            ]
        );
        // Beyond the gains a log's own units give: one only.
        assert_eq!(near(3.7), one("3.6", "km/h to m/s"));
        assert_eq!(near(3.1), one("3.28084", "feet to metres"));
        // A scale wrong by a quarter, a fifth or fivefold is no unit's (twice is near
        // knots to m/s).
        for factor in [0.75, 1.0, 1.2, 1.35, 5.0, 10.0, f64::NAN] {
            assert_eq!(near(factor), [], "{factor}");
        }
    }
}
