//! The vehicle's odometer pitch boresight across a campaign's runs. The angle is the
//! vehicle's and its IMU's installation, not a run's: the runs whose control points'
//! heights fitted it are pooled (`campaign.md`) into the value to configure
//! (`[vehicle] odo_pitch_deg`), which then gives the heights of every run, those without
//! a point far enough along their route too.
//!
//! Each run's angle carries more than its points' height errors: whatever else grows in
//! proportion to distance is fitted with it, first the levelling error of its start (an
//! accelerometer's bias of `b` g tilts the levelled pitch by `b` rad). So each run's angle
//! is weighted by the inverse of its points' variance plus that of the levelling
//! ([`LEVELLING_SIGMA_RAD`]), and a run lying more than [`DISAGREE_SIGMA`] from the
//! others' is named and set aside.

use std::fmt::Write as _;

use unz_stages::disupt::{OdoPitchFit, OdoPitchRefusal};

use crate::campaign_outliers::{Mean, Verdict, consistent};
use crate::campaign_settings::Pooled;

/// Height error of a refused fit's point beyond which a run's note says so, m: dead
/// reckoning's own vertical error at the control points of a simulated 40-minute run is
/// 0.1–3 m; a datum or an angle left out is tens of metres (Kingston: 38 m after 2.4 km).
pub const HEIGHT_NOTE_M: f64 = 10.0;

pub use crate::campaign_outliers::DISAGREE_SIGMA;

/// The levelling error a run's angle carries beside its points', rad: a tactical
/// accelerometer's bias, 1 mg (the HG1700 of the Kingston log; an LN-200's is 0.3 mg),
/// is 1 mrad (0.057°) of pitch at the start. Simulated 40-minute runs of one vehicle at
/// 1.5° fit 1.488–1.507°.
pub const LEVELLING_SIGMA_RAD: f64 = 1e-3;

/// One run's fit, as the pool reads it.
#[derive(Debug, Clone, PartialEq)]
struct RunFit {
    name: String,
    /// The angle configured for the run, deg.
    configured_deg: f64,
    /// Whether its corrected navigation took it.
    taken: bool,
    /// tan of its own fitted angle: its points' least squares through its start.
    tan: f64,
    /// Its points: (slope m per tan β, height error with the configured angle, m).
    points: Vec<(f64, f64)>,
}

impl RunFit {
    /// The run's height errors at its points with tan β = `tan`, m.
    fn errors_at(&self, tan: f64) -> impl Iterator<Item = f64> + '_ {
        let tan_configured = self.configured_deg.to_radians().tan();
        self.points
            .iter()
            .map(move |(slope, dh)| dh + (tan - tan_configured) * slope)
    }

    /// RMS of its height errors with tan β = `tan`, m.
    fn rms_at(&self, tan: f64) -> f64 {
        let sum2: f64 = self.errors_at(tan).map(|e| e * e).sum();
        (sum2 / self.points.len() as f64).sqrt()
    }

    /// Σ slope² over its points, m².
    fn slope2(&self) -> f64 {
        self.points.iter().map(|(s, _)| s * s).sum()
    }

    /// The variance of its tan β: its points' (`point_sigma_m` each) and the levelling's.
    fn variance(&self, point_sigma_m: f64) -> f64 {
        point_sigma_m.powi(2) / self.slope2() + LEVELLING_SIGMA_RAD.powi(2)
    }
}

/// The runs' pitch boresight fits, gathered run by run.
#[derive(Debug, Default)]
pub struct PitchAcross {
    /// The runs whose fit was taken, and those whose points showed no change from a
    /// configured angle (their own angle is still their points' best).
    runs: Vec<RunFit>,
    /// Runs with a fit (taken or refused).
    fitted: usize,
}

/// The σ of the angle of a mean of tan β, degrees.
fn sigma_deg(mean: &Mean) -> f64 {
    (mean.variance.sqrt() / (1.0 + mean.x * mean.x)).to_degrees()
}

/// The runs' pool: each run's tan β and its variance, the verdict on them, their mean,
/// and the points' σ within a run they were weighed by, m.
struct Pool {
    point_sigma_m: f64,
    estimates: Vec<(f64, f64)>,
    verdict: Verdict,
    mean: Mean,
}

fn deg(tan: f64) -> f64 {
    tan.atan().to_degrees()
}

impl PitchAcross {
    /// Adds the run `name`'s fit (its `disupt.json`'s `odo_pitch`): pooled when taken, or
    /// when its points show no change from the configured angle. A fit refused beyond
    /// the limits (a datum) or without a point far enough is counted alone.
    pub fn add(&mut self, name: &str, fit: &OdoPitchFit) {
        self.fitted += 1;
        let no_change =
            fit.configured_deg != 0.0 && fit.refused_for == Some(OdoPitchRefusal::NotOneAngle);
        if !(fit.applied || no_change) {
            return;
        }
        // The fit's angle is its points' least squares through the start (their slopes
        // and their errors with the configured angle), taken or refused.
        let run = RunFit {
            name: name.to_owned(),
            configured_deg: fit.configured_deg,
            taken: fit.applied,
            tan: fit.odo_pitch_deg.to_radians().tan(),
            points: fit
                .points
                .iter()
                .map(|p| (p.slope_m, p.dh_before_m))
                .collect(),
        };
        if run.slope2() > 0.0 {
            self.runs.push(run);
        }
    }

    /// A point's height σ within a run, m: the RMS of the runs' points about each run's
    /// own angle (0 without a run of two points or more: the levelling's σ alone).
    fn point_sigma_m(&self) -> f64 {
        let (sum2, dof) = self.runs.iter().fold((0.0, 0), |(s, n), r| {
            (
                s + r.errors_at(r.tan).map(|e| e * e).sum::<f64>(),
                n + r.points.len() - 1,
            )
        });
        if dof > 0 {
            (sum2 / dof as f64).sqrt()
        } else {
            0.0
        }
    }

    /// Each run's tan β and its variance (its points', `point_sigma_m` each, and the
    /// levelling's).
    fn estimates(&self, point_sigma_m: f64) -> Vec<(f64, f64)> {
        self.runs
            .iter()
            .map(|r| (r.tan, r.variance(point_sigma_m)))
            .collect()
    }

    /// The pool the section shows, when a run's fit was taken and the mean stands out of
    /// its σ or an angle is configured.
    fn pool(&self) -> Option<Pool> {
        if !self.runs.iter().any(|r| r.taken) {
            return None;
        }
        let point_sigma_m = self.point_sigma_m();
        let estimates = self.estimates(point_sigma_m);
        let verdict = consistent(&estimates);
        let mean = verdict.all.mean()?;
        // Runs of a vehicle without an angle take their levelling's few hundredths of a
        // degree now and then: nothing to set unless the mean stands out of its σ (or an
        // angle is configured, which the section then checks).
        let configured = self.runs.iter().any(|r| r.configured_deg != 0.0);
        if !configured && mean.x.abs() <= DISAGREE_SIGMA * mean.variance.sqrt() {
            return None;
        }
        Some(Pool {
            point_sigma_m,
            estimates,
            verdict,
            mean,
        })
    }

    /// The angle to configure (`[vehicle] odo_pitch_deg`, as the section writes it), when
    /// the section is shown, no pooled run disagrees with the others and a pooled run's
    /// configured angle lies beyond its σ.
    pub fn setting(&self) -> Option<Pooled> {
        let pool = self.pool()?;
        let pooled = &pool.verdict.pooled;
        let in_pool = || self.runs.iter().zip(pooled).filter(|(_, p)| **p);
        Pooled::rounded(
            deg(pool.mean.x),
            sigma_deg(&pool.mean),
            in_pool().count(),
            3,
        )
        .if_a_change(in_pool().map(|(r, _)| r.configured_deg))
        .filter(|_| !pool.verdict.pooled_disagree())
    }

    /// `campaign.md`'s section, when a run's fit was taken and the mean stands out of its
    /// σ or an angle is configured.
    pub fn markdown(&self) -> Option<String> {
        let taken = self.runs.iter().filter(|r| r.taken).count();
        let Pool {
            point_sigma_m,
            estimates,
            verdict,
            mean,
        } = self.pool()?;
        let pooled = &verdict.pooled;
        let angle = deg(mean.x);
        let sigma_deg = sigma_deg(&mean);
        let in_pool: Vec<&RunFit> = self
            .runs
            .iter()
            .zip(pooled)
            .filter(|(_, p)| **p)
            .map(|(r, _)| r)
            .collect();
        let n_points: usize = in_pool.iter().map(|r| r.points.len()).sum();
        let sum2: f64 = in_pool
            .iter()
            .flat_map(|r| r.errors_at(mean.x))
            .map(|e| e * e)
            .sum();
        let mut md = format!(
            "\n## The vehicle's odometer pitch\n\n{taken} of the {} runs whose control \
             points' heights were fitted took an odometer pitch boresight (the path's climb \
             above the IMU's x){}. The {}, weighted by their points' heights (σ \
             {point_sigma_m:.2} m about each run's angle) and the levelling ({:.3}°): \
             **{angle:.3}° ± {sigma_deg:.3}°**; with it, their points' heights are \
             {:.2} m RMS off. If the runs share one vehicle and its installation, set \
             `[vehicle] odo_pitch_deg = {angle:.3}`: a run then climbs by it from its start, \
             and its points fit only what they show beyond it (a run without a point 200 m \
             along its route gets its heights from it alone).\n",
            self.fitted,
            match self.runs.len() - taken {
                0 => String::new(),
                n => format!(
                    ", and {n} showed no change from the configured angle (refused, with \
                     their own angle still their points' best)"
                ),
            },
            match in_pool.len() {
                1 => "angle of 1 run".to_owned(),
                n => format!("angles of {n} runs"),
            },
            LEVELLING_SIGMA_RAD.to_degrees(),
            (sum2 / n_points as f64).sqrt(),
        );
        let disagreeing: Vec<&str> = (0..self.runs.len())
            .filter(|&i| verdict.named[i])
            .map(|i| self.runs[i].name.as_str())
            .collect();
        if !disagreeing.is_empty() {
            let _ = writeln!(
                md,
                "\nRuns whose angle lies more than {DISAGREE_SIGMA}σ from the others'{}: {}: \
                 another vehicle or installation, or control points' heights in another \
                 datum?",
                if in_pool.len() < self.runs.len() {
                    ", left out of the mean"
                } else {
                    ""
                },
                disagreeing.join(", ")
            );
        }
        md += "\n| run | configured [°] | fitted [°] | taken | the others' [°] | Δh with the \
               others' (RMS) [m] | pooled |\n|---|---|---|---|---|---|---|\n";
        for (i, run) in self.runs.iter().enumerate() {
            let others = verdict.others(i, &estimates);
            let _ = writeln!(
                md,
                "| {} | {:.3} | {:.3} | {} | {} | {} | {} |",
                run.name,
                run.configured_deg,
                deg(run.tan),
                if run.taken { "yes" } else { "no" },
                others.map_or("–".to_owned(), |m| format!("{:.3}", deg(m.x))),
                others.map_or("–".to_owned(), |m| format!("{:.2}", run.rms_at(m.x))),
                if pooled[i] { "yes" } else { "no" },
            );
        }
        Some(md)
    }
}

/// A run's note on its heights, when its fit was refused and a point's height is left
/// more than [`HEIGHT_NOTE_M`] off.
pub fn heights_note(fit: &OdoPitchFit) -> Option<String> {
    let why = fit.refused.as_deref()?;
    let worst = fit
        .points
        .iter()
        .max_by(|a, b| a.dh_m.abs().total_cmp(&b.dh_m.abs()))?;
    (worst.dh_m.abs() > HEIGHT_NOTE_M).then(|| {
        format!(
            "heights {:+.1} m off at point {} after {:.0} m, not fitted: {why}",
            worst.dh_m, worst.id, worst.distance_m
        )
    })
}

#[cfg(test)]
mod tests {
    use unz_stages::disupt::{HeightError, fit_odo_pitch};

    use super::*;

    /// A run's fit to points at `distances_m` whose heights, with `configured_deg`, are
    /// off as an angle of `true_deg` leaves them, plus `noise_m` in turn.
    fn run(configured_deg: f64, true_deg: f64, distances_m: &[f64], noise_m: f64) -> OdoPitchFit {
        let tan = true_deg.to_radians().tan() - configured_deg.to_radians().tan();
        let errors: Vec<HeightError> = distances_m
            .iter()
            .zip(0u32..)
            .map(|(&d, id)| HeightError {
                id,
                t_s: f64::from(id),
                distance_m: d,
                dh_m: -tan * d + if id % 2 == 0 { noise_m } else { -noise_m },
                slope_m: d,
            })
            .collect();
        fit_odo_pitch(&errors, configured_deg).unwrap()
    }

    #[test]
    fn the_runs_points_are_fitted_together() {
        let mut p = PitchAcross::default();
        assert_eq!(p.markdown(), None);
        // Three runs of one vehicle at 1.5°, one of them configured with 1.4° already.
        p.add("a", &run(0.0, 1.5, &[3000.0, 6000.0], 0.5));
        p.add("b", &run(0.0, 1.5, &[2000.0, 8000.0], 0.5));
        p.add("c", &run(1.4, 1.5, &[4000.0, 5000.0], 0.5));
        // A run whose only point is near the start: counted, not pooled.
        p.add("d", &run(0.0, 1.5, &[100.0], 0.0));
        let sigma_m = p.point_sigma_m();
        // Two points a run, each 0.5 m off: about 0.66 m about each run's own angle.
        assert!((sigma_m - 0.66).abs() < 0.01, "{sigma_m}");
        let mean = consistent(&p.estimates(sigma_m)).all.mean().unwrap();
        assert!((deg(mean.x) - 1.5).abs() < 0.01, "{mean:?}");
        // Three runs, each with the levelling's 1 mrad and its points' σ: a little over
        // 1/√3 mrad.
        let sigma_rad = mean.variance.sqrt();
        assert!(sigma_rad > 0.577e-3 && sigma_rad < 0.59e-3, "{sigma_rad}");
        let md = p.markdown().unwrap();
        assert!(md.contains("3 of the 4 runs"), "{md}");
        assert!(md.contains("`[vehicle] odo_pitch_deg = 1.50"), "{md}");
        assert!(!md.contains("more than 3σ"), "{md}");
        assert!(md.contains("| c | 1.400 | 1.50"), "{md}");
        let s = p.setting().unwrap();
        assert!((s.value - 1.5).abs() < 0.01 && s.runs == 3, "{s:?}");
        assert_eq!(format!("{:.3}", s.value), after(&md, "odo_pitch_deg = "));
        // A configured run whose points show no change is pooled, not taken.
        let mut p2 = PitchAcross::default();
        p2.add("f", &run(1.5, 1.5, &[3000.0, 6000.0], 0.5));
        assert_eq!(p2.runs.len(), 1);
        assert_eq!(p2.markdown(), None);
        p2.add("g", &run(1.4, 1.5, &[3000.0, 6000.0], 0.5));
        let md2 = p2.markdown().unwrap();
        assert!(md2.contains("1 of the 2 runs"), "{md2}");
        assert!(
            md2.contains("and 1 showed no change from the configured angle"),
            "{md2}"
        );
        assert!(md2.contains("| f | 1.500 | 1.50"), "{md2}");
        // A vehicle without an angle: its runs' few hundredths of a degree are within their
        // mean's σ, and there is nothing to set.
        let mut level = PitchAcross::default();
        level.add("z1", &run(0.0, 0.03, &[3000.0, 6000.0], 0.0));
        level.add("z2", &run(0.0, -0.01, &[3000.0, 6000.0], 0.0));
        assert!(level.runs.len() == 2 && level.markdown().is_none());
        assert_eq!(level.setting(), None);
        // A run of another vehicle, at 3°, is named and left out.
        p.add("e", &run(0.0, 3.0, &[3000.0, 6000.0], 0.5));
        let md = p.markdown().unwrap();
        assert!(md.contains("The angles of 3 runs"), "{md}");
        assert!(md.contains("**1.50"), "{md}");
        assert!(md.contains("| e | 0.000 | 3.002 | yes | 1.502 |"), "{md}");
        assert!(md.contains("| no |"), "{md}");
        assert!(
            md.contains("more than 3σ from the others', left out of the mean: e: "),
            "{md}"
        );
        // The others agree: their angle is the setting.
        assert_eq!(p.setting().map(|s| s.runs), Some(3));
    }

    /// The word after `what` in `md`, up to a backtick.
    fn after<'a>(md: &'a str, what: &str) -> &'a str {
        md.split(what).nth(1).unwrap().split('`').next().unwrap()
    }

    /// Of two runs that disagree, neither can be told wrong: both are pooled and named.
    #[test]
    fn two_runs_that_disagree_are_both_named() {
        let mut p = PitchAcross::default();
        p.add("a", &run(0.0, 1.5, &[3000.0, 6000.0], 0.5));
        p.add("b", &run(0.0, 3.0, &[3000.0, 6000.0], 0.5));
        let md = p.markdown().unwrap();
        assert!(md.contains("**2.25"), "{md}");
        assert!(
            md.contains("from the others': a, b: another vehicle"),
            "{md}"
        );
        assert_eq!(p.setting(), None);
        // Within the levelling's σ of each other, they agree.
        let mut p = PitchAcross::default();
        p.add("a", &run(0.0, 1.5, &[3000.0, 6000.0], 0.5));
        p.add("b", &run(0.0, 1.6, &[3000.0, 6000.0], 0.5));
        assert!(!p.markdown().unwrap().contains("3σ"));
        assert_eq!(p.setting().map(|s| s.runs), Some(2));
    }

    #[test]
    fn a_refused_fit_far_off_in_height_is_noted() {
        // 35 m off in datum at both points: refused, and noted.
        let mut fit = run(0.0, 0.0, &[800.0, 2400.0], 0.0);
        for (q, dh) in fit.points.iter_mut().zip([15.6, -8.4]) {
            (q.dh_before_m, q.dh_m) = (dh, dh);
        }
        let errors: Vec<HeightError> = fit
            .points
            .iter()
            .map(|q| HeightError {
                id: q.id,
                t_s: q.t_s,
                distance_m: q.distance_m,
                dh_m: q.dh_m,
                slope_m: q.slope_m,
            })
            .collect();
        let fit = fit_odo_pitch(&errors, 0.0).unwrap();
        let note = heights_note(&fit).unwrap();
        assert!(
            note.starts_with("heights +15.6 m off at point 0 after 800 m"),
            "{note}"
        );
        // Refused, but within a few metres: no note; taken: no note.
        let near = run(0.0, 0.01, &[800.0, 2400.0], 1.0);
        assert!(!near.applied);
        assert_eq!(heights_note(&near), None);
        assert_eq!(heights_note(&run(0.0, 1.5, &[800.0, 2400.0], 0.0)), None);
    }
}
