//! Which marks stand for a control point. A point is surveyed at a stop, and a point id
//! marked more than once is placed at the last of its marks made at rest: a second press
//! is how an operator corrects a first one (made while driving up to the point, at a
//! stop short of it, or during the static start), or repeats it at the same stop, where
//! either serves. A point the route comes back to is visited again: marks at rest at
//! stops apart along the odometer's path ([`SAME_STOP_PATH_M`]) that the navigation puts
//! at the same place ([`same_place`]) are each a visit, and each is compared with the
//! point.

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
/// Marks of one id with at least this much of the odometer's path between them were made
/// at different stops, m: a press repeated at a stop, or made while creeping up to the
/// point, is well within it.
pub const SAME_STOP_PATH_M: f64 = 100.0;
/// Two stops whose navigated places (the initial settings, before DISUPT) are at most
/// this far apart, plus [`SAME_PLACE_PER_PATH`] of the path between them, are at the same
/// place, m: the initial azimuth and the odometer's scale move a place the route comes
/// back to by the same amount both times, leaving the gyros' drift over the drive
/// between (LN-200: about 0.5 % of it).
pub const SAME_PLACE_M: f64 = 30.0;
/// The part of the path between two stops added to [`SAME_PLACE_M`].
pub const SAME_PLACE_PER_PATH: f64 = 0.03;

/// Whether stops whose navigated places are `apart_m` apart, with `path_m` of the
/// odometer's path between them, are at the same place.
pub fn same_place(apart_m: f64, path_m: f64) -> bool {
    apart_m <= SAME_PLACE_M + SAME_PLACE_PER_PATH * path_m.abs()
}

/// A control point whose id was marked more than once, and the marks used
/// (`navigate.json`'s `repeated_marks`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RepeatedMark {
    /// Control-point id.
    pub id: u32,
    /// Marks of that id in the log.
    pub marks: usize,
    /// Time of the mark used (of the last visit), s in the log's time base.
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
    /// The point visited more than once: the time of each visit's mark, s, in time
    /// order (the last is `used_t_s`); each is compared with the point. Absent with one
    /// visit.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub visits_t_s: Vec<f64>,
    /// Marks at rest at other stops that the navigation puts elsewhere than the last
    /// visit (beyond [`same_place`]): presses the last corrected, not used, s.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub elsewhere_t_s: Vec<f64>,
    /// Marks at rest at the run's start (less than [`SAME_STOP_PATH_M`] of the odometer's
    /// path from the log's first reading), with a later stop marked: not used, s. The
    /// navigation starts at the manifest's site, so a mark there compares the site with
    /// the survey, not the navigation (a site read off a map would be a point off).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub at_start_t_s: Vec<f64>,
}

/// A stop's mark (index into the marks) and the odometer's distance there, m.
type Stop = (usize, f64);

impl RepeatedMark {
    /// What the campaign's note says of it: the visits, or the mark used and why, and
    /// the presses at other stops left out.
    pub fn said(&self) -> String {
        let times = |t: &[f64]| {
            t.iter()
                .map(|t| format!("{t:.2}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let mut s = if self.visits_t_s.len() > 1 {
            format!(
                "control point {} visited {} times (marked {}), at t_s = {}",
                self.id,
                self.visits_t_s.len(),
                self.marks,
                times(&self.visits_t_s)
            )
        } else {
            format!(
                "control point {} marked {} times: the mark at t_s = {:.2} used ({})",
                self.id,
                self.marks,
                self.used_t_s,
                match (self.at_rest, self.used_speed_mps) {
                    (true, _) => "the last at rest".to_owned(),
                    (false, Some(v)) => format!("none at rest: the slowest, {v:.1} m/s"),
                    (false, None) => "no odometer about it".to_owned(),
                }
            )
        };
        if !self.at_start_t_s.is_empty() {
            s += &format!(
                "; its marks at the run's start (where the site stands for it), not used: \
                 t_s = {}",
                times(&self.at_start_t_s)
            );
        }
        if !self.elsewhere_t_s.is_empty() {
            s += &format!(
                "; its marks at rest at other stops, placed elsewhere by the navigation, not \
                 used: t_s = {}",
                times(&self.elsewhere_t_s)
            );
        }
        s
    }
}

/// A repeated id's marks, before the navigation says which stops are at the same place.
#[derive(Debug, Clone)]
struct Repeated {
    id: u32,
    marks: usize,
    first: usize,
    /// The mark of each stop made at rest, with the odometer's distance there, in time
    /// order; or the one mark used (the slowest, or none at rest).
    stops: Vec<Stop>,
    /// Marks at rest at the run's start, before a later stop (not candidates).
    at_start: Vec<usize>,
    used_speed_mps: Option<f64>,
}

/// The marks chosen for the manifest's control points ([`choose_marks`]); which of a
/// point's stops are visits is settled by [`ChosenMarks::settle`].
#[derive(Debug, Clone, Default)]
pub struct ChosenMarks {
    /// Each id's mark (index into the marks), for ids marked once.
    once: BTreeMap<u32, usize>,
    repeated: Vec<Repeated>,
}

impl ChosenMarks {
    /// The marks whose navigated place [`Self::settle`] needs (indices into the marks):
    /// the stops of ids marked at rest at more than one; none otherwise.
    pub fn to_place(&self) -> Vec<usize> {
        self.repeated
            .iter()
            .filter(|r| r.stops.len() > 1)
            .flat_map(|r| r.stops.iter().map(|s| s.0))
            .collect()
    }

    /// Each id's marks used (indices into the marks, in time order: a visit each), and
    /// the repeated ids. Of an id marked at rest at several stops, the last is a visit,
    /// and each earlier stop is one too when `place` (north and east, m, of a mark among
    /// [`Self::to_place`]) puts it at the same place ([`same_place`]); else it is a press
    /// the last corrected. A mark without a place is not a visit.
    pub fn settle(
        self,
        marks: &MarksTable,
        place: impl Fn(usize) -> Option<[f64; 2]>,
    ) -> (BTreeMap<u32, Vec<usize>>, Vec<RepeatedMark>) {
        let t_s = |i: usize| marks.t_ns[i] as f64 * 1e-9;
        let mut used: BTreeMap<u32, Vec<usize>> =
            self.once.into_iter().map(|(id, i)| (id, vec![i])).collect();
        let mut repeated = Vec::with_capacity(self.repeated.len());
        for r in self.repeated {
            let (visits, elsewhere): (Vec<Stop>, Vec<Stop>) = match r.stops.split_last() {
                Some((&(last, d_last), earlier)) => {
                    let at_last = place(last);
                    let beside_last = |&&(i, d): &&Stop| match (place(i), at_last) {
                        (Some(a), Some(b)) => {
                            same_place((a[0] - b[0]).hypot(a[1] - b[1]), d_last - d)
                        }
                        _ => false,
                    };
                    let (mut v, e): (Vec<Stop>, Vec<Stop>) = earlier.iter().partition(beside_last);
                    v.push((last, d_last));
                    (v, e)
                }
                None => (vec![(r.first, f64::NAN)], Vec::new()),
            };
            let last = visits.last().map_or(r.first, |v| v.0);
            let times = |v: &[Stop]| v.iter().map(|&(i, _)| t_s(i)).collect::<Vec<_>>();
            repeated.push(RepeatedMark {
                id: r.id,
                marks: r.marks,
                used_t_s: t_s(last),
                used_speed_mps: r.used_speed_mps,
                at_rest: r.used_speed_mps.is_some_and(|v| v <= AT_REST_MPS),
                first_t_s: t_s(r.first),
                visits_t_s: if visits.len() > 1 {
                    times(&visits)
                } else {
                    Vec::new()
                },
                elsewhere_t_s: times(&elsewhere),
                at_start_t_s: r.at_start.iter().map(|&i| t_s(i)).collect(),
            });
            used.insert(r.id, visits.into_iter().map(|v| v.0).collect());
        }
        (used, repeated)
    }
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

/// The marks that stand for each of `ids` ([`ChosenMarks`], settled by
/// [`ChosenMarks::settle`]).
///
/// An id marked once is that mark. Of an id marked several times, the marks `in_log` are
/// split into stops where the odometer's path between neighbours reaches
/// [`SAME_STOP_PATH_M`]; each stop's last mark made at rest is a candidate visit, but for
/// stops at the run's start (within that path of the log's first odometer reading) before
/// a later one. Without any at rest, the slowest mark (the last on a tie), else (no mark
/// in the log) its first mark, is used. The ingested odometer (`odometer.parquet`) is
/// read, once and batch by batch, only when some id is marked more than once.
pub fn choose_marks(
    marks: &MarksTable,
    ids: &[u32],
    odometer: &Path,
    in_log: impl Fn(i64) -> bool,
) -> anyhow::Result<ChosenMarks> {
    let ids: std::collections::BTreeSet<u32> = ids.iter().copied().collect();
    let mut of_id: BTreeMap<u32, Vec<usize>> = BTreeMap::new();
    for (i, id) in marks.point_id.iter().enumerate() {
        if ids.contains(id) {
            of_id.entry(*id).or_default().push(i);
        }
    }
    let once: BTreeMap<u32, usize> = of_id
        .iter()
        .filter(|(_, v)| v.len() == 1)
        .map(|(&id, v)| (id, v[0]))
        .collect();
    // The marks whose speed and path decide: those of repeated ids inside the log, in
    // time order (the log's on a tie).
    let candidates: Vec<(u32, Vec<usize>)> = of_id
        .iter()
        .filter(|(_, v)| v.len() > 1)
        .map(|(&id, v)| {
            let mut inside: Vec<usize> = v
                .iter()
                .copied()
                .filter(|&i| in_log(marks.t_ns[i]))
                .collect();
            inside.sort_by_key(|&i| marks.t_ns[i]);
            (id, inside)
        })
        .collect();
    if candidates.is_empty() {
        return Ok(ChosenMarks {
            once,
            repeated: Vec::new(),
        });
    }
    // The marks' times, and the log's start last (the first reading, held before it).
    let times_ns: Vec<i64> = candidates
        .iter()
        .flat_map(|(_, v)| v.iter().map(|&i| marks.t_ns[i]))
        .chain([i64::MIN])
        .collect();
    let mut about = odometer_about(odometer, &times_ns)?;
    let start_m = about.pop().map_or(f64::NAN, |a| a.distance_m);
    let mut next = about.into_iter();
    let mut repeated = Vec::with_capacity(candidates.len());
    for (id, inside) in candidates {
        let at: Vec<OdometerAbout> = next.by_ref().take(inside.len()).collect();
        let first = of_id[&id][0];
        // Stops: runs of marks with less than SAME_STOP_PATH_M between neighbours (an
        // unknown distance does not part them).
        let mut stops: Vec<Vec<usize>> = Vec::new();
        for k in 0..at.len() {
            let apart =
                k > 0 && (at[k].distance_m - at[k - 1].distance_m).abs() >= SAME_STOP_PATH_M;
            match stops.last_mut() {
                Some(stop) if !apart => stop.push(k),
                _ => stops.push(vec![k]),
            }
        }
        let at_rest = |k: &usize| at[*k].speed_mps <= AT_REST_MPS;
        let mut rest: Vec<usize> = stops
            .iter()
            .filter_map(|stop| stop.iter().rev().copied().find(at_rest))
            .collect();
        // Stops at the run's start, before a later one: the site stands for them.
        let at_start: Vec<usize> = match rest.split_last() {
            Some((_, earlier)) => earlier
                .iter()
                .copied()
                .filter(|&k| (at[k].distance_m - start_m).abs() < SAME_STOP_PATH_M)
                .collect(),
            None => Vec::new(),
        };
        let at_start_set: std::collections::BTreeSet<usize> = at_start.iter().copied().collect();
        rest.retain(|k| !at_start_set.contains(k));
        let (stops, used_speed_mps) = if let Some(&last) = rest.last() {
            (
                rest.iter()
                    .map(|&k| (inside[k], at[k].distance_m))
                    .collect(),
                Some(at[last].speed_mps),
            )
        } else {
            // None at rest: the slowest (the last on a tie); a mark without a speed (no
            // odometer in the log) is never picked for one.
            let slowest = (0..at.len())
                .rev()
                .filter(|&k| at[k].speed_mps.is_finite())
                .min_by(|&a, &b| at[a].speed_mps.total_cmp(&at[b].speed_mps));
            match slowest {
                Some(k) => (vec![(inside[k], at[k].distance_m)], Some(at[k].speed_mps)),
                None => (
                    vec![(inside.last().copied().unwrap_or(first), f64::NAN)],
                    None,
                ),
            }
        };
        repeated.push(Repeated {
            id,
            marks: of_id[&id].len(),
            first,
            stops,
            at_start: at_start.into_iter().map(|k| inside[k]).collect(),
            used_speed_mps,
        });
    }
    Ok(ChosenMarks { once, repeated })
}

/// The odometer about a time: its mean speed over ±[`SPEED_HALF_WINDOW_S`], m/s, and
/// its distance there, m (NaN without an odometer).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometerAbout {
    /// Mean speed, m/s.
    pub speed_mps: f64,
    /// Distance, m.
    pub distance_m: f64,
}

/// The ingested odometer about each of `times_ns` ([`OdometerAbout`]), reading
/// `odometer.parquet` batch by batch. Distances are interpolated linearly between tags,
/// held before the first and after the last; a tag not after the one before does not
/// interpolate.
pub fn odometer_about(path: &Path, times_ns: &[i64]) -> anyhow::Result<Vec<OdometerAbout>> {
    let half_ns = (SPEED_HALF_WINDOW_S * 1e9) as i64;
    // Each time's window ends and the time itself, in time order.
    let mut ends: Vec<(i64, usize)> = times_ns
        .iter()
        .enumerate()
        .flat_map(|(k, &t)| {
            [
                (t.saturating_sub(half_ns), 3 * k),
                (t, 3 * k + 1),
                (t.saturating_add(half_ns), 3 * k + 2),
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
        .chunks_exact(3)
        .map(|w| OdometerAbout {
            speed_mps: (w[2] - w[0]).abs() / (2.0 * SPEED_HALF_WINDOW_S),
            distance_m: w[1],
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use unz_formats::tables::OdometerTable;

    /// An odometer at 100 Hz: driving at 10 m/s until 20 s, stopped until 40 s, driving
    /// again until 60 s, stopped after.
    fn odometer(dir: &Path) -> std::path::PathBuf {
        odometer_driving(dir, |s| s <= 20.0 || (40.0 < s && s <= 60.0))
    }

    /// An odometer at 100 Hz for 80 s, at 10 m/s while `driving`, from 0 m.
    fn odometer_driving(dir: &Path, driving: impl Fn(f64) -> bool) -> std::path::PathBuf {
        let mut t = OdometerTable::default();
        let mut d = 0.0;
        for k in 0..8000_i64 {
            let s = k as f64 * 0.01;
            if k > 0 && driving(s) {
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
    fn speeds_and_distances_about_marks_are_the_odometers() {
        let tmp = tempfile::tempdir().unwrap();
        let path = odometer(tmp.path());
        let t: Vec<i64> = [10.0, 30.0, 20.0, 0.5, 100.0]
            .iter()
            .map(|s| (s * 1e9) as i64)
            .collect();
        let a = odometer_about(&path, &t).unwrap();
        let v: Vec<f64> = a.iter().map(|a| a.speed_mps).collect();
        assert!((v[0] - 10.0).abs() < 1e-9, "{v:?}");
        assert_eq!(v[1], 0.0);
        // Half of the window driving.
        assert!((v[2] - 5.0).abs() < 0.06, "{v:?}");
        // Before the first tag the distance is held: 15 m over the 2-s window.
        assert!((v[3] - 7.5).abs() < 0.06, "{v:?}");
        // After the last tag too.
        assert_eq!(v[4], 0.0);
        let d: Vec<f64> = a.iter().map(|a| a.distance_m).collect();
        for (got, want) in d.iter().zip([100.0, 200.0, 200.0, 5.0, 400.0]) {
            assert!((got - want).abs() < 0.11, "{d:?}");
        }
    }

    /// Marks chosen and settled without any navigated place.
    fn settled(
        m: &MarksTable,
        ids: &[u32],
        path: &Path,
        in_log: impl Fn(i64) -> bool,
    ) -> (BTreeMap<u32, Vec<usize>>, Vec<RepeatedMark>) {
        choose_marks(m, ids, path, in_log)
            .unwrap()
            .settle(m, |_| None)
    }

    #[test]
    fn a_repeated_id_takes_its_last_mark_at_rest() {
        let tmp = tempfile::tempdir().unwrap();
        let path = odometer(tmp.path());
        let all = |_| true;
        // An early press while driving, then two at the stop; id 2 marked once.
        let m = marks(&[(15.0, 1), (25.0, 1), (26.0, 2), (30.0, 1)]);
        let (chosen, repeated) = settled(&m, &[1, 2], &path, all);
        assert_eq!(chosen[&1], [3]);
        assert_eq!(chosen[&2], [2]);
        assert_eq!(repeated.len(), 1);
        let r = &repeated[0];
        assert_eq!((r.id, r.marks, r.at_rest), (1, 3, true));
        assert!((r.used_t_s - 30.0).abs() < 1e-9 && (r.first_t_s - 15.0).abs() < 1e-9);
        assert!(r.visits_t_s.is_empty() && r.elsewhere_t_s.is_empty());

        // A press during the static start and one at a stop short of the point, both at
        // rest, corrected by the press at the point: the last.
        let m = marks(&[(25.0, 1), (70.0, 1), (79.0, 1)]);
        let (chosen, repeated) = settled(&m, &[1], &path, all);
        assert_eq!(chosen[&1], [2]);
        assert_eq!(repeated[0].elsewhere_t_s, [25.0]);

        // None at rest: the slowest.
        let m = marks(&[(10.0, 1), (40.5, 1), (50.0, 1), (55.0, 1)]);
        let (chosen, repeated) = settled(&m, &[1], &path, all);
        assert_eq!(chosen[&1], [1]);
        assert!(!repeated[0].at_rest);
        let v = repeated[0].used_speed_mps.unwrap();
        assert!((v - 7.5).abs() < 0.06, "{repeated:?}");

        // Marks outside the log do not count; with none inside, the first is kept (and
        // the match names it as outside the log).
        let m = marks(&[(25.0, 1), (35.0, 1)]);
        let (chosen, _) = settled(&m, &[1], &path, |t| t < 30_000_000_000);
        assert_eq!(chosen[&1], [0]);
        let (chosen, repeated) = settled(&m, &[1], &path, |_| false);
        assert_eq!(chosen[&1], [0]);
        assert_eq!(repeated[0].used_speed_mps, None);

        // Ids the manifest does not name are not read; no repeated id, no odometer read.
        let m = marks(&[(15.0, 7), (25.0, 7), (30.0, 1)]);
        let (chosen, repeated) = settled(&m, &[1], Path::new("/nonexistent/odometer.parquet"), all);
        assert_eq!((chosen.len(), &chosen[&1]), (1, &vec![2]));
        assert!(repeated.is_empty());
    }

    #[test]
    fn a_point_the_route_comes_back_to_is_visited_again() {
        let tmp = tempfile::tempdir().unwrap();
        let path = odometer(tmp.path());
        // At rest at 200 m (twice: one stop) and at 400 m, and a press driving between.
        let m = marks(&[(25.0, 1), (30.0, 1), (50.0, 1), (79.0, 1)]);
        let c = choose_marks(&m, &[1], &path, |_| true).unwrap();
        // One candidate per stop: the first stop's last press at rest, and the last.
        assert_eq!(c.to_place(), [1, 3]);
        // The navigation puts them 25 m apart, with 200 m of path between: within
        // 30 m + 3 %, the same place.
        let (used, repeated) = c
            .clone()
            .settle(&m, |i| Some(if i == 1 { [0.0, 0.0] } else { [15.0, 20.0] }));
        assert_eq!(used[&1], [1, 3]);
        let r = &repeated[0];
        let ms = |t: &[f64]| {
            t.iter()
                .map(|t| (t * 1e3).round() as i64)
                .collect::<Vec<_>>()
        };
        assert_eq!(
            (ms(&r.visits_t_s), ms(&[r.used_t_s])),
            (vec![30_000, 79_000], vec![79_000])
        );
        assert!(r.elsewhere_t_s.is_empty() && r.at_rest);
        // 40 m apart: elsewhere, a press the last corrected.
        let (used, repeated) = c.settle(&m, |i| Some([0.0, if i == 1 { 0.0 } else { 40.0 }]));
        assert_eq!(used[&1], [3]);
        assert_eq!(ms(&repeated[0].elsewhere_t_s), [30_000]);
        assert!(repeated[0].visits_t_s.is_empty());
        assert!(same_place(30.0, 0.0) && !same_place(30.1, 0.0) && same_place(330.0, 10_000.0));
    }

    #[test]
    fn a_mark_at_the_runs_start_is_not_a_visit() {
        let tmp = tempfile::tempdir().unwrap();
        // Standing until 10 s, then 200 m, standing after.
        let path = odometer_driving(tmp.path(), |s| 10.0 < s && s <= 30.0);
        let ms = |t: &[f64]| {
            t.iter()
                .map(|t| (t * 1e3).round() as i64)
                .collect::<Vec<_>>()
        };
        // Marked at rest during the static start and at the stop 200 m on: the site
        // stands for the start, so only the stop is a candidate (no place asked).
        let m = marks(&[(5.0, 1), (40.0, 1)]);
        let c = choose_marks(&m, &[1], &path, |_| true).unwrap();
        assert!(c.to_place().is_empty());
        let (used, repeated) = c.settle(&m, |_| None);
        assert_eq!(used[&1], [1]);
        assert_eq!(ms(&repeated[0].at_start_t_s), [5_000]);
        assert!(repeated[0].visits_t_s.is_empty() && repeated[0].elsewhere_t_s.is_empty());
        // Marked at the start only (twice): the last, as ever.
        let m = marks(&[(2.0, 1), (5.0, 1)]);
        let (used, repeated) = settled(&m, &[1], &path, |_| true);
        assert_eq!(used[&1], [1]);
        assert!(repeated[0].at_start_t_s.is_empty());
    }
}
