//! The odometer's lag across a campaign's runs. The lag is the vehicle's odometer and its
//! logger's (an OBD-II speed read over a bus, a pulse counter's latch), not a run's:
//! where the joint fits of several runs estimated it, their inverse-variance mean is the
//! derive's offset to configure (`campaign.md`). Configured, the ingest's bridges of the
//! odometer's failures are centred on it, a run whose joint fit cannot estimate the lag
//! (fewer than two control points) is derived with it, and each fit searches about it.

use std::fmt::Write as _;

use crate::campaign_mark::DISAGREE_CHI2_PER_DOF;
use crate::campaign_outliers::{SigmaPool, pooled_by_sigma};
use crate::campaign_settings::Pooled;

/// One run's odometer lag: in all (the configured offset's and the joint's beyond it), s,
/// and its 1σ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LagEstimate {
    /// The lag in all, s (positive: the odometer reports late).
    pub lag_s: f64,
    /// Its 1σ, s.
    pub sigma_s: f64,
    /// The derive's `odo_time_offset_s` the run was configured with, s.
    pub offset_s: f64,
    /// Whether the fit's lag stopped at its search's bound (its σ then says nothing).
    pub at_bound: bool,
}

/// The runs' estimates of the odometer's lag, gathered run by run.
#[derive(Debug, Default)]
pub struct LagAcross {
    estimates: Vec<(String, LagEstimate)>,
    /// Runs whose lag stopped at the search's bound, and their lag in all, s.
    at_bound: Vec<(String, f64)>,
}

impl LagAcross {
    /// Adds the run `name`'s estimate (when its joint fit estimated the lag: σ > 0; one
    /// at the search's bound is listed apart).
    pub fn add(&mut self, name: &str, estimate: LagEstimate) {
        if estimate.at_bound {
            self.at_bound.push((name.to_owned(), estimate.lag_s));
        } else if estimate.sigma_s > 0.0
            && estimate.sigma_s.is_finite()
            && estimate.lag_s.is_finite()
        {
            self.estimates.push((name.to_owned(), estimate));
        }
    }

    /// The runs' lags pooled by their σ, with those that disagree set aside, when two or
    /// more runs estimated the lag (one run's is in its own row).
    fn pool(&self) -> Option<SigmaPool> {
        let e = &self.estimates;
        (e.len() >= 2).then(|| {
            pooled_by_sigma(
                &e.iter()
                    .map(|(_, l)| (l.lag_s, l.sigma_s))
                    .collect::<Vec<_>>(),
            )
        })
    }

    /// The derive's `odo_time_offset_s` to configure (the mean lag, negated, as the
    /// section writes it), when the pooled runs' lags agree and a pooled run's configured
    /// offset lies beyond its σ.
    pub fn setting(&self) -> Option<Pooled> {
        let pool = self.pool()?;
        pool.setting(
            -pool.mean,
            3,
            self.estimates.iter().map(|(_, l)| l.offset_s),
        )
    }

    /// `campaign.md`'s section, when two or more runs estimated the lag.
    pub fn markdown(&self) -> Option<String> {
        let e = &self.estimates;
        let pool = self.pool()?;
        let (lag, sigma) = (pool.mean, pool.sigma);
        let offset = -lag;
        let mut md = format!(
            "\n## The odometer's lag\n\n{} runs' joint fits estimated the odometer's lag \
             (the configured `[derive] odo_time_offset_s`'s and the fit's beyond it). Their \
             inverse-variance mean: **{lag:.3} ± {sigma:.3} s** (positive: the odometer \
             reports late). If the runs share one odometer and its logger, set `[derive] \
             odo_time_offset_s = {offset:.3}`: the ingest then bridges the odometer's \
             failures about it, a run the joint fit cannot estimate the lag of (fewer than \
             two control points) is derived with it, and each fit searches about it.\n",
            e.len()
        );
        md += &pool
            .set_aside_sentence("lag", e.iter().map(|(n, _)| n.as_str()))
            .unwrap_or_default();
        if let Some(c) = pool.chi2.filter(|c| *c > DISAGREE_CHI2_PER_DOF) {
            let _ = writeln!(
                md,
                "\nThe runs' lags disagree beyond their σ (χ² per degree of freedom {c:.1}): \
                 more than one odometer or logger, or a logger whose delay changed?"
            );
        }
        md += "\n| run | configured offset [s] | lag in all [s] | pooled |\n|---|---|---|---|\n";
        for ((name, l), pooled) in e.iter().zip(&pool.verdict.pooled) {
            let _ = writeln!(
                md,
                "| {name} | {:.3} | {:.3} ± {:.3} | {} |",
                l.offset_s,
                l.lag_s,
                l.sigma_s,
                if *pooled { "yes" } else { "no" }
            );
        }
        if !self.at_bound.is_empty() {
            let listed: Vec<String> = self
                .at_bound
                .iter()
                .map(|(name, lag)| format!("{name} ({lag:.3} s)"))
                .collect();
            let _ = writeln!(
                md,
                "\nLeft out, their lag at the search's bound (`[disupt] odo_lag_bound_s` about \
                 the configured offset): {}.",
                listed.join(", ")
            );
        }
        Some(md)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lag(lag_s: f64, sigma_s: f64, offset_s: f64) -> LagEstimate {
        LagEstimate {
            lag_s,
            sigma_s,
            offset_s,
            at_bound: false,
        }
    }

    #[test]
    fn the_runs_lags_are_pooled_by_their_sigma() {
        let mut l = LagAcross::default();
        // Not estimated (σ 0): left out.
        l.add("a", lag(0.0, 0.0, 0.0));
        l.add("b", lag(0.38, 0.1, 0.0));
        assert_eq!(l.markdown(), None);
        // Weights 1:1:4.
        l.add("c", lag(0.42, 0.1, -0.3));
        l.add("d", lag(0.40, 0.05, 0.0));
        let md = l.markdown().unwrap();
        assert!(md.contains("3 runs' joint fits"), "{md}");
        assert!(md.contains("**0.400 ± 0.041 s**"), "{md}");
        assert!(md.contains("odo_time_offset_s = -0.400`"), "{md}");
        assert!(md.contains("| c | -0.300 | 0.420 ± 0.100 | yes |"), "{md}");
        assert!(!md.contains("disagree"), "{md}");
        // The offset as the section writes it; σ = 1/√(100 + 100 + 400).
        let s = l.setting().unwrap();
        assert_eq!((s.value, s.runs), (-0.4, 3));
        assert!((s.sigma - 600f64.sqrt().recip()).abs() < 1e-12, "{s:?}");
        // Runs configured with the offset they show: nothing to change.
        let mut configured = LagAcross::default();
        configured.add("a", lag(0.41, 0.1, -0.4));
        configured.add("b", lag(0.38, 0.1, -0.4));
        assert!(configured.markdown().is_some());
        assert_eq!(configured.setting(), None);
        // A lag at the search's bound is listed apart, not pooled.
        l.add(
            "f",
            LagEstimate {
                at_bound: true,
                ..lag(-1.0, 0.1, 0.0)
            },
        );
        let md = l.markdown().unwrap();
        assert!(md.contains("**0.400 ± 0.041 s**"), "{md}");
        assert!(md.contains("configured offset): f (-1.000 s)."), "{md}");
        // A logger 1 s late, 10σ from the others: set aside, the others' mean kept.
        l.add("e", lag(1.4, 0.1, 0.0));
        let md = l.markdown().unwrap();
        assert!(md.contains("**0.400 ± 0.041 s**"), "{md}");
        assert!(md.contains("others', left out of the mean: e.\n"), "{md}");
        assert!(md.contains("| e | 0.000 | 1.400 ± 0.100 | no |"), "{md}");
        assert!(!md.contains("disagree beyond their σ"), "{md}");
        assert_eq!(l.setting().map(|s| (s.value, s.runs)), Some((-0.4, 3)));
        // Two that disagree: neither can be told wrong, and nothing is set.
        let mut two = LagAcross::default();
        two.add("a", lag(0.4, 0.05, 0.0));
        two.add("b", lag(1.0, 0.05, 0.0));
        assert!(two.markdown().unwrap().contains("disagree beyond their σ"));
        assert_eq!(two.setting(), None);
    }
}
