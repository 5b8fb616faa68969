//! What a campaign's summary pools across its runs: the control points that disagree, the
//! vehicle's mark, the odometer's pitch and lag and the IMU's yaw on the vehicle
//! (`campaign.md`'s sections below the runs), and the settings they agree on
//! (`campaign-settings.toml`). One campaign's runs, or the runs of several shards'
//! output folders (`unz campaign merge`): the pools are the same either way.

use std::path::Path;

use unz_formats::manifest::RunManifest;

use crate::artifacts::{RunLayout, StageName, files};
use crate::campaign::read_report;
use crate::campaign_lag::{LagAcross, LagEstimate};
use crate::campaign_mark::{MarkAcross, MarkEstimate};
use crate::campaign_pitch::PitchAcross;
use crate::campaign_points::PointsAcross;
use crate::campaign_settings::PooledSettings;
use crate::campaign_yaw::{YawAcross, YawEstimate};
use crate::disupt_stage::DisuptOut;
use crate::flow::NavigateSummary;

/// The runs' pools, gathered run by run.
#[derive(Debug, Default)]
pub struct Pools {
    points: PointsAcross,
    marks: MarkAcross,
    pitches: PitchAcross,
    lags: LagAcross,
    yaws: YawAcross,
    /// The runs' own `[params]` (those that have one), by run name.
    runs_params: Vec<(String, toml::Table)>,
}

/// The pools' sections of `campaign.md` and the settings file's text (None when the runs
/// show no setting to change).
#[derive(Debug, Clone, PartialEq)]
pub struct PoolsText {
    /// The sections, each starting with its `## ` heading.
    pub markdown: String,
    /// `campaign-settings.toml`'s text.
    pub settings: Option<String>,
}

/// What the pools read of a run: its manifest (when readable), its `disupt.json` and its
/// `navigate.json` (when written and readable).
#[derive(Debug, Default)]
pub struct RunReports {
    /// The run's manifest.
    pub manifest: Option<RunManifest>,
    /// Its disupt stage's report.
    pub disupt: Option<DisuptOut>,
    /// Its navigate stage's report.
    pub navigate: Option<NavigateSummary>,
}

impl RunReports {
    /// The run `name`'s reports in the output folder `out`, and its manifest at
    /// `manifest`.
    pub fn read(out: &Path, name: &str, manifest: &Path) -> Self {
        let layout = RunLayout::new(out, name);
        Self {
            manifest: RunManifest::load(manifest).ok(),
            disupt: read_report(&layout.file(StageName::Disupt, files::DISUPT_REPORT)),
            navigate: read_report(&layout.file(StageName::Navigate, files::NAVIGATE_REPORT)),
        }
    }
}

impl Pools {
    /// Adds the run `name` with its reports.
    pub fn add(&mut self, name: &str, reports: &RunReports) {
        let manifest = reports.manifest.as_ref();
        if let Some(params) = manifest.and_then(|m| m.params.clone()) {
            self.runs_params.push((name.to_owned(), params));
        }
        let Some(d) = &reports.disupt else { return };
        let nav = reports.navigate.as_ref();
        // The runs' control points, by their surveyed positions.
        if let Some(h) = d.methods.get("joint").and_then(|j| j.holdout.as_ref())
            && let Some(m) = manifest
        {
            self.points.add(&m.control_points, h);
        }
        if let Some(fit) = &d.odo_pitch {
            self.pitches.add(name, fit);
        }
        if let Some(lag) = lag_estimate(d) {
            self.lags.add(name, lag);
        }
        if let Some(yaw) = yaw_estimate(d, nav) {
            self.yaws.add(name, yaw);
        }
        let estimate = mark_estimate(d);
        self.marks.add(
            name,
            d.joint_mark_arm_check.is_some() || estimate.is_some(),
            estimate,
        );
    }

    /// The sections and the settings file's text: `config` (the campaign's) with the
    /// settings the runs agree on; `settings_file` is the name the sections give it.
    pub fn finish(&self, config: &toml::Table, settings_file: &str) -> anyhow::Result<PoolsText> {
        let mut markdown: String = [
            self.points.markdown(),
            self.marks.markdown(),
            self.pitches.markdown(),
            self.lags.markdown(),
            self.yaws.markdown(),
        ]
        .into_iter()
        .flatten()
        .collect();
        let settings = PooledSettings {
            odo_pitch_deg: self.pitches.setting(),
            odo_time_offset_s: self.lags.setting(),
            imu_mounting_yaw_deg: self.yaws.setting(),
        };
        let settings = crate::campaign_settings::text(config, &settings, &self.runs_params)?;
        if settings.is_some() {
            markdown += &format!(
                "\n## The settings to configure\n\nThe settings above that differ from what \
                 the runs were configured with, and that the runs agree on, are in \
                 `{settings_file}` in this folder, with the campaign's config: if the runs \
                 share one vehicle, its installation and its odometer's logger, run the \
                 campaign again with `--config` that file.\n"
            );
        }
        Ok(PoolsText { markdown, settings })
    }
}

/// The vehicle's mark from the navigated point (the configured arm and the joint fit's
/// move of it), when the joint fit estimated it.
pub(crate) fn mark_estimate(d: &DisuptOut) -> Option<MarkEstimate> {
    let ([f, r, z], s) = d.joint_mark()?;
    let s = s?;
    Some(MarkEstimate {
        forward_m: (f, s[0]),
        right_m: (r, s[1]),
        down_m: z,
    })
}

/// The odometer's lag in all (the configured offset's and the joint's), when the joint
/// fit estimated it.
fn lag_estimate(d: &DisuptOut) -> Option<LagEstimate> {
    let x = &d.methods.get("joint")?.outcome.x;
    Some(LagEstimate {
        lag_s: x.odo_lag_s - d.odo_time_offset_s,
        sigma_s: x.sigma.as_ref()?.odo_lag_s,
        offset_s: d.odo_time_offset_s,
        at_bound: d.joint_odo_lag_at_bound_s.is_some(),
    })
}

/// The odometer yaw boresight the joint fit estimated, else the one its residuals showed
/// below the refit's threshold, with the mounting the run was ingested with (`nav`'s).
fn yaw_estimate(d: &DisuptOut, nav: Option<&NavigateSummary>) -> Option<YawEstimate> {
    let x = &d.methods.get("joint")?.outcome.x;
    let estimated = x.sigma.as_ref().map(|s| s.odo_yaw_deg).filter(|s| *s > 0.0);
    let (boresight_deg, sigma_deg) = match (estimated, &d.joint_odo_yaw_check) {
        (Some(s), _) => (x.odo_yaw_deg, s),
        (None, Some(check)) => (check.seen.odo_yaw_deg, check.seen.sigma_deg),
        (None, None) => return None,
    };
    Some(YawEstimate {
        boresight_deg,
        sigma_deg,
        estimated: estimated.is_some(),
        mounting_deg: nav
            .and_then(|n| n.imu_axes.as_ref()?.named_mounting_deg)
            .unwrap_or_default(),
    })
}

/// The settings file that goes with a merged summary `into` (`all.parquet` →
/// `all-settings.toml`), and its markdown (`all.md`).
pub fn merged_names(into: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let stem = into
        .file_stem()
        .map_or_else(|| "campaign".into(), |s| s.to_string_lossy().into_owned());
    (
        into.with_file_name(format!("{stem}-settings.toml")),
        into.with_file_name(format!("{stem}.md")),
    )
}
