//! The turn in heading a lost sample's fill leaves, as a nuisance of the joint fit.
//!
//! The z gyro's fill over a gap ([`crate::derive`]) misses the heading's turn there as the
//! x and y gyros' miss the tilt ([`super::gap_tilts`]): the dead-reckoned route after the
//! gap is turned about the gap's point by the miss, and every control point after it
//! moves across its line from the gap. The joint fit gives each gap (at most
//! [`MAX_TURN_STEPS`], gathered beyond) an unknown turn with a prior σ from the z rates
//! around it, profiled out of the control points' rows as the tilt steps are out of the
//! epochs': the azimuth's σ then carries the turns the fills may have made. The route's
//! points come from a dead reckoning of the derive's odometer on its z gyro (a model of
//! the route, good to the degree: the turns' columns need no more).

use std::sync::Arc;

use nalgebra::{Cholesky, DMatrix, DVector, Dyn, Matrix2};

use super::gap_tilts::{FactorCache, gathered};

/// At most this many turn steps: gaps beyond it are gathered, in order, into as many
/// groups, each turning about its first gap's point with the group's variances summed.
pub const MAX_TURN_STEPS: usize = 64;

/// A gap's turn: where the route turns (north, east from the start, m), after which
/// sample, and its prior variance, rad².
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct TurnGap {
    pub(super) sample: usize,
    pub(super) at_ne_m: [f64; 2],
    pub(super) var_rad2: f64,
}

/// The gaps' turns over a problem's control points.
#[derive(Debug)]
pub(super) struct TurnSteps {
    steps: Vec<TurnGap>,
    /// Per control point, unweighted: how each step moves its (north, east), m per rad
    /// (rows 2i and 2i + 1, a column a step).
    columns: DMatrix<f64>,
    /// The normal matrix's factor at the last few control points' weights.
    factors: FactorCache<Vec<f64>>,
}

impl TurnSteps {
    /// The turns of `gaps` (in order) over control points at samples `cp_samples` and
    /// points `cp_ne_m`; `None` without a gap before a control point.
    pub(super) fn new(
        gaps: Vec<TurnGap>,
        cp_samples: &[usize],
        cp_ne_m: &[[f64; 2]],
    ) -> Option<Self> {
        let last = cp_samples.iter().copied().max()?;
        let gaps: Vec<TurnGap> = gaps.into_iter().filter(|g| g.sample < last).collect();
        if gaps.is_empty() {
            return None;
        }
        let steps = gathered(gaps, MAX_TURN_STEPS, |into, g| into.var_rad2 += g.var_rad2);
        let columns = DMatrix::from_fn(2 * cp_samples.len(), steps.len(), |row, j| {
            let (i, axis) = (row / 2, row % 2);
            let g = &steps[j];
            if cp_samples[i] <= g.sample {
                return 0.0;
            }
            // The route beyond the gap turned by ε about its point (clockwise from above,
            // as heading counts): (ΔN, ΔE) = ε (−(E − E_g), N − N_g).
            if axis == 0 {
                -(cp_ne_m[i][1] - g.at_ne_m[1])
            } else {
                cp_ne_m[i][0] - g.at_ne_m[0]
            }
        });
        Some(Self {
            steps,
            columns,
            factors: FactorCache::new(),
        })
    }

    /// The steps, and the rows their priors append.
    pub(super) fn len(&self) -> usize {
        self.steps.len()
    }

    /// The prior variance of every step, rad².
    pub(super) fn variances(&self) -> impl Iterator<Item = f64> + '_ {
        self.steps.iter().map(|s| s.var_rad2)
    }

    /// Profiles the turns out of the control points' rows `rows` (north, east of each,
    /// each times its weight in `weights`, 0 for a point left out), appending the
    /// priors' whitened rows to `tail`. Linear in the rows.
    pub(super) fn profile(&self, rows: &mut [f64], weights: &[f64], tail: &mut Vec<f64>) {
        let m = self.steps.len();
        let factor = match self.factor(weights) {
            Some(f) if rows.len() == self.columns.nrows() => f,
            _ => {
                tail.extend(std::iter::repeat_n(0.0, m));
                return;
            }
        };
        let weighted = |row: usize, j: usize| self.columns[(row, j)] * weights[row / 2];
        let rhs = DVector::from_fn(m, |j, _| {
            -(0..rows.len())
                .map(|row| weighted(row, j) * rows[row])
                .sum::<f64>()
        });
        let delta = factor.solve(&rhs);
        for (row, v) in rows.iter_mut().enumerate() {
            *v += (0..m).map(|j| weighted(row, j) * delta[j]).sum::<f64>();
        }
        for (j, s) in self.steps.iter().enumerate() {
            tail.push(delta[j] / s.var_rad2.sqrt());
        }
    }

    /// What the turns, as the other points weighed with `weights` leave them, add to the
    /// spread (north, east; m²) of control point `i`'s error: `Bᵢ N⁻¹ Bᵢᵀ`.
    pub(super) fn spread_at(&self, i: usize, weights: &[f64]) -> Option<Matrix2<f64>> {
        let factor = self.factor(weights)?;
        let b = self.columns.rows(2 * i, 2).transpose();
        let solved = factor.solve(&b.clone_owned());
        let s = b.transpose() * solved;
        Some(Matrix2::new(s[(0, 0)], s[(0, 1)], s[(1, 0)], s[(1, 1)]))
    }

    /// The Cholesky factor of `BᵀW²B + Q⁻¹` at `weights`, kept for the next calls.
    fn factor(&self, weights: &[f64]) -> Option<Arc<Cholesky<f64, Dyn>>> {
        if weights.len() * 2 != self.columns.nrows() {
            return None;
        }
        self.factors.get(weights, || {
            let m = self.steps.len();
            let mut normal = DMatrix::from_fn(m, m, |a, b| {
                (0..self.columns.nrows())
                    .map(|row| {
                        let w2 = weights[row / 2] * weights[row / 2];
                        self.columns[(row, a)] * self.columns[(row, b)] * w2
                    })
                    .sum::<f64>()
            });
            for (j, s) in self.steps.iter().enumerate() {
                normal[(j, j)] += 1.0 / s.var_rad2;
            }
            normal
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A route north 1000 m, a gap there, then east 1000 m to a control point: a turn ε
    /// (to the right) at the gap moves the point by (−(E − E_g), N − N_g) ε = (−1000 ε, 0):
    /// south, its leg east turned towards the south.
    #[test]
    fn a_turn_moves_a_later_point_across_its_line_from_the_gap() {
        let gaps = vec![TurnGap {
            sample: 100,
            at_ne_m: [1000.0, 0.0],
            var_rad2: 1e-6,
        }];
        let t = TurnSteps::new(gaps, &[50, 200], &[[500.0, 0.0], [1000.0, 1000.0]]).unwrap();
        assert_eq!(t.len(), 1);
        assert_eq!(t.columns.column(0).as_slice(), &[0.0, 0.0, -1000.0, 0.0]);
        // The point's error a turn of 2 mrad explains is profiled out but for the prior's
        // pull: with a weight of 1/m, N = 10⁶ + 10⁶, so half remains.
        let eps = 2e-3;
        let mut rows = vec![0.0, 0.0, -1000.0 * eps, 0.0];
        let mut tail = Vec::new();
        t.profile(&mut rows, &[1.0, 1.0], &mut tail);
        assert!((rows[2] - (-1.0)).abs() < 1e-9, "{rows:?}");
        assert_eq!(tail.len(), 1);
        // The cost is the marginal one: r² / (1 + w² b² q) = 4 / 2.
        let cost: f64 = rows.iter().chain(&tail).map(|v| v * v).sum();
        assert!((cost - 2.0).abs() < 1e-9, "{cost}");
        // Held out (weight 0), the point's spread is the turn's prior: (1000 m)² 10⁻⁶.
        let s = t.spread_at(1, &[1.0, 0.0]).unwrap();
        assert!(
            (s[(0, 0)] - 1.0).abs() < 1e-9 && s[(1, 1)].abs() < 1e-12,
            "{s}"
        );
    }

    #[test]
    fn gaps_after_the_last_point_take_no_step() {
        let gap = |sample| TurnGap {
            sample,
            at_ne_m: [0.0, 0.0],
            var_rad2: 1e-6,
        };
        assert!(TurnSteps::new(vec![gap(300)], &[200], &[[1.0, 1.0]]).is_none());
        let many: Vec<TurnGap> = (0..200).map(gap).collect();
        let t = TurnSteps::new(many, &[500], &[[1.0, 1.0]]).unwrap();
        assert_eq!(t.len(), MAX_TURN_STEPS);
        assert!((t.variances().sum::<f64>() - 200e-6).abs() < 1e-15);
    }
}
