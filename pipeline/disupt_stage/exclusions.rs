//! Control points inconsistent with the rest of the run, left out of the joint fit one at
//! a time (a point the route came back to, at every visit).

use rayon::prelude::*;
use unz_stages::disupt::{
    self, DisuptError, HOLDOUT_MIN_POINTS, Holdout, JointOptions, ProblemSpec, points_among,
    points_of, visits_of,
};

use super::joint_run::{JointInputs, JointRun, run_joint};

/// The joint fit without the control points it found inconsistent.
pub(super) struct Excluding {
    /// The fit without them.
    pub(super) run: JointRun,
    /// What the search found.
    pub(super) found: Exclusions,
}

/// What the search for control points to leave out found, beside the fit.
#[derive(Debug, Default)]
pub(super) struct Exclusions {
    /// The points left out: indices into the case's fixes, ascending.
    pub(super) excluded: Vec<usize>,
    /// The hold-out of the fit, when the search computed it: it stopped because no point
    /// the fit weighs was inconsistent, or because the refit without one failed.
    pub(super) holdout: Option<Vec<Holdout>>,
    /// Why an inconsistent point stayed in the fit: the fit without it failed.
    pub(super) refit_error: Option<String>,
    /// Why the fit with every point was refused, when leaving one out brought it within
    /// its bounds ([`without_the_point_out_of_bounds`]).
    pub(super) refused_with_all: Option<String>,
}

impl Excluding {
    /// `run`, with every point in it.
    pub(super) fn of(run: JointRun) -> Self {
        Self {
            run,
            found: Exclusions::default(),
        }
    }
}

/// Most of a run's `n` control points the joint fit may leave out: a third of them (more
/// disagreeing points say the log or the settings are wrong, not the survey), and so many
/// that [`HOLDOUT_MIN_POINTS`] stay to judge the rest. With three points the hold-out
/// names a point but cannot tell which is wrong (measured: a point 10 m off among three,
/// another called the more inconsistent); with four it can.
pub(super) fn most_excluded(n: usize) -> usize {
    (n / 3).min(n.saturating_sub(HOLDOUT_MIN_POINTS))
}

/// `out`'s fit (without its `excluded`) redone without the control points its hold-out finds
/// inconsistent, when `dparams.joint_exclude_inconsistent`: the most inconsistent point
/// (in σ of what the fit without it predicts) is left out and the whole joint fit redone
/// without it ([`run_joint`]: lag, boresight check), then the new fit's hold-out judged,
/// until no point it weighs is inconsistent or [`most_excluded`] are out. A point off
/// pulls the fits that keep it, so the others' hold-outs can fail beside it; judged again
/// without it, they pass.
pub(super) fn exclude_inconsistent(
    x: JointInputs<'_>,
    mut out: Excluding,
) -> Result<Excluding, DisuptError> {
    if !x.dparams.joint_exclude_inconsistent {
        return Ok(out);
    }
    let points = points_of(&x.case.fixes);
    while points_among(&x.case.fixes, &out.found.excluded) < most_excluded(points.len()) {
        let now = ProblemSpec {
            excluded_cps: &out.found.excluded,
            ..*x.spec
        };
        let fitted_on = now.on(out.run.derived.as_ref().unwrap_or(&x.case.derived));
        let h = disupt::holdout(&fitted_on, &out.run.fit, &out.run.params)?;
        let worst = h
            .iter()
            .enumerate()
            .filter(|(_, p)| p.inconsistent && !p.excluded)
            .max_by(|a, b| {
                let sigma = |p: &Holdout| p.error_sigma.unwrap_or(0.0);
                sigma(a.1).total_cmp(&sigma(b.1))
            })
            .map(|(i, _)| i);
        let Some(i) = worst else {
            out.found.holdout = Some(h);
            break;
        };
        // The point at every visit: its coordinates are what is off.
        let mut next = out.found.excluded.clone();
        next.extend(visits_of(&x.case.fixes, i));
        next.sort_unstable();
        // Without it the fit may leave its bounds, dragged by another point off (two
        // typed wrong): one more (or two) left out brings it back within them.
        let refit = match run_joint_without(x, &next) {
            Err(DisuptError::OutOfBounds(said)) => {
                let search = points_within_bounds(x, &next);
                match search.without {
                    Some(more) => run_joint_without(x, &more).map(|mut refit| {
                        add_passes(&mut refit, search.passes);
                        next = more;
                        refit
                    }),
                    None => Err(DisuptError::OutOfBounds(said)),
                }
            }
            other => other,
        };
        match refit {
            Ok(mut refit) => {
                // The method's passes: every fit's.
                add_passes(&mut refit, out.run.fit.result.evaluations);
                out.run = refit;
                out.found.excluded = next;
            }
            Err(e) => {
                out.found.refit_error = Some(format!(
                    "the joint fit without control point {} failed: {e}",
                    x.case.fixes[i].id
                ));
                out.found.holdout = Some(h);
                break;
            }
        }
    }
    Ok(out)
}

/// The whole joint fit ([`run_joint`]) redone with the control points `excluded`
/// (indices into the case's fixes) left out.
fn run_joint_without(x: JointInputs<'_>, excluded: &[usize]) -> Result<JointRun, DisuptError> {
    let without = ProblemSpec {
        excluded_cps: excluded,
        ..*x.spec
    };
    run_joint(JointInputs {
        problem: &x.problem.excluding(excluded),
        spec: &without,
        ..x
    })
}

/// The joint fit that `refused` for leaving its bounds, redone without the control points
/// whose absence brings it within them (when `x.dparams.joint_exclude_inconsistent` and
/// [`most_excluded`] allows: [`points_within_bounds`]): a point surveyed hundreds of
/// metres off (a digit typed wrong) drags the fit beyond them before any hold-out can
/// judge it. `refused` stands, with what was tried, when no point or pair explains it.
pub(super) fn without_the_point_out_of_bounds(
    x: JointInputs<'_>,
    refused: DisuptError,
) -> Result<Excluding, DisuptError> {
    if !x.dparams.joint_exclude_inconsistent {
        return Err(refused);
    }
    let search = points_within_bounds(x, &[]);
    let no_single = |e: DisuptError| match e {
        DisuptError::OutOfBounds(said) => DisuptError::OutOfBounds(format!(
            "{said}; without any {} as well",
            match search.largest {
                0 => return DisuptError::OutOfBounds(said),
                1 => "one control point",
                _ => "one or two control points",
            }
        )),
        other => other,
    };
    let Some(excluded) = search.without.clone() else {
        return Err(no_single(refused));
    };
    match run_joint_without(x, &excluded) {
        Ok(mut run) => {
            // The method's passes: the search's too.
            add_passes(&mut run, search.passes);
            Ok(Excluding {
                run,
                found: Exclusions {
                    excluded,
                    refused_with_all: Some(refused.to_string()),
                    ..Exclusions::default()
                },
            })
        }
        Err(_) => Err(no_single(refused)),
    }
}

/// Most pairs of control points [`points_within_bounds`] tries, a fit each (thirteen
/// points): beyond, it tries single points only.
const MAX_PAIRS: usize = 78;

/// What [`points_within_bounds`] found.
struct BoundsSearch {
    /// The fixes to leave out (the base's and the points found, every visit; ascending),
    /// when some brought the fit within its bounds.
    without: Option<Vec<usize>>,
    /// The most points tried together beside the base (0: none could be).
    largest: usize,
    /// The passes of every fit tried.
    passes: usize,
}

/// The fewest control points (one, else two) whose leaving out beside the fixes `base`
/// brings the joint fit, at the configured odometer timing, within its bounds, within
/// [`most_excluded`]. Each point (every visit), then each pair of points (at most
/// [`MAX_PAIRS`]), is left out of a fit, side by side; of the fits within their bounds
/// with as few points out, the one whose control points fit best (least cost per point
/// weighed) names them.
fn points_within_bounds(x: JointInputs<'_>, base: &[usize]) -> BoundsSearch {
    let fixes = &x.case.fixes;
    let points = points_of(fixes);
    let room = most_excluded(points.len()).saturating_sub(points_among(fixes, base));
    let others: Vec<usize> = points.into_iter().filter(|i| !base.contains(i)).collect();
    let start = x.problem.x0();
    let mut search = BoundsSearch {
        without: None,
        largest: 0,
        passes: 0,
    };
    for k in 1..=room.min(2) {
        let sets: Vec<Vec<usize>> = match k {
            1 => others.iter().map(|&i| vec![i]).collect(),
            _ if others.len() * (others.len() - 1) / 2 <= MAX_PAIRS => others
                .iter()
                .enumerate()
                .flat_map(|(a, &i)| others[a + 1..].iter().map(move |&j| vec![i, j]))
                .collect(),
            _ => break,
        };
        // (fixes left out, the fit's control-point cost per residual when within its
        // bounds, its passes)
        let tried: Vec<(Vec<usize>, Option<f64>, usize)> = sets
            .into_par_iter()
            .map(|set| {
                let mut without = base.to_vec();
                for i in set {
                    without.extend(visits_of(fixes, i));
                }
                without.sort_unstable();
                let p = x.problem.excluding(&without);
                let weighed = 2.0 * (fixes.len() - without.len()) as f64;
                let (cost, passes) =
                    match disupt::joint_fit(&p, x.dparams, &JointOptions::default()) {
                        Ok(fit) => {
                            let within = disupt::within_bounds(&fit, &start, x.dparams).is_ok();
                            let cost = within.then_some(fit.cp_cost / weighed.max(1.0));
                            (cost, fit.result.evaluations)
                        }
                        Err(_) => (None, p.passes()),
                    };
                (without, cost, passes)
            })
            .collect();
        search.largest = k;
        search.passes += tried.iter().map(|t| t.2).sum::<usize>();
        search.without = tried
            .into_iter()
            .filter_map(|(without, cost, _)| Some((without, cost?)))
            .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
            .map(|(without, _)| without);
        if search.without.is_some() {
            break;
        }
    }
    search
}

/// Counts `passes` of fits before it in `run`'s (and its one step's).
fn add_passes(run: &mut JointRun, passes: usize) {
    let r = &mut run.fit.result;
    r.evaluations += passes;
    if let Some(step) = r.steps.first_mut() {
        step.evaluations = r.evaluations;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_third_of_the_points_at_most_and_three_stay() {
        let most: Vec<usize> = (0..=12).map(most_excluded).collect();
        assert_eq!(most, [0, 0, 0, 0, 1, 1, 2, 2, 2, 3, 3, 3, 4]);
    }
}
