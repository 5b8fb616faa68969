//! A failure bridged again at the odometer's lag: a level drive that pulls away from a
//! stop during a failure, its odometer late, where the readings around the failure (at
//! rest before it, at a constant speed after it) do not show the lag.

use std::ops::Range;
use std::sync::Arc;

use unz_stages::derive::{Derived, MovedOdometer, OdoTimes, RawSeries};
use unz_stages::odo_rebridge::{FailedRows, MAX_REBRIDGED, Rebridges, WindowVelocities};
use unz_stages::time_base::TimeBase;

const G_MPS2: f64 = 9.81;
const DT_S: f64 = 0.01;
const PULSE_M: f64 = 0.0125;

/// A level drive of `n` samples whose along-track acceleration over the sample ending at
/// `t` is `accel(t)`, and its route's distance at `t` from the same acceleration.
struct Drive {
    derived: Derived,
    dvel_mps: Vec<[f64; 3]>,
    tags_ns: Vec<i64>,
}

impl Drive {
    fn new(n: usize, accel: impl Fn(f64) -> f64) -> Self {
        let tags_ns: Vec<i64> = (1..=n as i64).map(|k| k * 10_000_000).collect();
        let dvel_mps: Vec<[f64; 3]> = (1..=n)
            .map(|k| [accel(k as f64 * DT_S) * DT_S, 0.0, -G_MPS2 * DT_S])
            .collect();
        let derived = Derived {
            t0_ns: tags_ns[0],
            nominal_dt_s: DT_S,
            t_s: TimeBase::from_nanos(tags_ns.iter().map(|t| t - tags_ns[0])),
            dt_s: Arc::new(vec![DT_S; n]),
            dtheta_rad: Arc::new(vec![[0.0; 3]; n].into()),
            ..Derived::default()
        };
        Self {
            derived,
            dvel_mps,
            tags_ns,
        }
    }

    /// The velocity increments over `rows`, as the disupt stage reads them.
    fn velocity(&self) -> impl FnOnce(&[Range<usize>]) -> Result<WindowVelocities, ()> + '_ {
        |rows| {
            Ok(rows
                .iter()
                .map(|r| self.dvel_mps[r.clone()].to_vec())
                .collect())
        }
    }
}

/// Pulls away from a stop at 30 s at 1 m/s² to 10 m/s at 40 s, on to 100 s.
fn pull_away_m(t_s: f64) -> f64 {
    let a = (t_s - 30.0).clamp(0.0, 10.0);
    0.5 * a * a + 10.0 * (t_s - 40.0).max(0.0)
}

/// Whole pulses.
fn pulses(d_m: f64) -> f64 {
    (d_m / PULSE_M).round() * PULSE_M
}

/// The ingested distances of the pull-away with the odometer `lag_s` late, failed over
/// rows `[2500, 4500)` (25 to 45 s): held there, and `after_off_m` off after it (what an
/// ingest's bridge off by that much leaves).
fn ingested(drive: &Drive, lag_s: f64, after_off_m: f64) -> Vec<f64> {
    drive
        .tags_ns
        .iter()
        .enumerate()
        .map(|(k, t)| {
            let read = pulses(pull_away_m(*t as f64 * 1e-9 - lag_s));
            match k {
                ..2500 => read,
                2500..4500 => pulses(pull_away_m(25.0 - lag_s)),
                _ => read + after_off_m,
            }
        })
        .collect()
}

const FAILURE: [FailedRows; 1] = [FailedRows {
    first: 2500,
    len: 2000,
    bridged: true,
}];

#[test]
fn a_failure_from_a_stop_is_bridged_at_the_lag_given() {
    let lag_s = 0.4;
    let drive = Drive::new(10_000, |t| {
        if (30.0..40.0).contains(&(t - 0.5 * DT_S)) {
            1.0
        } else {
            0.0
        }
    });
    let odo = ingested(&drive, lag_s, -20.0);
    let r = Rebridges::new(
        &drive.derived,
        &odo,
        &FAILURE,
        G_MPS2,
        0.0,
        drive.velocity(),
    )
    .unwrap()
    .unwrap();
    // At the lag, the bridge is the route the late odometer would have read, and the
    // readings after it move back by what the ingest's bridge was off.
    let patch = r.patch_at(lag_s);
    let span = &patch.spans[0];
    assert_eq!((patch.spans.len(), span.first), (1, 2500));
    assert_eq!(span.distance_m.len(), 2000);
    let worst = span
        .distance_m
        .iter()
        .enumerate()
        .map(|(i, d)| (d - pull_away_m(drive.tags_ns[2500 + i] as f64 * 1e-9 - lag_s)).abs())
        .fold(0.0, f64::max);
    assert!(worst < 0.02, "bridged {worst} m off at the lag");
    assert!(
        (span.shift_after_m - 20.0).abs() < 0.02,
        "{}",
        span.shift_after_m
    );
    let changed = r.changes_at(lag_s);
    assert_eq!((changed.failures, changed.left), (1, 0));
    assert!(
        (changed.largest_change_m - 20.0).abs() < 0.02,
        "{changed:?}"
    );
    // On time, the bridge is off by about the lag times the change of speed (4 m).
    let off = r.patch_at(0.0).spans[0].shift_after_m - 20.0;
    assert!((2.0..6.0).contains(&off.abs()), "on time, off by {off} m");
    // A lag configured (the joint's zero 0.4 s late) is the lag's start.
    let configured = Rebridges::new(
        &drive.derived,
        &odo,
        &FAILURE,
        G_MPS2,
        lag_s,
        drive.velocity(),
    )
    .unwrap()
    .unwrap();
    assert_eq!(configured.patch_at(0.0), r.patch_at(lag_s));

    // A pass reads the route's increments through the patch: from the start to the end,
    // the odometer moved back onto the IMU's time by the lag, the route's distance.
    let raw = RawSeries {
        imu_t_ns: &[],
        dtheta_rad: &[],
        dvel_mps: &[],
        odo_t_ns: OdoTimes::Slice(&drive.tags_ns),
        odo_distance_m: &odo,
    };
    let patch_first = patch.spans[0].first;
    let moved = MovedOdometer::new(&drive.derived, &raw, -lag_s).patched(Some(patch));
    let mut d_m = 0.0;
    for (k, dd) in moved.increments().enumerate() {
        d_m += dd;
        // Up to the log's last lag (beyond, the odometer's last reading holds).
        if k % 500 == 499 && k < 9900 {
            let t_s = drive.tags_ns[k] as f64 * 1e-9;
            let want = pull_away_m(t_s);
            assert!(
                (d_m - want).abs() < 0.03,
                "at {t_s} s: {d_m} against {want}"
            );
        }
    }
    // Read from any sample on (a run's stretches integrated side by side), the
    // increments are the same, bit for bit: inside the patch's span, around it, at the
    // ends and past them.
    let all: Vec<u64> = moved.increments().map(f64::to_bits).collect();
    let p = patch_first;
    for k in [0, 1, 777, p - 1, p, p + 3, 9_999, all.len() - 1, all.len()] {
        let from: Vec<u64> = moved.increments_from(k).map(f64::to_bits).collect();
        assert!(from == all[k..], "from sample {k}");
    }
    assert_eq!(moved.increments_from(all.len() + 5).count(), 0);
    // Without the patch, the ingest's 20 m stay in the route.
    let unpatched: f64 = MovedOdometer::new(&drive.derived, &raw, -lag_s)
        .increments()
        .sum();
    assert!(
        (unpatched - d_m + 20.0).abs() < 0.03,
        "{unpatched} against {d_m}"
    );
}

/// Beyond [`MAX_REBRIDGED`] failures the longest are bridged again, the rest left; held
/// failures are never bridged, and bound the windows of their neighbours.
#[test]
fn the_longest_failures_are_bridged_again() {
    let n = 30_000;
    let drive = Drive::new(n, |_| 0.0);
    // A constant 10 m/s from the start (the odometer on time).
    let route = |k: usize| pulses(10.0 * drive.tags_ns[k] as f64 * 1e-9);
    let count = MAX_REBRIDGED + 6;
    // Failures every 4 s from 10 s, the first six 0.3 s long and the rest 0.5 s, held
    // over; and one held failure in the middle.
    let mut failed: Vec<FailedRows> = (0..count)
        .map(|i| FailedRows {
            first: 1000 + 400 * i,
            len: if i < 6 { 30 } else { 50 },
            bridged: true,
        })
        .collect();
    failed.push(FailedRows {
        first: 1000 + 400 * count + 100,
        len: 200,
        bridged: false,
    });
    let mut odo: Vec<f64> = (0..n).map(route).collect();
    for f in &failed {
        let held = odo[f.first - 1];
        odo[f.first..f.first + f.len].fill(held);
    }
    let r = Rebridges::new(&drive.derived, &odo, &failed, G_MPS2, 0.0, drive.velocity())
        .unwrap()
        .unwrap();
    let patch = r.patch_at(0.0);
    assert_eq!(patch.spans.len(), MAX_REBRIDGED);
    // The six shortest are left.
    assert_eq!(patch.spans[0].first, failed[6].first);
    for s in &patch.spans {
        for (i, d) in s.distance_m.iter().enumerate() {
            assert!((d - route(s.first + i)).abs() < 0.01, "row {}", s.first + i);
        }
        assert!(s.shift_after_m.abs() < 0.01, "{}", s.shift_after_m);
    }
    let changed = r.changes_at(0.0);
    assert_eq!((changed.failures, changed.left), (MAX_REBRIDGED, 6));
    // The held failure's rows are not a bridged failure's readings: without a bridged
    // one, nothing to bridge.
    let held_only = [failed[count]];
    let none = Rebridges::new(
        &drive.derived,
        &odo,
        &held_only,
        G_MPS2,
        0.0,
        drive.velocity(),
    )
    .unwrap();
    assert!(none.is_none());
    // Rows that are not the IMU's samples (a text log's odometer): nothing bridged again.
    let short = &odo[..n - 1];
    let none = Rebridges::new(
        &drive.derived,
        short,
        &failed,
        G_MPS2,
        0.0,
        drive.velocity(),
    )
    .unwrap();
    assert!(none.is_none());
}

/// A log that begins failed is bridged from the readings after it alone, from where the
/// ingest began it; one that ends failed, from those before it, its change measured to
/// its last row.
#[test]
fn failures_at_the_log_s_ends_are_bridged_again_from_one_side() {
    let n = 6000;
    let drive = Drive::new(n, |_| 0.0);
    // A constant 10 m/s, the odometer on time.
    let route = |k: usize| pulses(10.0 * drive.tags_ns[k] as f64 * 1e-9);
    let failed = [
        FailedRows {
            first: 0,
            len: 500,
            bridged: true,
        },
        FailedRows {
            first: 5000,
            len: 1000,
            bridged: true,
        },
    ];
    // The ingest began the route at 0 at the first row and held it over the failures;
    // the readings after the first are 3 m off (what its bridge left).
    let odo: Vec<f64> = (0..n)
        .map(|k| match k {
            ..500 => 0.0,
            500..5000 => route(k) - route(0) + 3.0,
            _ => route(4999) - route(0) + 3.0,
        })
        .collect();
    let r = Rebridges::new(&drive.derived, &odo, &failed, G_MPS2, 0.0, drive.velocity())
        .unwrap()
        .unwrap();
    let patch = r.patch_at(0.0);
    assert_eq!(patch.spans.len(), 2);
    let (first, last) = (&patch.spans[0], &patch.spans[1]);
    for (i, d) in first.distance_m.iter().enumerate() {
        let want = route(i) - route(0);
        assert!((d - want).abs() < 0.01, "row {i}: {d} against {want}");
    }
    // The readings after it move back by the 3 m.
    assert!(
        (first.shift_after_m + 3.0).abs() < 0.01,
        "{}",
        first.shift_after_m
    );
    // The last failure continues the moved readings before it.
    for (i, d) in last.distance_m.iter().enumerate() {
        let want = route(5000 + i) - route(0);
        assert!(
            (d - want).abs() < 0.02,
            "row {}: {d} against {want}",
            5000 + i
        );
    }
    // Its change: the distance it adds over the ingest's held one (1000 rows at 0.1 m).
    let changed = r.changes_at(0.0);
    assert_eq!((changed.failures, changed.left), (2, 0));
    assert!(
        (changed.largest_change_m - 100.0).abs() < 0.05,
        "{changed:?}"
    );
}
