//! The corrected route's heights at the control points, and the odometer pitch boresight
//! they show ([`disupt::fit_odo_pitch`]).

use unz_stages::criteria::ControlPointFix;
use unz_stages::disupt::{self, HeightError, OdoPitchFit};
use unz_stages::strapdown::{self, CriteriaSink, NavInputs, NavSettings};

use crate::method_tables::KeptTrack;

/// The corrected route's pass: its inputs and settings (with the vehicle's configured
/// pitch boresight, if any), and the samples of its control points and of its kept track.
pub(super) struct CorrectedPass<'a> {
    pub(super) inputs: NavInputs<'a>,
    pub(super) settings: NavSettings,
    /// The vehicle's configured pitch boresight, deg (`settings` have it).
    pub(super) odo_pitch_deg: f64,
    pub(super) fixes: &'a [ControlPointFix],
    /// The criteria's block (the probe keeps what the criteria read).
    pub(super) block: usize,
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
    let mut probe = [CriteriaSink::default()];
    let tan_step = fit.applied_rad().tan() - tan_base;
    let fix_samples = pass.fixes.iter().map(|f| f.sample);
    strapdown::run_criteria(
        &pass.inputs,
        &[NavSettings {
            odo_pitch_rad: fit.applied_rad(),
            ..pass.settings
        }],
        pass.block,
        &fix_samples
            .chain(pass.kept_samples.iter().copied())
            .collect::<Vec<_>>(),
        &mut probe,
    );
    let probed = disupt::height_errors_at(pass.fixes, |k| probe[0].position_at(k));
    let fit = disupt::fit_odo_pitch(
        &disupt::with_slopes(&heights, &probed, tan_step),
        pass.odo_pitch_deg,
    )
    .unwrap_or(fit);
    // The track's rows are its kept samples the pass reached, in order.
    let ratio = (fit.applied_rad().tan() - tan_base) / tan_step;
    for (h, &k) in track.h_m.iter_mut().zip(pass.kept_samples) {
        if let Some(p) = probe[0].position_at(k) {
            let without = f64::from(*h);
            *h = (without + (p.h_m - without) * ratio) as f32;
        }
    }
    Some(fit)
}
