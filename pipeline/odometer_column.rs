//! A text log's 8th column, the odometer's speed at each IMU sample: its gaps (speeds
//! beyond a land vehicle's, left out, while the IMU goes on) and its stands (zero speeds
//! while the vehicle may move: a logger that writes zero when it loses the speed) found,
//! judged and bridged as the log streams, as a speed file's are
//! ([`crate::odometer_gaps`]).
//!
//! One pass: the readings go through a [`GapFinder`]; the IMU's samples over the last
//! [`KEPT_S`] are kept for the windows of the gaps it finds (a gap is complete once its
//! window after it is read, at most [`MAX_BRIDGED_S`] and two windows after its
//! window's start); the readings a gap or a stand may still replace are held until it
//! is settled, then given out in order with the route's distance. Memory: those samples
//! and readings, whatever the log's length (a stand longer than the longest bridged
//! releases its readings older than that).

use std::collections::VecDeque;

use unz_formats::OdometerFailures;
use unz_stages::odo_bridge::WINDOW_S;

use crate::odometer_bridge::{Given, MAX_BRIDGED_S};
use crate::odometer_gaps::{BridgedGaps, Gap, GapFinder, ImuSample, tag_ns};

/// The IMU's samples kept, s: a gap's window reaches [`WINDOW_S`] before it, and a gap
/// or a stand's judged stretch is at most [`MAX_BRIDGED_S`] long, complete [`WINDOW_S`]
/// after it; a second to spare.
pub const KEPT_S: f64 = MAX_BRIDGED_S + 2.0 * WINDOW_S + 1.0;
/// The IMU's samples kept at most, whatever their time tags (tags that do not advance
/// would otherwise hold a log whole): [`KEPT_S`] at 1 kHz and more.
const MAX_KEPT_SAMPLES: usize = 150_000;
/// Readings held at most, whatever their time tags; beyond, the gaps and the stand not
/// complete are forgotten (left to the trapezoid, counted) and the older half of the
/// readings given out.
const MAX_PENDING: usize = 200_000;

/// The 8th column's readings and the IMU's samples, streamed; each reading given out with
/// the route's distance once no gap or stand can replace it.
pub struct ColumnBridger {
    finder: GapFinder,
    /// The IMU's samples over the last [`KEPT_S`].
    recent: VecDeque<ImuSample>,
    /// Readings not given out yet: time tag, ns, and distance as written, m.
    pending: VecDeque<(i64, f64)>,
    /// The gaps bridged and not yet given out, and how the failures were bridged.
    bridged: BridgedGaps,
    /// The IMU's samples since the last reading.
    unread: u64,
    /// The first sample's time tag, ns: the times inside are taken from it, so that a
    /// reading's time and its sample's are the same number whatever the log's epoch.
    origin_ns: Option<i64>,
    g_mps2: f64,
    lag_prior_s: f64,
}

impl ColumnBridger {
    /// A bridger at a site where gravity is `g_mps2`, the odometer's lag searched about
    /// `lag_prior_s` (the configured odometer time offset, negated).
    pub fn new(g_mps2: f64, lag_prior_s: f64) -> Self {
        Self {
            finder: GapFinder::default(),
            recent: VecDeque::new(),
            pending: VecDeque::new(),
            bridged: BridgedGaps::default(),
            unread: 0,
            origin_ns: None,
            g_mps2,
            lag_prior_s,
        }
    }

    /// Takes the next IMU sample (its time tag, ns, and increments), with the column's
    /// reading there if it has one: the trapezoid's distance, m, and the distance as
    /// written (through the odometer's range check), m. The readings settled go to
    /// `out`, in order, after the rows of the gaps bridged before them.
    pub fn sample(
        &mut self,
        (t_ns, dtheta_rad, dvel_mps): ImuSample,
        reading: Option<(f64, f64)>,
        mut out: impl FnMut(i64, Given),
    ) {
        let origin_ns = *self.origin_ns.get_or_insert(t_ns);
        let since_ns = t_ns.saturating_sub(origin_ns);
        let t_s = since_ns as f64 * 1e-9;
        self.recent.push_back((since_ns, dtheta_rad, dvel_mps));
        while self.recent.len() > MAX_KEPT_SAMPLES
            || (self.recent.front()).is_some_and(|s| t_s - s.0 as f64 * 1e-9 > KEPT_S)
        {
            self.recent.pop_front();
        }
        let Some((trapezoid_m, written_m)) = reading else {
            self.unread += 1;
            self.finder.read_to(t_s);
            for g in self.finder.take_complete() {
                self.close(g);
            }
            return;
        };
        if self.finder.push((t_s, trapezoid_m)) && self.finder.take_long_gap().is_some() {
            // Too long to bridge: the trapezoid stays, its samples counted.
            let f = self.bridged.failures_mut();
            f.file_gaps += 1;
            f.not_bridged += 1;
            f.not_bridged_samples += self.unread;
        }
        self.unread = 0;
        self.pending.push_back((since_ns, written_m));
        for g in self.finder.take_complete() {
            self.close(g);
        }
        if self.pending.len() > MAX_PENDING {
            let forgotten = self.finder.forget_unsettled();
            let f = self.bridged.failures_mut();
            f.file_gaps += forgotten;
            f.not_bridged += forgotten;
            // The oldest half goes out now, whatever may still replace it: with tags that
            // do not advance nothing settles (each reading is at the time a stand may
            // begin from), and every reading would forget again, copying the window
            // before it each time (a 300 000-line log took 68 s).
            let origin_ns = self.origin_ns.unwrap_or(0);
            while self.pending.len() > MAX_PENDING / 2 {
                let Some((t_ns, d)) = self.pending.pop_front() else {
                    break;
                };
                (self.bridged).give(t_ns, d, |t, given| out(t.saturating_add(origin_ns), given));
            }
        }
        self.release(out);
    }

    /// Bridges a complete gap or stand with the IMU's samples over its window.
    fn close(&mut self, g: Gap) {
        if !g.is_stand() {
            self.bridged.failures_mut().file_gaps += 1;
        }
        let (first_s, last_s) = g.span_s();
        let samples: Vec<ImuSample> = (self.recent.iter())
            .filter(|s| (first_s..=last_s).contains(&(s.0 as f64 * 1e-9)))
            .copied()
            .collect();
        self.bridged
            .close(g, samples, self.g_mps2, self.lag_prior_s);
    }

    /// Gives out the readings no gap or stand can replace any more.
    fn release(&mut self, mut out: impl FnMut(i64, Given)) {
        let origin_ns = self.origin_ns.unwrap_or(0);
        let unsettled_ns = self.finder.unsettled_from_s().map(tag_ns);
        while let Some(&(t_ns, d)) = self.pending.front() {
            if unsettled_ns.is_some_and(|u| t_ns >= u) {
                break;
            }
            self.pending.pop_front();
            (self.bridged).give(t_ns, d, |t, given| out(t.saturating_add(origin_ns), given));
        }
    }

    /// Bridges the gaps still collecting their readings after them with the samples
    /// kept, gives out the readings held, and returns how the failures were bridged.
    pub fn finish(mut self, mut out: impl FnMut(i64, Given)) -> OdometerFailures {
        let (rest, more) = std::mem::take(&mut self.finder).finish();
        for g in rest {
            self.close(g);
        }
        let f = self.bridged.failures_mut();
        f.file_gaps += more;
        f.not_bridged += more;
        self.release(&mut out);
        self.bridged.failures().clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::odometer_gaps::{GapBridger, find_gaps};
    use proptest::strategy::Strategy as _;
    use unz_formats::schema::DistanceSource;

    /// Tags that do not advance, the column's speed standing at zero (a damaged log):
    /// once the readings held reached their bound, every reading forgot the stand and
    /// opened another, copying the window before it (a 300 000-line log took 68 s, one of
    /// 1.5 million more than ten minutes). Now the oldest half goes out: every reading
    /// comes out once, within a deadline the old way misses by minutes.
    #[test]
    fn tags_that_do_not_advance_stream_through() {
        let n = 2 * MAX_PENDING + 50_000;
        let (done, result) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut b = ColumnBridger::new(9.81, 0.0);
            let mut rows = 0_usize;
            let mut count = |_: i64, _: Given| rows += 1;
            let at_rest = (5_000_000_000, [0.0; 3], [0.0, 0.0, -0.0981]);
            for _ in 0..n {
                b.sample(at_rest, Some((0.0, 0.0)), &mut count);
            }
            b.finish(&mut count);
            done.send(rows).unwrap();
        });
        let rows = (result.recv_timeout(std::time::Duration::from_secs(60)))
            .expect("the column's bridge did not stream through in 60 s");
        assert_eq!(rows, n);
    }

    /// What a stretch of the column says.
    #[derive(Debug, Clone, Copy)]
    enum Stretch {
        /// The speed, m/s, at every sample.
        Speed(f64),
        /// Zero at every sample.
        Zero,
        /// No reading (speeds beyond a land vehicle's).
        Missing,
    }

    /// A 10-Hz column over `stretches` (each its kind and length in samples), from
    /// t = 0: the readings (time, s, and the trapezoid's distance, m), one per sample
    /// or none.
    fn column(stretches: &[(Stretch, usize)]) -> Vec<Option<(f64, f64)>> {
        let mut out = Vec::new();
        let mut prev: Option<(f64, f64, f64)> = None;
        for &(kind, n) in stretches {
            for _ in 0..n {
                let t_s = (out.len() as i64 * 100_000_000) as f64 * 1e-9;
                let v = match kind {
                    Stretch::Speed(v) => v,
                    Stretch::Zero => 0.0,
                    Stretch::Missing => {
                        out.push(None);
                        continue;
                    }
                };
                let d = prev.map_or(0.0, |(t0, v0, d0)| d0 + 0.5 * (v0 + v) * (t_s - t0));
                prev = Some((t_s, v, d));
                out.push(Some((t_s, d)));
            }
        }
        out
    }

    /// The rows and the failures of a speed file's three passes over `readings`
    /// ([`find_gaps`], [`GapBridger`], [`BridgedGaps::give`]) and of the stream's one
    /// pass, over the same IMU samples.
    fn both(
        readings: &[Option<(f64, f64)>],
        imu: impl Fn(usize) -> ImuSample,
    ) -> [(Vec<(i64, Given)>, OdometerFailures); 2] {
        let mut it = readings.iter().flatten().copied();
        let (gaps, more) = find_gaps(|| Ok::<_, ()>(it.next())).unwrap();
        let mut bridger = GapBridger::new(gaps, more, 9.81, 0.0);
        for k in 0..readings.len() {
            let (t_ns, dtheta, dvel) = imu(k);
            bridger.sample(t_ns, dtheta, dvel);
        }
        let mut bridged = bridger.finish();
        let mut file_rows = Vec::new();
        for &(t_s, d) in readings.iter().flatten() {
            bridged.give(tag_ns(t_s), d, |t, g| file_rows.push((t, g)));
        }
        let mut stream = ColumnBridger::new(9.81, 0.0);
        let mut rows = Vec::new();
        for (k, r) in readings.iter().enumerate() {
            stream.sample(imu(k), r.map(|(_, d)| (d, d)), |t, g| rows.push((t, g)));
        }
        let f = stream.finish(|t, g| rows.push((t, g)));
        [(file_rows, bridged.failures().clone()), (rows, f)]
    }

    /// A vehicle driving along its x axis on level ground at 10-Hz samples: speeding up
    /// by `accel_mps2(k)` at sample `k`.
    fn level(accel_mps2: impl Fn(usize) -> f64) -> impl Fn(usize) -> ImuSample {
        move |k| {
            let dvel = [accel_mps2(k) * 0.1, 0.0, -0.981];
            (k as i64 * 100_000_000, [0.0; 3], dvel)
        }
    }

    #[test]
    fn a_speed_that_stood_while_driving_is_bridged_and_a_stop_is_not() {
        // 10 m/s for 30 s, the column zero for 20 s while the IMU drives on, then 10 m/s
        // again: one stand, found moving, bridged at 10 m/s.
        let readings = column(&[
            (Stretch::Speed(10.0), 300),
            (Stretch::Zero, 200),
            (Stretch::Speed(10.0), 300),
        ]);
        let [file, (rows, f)] = both(&readings, level(|_| 0.0));
        assert_eq!((f.stuck, f.bridged, f.file_gaps), (1, 1, 0), "{f:?}");
        // From the last reading at 10 m/s to the first again: 20.1 s.
        assert!((f.bridged_distance_m - 201.0).abs() < 0.1, "{f:?}");
        assert_eq!(file, (rows.clone(), f));
        assert_eq!(rows.len(), 800);
        let last = rows.last().unwrap().1.0;
        assert!((last - 799.0).abs() < 1.0, "{last} m");

        // Braking at 2 m/s² to rest, standing 20 s, driving off at 2 m/s²: the
        // column's own distances, bridged nowhere.
        let v = |k: usize| match k {
            0..300 => 10.0,
            300..350 => 10.0 - 0.2 * (k - 300) as f64,
            350..550 => 0.0,
            550..600 => 0.2 * (k - 550) as f64,
            _ => 10.0,
        };
        let a = move |k: usize| (v(k + 1) - v(k)) * 10.0;
        let stretches: Vec<(Stretch, usize)> = (0..800)
            .map(|k| match v(k) {
                0.0 => (Stretch::Zero, 1),
                s => (Stretch::Speed(s), 1),
            })
            .collect();
        let readings = column(&stretches);
        let [file, (rows, f)] = both(&readings, level(a));
        assert_eq!(f, OdometerFailures::default());
        assert_eq!(file, (rows.clone(), f));
        let given: Vec<(i64, Given)> = (readings.iter().flatten())
            .map(|&(t, d)| (tag_ns(t), (d, DistanceSource::Reading)))
            .collect();
        assert_eq!(rows, given);
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(48))]

        /// A hostile log's time tags (steps of −1 to 1 s, repeated, going back) with any
        /// speeds and increments: no panic, the distances finite, each reading given out
        /// once at most, and the counts adding up.
        #[test]
        fn tags_that_stand_or_go_back_break_nothing(
            steps in proptest::collection::vec(
                (proptest::prop_oneof![3 => 0.01f64..0.011, 1 => -1.0f64..1.0], 0.0f64..3.0),
                1..3000,
            ),
        ) {
            let mut stream = ColumnBridger::new(9.81, 0.0);
            let mut rows = Vec::new();
            let (mut t_s, mut d) = (100.0, 0.0);
            for &(dt, v) in &steps {
                t_s += dt;
                d += if dt > 0.0 && v > 1.0 { v * dt } else { 0.0 };
                let imu = (tag_ns(t_s), [0.0; 3], [0.0, 0.0, -0.0981]);
                stream.sample(imu, Some((d, d)), |t, g| rows.push((t, g)));
            }
            let f = stream.finish(|t, g| rows.push((t, g)));
            proptest::prop_assert!(rows.iter().all(|r| r.1.0.is_finite()));
            let given = rows.iter().filter(|r| r.1.1 == DistanceSource::Reading).count();
            proptest::prop_assert!(given <= steps.len());
            proptest::prop_assert_eq!(f.bridged + f.not_bridged, f.file_gaps + f.stuck);
        }

        /// Any column (speeds, zeros and missing readings in stretches of up to 200 s)
        /// over any IMU increments: the stream gives the rows and the failures the speed
        /// file's three passes give, in time order, every reading once (or its bridge's
        /// row in its place).
        #[test]
        fn the_stream_gives_what_the_three_passes_give(
            stretches in proptest::collection::vec(
                (
                    proptest::prop_oneof![
                        3 => (0.5f64..30.0).prop_map(Stretch::Speed),
                        2 => proptest::strategy::Just(Stretch::Zero),
                        1 => proptest::strategy::Just(Stretch::Missing),
                    ],
                    proptest::prop_oneof![3 => 1usize..60, 1 => 60usize..2000],
                ),
                1..12,
            ),
            imu in proptest::collection::vec(
                (proptest::array::uniform3(-0.05f64..0.05), proptest::array::uniform3(-1.5f64..1.5)),
                64,
            ),
        ) {
            let readings = column(&stretches);
            let sample = |k: usize| {
                let (dtheta, dvel) = imu[k % imu.len()];
                let dvel = [dvel[0] * 0.1, dvel[1] * 0.1, -0.981 + dvel[2] * 0.01];
                (k as i64 * 100_000_000, dtheta.map(|w| w * 0.1), dvel)
            };
            let [file, (rows, f)] = both(&readings, sample);
            proptest::prop_assert_eq!(&file, &(rows.clone(), f.clone()));
            proptest::prop_assert!(rows.windows(2).all(|w| w[0].0 < w[1].0));
            proptest::prop_assert!(rows.iter().all(|r| r.1.0.is_finite()));
            proptest::prop_assert_eq!(f.bridged + f.not_bridged, f.file_gaps + f.stuck);
            let given = rows.iter().filter(|r| r.1.1 == DistanceSource::Reading).count();
            let replaced = readings.iter().flatten().count() - given;
            let bridged = rows.len() - given;
            proptest::prop_assert!(replaced <= bridged);
        }
    }
}
