//! `OUT/campaign-settings.toml`: the campaign's config with the vehicle's settings its runs
//! pooled and agree on (`campaign.md`'s sections on the odometer's pitch, the odometer's
//! lag and the IMU's yaw on the vehicle) where they differ from what the runs were
//! configured with beyond [`CHANGE_SIGMA`], ready for the next pass:
//! `unz run CAMPAIGN --out OUT --config OUT/campaign-settings.toml`.
//!
//! Nothing applies it: whether the runs share one vehicle, one installation and one
//! odometer logger is the user's to say, and each run's stages depend on its own inputs
//! and parameters only. The file is a config like any other, read by [`crate::config`]:
//! it is checked through it before it is written, and a setting it would refuse (out of
//! its range) is left out and said in the file's header.

use std::fmt::Write as _;
use std::path::Path;

use unz_formats::atomic::write_atomic;

use crate::config;

/// The file's name in the output folder.
pub const FILE: &str = "campaign-settings.toml";

/// How many runs that keep their own setting the header names (the rest are counted).
const NAMED_RUNS: usize = 10;

/// A setting the campaign's runs pooled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pooled {
    /// The value to configure, rounded to the decimals `campaign.md` writes it with.
    pub value: f64,
    /// Its 1σ, in the setting's unit.
    pub sigma: f64,
    /// How many runs it pools.
    pub runs: usize,
}

/// How many σ from the pooled value a run's configured value must lie for the pool to be
/// a change to configure: within it, the runs show nothing the configuration lacks.
pub const CHANGE_SIGMA: f64 = 3.0;

impl Pooled {
    /// `value` rounded to `decimals` as `campaign.md` writes it, with its σ and runs.
    pub fn rounded(value: f64, sigma: f64, runs: usize, decimals: usize) -> Self {
        let value = format!("{value:.decimals$}").parse().unwrap_or(value);
        Self { value, sigma, runs }
    }

    /// Self, when a run's `configured` value lies beyond [`CHANGE_SIGMA`] from it.
    pub fn if_a_change(self, mut configured: impl Iterator<Item = f64>) -> Option<Self> {
        configured
            .any(|c| (c - self.value).abs() > CHANGE_SIGMA * self.sigma)
            .then_some(self)
    }
}

/// The vehicle's settings a campaign's runs pooled and agree on, where they differ from
/// what the runs were configured with.
#[derive(Debug, Default, Clone, Copy, PartialEq)]
pub struct PooledSettings {
    /// `[vehicle] odo_pitch_deg`: the odometer's pitch boresight, degrees.
    pub odo_pitch_deg: Option<Pooled>,
    /// `[derive] odo_time_offset_s`: the odometer's lag, negated, s.
    pub odo_time_offset_s: Option<Pooled>,
    /// `[vehicle] imu_mounting_deg`'s yaw: the IMU's yaw on the vehicle, degrees (its roll
    /// and pitch are the campaign config's).
    pub imu_mounting_yaw_deg: Option<Pooled>,
}

/// One of the settings, where it goes in a config.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Key {
    OdoPitch,
    OdoTimeOffset,
    ImuMountingYaw,
}

impl Key {
    const ALL: [Key; 3] = [Key::OdoPitch, Key::OdoTimeOffset, Key::ImuMountingYaw];

    /// Its section and key.
    fn path(self) -> (&'static str, &'static str) {
        match self {
            Key::OdoPitch => ("vehicle", "odo_pitch_deg"),
            Key::OdoTimeOffset => ("derive", "odo_time_offset_s"),
            Key::ImuMountingYaw => ("vehicle", "imu_mounting_deg"),
        }
    }

    /// How the header names it, with its unit.
    fn said(self, p: &Pooled) -> String {
        let (section, key) = self.path();
        match self {
            Key::OdoPitch => format!("[{section}] {key} = {}: ± {:.3}°", p.value, p.sigma),
            Key::OdoTimeOffset => format!("[{section}] {key} = {}: ± {:.3} s", p.value, p.sigma),
            Key::ImuMountingYaw => {
                format!("[{section}] {key}'s yaw = {}: ± {:.2}°", p.value, p.sigma)
            }
        }
    }

    fn of(self, s: &PooledSettings) -> Option<Pooled> {
        match self {
            Key::OdoPitch => s.odo_pitch_deg,
            Key::OdoTimeOffset => s.odo_time_offset_s,
            Key::ImuMountingYaw => s.imu_mounting_yaw_deg,
        }
    }

    /// Whether a run's `[params]` table sets it (and so keeps its own).
    fn set_in(self, params: &toml::Table) -> bool {
        let (section, key) = self.path();
        params
            .get(section)
            .and_then(|s| s.as_table())
            .is_some_and(|s| s.contains_key(key))
    }
}

/// `config` with `p`'s value for `key` (the yaw in the config's mounting).
fn with(config: &toml::Table, key: Key, p: &Pooled) -> anyhow::Result<toml::Table> {
    let value = match key {
        Key::OdoPitch | Key::OdoTimeOffset => toml::Value::Float(p.value),
        Key::ImuMountingYaw => {
            let mut mounting = config::effective(config, None)?.vehicle.imu_mounting_deg;
            mounting[2] = p.value;
            toml::Value::Array(mounting.into_iter().map(toml::Value::Float).collect())
        }
    };
    let (section, name) = key.path();
    let mut table = config.clone();
    let entry = table
        .entry(section)
        .or_insert_with(|| toml::Value::Table(toml::Table::new()));
    let toml::Value::Table(section_table) = entry else {
        anyhow::bail!("the config's {section} is not a table");
    };
    section_table.insert(name.to_owned(), value);
    config::effective(&table, None)?;
    Ok(table)
}

/// The file's text: `config` with `settings` (each checked as the config's parser
/// checks it), after a header that says what was pooled and which runs keep their own
/// (`runs_params`: each run's name and `[params]`). None when nothing was pooled.
pub fn text(
    config: &toml::Table,
    settings: &PooledSettings,
    runs_params: &[(String, toml::Table)],
) -> anyhow::Result<Option<String>> {
    if Key::ALL.iter().all(|k| k.of(settings).is_none()) {
        return Ok(None);
    }
    let mut table = config.clone();
    let mut head = String::from(
        "# The vehicle's settings this campaign's runs pooled and agree on, where they differ\n\
         # from what the runs were configured with (campaign.md says how), with the campaign's\n\
         # config. If the runs share one vehicle, its installation and its odometer's logger,\n\
         # run the campaign again with `--config` this file.\n",
    );
    for key in Key::ALL {
        let Some(p) = key.of(settings) else { continue };
        let _ = write!(head, "#   {}, from {} runs", key.said(&p), p.runs);
        match with(&table, key, &p) {
            Ok(t) => table = t,
            Err(e) => {
                let _ = write!(head, " (left out: {e:#})");
            }
        }
        head.push('\n');
        let keeping: Vec<&str> = runs_params
            .iter()
            .filter(|(_, params)| key.set_in(params))
            .map(|(name, _)| name.as_str())
            .collect();
        if !keeping.is_empty() {
            let named = keeping.len().min(NAMED_RUNS);
            let _ = writeln!(
                head,
                "#     kept by the runs that set it in their own [params]: {}{}",
                keeping[..named].join(", "),
                match keeping.len() - named {
                    0 => String::new(),
                    more => format!(" and {more} more"),
                }
            );
        }
    }
    Ok(Some(format!("{head}\n{}", toml::to_string(&table)?)))
}

/// Writes the file at `path` (atomically), or removes an earlier campaign's when there
/// is nothing to write (a stale file would advise what these runs no longer show).
pub fn write(path: &Path, text: Option<&str>) -> anyhow::Result<()> {
    match text {
        Some(t) => Ok(write_atomic(path, t.as_bytes())?),
        None => match std::fs::remove_file(path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                Err(anyhow::anyhow!("cannot remove {}: {e}", path.display()))
            }
            _ => Ok(()),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pooled(value: f64) -> Option<Pooled> {
        Some(Pooled {
            value,
            sigma: 0.05,
            runs: 3,
        })
    }

    /// The file is a config the parser reads back into the pooled values, on top of the
    /// campaign's (its mounting's roll and pitch kept, its other keys kept).
    #[test]
    fn the_settings_are_a_config_with_the_pooled_values() {
        let config: toml::Table = toml::from_str(
            "[vehicle]\nimu_mounting_deg = [0.5, -1.0, 0.0]\n[disupt]\nazimuth_bound_deg = 20.0\n",
        )
        .unwrap();
        let settings = PooledSettings {
            odo_pitch_deg: pooled(1.498),
            odo_time_offset_s: pooled(-0.38),
            imu_mounting_yaw_deg: pooled(-0.6),
        };
        let mut own = toml::Table::new();
        own.insert(
            "derive".into(),
            toml::Value::Table(toml::from_str("odo_time_offset_s = 0.1").unwrap()),
        );
        let runs = [
            ("r1".to_owned(), toml::Table::new()),
            ("r2".to_owned(), own),
        ];
        let text = text(&config, &settings, &runs).unwrap().unwrap();
        let dir = tempfile::tempdir().unwrap();
        write(&dir.path().join(FILE), Some(&text)).unwrap();
        let read = config::load(Some(&dir.path().join(FILE))).unwrap();
        let p = config::effective(&read, None).unwrap();
        assert_eq!(p.vehicle.odo_pitch_deg, 1.498);
        assert_eq!(p.derive.odo_time_offset_s, -0.38);
        assert_eq!(p.vehicle.imu_mounting_deg, [0.5, -1.0, -0.6]);
        assert_eq!(p.disupt.azimuth_bound_deg, 20.0);
        assert!(
            text.contains("[vehicle] odo_pitch_deg = 1.498: ± 0.050°, from 3 runs"),
            "{text}"
        );
        assert!(text.contains("their own [params]: r2\n"), "{text}");
        assert_eq!(text.matches("own [params]").count(), 1, "{text}");
        // Hundreds of runs keeping their own: ten named, the rest counted.
        let many: Vec<(String, toml::Table)> = (0..25)
            .map(|i| (format!("r{i:02}"), runs[1].1.clone()))
            .collect();
        let text_many = super::text(&config, &settings, &many).unwrap().unwrap();
        assert!(
            text_many.contains(": r00, r01, r02, r03, r04, r05, r06, r07, r08, r09 and 15 more\n"),
            "{text_many}"
        );
        // Nothing pooled: no file, and an earlier one goes.
        assert_eq!(text_of(&PooledSettings::default()), None);
        write(&dir.path().join(FILE), None).unwrap();
        assert!(!dir.path().join(FILE).exists());
        write(&dir.path().join(FILE), None).unwrap();
    }

    fn text_of(s: &PooledSettings) -> Option<String> {
        text(&toml::Table::new(), s, &[]).unwrap()
    }

    /// A value the config's parser refuses is left out and said; the others stay.
    #[test]
    fn a_setting_out_of_its_range_is_left_out_and_said() {
        let settings = PooledSettings {
            odo_pitch_deg: pooled(31.0),
            odo_time_offset_s: pooled(0.4),
            ..PooledSettings::default()
        };
        let text = text_of(&settings).unwrap();
        assert!(
            text.contains("(left out: vehicle.odo_pitch_deg = 31 is outside"),
            "{text}"
        );
        let p = config::effective(&toml::from_str(&text).unwrap(), None).unwrap();
        assert_eq!(
            (p.vehicle.odo_pitch_deg, p.derive.odo_time_offset_s),
            (0.0, 0.4)
        );
    }
}
