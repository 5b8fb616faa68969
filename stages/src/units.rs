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
    /// The ratio of [`UNIT_RATIOS`] nearest `factor` or its inverse, within 8 % (feet to
    /// metres and km/h to m/s are 9.7 % apart; a right scale is within 10 % of 1).
    pub fn near(factor: f64) -> Option<Self> {
        let off = |ratio: f64| (factor.abs().ln().abs() - ratio.ln()).abs();
        let (ratio, of) = (UNIT_RATIOS.into_iter())
            .filter(|&(ratio, _)| off(ratio) < 1.08f64.ln())
            .min_by(|a, b| off(a.0).total_cmp(&off(b.0)))?;
        Some(Self {
            ratio,
            of,
            inverse: factor.abs() < 1.0,
        })
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
    fn a_factor_near_a_ratio_of_units_finds_the_nearest() {
        let near = |f: f64| UnitRatio::near(f).map(|u| (u.shown(), u.of));
        assert_eq!(near(3.471), Some(("3.6".into(), "km/h to m/s")));
        assert_eq!(near(0.27), Some(("1/3.6".into(), "km/h to m/s")));
        assert_eq!(near(3.3), Some(("3.28084".into(), "feet to metres")));
        assert_eq!(
            near(0.62),
            Some(("1/1.609344".into(), "miles to kilometres"))
        );
        assert_eq!(near(2.3), Some(("2.236936".into(), "mph to m/s")));
        assert_eq!(near(1.9), Some(("1.943844".into(), "knots to m/s")));
        assert_eq!(near(1e-3), Some(("1/1000".into(), "kilometres to metres")));
        // A scale wrong by a quarter, a fifth or fivefold is no unit's (twice is near
        // knots to m/s).
        for factor in [0.75, 1.0, 1.2, 1.35, 5.0, 10.0, f64::NAN] {
            assert_eq!(near(factor), None, "{factor}");
        }
    }
}
