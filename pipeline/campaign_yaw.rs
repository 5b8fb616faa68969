//! The IMU's yaw on the vehicle across a campaign's runs. An IMU turned on the vehicle
//! turns the odometer's direction of travel from its x: the joint fit's residuals show
//! that odometer yaw boresight in each run (and the fit estimates it beyond 3σ), and a
//! run's azimuth takes whatever its fit does not. The boresight is the installation's,
//! not a run's: the runs' estimates, those below the refit's threshold too, pool by their
//! σ into the mounting to configure (`[vehicle] imu_mounting_deg`'s yaw), which then turns
//! every run's increments into the vehicle's axes (`campaign.md`).

use std::fmt::Write as _;

use crate::campaign_mark::DISAGREE_CHI2_PER_DOF;
use crate::campaign_outliers::{SigmaPool, pooled_by_sigma};
use crate::campaign_settings::Pooled;

/// How many σ from none the runs' mean boresight must lie for the section to advise a
/// mounting (without a mounting configured, which the section then checks).
const SHOWN_SIGMA: f64 = 3.0;

/// One run's odometer yaw boresight and the mounting it was navigated with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct YawEstimate {
    /// The boresight: the odometer's direction is the body's x turned by it, degrees.
    pub boresight_deg: f64,
    /// Its 1σ, degrees.
    pub sigma_deg: f64,
    /// Whether the joint fit estimated it (else its residuals showed it below the refit's
    /// threshold).
    pub estimated: bool,
    /// The IMU's mounting the run was ingested with (`[vehicle] imu_mounting_deg`).
    pub mounting_deg: [f64; 3],
}

impl YawEstimate {
    /// The IMU's mounting yaw this run shows in all, degrees: the configured yaw less the
    /// boresight left (an IMU turned ψ to the right shows the odometer ψ to the left).
    fn mounting_yaw_deg(&self) -> f64 {
        self.mounting_deg[2] - self.boresight_deg
    }
}

/// The runs' odometer yaw boresights, gathered run by run.
#[derive(Debug, Default)]
pub struct YawAcross {
    estimates: Vec<(String, YawEstimate)>,
}

impl YawAcross {
    /// Adds the run `name`'s estimate (with σ > 0).
    pub fn add(&mut self, name: &str, estimate: YawEstimate) {
        if estimate.sigma_deg > 0.0
            && estimate.sigma_deg.is_finite()
            && estimate.boresight_deg.is_finite()
        {
            self.estimates.push((name.to_owned(), estimate));
        }
    }

    /// The runs' mounting yaws pooled by their σ, with those that disagree set aside, when
    /// the mean lies beyond its 3σ from none or a mounting is configured.
    fn pool(&self) -> Option<SigmaPool> {
        let e = &self.estimates;
        if e.is_empty() {
            return None;
        }
        let pool = pooled_by_sigma(
            &e.iter()
                .map(|(_, y)| (y.mounting_yaw_deg(), y.sigma_deg))
                .collect::<Vec<_>>(),
        );
        let configured = e.iter().any(|(_, y)| y.mounting_deg != [0.0; 3]);
        (configured || pool.mean.abs() > SHOWN_SIGMA * pool.sigma).then_some(pool)
    }

    /// The mounting's yaw to configure (`[vehicle] imu_mounting_deg`'s third, as the
    /// section writes it), when the pooled runs' yaws agree and a pooled run's configured
    /// yaw lies beyond its σ.
    pub fn setting(&self) -> Option<Pooled> {
        let pool = self.pool()?;
        pool.setting(
            pool.mean,
            2,
            self.estimates.iter().map(|(_, y)| y.mounting_deg[2]),
        )
    }

    /// `campaign.md`'s section, when the runs' mean mounting yaw lies beyond its 3σ from
    /// none, or a mounting is configured.
    pub fn markdown(&self) -> Option<String> {
        let e = &self.estimates;
        let pool = self.pool()?;
        let (yaw, sigma, chi2) = (pool.mean, pool.sigma, pool.chi2);
        let [roll, pitch, _] = e[0].1.mounting_deg;
        let same_tilt = e
            .iter()
            .all(|(_, y)| y.mounting_deg[..2] == e[0].1.mounting_deg[..2]);
        let estimated = e.iter().filter(|(_, y)| y.estimated).count();
        let mut md = format!(
            "\n## The IMU's yaw on the vehicle\n\n{} runs' joint fits showed an odometer yaw \
             boresight ({estimated} estimated it, {} showed it in their residuals below the \
             refit's threshold). With the mounting each was ingested with, their \
             inverse-variance mean of the IMU's yaw on the vehicle: **{yaw:.2}° ± \
             {sigma:.2}°**. If the runs share one vehicle and its installation, set \
             `[vehicle] imu_mounting_deg = [{roll}, {pitch}, {yaw:.2}]`: the increments are \
             then the vehicle's, and no run's azimuth takes the turn.\n",
            e.len(),
            e.len() - estimated
        );
        if !same_tilt {
            md += "\nThe runs' configured mountings differ in roll or pitch: the roll and \
                   pitch above are the first run's.\n";
        }
        md += &pool
            .set_aside_sentence("yaw", e.iter().map(|(n, _)| n.as_str()))
            .unwrap_or_default();
        if let Some(c) = chi2.filter(|c| *c > DISAGREE_CHI2_PER_DOF) {
            let _ = writeln!(
                md,
                "\nThe runs' yaws disagree beyond their σ (χ² per degree of freedom {c:.1}): \
                 more than one vehicle or installation, or an IMU moved between runs?"
            );
        }
        md += "\n| run | configured yaw [°] | boresight [°] | estimated | yaw in all [°] | pooled \
               |\n|---|---|---|---|---|---|\n";
        for ((name, y), pooled) in e.iter().zip(&pool.verdict.pooled) {
            let _ = writeln!(
                md,
                "| {name} | {:.2} | {:.2} ± {:.2} | {} | {:.2} | {} |",
                y.mounting_deg[2],
                y.boresight_deg,
                y.sigma_deg,
                if y.estimated { "yes" } else { "no" },
                y.mounting_yaw_deg(),
                if *pooled { "yes" } else { "no" }
            );
        }
        Some(md)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn yaw(boresight_deg: f64, sigma_deg: f64, mounting_deg: [f64; 3]) -> YawEstimate {
        YawEstimate {
            boresight_deg,
            sigma_deg,
            estimated: boresight_deg.abs() > 3.0 * sigma_deg,
            mounting_deg,
        }
    }

    #[test]
    fn the_runs_boresights_pool_into_the_mounting() {
        let mut y = YawAcross::default();
        // Runs without a turn: nothing to set.
        y.add("a", yaw(0.1, 0.25, [0.0; 3]));
        y.add("b", yaw(-0.2, 0.25, [0.0; 3]));
        assert_eq!(y.markdown(), None);
        assert_eq!(y.setting(), None);
        // Four runs of an IMU turned 0.6° to the left, none beyond the refit's 3σ alone
        // (0.5–0.7° ± 0.25°), pool to 6σ.
        let mut y = YawAcross::default();
        for (name, b) in [("a", 0.5), ("b", 0.7), ("c", 0.6), ("d", 0.6)] {
            y.add(name, yaw(b, 0.25, [0.0; 3]));
        }
        y.add("z", yaw(1.0, 0.0, [0.0; 3]));
        let md = y.markdown().unwrap();
        assert!(md.contains("4 runs' joint fits"), "{md}");
        assert!(md.contains("(0 estimated it"), "{md}");
        assert!(md.contains("**-0.60° ± 0.12°**"), "{md}");
        assert!(md.contains("imu_mounting_deg = [0, 0, -0.60]"), "{md}");
        assert!(!md.contains("disagree"), "{md}");
        let s = y.setting().unwrap();
        assert_eq!((s.value, s.runs), (-0.6, 4));
        // Configured: the yaw in all is the configured one less the boresight left.
        let mut y = YawAcross::default();
        y.add("a", yaw(0.05, 0.2, [0.0, 1.0, -0.6]));
        y.add("b", yaw(-0.05, 0.2, [0.0, 1.0, -0.6]));
        let md = y.markdown().unwrap();
        assert!(md.contains("**-0.60° ± 0.14°**"), "{md}");
        assert!(md.contains("imu_mounting_deg = [0, 1, -0.60]"), "{md}");
        // That is what the runs show: nothing to change.
        assert_eq!(y.setting(), None);
        // Another installation, 3° off: set aside (the others' mean kept).
        y.add("c", yaw(3.0, 0.2, [0.0, 1.0, -0.6]));
        let md = y.markdown().unwrap();
        assert!(md.contains("**-0.60° ± 0.14°**"), "{md}");
        assert!(md.contains("left out of the mean: c.\n"), "{md}");
        assert!(md.contains("| -3.60 | no |"), "{md}");
        assert_eq!(y.setting(), None);
        // Two that disagree: named by their χ², nothing set.
        let mut two = YawAcross::default();
        two.add("a", yaw(0.5, 0.2, [0.0; 3]));
        two.add("b", yaw(3.0, 0.2, [0.0; 3]));
        assert!(two.markdown().unwrap().contains("disagree beyond their σ"));
        assert_eq!(two.setting(), None);
    }
}
