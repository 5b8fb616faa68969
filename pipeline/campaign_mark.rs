//! The vehicle's mark across a campaign's runs. The mark's lever arm is the vehicle's, not
//! a run's: where the joint fits of several runs estimated it, their inverse-variance mean
//! is what to configure, far more precise than any one run's (`campaign.md`).

use std::fmt::Write as _;

/// One run's estimate of the mark, from the navigated point in the IMU's axes, m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkEstimate {
    /// Forward (body x) and its 1σ.
    pub forward_m: (f64, f64),
    /// Right (body y) and its 1σ.
    pub right_m: (f64, f64),
    /// Down (body z), as configured (not estimated).
    pub down_m: f64,
}

/// The runs' estimates of the vehicle's mark, gathered run by run.
#[derive(Debug, Default)]
pub struct MarkAcross {
    /// The runs that estimated the mark: name and estimate.
    estimates: Vec<(String, MarkEstimate)>,
    /// Runs whose joint fit was checked for a mark.
    checked: usize,
}

/// The inverse-variance mean of `(value, σ)`, its σ, and the χ² per degree of freedom of
/// the values about it (`None` with fewer than two).
pub(crate) fn weighted_mean(
    v: impl Iterator<Item = (f64, f64)> + Clone,
) -> (f64, f64, Option<f64>) {
    let w_sum: f64 = v.clone().map(|(_, s)| 1.0 / (s * s)).sum();
    let mean = v.clone().map(|(x, s)| x / (s * s)).sum::<f64>() / w_sum;
    let n = v.clone().count();
    let chi2 =
        (n > 1).then(|| v.map(|(x, s)| ((x - mean) / s).powi(2)).sum::<f64>() / (n - 1) as f64);
    (mean, (1.0 / w_sum).sqrt(), chi2)
}

/// χ² per degree of freedom beyond which the runs' estimates disagree: about the 99.7 %
/// point for a few runs (for one degree of freedom it is 8.8, for ten 2.6; 3 is a
/// middle that flags a second vehicle without flagging the spread of one).
pub(crate) const DISAGREE_CHI2_PER_DOF: f64 = 3.0;

impl MarkAcross {
    /// Adds the run `name`: whether its joint fit was checked for a mark (or estimated
    /// it), and its estimate when the fit estimated one.
    pub fn add(&mut self, name: &str, checked: bool, estimate: Option<MarkEstimate>) {
        self.checked += usize::from(checked);
        self.estimates
            .extend(estimate.map(|e| (name.to_owned(), e)));
    }

    /// `campaign.md`'s section, when a run's joint fit estimated the mark.
    pub fn markdown(&self) -> Option<String> {
        let e = &self.estimates;
        if e.is_empty() {
            return None;
        }
        let (f, sf, chi_f) = weighted_mean(e.iter().map(|(_, m)| m.forward_m));
        let (r, sr, chi_r) = weighted_mean(e.iter().map(|(_, m)| m.right_m));
        let down: Vec<f64> = e.iter().map(|(_, m)| m.down_m).collect();
        let z = down[0];
        let mut md = format!(
            "\n## The vehicle's mark\n\n{} of the {} runs whose joint fit was checked for the \
             vehicle's mark estimated it (their control points' errors turned with the \
             heading at the stops). Their inverse-variance mean, from the navigated point in \
             the IMU's axes: **{f:.2} ± {sf:.2} m forward, {r:.2} ± {sr:.2} m right** \
             ({z} m down, as configured). If the runs share one vehicle and its \
             installation, set `[vehicle] mark_lever_arm_m = [{f:.2}, {r:.2}, {z}]`.\n",
            e.len(),
            self.checked
        );
        if down.iter().any(|d| *d != z) {
            md += "\nThe runs' configured arms differ in height (down): each run's estimate is \
                   from its own.\n";
        }
        let disagree = [chi_f, chi_r]
            .into_iter()
            .flatten()
            .any(|c| c > DISAGREE_CHI2_PER_DOF);
        if disagree {
            let _ = writeln!(
                md,
                "\nThe runs' estimates disagree beyond their σ (χ² per degree of freedom: \
                 forward {:.1}, right {:.1}): more than one vehicle or installation?",
                chi_f.unwrap_or(f64::NAN),
                chi_r.unwrap_or(f64::NAN)
            );
        }
        md += "\n| run | forward [m] | right [m] |\n|---|---|---|\n";
        for (name, m) in e {
            let _ = writeln!(
                md,
                "| {name} | {:.2} ± {:.2} | {:.2} ± {:.2} |",
                m.forward_m.0, m.forward_m.1, m.right_m.0, m.right_m.1
            );
        }
        Some(md)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(f: f64, r: f64, s: f64) -> MarkEstimate {
        MarkEstimate {
            forward_m: (f, s),
            right_m: (r, s),
            down_m: 0.3,
        }
    }

    #[test]
    fn the_runs_estimates_are_pooled_by_their_sigma() {
        let mut m = MarkAcross::default();
        m.add("a", true, None);
        assert_eq!(m.markdown(), None);
        // Two runs at σ 0.3 m and one at σ 0.6 m: weights 4:4:1.
        m.add("b", true, Some(at(1.4, -1.1, 0.3)));
        m.add("c", true, Some(at(1.6, -0.9, 0.3)));
        m.add("d", true, Some(at(1.0, -1.0, 0.6)));
        let (f, sf, _) = weighted_mean([(1.4, 0.3), (1.6, 0.3), (1.0, 0.6)].into_iter());
        assert!((f - (1.4 * 4.0 + 1.6 * 4.0 + 1.0) / 9.0).abs() < 1e-12);
        assert!((sf - 0.2).abs() < 1e-12);
        let md = m.markdown().unwrap();
        assert!(md.contains("3 of the 4 runs"), "{md}");
        assert!(
            md.contains("1.44 ± 0.20 m forward, -1.00 ± 0.20 m right"),
            "{md}"
        );
        assert!(md.contains("mark_lever_arm_m = [1.44, -1.00, 0.3]"), "{md}");
        assert!(!md.contains("disagree"), "{md}");
        assert!(md.contains("| d | 1.00 ± 0.60 | -1.00 ± 0.60 |"), "{md}");
        // A second vehicle 2 m further forward.
        m.add("e", true, Some(at(3.5, -1.0, 0.3)));
        m.add("f", true, Some(at(3.4, -1.0, 0.3)));
        assert!(m.markdown().unwrap().contains("disagree beyond their σ"));
    }
}
