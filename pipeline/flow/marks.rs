//! Which mark stands for a control point. A point is surveyed at a stop, and a point id
//! marked more than once is placed at the last of its marks made at rest: a second press
//! is how an operator corrects a first one (made while driving up to the point, at a
//! stop short of it, or during the static start), or repeats it at the same stop, where
//! either serves.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};
use unz_formats::parquet_io::for_each_batch_of;
use unz_formats::schema;
use unz_formats::tables::{MarksTable, f64_column, i64_column};

/// The odometer's speed about a mark is taken over this long either side of it, s.
pub const SPEED_HALF_WINDOW_S: f64 = 1.0;
/// A mark about which the odometer's mean speed is at most this was made at rest, m/s
/// (one 12.5-mm pulse in a 2-s window is 6 mm/s; a vehicle creeping up to a point goes
/// 0.5 m/s and more).
pub const AT_REST_MPS: f64 = 0.1;

/// A control point whose id was marked more than once, and the mark used
/// (`navigate.json`'s `repeated_marks`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RepeatedMark {
    /// Control-point id.
    pub id: u32,
    /// Marks of that id in the log.
    pub marks: usize,
    /// Time of the mark used, s in the log's time base.
    pub used_t_s: f64,
    /// The odometer's mean speed over ±1 s about it, m/s (none when no mark of the id
    /// is inside the log, or the log has no odometer there).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub used_speed_mps: Option<f64>,
    /// Whether it was made at rest (at most [`AT_REST_MPS`]); when none of the marks
    /// was, the slowest is used (the last on a tie).
    pub at_rest: bool,
    /// Time of the id's first mark, s.
    pub first_t_s: f64,
}

/// Marks whose point id no control point of the manifest has: a key pressed wrong, or a
/// point missing from the manifest (`navigate.json`'s `unknown_marks`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UnknownMarks {
    /// How many marks.
    pub total: usize,
    /// The first [`UNKNOWN_MARKS_LISTED`], in the log's order: (point id, time s in the
    /// log's time base).
    pub first: Vec<(u32, f64)>,
}

/// Most unknown marks listed by time (the rest are counted).
pub const UNKNOWN_MARKS_LISTED: usize = 20;

impl UnknownMarks {
    /// The marks of `marks` whose id is not among `ids`; `None` without any.
    pub fn of(marks: &MarksTable, ids: &[u32]) -> Option<Self> {
        let mut out = Self {
            total: 0,
            first: Vec::new(),
        };
        for (id, t_ns) in marks.point_id.iter().zip(&marks.t_ns) {
            if ids.contains(id) {
                continue;
            }
            out.total += 1;
            if out.first.len() < UNKNOWN_MARKS_LISTED {
                out.first.push((*id, *t_ns as f64 * 1e-9));
            }
        }
        (out.total > 0).then_some(out)
    }

    /// "4 at t_s = 1234.50, 7 at t_s = …" (and how many more).
    pub fn listed(&self) -> String {
        let mut s = self
            .first
            .iter()
            .map(|(id, t)| format!("{id} at t_s = {t:.2}"))
            .collect::<Vec<_>>()
            .join(", ");
        if self.total > self.first.len() {
            s += &format!(" and {} more", self.total - self.first.len());
        }
        s
    }
}

/// The mark that stands for each of `ids` (an index into `marks`), and the repeated ones.
///
/// An id marked once is that mark. An id marked several times is the last of its marks
/// `in_log` made at rest, else the slowest of them (the last on a tie), else (no mark in
/// the log) its first mark. The ingested odometer (`odometer.parquet`) is read, once and
/// batch by batch, only when some id is marked more than once.
pub fn choose_marks(
    marks: &MarksTable,
    ids: &[u32],
    odometer: &Path,
    in_log: impl Fn(i64) -> bool,
) -> anyhow::Result<(BTreeMap<u32, usize>, Vec<RepeatedMark>)> {
    let ids: std::collections::BTreeSet<u32> = ids.iter().copied().collect();
    let mut of_id: BTreeMap<u32, Vec<usize>> = BTreeMap::new();
    for (i, id) in marks.point_id.iter().enumerate() {
        if ids.contains(id) {
            of_id.entry(*id).or_default().push(i);
        }
    }
    let mut chosen: BTreeMap<u32, usize> = of_id.iter().map(|(&id, v)| (id, v[0])).collect();
    // The marks whose speed decides: those of repeated ids inside the log.
    let candidates: Vec<(u32, Vec<usize>)> = of_id
        .iter()
        .filter(|(_, v)| v.len() > 1)
        .map(|(&id, v)| {
            let inside: Vec<usize> = v
                .iter()
                .copied()
                .filter(|&i| in_log(marks.t_ns[i]))
                .collect();
            (id, inside)
        })
        .collect();
    if candidates.is_empty() {
        return Ok((chosen, Vec::new()));
    }
    let times_ns: Vec<i64> = candidates
        .iter()
        .flat_map(|(_, v)| v.iter().map(|&i| marks.t_ns[i]))
        .collect();
    let speeds = odometer_speeds_mps(odometer, &times_ns)?;
    let mut next = speeds.into_iter();
    let mut repeated = Vec::with_capacity(candidates.len());
    for (id, inside) in candidates {
        let speed: Vec<f64> = next.by_ref().take(inside.len()).collect();
        let first = of_id[&id][0];
        // The last at rest, else the slowest (the last on a tie); a mark without a
        // speed (no odometer in the log) is never picked for one.
        let finite = |k: &usize| speed[*k].is_finite();
        let pick = (0..speed.len())
            .rev()
            .filter(finite)
            .find(|&k| speed[k] <= AT_REST_MPS)
            .or_else(|| {
                (0..speed.len())
                    .rev()
                    .filter(finite)
                    .min_by(|&a, &b| speed[a].total_cmp(&speed[b]))
            });
        let (used, used_speed_mps) = match pick {
            Some(k) => (inside[k], Some(speed[k])),
            None => (inside.last().copied().unwrap_or(first), None),
        };
        chosen.insert(id, used);
        repeated.push(RepeatedMark {
            id,
            marks: of_id[&id].len(),
            used_t_s: marks.t_ns[used] as f64 * 1e-9,
            used_speed_mps,
            at_rest: used_speed_mps.is_some_and(|v| v <= AT_REST_MPS),
            first_t_s: marks.t_ns[first] as f64 * 1e-9,
        });
    }
    Ok((chosen, repeated))
}

/// The ingested odometer's mean speed over ±[`SPEED_HALF_WINDOW_S`] about each of
/// `times_ns`, m/s, reading `odometer.parquet` batch by batch. Distances are
/// interpolated linearly between tags, held before the first and after the last; a tag
/// not after the one before does not interpolate.
pub fn odometer_speeds_mps(path: &Path, times_ns: &[i64]) -> anyhow::Result<Vec<f64>> {
    let half_ns = (SPEED_HALF_WINDOW_S * 1e9) as i64;
    // Each time's two ends, in time order.
    let mut ends: Vec<(i64, usize)> = times_ns
        .iter()
        .enumerate()
        .flat_map(|(k, &t)| {
            [
                (t.saturating_sub(half_ns), 2 * k),
                (t.saturating_add(half_ns), 2 * k + 1),
            ]
        })
        .collect();
    ends.sort_unstable();
    let mut at = vec![f64::NAN; ends.len()];
    let mut next = 0;
    let mut prev: Option<(i64, f64)> = None;
    for_each_batch_of(path, &[schema::T_NS, schema::DISTANCE_M], |b| {
        let t = i64_column(b, schema::T_NS)?;
        let d = f64_column(b, schema::DISTANCE_M)?;
        for (&t, d) in t.iter().zip(d) {
            while next < ends.len() && ends[next].0 <= t {
                let end = ends[next].0;
                at[ends[next].1] = match prev {
                    _ if end == t => d,
                    Some((t0, d0)) if t > t0 && end > t0 => {
                        d0 + (d - d0) * ((end - t0) as f64 / (t - t0) as f64)
                    }
                    Some((_, d0)) => d0,
                    // Before the first tag: held.
                    None => d,
                };
                next += 1;
            }
            prev = Some((t, d));
        }
        Ok(())
    })?;
    if let Some((_, d)) = prev {
        for &(_, k) in &ends[next..] {
            at[k] = d;
        }
    }
    Ok(at
        .chunks_exact(2)
        .map(|w| (w[1] - w[0]).abs() / (2.0 * SPEED_HALF_WINDOW_S))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use unz_formats::tables::OdometerTable;

    /// An odometer at 100 Hz: driving at 10 m/s until 20 s, stopped until 40 s, driving
    /// again until 60 s, stopped after.
    fn odometer(dir: &Path) -> std::path::PathBuf {
        let mut t = OdometerTable::default();
        let mut d = 0.0;
        for k in 0..8000_i64 {
            let s = k as f64 * 0.01;
            if k > 0 && (s <= 20.0 || (40.0 < s && s <= 60.0)) {
                d += 0.1;
            }
            t.t_ns.push(k * 10_000_000);
            t.distance_m.push(d);
            t.pulses.push(None);
            t.source.push(0);
        }
        let path = dir.join("odometer.parquet");
        let schema = schema::odometer_scaled(None, None);
        unz_formats::parquet_io::write_batch(&path, &t.to_batch(schema).unwrap()).unwrap();
        path
    }

    fn marks(at: &[(f64, u32)]) -> MarksTable {
        MarksTable {
            t_ns: at.iter().map(|(t, _)| (t * 1e9) as i64).collect(),
            point_id: at.iter().map(|(_, id)| *id).collect(),
        }
    }

    #[test]
    fn speeds_about_marks_are_the_odometers() {
        let tmp = tempfile::tempdir().unwrap();
        let path = odometer(tmp.path());
        let t: Vec<i64> = [10.0, 30.0, 20.0, 0.5, 100.0]
            .iter()
            .map(|s| (s * 1e9) as i64)
            .collect();
        let v = odometer_speeds_mps(&path, &t).unwrap();
        assert!((v[0] - 10.0).abs() < 1e-9, "{v:?}");
        assert_eq!(v[1], 0.0);
        // Half of the window driving.
        assert!((v[2] - 5.0).abs() < 0.06, "{v:?}");
        // Before the first tag the distance is held: 15 m over the 2-s window.
        assert!((v[3] - 7.5).abs() < 0.06, "{v:?}");
        // After the last tag too.
        assert_eq!(v[4], 0.0);
    }

    #[test]
    fn a_repeated_id_takes_its_last_mark_at_rest() {
        let tmp = tempfile::tempdir().unwrap();
        let path = odometer(tmp.path());
        let all = |_| true;
        // An early press while driving, then two at the stop; id 2 marked once.
        let m = marks(&[(15.0, 1), (25.0, 1), (26.0, 2), (30.0, 1)]);
        let (chosen, repeated) = choose_marks(&m, &[1, 2], &path, all).unwrap();
        assert_eq!(chosen[&1], 3);
        assert_eq!(chosen[&2], 2);
        assert_eq!(repeated.len(), 1);
        let r = &repeated[0];
        assert_eq!((r.id, r.marks, r.at_rest), (1, 3, true));
        assert!((r.used_t_s - 30.0).abs() < 1e-9 && (r.first_t_s - 15.0).abs() < 1e-9);

        // A press during the static start and one at a stop short of the point, both at
        // rest, corrected by the press at the point: the last.
        let m = marks(&[(25.0, 1), (70.0, 1), (79.0, 1)]);
        let (chosen, _) = choose_marks(&m, &[1], &path, all).unwrap();
        assert_eq!(chosen[&1], 2);

        // None at rest: the slowest.
        let m = marks(&[(10.0, 1), (40.5, 1), (50.0, 1), (55.0, 1)]);
        let (chosen, repeated) = choose_marks(&m, &[1], &path, all).unwrap();
        assert_eq!(chosen[&1], 1);
        assert!(!repeated[0].at_rest);
        let v = repeated[0].used_speed_mps.unwrap();
        assert!((v - 7.5).abs() < 0.06, "{repeated:?}");

        // Marks outside the log do not count; with none inside, the first is kept (and
        // the match names it as outside the log).
        let m = marks(&[(25.0, 1), (35.0, 1)]);
        let (chosen, _) = choose_marks(&m, &[1], &path, |t| t < 30_000_000_000).unwrap();
        assert_eq!(chosen[&1], 0);
        let (chosen, repeated) = choose_marks(&m, &[1], &path, |_| false).unwrap();
        assert_eq!(chosen[&1], 0);
        assert_eq!(repeated[0].used_speed_mps, None);

        // Ids the manifest does not name are not read; no repeated id, no odometer read.
        let m = marks(&[(15.0, 7), (25.0, 7), (30.0, 1)]);
        let (chosen, repeated) =
            choose_marks(&m, &[1], Path::new("/nonexistent/odometer.parquet"), all).unwrap();
        assert_eq!((chosen.len(), chosen[&1]), (1, 2));
        assert!(repeated.is_empty());
    }
}
