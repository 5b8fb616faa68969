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
