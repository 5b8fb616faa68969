//! The review passes: one exact pass per method's settings, side by side, giving its
//! track, Kryt1 series and control-point errors.

use rayon::prelude::*;
use unz_stages::criteria::{self, ControlPointFix, Kryt1Series, Kryt2};
use unz_stages::derive::Derived;
use unz_stages::disupt::{HeightError, Problem, X, height_errors_at};
use unz_stages::strapdown::{self, LaneBatch, PassSink, ReviewPass};

use super::joint_run::ClassicResult;
use crate::method_tables::{KeptTrack, MethodKryt1, TrackBuilder, method_kryt1};

/// One set of settings to review: a method's (or the initial ones) and the derive its
/// pass runs on.
pub(super) struct Reviewed<'d> {
    pub(super) name: &'static str,
    pub(super) x: X,
    pub(super) derived: &'d Derived,
}

/// The settings reviewed before the joint fit's: the initial ones (`x_before`), then
/// OWPI's and OEPI's, those of `classic` that ran, all on `derived`.
pub(super) fn classic_reviewed<'d>(
    x_before: X,
    derived: &'d Derived,
    classic: &[ClassicResult],
) -> Vec<Reviewed<'d>> {
    let initial = Reviewed {
        name: "initial",
        x: x_before,
        derived,
    };
    let ran = classic.iter().rev().filter_map(|(name, result)| {
        result.as_ref().ok().map(|r| Reviewed {
            name,
            x: r.x,
            derived,
        })
    });
    std::iter::once(initial).chain(ran).collect()
}

/// What a review pass gives of one set of settings (the control points' horizontal and
/// height errors among it).
pub(super) struct ReviewOutcome {
    pub(super) kryt1_rad: f64,
    pub(super) cps: Vec<Kryt2>,
    pub(super) heights: Vec<HeightError>,
    pub(super) track: KeptTrack,
    pub(super) kryt1_series: MethodKryt1,
}

/// The review passes of `reviewed` in two batches side by side, each at most
/// [`strapdown::MAX_LANES`] lanes, each on its own derive's odometer (the derives share
/// their IMU series), their tracks at the samples `keep`: the last one alone, as it also
/// feeds every sample to `track` (the route σ's states: the longer work per sample), and
/// the others (at 12 h: 0.38-0.40 s against 0.48-0.51 in one batch, 0.42-0.44 in halves).
/// Each outcome is what the pass alone gives (a lane is its pass alone bit for bit, the
/// tracked one too: `strapdown::lanes`' tests).
pub(super) fn review_passes(
    problem: &Problem<'_>,
    reviewed: &[Reviewed<'_>],
    fixes: &[ControlPointFix],
    keep: &[usize],
    track: &mut (impl PassSink + Send),
) -> Vec<ReviewOutcome> {
    let (first, rest) = reviewed.split_at(reviewed.len().saturating_sub(1));
    let (mut outcomes, rest) = rayon::join(
        || untracked_reviews(problem, first, fixes, keep),
        || review_batch(problem, rest, fixes, keep, track),
    );
    outcomes.extend(rest);
    outcomes
}

/// [`review_batch`] without a track: reviews that feed no route σ.
pub(super) fn untracked_reviews(
    problem: &Problem<'_>,
    reviewed: &[Reviewed<'_>],
    fixes: &[ControlPointFix],
    keep: &[usize],
) -> Vec<ReviewOutcome> {
    review_batch(
        problem,
        reviewed,
        fixes,
        keep,
        &mut None::<strapdown::NavTrack>,
    )
}

/// The review passes of `reviewed` (at most [`strapdown::MAX_LANES`]) in one batch of
/// lanes, the last one's every sample into `track` ([`review_passes`]).
pub(super) fn review_batch(
    problem: &Problem<'_>,
    reviewed: &[Reviewed<'_>],
    fixes: &[ControlPointFix],
    keep: &[usize],
    track: &mut (impl PassSink + Send),
) -> Vec<ReviewOutcome> {
    let Some(first) = reviewed.first() else {
        return Vec::new();
    };
    let n = first.derived.nav_inputs().len();
    let at: Vec<usize> = fixes.iter().map(|f| f.sample).filter(|&k| k < n).collect();
    let passes = review_lanes(problem, reviewed, keep, &at, track);
    reviewed
        .par_iter()
        .zip(passes)
        .map(|(r, mut pass)| {
            let d = r.derived;
            let mut series = Kryt1Series::default();
            let kryt1_rad = criteria::kryt1_from_blocks(
                &d.epochs,
                &problem.lp,
                std::mem::take(&mut pass.criteria.blocks),
                &problem.kalman,
                Some(&mut series),
            );
            let cps = criteria::kryt2_at(fixes, |k| pass.criteria.position_at(k));
            let heights = height_errors_at(fixes, |k| pass.criteria.position_at(k));
            ReviewOutcome {
                kryt1_rad,
                cps,
                heights,
                track: pass.rows.map(TrackBuilder::finish).unwrap_or_default(),
                kryt1_series: method_kryt1(r.name, d, &series),
            }
        })
        .collect()
}

/// The passes of the methods `reviewed` side by side, the last one also feeding every
/// sample to `track`.
fn review_lanes<'d, S: PassSink>(
    problem: &Problem<'_>,
    reviewed: &[Reviewed<'d>],
    keep: &[usize],
    at: &[usize],
    track: &mut S,
) -> Vec<ReviewPass<Option<TrackBuilder>>> {
    strapdown::in_lanes(
        reviewed.len(),
        &mut ReviewBatch {
            problem,
            reviewed,
            keep,
            at,
            track,
        },
    )
}

/// [`review_passes`]' lanes.
struct ReviewBatch<'r, 'd, 'p, S> {
    problem: &'r Problem<'p>,
    reviewed: &'r [Reviewed<'d>],
    keep: &'r [usize],
    at: &'r [usize],
    track: &'r mut S,
}

impl<'r, 'd, S: PassSink> LaneBatch for ReviewBatch<'r, 'd, '_, S> {
    type Out = ReviewPass<Option<TrackBuilder>>;

    fn run<const N: usize>(&mut self, points: [usize; N]) -> [Self::Out; N] {
        let reviewed = self.reviewed;
        let last = reviewed.len() - 1;
        let settings = points.map(|i| self.problem.settings(&reviewed[i].x));
        let odometers = points.map(|i| &reviewed[i].derived.odo_dist_m[..]);
        let tracked = points.iter().position(|&i| i == last).unwrap_or(0);
        // Each method's trajectory is built as its lane runs (none for a lane that
        // repeats the one before).
        let rows = std::array::from_fn(|l| {
            (l == 0 || points[l] != points[l - 1]).then(|| {
                let r = &reviewed[points[l]];
                TrackBuilder::new(r.name, self.keep.len())
            })
        });
        strapdown::run_review(
            &reviewed[0].derived.nav_inputs(),
            odometers,
            &settings,
            self.problem.lp.block,
            self.at,
            self.keep,
            rows,
            tracked,
            self.track,
        )
    }
}
