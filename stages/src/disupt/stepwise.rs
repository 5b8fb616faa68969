//! OEPI and OWPI (the paper's Tables 1 and 2): one component at a time, each by a
//! bounded search on a linearisation confirmed by an exact pass.

use std::borrow::Cow;
use std::cell::RefCell;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use argmin::core::{CostFunction, Error as ArgminError, Executor, State};
use argmin::solver::brent::BrentOpt;
use argmin::solver::neldermead::NelderMead;

use super::DisuptError;
use super::problem::{Problem, linearization_of, moved_by_steps};
use super::results::{Component, Criterion, MethodResult, Step, last_cp};
use super::settings::{DisuptParams, X, params_of, x_of};
use crate::linearized::{Linearization, N_PARAMS, Observation, Setting};

/// Relinearisations of one search before it falls back to exact passes.
const MAX_RELINEARISATIONS: usize = 6;

/// A criterion over the free parameters of `p`, evaluated exactly (a pass each) or on a
/// linearisation (no pass).
struct Objective<'p, 'a> {
    problem: &'p Problem<'a>,
    lin: Option<&'p Linearization>,
    p: [f64; N_PARAMS],
    free: &'static [Setting],
    criterion: Criterion,
    /// The methods' bounds, when the free settings are held within them around `p` (a
    /// value beyond is taken at the bound).
    within: Option<&'p DisuptParams>,
    buf: RefCell<Observation>,
    tally: &'p AtomicUsize,
}

impl Objective<'_, '_> {
    /// The parameters at `values` of the free settings (held within the bounds when
    /// asked).
    fn params_at(&self, values: &[f64]) -> [f64; N_PARAMS] {
        let mut p = self.p;
        for (s, &v) in self.free.iter().zip(values) {
            let i = s.index();
            p[i] = match self.within {
                Some(bounds) => v.clamp(self.p[i] - bounds.bound(*s), self.p[i] + bounds.bound(*s)),
                None => v,
            };
        }
        p
    }

    fn at(&self, values: &[f64]) -> f64 {
        let p = self.params_at(values);
        let value = |y: &Observation| match self.criterion {
            Criterion::Kryt1 => self.problem.kryt1(y),
            Criterion::Kryt2 | Criterion::LeastSquares => y.kryt2_rms(),
        };
        match self.lin {
            Some(lin) => {
                let mut y = self.buf.borrow_mut();
                lin.predict_into(&p, &mut y);
                value(&y)
            }
            None => value(&self.problem.observe_by(&x_of(&p), self.tally)),
        }
    }
}

/// One component (Brent).
struct Along<'o, 'p, 'a>(&'o Objective<'p, 'a>);

impl CostFunction for Along<'_, '_, '_> {
    type Param = f64;
    type Output = f64;

    fn cost(&self, v: &f64) -> Result<f64, ArgminError> {
        Ok(self.0.at(&[*v]))
    }
}

/// Several components (Nelder–Mead).
struct Within<'o, 'p, 'a>(&'o Objective<'p, 'a>);

impl CostFunction for Within<'_, '_, '_> {
    type Param = Vec<f64>;
    type Output = f64;

    fn cost(&self, v: &Vec<f64>) -> Result<f64, ArgminError> {
        Ok(self.0.at(v))
    }
}

/// Minimises `criterion` over `settings`, starting from `x`, on `lin` (or exactly). A
/// single setting is searched within its bound of `x` ([`DisuptParams::bound`]); several
/// are searched freely, or within their bounds when `bounded`.
#[allow(clippy::too_many_arguments)]
fn minimise(
    problem: &Problem<'_>,
    lin: Option<&Linearization>,
    x: X,
    settings: &'static [Setting],
    criterion: Criterion,
    p: &DisuptParams,
    bounded: bool,
    tally: &AtomicUsize,
) -> Result<X, DisuptError> {
    let objective = Objective {
        problem,
        lin,
        p: params_of(&x),
        free: settings,
        criterion,
        within: bounded.then_some(p),
        buf: RefCell::new(Observation::default()),
        tally,
    };
    let mut out = x;
    if let [single] = settings {
        let half = if *single == Setting::Azimuth {
            p.azimuth_bound_deg
        } else {
            p.drift_bound_deg_h
        };
        let c = x.get(*single);
        let (rel, abs) = if lin.is_some() {
            (1e-10, 1e-6)
        } else {
            (1e-8, 1e-4)
        };
        let solver = BrentOpt::new(c - half, c + half).set_tolerance(rel, abs);
        let res = Executor::new(Along(&objective), solver)
            .configure(|s| s.max_iters(200))
            .run()
            .map_err(DisuptError::Optimiser)?;
        out.set(*single, *res.state().get_best_param().unwrap_or(&c));
        return Ok(out);
    }
    {
        // Several settings at once: Nelder–Mead from a simplex of unit steps.
        let start: Vec<f64> = settings.iter().map(|&s| x.get(s)).collect();
        let mut simplex = vec![start.clone()];
        simplex.extend((0..start.len()).map(|i| {
            let mut v = start.clone();
            v[i] += 1.0;
            v
        }));
        let solver = NelderMead::new(simplex)
            .with_sd_tolerance(1e-9)
            .map_err(DisuptError::Optimiser)?;
        let res = Executor::new(Within(&objective), solver)
            .configure(|s| s.max_iters(if lin.is_some() { 2000 } else { 400 }))
            .run()
            .map_err(DisuptError::Optimiser)?;
        let best = res.state().get_best_param().cloned().unwrap_or(start);
        let best = objective.params_at(&best);
        for &s in settings {
            out.set(s, best[s.index()]);
        }
    }
    Ok(out)
}

/// Where one step of OEPI/OWPI ended.
struct Searched {
    /// The optimum.
    x: X,
    /// Its exact observation.
    y: Observation,
    /// A linearisation at `x` in the next step's settings, when it was built.
    next_lin: Option<Linearization>,
}

/// One step of OEPI/OWPI from `x` (whose exact observation is `y`, and `lin` a
/// linearisation there, when at hand): search the linearisation, confirm with an exact
/// pass, relinearise where they disagree.
///
/// The exact pass at the model's optimum runs in one batch of lanes with the
/// finite-difference passes either outcome needs next (this step's settings, to
/// relinearise there if the two disagree; `next`, the following step's, if they agree),
/// which cost little beside it: a step costs one batch of passes instead of two passes
/// in turn, and the results are those of separate passes, bit for bit.
#[allow(clippy::too_many_arguments)]
fn search(
    problem: &Problem<'_>,
    x: X,
    y: &Observation,
    lin: Option<Linearization>,
    (component, next): (Component, &[Setting]),
    criterion: Criterion,
    p: &DisuptParams,
    tally: &AtomicUsize,
) -> Result<Searched, DisuptError> {
    let free = component.settings();
    let base = problem.base_linearization();
    let at_x = |l: &Linearization| l.p_ref == params_of(&x) && l.covers(free);
    let mut lin = match lin {
        Some(l) if at_x(&l) => Cow::Owned(l),
        _ if at_x(base) => Cow::Borrowed(base),
        _ => Cow::Owned(problem.linearize_by(&x, y.clone(), free, tally)),
    };
    let mut which = free.to_vec();
    which.extend(next.iter().filter(|s| !free.contains(s)));
    for _ in 0..MAX_RELINEARISATIONS {
        let x_new = minimise(problem, Some(&lin), x, free, criterion, p, false, tally)?;
        let mut xs = vec![x_new];
        xs.extend(moved_by_steps(&x_new, &which));
        let mut ys = problem.observe_batched_by(&xs, tally);
        let y_new = ys.remove(0);
        let agrees = lin.predict(&params_of(&x_new)).agrees_with(&y_new);
        let there = linearization_of(&x_new, y_new.clone(), &which, ys);
        if agrees {
            return Ok(Searched {
                x: x_new,
                y: y_new,
                next_lin: Some(there),
            });
        }
        lin = Cow::Owned(there);
    }
    let x_new = minimise(problem, None, x, free, criterion, p, false, tally)?;
    let y_new = problem.observe_by(&x_new, tally);
    Ok(Searched {
        x: x_new,
        y: y_new,
        next_lin: None,
    })
}

fn run_steps(
    problem: &Problem<'_>,
    plan: &[(Component, Criterion)],
    p: &DisuptParams,
) -> Result<MethodResult, DisuptError> {
    let t0 = Instant::now();
    let tally = AtomicUsize::new(0);
    let passes = || tally.load(Ordering::Relaxed);
    let mut x = problem.x0();
    let mut y = problem.base_linearization().y_ref.clone();
    let mut lin = None;
    let mut steps = Vec::new();
    for (i, &(component, criterion)) in plan.iter().enumerate() {
        let before = passes();
        let input = x;
        let next = plan.get(i + 1).map_or(&[][..], |(c, _)| c.settings());
        let done = search(
            problem,
            x,
            &y,
            lin.take(),
            (component, next),
            criterion,
            p,
            &tally,
        )?;
        (x, y, lin) = (done.x, done.y, done.next_lin);
        let (dx_m, dy_m) = last_cp(&y);
        steps.push(Step {
            step: i + 1,
            component,
            criterion,
            input,
            output: x,
            dx_m,
            dy_m,
            evaluations: passes() - before,
            at_bound: p.at_bound(&input, &x, component.settings()),
        });
    }
    let (dx_m, dy_m) = last_cp(&y);
    Ok(MethodResult {
        x,
        sigma: None,
        dx_m,
        dy_m,
        kryt1: problem.kryt1(&y),
        steps,
        evaluations: passes(),
        wall_s: t0.elapsed().as_secs_f64(),
    })
}

/// The horizontal drifts, which a wrong azimuth's Earth rate can pass for in the pitch
/// and roll.
const DRIFTS_XY: &[Setting] = &[Setting::DriftX, Setting::DriftY];

/// Kryt1 of each of `points` (settings and their exact observation) with the horizontal
/// drifts free: the least Kryt1 over (driftx, drifty) within the methods' drift bound of
/// there ([`DisuptParams::drift_bound_deg_h`]), on a linearisation in those two (two
/// passes a point, side by side in lanes; counted in `tally`).
///
/// How well the log's pitch and roll accept each point's azimuth. At given drifts, Kryt1
/// confounds a few degrees of azimuth with the horizontal drifts: the Earth's rate
/// misapplied by an azimuth error δψ passes for a horizontal drift of Ω cos φ · δψ
/// (0.84 °/h for 5° at 50° N, the size of an LN-200's drifts), so a right azimuth at the
/// initial drifts may show more Kryt1 than a wrong one. With the drifts free, what remains
/// is what no drift explains: the route's turns tell a drift, which turns with the body,
/// from an azimuth error, which does not. The bound keeps the drifts to what a gyro may
/// have: on a short drive, unbounded drifts pass for any azimuth (a 200-s run with a
/// control point 1 km off: a wrong 78° turn, whose misapplied Earth rate is about
/// 12 °/h, had no more Kryt1 than the start with the drifts unbounded; within ±5 °/h, ten
/// times the start's).
pub fn kryt1_with_free_drifts_xy(
    problem: &Problem<'_>,
    points: &[(X, &Observation)],
    p: &DisuptParams,
    tally: &AtomicUsize,
) -> Result<Vec<f64>, DisuptError> {
    let moved: Vec<X> = points
        .iter()
        .flat_map(|(x, _)| moved_by_steps(x, DRIFTS_XY))
        .collect();
    let mut ys = problem.observe_many_by(&moved, tally).into_iter();
    points
        .iter()
        .map(|&(x, y)| {
            let lin = linearization_of(&x, y.clone(), DRIFTS_XY, ys.by_ref().take(2).collect());
            let best = minimise(
                problem,
                Some(&lin),
                x,
                DRIFTS_XY,
                Criterion::Kryt1,
                p,
                true,
                tally,
            )?;
            Ok(problem.kryt1(&lin.predict(&params_of(&best))))
        })
        .collect()
}

/// OEPI (paper Table 1).
pub fn oepi(problem: &Problem<'_>, p: &DisuptParams) -> Result<MethodResult, DisuptError> {
    if problem.fixes.is_empty() {
        return Err(DisuptError::NoControlPoint("OEPI"));
    }
    run_steps(
        problem,
        &[
            (Component::Azimuth, Criterion::Kryt2),
            (Component::DriftZ, Criterion::Kryt2),
            (Component::DriftX, Criterion::Kryt1),
            (Component::DriftY, Criterion::Kryt1),
        ],
        p,
    )
}

/// OWPI (paper Table 2).
pub fn owpi(problem: &Problem<'_>, p: &DisuptParams) -> Result<MethodResult, DisuptError> {
    run_steps(
        problem,
        &[
            (Component::Azimuth, Criterion::Kryt1),
            (Component::DriftZ, Criterion::Kryt1),
            (Component::AzimuthDriftXy, Criterion::Kryt1),
        ],
        p,
    )
}
