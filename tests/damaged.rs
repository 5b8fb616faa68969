//! Damaged content through the whole chain: records whose CRC is right but whose fields
//! are not (times jumping or saturated, increments at the counters' limits, odometer
//! counts stuck, jumping or wrapping, status bits), stretches dropped or repeated, logs
//! cut short, header fields and marks changed or repeated, manifest numbers at their
//! limits. Each damaged copy of one simulated run is a run of one campaign: each ends "ok"
//! or fails with its stage and reason, none panics or hangs, and the campaign and its
//! summary go on. (Exploring the same mutations in 1 160 one-run campaigns found the
//! control points no setting reaches and the gaps no dead reckoning bridges, `hostile.rs`.)

use unz_formats::raw::MarkRecord;

use crate::util::{Log, read_log, simulated_run, unz_output, write_log};

/// xorshift64: the cases are the same on every run of the test.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }

    fn pick<T: Copy>(&mut self, v: &[T]) -> T {
        v[self.below(v.len())]
    }
}

/// One damage to `log` or `manifest`; says what it did.
fn damage(r: &mut Rng, log: &mut Log, manifest: &mut toml::Table) -> String {
    let n = log.imu.len();
    let k = r.below(n);
    let m = 1 + if r.below(2) == 0 {
        r.below(5)
    } else {
        r.below(n / 4)
    };
    let span = k..(k + m).min(n);
    let imu = &mut log.imu;
    match r.below(14) {
        0 => {
            let t = r.pick(&[0, u64::MAX, 1 << 63, imu[k].t_us.wrapping_sub(5_000_000)]);
            imu[span].iter_mut().for_each(|x| x.t_us = t);
            format!("t_us of [{k}, +{m}) = {t}")
        }
        1 => {
            let by = r.pick(&[1_000_000_000_000, 1, u64::MAX, 1_500_000]);
            imu[k..]
                .iter_mut()
                .for_each(|x| x.t_us = x.t_us.wrapping_add(by));
            format!("t_us from {k} on + {by}")
        }
        2 | 3 => {
            let v = r.pick(&[i32::MIN, i32::MAX, 0, 1 << 30, 123_456_789]);
            let c = r.below(3);
            let gyro = r.below(2) == 0;
            for x in &mut imu[span] {
                if gyro { x.dtheta[c] = v } else { x.dvel[c] = v }
            }
            format!(
                "{} [{c}] of [{k}, +{m}) = {v}",
                if gyro { "dtheta" } else { "dvel" }
            )
        }
        4 => {
            let v = r.pick(&[0, u32::MAX, 1 << 31]);
            imu[span].iter_mut().for_each(|x| x.odo_count = v);
            format!("odo_count of [{k}, +{m}) = {v}")
        }
        5 => {
            let by = r.pick(&[1 << 31, u32::MAX, 1_000_000]);
            imu[k..]
                .iter_mut()
                .for_each(|x| x.odo_count = x.odo_count.wrapping_add(by));
            format!("odo_count from {k} on + {by}")
        }
        6 => {
            let held = imu[k].odo_count;
            imu[span].iter_mut().for_each(|x| x.odo_count = held);
            format!("odo_count stuck on [{k}, +{m})")
        }
        7 => {
            let v = r.next() as u16;
            imu[span].iter_mut().for_each(|x| x.status = v);
            format!("status of [{k}, +{m}) = {v:#06x}")
        }
        8 => {
            let end = span.end;
            imu.drain(span);
            for (at, _) in &mut log.marks {
                if *at > k {
                    *at = (*at).saturating_sub(end - k).max(k);
                }
            }
            format!("[{k}, {end}) dropped")
        }
        9 => {
            let again = imu[span.clone()].to_vec();
            imu.splice(span.end..span.end, again);
            format!("[{k}, +{m}) repeated")
        }
        10 => {
            let keep = r.pick(&[0, 1, 2, 10, 99, 101, 6000]);
            imu.truncate(keep);
            log.marks.retain(|(at, _)| *at <= keep);
            format!("cut after {keep} records")
        }
        11 => {
            let h = &mut log.header;
            match r.below(4) {
                0 => h.sample_period_us = r.pick(&[1, 1_000_000, 20_000]),
                1 => h.start_time_us = r.pick(&[i64::MIN, i64::MAX, -1]),
                2 => h.dtheta_lsb_rad = r.pick(&[1e-300, 5e-324, 1e-3, f64::NAN]),
                _ => h.odo_lsb_m = r.pick(&[0.0, 1e-6, 10.0, -0.0125]),
            }
            "header field changed".to_owned()
        }
        12 => damage_marks(log, k, r.below(4)),
        _ => {
            let (table, key) = r.pick(&[
                ("site", "latitude_deg"),
                ("site", "height_m"),
                ("initial", "azimuth_deg"),
                ("initial", "static_s"),
                ("control_point", "longitude_deg"),
            ]);
            let v = r.pick(&[
                f64::NAN,
                f64::INFINITY,
                1e300,
                -5.0,
                0.0,
                89.9,
                360.0,
                1e-300,
            ]);
            let t = match manifest.get_mut(table).unwrap() {
                toml::Value::Array(a) => a[0].as_table_mut().unwrap(),
                v => v.as_table_mut().unwrap(),
            };
            t.insert(key.to_owned(), v.into());
            format!("manifest {table}.{key} = {v}")
        }
    }
}

/// Changes the marks of `log` at IMU record `k`, in one of four ways (`kind` 0–3).
fn damage_marks(log: &mut Log, k: usize, kind: usize) -> String {
    let t = log.imu[k].t_us;
    match kind {
        0 => {
            log.marks.clear();
            "marks removed".to_owned()
        }
        1 => {
            log.marks.iter_mut().for_each(|(_, mk)| mk.t_us = t);
            format!("marks moved to record {k}")
        }
        2 => {
            log.marks.iter_mut().for_each(|(_, mk)| mk.point_id = 77);
            "marks of point 77".to_owned()
        }
        _ => {
            // Every point marked again at record k, wherever the vehicle is.
            let again: Vec<_> = log
                .marks
                .iter()
                .map(|(_, mk)| (k, MarkRecord { t_us: t, ..*mk }))
                .collect();
            log.marks.extend(again);
            log.marks.sort_by_key(|(at, _)| *at);
            format!("marks repeated at record {k}")
        }
    }
}

#[test]
fn damaged_runs_end_ok_or_fail_by_name_and_the_campaign_goes_on() {
    // 24 randomly damaged runs, then one run for each way of changing the marks.
    const RANDOM_RUNS: usize = 24;
    const RUNS: usize = RANDOM_RUNS + 4;
    let tmp = tempfile::tempdir().unwrap();
    let sim = simulated_run(&tmp.path().join("sim"), 80, &["--duration-s", "200"]);
    let base_log = read_log(&sim.join("sim-0080.unz"));
    let base_manifest: toml::Table = std::fs::read_to_string(sim.join("run.toml"))
        .unwrap()
        .parse()
        .unwrap();
    let camp = tmp.path().join("c");
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let mut what = Vec::new();
    for i in 0..RUNS {
        let name = format!("d{i:02}");
        let (mut log, mut manifest) = (base_log.clone(), base_manifest.clone());
        let mut said = Vec::new();
        if i < RANDOM_RUNS {
            for _ in 0..1 + rng.below(3) {
                if !log.imu.is_empty() {
                    said.push(damage(&mut rng, &mut log, &mut manifest));
                }
            }
        } else {
            let k = rng.below(log.imu.len());
            said.push(damage_marks(&mut log, k, i - RANDOM_RUNS));
        }
        manifest.insert("name".into(), name.clone().into());
        let dir = camp.join(&name);
        std::fs::create_dir_all(&dir).unwrap();
        write_log(&dir.join("sim-0080.unz"), &log);
        std::fs::write(dir.join("run.toml"), toml::to_string(&manifest).unwrap()).unwrap();
        what.push(format!("{name}: {}", said.join("; ")));
    }
    let out = tmp.path().join("o");
    let o = unz_output(&[
        "run",
        camp.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let text =
        String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
    let cases = what.join("\n");
    assert!(matches!(o.status.code(), Some(0 | 1)), "{text}\n{cases}");
    assert!(!text.contains("panicked"), "{text}\n{cases}");
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    let rows: Vec<&str> = summary.lines().skip(2).collect();
    assert_eq!(rows.len(), RUNS, "{summary}");
    let (mut ok, mut failed) = (0, 0);
    for row in rows {
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        let (name, status, error) = (cells[1], cells[2], cells[cells.len() - 2]);
        assert!(!error.contains("a bug in unz"), "{row}\n{cases}");
        match status {
            "ok" => {
                ok += 1;
                assert!(out.join(name).join("review").is_dir(), "{row}");
            }
            _ => {
                failed += 1;
                // A manifest's error names its line; a stage's, the stage.
                assert!(error.contains("stage ") || error.contains("line "), "{row}");
            }
        }
    }
    // The mutations hit both ways: some damage is repaired or harmless, some fatal.
    assert!(
        ok > 0 && failed > 0,
        "{ok} ok, {failed} failed\n{summary}\n{cases}"
    );
}
