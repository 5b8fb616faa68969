//! The run manifest, `run.toml` (§2 and §3 of the raw-format spec).
//!
//! Parsing is strict: unknown keys, missing fields and bad values are errors naming the
//! line. Every path a manifest names is resolved inside the manifest's folder; a path
//! that would leave it (absolute, `..`, or a symlink pointing out) is an error.

use std::path::{Component, Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use crate::error::{FileError, FormatError};

/// Longest run name accepted.
pub const MAX_NAME_LEN: usize = 128;
/// Largest manifest read (a manifest is a few hundred bytes; this bounds allocation).
pub const MAX_MANIFEST_BYTES: u64 = 1 << 20;

/// Format of the raw log.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
pub enum LogFormat {
    /// The binary UNZ log (§1).
    #[serde(rename = "unz-binary")]
    UnzBinary,
    /// The KF-GINS IMU text format (§3).
    #[serde(rename = "kf-gins")]
    KfGins,
}

/// What the separate odometer file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum OdometerKind {
    /// Speed, m/s.
    SpeedMps,
    /// Cumulative travelled distance, m.
    DistanceM,
    /// Speed, km/h (as OBD-II gives it): read as m/s, divided by 3.6.
    SpeedKmh,
}

impl OdometerKind {
    /// Whether the file holds speeds (integrated into distance), not distances.
    pub fn is_speed(self) -> bool {
        self != Self::DistanceM
    }

    /// The unit of the file's values.
    pub fn unit(self) -> &'static str {
        match self {
            Self::SpeedMps => "m/s",
            Self::SpeedKmh => "km/h",
            Self::DistanceM => "m",
        }
    }

    /// The file's value in SI units (m/s or m).
    pub fn si(self, value: f64) -> f64 {
        match self {
            Self::SpeedKmh => value / 3.6,
            Self::SpeedMps | Self::DistanceM => value,
        }
    }

    /// An SI value (m/s or m) as the file writes it, with its unit: "100 km/h" of
    /// 27.78 m/s (to a millionth: the file's own digits, not the division's residue); in
    /// m/s or m the value as it is.
    pub fn as_written(self, si: f64) -> String {
        match self {
            Self::SpeedKmh => {
                let text = format!("{:.6}", si * 3.6);
                let trimmed = text.trim_end_matches('0').trim_end_matches('.');
                format!("{trimmed} km/h")
            }
            Self::SpeedMps | Self::DistanceM => format!("{si} {}", self.unit()),
        }
    }
}

/// A geodetic position on WGS-84.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Geodetic {
    /// Latitude, degrees.
    pub latitude_deg: f64,
    /// Longitude, degrees.
    pub longitude_deg: f64,
    /// Ellipsoidal height, m.
    pub height_m: f64,
}

/// Initial settings given by the manifest.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct Initial {
    /// azpocz: heading from the pre-run alignment, degrees clockwise from true north.
    pub azimuth_deg: Option<f64>,
    /// Initial pitch, degrees (default: levelled).
    pub pitch_deg: Option<f64>,
    /// Initial roll, degrees (default: levelled).
    pub roll_deg: Option<f64>,
    /// Length of the initial stationary period, s (0: none, logging began in motion).
    pub static_s: Option<f64>,
    /// Initial gyro drift guess (x, y, z body), rad/s.
    pub drift_rad_s: Option<[f64; 3]>,
}

/// The odometer section.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct Odometer {
    /// Metres per pulse, overriding the raw header's `odo_lsb_m`.
    pub scale_m_per_pulse: Option<f64>,
    /// Separate odometer file (text logs), resolved inside the run folder.
    pub file: Option<PathBuf>,
    /// What the odometer file holds.
    pub kind: Option<OdometerKind>,
    /// A speed odometer's floor, m/s: readings at or below it in magnitude are read as 0 (a
    /// speed sensor's noise at rest; [`crate::speed_floor`]). Speeds only, up to
    /// [`crate::speed_floor::SPEED_FLOOR_MAX_MPS`].
    pub speed_floor_mps: Option<f64>,
    /// The column of the odometer file's value, 1-based (the time is the first), in a file
    /// of more columns than `t_s value` (an OBD-II logger's CSV); `None`: two columns, or
    /// the column named by [`Self::value_header`].
    pub value_column: Option<usize>,
    /// The odometer file's value's column named as the file's header line names it
    /// (`value_column` written as a name: `value_column = "speed_mps"`), found when the
    /// file is read.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub value_header: Option<String>,
}

impl Odometer {
    /// The value's column as the manifest names it, for a message: "column 3", "column
    /// \"speed_mps\"" (column 2, a `t_s value` file's, when none is named).
    pub fn value_column_said(&self) -> String {
        match (&self.value_header, self.value_column) {
            (Some(name), _) => format!("column {name:?}"),
            (None, column) => format!("column {}", column.unwrap_or(2)),
        }
    }
}

/// Longest header name `[odometer] value_column` may give, characters.
pub const MAX_VALUE_HEADER_CHARS: usize = 128;

/// A surveyed control point visited at a stop.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ControlPoint {
    /// Matched to control-point mark records.
    pub id: u32,
    /// Surveyed position.
    pub position: Geodetic,
    /// Time of the stop in the log's time base, s (for logs without a mark).
    pub t_s: Option<f64>,
}

/// A validated run manifest with its paths resolved.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct RunManifest {
    /// The manifest file.
    pub path: PathBuf,
    /// Run name: the run's output folder.
    pub name: String,
    /// Raw log, resolved inside the run folder.
    pub raw: PathBuf,
    /// Raw log format.
    pub format: LogFormat,
    /// Position at the start of the run.
    pub site: Geodetic,
    /// Initial settings.
    pub initial: Initial,
    /// Odometer settings.
    pub odometer: Odometer,
    /// Control points, in manifest order.
    pub control_points: Vec<ControlPoint>,
    /// Per-run parameter overrides (`[params]`), checked by the pipeline.
    pub params: Option<toml::Table>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawManifest {
    name: Spanned<String>,
    raw: Spanned<String>,
    format: LogFormat,
    site: RawSite,
    #[serde(default)]
    initial: RawInitial,
    #[serde(default)]
    odometer: RawOdometer,
    #[serde(default)]
    control_point: Vec<RawControlPoint>,
    params: Option<toml::Table>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSite {
    latitude_deg: Spanned<f64>,
    longitude_deg: Spanned<f64>,
    height_m: Spanned<f64>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawInitial {
    azimuth_deg: Option<Spanned<f64>>,
    pitch_deg: Option<Spanned<f64>>,
    roll_deg: Option<Spanned<f64>>,
    static_s: Option<Spanned<f64>>,
    drift_rad_s: Option<Spanned<[f64; 3]>>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawOdometer {
    scale_m_per_pulse: Option<Spanned<f64>>,
    file: Option<Spanned<String>>,
    kind: Option<OdometerKind>,
    speed_floor_mps: Option<Spanned<f64>>,
    value_column: Option<Spanned<RawValueColumn>>,
}

/// `[odometer] value_column` as written: a column's number, or its name on the file's
/// header line.
enum RawValueColumn {
    Number(i64),
    Name(String),
}

impl<'de> Deserialize<'de> for RawValueColumn {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Column;
        impl serde::de::Visitor<'_> for Column {
            type Value = RawValueColumn;

            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(
                    "a column's number (2 for the second, the time being the first) or its \
                     name on the file's header line (\"speed_mps\")",
                )
            }

            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<RawValueColumn, E> {
                Ok(RawValueColumn::Number(v))
            }

            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<RawValueColumn, E> {
                Ok(RawValueColumn::Number(i64::try_from(v).unwrap_or(i64::MAX)))
            }

            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<RawValueColumn, E> {
                Ok(RawValueColumn::Name(v.to_owned()))
            }
        }
        d.deserialize_any(Column)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawControlPoint {
    id: Spanned<u32>,
    latitude_deg: Spanned<f64>,
    longitude_deg: Spanned<f64>,
    height_m: Spanned<f64>,
    t_s: Option<Spanned<f64>>,
}

/// 1-based line of a byte offset.
fn line_of(text: &str, offset: usize) -> usize {
    line_of_bytes(text.as_bytes(), offset)
}

struct Checker<'a> {
    text: &'a str,
}

impl Checker<'_> {
    fn err<T>(&self, span: std::ops::Range<usize>, reason: String) -> Result<T, FormatError> {
        Err(FormatError::Manifest {
            line: line_of(self.text, span.start),
            reason,
        })
    }

    /// A value as the manifest writes it (`1e308`, not its 309 digits), at most 40
    /// characters of it.
    fn as_written(&self, span: std::ops::Range<usize>) -> &str {
        let text = self.text.get(span).unwrap_or_default().trim();
        text.char_indices()
            .nth(40)
            .map_or(text, |(end, _)| &text[..end])
    }

    fn in_range(&self, v: &Spanned<f64>, key: &str, lo: f64, hi: f64) -> Result<f64, FormatError> {
        let x = *v.get_ref();
        if x.is_finite() && (lo..=hi).contains(&x) {
            Ok(x)
        } else {
            self.err(
                v.span(),
                format!(
                    "{key} = {} is outside [{lo}, {hi}]",
                    self.as_written(v.span())
                ),
            )
        }
    }

    /// `[odometer] value_column`: 2 to [`crate::kfgins::MAX_VALUE_COLUMN`], the first
    /// being the time, as a number (the first of the pair) or a header's name (the
    /// second: a line of text, [`MAX_VALUE_HEADER_CHARS`] at most).
    fn value_column(
        &self,
        v: &Spanned<RawValueColumn>,
    ) -> Result<(Option<usize>, Option<String>), FormatError> {
        let max = crate::kfgins::MAX_VALUE_COLUMN;
        match v.get_ref() {
            RawValueColumn::Number(n) => match usize::try_from(*n) {
                Ok(column) if (2..=max).contains(&column) => Ok((Some(column), None)),
                _ => self.err(
                    v.span(),
                    format!(
                        "value_column = {} is outside [2, {max}] (counted from 1: the time is \
                         column 1, the value of a `t_s value` file column 2)",
                        self.as_written(v.span())
                    ),
                ),
            },
            RawValueColumn::Name(name) => {
                let name = name.trim();
                let chars = name.chars().count();
                if chars == 0 || chars > MAX_VALUE_HEADER_CHARS || name.contains(['\n', '\r']) {
                    return self.err(
                        v.span(),
                        format!(
                            "value_column = {} is no column's name on a header line (1 to \
                             {MAX_VALUE_HEADER_CHARS} characters, one line)",
                            self.as_written(v.span())
                        ),
                    );
                }
                Ok((None, Some(name.to_owned())))
            }
        }
    }

    /// `[odometer] speed_floor_mps`, for an odometer that gives speeds: a count's steps
    /// and a file's distances have no reading at rest to floor.
    fn speed_floor(
        &self,
        v: &Spanned<f64>,
        format: LogFormat,
        kind: Option<OdometerKind>,
    ) -> Result<f64, FormatError> {
        let max = crate::speed_floor::SPEED_FLOOR_MAX_MPS;
        if format == LogFormat::UnzBinary {
            return self.err(
                v.span(),
                "speed_floor_mps is for an odometer that gives speeds; a binary log's \
                 odometer is a pulse count"
                    .into(),
            );
        }
        if kind == Some(OdometerKind::DistanceM) {
            return self.err(
                v.span(),
                "speed_floor_mps is for an odometer that gives speeds; kind = \"distance_m\" \
                 gives distances"
                    .into(),
            );
        }
        let x = self.in_range(v, "speed_floor_mps", 0.0, max)?;
        if x == 0.0 {
            return self.err(
                v.span(),
                format!(
                    "speed_floor_mps = 0 floors nothing: leave it out, or give the speed \
                     below which a reading is the sensor's noise at rest (up to {max} m/s, \
                     a move's)"
                ),
            );
        }
        Ok(x)
    }

    fn geodetic(
        &self,
        lat: &Spanned<f64>,
        lon: &Spanned<f64>,
        h: &Spanned<f64>,
    ) -> Result<Geodetic, FormatError> {
        Ok(Geodetic {
            // Not at the poles: north/east dead reckoning divides by cos(latitude).
            latitude_deg: self.in_range(lat, "latitude_deg", -89.0, 89.0)?,
            longitude_deg: self.in_range(lon, "longitude_deg", -180.0, 180.0)?,
            height_m: self.in_range(h, "height_m", -1000.0, 10_000.0)?,
        })
    }
}

/// Names an output folder holds beside the runs' folders: no run may take them.
pub const RESERVED_NAMES: [&str; 6] = [
    "campaign.parquet",
    "campaign.md",
    "campaign.html",
    "campaign-settings.toml",
    "unz.lock",
    "unz.hashes",
];

/// Whether `name` is a plain run name: letters, digits, `-`, `_`, `.`; not starting with
/// `.` (hidden and temporary files), and none of [`RESERVED_NAMES`].
pub fn is_plain_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= MAX_NAME_LEN
        && !name.starts_with('.')
        && !RESERVED_NAMES.contains(&name)
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
}

/// Resolves `rel` inside `dir`, refusing anything that could leave it.
pub fn resolve_inside(dir: &Path, rel: &str) -> Result<PathBuf, String> {
    let p = Path::new(rel);
    if rel.is_empty() {
        return Err("the path is empty".into());
    }
    for c in p.components() {
        match c {
            Component::Normal(_) | Component::CurDir => {}
            Component::ParentDir => return Err(format!("path {rel:?} may not contain '..'")),
            Component::RootDir | Component::Prefix(_) => {
                return Err(format!(
                    "path {rel:?} must be relative to the manifest's folder"
                ));
            }
        }
    }
    let joined = dir.join(p);
    // A symlink may still point out of the folder: compare canonical forms when it exists.
    if let (Ok(real), Ok(real_dir)) = (joined.canonicalize(), dir.canonicalize())
        && !real.starts_with(&real_dir)
    {
        return Err(format!(
            "path {rel:?} resolves outside the manifest's folder"
        ));
    }
    Ok(joined)
}

/// Opens `path`, a file the manifest in `dir` names, and checks that what was opened is
/// inside `dir`: the file the path resolves to now must be the very file opened (same
/// device and inode), so a symbolic link switched between the manifest's check and the
/// open cannot smuggle in a file from elsewhere. Only a regular file opens
/// ([`crate::regular::open_regular`]: a FIFO is refused, not waited on).
pub fn open_inside(dir: &Path, path: &Path) -> std::io::Result<std::fs::File> {
    let file = crate::regular::open_regular(path)?;
    let escape = |what: &str| {
        std::io::Error::new(
            std::io::ErrorKind::PermissionDenied,
            format!("{what}: the file must stay inside the manifest's folder"),
        )
    };
    let real = path.canonicalize()?;
    if !real.starts_with(dir.canonicalize()?) {
        return Err(escape("it resolves outside the manifest's folder"));
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let (opened, named) = (file.metadata()?, std::fs::metadata(&real)?);
        if (opened.dev(), opened.ino()) != (named.dev(), named.ino()) {
            return Err(escape("it changed while it was being opened"));
        }
    }
    Ok(file)
}

impl RunManifest {
    /// Opens a file this manifest names (its raw log, its odometer file), inside its
    /// folder; see [`open_inside`].
    pub fn open_named(&self, path: &Path) -> std::io::Result<std::fs::File> {
        open_inside(self.dir(), path)
    }

    /// `path` (a file this manifest names, resolved) as the manifest names it: relative
    /// to its folder. Anything else is given back whole.
    pub fn named<'p>(&self, path: &'p Path) -> &'p Path {
        path.strip_prefix(self.dir()).unwrap_or(path)
    }

    /// Reads and validates a manifest file.
    pub fn load(path: &Path) -> Result<Self, FileError> {
        let text = read_bounded(path, MAX_MANIFEST_BYTES).map_err(|e| e.in_file(path))?;
        Self::parse(&text, path).map_err(|e| e.in_file(path))
    }

    /// Parses manifest text; `path` is where it came from (paths resolve beside it).
    pub fn parse(text: &str, path: &Path) -> Result<Self, FormatError> {
        let raw: RawManifest = toml::from_str(text).map_err(|e| FormatError::Manifest {
            line: e.span().map_or(0, |s| line_of(text, s.start)),
            reason: e.message().trim().to_owned(),
        })?;
        let c = Checker { text };
        let dir = path.parent().unwrap_or(Path::new("."));

        let name = raw.name.get_ref().clone();
        if !is_plain_name(&name) {
            return c.err(
                raw.name.span(),
                format!(
                    "name {name:?} is not a plain run name (letters, digits, '-', '_', '.'; \
                     at most {MAX_NAME_LEN} characters; not starting with '.'; not one of \
                     the output folder's own names {RESERVED_NAMES:?})"
                ),
            );
        }
        let raw_path = match resolve_inside(dir, raw.raw.get_ref()) {
            Ok(p) => p,
            Err(reason) => return c.err(raw.raw.span(), format!("raw: {reason}")),
        };
        let site = c.geodetic(
            &raw.site.latitude_deg,
            &raw.site.longitude_deg,
            &raw.site.height_m,
        )?;

        let i = &raw.initial;
        let initial = Initial {
            azimuth_deg: i
                .azimuth_deg
                .as_ref()
                .map(|v| c.in_range(v, "azimuth_deg", -360.0, 360.0))
                .transpose()?,
            pitch_deg: i
                .pitch_deg
                .as_ref()
                .map(|v| c.in_range(v, "pitch_deg", -90.0, 90.0))
                .transpose()?,
            roll_deg: i
                .roll_deg
                .as_ref()
                .map(|v| c.in_range(v, "roll_deg", -180.0, 180.0))
                .transpose()?,
            static_s: i
                .static_s
                .as_ref()
                // 0: no static start (logging began in motion). A day at most.
                .map(|v| c.in_range(v, "static_s", 0.0, 86_400.0))
                .transpose()?,
            drift_rad_s: match &i.drift_rad_s {
                Some(v) if v.get_ref().iter().all(|d| d.is_finite() && d.abs() < 1e-2) => {
                    Some(*v.get_ref())
                }
                Some(v) => {
                    return c.err(
                        v.span(),
                        format!(
                            "drift_rad_s = {:?} must be finite and below 1e-2 rad/s",
                            v.get_ref()
                        ),
                    );
                }
                None => None,
            },
        };

        let o = &raw.odometer;
        let (value_column, value_header) = match (&o.value_column, &o.file) {
            (None, _) => (None, None),
            (Some(v), None) => {
                return c.err(
                    v.span(),
                    "odometer.value_column names a column of the [odometer] file, and there is \
                     none"
                        .into(),
                );
            }
            (Some(v), Some(_)) => c.value_column(v)?,
        };
        let odometer = Odometer {
            scale_m_per_pulse: o
                .scale_m_per_pulse
                .as_ref()
                .map(|v| c.in_range(v, "scale_m_per_pulse", 1e-6, 10.0))
                .transpose()?,
            file: match &o.file {
                Some(f) => match resolve_inside(dir, f.get_ref()) {
                    Ok(p) => Some(p),
                    Err(reason) => return c.err(f.span(), format!("odometer.file: {reason}")),
                },
                None => None,
            },
            kind: o.kind,
            speed_floor_mps: o
                .speed_floor_mps
                .as_ref()
                .map(|v| c.speed_floor(v, raw.format, o.kind))
                .transpose()?,
            value_column,
            value_header,
        };
        if let (Some(f), None) = (&o.file, o.kind) {
            return c.err(
                f.span(),
                "odometer.file needs odometer.kind (\"speed_mps\", \"speed_kmh\" or \"distance_m\")"
                    .into(),
            );
        }

        let mut control_points: Vec<ControlPoint> = Vec::with_capacity(raw.control_point.len());
        for cp in &raw.control_point {
            let id = *cp.id.get_ref();
            if control_points.iter().any(|p| p.id == id) {
                return c.err(cp.id.span(), format!("control point id {id} appears twice"));
            }
            control_points.push(ControlPoint {
                id,
                position: c.geodetic(&cp.latitude_deg, &cp.longitude_deg, &cp.height_m)?,
                t_s: match &cp.t_s {
                    Some(v) if v.get_ref().is_finite() => Some(*v.get_ref()),
                    Some(v) => return c.err(v.span(), "t_s must be a finite number".into()),
                    None => None,
                },
            });
        }

        Ok(Self {
            path: path.to_path_buf(),
            name,
            raw: raw_path,
            format: raw.format,
            site,
            initial,
            odometer,
            control_points,
            params: raw.params,
        })
    }

    /// The run folder (the manifest's parent; `.` for a manifest named without a folder).
    pub fn dir(&self) -> &Path {
        match self.path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        }
    }
}

/// Reads a whole text file, refusing files larger than `max_bytes` and text that is not
/// UTF-8, naming where and what to mend: a manifest saved by an editor as UTF-16 or in a
/// Latin-1 code page would otherwise fail with no place ("stream did not contain valid
/// UTF-8"), and one in UTF-16 without its byte-order mark would be read as text with a
/// NUL byte between letters.
pub fn read_bounded(path: &Path, max_bytes: u64) -> Result<String, FormatError> {
    use std::io::Read;
    let file = crate::regular::open_regular(path).map_err(|source| FormatError::Open { source })?;
    let mut bytes = Vec::new();
    if let Err(source) = file.take(max_bytes + 1).read_to_end(&mut bytes) {
        let offset = bytes.len() as u64;
        return Err(FormatError::Io { offset, source });
    }
    if bytes.len() as u64 > max_bytes {
        return Err(FormatError::Invalid(format!(
            "file is larger than {max_bytes} bytes"
        )));
    }
    if bytes.starts_with(&[0xFF, 0xFE]) || bytes.starts_with(&[0xFE, 0xFF]) {
        return Err(FormatError::Invalid(crate::kfgins::UTF16_TEXT.into()));
    }
    let text = String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        FormatError::Manifest {
            line: line_of_bytes(e.as_bytes(), at),
            reason: format!(
                "byte 0x{:02X} at byte offset {at} is not UTF-8 (text saved in a Latin-1 or \
                 Windows code page?): the file must be UTF-8 or ASCII",
                e.as_bytes()[at]
            ),
        }
    })?;
    if let Some(at) = text.find('\0') {
        return Err(FormatError::Manifest {
            line: line_of(&text, at),
            reason: format!(
                "a NUL byte at byte offset {at} (UTF-16 text without its byte-order \
                 mark?): the file must be UTF-8 or ASCII"
            ),
        });
    }
    Ok(text)
}

/// The 1-based line of byte `offset` in `bytes`.
fn line_of_bytes(bytes: &[u8], offset: usize) -> usize {
    bytes[..offset.min(bytes.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
name = "route-03"
raw = "route-03.unz"
format = "unz-binary"

[site]
latitude_deg = 52.2297
longitude_deg = 21.0122
height_m = 110.0

[initial]
azimuth_deg = 109.503

[[control_point]]
id = 1
latitude_deg = 52.2311
longitude_deg = 21.1620
height_m = 112.0
t_s = 2415.3
"#;

    fn parse(text: &str) -> Result<RunManifest, FormatError> {
        RunManifest::parse(text, Path::new("/campaign/route-03/run.toml"))
    }

    fn err_line(text: &str) -> (usize, String) {
        match parse(text) {
            Err(FormatError::Manifest { line, reason }) => (line, reason),
            other => panic!("expected a manifest error, got {other:?}"),
        }
    }

    #[test]
    fn the_spec_example_parses() {
        let m = parse(GOOD).unwrap();
        assert_eq!(m.name, "route-03");
        assert_eq!(m.raw, Path::new("/campaign/route-03/route-03.unz"));
        assert_eq!(m.initial.azimuth_deg, Some(109.503));
        assert_eq!(m.control_points[0].t_s, Some(2415.3));
    }

    #[test]
    fn unknown_key_names_its_line() {
        let text = GOOD.replace(
            "azimuth_deg = 109.503",
            "azimuth_deg = 109.503\nazimuth = 3",
        );
        let (line, reason) = err_line(&text);
        assert_eq!(line, 13);
        assert!(reason.contains("azimuth"), "{reason}");
    }

    #[test]
    fn missing_field_is_an_error() {
        let text = GOOD.replace("height_m = 110.0\n", "");
        let (_, reason) = err_line(&text);
        assert!(reason.contains("height_m"), "{reason}");
    }

    #[test]
    fn bad_value_names_its_line() {
        let text = GOOD.replace("latitude_deg = 52.2297", "latitude_deg = 152.2297");
        let (line, reason) = err_line(&text);
        assert_eq!(line, 7);
        assert!(reason.contains("latitude_deg"), "{reason}");
    }

    #[test]
    fn a_value_out_of_range_is_quoted_as_written() {
        for (written, quoted) in [
            ("1e308", "1e308"),
            ("nan", "nan"),
            ("-inf", "-inf"),
            ("1_000.5", "1_000.5"),
            (
                &format!("1{}.0", "0".repeat(60)),
                &format!("1{}", "0".repeat(39)),
            ),
        ] {
            let text = GOOD.replace(
                "latitude_deg = 52.2297",
                &format!("latitude_deg = {written}"),
            );
            let (line, reason) = err_line(&text);
            assert_eq!(line, 7);
            assert!(
                reason.starts_with(&format!("latitude_deg = {quoted} is outside [-89, 89]")),
                "{reason}"
            );
        }
    }

    /// `[odometer] speed_floor_mps` is taken for a text log's speeds, and refused, naming
    /// its line, for a binary log's count, a file of distances, 0 and beyond a move's
    /// speed.
    #[test]
    fn a_speed_floor_is_for_speeds_within_a_moves() {
        let text_log = |odometer: &str| {
            GOOD.replace("format = \"unz-binary\"", "format = \"kf-gins\"")
                .replace("[initial]", &format!("[odometer]\n{odometer}\n[initial]"))
        };
        let m = parse(&text_log("speed_floor_mps = 0.04")).unwrap();
        assert_eq!(m.odometer.speed_floor_mps, Some(0.04));
        let file = "file = \"odo.txt\"\nkind = \"speed_kmh\"\nspeed_floor_mps = 0.1";
        assert_eq!(
            parse(&text_log(file)).unwrap().odometer.speed_floor_mps,
            Some(0.1)
        );
        let binary = GOOD.replace("[initial]", "[odometer]\nspeed_floor_mps = 0.04\n[initial]");
        for (text, says) in [
            (binary, "a binary log's odometer is a pulse count"),
            (
                text_log("file = \"odo.txt\"\nkind = \"distance_m\"\nspeed_floor_mps = 0.04"),
                "kind = \"distance_m\" gives distances",
            ),
            (text_log("speed_floor_mps = 0.0"), "floors nothing"),
            (text_log("speed_floor_mps = 0.2"), "is outside [0, 0.1]"),
            (text_log("speed_floor_mps = -0.04"), "is outside [0, 0.1]"),
            (text_log("speed_floor_mps = nan"), "is outside [0, 0.1]"),
        ] {
            let (line, reason) = err_line(&text);
            let at = text
                .lines()
                .position(|l| l.starts_with("speed_floor_mps"))
                .unwrap();
            assert_eq!(line, at + 1, "{reason}");
            assert!(reason.contains(says), "{reason}");
        }
    }

    /// `[odometer] value_column` names a column of the odometer file, 2 to 64; refused,
    /// naming its line, without a file and out of that range.
    #[test]
    fn a_value_column_is_a_column_of_the_odometer_file() {
        let text_log = |odometer: &str| {
            GOOD.replace("format = \"unz-binary\"", "format = \"kf-gins\"")
                .replace("[initial]", &format!("[odometer]\n{odometer}\n[initial]"))
        };
        let file = "file = \"odo.csv\"\nkind = \"speed_kmh\"\n";
        let m = parse(&text_log(&format!("{file}value_column = 3"))).unwrap();
        assert_eq!(m.odometer.value_column, Some(3));
        assert_eq!(m.odometer.value_column_said(), "column 3");
        assert_eq!(parse(&text_log(file)).unwrap().odometer.value_column, None);
        // By its name on the file's header line.
        let m = parse(&text_log(&format!("{file}value_column = \" speed_mps \""))).unwrap();
        assert_eq!(
            (m.odometer.value_column, m.odometer.value_header.as_deref()),
            (None, Some("speed_mps"))
        );
        assert_eq!(m.odometer.value_column_said(), "column \"speed_mps\"");
        for (text, says) in [
            (
                text_log("value_column = 2"),
                "of the [odometer] file, and there is none",
            ),
            (
                text_log(&format!("{file}value_column = 1")),
                "is outside [2, 64]",
            ),
            (
                text_log(&format!("{file}value_column = 65")),
                "is outside [2, 64]",
            ),
            (
                text_log(&format!("{file}value_column = -2")),
                "is outside [2, 64]",
            ),
            (
                text_log(&format!("{file}value_column = 9223372036854775807")),
                "is outside [2, 64]",
            ),
            (
                text_log(&format!("{file}value_column = \" \"")),
                "is no column's name on a header line (1 to 128 characters, one line)",
            ),
            (
                text_log(&format!("{file}value_column = \"{}\"", "x".repeat(129))),
                "is no column's name on a header line",
            ),
            (
                text_log(&format!("{file}value_column = \"a\\nb\"")),
                "is no column's name on a header line",
            ),
            (
                text_log(&format!("{file}value_column = 2.5")),
                "a column's number (2 for the second, the time being the first) or its name",
            ),
        ] {
            let (line, reason) = err_line(&text);
            let at = text
                .lines()
                .position(|l| l.starts_with("value_column"))
                .unwrap();
            assert_eq!(line, at + 1, "{reason}");
            assert!(reason.contains(says), "{reason}");
        }
    }

    /// Regression (hostile-archive probe): a symlink switched to a file outside the run
    /// folder after the manifest's check is refused when the file is opened.
    #[cfg(unix)]
    #[test]
    fn a_file_opened_outside_the_folder_is_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let (run, outside) = (tmp.path().join("run"), tmp.path().join("secret.unz"));
        std::fs::create_dir_all(&run).unwrap();
        std::fs::write(&outside, b"outside").unwrap();
        std::fs::write(run.join("inside.unz"), b"inside").unwrap();
        let link = run.join("raw.unz");
        std::os::unix::fs::symlink("inside.unz", &link).unwrap();
        assert!(open_inside(&run, &link).is_ok());
        // The link now points out (as a racing writer would switch it).
        std::fs::remove_file(&link).unwrap();
        std::os::unix::fs::symlink(&outside, &link).unwrap();
        let e = open_inside(&run, &link).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::PermissionDenied, "{e}");
        assert!(e.to_string().contains("outside"), "{e}");
    }

    /// Regression (hostile-archive probe): a manifest saved as UTF-16 or in a Latin-1
    /// code page failed with "read failed at byte offset 0: stream did not contain valid
    /// UTF-8", naming neither the place nor the cause; it now names both, and a UTF-8
    /// byte-order mark is read past.
    #[test]
    fn a_manifest_not_in_utf8_says_where_and_what_to_mend() {
        let tmp = tempfile::tempdir().unwrap();
        let load = |name: &str, bytes: &[u8]| {
            let path = tmp.path().join(name);
            std::fs::write(&path, bytes).unwrap();
            RunManifest::load(&path)
                .map(|m| m.name)
                .map_err(|e| e.to_string())
        };
        let utf16 = |bom: bool| -> Vec<u8> {
            let text = if bom {
                format!("\u{feff}{GOOD}")
            } else {
                GOOD.into()
            };
            text.encode_utf16().flat_map(u16::to_le_bytes).collect()
        };
        assert_eq!(load("plain.toml", GOOD.as_bytes()), Ok("route-03".into()));
        let marked = [b"\xEF\xBB\xBF", GOOD.as_bytes()].concat();
        assert_eq!(load("utf8-bom.toml", &marked), Ok("route-03".into()));

        let e = load("utf16.toml", &utf16(true)).unwrap_err();
        assert!(e.starts_with("UTF-16 text (its byte-order mark): "), "{e}");
        let e = load("utf16-no-bom.toml", &utf16(false)).unwrap_err();
        // GOOD opens with a newline ("\n\0" in UTF-16): its NUL is on line 2.
        assert!(
            e.starts_with("line 2: a NUL byte at byte offset 1 (UTF-16"),
            "{e}"
        );
        let latin1 = [&b"# ok\n# ok\n# caf\xE9\n"[..], GOOD.as_bytes()].concat();
        let e = load("latin1.toml", &latin1).unwrap_err();
        assert!(
            e.starts_with("line 3: byte 0xE9 at byte offset 15 is not UTF-8 (text saved in"),
            "{e}"
        );
        assert!(e.ends_with("latin1.toml)"), "{e}");
    }

    #[test]
    fn paths_may_not_escape() {
        for bad in ["../other/x.unz", "/etc/passwd", "a/../../x"] {
            let text = GOOD.replace("\"route-03.unz\"", &format!("{bad:?}"));
            let (line, reason) = err_line(&text);
            assert_eq!(line, 3, "{bad}");
            assert!(reason.starts_with("raw:"), "{reason}");
        }
    }

    #[test]
    fn names_must_be_plain() {
        for bad in ["..", ".", "a/b", "", "x y"] {
            let text = GOOD.replace("\"route-03\"", &format!("{bad:?}"));
            let (line, _) = err_line(&text);
            assert_eq!(line, 2, "{bad:?}");
        }
    }

    #[test]
    fn duplicate_control_point_ids_are_refused() {
        let cp = "\n[[control_point]]\nid = 1\nlatitude_deg = 1.0\nlongitude_deg = 2.0\nheight_m = 3.0\n";
        let (line, reason) = err_line(&format!("{GOOD}{cp}"));
        assert_eq!(line, 22);
        assert!(reason.contains("twice"));
    }
}
