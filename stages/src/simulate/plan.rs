//! Random but realistic routes: a static start, drives of 5–15 m/s with turns, hills and
//! side slopes, intermediate stops, a mid-route and a final stop on control points; or
//! such a route driven out and back, its control points visited twice.

use rand::Rng;

use super::route::{Motion, Profile, Pulse};

/// Peak lateral acceleration allowed in turns, m/s².
const MAX_LATERAL_MPS2: f64 = 2.0;

/// A stop on a surveyed control point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlannedStop {
    /// Control-point id.
    pub id: u32,
    /// Time the vehicle is at rest, s.
    pub start_s: f64,
    /// Time it moves again (or the end of the run), s.
    pub end_s: f64,
}

/// A planned route: the motion and its control-point stops.
#[derive(Debug, Clone, PartialEq)]
pub struct RoutePlan {
    /// The motion profiles.
    pub motion: Motion,
    /// Control-point stops, in time order (the last is the final stop).
    pub stops: Vec<PlannedStop>,
    /// Intervals where the vehicle is at rest (start, end), s.
    pub rests: Vec<(f64, f64)>,
}

/// Plans a route of `duration_s` with a static start of `static_s`. With
/// `cp_at_every_stop`, every intermediate stop is on a control point too (numbered in
/// time order); the route itself is the same.
pub fn plan_route(
    rng: &mut impl Rng,
    duration_s: f64,
    static_s: f64,
    heading0_rad: f64,
    cp_at_every_stop: bool,
) -> RoutePlan {
    let end_drive = duration_s - final_stop_s(duration_s);
    let mid_target = static_s + 0.5 * (end_drive - static_s);
    let (mut accel, mut yaw, mut pitch, mut roll) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut stops = Vec::new();
    let mut rests = vec![(0.0, static_s)];
    let mut t = static_s;
    let mut v = 0.0;
    let mut mid_done = duration_s < 600.0; // short runs have the final control point only
    while t < end_drive {
        let target: f64 = rng.random_range(4.0..12.0);
        let a_peak: f64 = rng.random_range(0.8..1.8);
        let t_acc = 2.0 * (target - v).abs() / a_peak;
        let t_dec = 2.0 * target / 1.2;
        if t + t_acc + 10.0 + t_dec > end_drive {
            if v > 0.0 {
                accel.push(Pulse {
                    t0_s: t,
                    dur_s: 2.0 * v / 1.2,
                    amp: -1.2,
                });
                t += 2.0 * v / 1.2;
            }
            break;
        }
        accel.push(Pulse {
            t0_s: t,
            dur_s: t_acc,
            amp: (target - v).signum() * a_peak,
        });
        t += t_acc;
        v = target;
        let cruise = rng.random_range(30.0..150.0_f64).min(end_drive - t - t_dec);
        cruise_events(rng, t, t + cruise, v, &mut yaw, &mut pitch, &mut roll);
        t += cruise;
        let stop_here = rng.random_bool(0.6) || (!mid_done && t > mid_target);
        if stop_here {
            let dec_peak: f64 = rng.random_range(0.8..1.5);
            let t_dec = 2.0 * v / dec_peak;
            accel.push(Pulse {
                t0_s: t,
                dur_s: t_dec,
                amp: -dec_peak,
            });
            t += t_dec;
            v = 0.0;
            let rest = if !mid_done && t > mid_target {
                mid_done = true;
                stops.push(PlannedStop {
                    id: 1,
                    start_s: t,
                    end_s: t + 40.0,
                });
                40.0
            } else {
                let rest = rng.random_range(15.0..70.0);
                if cp_at_every_stop {
                    stops.push(PlannedStop {
                        id: 0,
                        start_s: t,
                        end_s: t + rest,
                    });
                }
                rest
            };
            rests.push((t, t + rest));
            t += rest;
        }
    }
    if cp_at_every_stop {
        for (i, stop) in stops.iter_mut().enumerate() {
            stop.id = i as u32 + 1;
        }
    }
    // Whatever remains is the final stop.
    let last_rest = t;
    stops.push(PlannedStop {
        id: stops.len() as u32 + 1,
        start_s: last_rest,
        end_s: duration_s,
    });
    rests.push((last_rest, duration_s));
    RoutePlan {
        motion: Motion {
            heading0_rad,
            accel: Profile::new(accel),
            yaw_rate: Profile::new(yaw),
            pitch: Profile::new(pitch),
            roll: Profile::new(roll),
            pitch0_rad: 0.0,
            roll0_rad: 0.0,
        },
        stops,
        rests,
    }
}

/// The final stop of a route of `duration_s`, s: a tenth of it, within 20–60 s.
fn final_stop_s(duration_s: f64) -> f64 {
    60.0_f64.min(0.1 * duration_s).max(20.0)
}

/// How long the turn about at the far end of an out-and-back route takes, s.
pub const PIVOT_S: f64 = 16.0;
/// Least time the vehicle stands at the far end before and after the turn about, s.
pub const FAR_REST_S: f64 = 10.0;

/// Plans an out-and-back route of `duration_s` with a static start of `static_s`: a route
/// of [`plan_route`] driven out over about half of it, a turn about on the spot at its
/// last stop (a pivot turn, as a tracked vehicle makes: 180° in [`PIVOT_S`]), and the
/// same path driven back to the start, where the vehicle stops to the end. Every stop
/// out is made again at the same place on the way back, with its control point when it
/// has one, so those points are visited twice (the far one once, within its stop); the
/// stop at the start has a point of its own (the last id). The drive back is the drive
/// out reversed in time: speed, turns, grades and side slopes mirrored, so the path is
/// the same (grades and side slopes change sign in the direction of travel). The
/// constant tilt of [`Motion`] must stay zero for the heights to close.
pub fn plan_out_and_back(
    rng: &mut impl Rng,
    duration_s: f64,
    static_s: f64,
    heading0_rad: f64,
    cp_at_every_stop: bool,
) -> RoutePlan {
    // The time the drive back mirrors: the middle of the turn about.
    let mirror_s = 0.5 * (duration_s - final_stop_s(duration_s) + static_s);
    // A route's last stop may begin after its planned end (a long stop near it): drawn
    // again then, as the turn about needs its time before the mirror.
    let fits = |r: &RoutePlan| {
        r.stops
            .last()
            .is_some_and(|s| s.start_s <= mirror_s - FAR_REST_S)
    };
    let mut draw = || {
        plan_route(
            rng,
            mirror_s - FAR_REST_S,
            static_s,
            heading0_rad,
            cp_at_every_stop,
        )
    };
    let mut out = draw();
    for _ in 0..100 {
        if fits(&out) {
            break;
        }
        out = draw();
    }
    let mirror_s = mirror_s.max(out.stops.last().map_or(0.0, |s| s.start_s) + FAR_REST_S);
    let back = |t: f64| 2.0 * mirror_s - t;
    let mirrored = |p: &Profile, extra: Option<Pulse>| {
        let pulses = p.pulses().iter().flat_map(|q| {
            [
                *q,
                Pulse {
                    t0_s: back(q.t0_s + q.dur_s),
                    dur_s: q.dur_s,
                    amp: -q.amp,
                },
            ]
        });
        Profile::new(pulses.chain(extra).collect())
    };
    let pivot = Pulse {
        t0_s: mirror_s - 0.5 * PIVOT_S,
        dur_s: PIVOT_S,
        amp: std::f64::consts::TAU / PIVOT_S,
    };
    let m = &out.motion;
    let motion = Motion {
        heading0_rad,
        accel: mirrored(&m.accel, None),
        yaw_rate: mirrored(&m.yaw_rate, Some(pivot)),
        pitch: mirrored(&m.pitch, None),
        roll: mirrored(&m.roll, None),
        pitch0_rad: 0.0,
        roll0_rad: 0.0,
    };
    // The far stop spans the turn about; every other stop out is made again on the way
    // back, in reverse order.
    let end_id = out.stops.iter().map(|s| s.id).max().unwrap_or(0) + 1;
    let (far, mut before) = out.stops.split_last().expect("a route has a final stop");
    let (mut far_rest, mut rests_out) = out.rests.split_last().expect("a route has a final rest");
    let mut far = *far;
    // A route's last stop may follow its stop before without a drive between (the route
    // ran out of time there): one stop, under the earlier one's id.
    if let Some((last, rest)) = before.split_last()
        && last.end_s >= far.start_s
    {
        far = PlannedStop {
            id: last.id,
            start_s: last.start_s,
            ..far
        };
        before = rest;
        let (last_rest, rest) = rests_out.split_last().expect("a stop has its rest");
        far_rest = last_rest;
        rests_out = rest;
    }
    let mut stops = before.to_vec();
    stops.push(PlannedStop {
        end_s: back(far.start_s),
        ..far
    });
    stops.extend(before.iter().rev().map(|s| PlannedStop {
        id: s.id,
        start_s: back(s.end_s),
        end_s: back(s.start_s),
    }));
    let home_s = back(static_s);
    stops.push(PlannedStop {
        id: end_id,
        start_s: home_s,
        end_s: duration_s,
    });
    let mut rests = rests_out.to_vec();
    rests.push((far_rest.0, back(far_rest.0)));
    rests.extend(
        rests_out[1..]
            .iter()
            .rev()
            .map(|&(a, b)| (back(b), back(a))),
    );
    rests.push((home_s, duration_s));
    RoutePlan {
        motion,
        stops,
        rests,
    }
}

/// Turns, hills and side slopes inside a cruise at constant speed `v` over `[c0, c1]`.
fn cruise_events(
    rng: &mut impl Rng,
    c0: f64,
    c1: f64,
    v: f64,
    yaw: &mut Vec<Pulse>,
    pitch: &mut Vec<Pulse>,
    roll: &mut Vec<Pulse>,
) {
    let mut ts = c0 + rng.random_range(2.0..10.0);
    loop {
        let dpsi: f64 = rng.random_range(15f64.to_radians()..100f64.to_radians()) * sign(rng);
        let dur = (2.0 * dpsi.abs() * v / MAX_LATERAL_MPS2).max(3.0);
        if ts + dur > c1 {
            break;
        }
        yaw.push(Pulse {
            t0_s: ts,
            dur_s: dur,
            amp: 2.0 * dpsi / dur,
        });
        ts += dur + rng.random_range(5.0..40.0);
    }
    for (channel, lo_deg, hi_deg, dur_lo, dur_hi) in
        [(pitch, 1.0, 5.0, 8.0, 30.0), (roll, 0.5, 3.0, 5.0, 20.0)]
    {
        let mut ts = c0 + rng.random_range(1.0..15.0);
        loop {
            let dur = rng.random_range(dur_lo..dur_hi);
            if ts + dur > c1 {
                break;
            }
            let amp =
                rng.random_range(f64::to_radians(lo_deg)..f64::to_radians(hi_deg)) * sign(rng);
            channel.push(Pulse {
                t0_s: ts,
                dur_s: dur,
                amp,
            });
            ts += dur + rng.random_range(3.0..30.0);
        }
    }
}

fn sign(rng: &mut impl Rng) -> f64 {
    if rng.random_bool(0.5) { 1.0 } else { -1.0 }
}
