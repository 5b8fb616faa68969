//! Hold-out errors: each control point's error when the joint fit leaves it out.

use std::sync::atomic::AtomicUsize;

use nalgebra::{DMatrix, Matrix2, Vector2};
use serde::{Deserialize, Serialize};

use super::DisuptError;
use super::gyro_walk::{WalkFit, walk_covariance_of};
use super::joint::{
    JointFit, JointModel, JointOptions, attitude_rows, covariance_of, cp_weights, joint_fit,
};
use super::problem::Problem;
use super::settings::{DisuptParams, X, x_of};
use crate::criteria::ControlPointFix;
use crate::linearized::Setting;

/// How many σ of its predicted spread a control point's hold-out error may reach before
/// the point is called inconsistent with the rest of the run: √χ²₂(0.999), so that a run
/// whose points all agree has one such call in a thousand per point.
pub const HOLDOUT_INCONSISTENT_SIGMA: f64 = 3.717;

/// Fewest control points for that call. With two, each hold-out fit keeps one point,
/// which leaves the vertical drift to the attitude residuals alone when there is no
/// static start: on 14 simulated logs begun while driving, correct points' hold-out
/// errors reached 4.6σ of that fit's linearised spread. With three or more the fits keep
/// two (36 clean simulated runs: none above 2.1σ).
pub const HOLDOUT_MIN_POINTS: usize = 3;

/// With two control points (fewer than [`HOLDOUT_MIN_POINTS`], so neither is called
/// inconsistent) and a static start, the hold-out errors, in σ, beyond which both
/// together are said to disagree with the log ([`Holdout::apart`]): correct points
/// reached 5.3σ on 50 simulated runs with a static start (100 hold-outs). Without one
/// they reached 12.9σ on 14 logs begun while driving, so no call is made there. On
/// Kingston (1.1σ and 1.1σ as surveyed) the site 50 m off gave 41σ and 32σ, 20 m off
/// 12.5σ and 12.4σ, the first point timed 25 s early 31σ and 26σ.
pub const HOLDOUT_TWO_POINTS_SIGMA: f64 = 10.0;

/// Hold-out refits whose exact passes run, and whose observations are held, at once
/// (whole batches of lanes). A run with more points holds this many observations, not one
/// per point: with 5 050 points a 10-minute run's disupt process peaked at 2.0 GB when
/// all were held at once, at 67 MB a chunk at a time.
const HOLDOUT_PASSES_AT_ONCE: usize = 16 * super::problem::LANES;

/// The error at a control point when it was left out of the joint fit, and how it
/// compares with what the fit without it predicts there.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Holdout {
    /// Control-point id.
    pub id: u32,
    /// Time of the stop, s in the log's time base: which visit, of a point the route
    /// came back to.
    #[serde(default)]
    pub t_s: f64,
    /// ΔX north there, navigated minus known, m.
    pub dx_m: f64,
    /// ΔY east there, m.
    pub dy_m: f64,
    /// Predicted 1σ of ΔX, m: the fit without the point, its covariance carried to the
    /// point's position by the point's sensitivities, the point's own σ
    /// (`position_sigma_m`) and the gyros' angle random walk's turn of the route to it
    /// (net of what the fit's settings take of it). Absent when that fit has no
    /// covariance.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_north_m: Option<f64>,
    /// Predicted 1σ of ΔY, m (as `sigma_north_m`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_east_m: Option<f64>,
    /// The error in units of its predicted spread: √(dᵀS⁻¹d), d = (ΔX, ΔY), S the
    /// predicted 2 × 2 covariance (north–east correlation included). Absent with the σ.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error_sigma: Option<f64>,
    /// `error_sigma` above [`HOLDOUT_INCONSISTENT_SIGMA`], in a run of at least
    /// [`HOLDOUT_MIN_POINTS`] control points: the point disagrees with the rest of the
    /// run (its coordinates, its mark or the stop are suspect).
    pub inconsistent: bool,
    /// The joint fit left the point out ([`Problem::excluded_cps`]): the error is the
    /// fit's own there, its spread what the fit predicts.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub excluded: bool,
    /// One of exactly two control points, in a run with a static start, whose hold-out
    /// errors are both beyond `HOLDOUT_TWO_POINTS_SIGMA`: the two disagree with the
    /// log (a point's coordinates, time or mark, or the site, are off), and the fit
    /// cannot tell which.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub apart: bool,
}

impl Holdout {
    fn new(fix: &ControlPointFix, d: [f64; 2], s: Option<Matrix2<f64>>, points: usize) -> Self {
        Self::of(fix.id, fix.t_s, d, s, points)
    }

    fn of(id: u32, t_s: f64, d: [f64; 2], s: Option<Matrix2<f64>>, points: usize) -> Self {
        let error_sigma = s.and_then(|s| {
            let d = Vector2::new(d[0], d[1]);
            let t = d.dot(&(s.try_inverse()? * d));
            t.is_finite().then(|| t.max(0.0).sqrt())
        });
        let sd = |k: usize| error_sigma.and(s).map(|s| s[(k, k)].max(0.0).sqrt());
        Self {
            id,
            t_s,
            dx_m: d[0],
            dy_m: d[1],
            sigma_north_m: sd(0),
            sigma_east_m: sd(1),
            error_sigma,
            inconsistent: points >= HOLDOUT_MIN_POINTS
                && error_sigma.is_some_and(|e| e > HOLDOUT_INCONSISTENT_SIGMA),
            excluded: false,
            apart: false,
        }
    }

    /// The point's id, and the visit's time when `all` (the run's hold-outs) has the
    /// point more than once: a point the route came back to.
    pub fn label(&self, all: &[Holdout]) -> String {
        if all.iter().filter(|q| q.id == self.id).count() > 1 {
            format!("{} at t_s = {:.1}", self.id, self.t_s)
        } else {
            self.id.to_string()
        }
    }
}

/// Median and largest horizontal error of hold-out results, m, over the points the fit
/// weighs (those it left out measure their survey, not the route); `None` without any.
pub fn holdout_median_max_m(h: &[Holdout]) -> Option<(f64, f64)> {
    let mut e: Vec<f64> = h
        .iter()
        .filter(|p| !p.excluded)
        .map(|p| p.dx_m.hypot(p.dy_m))
        .collect();
    median_max(&mut e)
}

/// Median and largest of `v` (sorted in place); `None` when it is empty.
pub fn median_max(v: &mut [f64]) -> Option<(f64, f64)> {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let median = match n {
        0 => return None,
        _ if n % 2 == 1 => v[n / 2],
        _ => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    };
    Some((median, v[n - 1]))
}

/// What a user is told of the control points the joint fit left out, and of those whose
/// hold-out error is inconsistent with its predicted spread but stayed in (`None` when
/// there are none): each one's error and how many σ it is, the largest first. An error
/// at one point pulls the fits that keep it, so the others' hold-outs can fail beside
/// it; the largest is the likeliest culprit.
pub fn inconsistent_points_note(h: &[Holdout]) -> Option<String> {
    let label = |p: &Holdout| p.label(h);
    let listed = |keep: &dyn Fn(&Holdout) -> bool| {
        let mut bad: Vec<&Holdout> = h.iter().filter(|p| keep(p)).collect();
        bad.sort_by(|a, b| {
            b.error_sigma
                .unwrap_or(0.0)
                .total_cmp(&a.error_sigma.unwrap_or(0.0))
        });
        let each: Vec<String> = bad
            .iter()
            .map(|p| {
                format!(
                    "{} ({:.1} m, {:.1}σ)",
                    label(p),
                    p.dx_m.hypot(p.dy_m),
                    p.error_sigma.unwrap_or(f64::NAN)
                )
            })
            .collect();
        let plural = if bad.len() > 1 { "s" } else { "" };
        (!bad.is_empty()).then(|| (plural, each.join(", ")))
    };
    let excluded = listed(&|p| p.excluded).map(|(s, each)| {
        format!(
            "control point{s} left out of the joint fit, inconsistent with the rest of the run \
             (error, and in σ of what the fit without it predicts): {each}; check the \
             coordinates and the mark"
        )
    });
    let kept = listed(&|p| p.inconsistent && !p.excluded).map(|(s, each)| {
        format!(
            "control point{s} inconsistent with the rest of the run (hold-out error, and in σ \
             of what the fit without it predicts): {each}; check the coordinates and the \
             mark, the largest first"
        )
    });
    let two_apart = listed(&|p| p.apart).map(|(_, each)| {
        format!(
            "the two control points disagree with the log beyond what the settings explain \
             (hold-out error, and in σ of what the fit without it predicts): {each}; with \
             two points the fit cannot tell which is off: check their coordinates, times \
             and marks, and the site (the run's start)"
        )
    });
    let notes: Vec<String> = excluded.into_iter().chain(kept).chain(two_apart).collect();
    (!notes.is_empty()).then(|| notes.join("; "))
}

/// Hold-out errors: for every control point, the joint fit without it (same weights),
/// and the error there of an exact pass with those settings. A point the route came back
/// to is held out at every visit (its coordinates are shared), and each visit has its
/// error. Each refit solves the fit's linearisation without the point's rows (no pass);
/// the exact passes run side by side, and a refit whose exact pass disagrees with the
/// model is redone in full. A point the fit already leaves out
/// ([`Problem::excluded_cps`]) has the fit's own error there (no refit, no pass). The
/// consistency call counts the distinct points the fit weighs.
pub fn holdout(
    problem: &Problem<'_>,
    fit: &JointFit,
    p: &DisuptParams,
) -> Result<Vec<Holdout>, DisuptError> {
    let n = problem.points_used();
    let n_att = attitude_rows(problem);
    let s2 = fit.cost / fit.dof;
    let fixes = problem.fixes;
    let mut refits = Vec::with_capacity(fixes.len());
    let mut out: Vec<Option<Holdout>> = vec![None; fixes.len()];
    let mut visits_of: std::collections::BTreeMap<u32, Vec<usize>> = Default::default();
    for (i, f) in fixes.iter().enumerate() {
        visits_of.entry(f.id).or_default().push(i);
    }
    for i in 0..fixes.len() {
        if !problem.cp_used(i) {
            // The fit leaves the point out: its own model predicts the error there (its
            // covariance from the residuals' scatter, the gyros' walk apart).
            let model = JointModel::new(problem, &fit.lin, &fit.free, &fit.weights, None);
            let c = covariance_of(&model, n_att, fit.inflation, s2);
            let spread = predicted_spread(problem, fit, c.as_ref(), &fit.free, i, None, p)
                .map(|s| s + walk_spread(problem, fit, &model, &fit.free, i, None));
            out[i] = Some(Holdout {
                excluded: true,
                ..Holdout::new(&fixes[i], fit.y.cp_m[i], spread, n)
            });
            continue;
        }
        // A point's later visits are held out with its first.
        let Some(visits) = visits_of.remove(&fixes[i].id) else {
            continue;
        };
        // Without the only control point, nothing sees the odometer's settings.
        let free: Vec<Setting> = fit
            .free
            .iter()
            .copied()
            .filter(|s| n > 1 || !s.needs_control_points())
            .collect();
        let model = JointModel::new(problem, &fit.lin, &free, &fit.weights, Some(i));
        let delta = model.solve()?;
        let mut pi = fit.lin.p_ref;
        for (k, s) in free.iter().enumerate() {
            pi[s.index()] += delta[k];
        }
        let c = covariance_of(&model, n_att, fit.inflation, s2);
        let spreads: Vec<_> = visits
            .iter()
            .map(|&j| {
                predicted_spread(problem, fit, c.as_ref(), &free, j, Some(i), p)
                    .map(|s| s + walk_spread(problem, fit, &model, &free, j, Some(i)))
            })
            .collect();
        refits.push((visits, pi, spreads));
    }
    // The refits' exact passes, a chunk at a time: each pass's observation holds the
    // run's epochs and every point, so all at once would hold points × (epochs + points).
    let tally = AtomicUsize::new(0);
    let mut refits = refits.into_iter().peekable();
    while refits.peek().is_some() {
        let chunk: Vec<_> = refits.by_ref().take(HOLDOUT_PASSES_AT_ONCE).collect();
        let xs: Vec<X> = chunk.iter().map(|(_, pi, _)| x_of(pi)).collect();
        let ys = problem.observe_many_by(&xs, &tally);
        for ((visits, pi, spreads), y) in chunk.into_iter().zip(ys) {
            let y = if fit.lin.predict(&pi).agrees_with(&y) {
                y
            } else {
                let opts = JointOptions {
                    attitude_sigma_rad: Some(fit.attitude_sigma_rad),
                    skip_cp: Some(visits[0]),
                    warm: Some(&fit.lin),
                };
                joint_fit(problem, p, &opts)?.y
            };
            for (j, spread) in visits.into_iter().zip(spreads) {
                out[j] = Some(Holdout::new(&fixes[j], y.cp_m[j], spread, n));
            }
        }
    }
    let mut out: Vec<Holdout> = out.into_iter().flatten().collect();
    mark_two_apart(&mut out, problem.drift_z_prior_deg_h.is_some());
    Ok(out)
}

/// Marks [`Holdout::apart`] on the hold-outs `h` of a run with two control points, when
/// it has a `static_start` and every visit's error is beyond
/// [`HOLDOUT_TWO_POINTS_SIGMA`].
fn mark_two_apart(h: &mut [Holdout], static_start: bool) {
    let weighed = || h.iter().filter(|p| !p.excluded);
    let ids: std::collections::BTreeSet<u32> = weighed().map(|p| p.id).collect();
    let far = |p: &Holdout| p.error_sigma.is_some_and(|e| e > HOLDOUT_TWO_POINTS_SIGMA);
    if static_start && ids.len() == 2 && weighed().all(far) {
        for p in h.iter_mut().filter(|p| !p.excluded) {
            p.apart = true;
        }
    }
}

/// The gyros' angle random walk's share of the covariance (north, east; m²) of control
/// point visit `j`'s error after a fit of `model` (whose rows for the point are weighed
/// out): the walk turns the route to the point itself, and the fit's settings, which
/// absorb part of the same walk through the other points and the epochs, carry part of
/// that turn there too. The error is `e = r_j − J_j δ` with `δ = G r` the fit's step
/// (`G = (AᵀA)⁻¹Aᵀ`) and `r_j` the point's own rows (in metres), so `F = E_j − J_j G`
/// and the share `F Σ Fᵀ` ([`super::gyro_walk`]); zero without a walk or an inverse.
fn walk_spread(
    problem: &Problem<'_>,
    fit: &JointFit,
    model: &JointModel,
    free: &[Setting],
    j: usize,
    skip: Option<usize>,
) -> Matrix2<f64> {
    let Some(walk) = problem.gyro_walk else {
        return Matrix2::zeros();
    };
    let a = &model.a;
    let n_att = attitude_rows(problem);
    let row = n_att + 2 * j;
    let Some(normal_inv) = a.tr_mul(a).try_inverse() else {
        return Matrix2::zeros();
    };
    if row + 1 >= a.nrows() {
        return Matrix2::zeros();
    }
    let mut jac = DMatrix::zeros(2, free.len());
    for (k, s) in free.iter().enumerate() {
        if let Some(slope) = &fit.lin.slopes[s.index()] {
            jac[(0, k)] = slope.cp_m[j][0];
            jac[(1, k)] = slope.cp_m[j][1];
        }
    }
    // F = E_j − (J_j (AᵀA)⁻¹) Aᵀ = E_j − (A (J_j (AᵀA)⁻¹)ᵀ)ᵀ, without forming G or Aᵀ.
    let mut f = -(a * (jac * normal_inv).transpose()).transpose();
    f[(0, row)] += 1.0;
    f[(1, row + 1)] += 1.0;
    // The point's rows as the walk moves them: in metres (weight 1).
    let mut weights = cp_weights(problem, skip, &fit.weights);
    weights[j] = 1.0;
    let walk_fit = WalkFit {
        lin: &fit.lin,
        attitude_sigma_rad: fit.weights.attitude_sigma_rad,
        cp_weights: &weights,
        azimuth_deg: fit.result.x.azimuth_deg,
    };
    let c = walk_covariance_of(walk, problem, &walk_fit, &f);
    Matrix2::new(c[(0, 0)], c[(0, 1)], c[(1, 0)], c[(1, 1)])
}

/// The predicted covariance (north, east; m²) of control point `i`'s hold-out error:
/// `J C Jᵀ + σ² I`, with `C` the covariance of the `free` settings of the fit without the
/// point (its rows weighed out; the full fit's variance factor and attitude inflation),
/// `J` the point's position per free setting (the fit's linearisation) and `σ` the
/// control points' own (`position_sigma_m`), plus what the turns of lost samples' fills
/// before it leave (the fit's points but those `skip` holds out weighed). `None` without
/// `C` (singular).
fn predicted_spread(
    problem: &Problem<'_>,
    fit: &JointFit,
    c: Option<&DMatrix<f64>>,
    free: &[Setting],
    i: usize,
    skip: Option<usize>,
    p: &DisuptParams,
) -> Option<Matrix2<f64>> {
    let c = c?;
    let mut j = DMatrix::zeros(2, free.len());
    for (k, s) in free.iter().enumerate() {
        if let Some(slope) = &fit.lin.slopes[s.index()] {
            j[(0, k)] = slope.cp_m[i][0];
            j[(1, k)] = slope.cp_m[i][1];
        }
    }
    let jcj = &j * c * j.transpose();
    let var_m2 = p.position_sigma_m * p.position_sigma_m;
    // The turns lost samples' fills may have made before the point, as the points the
    // fit weighed leave them ([`super::gap_turns`]).
    let turns = (problem.gap_tilts.as_ref())
        .and_then(|g| g.turn_spread_at(i, &cp_weights(problem, skip, &fit.weights)))
        .unwrap_or_else(Matrix2::zeros);
    Some(Matrix2::new(
        jcj[(0, 0)] + var_m2 + turns[(0, 0)],
        jcj[(0, 1)] + turns[(0, 1)],
        jcj[(1, 0)] + turns[(1, 0)],
        jcj[(1, 1)] + var_m2 + turns[(1, 1)],
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_error_is_measured_in_its_predicted_spread() {
        // σ north 2 m, σ east 1 m, uncorrelated: (2, 1) m is √2 σ.
        let s = Matrix2::new(4.0, 0.0, 0.0, 1.0);
        let h = Holdout::of(7, 0.0, [2.0, 1.0], Some(s), 3);
        assert!((h.error_sigma.unwrap() - 2f64.sqrt()).abs() < 1e-12);
        assert_eq!((h.sigma_north_m, h.sigma_east_m), (Some(2.0), Some(1.0)));
        assert!(!h.inconsistent);
        // Correlated: along the correlation the error counts less than across it.
        let c = Matrix2::new(1.0, 0.9, 0.9, 1.0);
        let along = Holdout::of(1, 0.0, [1.0, 1.0], Some(c), 3)
            .error_sigma
            .unwrap();
        let across = Holdout::of(1, 0.0, [1.0, -1.0], Some(c), 3)
            .error_sigma
            .unwrap();
        assert!((along - (2.0 / 1.9f64).sqrt()).abs() < 1e-12);
        assert!((across - (2.0 / 0.1f64).sqrt()).abs() < 1e-9);
        assert!(Holdout::of(1, 0.0, [1.0, -1.0], Some(c), 3).inconsistent);
    }

    #[test]
    fn two_points_or_no_spread_are_never_called_inconsistent() {
        let s = Matrix2::new(1.0, 0.0, 0.0, 1.0);
        let far = Holdout::of(1, 0.0, [100.0, 0.0], Some(s), 2);
        assert!((far.error_sigma.unwrap() - 100.0).abs() < 1e-12 && !far.inconsistent);
        let singular = Holdout::of(1, 0.0, [100.0, 0.0], Some(Matrix2::zeros()), 5);
        assert_eq!(
            (
                singular.error_sigma,
                singular.sigma_north_m,
                singular.inconsistent
            ),
            (None, None, false)
        );
        let none = Holdout::of(1, 0.0, [100.0, 0.0], None, 5);
        assert_eq!((none.error_sigma, none.inconsistent), (None, false));
    }

    #[test]
    fn points_left_out_are_named_apart_and_not_in_the_median() {
        let s = Matrix2::new(1.0, 0.0, 0.0, 1.0);
        let left_out = Holdout {
            excluded: true,
            ..Holdout::of(6, 0.0, [9.0, 0.0], Some(s), 4)
        };
        let h = [
            Holdout::of(1, 0.0, [0.5, 0.0], Some(s), 4),
            left_out,
            Holdout::of(2, 0.0, [0.0, 4.0], Some(s), 4),
        ];
        assert_eq!(holdout_median_max_m(&h), Some((2.25, 4.0)));
        assert_eq!(holdout_median_max_m(&h[1..2]), None);
        assert_eq!(
            inconsistent_points_note(&h).unwrap(),
            "control point left out of the joint fit, inconsistent with the rest of the run \
             (error, and in σ of what the fit without it predicts): 6 (9.0 m, 9.0σ); check the \
             coordinates and the mark; control point inconsistent with the rest of the run \
             (hold-out error, and in σ of what the fit without it predicts): 2 (4.0 m, 4.0σ); \
             check the coordinates and the mark, the largest first"
        );
    }

    #[test]
    fn the_note_names_the_inconsistent_points_largest_first() {
        let s = Matrix2::new(1.0, 0.0, 0.0, 1.0);
        let h = [
            Holdout::of(1, 0.0, [0.5, 0.0], Some(s), 3),
            Holdout::of(2, 0.0, [4.0, 3.0], Some(s), 3),
            Holdout::of(3, 0.0, [0.0, 9.0], Some(s), 3),
        ];
        assert_eq!(inconsistent_points_note(&h[..1]), None);
        let note = inconsistent_points_note(&h).unwrap();
        assert!(
            note.starts_with("control points inconsistent")
                && note.contains(": 3 (9.0 m, 9.0σ), 2 (5.0 m, 5.0σ);"),
            "{note}"
        );
    }

    #[test]
    fn two_points_far_beyond_their_spread_are_said_to_disagree_together() {
        let s = Matrix2::new(1.0, 0.0, 0.0, 1.0);
        let marked = |h: &[Holdout], static_start: bool| {
            let mut h = h.to_vec();
            mark_two_apart(&mut h, static_start);
            h
        };
        let two = [
            Holdout::of(1, 0.0, [30.0, 0.0], Some(s), 2),
            Holdout::of(2, 0.0, [0.0, 40.0], Some(s), 2),
        ];
        let h = marked(&two, true);
        assert!(h.iter().all(|p| p.apart && !p.inconsistent));
        let note = inconsistent_points_note(&h).unwrap();
        assert!(
            note.starts_with("the two control points disagree with the log")
                && note.contains(": 2 (40.0 m, 40.0σ), 1 (30.0 m, 30.0σ); with two points")
                && note.ends_with("and the site (the run's start)"),
            "{note}"
        );
        // Without a static start (correct points reached 12.9σ), or with one of them
        // within 10σ, or none beyond: nothing said.
        assert_eq!(inconsistent_points_note(&marked(&two, false)), None);
        for near in [[9.0, 0.0], [1.0, 1.0]] {
            let h = marked(&[two[0], Holdout::of(2, 0.0, near, Some(s), 2)], true);
            assert!(h.iter().all(|p| !p.apart));
            assert_eq!(inconsistent_points_note(&h), None);
        }
        // A point the route came back to, visited twice, and one more: two points.
        let visits = marked(
            &[two[0], two[1], Holdout::of(1, 9.0, [0.0, 25.0], Some(s), 2)],
            true,
        );
        assert!(
            inconsistent_points_note(&visits)
                .unwrap()
                .contains("1 at t_s = 9.0")
        );
        // Three points: the per-point call ([`HOLDOUT_MIN_POINTS`]) says it.
        let three = marked(
            &[two[0], two[1], Holdout::of(3, 0.0, [0.0, 25.0], Some(s), 3)],
            true,
        );
        assert!(three.iter().all(|p| !p.apart));
        // A point the fit left out does not count as one of two.
        let left_out = Holdout {
            excluded: true,
            ..Holdout::of(3, 0.0, [0.0, 25.0], Some(s), 3)
        };
        assert!(
            marked(&[two[0], two[1], left_out], true)[..2]
                .iter()
                .all(|p| p.apart)
        );
    }

    #[test]
    fn a_point_visited_twice_is_named_with_each_visits_time() {
        let s = Matrix2::new(1.0, 0.0, 0.0, 1.0);
        let h = [
            Holdout::of(1, 700.3, [0.0, 5.0], Some(s), 3),
            Holdout::of(2, 900.0, [0.5, 0.0], Some(s), 3),
            Holdout::of(1, 1600.0, [0.0, 4.5], Some(s), 3),
        ];
        let labels: Vec<String> = h.iter().map(|p| p.label(&h)).collect();
        assert_eq!(labels, ["1 at t_s = 700.3", "2", "1 at t_s = 1600.0"]);
        let note = inconsistent_points_note(&h).unwrap();
        assert!(
            note.contains(": 1 at t_s = 700.3 (5.0 m, 5.0σ), 1 at t_s = 1600.0 (4.5 m, 4.5σ);"),
            "{note}"
        );
    }
}
