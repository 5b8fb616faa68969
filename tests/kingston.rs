//! Real data: the Kingston 2008 segment (HG1700 IMU at 10 Hz, OBD-II speed at 1 Hz,
//! NovAtel SPAN reference). See tests/data/kingston2008-seg1/README.md.

use unz::flow::{Overrides, Params, RunCtx, load_case};
use unz::runs::load_run;
use unz_stages::attitude::wrap_pi;
use unz_stages::criteria;
use unz_stages::strapdown::NavTrack;

use crate::util::{read_json, test_data};

/// The reference at 1 Hz: t_s, position (latitude, longitude in degrees, height in m),
/// roll, pitch, azimuth (degrees), speed (m/s).
struct Reference {
    t_s: Vec<f64>,
    position: Vec<[f64; 3]>,
    roll: Vec<f64>,
    pitch: Vec<f64>,
    azimuth: Vec<f64>,
    speed: Vec<f64>,
    /// Direction of travel, degrees from north.
    track: Vec<f64>,
}

fn reference() -> Reference {
    let text = std::fs::read_to_string(test_data("kingston2008-seg1").join("truth.csv")).unwrap();
    let mut r = Reference {
        t_s: vec![],
        position: vec![],
        roll: vec![],
        pitch: vec![],
        azimuth: vec![],
        speed: vec![],
        track: vec![],
    };
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        r.t_s.push(v[0]);
        r.position.push([v[1], v[2], v[3]]);
        r.speed.push(v[4].hypot(v[5]));
        r.track.push(v[5].atan2(v[4]).to_degrees());
        r.roll.push(v[7]);
        r.pitch.push(v[8]);
        r.azimuth.push(v[9]);
    }
    r
}

/// Navigation interpolated to the reference's epochs: (roll, pitch, heading) in degrees.
fn at_reference(track: &NavTrack, t0_s: f64, t_s: &[f64], r: &Reference) -> Vec<(usize, [f64; 3])> {
    let (roll, pitch, heading) = track.euler_columns();
    let lerp = |a: f64, b: f64, w: f64| a + w * wrap_pi(b - a);
    r.t_s
        .iter()
        .enumerate()
        .filter_map(|(i, &t)| {
            let k = t_s.partition_point(|&x| x + t0_s < t);
            if k == 0 || k >= t_s.len() {
                return None;
            }
            let w = (t - t0_s - t_s[k - 1]) / (t_s[k] - t_s[k - 1]);
            let v = |c: &[f64]| lerp(c[k - 1], c[k], w).to_degrees();
            Some((i, [v(&roll), v(&pitch), v(&heading)]))
        })
        .collect()
}

#[test]
fn kingston_gyrocompass_heading_changes_attitude_and_control_points() {
    let out = tempfile::tempdir().unwrap();
    let ctx = RunCtx::new(
        load_run(&test_data("kingston2008-seg1")).unwrap(),
        out.path().to_path_buf(),
        false,
    );
    let case = load_case(&ctx, &Params::default(), &Overrides::default()).unwrap();
    let mut track = NavTrack::default();
    case.navigate(&mut track);
    let r = reference();
    let t0_s = case.derived.t0_ns as f64 * 1e-9;
    let pairs = at_reference(&track, t0_s, &case.derived.t_s.to_vec(), &r);
    assert!(
        pairs.len() > 850,
        "{} reference epochs matched",
        pairs.len()
    );

    // The car starts moving when the reference speed first exceeds 1 m/s; the reference
    // heading has settled 60 s later (data README).
    let i_move = r.speed.iter().position(|&v| v > 1.0).unwrap();
    let settle = i_move + 60;
    let yaw_rate_ref = |i: usize| -> f64 {
        let (a, b) = (i.saturating_sub(1), (i + 1).min(r.t_s.len() - 1));
        wrap_pi((r.azimuth[b] - r.azimuth[a]).to_radians())
            .to_degrees()
            .abs()
            / (r.t_s[b] - r.t_s[a])
    };
    // e = navigated − reference heading over the settled part. Its median is the initial
    // heading error (the gyrocompass's error against the settled reference); e − median
    // is how far the heading *changes* stray from the reference's.
    let errs: Vec<(usize, f64)> = pairs
        .iter()
        .filter(|(i, _)| *i >= settle)
        .map(|&(i, nav)| {
            (
                i,
                wrap_pi((nav[2] - r.azimuth[i]).to_radians()).to_degrees(),
            )
        })
        .collect();
    let mut sorted: Vec<f64> = errs.iter().map(|e| e.1).collect();
    sorted.sort_by(f64::total_cmp);
    let gc_err = sorted[sorted.len() / 2];
    // A 1 Hz reference cannot time a 20°/s turn better than a few tens of ms (0.4° per
    // 20 ms): headings are compared where the reference turns slower than 10°/s, and
    // everywhere within 1°.
    let steady = |i: usize| yaw_rate_ref(i) < 10.0;
    let worst_change = errs
        .iter()
        .filter(|(i, _)| steady(*i))
        .map(|(_, e)| (e - gc_err).abs())
        .fold(0.0, f64::max);
    let worst_change_all = errs
        .iter()
        .map(|(_, e)| (e - gc_err).abs())
        .fold(0.0, f64::max);
    let worst_roll = pairs
        .iter()
        .map(|&(i, nav)| (nav[0] - r.roll[i]).abs())
        .fold(0.0, f64::max);
    let worst_pitch = pairs
        .iter()
        .map(|&(i, nav)| (nav[1] - r.pitch[i]).abs())
        .fold(0.0, f64::max);
    let cps = criteria::kryt2(&track, &case.fixes);
    eprintln!(
        "Kingston: gyrocompass {:.2}° (σ {:.1}°), error against the settled reference {gc_err:.2}°; \
         max heading-change error {worst_change:.3}° ({worst_change_all:.3}° in fast turns too); max roll error {worst_roll:.3}°, pitch {worst_pitch:.3}°",
        case.initial.azimuth_deg,
        case.initial.gyrocompass_sigma_deg.unwrap()
    );
    for cp in &cps {
        eprintln!(
            "Kingston control point {}: ΔX {:.1} m, ΔY {:.1} m, Kryt2 {:.1} m",
            cp.id, cp.dx_m, cp.dy_m, cp.kryt2_m
        );
    }
    assert!(gc_err.abs() < 3.0, "gyrocompass off by {gc_err}°");
    assert!(worst_change < 0.5, "heading changes off by {worst_change}°");
    assert!(
        worst_change_all < 1.0,
        "heading changes off by {worst_change_all}° in a turn"
    );
    assert!(
        worst_roll < 0.3 && worst_pitch < 0.3,
        "roll {worst_roll}°, pitch {worst_pitch}°"
    );
    assert_eq!(cps.len(), 2);
    // Town driving of 2.4 km with a heading error of a few degrees: tens of metres at most.
    assert!(cps.iter().all(|c| c.kryt2_m < 100.0), "{cps:?}");
}

/// Median |navigated − reference| heading over the settled moving part, degrees.
fn median_heading_error(track: &NavTrack, t0_s: f64, t_s: &[f64], r: &Reference) -> f64 {
    let settle = r.speed.iter().position(|&v| v > 1.0).unwrap() + 60;
    let mut e: Vec<f64> = at_reference(track, t0_s, t_s, r)
        .into_iter()
        .filter(|(i, _)| *i >= settle && r.speed[*i] > 1.0)
        .map(|(i, nav)| {
            wrap_pi((nav[2] - r.azimuth[i]).to_radians())
                .to_degrees()
                .abs()
        })
        .collect();
    e.sort_by(f64::total_cmp);
    e[e.len() / 2]
}

#[test]
fn kingston_disupt_corrects_the_gyrocompass_heading() {
    use unz::disupt_stage::problem_of;
    use unz_stages::disupt::{DisuptParams, joint, oepi};

    let out = tempfile::tempdir().unwrap();
    let ctx = RunCtx::new(
        load_run(&test_data("kingston2008-seg1")).unwrap(),
        out.path().to_path_buf(),
        false,
    );
    let params = Params::default();
    let case = load_case(&ctx, &params, &Overrides::default()).unwrap();
    let problem = problem_of(&case, &params);
    let r = reference();
    let t0_s = case.derived.t0_ns as f64 * 1e-9;
    let mut track = NavTrack::default();
    let mut judge = |x: unz_stages::disupt::X| {
        unz_stages::strapdown::navigate(&case.inputs(), &problem.settings(&x), &mut track);
        (
            median_heading_error(&track, t0_s, &case.derived.t_s.to_vec(), &r),
            criteria::kryt2(&track, &case.fixes),
        )
    };
    let (before, cps_before) = judge(problem.x0());
    let dp = DisuptParams::default();
    let o = oepi(&problem, &dp).unwrap();
    let j = joint(&problem, &dp).unwrap();
    let (after_oepi, cps_oepi) = judge(o.x);
    let (after_joint, cps_joint) = judge(j.x);
    eprintln!(
        "Kingston median heading error over the moving part: gyrocompass {before:.2}°, OEPI {after_oepi:.2}° (az {:.3}°), joint {after_joint:.2}° (az {:.3}° ± {:.3}°)",
        o.x.azimuth_deg,
        j.x.azimuth_deg,
        j.sigma.unwrap().azimuth_deg
    );
    eprintln!(
        "Kingston control point 2: before {:.1} m, OEPI {:.1} m, joint {:.1} m",
        cps_before[1].kryt2_m, cps_oepi[1].kryt2_m, cps_joint[1].kryt2_m
    );
    assert!(after_oepi < 0.6, "OEPI {after_oepi}°");
    assert!(after_joint < 0.5, "joint {after_joint}°");
    assert!(
        cps_oepi[1].kryt2_m < cps_before[1].kryt2_m && cps_joint[1].kryt2_m < cps_before[1].kryt2_m
    );
}

/// The corrected navigation's times (s) and its column `name`, of the disupt folder `dir`.
fn corrected_series(dir: &std::path::Path, name: &str) -> (Vec<f64>, Vec<f64>) {
    nav_series(&dir.join("corrected_nav.parquet"), name)
}

/// A navigation file's times (s) and its column `name`.
fn nav_series(path: &std::path::Path, name: &str) -> (Vec<f64>, Vec<f64>) {
    use unz_formats::parquet_io::read_batches;
    use unz_formats::tables::{f64_column, i64_column};

    let (_, b) = read_batches(path).unwrap();
    let t_s = b
        .iter()
        .flat_map(|b| i64_column(b, "t_ns").unwrap())
        .map(|t| t as f64 * 1e-9)
        .collect();
    let values = b
        .iter()
        .flat_map(|b| f64_column(b, name).unwrap())
        .collect();
    (t_s, values)
}

/// Median |corrected − reference| heading over the settled moving part (from 60 s after
/// the vehicle first moves), of the corrected navigation in the disupt folder `dir`,
/// degrees.
fn corrected_heading_error_deg(dir: &std::path::Path, r: &Reference) -> f64 {
    let (t_s, heading) = corrected_series(dir, "heading_deg");
    let settle = r.speed.iter().position(|&v| v > 1.0).unwrap() + 60;
    let mut e: Vec<f64> = (settle..r.t_s.len())
        .filter(|&i| r.speed[i] > 1.0 && r.t_s[i] >= t_s[0])
        .filter_map(|i| {
            let k = t_s.partition_point(|&t| t < r.t_s[i]);
            (k < t_s.len())
                .then(|| ((heading[k] - r.azimuth[i] + 180.0).rem_euclid(360.0) - 180.0).abs())
        })
        .collect();
    e.sort_by(f64::total_cmp);
    e[e.len() / 2]
}

/// The largest horizontal error of a method at the control points, m.
pub(crate) fn worst_control_point_m(m: &unz::disupt_stage::MethodOut) -> f64 {
    m.outcome
        .control_points
        .iter()
        .map(|c| c.kryt2_m)
        .fold(0.0, f64::max)
}

/// The real drive cut to begin while driving, 30 s after the vehicle first moves: no
/// static start, the site the reference's position there, the manifest azimuth 100.3°
/// off, the same two control points. Levelled in motion, the start is within 0.3° of the
/// reference's pitch and roll, the joint fit runs and its route's heading is as good as
/// the whole drive's (within 0.5° over the moving part; measured 0.40°, against 0.37°
/// with the static start), its control points within 2 m (measured 0.3 and 0.1 m).
/// Levelled from the first epoch alone, this log started 0.42° off in roll and the joint
/// fit left its bounds (drift y +9.2 °/h); the corrected heading was OEPI's, 0.57°.
#[test]
fn kingston_cut_to_begin_while_driving() {
    use unz::disupt_stage::DisuptOut;
    use unz::flow::NavigateSummary;

    const CUT_S: f64 = 152_700.0;
    let src = test_data("kingston2008-seg1");
    let tmp = tempfile::tempdir().unwrap();
    let run = tmp.path().join("cut");
    std::fs::create_dir_all(&run).unwrap();
    // Lines from the cut on (the odometer's from one sample before, to interpolate).
    let from = |name: &str, t0: f64| {
        let text = std::fs::read_to_string(src.join(name)).unwrap();
        let kept: String = text
            .lines()
            .filter(|l| l.split_whitespace().next().unwrap().parse::<f64>().unwrap() >= t0)
            .map(|l| format!("{l}\n"))
            .collect();
        std::fs::write(run.join(name), kept).unwrap();
    };
    from("imu.txt", CUT_S);
    from("odometer.txt", CUT_S - 1.0);
    let r = reference();
    let cut = r.t_s.iter().position(|&t| t == CUT_S).unwrap();
    let [lat_deg, lon_deg, h_m] = r.position[cut];
    let manifest = std::fs::read_to_string(src.join("run.toml")).unwrap();
    let mut m: toml::Table = toml::from_str(&manifest).unwrap();
    let table = |kv: &[(&str, f64)]| {
        toml::Value::Table(
            kv.iter()
                .map(|(k, v)| ((*k).to_owned(), toml::Value::Float(*v)))
                .collect(),
        )
    };
    m["site"] = table(&[
        ("latitude_deg", lat_deg),
        ("longitude_deg", lon_deg),
        ("height_m", h_m),
    ]);
    m["initial"] = table(&[
        ("azimuth_deg", (r.azimuth[cut] + 100.3).rem_euclid(360.0)),
        ("static_s", 0.0),
    ]);
    std::fs::write(run.join("run.toml"), toml::to_string(&m).unwrap()).unwrap();
    let out = tmp.path().join("o");
    crate::util::run_until(&run, &out, "disupt");
    let dir = out.join("kingston2008-segment1");
    let nav: NavigateSummary = read_json(&dir.join("navigate/navigate.json"));
    let i = &nav.initial;
    assert!(
        i.in_motion_level.is_some() && i.gyrocompass_skipped.is_some(),
        "{i:?}"
    );
    let (pitch_err, roll_err) = (i.pitch_deg - r.pitch[cut], i.roll_deg - r.roll[cut]);
    let d: DisuptOut = read_json(&dir.join("disupt/disupt.json"));
    let j = d
        .methods
        .get("joint")
        .unwrap_or_else(|| panic!("joint not run: {:?}", d.skipped));
    let heading_err = corrected_heading_error_deg(&dir.join("disupt"), &r);
    let cp_max = worst_control_point_m(j);
    eprintln!(
        "Kingston cut to begin while driving: levelled {pitch_err:+.3}° / {roll_err:+.3}° off, \
         corrected by {:?}, heading {heading_err:.3}°, control points ≤ {cp_max:.2} m",
        d.corrected_by
    );
    assert!(pitch_err.abs() < 0.3 && roll_err.abs() < 0.3);
    assert!(heading_err < 0.5, "heading {heading_err}°");
    assert!(cp_max < 2.0, "control points {cp_max} m");
}

/// The real drive with a static start given past its drive-off (`static_s = 800`; the
/// car stood 527 s): the static start ends a second before the OBD-II speed has it 10 cm
/// on over a second, as `navigate.json` says, and the corrected heading and control
/// points are the whole drive's with its own 500 s (within 0.5° over the moving part and
/// 2 m).
#[test]
fn kingston_static_start_given_past_the_drive_off() {
    use unz::disupt_stage::DisuptOut;
    use unz::flow::NavigateSummary;

    let tmp = tempfile::tempdir().unwrap();
    let run = kingston_with_initial(&tmp.path().join("k"), "static_s", 800.0.into());
    let out = tmp.path().join("o");
    crate::util::run_until(&run, &out, "disupt");
    let dir = out.join("kingston2008-segment1");
    let nav: NavigateSummary = read_json(&dir.join("navigate/navigate.json"));
    let cut = nav.initial.static_cut.expect("the static start cut");
    assert_eq!(cut.given_s, 800.0);
    // The reference has the car leave its place between 527 and 528 s in.
    assert!((527.0..530.0).contains(&cut.moved_s), "{cut:?}");
    let d: DisuptOut = read_json(&dir.join("disupt/disupt.json"));
    let j = d
        .methods
        .get("joint")
        .unwrap_or_else(|| panic!("joint not run: {:?}", d.skipped));
    let r = reference();
    let heading_err = corrected_heading_error_deg(&dir.join("disupt"), &r);
    let cp_max = worst_control_point_m(j);
    eprintln!(
        "Kingston, static_s = 800: cut at {:.2} s, corrected by {:?}, heading {heading_err:.3}°, control points ≤ {cp_max:.2} m",
        nav.initial.static_s, d.corrected_by
    );
    assert!(heading_err < 0.5, "heading {heading_err}°");
    assert!(cp_max < 2.0, "control points {cp_max} m");
}

/// Kingston's two control points with the site 50 m off (north), or the first point timed
/// 25 s early (while driving to it): the hold-out errors go from 1.1σ as surveyed to
/// 26–41σ, beyond the 10σ at which two points are said to disagree with the log
/// (correct points reached 5.3σ on 50 simulated runs with a static start), and
/// `disupt.json`, `disupt.md` and the campaign's note say so. The run as surveyed says
/// nothing.
#[test]
fn kingston_two_control_points_apart_from_the_log_are_said() {
    use unz::disupt_stage::DisuptOut;

    let tmp = tempfile::tempdir().unwrap();
    let cases: [(&str, &str, &str, bool); 3] = [
        ("as surveyed", "", "", false),
        (
            "the site 50 m north",
            "latitude_deg = 44.232490740",
            "latitude_deg = 44.232940740",
            true,
        ),
        (
            "point 1 timed 25 s early",
            "t_s = 152825.0",
            "t_s = 152800.0",
            true,
        ),
    ];
    for (k, (case, from, to, apart)) in cases.into_iter().enumerate() {
        let run = kingston_edited(&tmp.path().join(format!("k{k}")), from, to);
        let out = tmp.path().join(format!("o{k}"));
        let o = unz_run(&run, &out);
        assert!(
            o.status.success(),
            "{case}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let dir = out.join("kingston2008-segment1/disupt");
        let d: DisuptOut = read_json(&dir.join("disupt.json"));
        let holdout = d.methods["joint"].holdout.clone().unwrap();
        let sigmas: Vec<f64> = holdout.iter().map(|h| h.error_sigma.unwrap()).collect();
        eprintln!("Kingston, {case}: hold-outs {sigmas:.1?} σ");
        assert!(
            holdout.iter().all(|h| h.apart == apart),
            "{case}: {holdout:?}"
        );
        let said = "the two control points disagree with the log beyond what the settings explain";
        for file in [dir.join("disupt.md"), out.join("campaign.md")] {
            let text = std::fs::read_to_string(&file).unwrap();
            assert_eq!(text.contains(said), apart, "{case}: {}", file.display());
        }
    }
}

/// Kingston's speeds in m/s declared in km/h (`kind = "speed_kmh"`): the derive fails
/// naming the ratio and the file, as for km/h declared as m/s. The odometer's
/// accelerations read 1/3.6 of the truth, and the check's excitation was the odometer's
/// own: 1/13 of the drive's, below what it judges, so the run went on, the joint fit left
/// its bounds (scale +247 %) and OEPI's route was taken, 830 m off at the last point,
/// under an "ok". The excitation is now the accelerometers' part the odometer explains,
/// whatever its unit.
#[test]
fn kingston_speeds_in_ms_declared_in_kmh_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let run = kingston_edited(
        &tmp.path().join("k"),
        "kind = \"speed_mps\"",
        "kind = \"speed_kmh\"",
    );
    let err = crate::util::stage_fails("derive", &run, &tmp.path().join("o"));
    assert!(
        err.contains(
            "the odometer's distance is not in metres (near 1/3.6, the ratio of km/h to m/s)"
        ) && err.contains("(read as km/h: [odometer] kind = \"speed_kmh\")"),
        "{err}"
    );
}

/// Kingston's odometer file with its time tags moved by `shift_s` (a logger on another
/// clock), copied into `run`.
fn kingston_odometer_shifted(run: &std::path::Path, shift_s: f64) -> std::path::PathBuf {
    kingston_odometer_edited(run, |t, v| (t + shift_s, v))
}

/// Kingston's odometer file with each row `(t_s, value)` replaced by `edit`'s, copied
/// into `run`.
fn kingston_odometer_edited(
    run: &std::path::Path,
    edit: impl Fn(f64, f64) -> (f64, f64),
) -> std::path::PathBuf {
    let run = kingston_with(run, "");
    let rows: String = kingston_speeds()
        .into_iter()
        .map(|(t, v)| {
            let (t, v) = edit(t, v);
            format!("{t:.3} {v:.5}\n")
        })
        .collect();
    std::fs::write(run.join("odometer.txt"), rows).unwrap();
    run
}

/// Kingston's speeds read 10 m/s high (a CAN signal decoded with a wrong offset), with
/// no static start given (its stand would read the offset: below), fail the derive
/// naming the offset (8.3 m/s: the real drive's own fit gives −1.7 at none), where the
/// previous build said the gyros' rate was 3.0 times the vehicle's turn and the angle
/// increments must be in radians; its gyros reading double are still the gyros' (their
/// fit's gain 0.40, no right one's).
#[test]
fn kingston_a_speed_read_with_an_offset_is_told_from_the_gyros_scale() {
    let tmp = tempfile::tempdir().unwrap();
    let run = kingston_odometer_edited(&tmp.path().join("offset"), |t, v| (t, v + 10.0));
    let manifest = std::fs::read_to_string(run.join("run.toml")).unwrap();
    assert!(manifest.contains("static_s = 500.0\n"), "{manifest}");
    std::fs::write(
        run.join("run.toml"),
        manifest.replace("static_s = 500.0\n", ""),
    )
    .unwrap();
    let err = crate::util::stage_fails("derive", &run, &tmp.path().join("offset-o"));
    assert!(
        err.contains("m/s more than the vehicle's speed") && err.contains("from 0 at rest"),
        "{err}"
    );
    let offset_mps = crate::util::number_after(&err, "times (u − ");
    assert!((6.0..12.0).contains(&offset_mps), "{err}");
    let run = kingston_increments_edited(&tmp.path().join("gyros"), |v| {
        [2.0 * v[0], 2.0 * v[1], 2.0 * v[2], v[3], v[4], v[5]]
    });
    let err = crate::util::stage_fails("derive", &run, &tmp.path().join("gyros-o"));
    assert!(
        err.contains("the gyros' rate is 1.8 times the vehicle's turn"),
        "{err}"
    );
}

/// Kingston's speeds read 1 m/s high, 3 m/s high and 3 m/s low (a CAN speed decoded with
/// a wrong offset) fail the derive naming the offset to the cm/s, read where the static
/// start given (500 s) says the vehicle stood; the speeds mended as it says, the run is
/// the shipped one's. Before, 1 m/s high ran "ok" 2.6 km off at the last control point
/// before DISUPT (its joint fit refused), 3 m/s high was "about 1.3 m/s" by the turns and
/// 3 m/s low "runs backward over 55 % of its travel … check the sign of the speeds".
/// Speeds that stand at 0 with a sensor's noise of 0–4 cm/s are no offset (the shipped
/// file reads 0.8 and 2.0 cm/s at rest).
#[test]
fn kingston_a_speed_offset_is_read_off_the_static_start() {
    let tmp = tempfile::tempdir().unwrap();
    let shipped = kingston_shipped_disupt(tmp.path());
    for (name, offset_mps, mend) in [
        ("1", 1.0, "subtract 1.00 m/s from each"),
        ("3", 3.0, "subtract 3.00 m/s from each"),
        ("-3", -3.0, "add 3.00 m/s to each"),
    ] {
        let run = kingston_odometer_edited(&tmp.path().join(name), |t, v| (t, v + offset_mps));
        let err = crate::util::stage_fails("derive", &run, &tmp.path().join(format!("{name}-o")));
        let said = format!(
            "reads {offset_mps:.2} m/s, steady (σ 0.000 m/s), over the first 250 s of the \
             static start given (static_s = 500 s), where the vehicle stood: its readings' \
             zero is off"
        );
        assert!(err.contains(&said), "{name}: {err}");
        assert!(
            err.contains(&format!("from 0 at rest ({mend})")),
            "{name}: {err}"
        );
        // Mended as said.
        let said_mps = crate::util::number_after(&err, "odometer.txt reads ");
        kingston_odometer_edited(&run, |t, v| (t, v + offset_mps - said_mps));
        let out = tmp.path().join(format!("{name}-mended-o"));
        crate::util::run_until(&run, &out, "disupt");
        assert_same_worst_point(&out, &shipped);
    }
}

/// Kingston's speed logger holding 0.56 m/s through the stand (its first 528 readings,
/// where it read 0) while the drive reads 0 at its stops fails the derive naming the
/// stretch to write 0 over; mended as said, the run is the shipped one. Before, it was
/// neither an offset (the stops read below it) nor flat: the run went "ok" with the static
/// start cut at once, 2.3 km off at the last control point before DISUPT, its joint fit
/// refused (session 65's probe).
#[test]
fn kingston_a_speed_held_through_the_stand_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let shipped = kingston_shipped_disupt(tmp.path());
    let t0_s = kingston_speeds()[0].0;
    let stood = kingston_speeds()
        .iter()
        .take_while(|(t, _)| t - t0_s < 528.0)
        .count();
    assert!(
        stood == 528 && kingston_speeds()[..stood].iter().all(|(_, v)| *v == 0.0),
        "the shipped stand reads 0"
    );
    let held = |t: f64, v: f64| (t, if t - t0_s < 528.0 { 0.56 } else { v });
    let run = kingston_odometer_edited(&tmp.path().join("held"), held);
    let err = crate::util::stage_fails("derive", &run, &tmp.path().join("held-o"));
    assert!(
        err.contains(
            "odometer.txt reads 0.56 m/s, steady (σ 0.000 m/s), over the first 250 s of the \
             static start given (static_s = 500 s), where the vehicle stood, yet the log reads \
             0 at the drive's stops ("
        ) && err.contains("the stand's speed is a reading held"),
        "{err}"
    );
    assert!(
        err.contains(
            "odometer.txt over the log's first 527 s, where it reads 0.56 m/s, if the \
             vehicle stood, or set static_s to the time the vehicle stood if it drove"
        ),
        "{err}"
    );
    // Mended as said.
    let said_s = crate::util::number_after(&err, "over the log's first ");
    kingston_odometer_edited(&run, |t, v| (t, if t - t0_s <= said_s { 0.0 } else { v }));
    let out = tmp.path().join("mended-o");
    crate::util::run_until(&run, &out, "disupt");
    assert_same_worst_point(&out, &shipped);
}

/// Kingston's speed file in Unix milliseconds (a phone's or an OBD-II logger's clock):
/// every line is beyond the span the pipeline times to the nanosecond, and the ingest
/// names the unit and the date (19 May 2008), where before it asked "are the file's times
/// in ms, µs or ns?".
#[test]
fn kingston_a_speed_file_in_unix_milliseconds_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    // Unix time against GPS seconds of week 1480 on 19 May 2008 (14 leap seconds).
    let unix_ms = |t: f64, v: f64| ((t + 1_211_068_786.0) * 1e3, v);
    let run = kingston_odometer_edited(&tmp.path().join("ms"), unix_ms);
    let err = crate::util::stage_fails("ingest", &run, &tmp.path().join("ms-o"));
    assert!(
        err.contains(
            "gave no reading (the first line rejected, line 1: time 1.211220929e12 s is \
             beyond ±9e9 s (285 years), the span the pipeline times to the nanosecond: Unix \
             time in milliseconds (19 May 2008)? Write the file's times in seconds)"
        ),
        "{err}"
    );
}

/// An OBD-II logger's CSV of more columns (time, engine speed, speed, a status, under a
/// header line) as Kingston's speed file: without a setting the ingest fails naming the
/// file's columns and `[odometer] value_column`; with `value_column = 3`, or
/// `value_column = "speed_mps"` as its header names it, the run is the shipped one's byte
/// for byte, its header line the one rejected. Before, no column could be named: the
/// file's every line was rejected, "expected two numbers"; and before session 66, by its
/// number only.
#[test]
fn kingston_an_odometer_csv_of_more_columns_reads_the_column_named() {
    let tmp = tempfile::tempdir().unwrap();
    let shipped = kingston_with(&tmp.path().join("shipped"), "");
    let want = tmp.path().join("shipped-o");
    crate::util::run_until(&shipped, &want, "disupt");
    let run = kingston_with(&tmp.path().join("csv"), "");
    let rows: String = std::iter::once("time_s,rpm,speed_mps,status\n".to_owned())
        .chain(
            (kingston_speeds().into_iter())
                .map(|(t, v)| format!("{t:.3},{:.0},{v:.5},OK\n", 800.0 + 120.0 * v)),
        )
        .collect();
    std::fs::write(run.join("odometer.txt"), rows).unwrap();
    let err = crate::util::stage_fails("ingest", &run, &tmp.path().join("csv-bare"));
    assert!(
        err.contains(
            "line 1: expected two numbers `t_s value`, got \"time_s,rpm,speed_mps,status\"; line 2:"
        ) && err.contains(
            "(a file of 4 columns? name the value's in the manifest's [odometer] \
                 value_column: 2 for the second, the time being the first)"
        ),
        "{err}"
    );
    let manifest = std::fs::read_to_string(run.join("run.toml")).unwrap();
    let kind = "kind = \"speed_mps\"\n";
    assert!(manifest.contains(kind));
    let named = manifest.replace(kind, &format!("{kind}value_column = 3\n"));
    std::fs::write(run.join("run.toml"), named).unwrap();
    let out = tmp.path().join("csv-o");
    crate::util::run_until(&run, &out, "disupt");
    let stage = |o: &std::path::Path, file: &str| {
        std::fs::read(o.join("kingston2008-segment1").join(file)).unwrap()
    };
    assert!(stage(&want, "disupt/disupt.json") == stage(&out, "disupt/disupt.json"));
    let ingest: unz_formats::IngestReport =
        read_json(&out.join("kingston2008-segment1/ingest/ingest.json"));
    let file = ingest.odometer_file.expect("read");
    assert_eq!(file.lines_rejected, 1, "{file:?}");
    // By its name on the header line (session 66): the same run, the header the line
    // rejected as such; a name the header does not give fails the ingest, naming them.
    for (name, fails) in [("speed_mps", false), ("speed", true)] {
        let by_name = manifest.replace(kind, &format!("{kind}value_column = {name:?}\n"));
        std::fs::write(run.join("run.toml"), by_name).unwrap();
        let out = tmp.path().join(format!("csv-{name}-o"));
        if fails {
            let err = crate::util::stage_fails("ingest", &run, &out);
            assert!(
                err.contains(
                    "line 1: [odometer] value_column = \"speed\" names the value's column on \
                     the file's header line, and its header line names none so: its columns \
                     are \"time_s\", \"rpm\", \"speed_mps\", \"status\" (in "
                ) && err.contains("odometer.txt)"),
                "{err}"
            );
            continue;
        }
        crate::util::run_until(&run, &out, "disupt");
        assert!(stage(&want, "disupt/disupt.json") == stage(&out, "disupt/disupt.json"));
        let events: unz_formats::IngestEvents =
            read_json(&out.join("kingston2008-segment1/ingest/ingest_events.json"));
        assert_eq!(
            (events.odometer_file_faults.iter())
                .map(|f| (f.line, f.reason.as_str()))
                .collect::<Vec<_>>(),
            vec![(
                1,
                "the file's header line (its columns' names): \"speed_mps\" is column 3 \
                 ([odometer] value_column)"
            )]
        );
    }
}

/// Kingston's speeds in km/h, on a clock 5 s late: the derive names the clock first;
/// with the offset it names set, the accelerometers read the speeds 3.32 times theirs
/// (3.36 when the clock was read with the ingest's bridges), near feet to metres (3.28)
/// and 8.4 % below km/h to m/s (3.6), the two 9.7 % apart. Before, only the nearest, feet, was named; now both
/// are, the nearest first, and with the unit named in the manifest the route is the
/// shipped file's with the same offset's.
#[test]
fn kingston_speeds_in_kmh_on_another_clock_name_every_unit_near() {
    let tmp = tempfile::tempdir().unwrap();
    let kmh = kingston_odometer_edited(&tmp.path().join("kmh"), |t, v| (t + 5.0, v * 3.6));
    let err = crate::util::stage_fails("derive", &kmh, &tmp.path().join("o"));
    assert!(err.contains("s late against the IMU's"), "{err}");
    let offset_s = crate::util::named_offset_s(&err);
    // The shipped manifest with the odometer's `kind` and the offset named.
    let manifest = |run: &std::path::Path, kind: &str| {
        let shipped = std::fs::read_to_string(test_data("kingston2008-seg1").join("run.toml"));
        let m = (shipped.unwrap()).replace("kind = \"speed_mps\"", &format!("kind = \"{kind}\""));
        let set = format!("{m}\n[params.derive]\nodo_time_offset_s = {offset_s}\n");
        std::fs::write(run.join("run.toml"), set).unwrap();
    };
    manifest(&kmh, "speed_mps");
    let err = crate::util::stage_fails("derive", &kmh, &tmp.path().join("o"));
    assert!(
        err.contains("(near 3.28084, the ratio of feet to metres, or 3.6, of km/h to m/s)"),
        "{err}"
    );
    manifest(&kmh, "speed_kmh");
    crate::util::run_until(&kmh, &tmp.path().join("kmh-o"), "disupt");
    let mps = kingston_odometer_shifted(&tmp.path().join("mps"), 5.0);
    manifest(&mps, "speed_mps");
    crate::util::run_until(&mps, &tmp.path().join("mps-o"), "disupt");
    assert_same_worst_point(&tmp.path().join("kmh-o"), &tmp.path().join("mps-o"));
}

/// Kingston's OBD-II speed file on a clock 5 s late, and 5 s early: beyond the ±1 s of
/// lag the joint fit searches. Before, each ran "ok": late, with hold-out errors of 39
/// and 55 m (2.2 and 3.0 m on its own clock) and its lag at the search's bound; early,
/// with the lag short of its bound (−0.94 s) and hold-out errors of 51 and 129 m, which
/// the run blamed on the control points. Now the derive fails, naming the file and the
/// offset that aligns it (within the joint fit's ±1 s of the shift and Kingston's own
/// −0.58 s lag); set as named, the run is its own clock's again: the route's heading
/// within 0.45° of the reference and the hold-out errors within 4 m, as the README's
/// joint fit with lag and bias.
#[test]
fn kingston_an_odometer_file_on_another_clock_is_named() {
    let r = reference();
    let tmp = tempfile::tempdir().unwrap();
    for (shift_s, late) in [(5.0, "late"), (-5.0, "early")] {
        let dir = tmp.path().join(format!("{shift_s}"));
        let run = kingston_odometer_shifted(&dir.join("k"), shift_s);
        let err = crate::util::stage_fails("derive", &run, &dir.join("failed"));
        assert!(
            err.contains("odometer.txt's time tags run")
                && err.contains(&format!("s {late} against the IMU's")),
            "{err}"
        );
        let offset_s = crate::util::named_offset_s(&err);
        // Kingston's own lag, −0.58 ± 0.17 s, is the joint fit's to find.
        assert!((offset_s + shift_s - 0.58).abs() < 0.8, "{err}");
        let set = format!("[params.derive]\nodo_time_offset_s = {offset_s}\n");
        let manifest = std::fs::read_to_string(run.join("run.toml")).unwrap() + "\n" + &set;
        std::fs::write(run.join("run.toml"), manifest).unwrap();
        let (lag_s, heading_err, holdout_max) = own_clock_figures(&run, &dir.join("o"), &r);
        eprintln!(
            "odometer {shift_s:+} s, offset named {offset_s} s: lag {lag_s:.3} s, heading {heading_err:.3}°, hold-out ≤ {holdout_max:.2} m"
        );
        // The lag beyond the offset set: the whole lag is the shift and Kingston's own.
        assert!((lag_s - offset_s - shift_s + 0.58).abs() < 0.5, "{lag_s} s");
    }
}

/// Kingston's speed file in UTC seconds of day beside its IMU log in GPS seconds of week
/// (a logger timed by an NMEA fix): a day and 18 s (GPS time's lead on UTC) before the
/// IMU's tags. The derive names the day first ("add 86400 s"); written so, the file is
/// 18 s early, and the derive names the offset; set, the run is its own clock's again.
/// Before, the day's message named no shift, and the file a day on ran "ok": its two
/// stands fell where the vehicle drove and were bridged by the inertial speed (53 s),
/// which the accelerometers follow at no shift, so the clock's correlation was 0.43 (not
/// shown), the joint fit refused (the odometer's scale +307 000 ppm) and OWPI's route
/// 122 m off at the points. The clock is now read from the odometer's readings only
/// (0.91 at 18.4 s).
#[test]
fn kingston_an_odometer_in_utc_seconds_of_day_is_named_the_day_then_the_seconds() {
    let r = reference();
    let tmp = tempfile::tempdir().unwrap();
    let utc = kingston_odometer_shifted(&tmp.path().join("utc"), -86_418.0);
    let err = crate::util::stage_fails("derive", &utc, &tmp.path().join("utc-o"));
    assert!(
        err.contains("its time tags run 1 day before the IMU's, to the hour")
            && err.contains("add 86400 s to each of its time tags"),
        "{err}"
    );
    let run = kingston_odometer_shifted(&tmp.path().join("k"), -86_418.0 + 86_400.0);
    let err = crate::util::stage_fails("derive", &run, &tmp.path().join("failed"));
    assert!(err.contains("s early against the IMU's"), "{err}");
    let offset_s = crate::util::named_offset_s(&err);
    // Kingston's own lag, −0.58 ± 0.17 s, is the joint fit's to find.
    assert!((offset_s - 18.0 - 0.58).abs() < 0.8, "{err}");
    let set = format!("[params.derive]\nodo_time_offset_s = {offset_s}\n");
    let manifest = std::fs::read_to_string(run.join("run.toml")).unwrap() + "\n" + &set;
    std::fs::write(run.join("run.toml"), manifest).unwrap();
    own_clock_figures(&run, &tmp.path().join("o"), &r);
}

/// Kingston's `run`, its odometer on the IMU's clock again, run to disupt into `out`:
/// the joint fit's lag, s, the route's heading error against the reference, degrees, and
/// the worst hold-out error, m, asserted within 0.45° and 4 m (the README's joint fit
/// with lag and bias: 0.4° and 2–3 m).
fn own_clock_figures(
    run: &std::path::Path,
    out: &std::path::Path,
    r: &Reference,
) -> (f64, f64, f64) {
    crate::util::run_until(run, out, "disupt");
    let disupt = out.join("kingston2008-segment1/disupt");
    let d: unz::disupt_stage::DisuptOut = read_json(&disupt.join("disupt.json"));
    let j = &d.methods["joint"];
    let heading_err = corrected_heading_error_deg(&disupt, r);
    let holdout_max = (j.holdout.as_ref().unwrap().iter())
        .map(|h| h.dx_m.hypot(h.dy_m))
        .fold(0.0, f64::max);
    assert!(
        heading_err < 0.45 && holdout_max < 4.0,
        "{}: {heading_err}° {holdout_max} m",
        run.display()
    );
    (j.outcome.x.odo_lag_s, heading_err, holdout_max)
}

/// Kingston's speed file 150 s late and 200 s early: beyond the ±60 s that
/// `odo_time_offset_s` takes (a logger's clock set minutes off). Before, the first
/// failed blaming the odometer's stands while the vehicle moved, and the second ran "ok"
/// with its static start cut at the odometer's "first move", the joint fit out of its
/// bounds and OEPI's route 446 m off at the control points. Now the
/// derive, finding the drive nowhere within the setting's reach, searches half the log
/// and names the shift to write into the file (within 0.5 s of the shift and Kingston's
/// own −0.4 s); written so, the run is its own clock's again.
#[test]
fn kingston_an_odometer_file_minutes_off_is_named_with_the_shift_to_write() {
    let r = reference();
    let tmp = tempfile::tempdir().unwrap();
    for (shift_s, late) in [(150.0, "late"), (-200.0, "early")] {
        let dir = tmp.path().join(format!("{shift_s}"));
        let run = kingston_odometer_shifted(&dir.join("k"), shift_s);
        let err = crate::util::stage_fails("derive", &run, &dir.join("failed"));
        assert!(
            err.contains(&format!("s {late} against the IMU's, another clock's"))
                && err.contains("(beyond the ±60 s [derive] odo_time_offset_s takes)"),
            "{err}"
        );
        let named_s = crate::util::number_after(&err, "Add ");
        assert!((named_s + shift_s).abs() < 0.5, "{err}");
        let written = kingston_odometer_shifted(&dir.join("written"), shift_s + named_s);
        own_clock_figures(&written, &dir.join("o"), &r);
    }
}

/// Kingston's speed file with its time tags in milliseconds, a day late, and its lines in
/// reverse order (each but the first rejected as not after the one before): none leaves
/// two readings within the IMU's log. Before, the derive held the distance at zero and
/// the navigate failed blaming the first control point's coordinates, its mark or the
/// site ("the odometer measured 0 m of travel by its mark"). Now the derive fails naming
/// the file, the two spans and the likeliest reason (for the day, the shift to write).
#[test]
fn kingston_an_odometer_file_outside_the_log_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let in_ms = kingston_odometer_edited(&tmp.path().join("ms"), |t, v| (t * 1000.0, v));
    let err = crate::util::stage_fails("derive", &in_ms, &tmp.path().join("ms-o"));
    assert!(
        err.contains(
            "odometer.txt has 0 of its 877 rows within the IMU log (t_s = 152143.09 to 153018.99)"
        ) && err
            .contains("its time tags read in milliseconds would run t_s = 152143.00 to 153019.00"),
        "{err}"
    );
    let a_day_late = kingston_odometer_edited(&tmp.path().join("day"), |t, v| (t + 86_400.0, v));
    let err = crate::util::stage_fails("derive", &a_day_late, &tmp.path().join("day-o"));
    assert!(
        err.contains("where it runs t_s = 238543.00 to 239419.00")
            && err.contains("its time tags run 1 day after the IMU's, to the hour")
            && err.contains("add -86400 s to each of its time tags"),
        "{err}"
    );
    let reversed = kingston_with(&tmp.path().join("rev"), "");
    let rows: Vec<String> = (kingston_speeds().into_iter().rev())
        .map(|(t, v)| format!("{t} {v}\n"))
        .collect();
    std::fs::write(reversed.join("odometer.txt"), rows.concat()).unwrap();
    let err = crate::util::stage_fails("derive", &reversed, &tmp.path().join("rev-o"));
    assert!(
        err.contains("has 0 of its 1 rows within the IMU log")
            && err.contains("the ingest rejected 876 of its 877 lines"),
        "{err}"
    );
}

/// Kingston's OBD-II speeds negated, and read as distances: the odometer then runs
/// backward over all its travel, or over half of it. Before, the negated speeds turned
/// the axes' check, which named the IMU facing backwards (`imu_axes = "BLD"`); the
/// speeds read as distances went on to the navigate, which blamed the control points'
/// coordinates. Now the derive names the odometer file and what is wrong with it.
#[test]
fn kingston_an_odometer_running_backward_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let negated = kingston_odometer_edited(&tmp.path().join("neg"), |t, v| (t, -v));
    let err = crate::util::stage_fails("derive", &negated, &tmp.path().join("neg-o"));
    assert!(
        err.contains("odometer.txt runs backward over 100 % of its travel")
            && err.contains("its sign is reversed; write the speeds of")
            && !err.contains("imu_axes ="),
        "{err}"
    );
    let as_distances = kingston_edited(
        &tmp.path().join("dist"),
        "kind = \"speed_mps\"",
        "kind = \"distance_m\"",
    );
    let err = crate::util::stage_fails("derive", &as_distances, &tmp.path().join("dist-o"));
    assert!(
        err.contains("odometer.txt runs backward over 50 % of its travel")
            && err.contains("speeds? They are read as distances"),
        "{err}"
    );
}

/// Kingston's second control point timed 6 s before its stop, as the vehicle braked at
/// 4.4 m/s: the point is compared with a place the vehicle passed 10 m short of it.
/// Before, the run was "ok" with hold-out errors of 7.0 and 9.9 m (2.2 and 3.0 m as
/// surveyed), and nothing said. Now `navigate.json` and the campaign's note say the point
/// was passed, not stood at, and where the vehicle stood: 5.5 s later, 9.9 m on (the
/// ±1 s window's mean reaches 0.1 m/s half a second before the file's first zero speed,
/// at 153001). The point as surveyed is not said.
#[test]
fn kingston_a_control_point_timed_while_driving_is_said() {
    let tmp = tempfile::tempdir().unwrap();
    let run = kingston_edited(&tmp.path().join("k"), "t_s = 153011.5", "t_s = 152995.0");
    let out = tmp.path().join("o");
    crate::util::run_until(&run, &out, "navigate");
    let nav = navigate_summary(&out);
    let [m] = nav.moving_marks.as_slice() else {
        panic!("{:?}", nav.moving_marks)
    };
    assert_eq!((m.id, m.t_s), (2, 152995.0));
    // The file's speeds about it: 5.43, 5.40, 5.28, 4.94, 4.38 m/s at 152991–152995 s.
    assert!(m.speed_mps > 3.5 && m.speed_mps < 5.0, "{m:?}");
    let stop = m.nearest_stop.unwrap();
    assert!((stop.t_s - 153000.5).abs() < 0.6, "{stop:?}");
    assert!(stop.path_m > 7.0 && stop.path_m < 13.0, "{stop:?}");
    crate::util::run_until(&run, &out, "disupt");
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert!(
        summary.contains("control point 2 at t_s = 152995.00 was passed at")
            && summary.contains("check its time or mark"),
        "{summary}"
    );
    let nav = shipped_navigated(&tmp.path().join("shipped"));
    assert!(nav.moving_marks.is_empty(), "{:?}", nav.moving_marks);
}

/// Kingston with its heading given in radians (`azimuth_deg = 3.523`: 201.85°, the static
/// start's gyrocompassing) and 52° off (150°). Before, both ran "ok" with nothing said
/// (DISUPT's coarse search turned the first by 162°). Now `navigate.json`
/// (`initial.azimuth_apart`) and the campaign's note say how far the azimuth given is
/// from the gyrocompassing, naming radians where they fit; the run keeps what was given,
/// and DISUPT corrects it as before. 195° (7° off, within 4σ of the gyrocompassing's
/// 5.4°) and the manifest without an azimuth say nothing.
#[test]
fn kingston_an_azimuth_given_far_from_the_gyrocompassing_is_said() {
    let tmp = tempfile::tempdir().unwrap();
    let said = |name: &str, azimuth_deg: f64| {
        let run = kingston_with_initial(&tmp.path().join(name), "azimuth_deg", azimuth_deg.into());
        let out = tmp.path().join(format!("{name}-o"));
        crate::util::run_until(&run, &out, "navigate");
        let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
        (navigate_summary(&out).initial.azimuth_apart, summary)
    };
    let (apart, summary) = said("rad", 3.523);
    let apart = apart.expect("the azimuth given said");
    assert!((apart.apart_deg() - 161.7).abs() < 0.5, "{apart:?}");
    assert!(
        summary.contains("the azimuth given (3.523°) is 161.")
            && summary.contains("(3.523 read as radians is 201.8"),
        "{summary}"
    );
    let (apart, summary) = said("off", 150.0);
    assert!(apart.is_some_and(|a| (a.apart_deg() - 51.8).abs() < 0.5));
    assert!(!summary.contains("radians"), "{summary}");
    assert_eq!(said("near", 195.0).0, None);
    assert_eq!(
        shipped_navigated(&tmp.path().join("shipped"))
            .initial
            .azimuth_apart,
        None
    );
}

/// Kingston with `static_s = 0` (no static start) though it stands 527 s at its start:
/// the heading then comes from the control points alone. Before, the run was "ok" with
/// the joint fit's azimuth σ 0.69° (0.06° aligned) and hold-out errors of 16 and 29 m
/// (2.2 and 3.0 m), and nothing said. Now `navigate.json` (`initial.static_unused`) and
/// the campaign's note say the stand was left out, and the run keeps what was given.
/// With `static_s = 8` (8 minutes meant), the alignment gyrocompassed over 8 s of the
/// stand (σ 9.5° against 5.4°; the joint fit's azimuth σ 0.27°, hold-outs 2.9 and 4.1 m)
/// and nothing was said: now the 8 s and the minutes are.
#[test]
fn kingston_a_stand_left_out_of_the_alignment_is_said() {
    let tmp = tempfile::tempdir().unwrap();
    let run = kingston_edited(&tmp.path().join("k"), "static_s = 500.0", "static_s = 0.0");
    let out = tmp.path().join("o");
    crate::util::run_until(&run, &out, "disupt");
    let nav = navigate_summary(&out);
    let unused = nav.initial.static_unused.unwrap();
    // The speed file's first non-zero speed is at 152671 s, 527.9 s into the log; 10 cm
    // over a second at 528.6 s.
    assert_eq!(unused.given_s, 0.0);
    assert!((unused.stood_s - 527.0).abs() < 1.5, "{unused:?}");
    assert_eq!(nav.initial.static_s, 0.0);
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert!(
        summary.contains("the vehicle stood 528 s at the log's start by its odometer")
            && summary.contains("(static_s = 0 s) leaves it out of the alignment"),
        "{summary}"
    );
    // 8 s given (minutes meant): the alignment's 8 s of the stand said, and the minutes.
    let run = kingston_edited(&tmp.path().join("k8"), "static_s = 500.0", "static_s = 8.0");
    let out = tmp.path().join("o8");
    crate::util::run_until(&run, &out, "disupt");
    let unused = navigate_summary(&out).initial.static_unused.unwrap();
    assert_eq!(unused.given_s, 8.0);
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert!(
        summary.contains(
            "(static_s = 8 s) aligns over its first 8 s only (8 minutes would be 480 s: \
             static_s is in seconds)"
        ),
        "{summary}"
    );
    // As shipped (500 s given): nothing said.
    let nav = shipped_navigated(&tmp.path().join("shipped"));
    assert_eq!(nav.initial.static_unused, None);
}

/// Kingston's log moved to run over a GPS week's rollover (its time column in seconds of
/// week: 604343.09 to 604799.99, then 0.09 to 418.99), its speed file and its control
/// points' times with it. Before, the IMU's tags after the rollover were repaired one
/// interval apart and the speed file's 420 lines after it rejected as not after the one
/// before: the derive failed, the odometer having "0 of its 457 rows within the IMU log
/// (t_s = 604343.09 to 418.99)". Now each file's tags go on a week later (counted in
/// `ingest.json`), a point timed after the rollover is taken a week on, and the run is
/// the one on the week's own clock: the joint fit's control points within 1 cm.
#[test]
fn kingston_over_a_gps_weeks_rollover_is_the_run_on_its_own_clock() {
    let tmp = tempfile::tempdir().unwrap();
    let week_s = unz_formats::kfgins::GPS_WEEK_S;
    let run = kingston_retimed(&tmp.path().join("k"), |t| (t + 452_200.0) % week_s);
    let out = tmp.path().join("o");
    let report = disupt_with_ingest_report(&run, &out);
    assert_eq!(report.week_rollovers, 1);
    assert_eq!(report.odometer_file.unwrap().week_rollovers, 1);
    assert_same_worst_point(&out, &own_clock_reference(tmp.path()));
}

/// Kingston's log in UTC seconds of day (as a logger timed by an NMEA fix writes them)
/// over midnight, 750 s in (85650.09 to 86399.99, then 0.09 to 125.99), its first control
/// point timed before it and its second after. Before, as over a week's rollover: the
/// IMU's later tags repaired one interval apart, the speed file's 127 later lines
/// rejected, and the derive failed naming the odometer file ("0 of its 750 rows within the
/// IMU log"). Now the tags go on a day later (`day_rollovers` in `ingest.json`), the
/// second point is taken a day on and the first as written, and the run is the one on
/// its own clock: the joint fit's control points within 1 cm.
#[test]
fn kingston_over_midnight_in_seconds_of_day_is_the_run_on_its_own_clock() {
    let tmp = tempfile::tempdir().unwrap();
    let day_s = unz_formats::kfgins::DAY_S;
    let run = kingston_retimed(&tmp.path().join("k"), |t| {
        (t - 152_143.0 + day_s - 750.0) % day_s
    });
    let m = std::fs::read_to_string(run.join("run.toml")).unwrap();
    assert!(
        m.contains("t_s = 86332.0") && m.contains("t_s = 118.5"),
        "{m}"
    );
    let out = tmp.path().join("o");
    let report = disupt_with_ingest_report(&run, &out);
    assert_eq!((report.day_rollovers, report.week_rollovers), (1, 0));
    let file = report.odometer_file.unwrap();
    assert_eq!((file.day_rollovers, file.lines_rejected), (1, 0));
    assert_same_worst_point(&out, &own_clock_reference(tmp.path()));
}

/// Kingston in UTC seconds of day with its speed logger started across midnight from
/// its IMU: the IMU 30 s before midnight and the speed file at it (the file's readings
/// before midnight left out), and the IMU 5 s after midnight and the speed file 10 s
/// before it (ten more readings at rest). Before, each file's tags were unwrapped alone:
/// the first failed in the derive ("0 of its 847 rows within the IMU log"), the second
/// named a day's shift that, written into the file, would have moved its readings after
/// midnight a day back. Now the speed file's first tag is taken beside the log's (a day
/// on, or a day back until its own rollover), and each run is the one on its own clock:
/// the joint fit's control points within 1 cm.
#[test]
fn kingston_a_speed_file_begun_across_midnight_from_its_log_is_on_its_clock() {
    let tmp = tempfile::tempdir().unwrap();
    let day_s = unz_formats::kfgins::DAY_S;
    let own = own_clock_reference(tmp.path());
    let rows = |run: &std::path::Path| -> Vec<String> {
        let text = std::fs::read_to_string(run.join("odometer.txt")).unwrap();
        text.lines().map(str::to_owned).collect()
    };
    let tag = |row: &str| -> f64 { row.split_once(' ').unwrap().0.parse().unwrap() };
    // The IMU 30 s before midnight; the speed file from midnight on.
    let after = kingston_retimed(&tmp.path().join("after"), |t| {
        (t - 152_143.0 + day_s - 30.0) % day_s
    });
    let from_midnight: Vec<String> = (rows(&after).into_iter())
        .filter(|r| tag(r) < 80_000.0)
        .collect();
    std::fs::write(after.join("odometer.txt"), from_midnight.join("\n") + "\n").unwrap();
    // The IMU 5 s after midnight; the speed file 10 s before it, at rest.
    let before = kingston_retimed(&tmp.path().join("before"), |t| {
        (t - 152_143.09 + 5.0).rem_euclid(day_s)
    });
    let first = tag(&rows(&before)[0]);
    let at_rest = (1..=10)
        .rev()
        .map(|k| format!("{:.3} 0.00000", (first - k as f64).rem_euclid(day_s)));
    let with_rest: Vec<String> = at_rest.chain(rows(&before)).collect();
    assert!(tag(&with_rest[0]) > 86_000.0, "{}", with_rest[0]);
    std::fs::write(before.join("odometer.txt"), with_rest.join("\n") + "\n").unwrap();
    for (name, run, days) in [("after", &after, 1), ("before", &before, 1)] {
        let out = tmp.path().join(format!("{name}-o"));
        let file = disupt_with_ingest_report(run, &out).odometer_file.unwrap();
        assert_eq!(
            (file.day_rollovers, file.lines_rejected),
            (days, 0),
            "{name}"
        );
        assert_same_worst_point(&out, &own);
    }
}

/// Kingston's first control point timed in UTC seconds of day (a day and GPS time's 18 s
/// before the log's GPS seconds of week). Before, "control point 1 at t_s = 66407 is
/// outside the log" alone; now the day that brings it within the log is named, with the
/// time it would have there.
#[test]
fn kingston_a_control_points_time_in_utc_seconds_of_day_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let run = kingston_edited(&tmp.path().join("k"), "t_s = 152825.0", "t_s = 66407.0");
    let err = crate::util::stage_fails("navigate", &run, &tmp.path().join("o"));
    assert!(
        err.contains("control point 1 at t_s = 66407 is outside the log")
            && err
                .contains(": 86400 s later (1 day on) it would lie within it, at t_s = 152807.00")
            && err.contains("write the point's t_s on the log's clock"),
        "{err}"
    );
}

/// Kingston's log as a logger that stamps its lines as they come writes it: one line in
/// 40 written 60–80 ms late (0.6–0.8 of its 10-Hz period) and one in 40 as early, each
/// between lines on time. Before, a late line read as a gap of a sample lost (218 gaps in
/// `ingest.json` with the late lines alone) and the derive scaled its increments by its
/// interval: the error before DISUPT 32 and 29 m against 8.7 and 11.4, the joint fit's
/// azimuth 1.6° off the shipped run's, OWPI's 17°. Now each such line takes its slot's
/// time (the middle of its neighbours', counted as `lines_off_slot` and said), which is
/// the shipped tag to the nanosecond: the IMU's table and `disupt.json` are the shipped
/// run's byte for byte.
#[test]
fn kingston_lines_written_late_or_early_alone_take_their_slots() {
    let tmp = tempfile::tempdir().unwrap();
    let shipped = kingston_with(&tmp.path().join("shipped"), "");
    let mut off = 0;
    let run = kingston_imu_tags_edited(&tmp.path().join("jittery"), |k, t| {
        let by_s = 0.06 + 0.02 * ((k as f64 * 0.37).sin() * 0.5 + 0.5);
        let edited = match k % 40 {
            7 if k > 40 => t + by_s,
            27 => t - by_s,
            _ => return t,
        };
        off += 1;
        edited
    });
    assert!(off > 400, "{off}");
    let report = disupt_with_ingest_report(&run, &tmp.path().join("o"));
    assert_eq!(
        (report.lines_off_slot, report.seq_gaps, report.lost_samples),
        (off, 0, 0)
    );
    let shipped_report = disupt_with_ingest_report(&shipped, &tmp.path().join("so"));
    assert_eq!(shipped_report.lines_off_slot, 0);
    assert_imu_and_disupt_as_shipped(tmp.path());
    let log = std::fs::read_to_string(tmp.path().join("o/campaign.md")).unwrap();
    assert!(
        log.contains(&format!("{off} lines written late or early alone")),
        "{log}"
    );
}

/// Kingston's logger stamping every line with a jitter of up to ±30 ms (0.3 of its
/// 100-ms period, uniform, drawn by a fixed xorshift): every line stays in its slot (no
/// line off, no clock set back, no line lost in `ingest.json`), each sample's interval is
/// the period, and the corrections are the shipped run's within what the jitter leaves:
/// the joint fit's azimuth within 0.01° (a sixth of its σ, 0.059°; five draws moved it by
/// at most 0.003°), OEPI's within 0.02° (0.008°), OWPI's within 0.6° (0.38°: OWPI fits
/// the drifts and the azimuth on Kryt1 alone, its errors at the points 23 m on the
/// shipped run), and the joint fit's worst control point within 0.2 m of the shipped
/// one's. The odometer is still read at the jittering tags. Before, judged against the
/// last line's tag, a line 0.25 of a period early after one as late read as the clock
/// set back (±25 ms: three steps, 0.154 s in all; ±40 ms: over 100, and the derive
/// failed as an odometer 14.5 s off), the samples' intervals were their tags', and
/// OWPI's azimuth went 4.2° off with ±25 ms.
#[test]
fn kingston_a_logger_jittering_by_a_third_of_its_period_keeps_its_slots() {
    use unz::disupt_stage::DisuptOut;
    let tmp = tempfile::tempdir().unwrap();
    let shipped = kingston_with(&tmp.path().join("shipped"), "");
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let run = kingston_imu_tags_edited(&tmp.path().join("jittering"), |_, t| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let uniform = (state >> 11) as f64 / (1u64 << 53) as f64;
        t + 0.03 * (2.0 * uniform - 1.0)
    });
    let report = disupt_with_ingest_report(&run, &tmp.path().join("o"));
    assert_eq!(
        (
            report.lines_off_slot,
            report.text_clock_steps_back,
            report.seq_gaps,
            report.lost_samples
        ),
        (0, 0, 0, 0)
    );
    disupt_with_ingest_report(&shipped, &tmp.path().join("so"));
    let (got, want) = azimuths_near_shipped(tmp.path());
    let worst = |d: &DisuptOut| worst_control_point_m(&d.methods["joint"]);
    assert!(
        (worst(&got) - worst(&want)).abs() < 0.2,
        "{} m",
        worst(&got)
    );
}

/// Kingston as a logger writes it that stamps its lines as it receives them, five at a
/// time: each burst's lines 1 ms apart, the first at its last sample's time. Session 81's
/// reader took the tags' median step (1 ms) for the period, read each half-second gap as
/// 495 samples lost and the derive failed. Now its first lines show the bursts, and each
/// burst's lines end at its first tag a period apart: the shipped run's `imu.parquet` and
/// `disupt.json` byte for byte, the bursts said in the summary. Handed over 3 to 8 at a
/// time, each burst up to 30 ms late: no line lost, the shipped azimuths (OWPI within
/// 0.6°; the joint within 0.03°, half its σ of 0.059°: a burst's lateness cannot be
/// told, and its lines keep it, 15 ms on average against the speed file, which moves
/// the joint by 0.018°).
#[test]
fn kingston_tags_in_bursts_are_spread_over_each_burst() {
    let tmp = tempfile::tempdir().unwrap();
    let shipped = kingston_with(&tmp.path().join("shipped"), "");
    disupt_with_ingest_report(&shipped, &tmp.path().join("so"));
    let run = kingston_imu_tags_edited(&tmp.path().join("bursts"), |k, t| {
        let burst_end = t + 0.1 * (4 - k % 5) as f64;
        burst_end + 0.001 * (k % 5) as f64
    });
    let report = disupt_with_ingest_report(&run, &tmp.path().join("o"));
    let bursts = report.text_bursts.expect("bursts");
    assert!(bursts.whole_log && (bursts.bursts, bursts.longest_lines) == (1752, 5));
    assert_eq!((report.lost_samples, report.text_clock_steps_back), (0, 0));
    assert_imu_and_disupt_as_shipped(tmp.path());
    let summary = std::fs::read_to_string(tmp.path().join("o/campaign.md")).unwrap();
    assert!(
        summary.contains("the log's lines came in bursts (a logger stamping them as it received them, several at once: 1752 bursts of up to 5 lines): each burst's lines taken 100.000 ms apart"),
        "{summary}"
    );

    // Bursts of 3 to 8 lines, each stamped 0 to 30 ms after its last sample was made.
    // (The last burst holds the lines left.)
    let sizes = [3, 7, 5, 8, 4, 6, 3, 5, 8, 6, 4, 7];
    let (mut in_burst, mut burst, mut k0) = (Vec::new(), 0, 0);
    let size = |burst: usize, k0: usize| sizes[burst % sizes.len()].min(8760 - k0);
    for k in 0..8760 {
        if k == k0 + size(burst, k0) {
            (k0, burst) = (k, burst + 1);
        }
        in_burst.push((k - k0, size(burst, k0), burst));
    }
    std::fs::remove_dir_all(tmp.path().join("o")).unwrap();
    kingston_imu_tags_edited(&run, |k, t| {
        let (j, n, b) = in_burst[k];
        let late_s = 0.03 * ((b * 7) % 11) as f64 / 10.0;
        t + 0.1 * (n - 1 - j) as f64 + late_s + 0.001 * j as f64
    });
    let report = disupt_with_ingest_report(&run, &tmp.path().join("o"));
    let bursts = report.text_bursts.expect("bursts");
    assert!(bursts.whole_log && bursts.longest_lines == 8, "{bursts:?}");
    assert_no_line_lost_stepped_or_off(&report);
    azimuths_within(tmp.path(), 0.03);
}

/// Kingston as a logger writes it that stalls now and then (about one line in 60) and
/// then hands over the 3 to 6 lines it held at once, 1 ms apart, the first up to 10 ms
/// after the last sample was made. Session 82's reader read each stall as the clock set
/// back and lines lost (162 steps back, 491 lines lost) and the run went "ok" 550 m off
/// before DISUPT. Now each stall's lines end at its first tag a period apart: no line
/// lost or stepped, the shipped azimuths (joint within 0.01°, OWPI within 0.6°).
#[test]
fn kingston_a_logger_stalling_now_and_then_keeps_its_lines_on_their_slots() {
    let tmp = tempfile::tempdir().unwrap();
    let shipped = kingston_with(&tmp.path().join("shipped"), "");
    disupt_with_ingest_report(&shipped, &tmp.path().join("so"));
    // Line k's place in its stall (and the stall's lines), if in one.
    let (mut stall, mut stalls) = (vec![None; 8760], 0);
    let mut k = 200;
    while k < 8700 {
        let n = 3 + (k * 7) % 4;
        for j in 0..n {
            stall[k + j] = Some((j, n, stalls));
        }
        (k, stalls) = (k + 50 + (k * 13) % 21, stalls + 1);
    }
    let run = kingston_imu_tags_edited(&tmp.path().join("stalls"), |k, t| match stall[k] {
        Some((j, n, s)) => {
            let late_s = 0.01 * ((s * 3) % 7) as f64 / 6.0;
            t + 0.1 * (n - 1 - j) as f64 + late_s + 0.001 * j as f64
        }
        None => t,
    });
    let report = disupt_with_ingest_report(&run, &tmp.path().join("o"));
    let bursts = report.text_bursts.expect("bursts");
    assert!(
        !bursts.whole_log && bursts.bursts == stalls as u64,
        "{bursts:?}"
    );
    assert_no_line_lost_stepped_or_off(&report);
    azimuths_near_shipped(tmp.path());
}

/// Kingston as a logger writes it whose clock ticks every 156.25 ms (1.5625 of its
/// 100-ms periods, as a PC's 15.625-ms timer under a 100-Hz IMU): each tag its line's
/// time down to the tick, two lines to a tag now and then. Session 83's reader took the
/// tick for the period and each shared tag for the clock set back (3153 steps, +492 s),
/// and the derive failed on accelerometers "not in m/s"; on a 78.125-ms clock (0.78 of a
/// period: no tag shared, steps of one tick and two) it read every other step as a line
/// lost, and failed likewise. Now each line takes its slot on a clock following the
/// ticks: no line lost or stepped, the shipped azimuths (within
/// [`azimuths_near_shipped`]'s tolerances). With one line in a hundred lost, each is
/// counted and every line keeps its time to a tenth of a period but beside a gap whose
/// place among a tick's lines the ticks cannot tell (at most half the gaps: 34 of 90
/// measured), one line a period off; the joint azimuth stays within 0.5° of the same
/// lines lost from the shipped tags (0.375° measured: a tenth of a second of a 10-Hz
/// IMU's rotation moved, where lines lost already take Kryt1 before DISUPT from 0.90 to
/// 3.1 rad and OWPI 50° off).
#[test]
fn kingston_stamped_by_a_coarse_clock_keeps_its_lines_on_their_slots() {
    use unz_formats::parquet_io::read_batches;
    use unz_formats::tables::i64_column;
    let tmp = tempfile::tempdir().unwrap();
    let shipped = kingston_with(&tmp.path().join("shipped"), "");
    disupt_with_ingest_report(&shipped, &tmp.path().join("so"));
    // The ticks of a PC's timer under a 100-Hz IMU, and under a 128-Hz one (0.78 of a
    // period: steps of one tick and of two).
    for (tick_s, said) in [
        (0.15625, "156.250-ms ticks, 1.56 periods of"),
        (0.078125, "78.125-ms ticks, 0.78 periods of"),
    ] {
        let on_ticks = |_: usize, t: f64| (t / tick_s).floor() * tick_s;
        let run = kingston_imu_tags_edited(&tmp.path().join(format!("ticks-{tick_s}")), on_ticks);
        let _ = std::fs::remove_dir_all(tmp.path().join("o"));
        let report = disupt_with_ingest_report(&run, &tmp.path().join("o"));
        let ticks = report.text_ticks.expect("a coarse clock");
        let (tick_off_s, period_off_s) = (ticks.tick_s - tick_s, ticks.period_s - 0.1);
        assert!(
            tick_off_s.abs() < 1e-5 && period_off_s.abs() < 1e-5,
            "{ticks:?}"
        );
        assert_eq!((ticks.lines, ticks.early, ticks.restarts), (8760, 0, 0));
        assert_no_line_lost_stepped_or_off(&report);
        azimuths_near_shipped(tmp.path());
        let summary = std::fs::read_to_string(tmp.path().join("o/campaign.md")).unwrap();
        let said = format!("the log's time tags are a clock's of {said}");
        assert!(summary.contains(&said), "{summary}");
    }
    let tick_s = 0.15625;
    let on_ticks = |_: usize, t: f64| (t / tick_s).floor() * tick_s;

    let lost = |k: usize| k > 50 && k % 97 == 13;
    let dropped = (0..8760).filter(|&k| lost(k)).count() as u64;
    let joint_deg = |run: &std::path::Path, out: &str| {
        let out = tmp.path().join(out);
        let report = disupt_with_ingest_report(run, &out);
        let d: unz::disupt_stage::DisuptOut =
            read_json(&out.join("kingston2008-segment1/disupt/disupt.json"));
        (report, d.methods["joint"].outcome.x.azimuth_deg)
    };
    let exact = kingston_imu_lines_kept(&tmp.path().join("lost"), |k| !lost(k));
    let (exact_report, exact_deg) = joint_deg(&exact, "lost-o");
    let coarse = kingston_imu_lines_kept(&tmp.path().join("lost-ticks"), |k| !lost(k));
    edit_imu_tags(&coarse, on_ticks);
    let (report, coarse_deg) = joint_deg(&coarse, "lost-ticks-o");
    assert_eq!(
        (exact_report.lost_samples, report.lost_samples),
        (dropped, dropped)
    );
    let tags_s = |out: &str| -> Vec<f64> {
        let path = tmp
            .path()
            .join(out)
            .join("kingston2008-segment1/ingest/imu.parquet");
        let (_, batches) = read_batches(&path).unwrap();
        (batches.iter())
            .flat_map(|b| i64_column(b, "t_ns").unwrap())
            .map(|t| t as f64 * 1e-9)
            .collect()
    };
    let (exact_s, coarse_s) = (tags_s("lost-o"), tags_s("lost-ticks-o"));
    let mut offs_s: Vec<f64> = exact_s.iter().zip(&coarse_s).map(|(e, c)| c - e).collect();
    let median_s = {
        let mut sorted = offs_s.clone();
        sorted.sort_by(f64::total_cmp);
        sorted[sorted.len() / 2]
    };
    offs_s.iter_mut().for_each(|o| *o -= median_s);
    let off_slot = offs_s.iter().filter(|o| o.abs() > 0.01).count();
    assert!(
        offs_s.iter().all(|o| o.abs() < 0.11),
        "a line more than a period off"
    );
    assert!(
        2 * off_slot <= dropped as usize,
        "{off_slot} lines off their slot"
    );
    eprintln!("joint: {exact_deg:.4}° from the shipped tags, {coarse_deg:.4}° on ticks");
    assert!((coarse_deg - exact_deg).abs() < 0.5);
}

/// Kingston with one IMU line lost in a pitching turn (line 6001, 600 s in: the pitch
/// rate 1.3 °/s before it and 2.9 °/s after). Holding the closing sample's rate over the
/// stretch, as the derive did, tilted the dead reckoning by 0.165° in roll and pitch for
/// the rest of the run (Kryt1 before DISUPT 0.90 → 1.44 rad, OWPI 11.9° off). Filled with
/// the mean of the rates either side, the navigation's roll and pitch stay within 0.06°
/// of the shipped run's at every sample (0.042° measured), and its heading within 0.03°.
#[test]
fn kingston_a_line_lost_in_a_pitching_turn_is_filled_by_the_rates_either_side() {
    use unz_formats::parquet_io::read_batches;
    use unz_formats::tables::{f32_column, i64_column};
    let tmp = tempfile::tempdir().unwrap();
    let run = kingston_imu_lines_kept(&tmp.path().join("lost"), |k| k != 6000);
    let shipped = kingston_with(&tmp.path().join("shipped"), "");
    let nav = |run: &std::path::Path, out: &str| {
        let out = tmp.path().join(out);
        crate::util::run_until(run, &out, "navigate");
        let path = out.join("kingston2008-segment1/navigate/nav.parquet");
        let (_, batches) = read_batches(&path).unwrap();
        let column = |name: &str| -> Vec<f32> {
            (batches.iter())
                .flat_map(|b| f32_column(b, name).unwrap())
                .collect()
        };
        let t_ns: Vec<i64> = (batches.iter())
            .flat_map(|b| i64_column(b, "t_ns").unwrap())
            .collect();
        (
            t_ns,
            column("roll_deg"),
            column("pitch_deg"),
            column("heading_deg"),
        )
    };
    let (got, want) = (nav(&run, "o"), nav(&shipped, "so"));
    assert_eq!(got.0.len(), want.0.len() - 1);
    let mut worst = [0f32; 3];
    for (k, t) in got.0.iter().enumerate() {
        let i = want.0.binary_search(t).expect("a kept sample's time");
        for (w, (g, s)) in worst.iter_mut().zip([
            (got.1[k], want.1[i]),
            (got.2[k], want.2[i]),
            (got.3[k], want.3[i]),
        ]) {
            *w = w.max((g - s).abs());
        }
    }
    assert!(
        worst[0] < 0.06 && worst[1] < 0.06 && worst[2] < 0.03,
        "{worst:?}"
    );
}

/// Kingston losing about one IMU line in a hundred (three patterns, lines chosen by a
/// hash of their index). Each lost sample is filled from the rates either side, and on a
/// car the pitch and roll rates vibrate from sample to sample at 10 Hz: each fill is
/// about 1 mrad off about x and y, and the dead reckoning keeps it (no levelling). The
/// joint fit read the fills' random walk of tilt as drift: on these eight patterns its
/// horizontal drifts went up to 1.18 °/h from the shipped run's, up to 7.5 of their σ
/// (RMS 3.8 σ), before it took the fills' tilt as unknowns. Now each gap is a step of
/// tilt with a prior from the rates around it ([`unz_stages::disupt::GapTilts`]): the
/// drifts stay within 0.25 °/h of the shipped run's, 1.32 σ at most and 0.75 σ RMS,
/// about what σ that carry the fills' uncertainty leave beside the shipped run's own
/// (0.68–0.84). The fills' turns in heading, profiled out of the control points' rows
/// ([`unz_stages::disupt`]'s gap turns), take the azimuth's σ from 0.059° to 0.068–0.086°
/// and its offsets from the shipped run's from 0.93 σ RMS (2.21 σ at most) to 0.64 σ
/// (1.50 σ). The fit says how many gaps it took.
#[test]
fn kingston_lost_lines_tilt_is_not_read_as_drift() {
    let tmp = tempfile::tempdir().unwrap();
    let joint = |run: &std::path::Path, out: &str| {
        let out = tmp.path().join(out);
        crate::util::run_until(run, &out, "disupt");
        let d: unz::disupt_stage::DisuptOut =
            read_json(&out.join("kingston2008-segment1/disupt/disupt.json"));
        d
    };
    let shipped = kingston_with(&tmp.path().join("shipped"), "");
    let base = joint(&shipped, "so");
    assert!(base.joint_gap_tilts.is_none(), "no gap in the shipped log");
    let base_drift = base.methods["joint"].outcome.x.drift_rad_s;
    let base_azimuth_deg = base.methods["joint"].outcome.x.azimuth_deg;
    let base_azimuth_sigma_deg = (base.methods["joint"].outcome.x.sigma.as_ref())
        .expect("the joint's σ")
        .azimuth_deg;
    // splitmix64 of the pattern and the line: about one line in a hundred.
    let lost = |pattern: u64, k: usize| {
        let mut z = (pattern << 32 | k as u64).wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        k > 0 && k < 8759 && z.is_multiple_of(100)
    };
    let mut offs = Vec::new();
    for pattern in 1..=8 {
        let dropped = (0..8760).filter(|&k| lost(pattern, k)).count();
        let run = kingston_imu_lines_kept(&tmp.path().join(format!("lost-{pattern}")), |k| {
            !lost(pattern, k)
        });
        let d = joint(&run, &format!("o-{pattern}"));
        let gaps = d.joint_gap_tilts.expect("the gaps taken");
        assert!(
            10 * gaps.gaps >= 9 * dropped && gaps.gaps <= dropped,
            "{gaps:?} of {dropped} lost"
        );
        assert!(gaps.turn_steps > 0, "{gaps:?}");
        let x = &d.methods["joint"].outcome.x;
        // The turns' σ in the azimuth's: beyond the shipped run's (0.059°).
        let az_sigma = x.sigma.as_ref().expect("the joint's σ").azimuth_deg;
        let az_off = (x.azimuth_deg - base_azimuth_deg) / az_sigma;
        eprintln!("pattern {pattern}: azimuth {az_off:+.2} σ (σ {az_sigma:.3}°); {gaps:?}");
        assert!(az_off.abs() < 2.5 && az_sigma > base_azimuth_sigma_deg);
        let sigma = x.sigma.as_ref().expect("the joint's σ").drift_rad_s;
        let per_h = 180.0 / std::f64::consts::PI * 3600.0;
        for axis in 0..2 {
            let off = (x.drift_rad_s[axis] - base_drift[axis]) / sigma[axis];
            eprintln!(
                "pattern {pattern}, {dropped} lost: drift {axis} {:+.3} °/h against {:+.3}, \
                 σ {:.3}: {off:+.2} σ",
                x.drift_rad_s[axis] * per_h,
                base_drift[axis] * per_h,
                sigma[axis] * per_h
            );
            assert!(
                off.abs() < 2.5,
                "pattern {pattern}, axis {axis}: {off:+.2} σ"
            );
            offs.push(off);
        }
    }
    let rms = (offs.iter().map(|o| o * o).sum::<f64>() / offs.len() as f64).sqrt();
    eprintln!("RMS of the drifts' offsets: {rms:.2} σ");
    assert!(rms < 1.0, "the drifts' offsets' RMS {rms:.2} σ");
}

/// Kingston's reference (the SPAN's INS/GPS, the same HG1700) heads 0.28° left of its
/// own direction of travel while the car drives (the median over 205 epochs above 5 m/s;
/// their spread 0.44°, a car's slip in turns): the IMU sits yawed 0.28° on the car, the
/// odometer's direction 0.28° clockwise of its x. The joint fit's residuals show that
/// boresight from the pitch and roll alone (the control points see it only with the
/// azimuth): +0.58° ± 0.22°, the same sign and within 2σ (with the sign flipped, 3.9σ
/// off). At 2.6σ it is under the 3σ that refits with it free, so the shipped run's
/// azimuth takes it whole: its heading runs 0.24–0.50° from the reference's while
/// driving, at σ 0.054° (with `joint_odo_yaw = true`: −0.09 to −0.35° at σ 0.23°).
#[test]
fn kingston_odometer_yaw_boresight_seen_agrees_with_the_references_heading_and_track() {
    let r = reference();
    let mut off: Vec<f64> = (0..r.t_s.len())
        .filter(|&i| r.speed[i] > 5.0)
        .map(|i| wrap_pi((r.azimuth[i] - r.track[i]).to_radians()).to_degrees())
        .collect();
    assert!(off.len() > 150, "{} epochs driving", off.len());
    off.sort_by(f64::total_cmp);
    // The IMU's heading is the vehicle's less the boresight.
    let reference_yaw_deg = -off[off.len() / 2];
    assert!(
        (reference_yaw_deg - 0.28).abs() < 0.02,
        "{reference_yaw_deg}"
    );
    let tmp = tempfile::tempdir().unwrap();
    let run = kingston_with(&tmp.path().join("k"), "");
    let out = tmp.path().join("o");
    crate::util::run_until(&run, &out, "disupt");
    let d: unz::disupt_stage::DisuptOut =
        read_json(&out.join("kingston2008-segment1/disupt/disupt.json"));
    let check = d.joint_odo_yaw_check.expect("the boresight checked");
    let seen = check.seen;
    let z = (seen.odo_yaw_deg - reference_yaw_deg) / seen.sigma_deg;
    eprintln!(
        "reference {reference_yaw_deg:+.3}°, seen {:+.3}° ± {:.3}° ({z:+.2}σ from it)",
        seen.odo_yaw_deg, seen.sigma_deg
    );
    assert!(z.abs() < 2.0, "{z:+.2}σ");
    assert!(!check.refit, "{check:?}");
}

/// Kingston losing every k-th IMU line (k = 3, 5, 10, 50): steps of one period and of
/// two, as regular as a clock ticking every 100 ms stamps samples 100 k / (k − 1) ms
/// apart. The ingest read them as that clock (one line in ten lost: 111.111-ms samples,
/// the joint fit out of its bounds; one in fifty: "ok" with both control points' hold-out
/// errors 14σ; one in three or five: the derive failed on accelerometers "not in m/s").
/// The lines' velocity increments span 100 ms (99.98 by gravity), so each log is now
/// read as losing one line in k: every line lost counted, the fills taken as unknowns by
/// the joint fit, its azimuth within 3σ of the shipped run's (measured 0.9, 2.4, 1.3 and
/// 2.9σ: one in five and one in fifty cross the odometer yaw boresight's 3σ check,
/// which the shipped run shows at 2.6σ, and are refitted with it free), and neither
/// control point's hold-out error beyond what the fit without it predicts.
#[test]
fn kingston_lines_lost_regularly_are_not_read_as_a_finer_clock() {
    let tmp = tempfile::tempdir().unwrap();
    let shipped = kingston_with(&tmp.path().join("shipped"), "");
    let out = tmp.path().join("so");
    crate::util::run_until(&shipped, &out, "disupt");
    let base: unz::disupt_stage::DisuptOut =
        read_json(&out.join("kingston2008-segment1/disupt/disupt.json"));
    let base_azimuth_deg = base.methods["joint"].outcome.x.azimuth_deg;
    for k in [3, 5, 10, 50] {
        let lost = |i: usize| i > 0 && i < 8759 && i.is_multiple_of(k);
        let dropped = (0..8760).filter(|&i| lost(i)).count() as u64;
        let run = kingston_imu_lines_kept(&tmp.path().join(format!("every-{k}")), |i| !lost(i));
        let out = tmp.path().join(format!("o-{k}"));
        crate::util::run_until(&run, &out, "disupt");
        let dir = out.join("kingston2008-segment1");
        let ingest: unz_formats::IngestReport = read_json(&dir.join("ingest/ingest.json"));
        let loss = ingest
            .text_regular_loss
            .expect("read as lines lost regularly");
        assert!(ingest.text_ticks.is_none(), "{ingest:?}");
        assert_eq!(ingest.lost_samples, dropped, "one line in {k}");
        assert!((loss.one_in() - k as f64).abs() < 0.05, "{loss:?}");
        assert!((loss.period_s - 0.1).abs() < 1e-6, "{loss:?}");
        let d: unz::disupt_stage::DisuptOut = read_json(&dir.join("disupt/disupt.json"));
        let gaps = d.joint_gap_tilts.as_ref().expect("the gaps taken");
        // A fill whose miss is under a step's least σ (at rest) takes no step.
        let taken = gaps.gaps as u64;
        assert!(10 * taken >= 9 * dropped && taken <= dropped, "{gaps:?}");
        let joint = &d.methods["joint"].outcome;
        let sigma_deg = joint.x.sigma.as_ref().expect("the joint's σ").azimuth_deg;
        let off = (joint.x.azimuth_deg - base_azimuth_deg) / sigma_deg;
        eprintln!(
            "one in {k}: joint azimuth {:.3}° ({off:+.2}σ, σ {sigma_deg:.3}°); {gaps:?}",
            joint.x.azimuth_deg
        );
        assert!(off.abs() < 3.0, "one in {k}: {off:+.2}σ");
        let holdout = d.methods["joint"].holdout.as_ref().expect("the hold-out");
        assert_eq!(holdout.len(), 2);
        assert!(
            holdout
                .iter()
                .all(|h| !h.inconsistent && h.error_sigma.is_some_and(|e| e < 3.0)),
            "one in {k}: {holdout:?}"
        );
    }
}

/// Kingston keeping every other IMU line: its tags step evenly by 200 ms, a 5-Hz log to
/// the reader, while each line's increments span 100 ms, so the accelerometers read
/// half of gravity. The derive fails as before, and says the log keeps one sample in
/// two (it said only that the increments were not in m/s).
#[test]
fn kingston_keeping_every_other_line_fails_naming_one_sample_in_two() {
    let tmp = tempfile::tempdir().unwrap();
    let run = kingston_imu_lines_kept(&tmp.path().join("halved"), |i| i % 2 == 1);
    let err = crate::util::stage_fails("derive", &run, &tmp.path().join("o"));
    assert!(err.contains("4.90 m/s² in size"), "{err}");
    assert!(
        err.contains("each line's increments span 1/2 of the step between its tags")
            && err.contains("the log keeps one sample in 2"),
        "{err}"
    );
}

/// Kingston with four lines in five lost after its first 200 (its tags as shipped): the
/// samples kept cover under a quarter of the log, and the derive fails naming the counts
/// and the span per sample against the period; a log that lost most of its samples has
/// no dead reckoning to correct.
#[test]
fn kingston_a_log_that_lost_most_of_its_lines_fails_the_derive_naming_the_counts() {
    let tmp = tempfile::tempdir().unwrap();
    let run = kingston_imu_lines_kept(&tmp.path().join("lost"), |k| k < 200 || k % 5 == 0);
    let err = crate::util::stage_fails("derive", &run, &tmp.path().join("o"));
    assert!(err.contains("stage derive failed"), "{err}");
    assert!(
        err.contains("6844 IMU samples read as lost against 1912 kept")
            && err.contains("a log that lost most of its samples has no dead reckoning")
            && err.contains("while its tags step by 100.000 ms"),
        "{err}"
    );
    assert!(!err.contains("degrees?"), "{err}");
}

/// Kingston's logger's clock set back three times while it logs, its speed file and
/// control points on the clock it started on: 1.5 s back at line 3001, 70 ms (0.7 of a
/// period) at line 5001, 0.5 s at line 6001. Before, every tag after the first step went
/// back from the time repaired before it and the derive failed ("5760 of 8760 IMU time
/// tags do not increase"). Now each step is taken out (counted in `ingest.json`, said in
/// the summary), the line after it taking the time one period after the line before,
/// which is the shipped tag to the nanosecond: the IMU's table and `disupt.json` are the
/// shipped run's byte for byte. With its speed file set back with it (one logger), the
/// derive fails as on another clock (2.2 s early) and names the steps' lines: the one
/// shift for the whole file its clock check names alone is no fix.
#[test]
fn kingston_a_clock_set_back_while_logging_is_the_run_on_its_start_clock() {
    let tmp = tempfile::tempdir().unwrap();
    let shipped = kingston_with(&tmp.path().join("shipped"), "");
    let run = kingston_imu_tags_edited(&tmp.path().join("stepped"), |k, t| {
        t - set_back_s(|from| k >= from)
    });
    let report = disupt_with_ingest_report(&run, &tmp.path().join("o"));
    assert_eq!(
        (
            report.text_clock_steps_back,
            report.t_non_increasing,
            report.lost_samples
        ),
        (3, 0, 0)
    );
    assert!(
        (report.text_clock_shift_s - 2.07).abs() < 1e-6,
        "{report:?}"
    );
    disupt_with_ingest_report(&shipped, &tmp.path().join("so"));
    assert_imu_and_disupt_as_shipped(tmp.path());
    let summary = std::fs::read_to_string(tmp.path().join("o/campaign.md")).unwrap();
    assert!(
        summary.contains(
            "the log's clock was set back 3 times while it logged (line 3001 +1.500 s, \
             line 5001 +0.070 s, line 6001 +0.500 s;"
        ) && summary.contains("moved by +2.070000 s"),
        "{summary}"
    );

    // Its speed file written on the same clock (one logger, both files): its tags show
    // the steps, and are moved by them too. The file's times are then the shipped file's
    // (to the nanosecond), its distances within 1e-9 m (each trapezoid's interval from
    // the moved tags), and the methods' azimuths within 1e-6°. Before, the derive failed
    // as an odometer on another clock.
    assert_speeds_on_the_stepped_clock_follow(
        tmp.path(),
        &run,
        &[(3000, -1.5), (5000, -0.07), (6000, -0.5)],
    );
}

/// Kingston's IMU log with its clock set forward while it logged (0.437 s at line 3001,
/// 1.262 s at line 6001: a time sync's steps, whole periods and a phase), with its speed
/// file on that clock and on a clock of its own. The steps are taken out (not read as
/// lines lost) and the run is the shipped one: its `imu.parquet` and `disupt.json` byte
/// for byte, or, with the speed file moved back by the steps, within 1e-6°. Before, the
/// first step read as 4 lines lost and the second as 12, each sample after them had its
/// increments scaled over them (Kryt1 before DISUPT 4.8 rad for 0.90, OWPI 81° off with
/// such a step near the run's end), and a speed file on the stepped clock went on late
/// of the IMU by the steps. A step of whole periods still reads as lines lost (nothing
/// tells them apart without sequence numbers).
#[test]
fn kingston_a_clock_set_forward_while_logging_is_the_run_on_its_start_clock() {
    let tmp = tempfile::tempdir().unwrap();
    let shipped = kingston_with(&tmp.path().join("shipped"), "");
    disupt_with_ingest_report(&shipped, &tmp.path().join("so"));
    let forward_s = |after: &dyn Fn(usize) -> bool| -> f64 {
        [(3000, 0.437), (6000, 1.262)]
            .iter()
            .filter(|(from, _)| after(*from))
            .map(|(_, s)| s)
            .sum()
    };
    let run = kingston_imu_tags_edited(&tmp.path().join("stepped"), |k, t| {
        t + forward_s(&|from| k >= from)
    });
    let report = disupt_with_ingest_report(&run, &tmp.path().join("o"));
    assert_eq!(
        (
            report.text_clock_steps_forward,
            report.text_clock_steps_back,
            report.lost_samples
        ),
        (2, 0, 0)
    );
    assert!(
        (report.text_clock_shift_s + 1.699).abs() < 1e-6,
        "{report:?}"
    );
    let file = report.odometer_file.unwrap();
    assert_eq!(
        (file.clock_steps_followed, file.clock_steps_not_shown),
        (0, 2)
    );
    assert_imu_and_disupt_as_shipped(tmp.path());
    let summary = std::fs::read_to_string(tmp.path().join("o/campaign.md")).unwrap();
    assert!(
        summary.contains(
            "the log's clock was set forward twice while it logged (line 3001 -0.437 s, \
             line 6001 -1.262 s;"
        ) && summary.contains("the odometer file's tags showed 0 of the steps"),
        "{summary}"
    );

    // The speed file on the stepped clock too.
    assert_speeds_on_the_stepped_clock_follow(tmp.path(), &run, &[(3000, 0.437), (6000, 1.262)]);

    // A step of whole periods (0.5 s) reads as lines lost, as before.
    let whole = kingston_imu_tags_edited(&tmp.path().join("whole"), |k, t| {
        t + if k >= 3000 { 0.5 } else { 0.0 }
    });
    let report = disupt_with_ingest_report(&whole, &tmp.path().join("whole-o"));
    assert_eq!(
        (report.text_clock_steps_forward, report.lost_samples),
        (0, 5)
    );
}

/// `run` (in `dir`, beside the shipped run's output `dir/so`) with its speed file as
/// shipped written on the log's stepped clock, each tag at or after the shipped tag of IMU
/// line `from` (0-based) moved by `step_s` for each `(from, step_s)` of `steps` (what the
/// step adds to the clock's reading), to 1 ms: the file follows every step, and the run
/// is the shipped one to 1e-6° ([`assert_disupt_near`]; output folder `dir/both-o`).
fn assert_speeds_on_the_stepped_clock_follow(
    dir: &std::path::Path,
    run: &std::path::Path,
    steps: &[(usize, f64)],
) {
    let data = crate::util::test_data("kingston2008-seg1");
    let imu_tags: Vec<f64> = (std::fs::read_to_string(data.join("imu.txt"))
        .unwrap()
        .lines())
    .map(|l| l.split_once(' ').unwrap().0.parse().unwrap())
    .collect();
    let speeds: String = (std::fs::read_to_string(data.join("odometer.txt"))
        .unwrap()
        .lines())
    .map(|line| {
        let (t, rest) = line.split_once(' ').unwrap();
        let t: f64 = t.parse().unwrap();
        let moved: f64 = (steps.iter())
            .filter(|(from, _)| t >= imu_tags[*from])
            .map(|(_, step_s)| step_s)
            .sum();
        format!("{:.3} {rest}\n", t + moved)
    })
    .collect();
    std::fs::write(run.join("odometer.txt"), speeds).unwrap();
    let report = disupt_with_ingest_report(run, &dir.join("both-o"));
    let file = report.odometer_file.unwrap();
    assert_eq!(
        (file.clock_steps_followed, file.clock_steps_not_shown),
        (steps.len() as u64, 0)
    );
    assert_disupt_near(dir, "both-o", 1e-6);
}

/// The edited run's methods (output folder `dir/o_name`) are the shipped run's (`dir/so`)
/// to `tolerance_deg` in azimuth and a millimetre at the control points.
fn assert_disupt_near(dir: &std::path::Path, o_name: &str, tolerance_deg: f64) {
    use unz::disupt_stage::DisuptOut;
    let disupt = |o: &str| -> DisuptOut {
        read_json(&dir.join(o).join("kingston2008-segment1/disupt/disupt.json"))
    };
    let (got, want) = (disupt(o_name), disupt("so"));
    for method in ["joint", "oepi", "owpi"] {
        let (a, b) = (&got.methods[method].outcome, &want.methods[method].outcome);
        assert!(
            (a.x.azimuth_deg - b.x.azimuth_deg).abs() < tolerance_deg
                && (a.dx_m - b.dx_m).abs() < 1e-3
                && (a.dy_m - b.dy_m).abs() < 1e-3,
            "{method}: azimuth {} for {}, ΔX {} for {}, ΔY {} for {}",
            a.x.azimuth_deg,
            b.x.azimuth_deg,
            a.dx_m,
            b.dx_m,
            a.dy_m,
            b.dy_m
        );
    }
}

/// Kingston's IMU tags moved by a jitter that repeats every 7 lines (0.3 of its 100-ms
/// period, a sinusoid: a logger's polling beating with the IMU's rate): no line read as
/// lost, off its slot or stepped, and the methods' azimuths those of the shipped run
/// (joint within 0.01°, OEPI 0.02°, OWPI 0.6°). Before, the first lines' periodogram
/// took a side peak (1.17 of the period) and the reader read 1253 clock steps back: the
/// run went "ok" with Kryt1 before DISUPT 11 rad and its error 550 m.
#[test]
fn kingston_a_jitter_repeating_every_seven_lines_keeps_its_slots() {
    let tmp = tempfile::tempdir().unwrap();
    let shipped = kingston_with(&tmp.path().join("shipped"), "");
    disupt_with_ingest_report(&shipped, &tmp.path().join("so"));
    let run = kingston_imu_tags_edited(&tmp.path().join("beating"), |k, t| {
        t + 0.03 * (std::f64::consts::TAU * k as f64 / 7.0).sin()
    });
    let report = disupt_with_ingest_report(&run, &tmp.path().join("o"));
    assert_eq!(
        (
            report.lost_samples,
            report.lines_off_slot,
            report.text_clock_steps_back,
            report.text_clock_steps_forward
        ),
        (0, 0, 0, 0)
    );
    azimuths_near_shipped(tmp.path());
}

/// The edited run's methods (output folder `dir/o`) against the shipped run's (`dir/so`):
/// the joint azimuth within 0.01°, OEPI's 0.02°, OWPI's 0.6° (a jitter's share). Both
/// runs' outputs.
fn azimuths_near_shipped(
    dir: &std::path::Path,
) -> (unz::disupt_stage::DisuptOut, unz::disupt_stage::DisuptOut) {
    azimuths_within(dir, 0.01)
}

/// [`azimuths_near_shipped`] with the joint azimuth within `joint_deg`.
fn azimuths_within(
    dir: &std::path::Path,
    joint_deg: f64,
) -> (unz::disupt_stage::DisuptOut, unz::disupt_stage::DisuptOut) {
    use unz::disupt_stage::DisuptOut;
    let disupt = |o: &str| -> DisuptOut {
        read_json(&dir.join(o).join("kingston2008-segment1/disupt/disupt.json"))
    };
    let (got, want) = (disupt("o"), disupt("so"));
    for (method, tolerance_deg) in [("joint", joint_deg), ("oepi", 0.02), ("owpi", 0.6)] {
        let az = |d: &DisuptOut| d.methods[method].outcome.x.azimuth_deg;
        let off_deg = az(&got) - az(&want);
        eprintln!("{method}: azimuth {:.4}° ({off_deg:+.4}°)", az(&got));
        assert!(off_deg.abs() < tolerance_deg, "{method}: {off_deg}°");
    }
    (got, want)
}

/// Kingston's clock steps back (at its IMU lines 3001, 5001 and 6001, 0-based 3000,
/// 5000, 6000): what they add to a tag after the lines `after` says it is.
fn set_back_s(after: impl Fn(usize) -> bool) -> f64 {
    [(3000, 1.5), (5000, 0.07), (6000, 0.5)]
        .iter()
        .filter(|(from, _)| after(*from))
        .map(|(_, s)| s)
        .sum()
}

/// Kingston in `run` (created) with only the IMU lines `keep` takes (by their 0-based
/// index), as a log that lost the others.
fn kingston_imu_lines_kept(
    run: &std::path::Path,
    keep: impl Fn(usize) -> bool,
) -> std::path::PathBuf {
    let run = kingston_with(run, "");
    let imu = std::fs::read_to_string(run.join("imu.txt")).unwrap();
    let kept: String = (imu.lines().enumerate())
        .filter(|(k, _)| keep(*k))
        .map(|(_, line)| format!("{line}\n"))
        .collect();
    std::fs::write(run.join("imu.txt"), kept).unwrap();
    run
}

/// Kingston in `run` (created) with its IMU line `k`'s time tag `t` written `edit(k, t)`,
/// to 1 ms (its speed file and control points as shipped).
fn kingston_imu_tags_edited(
    run: &std::path::Path,
    edit: impl FnMut(usize, f64) -> f64,
) -> std::path::PathBuf {
    let run = kingston_with(run, "");
    edit_imu_tags(&run, edit);
    run
}

/// `run`'s `imu.txt` with its line `k`'s time tag `t` written `edit(k, t)`, to 1 ms.
fn edit_imu_tags(run: &std::path::Path, mut edit: impl FnMut(usize, f64) -> f64) {
    let imu: String = (std::fs::read_to_string(run.join("imu.txt"))
        .unwrap()
        .lines())
    .enumerate()
    .map(|(k, line)| {
        let (t, rest) = line.split_once(' ').unwrap();
        format!("{:.3} {rest}\n", edit(k, t.parse().unwrap()))
    })
    .collect();
    std::fs::write(run.join("imu.txt"), imu).unwrap();
}

/// The edited run's `imu.parquet` and `disupt.json` (output folder `dir/o`) are the
/// shipped run's (`dir/so`) byte for byte.
fn assert_imu_and_disupt_as_shipped(dir: &std::path::Path) {
    let run_dir = |o: &str| dir.join(o).join("kingston2008-segment1");
    for file in ["ingest/imu.parquet", "disupt/disupt.json"] {
        let got = std::fs::read(run_dir("o").join(file)).unwrap();
        let want = std::fs::read(run_dir("so").join(file)).unwrap();
        assert!(got == want, "{file} differs from the shipped run's");
    }
}

/// The ingest read no line as lost, the clock set back at none, and none off its slot.
fn assert_no_line_lost_stepped_or_off(report: &unz_formats::IngestReport) {
    let counted = (
        report.lost_samples,
        report.text_clock_steps_back,
        report.lines_off_slot,
    );
    assert_eq!(counted, (0, 0, 0), "{report:?}");
}

/// `run` to disupt into `out`: the ingest's account (`ingest.json`).
fn disupt_with_ingest_report(
    run: &std::path::Path,
    out: &std::path::Path,
) -> unz_formats::IngestReport {
    crate::util::run_until(run, out, "disupt");
    read_json(&out.join("kingston2008-segment1/ingest/ingest.json"))
}

/// Kingston on its own clock, its speed file written as the retimed runs write theirs
/// (`kingston_odometer_edited`), run to disupt into `dir/own-o`: that output folder.
fn own_clock_reference(dir: &std::path::Path) -> std::path::PathBuf {
    let own = kingston_odometer_edited(&dir.join("own"), |t, v| (t, v));
    let out = dir.join("own-o");
    crate::util::run_until(&own, &out, "disupt");
    out
}

/// Kingston in `run` (created) with every time tag `t` (the IMU's, the speed file's, the
/// control points') written `retimed(t)`, to 1 ms.
fn kingston_retimed(run: &std::path::Path, retimed: impl Fn(f64) -> f64) -> std::path::PathBuf {
    let run = kingston_odometer_edited(run, |t, v| (retimed(t), v));
    edit_imu_tags(&run, |_, t| retimed(t));
    let path = run.join("run.toml");
    let mut m: toml::Table = toml::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    for cp in m["control_point"].as_array_mut().unwrap() {
        let t_s = cp["t_s"].as_float().unwrap();
        cp["t_s"] = toml::Value::Float(retimed(t_s));
    }
    std::fs::write(&path, toml::to_string(&m).unwrap()).unwrap();
    run
}

/// Kingston's speeds with a sensor's noise at rest (0–4 cm/s, never negative, as a GNSS
/// ground speed has) where the file reads 0. Before, the odometer's net travel from the
/// log's start passed 5 cm 3.3 s in, the static start given (500 s) was cut there, and
/// the run went on "ok" with the alignment's 2.3 s: the heading 2.2 km off at the points
/// before DISUPT, the joint fit's azimuth σ 0.67° (0.06° as shipped), its hold-out errors
/// 36 and 47 m. Now a move is 10 cm over a second: the static start is as given, the
/// heading gyrocompassed as shipped, the joint fit's azimuth σ under 0.2° (0.11°, with
/// the gyros' walk in it since session 87; 0.07° as shipped, a third of the cut start's
/// 0.67°), and the 10 m the odometer counted over the stand are said (nothing as
/// shipped).
#[test]
fn kingston_a_speed_sensors_noise_at_rest_keeps_the_static_start_and_is_said() {
    let tmp = tempfile::tempdir().unwrap();
    let run = kingston_odometer_edited(&tmp.path().join("k"), |t, v| {
        (t, if v < 0.05 { noise_at_rest_mps(t) } else { v })
    });
    let out = tmp.path().join("o");
    crate::util::run_until(&run, &out, "disupt");
    let d: unz::disupt_stage::DisuptOut =
        read_json(&out.join("kingston2008-segment1/disupt/disupt.json"));
    let nav = navigate_summary(&out);
    let shipped = shipped_navigated(&tmp.path().join("shipped"));
    assert_eq!(nav.initial.static_cut, None);
    assert!(
        (nav.initial.static_s - 500.0).abs() < 1e-9,
        "{:?}",
        nav.initial
    );
    let heading_apart = nav.initial.azimuth_deg - shipped.initial.azimuth_deg;
    assert!(heading_apart.abs() < 0.05, "{heading_apart}°");
    let sigma = d.methods["joint"]
        .outcome
        .x
        .sigma
        .as_ref()
        .unwrap()
        .azimuth_deg;
    assert!(sigma < 0.2, "joint azimuth σ {sigma}°");
    let travel = nav.initial.stand_travel.expect("the stand's travel said");
    assert!(
        (travel.travel_m - 10.5).abs() < 1.5 && (travel.stood_s - 527.0).abs() < 1.5,
        "{travel:?}"
    );
    // The floor that reads the noise's fastest (4 cm/s) as 0.
    assert_eq!(travel.floor_mps, Some(0.04), "{travel:?}");
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert!(
        summary.contains("the odometer counted 1")
            && summary.contains("s the vehicle stood")
            && summary.contains("set [odometer] speed_floor_mps = 0.04 in the run's manifest"),
        "{summary}"
    );
    assert_eq!(shipped.initial.stand_travel, None);
}

/// A speed sensor's noise at rest at `t_s`: 0–4 cm/s, never negative (a GNSS ground
/// speed's), 2 cm/s on average, from the time tag's whole seconds.
fn noise_at_rest_mps(t_s: f64) -> f64 {
    0.04 * ((t_s as i64 * 7919).rem_euclid(101) as f64 / 100.0)
}

/// 0–4 cm/s of noise where Kingston's speed file reads 0 (a GNSS ground speed at rest),
/// read through the floor the stand's note names (`[odometer] speed_floor_mps = 0.04`):
/// the noise is gone as if never logged. The derive, the navigation and the methods'
/// report are byte for byte the shipped file's through the same floor, and `ingest.json`
/// counts the readings floored and the travel they held, as the file writes them
/// (summed here by the trapezoid). Without the floor the joint fit's worst hold-out error
/// is 41 m; with it, the shipped file's through the floor: 2.2 m (3.0 m as shipped
/// without one: the floor also reads the file's own 0.8 and 2.0 cm/s as 0).
#[test]
fn kingston_a_speed_floor_reads_a_sensors_noise_at_rest_as_never_logged() {
    let tmp = tempfile::tempdir().unwrap();
    let floor_mps = 0.04;
    let noisy = kingston_odometer_edited(&tmp.path().join("noisy"), |t, v| {
        (t, if v == 0.0 { noise_at_rest_mps(t) } else { v })
    });
    let shipped = kingston_with(&tmp.path().join("shipped"), "");
    let set = format!("kind = \"speed_mps\"\nspeed_floor_mps = {floor_mps}\n");
    for run in [&noisy, &shipped] {
        let m = std::fs::read_to_string(run.join("run.toml")).unwrap();
        let floored = m.replacen("kind = \"speed_mps\"\n", &set, 1);
        assert_ne!(floored, m);
        std::fs::write(run.join("run.toml"), floored).unwrap();
    }
    let (out, reference) = (tmp.path().join("o"), tmp.path().join("shipped-o"));
    crate::util::run_until(&noisy, &out, "disupt");
    crate::util::run_until(&shipped, &reference, "disupt");
    for file in [
        "derive/derived.parquet",
        "navigate/nav.parquet",
        "navigate/navigate.json",
        "disupt/disupt.json",
    ] {
        let bytes = |o: &std::path::Path| {
            std::fs::read(o.join("kingston2008-segment1").join(file)).unwrap()
        };
        assert!(bytes(&out) == bytes(&reference), "{file} differs");
    }
    // The floor's account, from the file as written.
    let written: Vec<(f64, f64)> = std::fs::read_to_string(noisy.join("odometer.txt"))
        .unwrap()
        .lines()
        .map(|l| {
            let (t, v) = l.split_once(' ').unwrap();
            (t.parse().unwrap(), v.parse().unwrap())
        })
        .collect();
    let taken = |v: f64| {
        if v != 0.0 && v.abs() <= floor_mps {
            v
        } else {
            0.0
        }
    };
    let floored = written.iter().filter(|(_, v)| taken(*v) != 0.0).count() as u64;
    let floored_m: f64 = (written.windows(2))
        .map(|w| 0.5 * (taken(w[0].1) + taken(w[1].1)) * (w[1].0 - w[0].0))
        .sum();
    let ingest: unz_formats::IngestReport =
        read_json(&out.join("kingston2008-segment1/ingest/ingest.json"));
    let report = ingest.speed_floor.expect("the floor's account");
    assert_eq!(report.floor_mps, floor_mps);
    assert_eq!(report.readings_floored, floored);
    assert!(
        (report.floored_m - floored_m).abs() < 1e-9,
        "{report:?}, {floored_m} m"
    );
    // The noise over the 527-s stand, 2 cm/s on average, and over the stops after.
    assert!(floored > 550 && floored_m > 10.0, "{report:?}");
    let nav = navigate_summary(&out);
    assert_eq!(nav.initial.stand_travel, None, "{:?}", nav.initial);
    let worst_m = joint_worst_holdout_m(&out);
    assert!(worst_m < 3.5, "worst hold-out {worst_m} m");
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert!(
        summary.contains("the odometer's speeds at or below 0.04 m/s were read as 0"),
        "{summary}"
    );
}

/// The same noise at rest in an 8th column (Kingston's speeds at its 10-Hz IMU lines),
/// through the same floor: the run is the noiseless column's through the floor, byte for
/// byte, and the floor's account counts the noise's 10 readings a second over the stand.
#[test]
fn kingston_a_speed_floor_reads_an_8th_columns_noise_at_rest_as_never_logged() {
    let tmp = tempfile::tempdir().unwrap();
    let (noisy, plain) = (tmp.path().join("noisy"), tmp.path().join("plain"));
    kingston_column(
        &noisy,
        |t, v| if v == 0.0 { noise_at_rest_mps(t) } else { v },
    );
    kingston_column(&plain, |_, v| v);
    for run in [&noisy, &plain] {
        let m = std::fs::read_to_string(run.join("run.toml")).unwrap();
        let floored = m + "\n[odometer]\nspeed_floor_mps = 0.04\n";
        std::fs::write(run.join("run.toml"), floored).unwrap();
    }
    let (out, reference) = (tmp.path().join("o"), tmp.path().join("plain-o"));
    crate::util::run_until(&noisy, &out, "disupt");
    crate::util::run_until(&plain, &reference, "disupt");
    for file in ["navigate/nav.parquet", "disupt/disupt.json"] {
        let bytes = |o: &std::path::Path| {
            std::fs::read(o.join("kingston2008-segment1").join(file)).unwrap()
        };
        assert!(bytes(&out) == bytes(&reference), "{file} differs");
    }
    let ingest: unz_formats::IngestReport =
        read_json(&out.join("kingston2008-segment1/ingest/ingest.json"));
    let report = ingest.speed_floor.expect("the floor's account");
    // At 10 Hz over the 527-s stand, about one reading in a hundred of it 0, and more
    // at the stops after; 2 cm/s on average over the stand.
    assert!(report.readings_floored > 5_000, "{report:?}");
    assert!((10.0..13.0).contains(&report.floored_m), "{report:?}");
    assert_eq!(navigate_summary(&out).initial.stand_travel, None);
    // A floor over a log with neither an 8th column nor a speed file floors nothing: said.
    let seven = kingston_edited(
        &tmp.path().join("seven"),
        "file = \"odometer.txt\"\nkind = \"speed_mps\"",
        "speed_floor_mps = 0.04",
    );
    let err = crate::util::stage_fails("ingest", &seven, &tmp.path().join("seven-o"));
    assert!(
        err.contains("speed_floor_mps is set, but imu.txt has no odometer speeds"),
        "{err}"
    );
}

/// An 8th column left blank on some lines (a logger's line without a fresh reading, a
/// CSV's empty last field): Kingston's speeds at its 10-Hz lines, one line in ten without
/// one, space- or comma-separated, and its first 300 lines without one (beyond what the
/// reader reads ahead to know the log). Every line is an IMU sample (none rejected), the
/// speeds given are the odometer's, and the fit is the whole column's within what nine
/// readings in ten give (the joint azimuth within 0.005°, its control points within
/// 0.1 m, its worst hold-out within 0.6 m); the CSV is the spaced log's byte for byte,
/// the late column the whole one's (its blank lines stand). Before, the log's columns were
/// its first line's: the lines without a speed were rejected, 876 IMU samples lost (OWPI's
/// route 536 m off, no lag estimated), and a first line without one rejected every line
/// with one.
#[test]
fn kingston_an_8th_column_left_blank_keeps_its_imu_samples() {
    let tmp = tempfile::tempdir().unwrap();
    let whole = tmp.path().join("whole");
    kingston_column(&whole, |_, v| v);
    let lines: Vec<String> = (std::fs::read_to_string(whole.join("imu.txt"))
        .unwrap()
        .lines())
    .map(String::from)
    .collect();
    let without_speed = |l: &str| l.rsplit_once(' ').unwrap().0.to_owned();
    let edited = |name: &str, edit: &dyn Fn(usize, &str) -> String| {
        let run = tmp.path().join(name);
        std::fs::create_dir_all(&run).unwrap();
        std::fs::copy(whole.join("run.toml"), run.join("run.toml")).unwrap();
        let text: String = lines
            .iter()
            .enumerate()
            .map(|(k, l)| edit(k, l) + "\n")
            .collect();
        std::fs::write(run.join("imu.txt"), text).unwrap();
        let out = tmp.path().join(format!("{name}-o"));
        crate::util::run_until(&run, &out, "disupt");
        let stage = out.join("kingston2008-segment1");
        let ingest: unz_formats::IngestReport = read_json(&stage.join("ingest/ingest.json"));
        assert_eq!(
            (ingest.imu_accepted, ingest.rejected_total()),
            (8760, 0),
            "{name}"
        );
        let disupt: unz::disupt_stage::DisuptOut = read_json(&stage.join("disupt/disupt.json"));
        let json = std::fs::read(stage.join("disupt/disupt.json")).unwrap();
        (disupt, json, joint_worst_holdout_m(&out))
    };
    let (want, want_json, want_holdout) = edited("plain", &|_, l| l.to_owned());
    let blank = |k: usize, l: &str| {
        if k % 10 == 9 {
            without_speed(l)
        } else {
            l.to_owned()
        }
    };
    let (got, spaced, holdout) = edited("blank", &blank);
    let (a, b) = (
        &got.methods["joint"].outcome,
        &want.methods["joint"].outcome,
    );
    assert!(
        (a.x.azimuth_deg - b.x.azimuth_deg).abs() < 0.005,
        "azimuth {} for {}",
        a.x.azimuth_deg,
        b.x.azimuth_deg
    );
    assert!(
        (a.dx_m - b.dx_m).abs() < 0.1 && (a.dy_m - b.dy_m).abs() < 0.1,
        "ΔX {} for {}, ΔY {} for {}",
        a.dx_m,
        b.dx_m,
        a.dy_m,
        b.dy_m
    );
    assert!(
        (holdout - want_holdout).abs() < 0.6,
        "{holdout} for {want_holdout}"
    );
    let csv = |k: usize, l: &str| {
        let l = blank(k, l).replace(' ', ",");
        if k % 10 == 9 { l + "," } else { l }
    };
    let (_, comma, _) = edited("csv", &csv);
    assert!(
        comma == spaced,
        "the CSV's disupt.json differs from the spaced log's"
    );
    let late = |k: usize, l: &str| {
        if k < 300 {
            without_speed(l)
        } else {
            l.to_owned()
        }
    };
    let (_, late, _) = edited("late", &late);
    assert!(
        late == want_json,
        "the late column's disupt.json differs from the whole one's"
    );
}

/// Kingston with an 8th column and its speed file named in the manifest too: the file is
/// the odometer, the column left unread and said (`ingest.json`'s `speed_column_unread`,
/// the run's log and the campaign's note); the run is the shipped one's byte for byte,
/// whether the column holds the speeds or a constant 21.5 (a temperature, say). Before,
/// the column won over the file, in silence: a temperature's column read as 21.5 m/s ran
/// "ok" with the route 13 km off and 18.7 km driven.
#[test]
fn kingston_an_odometer_file_beside_an_8th_column_is_the_odometer() {
    let tmp = tempfile::tempdir().unwrap();
    let shipped = kingston_with(&tmp.path().join("shipped"), "");
    let want = tmp.path().join("shipped-o");
    crate::util::run_until(&shipped, &want, "disupt");
    let data = test_data("kingston2008-seg1");
    for (name, column) in [("speeds", None), ("temperature", Some(21.5))] {
        let run = tmp.path().join(name);
        kingston_column(&run, |_, v| column.unwrap_or(v));
        std::fs::copy(data.join("odometer.txt"), run.join("odometer.txt")).unwrap();
        std::fs::copy(data.join("run.toml"), run.join("run.toml")).unwrap();
        let out = tmp.path().join(format!("{name}-o"));
        crate::util::run_until(&run, &out, "disupt");
        let stage = |o: &std::path::Path, file: &str| {
            std::fs::read(o.join("kingston2008-segment1").join(file)).unwrap()
        };
        assert!(
            stage(&want, "disupt/disupt.json") == stage(&out, "disupt/disupt.json"),
            "{name}: disupt.json differs from the shipped run's"
        );
        let ingest: unz_formats::IngestReport =
            read_json(&out.join("kingston2008-segment1/ingest/ingest.json"));
        assert!(
            ingest.speed_column_unread && ingest.odometer_file.is_some(),
            "{name}"
        );
        let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
        assert!(
            summary.contains(
                "the manifest's [odometer] file is the odometer: the log's 8th column is left \
                 unread"
            ),
            "{summary}"
        );
    }
    let ingest: unz_formats::IngestReport =
        read_json(&want.join("kingston2008-segment1/ingest/ingest.json"));
    assert!(!ingest.speed_column_unread);
}

/// A log's 8th column of something else than a speed, with no odometer file named, fails
/// the derive, which names the column, its mean and the turns' gain, and the file to name:
/// a temperature of 21.5 (constant, or drifting 1.5° over the log), a battery's voltage
/// stepping up while the engine pulls. Before, each was read as the speed and the run
/// ran "ok" kilometres off: the constant 18.7 km driven where 2.4 km were, 13.3 km off at
/// the last control point. Each reads a gain across of 0.20–0.34 (the vehicle's speed
/// in its turns against the column's); the column's accelerations sum to at most 1.7
/// (m/s²)² where the speeds' give 63.
#[test]
fn kingston_an_8th_column_that_is_no_speed_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let t0_s = 152_143.0;
    let temperature = |_: f64, _: f64| 21.5;
    let drifting = |t: f64, _: f64| 21.5 + 1.5 * (t - t0_s) / 900.0;
    let voltage = |_: f64, v: f64| if v > 0.5 { 13.4 } else { 12.6 };
    type Column<'a> = &'a dyn Fn(f64, f64) -> f64;
    let columns: [(&str, Column, f64); 3] = [
        ("temperature", &temperature, 21.5),
        ("drifting", &drifting, 22.2),
        ("voltage", &voltage, 12.9),
    ];
    for (name, column, mean_mps) in columns {
        let run = tmp.path().join(name);
        kingston_column(&run, column);
        let err = crate::util::stage_fails("derive", &run, &tmp.path().join(format!("{name}-o")));
        assert!(
            err.contains("the log's 8th column (the odometer's speed) reads")
                && err.contains(
                    "it is not the vehicle's speed. Name the odometer's file in \
                                 the manifest's [odometer] file"
                ),
            "{name}: {err}"
        );
        let said_mean = crate::util::number_after(&err, "speed) reads ");
        assert!((said_mean - mean_mps).abs() < 0.1, "{name}: {err}");
        let gain = crate::util::number_after(&err, "the accelerometers' y is ");
        assert!((0.15..0.4).contains(&gain), "{name}: {err}");
    }
}

/// Kingston with its 8th column a constant 5 (a temperature, say) and no odometer file:
/// near the car's speed in its turns, the turns read it as a speed (a gain across within
/// 0.7–1.4), and the run went "ok" 3.6 km off at its last control point before DISUPT.
/// The static start given (500 s) names it: it reads 5.00 m/s where the vehicle stood and
/// barely changes over the log. The shipped speeds written in the column run as before.
#[test]
fn kingston_an_8th_column_flat_near_the_turns_speed_is_named_by_its_stand() {
    let tmp = tempfile::tempdir().unwrap();
    let run = tmp.path().join("flat");
    kingston_column(&run, |_: f64, _: f64| 5.0);
    let err = crate::util::stage_fails("derive", &run, &tmp.path().join("flat-o"));
    assert!(
        err.contains(
            "the log's 8th column (the odometer's speed) reads 5.00 m/s, steady (σ 0.000 m/s), \
             over the first 250 s of the static start given (static_s = 500 s), where the \
             vehicle stood, and barely changes over the whole log (σ 0.00 m/s"
        ) && err.contains("it is not the vehicle's speed. Name the odometer's file"),
        "{err}"
    );
    let run = tmp.path().join("speeds");
    kingston_column(&run, |_: f64, v: f64| v);
    crate::util::run_until(&run, &tmp.path().join("speeds-o"), "derive");
}

/// Kingston's IMU log and control points in GPS seconds since the weeks' start (6
/// January 1980: 1480 weeks on), its speed file in seconds of week: the derive names the
/// 1480 weeks and the seconds to add; written into the file, the run is the one on its
/// own clock (its worst control point within 1 cm). A control point left in seconds of
/// week is named the same weeks. And the IMU log with its lines in reverse order of time
/// fails on its time base, named so, not on the odometer's overlap. Before, the weeks
/// were "another day's, a time zone's, or counted from another start?", and the reversed
/// log's failure blamed the odometer's clock.
#[test]
fn kingston_clocks_counted_from_the_gps_weeks_start_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let weeks_s = 1480.0 * unz_formats::kfgins::GPS_WEEK_S;
    let since_1980 = kingston_retimed(&tmp.path().join("k"), |t| t + weeks_s);
    let rows: String = (kingston_speeds().into_iter())
        .map(|(t, v)| format!("{t:.3} {v:.5}\n"))
        .collect();
    std::fs::write(since_1980.join("odometer.txt"), rows).unwrap();
    let err = crate::util::stage_fails("derive", &since_1980, &tmp.path().join("k-o"));
    assert!(
        err.contains("its time tags run 1480 GPS weeks before the IMU's")
            && err.contains("add 895104000 s to each of its time tags"),
        "{err}"
    );
    let mended = kingston_retimed(&tmp.path().join("mended"), |t| t + weeks_s);
    let out = tmp.path().join("mended-o");
    crate::util::run_until(&mended, &out, "disupt");
    assert_same_worst_point(&out, &own_clock_reference(tmp.path()));
    // A control point left in seconds of week.
    let manifest = std::fs::read_to_string(mended.join("run.toml")).unwrap();
    let at = format!("t_s = {:?}", 152_825.0 + weeks_s);
    assert!(manifest.contains(&at), "{manifest}");
    std::fs::write(
        mended.join("run.toml"),
        manifest.replace(&at, "t_s = 152825.0"),
    )
    .unwrap();
    let err = crate::util::stage_fails("navigate", &mended, &tmp.path().join("cp-o"));
    assert!(
        err.contains("895104000 s later (1480 GPS weeks on) it would lie within it"),
        "{err}"
    );
    let reversed = kingston_with(&tmp.path().join("rev"), "");
    let imu = std::fs::read_to_string(reversed.join("imu.txt")).unwrap();
    let lines: Vec<&str> = imu.lines().rev().collect();
    std::fs::write(reversed.join("imu.txt"), lines.join("\n") + "\n").unwrap();
    let err = crate::util::stage_fails("derive", &reversed, &tmp.path().join("rev-o"));
    assert!(
        err.contains("8759 of 8760 IMU time tags do not increase")
            && err.contains(
                "its tags fall from t_s = 153018.99 to 152143.09: its lines in reverse order \
                 of time?"
            ),
        "{err}"
    );
}

/// Kingston's speed file in Unix time (UTC seconds since 1970: 19 May 2008), its IMU
/// log in GPS seconds of week (week 1480): the derive names both clocks and the seconds
/// to add, the 14 leap seconds GPS time then ran ahead of UTC counted in; added to each
/// of the file's tags, the run is the one on its own clock (its worst control point
/// within 1 cm), where the shift to the hour would leave the odometer 14 s early. The IMU
/// log and its control points in Unix time beside the speed file in seconds of week name
/// the same seconds the other way, and a control point left in Unix time in the log of
/// seconds of week is named with its time on the log's clock. Before, the file was "not
/// the IMU's clock (another day's, a time zone's, or counted from another start?)", and
/// the point was named no clock.
#[test]
fn kingston_unix_time_against_gps_seconds_of_week_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    // 3657 days and 1480 weeks, less 14 leap seconds.
    let unix_ahead_s = 1_211_068_786.0;
    let unix = kingston_odometer_edited(&tmp.path().join("unix"), |t, v| (t + unix_ahead_s, v));
    let err = crate::util::stage_fails("derive", &unix, &tmp.path().join("unix-o"));
    assert!(
        err.contains(
            "its time tags are Unix time (UTC seconds since 1 January 1970; 19 May 2008) and \
             the IMU's GPS seconds of week (week 1480): add -1211068786 s to each of its time \
             tags (the 3657 days from 1 January 1970 to 6 January 1980 and 1480 GPS weeks, \
             less the 14 leap seconds GPS time then ran ahead of UTC)"
        ),
        "{err}"
    );
    // The seconds named added to each of the file's tags, as written.
    let shift_s = crate::util::number_after(&err, ": add ");
    let rows: String = (std::fs::read_to_string(unix.join("odometer.txt"))
        .unwrap()
        .lines())
    .map(|l| {
        let (t, v) = l.split_once(' ').unwrap();
        format!("{:.3} {v}\n", t.parse::<f64>().unwrap() + shift_s)
    })
    .collect();
    std::fs::write(unix.join("odometer.txt"), rows).unwrap();
    let out = tmp.path().join("mended-o");
    crate::util::run_until(&unix, &out, "disupt");
    assert_same_worst_point(&out, &own_clock_reference(tmp.path()));
    // The IMU log and its control points in Unix time, the speed file in seconds of week.
    let imu_unix = kingston_retimed(&tmp.path().join("imu-unix"), |t| t + unix_ahead_s);
    std::fs::copy(
        test_data("kingston2008-seg1").join("odometer.txt"),
        imu_unix.join("odometer.txt"),
    )
    .unwrap();
    let err = crate::util::stage_fails("derive", &imu_unix, &tmp.path().join("imu-unix-o"));
    assert!(
        err.contains(
            "the IMU log's time tags are Unix time (UTC seconds since 1 January 1970; 19 May \
             2008) and its GPS seconds of week (week 1480): add 1211068786 s to each of its \
             time tags"
        ),
        "{err}"
    );
    // A control point in Unix time, the log in seconds of week.
    let point = kingston_with(&tmp.path().join("point"), "");
    let manifest = std::fs::read_to_string(point.join("run.toml")).unwrap();
    assert!(manifest.contains("t_s = 152825.0"), "{manifest}");
    let moved = manifest.replace("t_s = 152825.0", "t_s = 1211221611.0");
    std::fs::write(point.join("run.toml"), moved).unwrap();
    let err = crate::util::stage_fails("navigate", &point, &tmp.path().join("point-o"));
    assert!(
        err.contains(
            "its t_s is Unix time (UTC seconds since 1 January 1970; 19 May 2008) and the \
             log's GPS seconds of week (week 1480); moved by -1211068786 s ("
        ) && err.contains("it would lie within it, at t_s = 152825.00"),
        "{err}"
    );
}

/// A control point's or the site's coordinates written another way than decimal
/// degrees, as field sheets and GIS exports write them: the run fails on the point (no
/// setting reaches it, as before), and the failure names the reading that brings it
/// within the odometer's reach: the point's latitude and longitude swapped, its west
/// longitude written positive, its coordinates in degrees and minutes; the site's in
/// radians or its longitude positive (every point out of reach: the site is named, not
/// the first point). A point merely 8 km off is named no reading. Before, each said only
/// "its coordinates, its mark's point id or the site are wrong".
#[test]
fn kingston_coordinates_written_another_way_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let point = "latitude_deg = 44.236711682\nlongitude_deg = -76.465835437";
    let site = "latitude_deg = 44.232490740\nlongitude_deg = -76.466492006";
    let cases = [
        (
            point,
            "latitude_deg = -76.465835437\nlongitude_deg = 44.236711682",
            "its latitude and longitude swapped? (read so, it lies 472 m from the start)",
        ),
        (
            point,
            "latitude_deg = 44.236711682\nlongitude_deg = 76.465835437",
            "its longitude's sign reversed (west is negative)?",
        ),
        (
            point,
            "latitude_deg = 44.142016\nlongitude_deg = -76.279501",
            "its coordinates in degrees and minutes (DD.MMmm), not decimal degrees?",
        ),
        (
            site,
            "latitude_deg = 0.771994\nlongitude_deg = -1.334580",
            "the site's coordinates in radians, not degrees?",
        ),
        (
            site,
            "latitude_deg = 44.232490740\nlongitude_deg = 76.466492006",
            "the site's longitude's sign reversed (west is negative)?",
        ),
    ];
    for (k, (from, to, named)) in cases.into_iter().enumerate() {
        let run = kingston_edited(&tmp.path().join(format!("k{k}")), from, to);
        let err = crate::util::stage_fails("navigate", &run, &tmp.path().join(format!("o{k}")));
        assert!(
            err.contains("control point 1 is ") && err.contains(&format!("are wrong: {named}")),
            "{named}: {err}"
        );
    }
    let far = "latitude_deg = 44.236711682\nlongitude_deg = -76.565835437";
    let run = kingston_edited(&tmp.path().join("far"), point, far);
    let err = crate::util::stage_fails("navigate", &run, &tmp.path().join("far-o"));
    assert!(err.trim_end().ends_with("the site are wrong"), "{err}");
}

/// The joint fit's worst horizontal hold-out error in `out`'s Kingston run, m.
fn joint_worst_holdout_m(out: &std::path::Path) -> f64 {
    let d: unz::disupt_stage::DisuptOut =
        read_json(&out.join("kingston2008-segment1/disupt/disupt.json"));
    let holdout = d.methods["joint"].holdout.as_ref().expect("hold-outs");
    unz_stages::disupt::holdout_median_max_m(holdout)
        .expect("hold-out errors")
        .1
}

/// Kingston's IMU log with its time tags in milliseconds (its 10-Hz samples step by 100),
/// beside its speed file in seconds, and with both in milliseconds. The first is now
/// failed by the odometer's overlap with the log, which names the IMU's tags; the second
/// (the two files together, as an 8th column is) by the IMU's sample interval, which now
/// says what its step would be in seconds.
#[test]
fn kingston_imu_time_tags_in_milliseconds_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let imu_in_ms = |run: &std::path::Path| {
        let imu = std::fs::read_to_string(run.join("imu.txt")).unwrap();
        let in_ms: String = imu
            .lines()
            .map(|l| {
                let (t, rest) = l.split_once(' ').unwrap();
                let t_ms = (t.parse::<f64>().unwrap() * 1000.0).round();
                format!("{t_ms} {rest}\n")
            })
            .collect();
        std::fs::write(run.join("imu.txt"), in_ms).unwrap();
    };
    let run = kingston_with(&tmp.path().join("imu"), "");
    imu_in_ms(&run);
    let err = crate::util::stage_fails("derive", &run, &tmp.path().join("imu-o"));
    assert!(
        err.contains("has 0 of its 877 rows within the IMU log")
            && err.contains(
                "the IMU log's time tags read in milliseconds would run t_s = 152143.09 to \
                 153018.99: write them in seconds"
            ),
        "{err}"
    );
    let both = kingston_odometer_edited(&tmp.path().join("both"), |t, v| (t * 1000.0, v));
    imu_in_ms(&both);
    let err = crate::util::stage_fails("derive", &both, &tmp.path().join("both-o"));
    assert!(
        err.contains("is 100.000 s, longer than derive.max_gap_s")
            && err.contains("(time tags in milliseconds? 0.1 s then"),
        "{err}"
    );
}

/// Kingston with its site at its second control point's coordinates, 1.1 km from where
/// it starts (a manifest's site copied from the run's end). Before, the run was "ok" with
/// the joint fit refused, blamed on "a control point's coordinates or mark, the
/// odometer's scale, or a setting given", and OEPI's route 1134 m off. Now `navigate.json`
/// (`site_apart`) and the campaign's note give the shift every point's error shares,
/// which is the site's error (the site given less the true one: −237 m north, −1120 m
/// east), and the refusal names the site among the suspects.
#[test]
fn kingston_a_site_off_is_named_by_the_shift_of_every_point() {
    let tmp = tempfile::tempdir().unwrap();
    let run = kingston_edited(
        &tmp.path().join("k"),
        "latitude_deg = 44.232490740",
        "latitude_deg = 44.230360898",
    );
    let manifest = std::fs::read_to_string(run.join("run.toml")).unwrap();
    let manifest = manifest.replacen(
        "longitude_deg = -76.466492006",
        "longitude_deg = -76.480514264",
        1,
    );
    std::fs::write(run.join("run.toml"), manifest).unwrap();
    let out = tmp.path().join("o");
    crate::util::run_until(&run, &out, "disupt");
    let nav = navigate_summary(&out);
    let apart = nav.site_apart.unwrap();
    // The site given less the true one: (44.230360898 − 44.232490740)° north is −236.7 m,
    // (−76.480514264 + 76.466492006)° east −1120.3 m (WGS-84); the errors' own spread
    // (the initial azimuth's and the drifts' share, 10 m on Kingston as surveyed) moves
    // their mean.
    assert!((apart.north_m + 236.7).abs() < 10.0, "{apart:?}");
    assert!((apart.east_m + 1120.3).abs() < 10.0, "{apart:?}");
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert!(
        summary.contains(
            "every control point's error before DISUPT is about -237 m north and -1113 m east"
        ) && summary.contains("the site (the run's start), the odometer's scale"),
        "{summary}"
    );
    let nav = shipped_navigated(&tmp.path().join("shipped"));
    assert_eq!(nav.site_apart, None);
}

/// Kingston with its gyro drift x given as 0.001 rad/s (206 °/h: a typo, or °/h written
/// as rad/s): the joint fit takes it back to 0.0 °/h, beyond its ±5 °/h bound, and is
/// refused; the reason the campaign's note gives blames the drift given, not the run.
#[test]
fn kingston_a_drift_given_far_off_is_blamed() {
    let tmp = tempfile::tempdir().unwrap();
    let drift = toml::Value::Array(vec![1e-3.into(), 0.0.into(), 0.0.into()]);
    let run = kingston_with_initial(&tmp.path().join("k"), "drift_rad_s", drift);
    let out = tmp.path().join("o");
    crate::util::run_until(&run, &out, "disupt");
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert!(
        summary.contains("drift x moved -206.3 °/h, bound ±5 °/h, from +206.3 °/h given to")
            && summary.contains("the drift given ([initial] drift_rad_s, in rad/s) is off"),
        "{summary}"
    );
}

/// Kingston with a pitch of 5° given beside its 500-s static start, whose accelerometers
/// level the car at −0.34°: `navigate.json` (`initial.level_apart`), the run's log and the
/// campaign's note say that the pitch given is 5.34° from the levelling (the joint fit,
/// which takes ±50 mrad of levelling, is refused). A roll and pitch given within 0.1° of
/// the levelling say nothing.
#[test]
fn kingston_a_tilt_given_far_from_the_levelling_is_said() {
    use unz::flow::NavigateSummary;

    let tmp = tempfile::tempdir().unwrap();
    for (k, (tilt, apart)) in [
        ("pitch_deg = 5.0", true),
        ("roll_deg = -0.3\npitch_deg = -0.3", false),
    ]
    .into_iter()
    .enumerate()
    {
        let with = format!("static_s = 500.0\n{tilt}");
        let run = kingston_edited(&tmp.path().join(format!("k{k}")), "static_s = 500.0", &with);
        let out = tmp.path().join(format!("o{k}"));
        let o = unz_run(&run, &out);
        assert!(o.status.success());
        let dir = out.join("kingston2008-segment1");
        let nav: NavigateSummary = read_json(&dir.join("navigate/navigate.json"));
        let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
        let log = String::from_utf8_lossy(&o.stderr);
        match nav.initial.level_apart {
            Some(a) => {
                assert!(apart, "{tilt}: {a:?}");
                assert!((a.given_deg[1] - 5.0).abs() < 1e-9 && (a.apart_deg() - 5.34).abs() < 0.05);
                assert!(
                    summary.contains(&a.said()) && log.contains(&a.said()),
                    "{summary}"
                );
            }
            None => {
                assert!(!apart, "{tilt}");
                assert!(!summary.contains("the roll and pitch given"), "{summary}");
            }
        }
    }
}

/// The shipped Kingston run's OBD-II speeds: time, s, and speed, m/s.
fn kingston_speeds() -> Vec<(f64, f64)> {
    std::fs::read_to_string(test_data("kingston2008-seg1").join("odometer.txt"))
        .unwrap()
        .lines()
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            (v[0], v[1])
        })
        .collect()
}

/// The shipped Kingston run copied into `tmp`/shipped and run up to its disupt stage into
/// `tmp`/shipped-o, returned.
fn kingston_shipped_disupt(tmp: &std::path::Path) -> std::path::PathBuf {
    let out = tmp.join("shipped-o");
    crate::util::run_until(&kingston_with(&tmp.join("shipped"), ""), &out, "disupt");
    out
}

/// The shipped Kingston run copied into `run` (created), `extra` added to its manifest.
fn kingston_with(run: &std::path::Path, extra: &str) -> std::path::PathBuf {
    std::fs::create_dir_all(run).unwrap();
    for f in ["imu.txt", "odometer.txt", "run.toml"] {
        std::fs::copy(test_data("kingston2008-seg1").join(f), run.join(f)).unwrap();
    }
    let manifest = std::fs::read_to_string(run.join("run.toml")).unwrap() + "\n" + extra;
    std::fs::write(run.join("run.toml"), manifest).unwrap();
    run.to_path_buf()
}

/// The Kingston run's `navigate.json` in the output folder `out`.
fn navigate_summary(out: &std::path::Path) -> unz::flow::NavigateSummary {
    read_json(&out.join("kingston2008-segment1/navigate/navigate.json"))
}

/// The shipped Kingston run copied into `dir/k` and navigated into `dir/o`: its
/// `navigate.json`.
fn shipped_navigated(dir: &std::path::Path) -> unz::flow::NavigateSummary {
    let out = dir.join("o");
    crate::util::run_until(&kingston_with(&dir.join("k"), ""), &out, "navigate");
    navigate_summary(&out)
}

/// `unz run RUN --out OUT`: every stage, the campaign's summary beside.
fn unz_run(run: &std::path::Path, out: &std::path::Path) -> std::process::Output {
    crate::util::unz_output(&["run", run.to_str().unwrap(), "--out", out.to_str().unwrap()])
}

/// The shipped Kingston run copied into `run` (created), `from` in its manifest (which
/// must hold it) replaced once by `to`.
fn kingston_edited(run: &std::path::Path, from: &str, to: &str) -> std::path::PathBuf {
    let run = kingston_with(run, "");
    let manifest = std::fs::read_to_string(run.join("run.toml")).unwrap();
    assert!(manifest.contains(from), "{from}");
    std::fs::write(run.join("run.toml"), manifest.replacen(from, to, 1)).unwrap();
    run
}

/// The shipped Kingston run copied into `run` (created), its manifest's `[initial] key`
/// set to `value`.
fn kingston_with_initial(
    run: &std::path::Path,
    key: &str,
    value: toml::Value,
) -> std::path::PathBuf {
    let run = kingston_with(run, "");
    let path = run.join("run.toml");
    let mut m: toml::Table = toml::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    m["initial"]
        .as_table_mut()
        .unwrap()
        .insert(key.into(), value);
    std::fs::write(&path, toml::to_string(&m).unwrap()).unwrap();
    run
}

/// Kingston with `extra` added to its manifest ([`kingston_with`] in `dir/k`), run to
/// disupt into `dir/o`: its report and its disupt folder.
fn kingston_disupt(
    dir: &std::path::Path,
    extra: &str,
) -> (unz::disupt_stage::DisuptOut, std::path::PathBuf) {
    let run = kingston_with(&dir.join("k"), extra);
    let out = dir.join("o");
    crate::util::run_until(&run, &out, "disupt");
    let disupt = out.join("kingston2008-segment1/disupt");
    (read_json(&disupt.join("disupt.json")), disupt)
}

/// What each odometer term of the joint fit buys on the real drive, end to end through
/// `unz run`: the OBD-II speed's lag and bias (the README's Kingston table). The figures
/// are the route's heading against the settled reference, the errors at the control
/// points, and each control point's error when it was left out of the fit.
#[test]
fn kingston_odometer_terms_through_the_binary() {
    let r = reference();
    let tmp = tempfile::tempdir().unwrap();
    let mut rows = Vec::new();
    for (lag, bias) in [(false, false), (true, false), (false, true), (true, true)] {
        let (d, dir) = kingston_disupt(
            &tmp.path().join(format!("{lag}-{bias}")),
            &format!("[params.disupt]\njoint_odo_lag = {lag}\njoint_odo_bias = {bias}\n"),
        );
        let j = &d.methods["joint"];
        // OWPI's vertical drift by Kryt1 runs into its ±5 °/h and is said to (README).
        let owpi_driftz = d.methods["owpi"]
            .steps
            .iter()
            .find(|st| st.component == unz_stages::disupt::Component::DriftZ)
            .unwrap();
        assert_eq!(
            owpi_driftz.at_bound,
            [unz_stages::linearized::Setting::DriftZ]
        );
        assert!(
            d.methods["oepi"]
                .steps
                .iter()
                .all(|st| st.at_bound.is_empty())
        );
        let heading_err = corrected_heading_error_deg(&dir, &r);
        let cp_max = worst_control_point_m(j);
        let holdout = j.holdout.as_ref().unwrap();
        let holdout_max = holdout
            .iter()
            .map(|h| h.dx_m.hypot(h.dy_m))
            .fold(0.0, f64::max);
        eprintln!(
            "Kingston joint, lag {lag}, bias {bias}: heading {heading_err:.3}°, control points ≤ {cp_max:.2} m, hold-out ≤ {holdout_max:.2} m; lag {:.3} ± {:.3} s, bias {:.3} ± {:.3} m/s, scale {:+.0} ppm",
            j.outcome.x.odo_lag_s,
            j.outcome.x.sigma.as_ref().unwrap().odo_lag_s,
            j.outcome.x.odo_bias_mps,
            j.outcome.x.sigma.as_ref().unwrap().odo_bias_mps,
            (j.outcome.x.odo_scale / d.before.x.odo_scale - 1.0) * 1e6
        );
        rows.push((heading_err, cp_max, holdout_max, j.outcome.x.odo_bias_mps));
        if lag {
            // The derive's reading of the clock, from the accelerations alone (−0.40 s),
            // agrees with the joint fit's lag from the route (−0.58 ± 0.17 s).
            let nav: unz::flow::NavigateSummary = read_json(&dir.join("../navigate/navigate.json"));
            let clock = nav.odometer_clock.expect("the odometer's clock read");
            let (fit, sigma) = (
                j.outcome.x.odo_lag_s,
                j.outcome.x.sigma.as_ref().unwrap().odo_lag_s,
            );
            assert!(
                clock.shown && (clock.fit.lag_s - fit).abs() < 2.0 * sigma,
                "{clock:?}; the joint fit's lag {fit} ± {sigma} s"
            );
        }
    }
    let [plain, _, _, both] = [rows[0], rows[1], rows[2], rows[3]];
    // The README's figure: the OBD-II speed reads about 0.08 m/s low (its σ here ~0.015).
    assert!(both.3 > 0.03 && both.3 < 0.15, "bias {} m/s", both.3);
    // With lag and bias, every figure improves on the plain joint fit, and the route
    // between the stops is then within the reference's few metres.
    assert!(
        both.0 < plain.0 && both.0 < 0.45,
        "heading {both:?} vs {plain:?}"
    );
    assert!(
        both.1 < plain.1 && both.1 < 2.0,
        "control points {both:?} vs {plain:?}"
    );
    assert!(
        both.2 < plain.2 && both.2 < 4.0,
        "hold-out {both:?} vs {plain:?}"
    );
}

/// The IMU's watch of a standing odometer count ([`unz::standing_motion`]) on a real
/// vehicle's vibration: from each of the segment's three stops (the 527-s static start,
/// 30 s and 15 s in traffic, the engine running) the count is taken to stand as the car
/// drives on, as a sensor that fails at a stop would. At rest it never calls motion (572 s
/// of it; the segment ends at its last stop); once the car drives off (the reference's
/// speed), it does within a few seconds, after the car has moved about its metre
/// (measured: 4.0 s and 1.66 m from the static start, 3.0 s and 1.17 m from the 30-s
/// stop).
#[test]
fn kingston_the_imu_watch_of_a_standing_count_on_real_vibration() {
    use unz::standing_motion::{MOVED_M, Motion, StandingMotion};
    use unz_formats::kfgins::KfGinsReader;

    let dir = test_data("kingston2008-seg1");
    let mut reader = KfGinsReader::new(std::io::BufReader::new(
        std::fs::File::open(dir.join("imu.txt")).unwrap(),
    ));
    let period_s = reader.period_s().unwrap().unwrap();
    let mut imu = Vec::new();
    while let Some(s) = reader.next_sample().unwrap() {
        imu.push(s);
    }
    let r = reference();
    let stops: Vec<[f64; 2]> = std::fs::read_to_string(dir.join("stops.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            [v[0], v[1]]
        })
        .collect();
    assert_eq!(stops.len(), 3);
    let [lat_deg, _, h_m] = r.position[0];
    let g = unz_stages::earth::normal_gravity_mps2(lat_deg.to_radians(), h_m);
    // The reference's distance from its epoch at `t0_s` to `t_s` (speed at 1 Hz,
    // trapezoids).
    let distance_m = |t0_s: f64, t_s: f64| -> f64 {
        r.t_s
            .windows(2)
            .zip(r.speed.windows(2))
            .map(|(t, v)| {
                let (a, b) = (t[0].max(t0_s), t[1].min(t_s));
                if b <= a {
                    return 0.0;
                }
                let at = |x: f64| v[0] + (v[1] - v[0]) * (x - t[0]) / (t[1] - t[0]);
                0.5 * (at(a) + at(b)) * (b - a)
            })
            .sum()
    };
    for [start_s, end_s] in stops {
        // The car drives off after the reference's last epoch below 0.05 m/s.
        let off_s = r
            .t_s
            .iter()
            .zip(&r.speed)
            .filter(|(t, v)| (start_s..=end_s + 5.0).contains(*t) && **v < 0.05)
            .map(|(t, _)| *t)
            .fold(f64::NAN, f64::max);
        let mut watch = StandingMotion::new(g, period_s);
        let found_s = imu.iter().filter(|s| s.t_s > start_s + 1.0).find_map(|s| {
            matches!(
                watch.push(s.t_s, s.dvel_mps, s.dtheta_rad),
                Motion::Moving { .. }
            )
            .then_some(s.t_s)
        });
        let last_s = imu.last().unwrap().t_s;
        if off_s >= last_s - 1.0 {
            // The segment ends standing at its last stop.
            eprintln!("stop {start_s}–{end_s} s: the log ends at rest, no motion called");
            assert_eq!(found_s, None, "motion called at rest");
            continue;
        }
        let found_s = found_s.expect("the car drives off");
        let moved_m = distance_m(off_s, found_s);
        eprintln!(
            "stop {start_s}–{end_s} s: drove off at {off_s} s, motion found {:.1} s later, \
             {moved_m:.2} m on",
            found_s - off_s
        );
        assert!(
            found_s > off_s,
            "motion called at rest: {found_s} s, off at {off_s} s"
        );
        // Judged every 2 s at 10 Hz (two blocks of ten samples).
        assert!(found_s - off_s < 6.0, "found {found_s} s, off at {off_s} s");
        assert!(moved_m > 0.5 * MOVED_M, "{moved_m} m");
    }
}

/// A gap in the OBD-II speed file (40 s of it removed while the car drives, an OBD
/// logger's dropout): its distance was the trapezoid of the speeds at its ends, 39 m off
/// at the control points, unreported. Now the gap is found, bridged by the inertial
/// along-track speed (its distance within 1 % of the file's own over it: 285.8 m against
/// 288.3 m), its rows written at the IMU's samples as bridged, reported in `ingest.json`
/// and the campaign's note, shown on the review's speed plot; the joint's control points
/// are as good as with the file intact (measured 0.6 m; intact 1.0 m).
#[test]
fn kingston_a_gap_in_the_odometer_file_is_bridged() {
    use unz_formats::IngestReport;

    let tmp = tempfile::tempdir().unwrap();
    let run = tmp.path().join("c/kingston");
    std::fs::create_dir_all(&run).unwrap();
    let data = test_data("kingston2008-seg1");
    for f in ["imu.txt", "run.toml"] {
        std::fs::copy(data.join(f), run.join(f)).unwrap();
    }
    let (from_s, to_s) = (152_760.0, 152_800.0);
    let odometer = std::fs::read_to_string(data.join("odometer.txt")).unwrap();
    let t_of = |l: &str| -> f64 { l.split_whitespace().next().unwrap().parse().unwrap() };
    let kept: Vec<&str> = odometer
        .lines()
        .filter(|l| !(from_s < t_of(l) && t_of(l) < to_s))
        .collect();
    std::fs::write(run.join("odometer.txt"), kept.join("\n") + "\n").unwrap();
    // The file's own distance over the gap: the trapezoid of its speeds.
    let speeds: Vec<(f64, f64)> = odometer
        .lines()
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            (v[0], v[1])
        })
        .filter(|(t, _)| (from_s..=to_s).contains(t))
        .collect();
    let intact_m: f64 = speeds
        .windows(2)
        .map(|w| 0.5 * (w[0].1 + w[1].1) * (w[1].0 - w[0].0))
        .sum();

    let out = tmp.path().join("o");
    crate::util::run_until(&run, &out, "review");
    let dir = out.join("kingston2008-segment1");
    let report: IngestReport = read_json(&dir.join("ingest/ingest.json"));
    let f = report.odometer_failures.expect("the gap reported");
    eprintln!(
        "gap {from_s}–{to_s} s: bridged {:.1} m, the file's own {intact_m:.1} m; {f:?}",
        f.bridged_distance_m
    );
    assert_eq!((f.file_gaps, f.bridged, f.not_bridged), (1, 1, 0), "{f:?}");
    assert_eq!(
        f.bridged_samples, 400,
        "the IMU's samples inside the 40-s gap at 10 Hz (tagged at .09 s)"
    );
    assert_eq!(f.longest_bridged_s, to_s - from_s);
    assert!(
        (f.bridged_distance_m - intact_m).abs() < 0.01 * intact_m,
        "{} m against {intact_m} m",
        f.bridged_distance_m
    );
    // The bridged rows: the IMU's samples inside the gap, between the readings.
    let (_, batches) =
        unz_formats::parquet_io::read_batches(&dir.join("ingest/odometer.parquet")).unwrap();
    let mut rows: Vec<(i64, u8)> = Vec::new();
    for b in &batches {
        let t = unz_formats::tables::i64_column(b, "t_ns").unwrap();
        let s = unz_formats::tables::u8_column(b, "distance_source").unwrap();
        rows.extend(t.into_iter().zip(s));
    }
    let bridged: Vec<i64> = rows.iter().filter(|r| r.1 == 1).map(|r| r.0).collect();
    assert_eq!(bridged.len(), 400);
    assert!(
        bridged
            .iter()
            .all(|&t| from_s < t as f64 * 1e-9 && (t as f64) * 1e-9 < to_s)
    );
    assert!(
        rows.windows(2).all(|w| w[0].0 < w[1].0),
        "rows in time order"
    );
    // The joint's control points as with the file intact.
    let d: unz::disupt_stage::DisuptOut = read_json(&dir.join("disupt/disupt.json"));
    let worst = worst_control_point_m(&d.methods["joint"]);
    eprintln!("joint's worst control point {worst:.2} m");
    assert!(worst < 2.0, "{worst} m");
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert!(
        summary.contains("the odometer file has no readings over 1 gap longer than 3 s")
            && summary.contains("bridged by the inertial along-track speed: 1 failure (40.0 s"),
        "{summary}"
    );
    // The review's speed plot marks the gap's blocks (one sample each at 10 Hz).
    let Some(py) = crate::util::python() else {
        return;
    };
    let rrd = dir.join("review/kingston2008-segment1.rrd");
    let info = crate::util::python_json(&py, "check_rrd.py", &[&rrd]);
    let blocks = info["temporal_rows"]["/plots/speed/bridged"]
        .as_i64()
        .unwrap();
    assert_eq!(blocks, 400, "{blocks} blocks bridged");
}

/// An OBD-II logger that writes zero, not nothing, when it loses the speed: the file's
/// distance stands while the car drives, and nothing flags it. Before, the route stopped
/// there: the joint's control points 190 and 45 m off (speeds zero for 19 s at 11 m/s),
/// and 12.6 and 5.5 m (the speed zero from the stop at control point 1 through the
/// drive-off, 14 s), the odometer scale taking 3.7 %. Now each stand of the file's speed
/// is judged by the IMU (`odometer_gaps::stand_failed`): braking into it from the
/// speed before it, and the watch of a standing count in it. Found, it is bridged by the
/// inertial along-track speed (195 m, and 87.3 m against the file's own 87.4 m), said as
/// an odometer that stood while the vehicle moved, and the control points are as with
/// the file intact (measured 0.77 and 0.29 m, 0.73 and 0.25 m; intact 0.97 and 0.38 m).
/// The file's real stops (15 and 30 s, and the 527-s static start's last two minutes) are
/// judged stops: nothing reported, the intact run's outputs unchanged.
#[test]
fn kingston_a_speed_stuck_at_zero_is_found_and_bridged() {
    use unz_formats::IngestReport;

    let tmp = tempfile::tempdir().unwrap();
    let speeds = kingston_speeds();
    // The file's own distance over [from, to], s: the trapezoid of its speeds.
    let own_m = |from: f64, to: f64| -> f64 {
        speeds
            .windows(2)
            .filter(|w| from <= w[0].0 && w[1].0 <= to)
            .map(|w| 0.5 * (w[0].1 + w[1].1) * (w[1].0 - w[0].0))
            .sum()
    };
    // The run with the speeds over `zeroed` (s) written as zero.
    let with_zeros = |name: &str, zeroed: std::ops::Range<f64>| {
        let run = kingston_with(&tmp.path().join(name).join("kingston"), "");
        let text: String = speeds
            .iter()
            .map(|&(t, v)| format!("{t} {:.5}\n", if zeroed.contains(&t) { 0.0 } else { v }))
            .collect();
        std::fs::write(run.join("odometer.txt"), text).unwrap();
        let out = tmp.path().join(name).join("o");
        crate::util::run_until(&run, &out, "disupt");
        let dir = out.join("kingston2008-segment1");
        let report: IngestReport = read_json(&dir.join("ingest/ingest.json"));
        let d: unz::disupt_stage::DisuptOut = read_json(&dir.join("disupt/disupt.json"));
        (
            report.odometer_failures,
            worst_control_point_m(&d.methods["joint"]),
            out,
        )
    };
    let (none, worst_intact, _) = with_zeros("intact", 0.0..0.0);
    assert_eq!(none, None, "the real stops are stops");

    // A stand found moving and bridged over [from, to] (s): one failure, its distance
    // the file's own there (intact), the control points as intact.
    let found = |name: &str, zeroed: std::ops::Range<f64>, from: f64, to: f64| {
        let (f, worst, out) = with_zeros(name, zeroed);
        let f = one_stand_as_its_own(name, f, worst, worst_intact, |_| own_m(from, to));
        assert_eq!(f.longest_bridged_s, to - from, "{f:?}");
        out
    };
    // Zero while driving at 11 m/s: the braking into the stand is not the IMU's.
    let out = found("driving", 152_761.0..152_780.0, 152_760.0, 152_780.0);
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert!(
        summary
            .contains("the odometer's distance stood while the vehicle moved, unflagged: 1 time"),
        "{summary}"
    );
    // Zero from the stop at control point 1 through the drive-off: the watch, from its
    // start (the car still at rest).
    found("drive-off", 152_842.0..152_856.0, 152_839.0, 152_856.0);
    // Zero from two seconds after the drive-off, the car at 2 m/s: the watch finds it,
    // its reference the car pulling away, so from the stand's start (the last reading
    // before it). From the watch's start, the bridge began at rest and gave 60.7 m of
    // 85.9, the points 4.7 and 1.9 m.
    found("pulling away", 152_844.0..152_856.0, 152_843.0, 152_856.0);

    // A stand (zeros over `zeroed`, s) found moving: `counts` stretches (stuck,
    // bridged), bridged as far as the file's own distance from `from` (s, the last
    // reading before the zeros) to the zeros' end, within 10 %.
    let stood = |name: &str, zeroed: std::ops::Range<f64>, counts: (u64, u64), from: f64| {
        let to = zeroed.end;
        let (f, worst, out) = with_zeros(name, zeroed);
        let f = f.expect("the stand reported");
        eprintln!("{name}: {f:?}; worst control point {worst:.2} m");
        assert_eq!((f.stuck, f.bridged), counts, "{f:?}");
        let truth_m = own_m(from, to);
        assert!(
            (f.bridged_distance_m - truth_m).abs() < 0.1 * truth_m,
            "{} m against {truth_m} m",
            f.bridged_distance_m
        );
        (f, worst, out)
    };
    // Zero from 17 s before the stop at control point 2 to the file's end, two seconds
    // after the stop (its last reading a creep): found by the braking. Bridged to the
    // file's end, from one side only over 36 s, the fit ran the route 1.7 km backwards;
    // the joint was refused and OWPI's route taken, 1.1 km off (such a bridge is now
    // refused). The IMU's watch backwards from the stand's end finds where the car came
    // to rest, and the bridge ends there, its readings at rest after it.
    let (f, worst, _) = stood("to the end", 152_984.0..153_001.0, (1, 1), 152_983.0);
    assert!(f.longest_bridged_s < 25.0, "{f:?}");
    assert!(worst < worst_intact + 1.0, "{worst} m");
    // Zero from 2 s before the car stopped at control point 1 through its drive-off 33 s
    // later: two stretches, into the stop and out of it, the stop's readings kept (7.3 m
    // bridged of the file's own 7.5 m). As one, across the stop, the bridge gave −17 m,
    // and the points were 4.8 m off.
    let (_, worst, _) = stood(
        "into and out of a stop",
        152_807.0..152_844.0,
        (2, 2),
        152_806.0,
    );
    assert!(worst < worst_intact + 1.0, "{worst} m");

    // Zero from the 527-s static start through its drive-off (19 s): a stand too long to
    // bridge whole, judged over its last two minutes. Before, the joint was refused (its
    // odometer scale 10 % off) and OEPI's route taken, 56 and 60 m off at the control
    // points. Now found; the bridge from rest gives 51.7 m of the file's own 56.3 m (8 %
    // short, as the bridges of city corners lose 3–14 %), the points 5.9 and 2.4 m.
    let (_, worst, out) = stood("static start", 152_671.0..152_690.0, (1, 1), 152_670.0);
    let d: unz::disupt_stage::DisuptOut =
        read_json(&out.join("kingston2008-segment1/disupt/disupt.json"));
    assert_eq!(d.corrected_by.as_deref(), Some("joint"), "{:?}", d.skipped);
    assert!(worst < 8.0, "{worst} m");
}

/// Checks a run with one stand of its speeds found moving (`f`, its worst control point
/// `worst` m): bridged once, as far as the speeds' own distance (`own_m` of the
/// failures, m) within 2 %, the control points within a metre of the intact run's.
fn one_stand_as_its_own(
    name: &str,
    f: Option<unz_formats::OdometerFailures>,
    worst: f64,
    worst_intact: f64,
    own_m: impl Fn(&unz_formats::OdometerFailures) -> f64,
) -> unz_formats::OdometerFailures {
    let f = f.expect("the stand reported");
    eprintln!("{name}: {f:?}; worst control point {worst:.2} m");
    assert_eq!((f.stuck, f.bridged, f.file_gaps), (1, 1, 0), "{f:?}");
    let truth_m = own_m(&f);
    assert!(
        (f.bridged_distance_m - truth_m).abs() < 0.02 * truth_m,
        "{} m against {truth_m} m",
        f.bridged_distance_m
    );
    assert!(
        worst < worst_intact + 1.0,
        "{worst} m, intact {worst_intact} m"
    );
    f
}

/// The same faults in a text log's 8th column (the odometer's speed at each IMU sample),
/// which the ingest judges as it streams: Kingston with its 1-Hz speeds interpolated to
/// its 10-Hz IMU lines as an 8th column, the speed file left out of the manifest.
/// Before, zeros for 19 s at 11 m/s put the joint's control points 192 and 45 m off,
/// unreported; zeros from the stop at control point 1 through its drive-off, 15 and
/// 6.5 m.
#[test]
fn kingston_a_speed_column_stuck_at_zero_is_found_and_bridged() {
    use unz_formats::IngestReport;

    let tmp = tempfile::tempdir().unwrap();
    let data = test_data("kingston2008-seg1");
    let file = kingston_speeds();
    let speed = |t_s: f64| speed_at(&file, t_s);
    let imu = std::fs::read_to_string(data.join("imu.txt")).unwrap();
    let times: Vec<f64> = (imu.lines())
        .map(|l| l.split_whitespace().next().unwrap().parse().unwrap())
        .collect();
    // The column's own distance over [from, to], s: the trapezoid of its speeds.
    let own_m = |from: f64, to: f64| -> f64 {
        (times.windows(2))
            .filter(|w| from <= w[0] + 1e-6 && w[1] <= to + 1e-6)
            .map(|w| 0.5 * (speed(w[0]) + speed(w[1])) * (w[1] - w[0]))
            .sum()
    };
    // The run with the column zero over `zeroed` (s).
    let with_zeros = |name: &str, zeroed: std::ops::Range<f64>| {
        let run = tmp.path().join(name).join("kingston");
        kingston_column(&run, |t, v| if zeroed.contains(&t) { 0.0 } else { v });
        let out = tmp.path().join(name).join("o");
        crate::util::run_until(&run, &out, "disupt");
        let dir = out.join("kingston2008-segment1");
        let report: IngestReport = read_json(&dir.join("ingest/ingest.json"));
        let d: unz::disupt_stage::DisuptOut = read_json(&dir.join("disupt/disupt.json"));
        assert_eq!(d.corrected_by.as_deref(), Some("joint"), "{:?}", d.skipped);
        (
            report.odometer_failures,
            worst_control_point_m(&d.methods["joint"]),
        )
    };
    let (none, worst_intact) = with_zeros("intact", 0.0..0.0);
    assert_eq!(none, None, "the real stops are stops");
    assert!(worst_intact < 1.5, "{worst_intact} m");

    // A stand found moving and bridged up to `to` (s): one failure, its distance the
    // column's own there (intact) within 2 %, the control points as intact.
    let found = |name: &str, zeroed: std::ops::Range<f64>, to: f64| {
        let (f, worst) = with_zeros(name, zeroed);
        one_stand_as_its_own(name, f, worst, worst_intact, |f| {
            own_m(to - f.longest_bridged_s, to)
        })
    };
    // Zero while driving at 11 m/s: the braking into the stand is not the IMU's. The
    // failure is from the last line before the zeros to the first after them.
    let f = found("driving", 152_761.0..152_780.0, 152_780.09);
    assert!((f.longest_bridged_s - 19.1).abs() < 1e-6, "{f:?}");
    // Zero from the stop at control point 1 through the drive-off: the watch, from its
    // start (the car still at rest).
    found("drive-off", 152_838.0..152_856.0, 152_856.09);
    // Zero from a second after the drive-off, the car at 0.8 m/s: the watch finds it,
    // its reference the car pulling away, so from the stand's start. From the watch's
    // start, the bridge began at rest and gave 58.0 m of 79.8, the points 1.11 and
    // 0.44 m.
    found("pulling away", 152_842.0..152_856.0, 152_856.09);
}

/// Kingston in `run` (created) with its 1-Hz speeds interpolated to its 10-Hz IMU lines
/// as an 8th column, each written as `speed(t_s, v_mps)`; the speed file left out of the
/// manifest.
fn kingston_column(run: &std::path::Path, speed: impl Fn(f64, f64) -> f64) {
    let data = test_data("kingston2008-seg1");
    let file = kingston_speeds();
    std::fs::create_dir_all(run).unwrap();
    let imu = std::fs::read_to_string(data.join("imu.txt")).unwrap();
    let text: String = imu
        .lines()
        .map(|l| {
            let t: f64 = l.split_whitespace().next().unwrap().parse().unwrap();
            format!("{l} {:.5}\n", speed(t, speed_at(&file, t)))
        })
        .collect();
    std::fs::write(run.join("imu.txt"), text).unwrap();
    let manifest = std::fs::read_to_string(data.join("run.toml")).unwrap();
    let without_file = "[odometer]\nfile = \"odometer.txt\"\nkind = \"speed_mps\"\n";
    assert!(manifest.contains(without_file));
    std::fs::write(run.join("run.toml"), manifest.replace(without_file, "")).unwrap();
}

/// The speed file's speed at `t_s`, m/s, linearly between its readings.
fn speed_at(file: &[(f64, f64)], t_s: f64) -> f64 {
    let k = file
        .partition_point(|r| r.0 <= t_s)
        .clamp(1, file.len() - 1);
    let ((t0, v0), (t1, v1)) = (file[k - 1], file[k]);
    (v0 + (v1 - v0) * (t_s - t0) / (t1 - t0)).max(0.0)
}

/// Speeds that jump faster than a car can change its speed and come back (a bus error,
/// a logger's "invalid" 255 km/h, junk) are left out, in a speed file (1 Hz) and in an
/// 8th column (10 Hz), and the route is as intact (within 0.3 m at the worst control
/// point). The previous build integrated them: with the file's, the joint fit was refused
/// and OEPI's route taken, 388 m off (intact 0.97 m); with the column's, OWPI's, 876 m
/// off (intact 0.48 m). Measured now: 0.16 and 0.71 m.
#[test]
fn kingston_speed_spikes_are_left_out() {
    use unz_formats::{IngestEvents, IngestReport};

    let tmp = tempfile::tempdir().unwrap();
    let file = kingston_speeds();
    // Runs `run` to disupt: its odometer's failures, its ingest's events and the joint's
    // worst control point, m.
    let disupt = |run: &std::path::Path, out: &std::path::Path| {
        crate::util::run_until(run, out, "disupt");
        let dir = out.join("kingston2008-segment1");
        let report: IngestReport = read_json(&dir.join("ingest/ingest.json"));
        let events: IngestEvents = read_json(&dir.join("ingest/ingest_events.json"));
        let d: unz::disupt_stage::DisuptOut = read_json(&dir.join("disupt/disupt.json"));
        assert_eq!(d.corrected_by.as_deref(), Some("joint"), "{:?}", d.skipped);
        let worst = worst_control_point_m(&d.methods["joint"]);
        (report.odometer_failures.unwrap_or_default(), events, worst)
    };

    // The file: six lone readings 25 m/s too fast while driving (2.3 g), five at 255 km/h
    // from 152 800 s (a burst of 5 s, a gap bridged by the IMU once left out), and the
    // dropouts below.
    let intact_dir = tmp.path().join("file");
    let (_, _, worst_intact) = disupt(
        &kingston_with(&intact_dir.join("k"), ""),
        &intact_dir.join("o"),
    );
    let lone: Vec<f64> = (file.iter())
        .filter(|r| r.1 > 5.0 && !(152_790.0..152_815.0).contains(&r.0))
        .step_by(30)
        .take(6)
        .map(|r| r.0)
        .collect();
    assert_eq!(lone.len(), 6);
    // And two readings in a row at zero, twice, while driving at 10 m/s or more (a
    // logger's dropouts: the car brakes to zero in a second, but does not pull away).
    let near_lone = |t: f64| lone.iter().any(|l| (t - l).abs() < 5.0);
    let dropouts: Vec<f64> = (file.windows(4))
        .filter(|w| w.iter().all(|r| r.1 > 10.0 && !near_lone(r.0)))
        .filter(|w| !(152_790.0..152_815.0).contains(&w[0].0))
        .step_by(40)
        .take(2)
        .map(|w| w[1].0)
        .collect();
    assert_eq!(dropouts.len(), 2);
    let run = kingston_with(&tmp.path().join("spiky").join("k"), "");
    let text: String = (file.iter())
        .map(|&(t, v)| {
            let v = match t {
                _ if lone.contains(&t) => v + 25.0,
                _ if (152_800.0..152_805.0).contains(&t) => 70.83,
                _ if dropouts.iter().any(|d| t == *d || t == d + 1.0) => 0.0,
                _ => v,
            };
            format!("{t} {v:.5}\n")
        })
        .collect();
    std::fs::write(run.join("odometer.txt"), text).unwrap();
    let (f, events, worst) = disupt(&run, &tmp.path().join("spiky").join("o"));
    eprintln!("file: {f:?}; worst control point {worst:.2} m (intact {worst_intact:.2} m)");
    assert_eq!(
        (f.spikes, f.jumps_kept, f.file_gaps, f.bridged),
        (15, 0, 1, 1),
        "{f:?}"
    );
    assert!(
        worst < worst_intact + 0.3,
        "{worst} m, intact {worst_intact} m"
    );
    let spikes: Vec<&str> = (events.odometer_file_faults.iter())
        .filter(|e| e.reason.ends_with("(a spike)"))
        .map(|e| e.reason.as_str())
        .collect();
    assert_eq!(spikes.len(), 15, "{spikes:?}");
    let first = format!(" m/s at {} s left out: it jumped from ", lone[0]);
    assert!(spikes[0].contains(&first), "{}", spikes[0]);

    // The column: 20 s of random speeds (0-50 m/s) from 152 800 s, and four lone lines
    // at zero while driving at 10 m/s or more (a drop of 10 m/s in 0.1 s).
    let intact_dir = tmp.path().join("column");
    kingston_column(&intact_dir.join("k"), |_, v| v);
    let (_, _, worst_intact) = disupt(&intact_dir.join("k"), &intact_dir.join("o"));
    let mut state = 28u64;
    let mut random = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let junk: Vec<f64> = (0..200).map(|_| 50.0 * random()).collect();
    let zeros: Vec<f64> = (file.iter())
        .filter(|r| r.1 > 10.0 && !(152_790.0..152_830.0).contains(&r.0))
        .step_by(20)
        .take(4)
        .map(|r| r.0)
        .collect();
    assert_eq!(zeros.len(), 4);
    let run = tmp.path().join("junk").join("k");
    kingston_column(&run, |t, v| {
        if (152_800.0..152_820.0).contains(&t) {
            junk[((t - 152_800.0) * 10.0).round() as usize % 200]
        } else if zeros.iter().any(|z| (t - z).abs() < 0.05) {
            0.0
        } else {
            v
        }
    });
    let (f, _, worst) = disupt(&run, &tmp.path().join("junk").join("o"));
    eprintln!("column: {f:?}; worst control point {worst:.2} m (intact {worst_intact:.2} m)");
    // Each junk line left out but the few that happen to be within reach of the speed
    // before them (a random speed within 3 m/s of it).
    assert!((196..=204).contains(&f.spikes), "{f:?}");
    assert_eq!((f.jumps_kept, f.file_gaps, f.bridged), (0, 1, 1), "{f:?}");
    assert!(
        worst < worst_intact + 0.3,
        "{worst} m, intact {worst_intact} m"
    );
}

/// Kingston's control points are the reference's positions at its stops, and the
/// reference is not the navigated point (the odometer's, an axle's middle). Compared at a
/// mark 1.5 m ahead of the navigated point (`[vehicle] mark_lever_arm_m`, the best of a
/// 0.5-m sweep of forward and right offsets), the joint's hold-outs fall from 1.33 and
/// 3.02 m to 0.07 and 0.06 m; behind it they grow (at 0.7 m behind: 4.34 m). The heading
/// does not move (the arm turns with the vehicle): on the only real data here, that is
/// the arm's sign and its axes. Two points are too few for the joint fit to check or
/// estimate the mark, so it is a sweep, not an estimate with a σ.
#[test]
fn kingston_control_points_fit_a_reference_point_ahead_of_the_axle() {
    let r = reference();
    let tmp = tempfile::tempdir().unwrap();
    let run_with = |forward_m: f64| {
        let (d, dir) = kingston_disupt(
            &tmp.path().join(format!("{forward_m}")),
            &format!("[params.vehicle]\nmark_lever_arm_m = [{forward_m}, 0.0, 0.0]\n"),
        );
        let j = &d.methods["joint"];
        let holdout_max = j
            .holdout
            .as_ref()
            .unwrap()
            .iter()
            .map(|h| h.dx_m.hypot(h.dy_m))
            .fold(0.0, f64::max);
        let heading = corrected_heading_error_deg(&dir, &r);
        eprintln!(
            "Kingston, mark {forward_m} m ahead: hold-out ≤ {holdout_max:.2} m, control points ≤ {:.2} m, heading {heading:.3}°",
            worst_control_point_m(j)
        );
        assert!(d.joint_mark_arm_check.is_none(), "two points: not checked");
        (holdout_max, heading)
    };
    let (behind, at, ahead) = (run_with(-1.5), run_with(0.0), run_with(1.5));
    assert!(
        ahead.0 < 0.5 && at.0 > 2.0 && behind.0 > at.0,
        "{behind:?} {at:?} {ahead:?}"
    );
    assert!((ahead.1 - at.1).abs() < 0.02, "{ahead:?} {at:?}");
}

/// The real log written in an IMU's own axes, as an IMU mounted upside down (ROS's
/// x forward, y left, z up) or sideways (x right, y forward, z up) logs them. The
/// previous build took them for the body's axes: the upside-down log's Kryt1 compared
/// the gyros' roll of 180° with the accelerometers' of 0°, its joint fit left its bounds
/// (odometer scale +32 %, pitch levelling 95 mrad) and OEPI's route was taken, 12.8 m
/// off at the last control point (the intact log's joint: 0.4 m); the sideways log's was
/// 1.37 km off. Now the derive fails each, naming the setting that fixes it; with the
/// setting, every table from the ingest to the corrected navigation is the intact log's,
/// byte for byte (the turn only moves and negates numbers).
#[test]
fn kingston_logged_in_the_imus_own_axes() {
    use unz_stages::imu_axes::ImuAxes;

    let tmp = tempfile::tempdir().unwrap();
    let intact = kingston_with(&tmp.path().join("intact"), "");
    crate::util::run_until(&intact, &tmp.path().join("intact-o"), "disupt");
    let imu = std::fs::read_to_string(intact.join("imu.txt")).unwrap();
    for (axes, words) in [
        ("FLU", "x forward, y left, z up"),
        ("RFU", "x right, y forward, z up"),
    ] {
        let a: ImuAxes = axes.parse().unwrap();
        let run = kingston_with(&tmp.path().join(axes), "");
        // Each increment in the log's axes, written so it reads back exactly.
        let text: String = imu
            .lines()
            .map(|l| {
                let f: Vec<&str> = l.split_whitespace().collect();
                let v: Vec<f64> = f[1..7].iter().map(|x| x.parse().unwrap()).collect();
                let dtheta = a.to_log([v[0], v[1], v[2]]);
                let dvel = a.to_log([v[3], v[4], v[5]]);
                let [a0, a1, a2] = dtheta;
                let [v0, v1, v2] = dvel;
                format!("{} {a0} {a1} {a2} {v0} {v1} {v2}\n", f[0])
            })
            .collect();
        std::fs::write(run.join("imu.txt"), text).unwrap();
        let out = tmp.path().join(format!("{axes}-o"));
        let err = crate::util::stage_fails("derive", &run, &out);
        assert!(err.contains("stage derive failed"), "{axes}: {err}");
        assert!(
            err.contains(&format!("imu_axes = \"{axes}\"")),
            "{axes}: {err}"
        );
        assert!(err.contains(words), "{axes}: {err}");

        let manifest = std::fs::read_to_string(run.join("run.toml")).unwrap();
        let named = format!("{manifest}\n[params.vehicle]\nimu_axes = \"{axes}\"\n");
        std::fs::write(run.join("run.toml"), named).unwrap();
        crate::util::run_until(&run, &out, "disupt");
        for file in [
            "ingest/imu.parquet",
            "ingest/odometer.parquet",
            "derive/derived.parquet",
            "derive/epochs.parquet",
            "navigate/nav.parquet",
            "disupt/disupt.json",
            "disupt/corrected_nav.parquet",
        ] {
            let at = |o: &str| {
                let path = tmp.path().join(o).join("kingston2008-segment1").join(file);
                std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
            };
            assert!(at("intact-o") == at(&format!("{axes}-o")), "{axes}: {file}");
        }
        let nav: unz::flow::NavigateSummary =
            read_json(&out.join("kingston2008-segment1/navigate/navigate.json"));
        let report = nav.imu_axes.unwrap();
        assert_eq!(report.named, a);
        assert!(report.check.tilt_deg < 2.0, "{report:?}");
        assert!(report.check.forward_turn_deg.abs() < 5.0, "{report:?}");
    }
}

/// The corrected route's height minus the reference's at the reference's epochs within
/// the log (1 Hz), m.
fn corrected_height_errors_m(disupt: &std::path::Path, r: &Reference) -> Vec<f64> {
    height_errors_m(&disupt.join("corrected_nav.parquet"), r)
}

/// A navigation file's height minus the reference's at the reference's epochs within the
/// log (1 Hz), m.
fn height_errors_m(nav: &std::path::Path, r: &Reference) -> Vec<f64> {
    let (t_s, h) = nav_series(nav, "h_m");
    r.t_s
        .iter()
        .zip(&r.position)
        .filter_map(|(&t, p)| {
            let k = t_s.partition_point(|&x| x < t);
            (k > 0 && k < t_s.len()).then(|| {
                let w = (t - t_s[k - 1]) / (t_s[k] - t_s[k - 1]);
                h[k - 1] + w * (h[k] - h[k - 1]) - p[2]
            })
        })
        .collect()
}

/// The real drive's heights. While driving, the reference INS's pitch lies 0.94° (median)
/// below its velocity's: the car's path climbs about 0.95° above the IMU's x. Dead
/// reckoning carried the distance along x, and the corrected route (0.4 m off
/// horizontally at the last control point) ended 38 m below it, 13.8 m RMS from the
/// reference's height. The two control points' heights fit 0.94° (each predicted by the
/// other within 1.5 and 4.5 m), and the corrected route's height is within 1.0 m RMS of
/// the reference's over the whole log (at most 3.6 m; the reference is SPAN's real-time
/// INS/GPS, good to a few metres). Configured as the vehicle's angle, it gives the drive
/// without its control points the same heights (1.05 m RMS, from 13.4). Its control
/// points' heights 35 m off in datum are refused. The same log rotated as from an IMU
/// pitched 10° up on its mount fits 9.07° the other way and gives the same heights
/// (0.98 m RMS).
#[test]
fn kingston_heights_give_the_odometers_pitch() {
    let tmp = tempfile::tempdir().unwrap();
    let r = reference();
    let rms = |e: &[f64]| (e.iter().map(|e| e * e).sum::<f64>() / e.len() as f64).sqrt();
    let (d, disupt) = kingston_disupt(&tmp.path().join("shipped"), "");
    assert_eq!(d.corrected_by.as_deref(), Some("joint"));
    let fit = d.odo_pitch.expect("fitted");
    assert!(fit.applied, "{fit:?}");
    assert!((fit.odo_pitch_deg - 0.94).abs() < 0.15, "{fit:?}");
    let last = fit.points.last().unwrap();
    assert!(last.dh_before_m < -30.0, "{last:?}");
    for p in &fit.points {
        assert!(p.dh_m.abs() < 2.0, "{p:?}");
        assert!(p.holdout_dh_m.is_some_and(|h| h.abs() < 6.0), "{p:?}");
    }
    // The joint's track in tracks.parquet takes the angle too: one line in the review.
    let (t_s, h) = corrected_series(&disupt, "h_m");
    let tracks = unz::method_tables::read_tracks(&disupt.join("tracks.parquet")).unwrap();
    let joint = tracks.iter().find(|t| t.method == "joint").unwrap();
    assert!(joint.t_ns.len() > 800);
    for (t, th) in joint.t_ns.iter().zip(&joint.h_m) {
        let k = t_s.partition_point(|&x| x < *t as f64 * 1e-9 - 1e-6);
        assert!(
            (f64::from(*th) - h[k]).abs() < 1e-3,
            "{t}: {th} against {}",
            h[k]
        );
    }
    let e = corrected_height_errors_m(&disupt, &r);
    assert!(e.len() > 800, "{}", e.len());
    let max = e.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    eprintln!(
        "Kingston height − reference: RMS {:.2} m, at most {max:.2} m",
        rms(&e)
    );
    assert!(rms(&e) < 2.0 && max < 5.0, "RMS {} m, max {max} m", rms(&e));

    // The angle configured for the vehicle (`[vehicle] odo_pitch_deg`, as a campaign's
    // runs would pool it; here this drive's own), and the drive without its control
    // points: nothing to fit, and the navigate stage's route climbs by the angle from the
    // start. Its heights come within 1.1 m RMS of the reference's (3.4 m at most), from
    // 13.4 m RMS (38.9 m) without it.
    let shipped = std::fs::read_to_string(test_data("kingston2008-seg1").join("run.toml")).unwrap();
    let without_points = &shipped[..shipped.find("[[control_point]]").unwrap()];
    let navigated = |name: &str, params: &str| {
        let run = tmp.path().join(name).join("k");
        let run = kingston_with(&run, "");
        std::fs::write(run.join("run.toml"), format!("{without_points}{params}")).unwrap();
        let out = tmp.path().join(name).join("o");
        crate::util::run_until(&run, &out, "disupt");
        let d: unz::disupt_stage::DisuptOut =
            read_json(&out.join("kingston2008-segment1/disupt/disupt.json"));
        assert!(d.odo_pitch.is_none(), "{:?}", d.odo_pitch);
        height_errors_m(&out.join("kingston2008-segment1/navigate/nav.parquet"), &r)
    };
    let (plain, configured) = (
        navigated("no-points", ""),
        navigated(
            "no-points-configured",
            &format!("[params.vehicle]\nodo_pitch_deg = {}\n", fit.odo_pitch_deg),
        ),
    );
    eprintln!(
        "Kingston without control points, height − reference: RMS {:.2} m without the angle, \
         {:.2} m with it",
        rms(&plain),
        rms(&configured)
    );
    assert!(rms(&plain) > 10.0, "RMS {} m", rms(&plain));
    assert!(rms(&configured) < 2.0, "RMS {} m", rms(&configured));

    // The control points' heights 35 m lower (above the geoid, where the start's is
    // ellipsoidal): a datum's offset does not grow with distance, and each point held out
    // is further than with no angle. Not fitted: the route's heights are as without it.
    let run = kingston_with(&tmp.path().join("datum/k"), "");
    let manifest = std::fs::read_to_string(run.join("run.toml")).unwrap();
    let lowered = manifest
        .replace("height_m = 44.419", "height_m = 9.419")
        .replace("height_m = 48.135", "height_m = 13.135");
    assert_ne!(lowered, manifest);
    std::fs::write(run.join("run.toml"), lowered).unwrap();
    let out = tmp.path().join("datum/o");
    crate::util::run_until(&run, &out, "disupt");
    let d: unz::disupt_stage::DisuptOut =
        read_json(&out.join("kingston2008-segment1/disupt/disupt.json"));
    let fit = d.odo_pitch.expect("fitted");
    assert!(!fit.applied, "{fit:?}");
    assert!(
        fit.refused
            .as_deref()
            .unwrap_or_default()
            .contains("do not show one angle")
    );
    for p in &fit.points {
        assert_eq!(p.dh_m, p.dh_before_m, "{p:?}");
    }

    // The IMU pitched 10° nose up on its mount.
    let run = kingston_mounted(&tmp.path().join("pitched/k"), [0.0, 10.0, 0.0]);
    let out = tmp.path().join("pitched/o");
    crate::util::run_until(&run, &out, "disupt");
    let disupt = out.join("kingston2008-segment1/disupt");
    let d: unz::disupt_stage::DisuptOut = read_json(&disupt.join("disupt.json"));
    let fit = d.odo_pitch.expect("fitted");
    assert!(fit.applied, "{fit:?}");
    assert!((fit.odo_pitch_deg + 10.0 - 0.94).abs() < 0.3, "{fit:?}");
    let pitched = corrected_height_errors_m(&disupt, &r);
    assert!(rms(&pitched) < 2.0, "RMS {} m", rms(&pitched));
}

/// Kingston as logged by an IMU mounted at `mounting_deg` (roll, pitch, yaw: its axes
/// the body's turned by them, as `[vehicle] imu_mounting_deg` names them), in `run`.
fn kingston_mounted(run: &std::path::Path, mounting_deg: [f64; 3]) -> std::path::PathBuf {
    let [r, p, y] = mounting_deg.map(f64::to_radians);
    let imu_from_body = nalgebra::Rotation3::from_euler_angles(r, p, y).inverse();
    kingston_increments_edited(run, |v| {
        let turn = |i: usize| imu_from_body * nalgebra::Vector3::new(v[i], v[i + 1], v[i + 2]);
        let (a, w) = (turn(0), turn(3));
        [a.x, a.y, a.z, w.x, w.y, w.z]
    })
}

/// Kingston with each line's six increments (angle, then velocity) as `edit` gives them,
/// its time tags as written, in `run`.
fn kingston_increments_edited(
    run: &std::path::Path,
    edit: impl Fn([f64; 6]) -> [f64; 6],
) -> std::path::PathBuf {
    let run = kingston_with(run, "");
    let imu = std::fs::read_to_string(run.join("imu.txt")).unwrap();
    let text: String = imu
        .lines()
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            let mut v = [0.0; 6];
            for (x, t) in v.iter_mut().zip(&f[1..7]) {
                *x = t.parse().unwrap();
            }
            let e = edit(v);
            format!(
                "{} {:e} {:e} {:e} {:e} {:e} {:e}\n",
                f[0], e[0], e[1], e[2], e[3], e[4], e[5]
            )
        })
        .collect();
    std::fs::write(run.join("imu.txt"), text).unwrap();
    run
}

/// Kingston as logged by an IMU yawed 20° on its mount, and one rolled 45°. The previous
/// build took the yawed log's axes for the body's: the joint fit left its bounds (its
/// azimuth takes a yaw, linearised) and OWPI's route was taken, 442 m off at the last
/// control point (15°: 323 m; 12° and 10° were within 0.9 m); the rolled one failed as
/// tilted, with no setting to fix it. Now the derive fails each naming the setting the
/// drive shows (yaw 19.4°; roll 45.3°, the nearest right angle's axes turned back
/// 44.7°), and with the setting as named, the joint fit's route is within 0.3 m of the
/// last point (as shipped: 0.4 m) and its heights within 1.0 m RMS of the reference's.
#[test]
fn kingston_an_imu_mounted_at_an_angle_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let r = reference();
    for (name, mounting) in [("yawed", [0.0, 0.0, 20.0]), ("rolled", [45.0, 0.0, 0.0])] {
        let run = kingston_mounted(&tmp.path().join(name).join("k"), mounting);
        let out = tmp.path().join(name).join("o");
        let err = crate::util::stage_fails("derive", &run, &out);
        let settings = crate::util::vehicle_settings_named(&err);
        assert!(settings.contains("imu_mounting_deg = ["), "{name}: {err}");
        if name == "yawed" {
            assert!(
                err.contains("yawed 19.") && !settings.contains("imu_axes"),
                "{err}"
            );
        } else {
            assert!(err.contains("45° from the body's down"), "{err}");
        }
        let manifest = std::fs::read_to_string(run.join("run.toml")).unwrap();
        let named = format!("{manifest}\n[params.vehicle]\n{settings}");
        std::fs::write(run.join("run.toml"), named).unwrap();
        crate::util::run_until(&run, &out, "disupt");
        assert!(joint_worst_control_point_m(&out) < 1.0, "{name}");
        let heights = corrected_height_errors_m(&out.join("kingston2008-segment1/disupt"), &r);
        let rms = (heights.iter().map(|e| e * e).sum::<f64>() / heights.len() as f64).sqrt();
        assert!(rms < 2.0, "{name}: {rms} m");
        let nav: unz::flow::NavigateSummary =
            read_json(&out.join("kingston2008-segment1/navigate/navigate.json"));
        let report = nav.imu_axes.unwrap();
        assert!(report.named_mounting_deg.is_some(), "{report:?}");
        let left = report.check.mounting_deg.unwrap();
        assert!(left.iter().all(|a| a.abs() < 0.5), "{name}: {left:?}");
    }
}

/// The joint fit's worst control point of the Kingston run disupt put in `out`, m (the
/// joint corrected it).
/// Asserts the joint fit's worst control point of the Kingston run in `out` is the one
/// in `reference`'s within 1 cm: the same route.
fn assert_same_worst_point(out: &std::path::Path, reference: &std::path::Path) {
    let (w, w0) = (
        joint_worst_control_point_m(out),
        joint_worst_control_point_m(reference),
    );
    assert!(
        (w - w0).abs() < 0.01,
        "{w} m, {w0} m in {}",
        reference.display()
    );
}

fn joint_worst_control_point_m(out: &std::path::Path) -> f64 {
    let d: unz::disupt_stage::DisuptOut =
        read_json(&out.join("kingston2008-segment1/disupt/disupt.json"));
    assert_eq!(d.corrected_by.as_deref(), Some("joint"), "{:?}", d.skipped);
    worst_control_point_m(&d.methods["joint"])
}

/// The OBD-II speeds written in km/h (as OBD-II gives them) or mph where the manifest
/// says m/s. The previous build integrated them: the joint fit left its bounds (odometer
/// scale −72 % and −55 %) and OEPI's route was taken, 2.92 km and 1.38 km off at the last
/// control point, under an "ok". Now the derive fails, naming the unit and the file: the
/// accelerometers' x follows the odometer's u̇ with a gain of 0.29 and 0.47 (1.04 as
/// shipped). Named in the manifest (`kind = "speed_kmh"`), the km/h file gives the
/// shipped file's route (within 1 cm at the control points: its speeds were written to
/// 1e-5 km/h).
#[test]
fn kingston_speeds_in_kmh_or_mph_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let intact = kingston_with(&tmp.path().join("intact"), "");
    crate::util::run_until(&intact, &tmp.path().join("intact-o"), "disupt");
    for (unit, factor) in [("km/h", 3.6), ("mph", 2.236_936)] {
        let run = kingston_with(&tmp.path().join(unit.replace('/', "")), "");
        let text: String = (kingston_speeds().iter())
            .map(|(t, v)| format!("{t} {:.5}\n", v * factor))
            .collect();
        std::fs::write(run.join("odometer.txt"), text).unwrap();
        let err = crate::util::stage_fails("derive", &run, &tmp.path().join("o"));
        assert!(
            err.contains("the odometer's distance is not in metres"),
            "{err}"
        );
        assert!(
            err.contains(&format!("(near {factor}, the ratio of {unit} to m/s")),
            "{err}"
        );
        assert!(err.contains("odometer.txt in m/s"), "{err}");
        if unit == "km/h" {
            let manifest = std::fs::read_to_string(run.join("run.toml")).unwrap();
            assert!(manifest.contains("kind = \"speed_mps\""));
            let named = manifest.replace("kind = \"speed_mps\"", "kind = \"speed_kmh\"");
            std::fs::write(run.join("run.toml"), named).unwrap();
            let out = tmp.path().join("kmh-o");
            crate::util::run_until(&run, &out, "disupt");
            assert_same_worst_point(&out, &tmp.path().join("intact-o"));
        }
    }
}

/// The speeds as an 8th column in km/h: the derive fails naming the unit and the column;
/// named in the manifest (`[odometer] kind = "speed_kmh"` without a file), the route is
/// the column in m/s's (within 1 cm at the control points). `distance_m` names no column.
#[test]
fn kingston_a_speed_column_in_kmh_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let mps = tmp.path().join("mps");
    kingston_column(&mps, |_, v| v);
    crate::util::run_until(&mps, &tmp.path().join("mps-o"), "disupt");

    let kmh = tmp.path().join("kmh");
    kingston_column(&kmh, |_, v| v * 3.6);
    let err = crate::util::stage_fails("derive", &kmh, &tmp.path().join("kmh-o"));
    assert!(err.contains("(near 3.6, the ratio of km/h to m/s"), "{err}");
    assert!(err.contains("8th column's speeds in m/s"), "{err}");
    let manifest = std::fs::read_to_string(kmh.join("run.toml")).unwrap();
    let with = |kind: &str| format!("{manifest}\n[odometer]\nkind = \"{kind}\"\n");
    std::fs::write(kmh.join("run.toml"), with("distance_m")).unwrap();
    let err = crate::util::stage_fails("ingest", &kmh, &tmp.path().join("kmh-o"));
    assert!(err.contains("the 8th column is a speed"), "{err}");
    std::fs::write(kmh.join("run.toml"), with("speed_kmh")).unwrap();
    crate::util::run_until(&kmh, &tmp.path().join("kmh-o"), "disupt");
    assert_same_worst_point(&tmp.path().join("kmh-o"), &tmp.path().join("mps-o"));
}
