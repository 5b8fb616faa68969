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
    /// Every ratio of [`UNIT_RATIOS`] within 8 % of `factor` or its inverse, the nearest
    /// first. A log in its own units gives a gain 0.98–1.09 from 1
    /// ([`crate::imu_axes::SCALE_GAIN_RANGE`]), so a factor between two ratios less than
    /// twice that apart (feet to metres and km/h to m/s, 9.7 %) may be either's: both are
    /// named. A right scale is within 10 % of 1, no ratio's.
    pub fn near(factor: f64) -> Vec<Self> {
        let off = |ratio: f64| (factor.abs().ln().abs() - ratio.ln()).abs();
        let mut near: Vec<(f64, &'static str)> = (UNIT_RATIOS.into_iter())
            .filter(|&(ratio, _)| off(ratio) < 1.08f64.ln())
            .collect();
        near.sort_by(|a, b| off(a.0).total_cmp(&off(b.0)));
        (near.into_iter())
            .map(|(ratio, of)| Self {
                ratio,
                of,
                inverse: factor.abs() < 1.0,
            })
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
        // Kingston's speeds in km/h read 3.45 (its gain in m/s is 1.04), and 3.36 with
        // its clock's lag left.
        assert_eq!(
            near(3.36),
            [
                ("3.28084".to_owned(), "feet to metres"),
                ("3.6".to_owned(), "km/h to m/s")
            ]
        );
        assert_eq!(
            near(1.0 / 3.45),
            [
                ("1/3.6".to_owned(), "km/h to m/s"),
                ("1/3.28084".to_owned(), "feet to metres")
            ]
        );
        // A scale wrong by a quarter, a fifth or fivefold is no unit's (twice is near
        // knots to m/s).
        for factor in [0.75, 1.0, 1.2, 1.35, 5.0, 10.0, f64::NAN] {
            assert_eq!(near(factor), [], "{factor}");
        }
    }
}
