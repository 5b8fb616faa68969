//! Runs' estimates of one of the vehicle's constants, pooled by the inverse of their
//! variances with the runs that disagree set aside: the run farthest from the others'
//! mean, beyond [`DISAGREE_SIGMA`] of their combined σ, again and again while three or
//! more remain. Of two that disagree, neither can be told wrong: both stay, and both are
//! named. A run's "others" are the pooled sums less its own, so each pass is linear in
//! the runs.

use crate::campaign_mark::{DISAGREE_CHI2_PER_DOF, weighted_mean};
use crate::campaign_settings::Pooled;

/// How many σ a run's estimate may lie from the others' before it is named as
/// disagreeing.
pub const DISAGREE_SIGMA: f64 = 3.0;

/// Inverse-variance sums of estimates: how many, Σ w and Σ w·x.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Weighted {
    runs: i64,
    w: f64,
    w_x: f64,
}

impl Weighted {
    /// The sums of one estimate `x` of variance `variance`.
    fn of((x, variance): (f64, f64)) -> Self {
        let w = 1.0 / variance;
        Self {
            runs: 1,
            w,
            w_x: w * x,
        }
    }

    /// These sums with `o`'s, times `sign` (−1 takes them out).
    fn plus(self, o: Self, sign: i8) -> Self {
        let s = f64::from(sign);
        Self {
            runs: self.runs + i64::from(sign) * o.runs,
            w: self.w + s * o.w,
            w_x: self.w_x + s * o.w_x,
        }
    }

    /// Their mean, None without an estimate.
    pub(crate) fn mean(self) -> Option<Mean> {
        (self.runs > 0 && self.w > 0.0).then(|| Mean {
            x: self.w_x / self.w,
            variance: 1.0 / self.w,
        })
    }
}

/// An inverse-variance mean and its variance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Mean {
    pub(crate) x: f64,
    pub(crate) variance: f64,
}

/// Which runs' estimates are pooled, which are named as disagreeing, and the pooled sums.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Verdict {
    /// Pooled, per run.
    pub(crate) pooled: Vec<bool>,
    /// Named as disagreeing, per run: those set aside, or both of two that disagree.
    pub(crate) named: Vec<bool>,
    /// The pooled runs' sums.
    pub(crate) all: Weighted,
}

impl Verdict {
    /// The mean of the pooled runs but run `i` (of `estimates`, as judged).
    pub(crate) fn others(&self, i: usize, estimates: &[(f64, f64)]) -> Option<Mean> {
        if self.pooled[i] {
            self.all.plus(Weighted::of(estimates[i]), -1)
        } else {
            self.all
        }
        .mean()
    }

    /// Whether a pooled run is named (two that disagree, neither set aside).
    pub(crate) fn pooled_disagree(&self) -> bool {
        self.pooled.iter().zip(&self.named).any(|(p, n)| *p && *n)
    }
}

/// Runs' estimates pooled with those that disagree set aside (see [`pooled_by_sigma`]).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SigmaPool {
    /// The verdict on the runs.
    pub(crate) verdict: Verdict,
    /// The pooled runs' inverse-variance mean.
    pub(crate) mean: f64,
    /// Its 1σ.
    pub(crate) sigma: f64,
    /// The pooled runs' χ² per degree of freedom about it (None with fewer than two).
    pub(crate) chi2: Option<f64>,
}

impl SigmaPool {
    /// Whether the pooled runs agree: no two named, χ² per degree of freedom within
    /// [`DISAGREE_CHI2_PER_DOF`].
    pub(crate) fn agree(&self) -> bool {
        !self.verdict.pooled_disagree() && self.chi2.is_none_or(|c| c <= DISAGREE_CHI2_PER_DOF)
    }

    /// The setting `value` (the pooled mean, or what it gives), rounded to `decimals` as
    /// a section writes it, when the pooled runs agree and a pooled run's `configured`
    /// value (one per run, in order) lies beyond [`crate::campaign_settings::CHANGE_SIGMA`]
    /// of the mean's σ from it.
    pub(crate) fn setting(
        &self,
        value: f64,
        decimals: usize,
        configured: impl Iterator<Item = f64>,
    ) -> Option<Pooled> {
        let pooled = &self.verdict.pooled;
        let runs = pooled.iter().filter(|p| **p).count();
        Pooled::rounded(value, self.sigma, runs, decimals)
            .if_a_change(configured.zip(pooled).filter(|(_, p)| **p).map(|(c, _)| c))
            .filter(|_| self.agree())
    }

    /// The sentence naming the runs set aside (`names`, the runs' in order), saying what
    /// of theirs (`what`: "lag") lay too far; None when none was.
    pub(crate) fn set_aside_sentence<'a>(
        &self,
        what: &str,
        names: impl Iterator<Item = &'a str>,
    ) -> Option<String> {
        let aside: Vec<&str> = names
            .zip(&self.verdict.pooled)
            .filter(|(_, p)| !**p)
            .map(|(n, _)| n)
            .collect();
        (!aside.is_empty()).then(|| {
            format!(
                "\nRuns whose {what} lies more than {DISAGREE_SIGMA}σ from the others', left \
                 out of the mean: {}.\n",
                aside.join(", ")
            )
        })
    }
}

/// Runs' estimates `(x, σ)`: the verdict on them and the pooled runs' mean.
pub(crate) fn pooled_by_sigma(estimates: &[(f64, f64)]) -> SigmaPool {
    let verdict = consistent(
        &estimates
            .iter()
            .map(|(x, s)| (*x, s * s))
            .collect::<Vec<_>>(),
    );
    let (mean, sigma, chi2) = weighted_mean(
        estimates
            .iter()
            .zip(&verdict.pooled)
            .filter(|(_, p)| **p)
            .map(|(e, _)| *e),
    );
    SigmaPool {
        verdict,
        mean,
        sigma,
        chi2,
    }
}

/// How many σ estimate `i` lies from the other pooled runs' mean.
fn sigmas_off(i: usize, estimates: &[(f64, f64)], verdict: &Verdict) -> Option<f64> {
    let (x, variance) = estimates[i];
    let others = verdict.others(i, estimates)?;
    Some((x - others.x).abs() / (variance + others.variance).sqrt())
}

/// The verdict on runs' `estimates` (each value and its variance).
pub(crate) fn consistent(estimates: &[(f64, f64)]) -> Verdict {
    let n = estimates.len();
    let sums = |pooled: &[bool]| {
        estimates
            .iter()
            .zip(pooled)
            .filter(|(_, p)| **p)
            .fold(Weighted::default(), |s, (e, _)| s.plus(Weighted::of(*e), 1))
    };
    let mut verdict = Verdict {
        pooled: vec![true; n],
        named: vec![false; n],
        all: sums(&vec![true; n]),
    };
    loop {
        let beyond: Vec<(usize, f64)> = (0..n)
            .filter(|&i| verdict.pooled[i])
            .filter_map(|i| Some((i, sigmas_off(i, estimates, &verdict)?)))
            .filter(|(_, z)| *z > DISAGREE_SIGMA)
            .collect();
        let Some(&(worst, _)) = beyond.iter().max_by(|a, b| a.1.total_cmp(&b.1)) else {
            break;
        };
        if verdict.pooled.iter().filter(|p| **p).count() < 3 {
            for (i, _) in beyond {
                verdict.named[i] = true;
            }
            break;
        }
        verdict.pooled[worst] = false;
        verdict.named[worst] = true;
        verdict.all = sums(&verdict.pooled);
    }
    verdict
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Four runs at 1.0 ± 0.1 and one at 2.0: the one set aside, the four pooled; two
    /// that disagree are both named and both pooled.
    #[test]
    fn a_run_far_from_the_others_is_set_aside() {
        let v = |x: f64| (x, 0.01);
        let five = [v(1.0), v(1.05), v(0.95), v(2.0), v(1.0)];
        let verdict = consistent(&five);
        assert_eq!(verdict.pooled, [true, true, true, false, true]);
        assert_eq!(verdict.named, [false, false, false, true, false]);
        let mean = verdict.all.mean().unwrap();
        assert!((mean.x - 1.0).abs() < 1e-12 && (mean.variance - 0.0025).abs() < 1e-12);
        // Run 3 against the pooled four.
        assert_eq!(verdict.others(3, &five), Some(mean));
        assert!(!verdict.pooled_disagree());
        let two = consistent(&[v(1.0), v(2.0)]);
        assert_eq!((two.pooled, two.named), (vec![true; 2], vec![true; 2]));
        let agree = consistent(&[v(1.0), v(1.2), v(0.9)]);
        assert_eq!(agree.named, [false; 3]);
    }
}
