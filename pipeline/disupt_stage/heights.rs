//! The corrected route's heights at the control points, and the odometer pitch boresight
//! they show ([`disupt::fit_odo_pitch`]).

use unz_stages::criteria::ControlPointFix;
use unz_stages::disupt::{self, HeightError, OdoPitchFit};
use unz_stages::strapdown::{self, CriteriaSink, NavInputs, NavSettings};

/// The odometer pitch boresight of the corrected route: fitted to its height errors at
/// the control points (`heights`, of its pass without one; the points `left_out` of its
/// fit not among them), then, when taken, fitted again on the slopes a probe pass at the
/// fitted angle measures (the fit took each point's height to move by its distance per
/// tan β; an IMU pitched on its mount moves it less, by the cosine). `settings` and
/// `inputs` are the corrected pass's; `fix_samples` the points' samples, `block` the
/// criteria's block (the probe keeps what the criteria read). None without a point.
#[allow(clippy::too_many_arguments)]
pub(super) fn odo_pitch_of(
    heights: Vec<HeightError>,
    left_out: impl Fn(&HeightError) -> bool,
    inputs: &NavInputs<'_>,
    settings: NavSettings,
    fixes: &[ControlPointFix],
    fix_samples: &[usize],
    block: usize,
) -> Option<OdoPitchFit> {
    let heights: Vec<HeightError> = heights.into_iter().filter(|h| !left_out(h)).collect();
    let fit = disupt::fit_odo_pitch(&heights)?;
    if !fit.applied {
        return Some(fit);
    }
    let mut probe = [CriteriaSink::default()];
    let tan_probe = fit.applied_rad().tan();
    strapdown::run_criteria(
        inputs,
        &[NavSettings {
            odo_pitch_rad: fit.applied_rad(),
            ..settings
        }],
        block,
        fix_samples,
        &mut probe,
    );
    let probed = disupt::height_errors_at(fixes, |k| probe[0].position_at(k));
    disupt::fit_odo_pitch(&disupt::with_slopes(&heights, &probed, tan_probe)).or(Some(fit))
}
