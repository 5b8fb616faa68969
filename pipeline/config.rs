//! Parameters: built-in defaults, then a TOML config file (`--config`), then the run's own
//! `[params]` table in run.toml. Unknown keys and bad values are errors naming the file.
//!
//! ```toml
//! [ingest]
//! raw_mcap_compression = "zstd"
//! [derive]
//! epoch_s = 1.0
//! [derive.filter]
//! cutoff_hz = 0.3
//! [kalman]
//! r_rad = 1e-3
//! [disupt]
//! azimuth_bound_deg = 15.0
//! [export]
//! mcap_compression = "zstd"
//! ```

use std::path::Path;

use anyhow::Context;
use serde::Deserialize;
use unz_formats::manifest::RunManifest;
use unz_stages::derive::ODO_TIME_OFFSET_RANGE_S;

use crate::flow::Params;
use crate::flow::case::MARK_LEVER_ARM_MAX_M;

/// Reads a config file's table (empty without a file).
pub fn load(path: Option<&Path>) -> anyhow::Result<toml::Table> {
    let Some(path) = path else {
        return Ok(toml::Table::new());
    };
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let at_line = |e: toml::de::Error| {
        let line = e.span().map_or(0, |s| {
            text[..s.start.min(text.len())].lines().count().max(1)
        });
        anyhow::anyhow!(
            "line {line}: {} (in {})",
            e.message().trim(),
            path.display()
        )
    };
    let table: toml::Table = toml::from_str(&text).map_err(at_line)?;
    // Checked now, so a bad config fails before any run starts: a key of the wrong shape
    // by its line in the file, a value out of its range by its name.
    toml::from_str::<Params>(&text).map_err(at_line)?;
    parse(&table).with_context(|| format!("in {}", path.display()))?;
    Ok(table)
}

/// `over` merged into `base`, table by table.
fn merge(base: &mut toml::Table, over: &toml::Table) {
    for (k, v) in over {
        match (base.get_mut(k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge(b, o),
            _ => {
                base.insert(k.clone(), v.clone());
            }
        }
    }
}

fn parse(table: &toml::Table) -> anyhow::Result<Params> {
    let params =
        Params::deserialize(toml::Value::Table(table.clone())).map_err(|e| {
            match where_in(table) {
                Some(at) => anyhow::anyhow!("{at}: {}", e.message().trim()),
                None => anyhow::anyhow!("{}", e.message().trim()),
            }
        })?;
    validate(&params)?;
    Ok(params)
}

/// The key a table fails to deserialize at, as `[section] key = value`: the table's
/// values carry no position, so it is written out and read again, whose error has a
/// span into that text.
fn where_in(table: &toml::Table) -> Option<String> {
    let text = toml::to_string(table).ok()?;
    let span = toml::from_str::<Params>(&text).err()?.span()?;
    let before = text.get(..span.start)?;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let line = text[line_start..].lines().next()?.trim();
    let section = before[..line_start]
        .lines()
        .rev()
        .find(|l| l.starts_with('['))
        .unwrap_or("");
    Some(format!("{section} {line}").trim().to_owned())
}

/// Every parameter within its physical range: a value outside (NaN, ∞, 1e300…) would
/// run to non-finite outputs under an "ok" status.
pub fn validate(p: &Params) -> anyhow::Result<()> {
    let d = &p.derive;
    let (a, k, m) = (&p.align, &p.kalman, &p.disupt);
    let checks: [(&str, f64, f64, f64); 18] = [
        ("derive.filter.block_s", d.filter.block_s, 1e-4, 10.0),
        ("derive.filter.cutoff_hz", d.filter.cutoff_hz, 1e-3, 50.0),
        ("derive.epoch_s", d.epoch_s, 1e-3, 3600.0),
        (
            "derive.odo_time_offset_s",
            d.odo_time_offset_s,
            -ODO_TIME_OFFSET_RANGE_S,
            ODO_TIME_OFFSET_RANGE_S,
        ),
        ("derive.gate_long_mps2", d.gate_long_mps2, 1e-3, 100.0),
        ("derive.gate_lat_mps2", d.gate_lat_mps2, 1e-3, 100.0),
        ("derive.max_gap_s", d.max_gap_s, 1e-3, 86_400.0),
        ("align.drift_sigma_rad_s", a.drift_sigma_rad_s, 0.0, 1e-2),
        ("align.arw_rad_sqrt_s", a.arw_rad_sqrt_s, 0.0, 1e-2),
        ("kalman.r_rad", k.r_rad, 1e-9, 1.0),
        (
            "kalman.rate_walk_rad_s_sqrt_s",
            k.rate_walk_rad_s_sqrt_s,
            0.0,
            1.0,
        ),
        ("disupt.azimuth_bound_deg", m.azimuth_bound_deg, 1e-3, 180.0),
        (
            "disupt.drift_bound_deg_h",
            m.drift_bound_deg_h,
            1e-3,
            1000.0,
        ),
        ("disupt.attitude_sigma_rad", m.attitude_sigma_rad, 1e-9, 1.0),
        ("disupt.position_sigma_m", m.position_sigma_m, 1e-6, 1e5),
        ("disupt.odo_lag_bound_s", m.odo_lag_bound_s, 1e-3, 5.0),
        (
            "disupt.odo_scale_bound_ppm",
            m.odo_scale_bound_ppm,
            1.0,
            1e6,
        ),
        (
            "derive.filter.cutoff_hz × block_s",
            d.filter.cutoff_hz * d.filter.block_s,
            0.0,
            0.5,
        ),
    ];
    let arm = p.vehicle.mark_lever_arm_m;
    let arm_checks = [
        ("vehicle.mark_lever_arm_m[0]", arm[0]),
        ("vehicle.mark_lever_arm_m[1]", arm[1]),
        ("vehicle.mark_lever_arm_m[2]", arm[2]),
    ]
    .map(|(name, v)| (name, v, -MARK_LEVER_ARM_MAX_M, MARK_LEVER_ARM_MAX_M));
    let mount = p.vehicle.imu_mounting_deg;
    let range = unz_stages::imu_mounting::MOUNTING_RANGE_DEG;
    let mount_checks = [
        ("vehicle.imu_mounting_deg[0] (roll)", mount[0], range[0]),
        ("vehicle.imu_mounting_deg[1] (pitch)", mount[1], range[1]),
        ("vehicle.imu_mounting_deg[2] (yaw)", mount[2], range[2]),
    ]
    .map(|(name, v, max)| (name, v, -max, max));
    let pitch_max = unz_stages::disupt::MAX_AGREED_ODO_PITCH_DEG;
    let pitch_check = (
        "vehicle.odo_pitch_deg",
        p.vehicle.odo_pitch_deg,
        -pitch_max,
        pitch_max,
    );
    for (name, v, lo, hi) in checks
        .into_iter()
        .chain(arm_checks)
        .chain(mount_checks)
        .chain([pitch_check])
    {
        if !(v.is_finite() && (lo..=hi).contains(&v)) {
            anyhow::bail!("{name} = {} is outside [{lo}, {hi}]", shown(v));
        }
    }
    Ok(())
}

/// A number from untrusted input for a message (a parameter's value, a control point's
/// time): as Rust writes it, or in exponent form when that would run to many digits
/// (`1e300`, `1e-30`).
pub(crate) fn shown(v: f64) -> String {
    if v == 0.0 || !v.is_finite() || (1e-6..1e15).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// The effective parameters of a run: defaults, `config`, then the run's `[params]`.
pub fn for_run(config: &toml::Table, manifest: &RunManifest) -> anyhow::Result<Params> {
    effective(config, manifest.params.as_ref())
        .with_context(|| format!("[params] of {}", manifest.path.display()))
}

/// Defaults, then `config`, then `run_params`.
pub fn effective(config: &toml::Table, run_params: Option<&toml::Table>) -> anyhow::Result<Params> {
    let mut table = config.clone();
    if let Some(p) = run_params {
        merge(&mut table, p);
    }
    parse(&table)
}

/// The parameters as TOML.
pub fn to_toml(params: &Params) -> anyhow::Result<String> {
    Ok(toml::to_string_pretty(params)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layers_merge_and_unknown_keys_fail() {
        let config: toml::Table =
            toml::from_str("[derive.filter]\ncutoff_hz = 0.5\n[kalman]\nr_rad = 2e-3\n").unwrap();
        let text = "name = \"r\"\nraw = \"r.unz\"\nformat = \"unz-binary\"\n[site]\nlatitude_deg = 1.0\nlongitude_deg = 2.0\nheight_m = 3.0\n[params.kalman]\nr_rad = 5e-3\n";
        let m = RunManifest::parse(text, Path::new("/c/r/run.toml")).unwrap();
        let p = for_run(&config, &m).unwrap();
        assert_eq!(p.derive.filter.cutoff_hz, 0.5);
        assert_eq!(p.kalman.r_rad, 5e-3);
        assert_eq!(
            p.derive.filter.block_s,
            Params::default().derive.filter.block_s
        );
        let bad: toml::Table = toml::from_str("[kalman]\nr = 1\n").unwrap();
        assert!(for_run(&bad, &m).is_err());
        // Values outside their physical range are refused by name (hostile archives).
        for (text, name) in [
            (
                "[disupt]\nazimuth_bound_deg = 1e300\n",
                "disupt.azimuth_bound_deg = 1e300 is outside",
            ),
            (
                "[derive.filter]\ncutoff_hz = nan\n",
                "derive.filter.cutoff_hz",
            ),
            ("[derive.filter]\ncutoff_hz = 10.0\n", "cutoff_hz × block_s"),
            ("[kalman]\nr_rad = -1.0\n", "kalman.r_rad"),
            (
                "[vehicle]\nmark_lever_arm_m = [1.0, 1e300, 0.0]\n",
                "vehicle.mark_lever_arm_m[1] = 1e300 is outside",
            ),
            (
                "[vehicle]\nmark_lever_arm_m = [1.0, 0.0, nan]\n",
                "vehicle.mark_lever_arm_m[2]",
            ),
            (
                "[vehicle]\nmark_lever_arm_m = [1.0, 0.0]\n",
                "mark_lever_arm_m",
            ),
            (
                "[vehicle]\nimu_mounting_deg = [0.0, 95.0, 0.0]\n",
                "vehicle.imu_mounting_deg[1] (pitch) = 95 is outside [-90, 90]",
            ),
            (
                "[vehicle]\nodo_pitch_deg = 31.0\n",
                "vehicle.odo_pitch_deg = 31 is outside [-30, 30]",
            ),
            (
                "[vehicle]\nimu_mounting_deg = [nan, 0.0, 0.0]\n",
                "vehicle.imu_mounting_deg[0] (roll)",
            ),
        ] {
            let t: toml::Table = toml::from_str(text).unwrap();
            let e = format!("{:#}", effective(&t, None).unwrap_err());
            assert!(e.contains(name), "{text}: {e}");
        }
        // A run's own vehicle over the campaign's.
        let t: toml::Table =
            toml::from_str("[vehicle]\nmark_lever_arm_m = [1.5, -1, 0.25]\n").unwrap();
        assert_eq!(
            effective(&t, None).unwrap().vehicle.mark_lever_arm_m,
            [1.5, -1.0, 0.25]
        );
        // Round trip of the printed defaults.
        let shown: toml::Table = toml::from_str(&to_toml(&Params::default()).unwrap()).unwrap();
        assert_eq!(parse(&shown).unwrap(), Params::default());
    }
}
