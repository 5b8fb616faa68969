//! `disupt.json` and `disupt.md`: the settings each method found, the errors they give,
//! and the paper's tables.

use std::fmt::Write as _;

use serde::Serialize;
use unz_stages::criteria::Kryt2;
use unz_stages::disupt::{self, Holdout, MethodResult, X};
use unz_stages::odo_rebridge::Rebridged;
use unz_stages::strapdown::NavSettings;
use unz_stages::units::DEG_PER_H;

/// Settings as reported.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct SettingsOut {
    /// Initial azimuth, degrees.
    pub azimuth_deg: f64,
    /// Gyro drifts, rad/s.
    pub drift_rad_s: [f64; 3],
    /// Odometer multiplier relative to the manifest's scale.
    pub odo_scale: f64,
    /// Odometer yaw boresight, degrees (moved by the joint fit only, when asked).
    pub odo_yaw_deg: f64,
    /// Odometer speed bias added while it moves, m/s (moved by the joint fit only, when
    /// asked).
    pub odo_bias_mps: f64,
    /// Odometer lag, s (positive: the odometer reports late), beyond derive's
    /// `odo_time_offset_s`; estimated by the joint fit only.
    pub odo_lag_s: f64,
    /// The vehicle's mark moved from the configured lever arm along the body's x and y,
    /// m (by the joint fit only, when it estimates the mark).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mark_arm_m: Option<[f64; 2]>,
    /// 1σ of each (joint only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma: Option<SigmaOut>,
}

/// 1σ of the settings.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct SigmaOut {
    /// degrees.
    pub azimuth_deg: f64,
    /// rad/s.
    pub drift_rad_s: [f64; 3],
    /// Multiplier.
    pub odo_scale: f64,
    /// degrees (0 when not estimated).
    pub odo_yaw_deg: f64,
    /// m/s (0 when not estimated).
    pub odo_bias_mps: f64,
    /// s (0 when not estimated).
    pub odo_lag_s: f64,
    /// m (absent when not estimated).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mark_arm_m: Option<[f64; 2]>,
}

/// Settings and the errors they give: the run before DISUPT, and each method's result.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct Outcome {
    /// The settings.
    pub x: SettingsOut,
    /// ΔX at the last control point, m.
    #[serde(
        skip_serializing_if = "unz_stages::finite::is_absent",
        default = "unz_stages::finite::absent"
    )]
    pub dx_m: f64,
    /// ΔY at the last control point, m.
    #[serde(
        skip_serializing_if = "unz_stages::finite::is_absent",
        default = "unz_stages::finite::absent"
    )]
    pub dy_m: f64,
    /// Kryt1, rad.
    #[serde(
        skip_serializing_if = "unz_stages::finite::is_absent",
        default = "unz_stages::finite::absent"
    )]
    pub kryt1_rad: f64,
    /// Errors at every control point.
    pub control_points: Vec<Kryt2>,
}

/// One method in `disupt.json`: its [`Outcome`] (flattened) and how it got there.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct MethodOut {
    /// Optimised settings and their errors.
    #[serde(flatten)]
    pub outcome: Outcome,
    /// Table rows.
    pub steps: Vec<disupt::Step>,
    /// Navigation passes.
    pub evaluations: usize,
    /// Joint only: the error at each control point when it was left out of the fit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub holdout: Option<Vec<Holdout>>,
    /// Joint only, with the lag estimated: every lag tried (s) and the fit's cost there.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lag_profile: Option<Vec<[f64; 2]>>,
    /// Joint only, with the lag estimated and odometer failures the ingest bridged: the
    /// failures bridged again at each lag tried, and what that changed at the estimated
    /// one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rebridged: Option<Rebridged>,
    /// Joint only: why a control point found inconsistent stayed in the fit (the fit
    /// without it failed). The points left out are `holdout`'s `excluded`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exclusion_error: Option<String>,
    /// Joint only: why the fit with every control point was refused, when leaving the
    /// one `holdout` marks `excluded` out brought it within its bounds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refused_with_all_points: Option<String>,
}

/// `disupt.json`.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct DisuptOut {
    /// Distance travelled to the last control point, m.
    #[serde(
        skip_serializing_if = "unz_stages::finite::is_absent",
        default = "unz_stages::finite::absent"
    )]
    pub distance_m: f64,
    /// The initial settings and their errors.
    pub before: Outcome,
    /// Per method.
    pub methods: std::collections::BTreeMap<String, MethodOut>,
    /// Methods that could not run, with the reason.
    pub skipped: std::collections::BTreeMap<String, String>,
    /// The method whose settings made `corrected_nav.parquet`.
    pub corrected_by: Option<String>,
    /// Methods that ran but were not taken for `corrected_nav.parquet` although preferred
    /// to `corrected_by`, with the reason.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub not_used: std::collections::BTreeMap<String, String>,
    /// The start of the searches when a coarse search over ±180° of azimuth by the
    /// control points found a better one than the run's initial azimuth and the pitch and
    /// roll agreed, degrees.
    pub coarse_azimuth_deg: Option<f64>,
    /// The coarse search's turn when Kryt1 refused it (the searches then start at the
    /// run's initial azimuth): control points too near the start to fix the azimuth.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coarse_azimuth_refused: Option<super::CoarseRefused>,
    /// What the joint fit's residuals said of an odometer yaw boresight, when the joint
    /// fit held it at zero (`joint_odo_yaw` off) and ran.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_odo_yaw_check: Option<OdoYawCheck>,
    /// The tilt steps the joint fit gave the run's lost and replaced samples
    /// ([`disupt::GapTilts`]), when it ran and a gap left one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_gap_tilts: Option<disupt::GapTiltSteps>,
    /// Passes of the first linearisation, shared by the methods (not in their own
    /// `evaluations`).
    pub shared_passes: usize,
    /// Where the vehicle's mark, whose errors at the control points every criterion and
    /// table here gives, lies from the navigated point (`[vehicle] mark_lever_arm_m`,
    /// IMU body axes, m); absent when it is the navigated point.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mark_lever_arm_m: Option<[f64; 3]>,
    /// The mark's horizontal lever arm the joint fit's control points showed beyond
    /// `mark_lever_arm_m` when the fit held the mark ([`disupt::JointFit::mark_arm_seen`];
    /// the fit weighed [`disupt::MARK_ARM_MIN_POINTS`] points or more), and whether the
    /// fit was redone estimating it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_mark_arm_check: Option<MarkArmCheck>,
    /// The corrected route's odometer pitch boresight, fitted to the control points'
    /// heights, and whether `corrected_nav.parquet` took it (absent when no method
    /// corrected the run, or no control point was reached).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub odo_pitch: Option<disupt::OdoPitchFit>,
    /// The derive's `odo_time_offset_s` the run was configured with, s: the joint's
    /// `odo_lag_s` is the odometer's lag beyond it (absent when zero).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub odo_time_offset_s: f64,
    /// The joint fit's odometer lag stopped at the search's bound (`[disupt]
    /// odo_lag_bound_s` about the configured offset): the lag may lie beyond, and its σ
    /// says nothing of it (absent when not).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_odo_lag_at_bound_s: Option<f64>,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// A mark's lever arm the joint fit's control points show, and whether the fit was redone
/// estimating it (`disupt.json`).
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct MarkArmCheck {
    /// The arm they show, with its covariance, beyond the configured one: the fit's model
    /// with the mark free, at the fit's odometer lag.
    #[serde(flatten)]
    pub seen: disupt::MarkArmSeen,
    /// The arm the joint fit redone with the mark free estimated (its lag searched again),
    /// when `seen` was beyond [`MARK_ARM_REFIT_SIGMA`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimated: Option<disupt::MarkArmSeen>,
    /// Whether that refit is the joint's result (its estimate beyond [`MARK_ARM_SIGMA`]):
    /// the joint's settings in `methods` are then its, its `mark_arm_m` the estimate.
    pub refit: bool,
    /// Why the refit failed, when it did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refit_error: Option<String>,
}

impl DisuptOut {
    /// The vehicle's mark from the navigated point as the joint fit estimated it (the
    /// configured arm and the fit's move of it, IMU axes, m), with the 1σ of its forward
    /// and right components when the fit has a covariance; `None` when the joint fit held
    /// the mark.
    pub fn joint_mark(&self) -> Option<([f64; 3], Option<[f64; 2]>)> {
        let x = &self.methods.get("joint")?.outcome.x;
        let moved = x.mark_arm_m?;
        let sigma = x.sigma.as_ref().and_then(|s| s.mark_arm_m);
        let [f, r, d] = self.mark_lever_arm_m.unwrap_or_default();
        Some(([f + moved[0], r + moved[1], d], sigma))
    }
}

/// How far from no arm, in σ of its covariance, the arm the control points show must be
/// for the joint fit to be redone with the mark free: the two-dimensional 95 % (χ² with
/// two degrees of freedom). The check holds the fit's lag, which takes part of an arm
/// along the vehicle (a 1.5-m arm showed as 0.4–1.3 m), so it asks for the refit early.
pub const MARK_ARM_REFIT_SIGMA: f64 = 2.45;

/// How far from no arm, in σ of its covariance, the arm the refit estimates must be for
/// the refit to be the joint's result and a user to be told: the two-dimensional 3σ (χ²
/// with two degrees of freedom at 99.73 %). Below it, the fit that held the mark stands.
pub const MARK_ARM_SIGMA: f64 = 3.44;

/// What a user is told of a mark's lever arm the joint fit estimated (the log,
/// `disupt.md`, the campaign's note), or failed to, from the `configured` arm.
pub fn mark_arm_note(check: &MarkArmCheck, configured: Option<[f64; 3]>) -> Option<String> {
    let seen = "the control points' errors turn with the vehicle's heading at the stops: the \
                vehicle's mark is not where `[vehicle] mark_lever_arm_m` puts it";
    let [x, y, z] = configured.unwrap_or_default();
    match (&check.refit_error, &check.estimated) {
        (Some(e), _) if check.seen.distance_sigma > MARK_ARM_SIGMA => Some(format!(
            "{seen} (about {:+.2} m forward and {:+.2} m right of it, {:.1}σ); the joint fit \
             with the mark free failed ({e}), so the route keeps part of that error",
            check.seen.forward_m, check.seen.right_m, check.seen.distance_sigma
        )),
        (None, Some(a)) if check.refit => Some(format!(
            "{seen}: the joint fit estimates it {:+.2} ± {:.2} m forward and {:+.2} ± {:.2} m \
             right of it ({:.1}σ), at [{:.2}, {:.2}, {z}] m from the navigated point in the \
             IMU's axes; set the lever arm to that",
            a.forward_m,
            a.sigma_forward_m,
            a.right_m,
            a.sigma_right_m,
            a.distance_sigma,
            x + a.forward_m,
            y + a.right_m,
        )),
        (None, None) if check.seen.distance_sigma > MARK_ARM_SIGMA => Some(format!(
            "{seen} (about {:+.2} m forward and {:+.2} m right of it, {:.1}σ), which the joint \
             fit did not estimate (`joint_mark_arm = false`): the route keeps part of that \
             error",
            check.seen.forward_m, check.seen.right_m, check.seen.distance_sigma
        )),
        _ => None,
    }
}

/// [`mark_arm_note`] of a run's `disupt.json`.
pub fn joint_mark_arm_note(out: &DisuptOut) -> Option<String> {
    mark_arm_note(out.joint_mark_arm_check.as_ref()?, out.mark_lever_arm_m)
}

/// An odometer yaw boresight the joint fit held at zero, as its residuals show it
/// ([`disupt::JointFit::odo_yaw_seen`]), and whether the fit was redone with it free.
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct OdoYawCheck {
    /// The boresight the residuals show and its 1σ.
    #[serde(flatten)]
    pub seen: disupt::OdoYawSeen,
    /// Whether the joint fit was redone with the boresight free (seen beyond
    /// [`ODO_YAW_REFIT_Z`] σ): the joint's settings in `methods` are then that fit's.
    pub refit: bool,
    /// Why the refit is not used, when it failed (the joint's settings are then the
    /// boresight-free fit's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refit_error: Option<String>,
}

/// How many σ from zero a boresight the joint fit's residuals show must be for the fit to
/// be redone with it free. Over 40 runs without one (simulated runs with and without a
/// static start, loops, Kingston) it was at most 2.6σ; a 1.5° boresight showed 5.9–9.4σ.
pub const ODO_YAW_REFIT_Z: f64 = 3.0;

/// What a user is told of an odometer yaw boresight the joint fit's residuals show (the
/// log, `disupt.md`, the campaign's note), when beyond [`ODO_YAW_REFIT_Z`] σ.
pub fn odo_yaw_note(c: &OdoYawCheck) -> Option<String> {
    if !c.refit && c.refit_error.is_none() {
        return None;
    }
    let seen = format!(
        "the pitch and roll show an odometer yaw boresight of {:+.2}° ± {:.2}° ({:.1}σ), which \
         the control points cannot tell from the azimuth (an IMU turned on the vehicle, or a \
         control point off its survey)",
        c.seen.odo_yaw_deg,
        c.seen.sigma_deg,
        c.seen.z()
    );
    Some(match &c.refit_error {
        None => format!(
            "{seen}: the joint fit estimates it (as `joint_odo_yaw = true` does), else its \
             azimuth would take it whole"
        ),
        Some(e) => format!(
            "{seen}; the joint fit with it free failed ({e}), so the joint's azimuth takes it \
             whole"
        ),
    })
}

/// What `disupt.md` and the campaign's summary say of the odometer's failures the joint
/// fit bridged again at each lag it tried.
pub fn rebridged_note(b: &Rebridged) -> String {
    let left = match b.left {
        0 => String::new(),
        n => format!("; {n} left as the ingest bridged them"),
    };
    format!(
        "the joint fit bridged the odometer's failures again at each lag it tried: {} (at \
         its lag, the distance across one changed by {:+.2} m at most against the ingest's \
         bridge){left}",
        b.failures, b.largest_change_m
    )
}

/// The odometer lag of a method and its 1σ, s.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Lag {
    pub(super) lag_s: f64,
    pub(super) sigma_s: f64,
}

/// The settings `x` as reported, with their 1σ (`sigma`) and the lag.
pub(super) fn settings_out(x: &X, base: &NavSettings, sigma: Option<&X>, lag: Lag) -> SettingsOut {
    let base_scale = base.odo_scale;
    SettingsOut {
        azimuth_deg: x.azimuth_deg.rem_euclid(360.0),
        drift_rad_s: x.drift_deg_h.map(|d| d * DEG_PER_H),
        odo_scale: base_scale * (1.0 + x.odo_ppm * 1e-6),
        odo_yaw_deg: base.odo_yaw_rad.to_degrees() + x.odo_yaw_deg,
        odo_bias_mps: base.odo_bias_mps + x.odo_bias_mps,
        odo_lag_s: lag.lag_s,
        mark_arm_m: Some(x.mark_arm_m).filter(|a| *a != [0.0; 2]),
        sigma: sigma.map(|s| SigmaOut {
            azimuth_deg: s.azimuth_deg,
            drift_rad_s: s.drift_deg_h.map(|d| d * DEG_PER_H),
            odo_scale: base_scale * s.odo_ppm * 1e-6,
            odo_yaw_deg: s.odo_yaw_deg,
            odo_bias_mps: s.odo_bias_mps,
            odo_lag_s: lag.sigma_s,
            mark_arm_m: Some(s.mark_arm_m).filter(|a| *a != [0.0; 2]),
        }),
    }
}

/// A method's entry of `disupt.json`.
pub(super) fn method_out(
    r: &MethodResult,
    base: &NavSettings,
    lag: Lag,
    cps: Vec<Kryt2>,
) -> MethodOut {
    MethodOut {
        outcome: Outcome {
            x: settings_out(&r.x, base, r.sigma.as_ref(), lag),
            dx_m: r.dx_m,
            dy_m: r.dy_m,
            kryt1_rad: r.kryt1,
            control_points: cps,
        },
        steps: r.steps.clone(),
        evaluations: r.evaluations,
        holdout: None,
        lag_profile: None,
        rebridged: None,
        exclusion_error: None,
        refused_with_all_points: None,
    }
}

/// One method's table (the paper's Table 1 or 2), its 1σ and its hold-out.
fn table(name: &str, r: &MethodOut, bounds: &disupt::DisuptParams) -> String {
    let mut s = format!(
        "## {name}\n\n| step | moved | by | azpocz in | driftx in | drifty in | driftz in | azpopt | driftx opt | drifty opt | driftz opt | ΔX [m] | ΔY [m] | passes |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n"
    );
    for st in &r.steps {
        let d = |x: &X, i: usize| format!("{:.6e}", x.drift_deg_h[i] * DEG_PER_H);
        let _ = writeln!(
            s,
            "| {} | {:?} | {:?} | {:.4} | {} | {} | {} | {:.4} | {} | {} | {} | {:.1} | {:.1} | {} |",
            st.step,
            st.component,
            st.criterion,
            st.input.azimuth_deg,
            d(&st.input, 0),
            d(&st.input, 1),
            d(&st.input, 2),
            st.output.azimuth_deg,
            d(&st.output, 0),
            d(&st.output, 1),
            d(&st.output, 2),
            st.dx_m,
            st.dy_m,
            st.evaluations
        );
    }
    for st in r.steps.iter().filter(|st| !st.at_bound.is_empty()) {
        let names: Vec<&str> = st.at_bound.iter().map(|b| b.name_and_unit().0).collect();
        let _ = writeln!(
            s,
            "\nStep {}: {} stopped at the edge of the search's range (±{} from its input): \
             clipped, not found; the criterion still fell beyond it.",
            st.step,
            names.join(", "),
            st.at_bound
                .iter()
                .map(|&b| format!("{} {}", bounds.bound(b), b.name_and_unit().1))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    if let Some(sd) = &r.outcome.x.sigma {
        let per_h = |v: f64| v / DEG_PER_H;
        let _ = writeln!(
            s,
            "\n1σ: azimuth {:.3}°, drifts [{:.3}, {:.3}, {:.3}] °/h, odometer {:.0} ppm",
            sd.azimuth_deg,
            per_h(sd.drift_rad_s[0]),
            per_h(sd.drift_rad_s[1]),
            per_h(sd.drift_rad_s[2]),
            sd.odo_scale / r.outcome.x.odo_scale * 1e6
        );
        if sd.odo_yaw_deg > 0.0 {
            let _ = writeln!(
                s,
                "\nOdometer yaw boresight {:.3}° ± {:.3}°.",
                r.outcome.x.odo_yaw_deg, sd.odo_yaw_deg
            );
        }
        if sd.odo_bias_mps > 0.0 {
            let _ = writeln!(
                s,
                "\nOdometer speed bias {:.3} m/s ± {:.3} m/s.",
                r.outcome.x.odo_bias_mps, sd.odo_bias_mps
            );
        }
        if let (Some(a), Some(sa)) = (r.outcome.x.mark_arm_m, sd.mark_arm_m) {
            let _ = writeln!(
                s,
                "\nThe vehicle's mark {:+.2} m ± {:.2} m forward and {:+.2} m ± {:.2} m right of \
                 the configured lever arm.",
                a[0], sa[0], a[1], sa[1]
            );
        }
        if r.lag_profile.is_some() {
            let _ = writeln!(
                s,
                "\nOdometer lag {:.3} s ± {:.3} s (positive: it reports late).",
                r.outcome.x.odo_lag_s, sd.odo_lag_s
            );
        }
        if let Some(b) = &r.rebridged {
            let mut note = rebridged_note(b);
            note[..1].make_ascii_uppercase();
            let _ = writeln!(s, "\n{note}.");
        }
    }
    if let Some(h) = &r.holdout {
        let _ = writeln!(
            s,
            "\nHold-out (each control point left out of the fit in turn; σ: what the fit without \
             it predicts there):\n\n| point | ΔX [m] | ΔY [m] | σ north [m] | σ east [m] | error / σ |\n|---|---|---|---|---|---|"
        );
        let or_dash =
            |v: Option<f64>, digits: usize| v.map_or("–".to_owned(), |v| format!("{v:.digits$}"));
        for p in h {
            let _ = writeln!(
                s,
                "| {} | {:.2} | {:.2} | {} | {} | {}{} |",
                p.label(h),
                p.dx_m,
                p.dy_m,
                or_dash(p.sigma_north_m, 2),
                or_dash(p.sigma_east_m, 2),
                or_dash(p.error_sigma, 1),
                match (p.excluded, p.inconsistent) {
                    (true, _) => " ✗ left out of the fit",
                    (false, true) => " ✗",
                    (false, false) => "",
                }
            );
        }
        if let Some((median, max)) = disupt::holdout_median_max_m(h) {
            let _ = writeln!(s, "\nHold-out error: median {median:.2} m, max {max:.2} m.");
        }
        if let Some(note) = disupt::inconsistent_points_note(h) {
            let _ = writeln!(s, "\n{note}.");
        }
        if let Some(e) = &r.exclusion_error {
            let _ = writeln!(s, "\n{e}.");
        }
        if let Some(why) = &r.refused_with_all_points {
            let _ = writeln!(
                s,
                "\nWith every control point the fit was refused: {why}. Without the point \
                 left out it was not."
            );
        }
    }
    let _ = writeln!(s, "\n{} passes.\n", r.evaluations);
    s
}

/// `disupt.md`'s section on the corrected route's heights at the control points and the
/// odometer pitch boresight they show.
fn heights_table(fit: &disupt::OdoPitchFit) -> String {
    let mut s = String::from(
        "## Heights

",
    );
    let _ = writeln!(
        s,
        "{}
",
        odo_pitch_note(fit)
    );
    s += if fit.configured_deg == 0.0 {
        "| point | distance [m] | Δh without [m] | Δh [m] | Δh held out [m] |\n"
    } else {
        "| point | distance [m] | Δh configured [m] | Δh [m] | Δh held out [m] |\n"
    };
    s += "|---|---|---|---|---|\n";
    for p in &fit.points {
        let held = p
            .holdout_dh_m
            .map_or_else(|| "–".to_owned(), |h| format!("{h:.2}"));
        let _ = writeln!(
            s,
            "| {} | {:.0} | {:.2} | {:.2} | {held} |",
            p.id, p.distance_m, p.dh_before_m, p.dh_m
        );
    }
    s + "\n"
}

/// What the corrected route's heights showed, in a sentence.
pub fn odo_pitch_note(fit: &disupt::OdoPitchFit) -> String {
    let configured = fit.configured_deg;
    match &fit.refused {
        None => format!(
            "The control points' heights show the path {:.3}° {} the IMU's x (an odometer \
             pitch boresight{}): the corrected navigation is written with it",
            fit.odo_pitch_deg.abs(),
            if fit.odo_pitch_deg >= 0.0 {
                "above"
            } else {
                "below"
            },
            if configured == 0.0 {
                String::new()
            } else {
                format!(
                    "; configured {configured:.3}°, {:+.3}° from it",
                    fit.change_deg()
                )
            }
        ),
        Some(why) => format!(
            "The control points' heights were not fitted with an odometer pitch boresight \
             ({:.3}°): {why}{}",
            fit.odo_pitch_deg,
            if configured == 0.0 {
                String::new()
            } else {
                format!("; the corrected navigation keeps the configured {configured:.3}°")
            }
        ),
    }
}

/// `disupt.md`: the paper's tables per method (the steps a search left at the edge of its
/// range, `bounds`, said below them), then the errors before DISUPT.
pub(super) fn markdown(run: &str, out: &DisuptOut, bounds: &disupt::DisuptParams) -> String {
    let mut md = format!("# DISUPT: {run}\n\n");
    for (name, title) in [("oepi", "OEPI"), ("owpi", "OWPI"), ("joint", "JOINT")] {
        if let Some(o) = out.methods.get(name) {
            md += &table(title, o, bounds);
        } else if let Some(e) = out.skipped.get(name) {
            md += &format!("## {title}\n\nnot run: {e}\n\n");
        }
    }
    for (name, why) in &out.not_used {
        md += &format!(
            "Note: {} not used for the corrected navigation: {why}.\n\n",
            name.to_uppercase()
        );
    }
    if let Some(r) = &out.coarse_azimuth_refused {
        md += &format!("Note: {}.\n\n", super::coarse_refused_note(r));
    }
    if let Some(note) = out.joint_odo_yaw_check.as_ref().and_then(odo_yaw_note) {
        md += &format!("Note: {note}.\n\n");
    }
    if let Some(g) = &out.joint_gap_tilts {
        md += &format!("Note: {}.\n\n", gap_tilts_note(g));
    }
    if let Some(note) = joint_mark_arm_note(out) {
        md += &format!("Note: {note}.\n\n");
    }
    if let Some([x, y, z]) = out.mark_lever_arm_m {
        md += &format!(
            "Control points are compared with the vehicle's mark, {x:.2} m forward, {y:.2} m \
             right and {z:.2} m down of the navigated point in the IMU's axes \
             (`[vehicle] mark_lever_arm_m`); the corrected navigation is the navigated \
             point's.\n\n"
        );
    }
    if let Some(fit) = &out.odo_pitch {
        md += &heights_table(fit);
    }
    let (dx, dy) = (out.before.dx_m, out.before.dy_m);
    md + &format!(
        "Before DISUPT: ΔX = {dx:.1} m, ΔY = {dy:.1} m at the last control point, after {:.0} m.\n",
        out.distance_m
    )
}

/// What the joint fit did with a run's gaps, in words.
pub fn gap_tilts_note(g: &disupt::GapTiltSteps) -> String {
    let turns = if g.turn_steps > 0 {
        format!(
            "; {} turns of the route, {:.2} mrad of heading together by the last control \
             point",
            g.turn_steps, g.turn_end_sigma_mrad
        )
    } else {
        String::new()
    };
    format!(
        "the joint fit took what the fills of {} gaps (samples lost or replaced) may have \
         turned as unknowns ({} steps of tilt, σ up to {:.2} mrad each, {:.2} mrad together \
         by the run's end{turns}), so that it is not read as drift or azimuth",
        g.gaps, g.steps, g.largest_sigma_mrad, g.end_sigma_mrad
    )
}
