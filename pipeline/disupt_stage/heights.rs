//! The corrected route's heights at the control points, and the odometer pitch boresight
//! they show ([`disupt::fit_odo_pitch`]).

use unz_stages::criteria::{ControlPointFix, FixPose};
use unz_stages::disupt::{self, HeightError, OdoPitchFit};
use unz_stages::strapdown::{self, NavInputs, NavSettings, PassSink};

use crate::method_tables::KeptTrack;

/// The corrected route's pass: its inputs and settings (with the vehicle's configured
/// pitch boresight, if any), and the samples of its control points and of its kept track.
pub(super) struct CorrectedPass<'a> {
    pub(super) inputs: NavInputs<'a>,
    pub(super) settings: NavSettings,
    /// The vehicle's configured pitch boresight, deg (`settings` have it).
    pub(super) odo_pitch_deg: f64,
    pub(super) fixes: &'a [ControlPointFix],
    /// The samples `tracks.parquet` keeps.
    pub(super) kept_samples: &'a [usize],
}

/// The odometer pitch boresight of the corrected route, and its kept track's heights
/// with it. Fitted to the route's height errors at the control points (`heights`, of its
/// pass with the configured one; the points `left_out` of its fit not among them), then,
/// when taken, fitted again on the slopes a probe pass at the fitted angle measures (the
/// fit took each point's height to move by its distance per tan β; an IMU pitched on its
/// mount moves it less, by the cosine). The same probe gives the height's move at each of
/// the track's samples, which moves in proportion to tan β: `track`'s heights take it for
/// the angle taken. None without a point.
pub(super) fn odo_pitch_of(
    heights: Vec<HeightError>,
    left_out: impl Fn(&HeightError) -> bool,
    pass: &CorrectedPass<'_>,
    track: &mut KeptTrack,
) -> Option<OdoPitchFit> {
    let heights: Vec<HeightError> = heights.into_iter().filter(|h| !left_out(h)).collect();
    let tan_base = pass.settings.odo_pitch_rad.tan();
    let fit = disupt::fit_odo_pitch(&heights, pass.odo_pitch_deg)?;
    if !fit.applied {
        return Some(fit);
    }
    let tan_step = fit.applied_rad().tan() - tan_base;
    let mut probe = Probe::new(pass.fixes, pass.kept_samples);
    strapdown::run(
        &pass.inputs,
        &NavSettings {
            odo_pitch_rad: fit.applied_rad(),
            ..pass.settings
        },
        &mut probe,
    );
    let probed = disupt::height_errors_at(pass.fixes, |k| probe.pose_at(k));
    let fit = disupt::fit_odo_pitch(
        &disupt::with_slopes(&heights, &probed, tan_step),
        pass.odo_pitch_deg,
    )
    .unwrap_or(fit);
    // The track's rows are its kept samples the pass reached, in order.
    let ratio = (fit.applied_rad().tan() - tan_base) / tan_step;
    for (h, &probed_m) in track.h_m.iter_mut().zip(&probe.kept_h_m) {
        let without = f64::from(*h);
        *h = (without + (probed_m - without) * ratio) as f32;
    }
    Some(fit)
}

/// What the boresight's probe pass keeps: its poses at the control points' samples and
/// its heights at the track's kept samples; not the criteria's blocks, which the probe
/// does not read, nor a pose at each kept sample (1.7 MB at 40 minutes, 10 Hz).
struct Probe<'a> {
    /// The control points' samples not reached yet, in decreasing order (popped).
    fixes_left: Vec<usize>,
    /// The poses at the control points' samples, in sample order.
    poses: Vec<(usize, FixPose)>,
    /// The track's kept samples (in increasing order) and the next one not reached.
    kept: &'a [usize],
    next_kept: usize,
    /// The heights at the kept samples reached, m.
    kept_h_m: Vec<f64>,
}

impl<'a> Probe<'a> {
    fn new(fixes: &[ControlPointFix], kept: &'a [usize]) -> Self {
        let mut fixes_left: Vec<usize> = fixes.iter().map(|f| f.sample).collect();
        fixes_left.sort_unstable_by(|a, b| b.cmp(a));
        fixes_left.dedup();
        Self {
            poses: Vec::with_capacity(fixes_left.len()),
            fixes_left,
            kept,
            next_kept: 0,
            kept_h_m: Vec::with_capacity(kept.len()),
        }
    }

    /// The pose at the control point's sample `k`, if the pass reached it.
    fn pose_at(&self, k: usize) -> Option<FixPose> {
        self.poses
            .binary_search_by_key(&k, |p| p.0)
            .ok()
            .map(|i| self.poses[i].1)
    }
}

impl PassSink for Probe<'_> {
    #[inline(always)]
    fn sample(&mut self, k: usize, lat: f64, lon: f64, h: f64, q: &[f64; 4], distance_m: f64) {
        if self.fixes_left.last() == Some(&k) {
            self.fixes_left.pop();
            let pose = FixPose {
                lat_rad: lat,
                lon_rad: lon,
                h_m: h,
                distance_m,
                q_b_to_n: *q,
            };
            self.poses.push((k, pose));
        }
        while self.kept.get(self.next_kept) == Some(&k) {
            self.kept_h_m.push(h);
            self.next_kept += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fix(sample: usize) -> ControlPointFix {
        ControlPointFix {
            id: sample as u32,
            sample,
            t_s: sample as f64 * 0.01,
            lat_rad: 0.0,
            lon_rad: 0.0,
            h_m: 0.0,
            mark_lever_arm_m: [0.0; 3],
        }
    }

    /// A pass over samples `0..reached` whose state at sample `k` is told by `k`.
    fn pass(probe: &mut Probe<'_>, reached: usize) {
        for k in 0..reached {
            let x = k as f64;
            probe.sample(k, x, -x, 100.0 + x, &[x, 0.0, 0.0, 1.0], 2.0 * x);
        }
    }

    #[test]
    fn the_probe_keeps_the_poses_at_the_points_and_the_heights_at_the_kept_samples() {
        // Points out of order and one twice; a kept sample twice.
        let fixes = [fix(40), fix(7), fix(40), fix(0)];
        let kept = [0, 10, 20, 20, 30, 50];
        let mut probe = Probe::new(&fixes, &kept);
        pass(&mut probe, 60);
        assert_eq!(probe.kept_h_m, [100.0, 110.0, 120.0, 120.0, 130.0, 150.0]);
        for k in [0, 7, 40] {
            let x = k as f64;
            let want = FixPose {
                lat_rad: x,
                lon_rad: -x,
                h_m: 100.0 + x,
                distance_m: 2.0 * x,
                q_b_to_n: [x, 0.0, 0.0, 1.0],
            };
            assert_eq!(probe.pose_at(k), Some(want), "{k}");
        }
        assert_eq!(probe.pose_at(10), None, "not a point");
    }

    #[test]
    fn a_probe_pass_that_ends_early_keeps_what_it_reached() {
        let fixes = [fix(5), fix(45)];
        let kept = [0, 10, 20, 30, 40, 50];
        let mut probe = Probe::new(&fixes, &kept);
        pass(&mut probe, 25);
        assert_eq!(probe.kept_h_m, [100.0, 110.0, 120.0]);
        assert!(probe.pose_at(5).is_some());
        assert_eq!(probe.pose_at(45), None);
    }
}
