//! Parameters: built-in defaults, then a TOML config file (`--config`), then the run's own
//! `[params]` table in run.toml. Unknown keys and bad values are errors naming the file.
//!
//! ```toml
//! [derive]
//! epoch_s = 1.0
//! [derive.filter]
//! cutoff_hz = 0.3
//! [kalman]
//! r_rad = 1e-3
//! [disupt]
//! azimuth_bound_deg = 15.0
//! ```

use std::path::Path;

use anyhow::Context;
use serde::Deserialize;
use unz_formats::manifest::RunManifest;

use crate::flow::Params;

/// Reads a config file's table (empty without a file).
pub fn load(path: Option<&Path>) -> anyhow::Result<toml::Table> {
    let Some(path) = path else {
        return Ok(toml::Table::new());
    };
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let table: toml::Table = toml::from_str(&text).map_err(|e| {
        let line = e.span().map_or(0, |s| {
            text[..s.start.min(text.len())].lines().count().max(1)
        });
        anyhow::anyhow!(
            "line {line}: {} (in {})",
            e.message().trim(),
            path.display()
        )
    })?;
    // Checked now, so a bad config fails before any run starts.
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
    Params::deserialize(toml::Value::Table(table.clone()))
        .map_err(|e| anyhow::anyhow!("{}", e.message().trim()))
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
        // Round trip of the printed defaults.
        let shown: toml::Table = toml::from_str(&to_toml(&Params::default()).unwrap()).unwrap();
        assert_eq!(parse(&shown).unwrap(), Params::default());
    }
}
