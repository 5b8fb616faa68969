//! `unz bench`: throughput measurements (kept out of the test run).

use std::process::ExitCode;
use std::time::Instant;

use unz_formats::manifest::RunManifest;
use unz_formats::mcap_io::McapCompression;
use unz_stages::simulate::{SimConfig, simulate};

use crate::cli::{BenchArgs, BenchTarget};
use crate::cpu_time::{available_cores, cpu_s_since, cpu_suffix, process_cpu_s};
use crate::ingest::{IngestOptions, ingest};

/// Runs the command.
pub fn run(args: &BenchArgs) -> anyhow::Result<ExitCode> {
    match args.what {
        BenchTarget::Ingest => bench_ingest(args),
        BenchTarget::Navigate => bench_navigate(args),
        BenchTarget::Campaign => bench_campaign(args),
        BenchTarget::Review => bench_review(args),
        BenchTarget::Disupt => bench_disupt(args),
        BenchTarget::Sweep => bench_sweep(args),
    }
}

fn bench_sweep(args: &BenchArgs) -> anyhow::Result<ExitCode> {
    use crate::disupt_stage::problem_of;
    use crate::flow::{Overrides, Params, load_case};
    use crate::sweep::{evaluate_grid, parse_over};

    let (_tmp, ctx) = simulated_run(args, 41)?;
    let params = Params::default();
    let case = load_case(&ctx, &params, &Overrides::default())?;
    let az0 = case.settings.initial.heading_rad.to_degrees();
    let axes = parse_over(&format!(
        "azimuth_deg={}:{}:41,drift_z_rad_s=-5e-6:5e-6:41",
        az0 - 15.0,
        az0 + 15.0
    ))?;
    let mut points = 0;
    let wall_s = best_of(args.repeat, || {
        // A fresh problem each time: nothing is reused between repetitions.
        let problem = problem_of(&case, &params);
        points = std::hint::black_box(evaluate_grid(&problem, &axes)).len();
    });
    println!(
        "sweep: {points} exact passes (41 × 41, azimuth ±15° × driftz ±5e-6 rad/s) on a {:.0} s run in {wall_s:.2} s on {} threads = {:.2} ms per pass per thread",
        args.duration_s,
        rayon::current_num_threads(),
        wall_s * 1e3 * rayon::current_num_threads() as f64 / points as f64
    );
    Ok(ExitCode::SUCCESS)
}

fn bench_ingest(args: &BenchArgs) -> anyhow::Result<ExitCode> {
    let tmp = tempfile::tempdir()?;
    let mut config = SimConfig::new("bench", 1);
    config.duration_s = args.duration_s;
    let run = simulate(&config);
    let run_dir = crate::simulate_io::write_run(&run, tmp.path())?;
    let manifest = RunManifest::load(&run_dir.join("run.toml"))?;
    let raw_bytes = std::fs::metadata(&manifest.raw)?.len() as f64;
    // The ingest's options as the stage gives them by default, but for `raw.mcap`.
    let options = |mcap| IngestOptions {
        mcap,
        odo_lag_prior_s: 0.0,
        imu_axes: Default::default(),
        imu_mounting: None,
        // As the stage does: the derive that follows takes the series.
        keep_series: true,
        max_gap_s: unz_stages::derive::DeriveParams::default().max_gap_s,
    };
    // Nothing else runs meanwhile; the ingest's tables and `raw.mcap` have threads of
    // their own.
    for (label, options) in [
        ("raw → Parquet", options(None)),
        ("full ingest (+ MCAP)", options(Some(McapCompression::None))),
        (
            "full ingest (+ zstd MCAP)",
            options(Some(McapCompression::Zstd)),
        ),
    ] {
        let mut best = f64::INFINITY;
        // The process's CPU a pass (every thread's): the ingest keeps both cores busy
        // from start to end, so its time follows its CPU, which the host's noise moves
        // less than the wall time of a 0.08-s pass.
        let mut least_cpu_s: Option<f64> = None;
        for _ in 0..args.repeat.max(1) {
            let out = tmp.path().join("out");
            let (t0, cpu0) = (Instant::now(), process_cpu_s());
            ingest(&manifest, &out, options)?;
            best = best.min(t0.elapsed().as_secs_f64());
            if let Some(cpu_s) = cpu_s_since(cpu0) {
                least_cpu_s = Some(least_cpu_s.map_or(cpu_s, |l| l.min(cpu_s)));
            }
            // Each repetition into an empty folder, as the stage writes (a re-run's stage
            // removes its old outputs first): renamed over the last repetition's files,
            // ext4 would start writing their pages out in the rename (15 ms for raw.mcap).
            std::fs::remove_dir_all(&out)?;
        }
        let cpu = least_cpu_s.map_or(String::new(), |cpu_s| {
            format!(
                "; CPU {cpu_s:.3} s a pass at the least = {:.0} MB per CPU-second",
                raw_bytes / 1e6 / cpu_s
            )
        });
        println!(
            "ingest {label}: {:.1} MB raw in {:.3} s = {:.0} MB/s ({:.2} M records/s){cpu}",
            raw_bytes / 1e6,
            best,
            raw_bytes / 1e6 / best,
            run.records.len() as f64 / best / 1e6
        );
    }
    // The reader alone over the log, in memory: its framing, CRCs and accounting.
    let log = std::fs::read(&manifest.raw)?;
    println!(
        "raw reader alone through the log, in memory: {:.0} MB/s",
        raw_bytes / 1e6 / best_read_s(args.repeat, &log)?
    );
    // The reader's worst case: nothing but resync search (random bytes behind a valid
    // header), in memory.
    let mut noise = crate::simulate_io::raw_header(&run.sensor)
        .encode()
        .to_vec();
    let mut state = 0x9E37_79B9_7F4A_7C15_u64;
    noise.extend((0..64usize << 20).map(|_| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 24) as u8
    }));
    println!(
        "raw reader through 64 MiB of random bytes (all resync search): {:.0} MB/s",
        noise.len() as f64 / 1e6 / best_read_s(args.repeat, &noise)?
    );
    Ok(ExitCode::SUCCESS)
}

/// One simulated run of `--duration-s` (seed `seed`) in a temporary folder, and its
/// context writing under it (the folder lives as long as the returned guard).
fn simulated_run(
    args: &BenchArgs,
    seed: u64,
) -> anyhow::Result<(tempfile::TempDir, crate::flow::RunCtx)> {
    let tmp = tempfile::tempdir()?;
    let ctx = crate::simulate_io::simulated_ctx(tmp.path(), "bench", seed, args.duration_s)?;
    Ok((tmp, ctx))
}

/// Best wall time, s, of `repeat` reads of a raw log in memory through the reader, record
/// by record (after one read that reports its error, if any).
fn best_read_s(repeat: u32, log: &[u8]) -> anyhow::Result<f64> {
    let read_all = || -> Result<(), unz_formats::FormatError> {
        let mut reader = unz_formats::raw::RawReader::new(log)?;
        while std::hint::black_box(reader.next_record()?).is_some() {}
        Ok(())
    };
    read_all()?;
    Ok(best_of(repeat, || {
        let _ = read_all();
    }))
}

/// Best wall time of `repeat` calls of `f`, s.
fn best_of(repeat: u32, mut f: impl FnMut()) -> f64 {
    (0..repeat.max(1))
        .map(|_| {
            let t0 = Instant::now();
            f();
            t0.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn bench_navigate(args: &BenchArgs) -> anyhow::Result<ExitCode> {
    use unz_stages::criteria::{self, KalmanParams, Kryt1Scratch};
    use unz_stages::filter::LowPass;
    use unz_stages::strapdown::NavTrack;

    use crate::flow::{Overrides, Params, load_case};

    let (_tmp, ctx) = simulated_run(args, 1)?;
    let params = Params::default();
    let case = load_case(&ctx, &params, &Overrides::default())?;
    let n = case.derived.dt_s.len();
    let mut track = NavTrack::default();
    case.navigate(&mut track);
    let nav_s = best_of(args.repeat * 4, || case.navigate(&mut track));
    let lp = LowPass::new(&params.derive.filter, case.derived.nominal_dt_s);
    let mut scratch = Kryt1Scratch::default();
    let kalman = KalmanParams::default();
    let crit_s = best_of(args.repeat * 4, || {
        case.navigate(&mut track);
        let k1 = criteria::kryt1(
            &case.derived.epochs,
            &lp,
            &track,
            &kalman,
            &mut scratch,
            None,
        );
        let k2 = criteria::kryt2(&track, &case.fixes);
        std::hint::black_box((k1, k2));
    });
    // A track-free pass (what the optimisers and sweeps run).
    {
        use unz_stages::strapdown::{CriteriaSink, run_criteria};
        let inputs = case.inputs();
        let mut sinks: [CriteriaSink; 4] = Default::default();
        let one = best_of(args.repeat * 4, || {
            let [sink, ..] = &mut sinks;
            run_criteria(
                &inputs,
                &[case.settings],
                lp.block,
                &[n / 2],
                std::array::from_mut(sink),
            );
            std::hint::black_box(&sinks);
        });
        let two = best_of(args.repeat * 4, || {
            let [a, b, ..] = &mut sinks;
            let mut two = [std::mem::take(a), std::mem::take(b)];
            run_criteria(&inputs, &[case.settings; 2], lp.block, &[n / 2], &mut two);
            std::hint::black_box(&two);
            [*a, *b] = two;
        });
        let four = best_of(args.repeat * 4, || {
            run_criteria(&inputs, &[case.settings; 4], lp.block, &[n / 2], &mut sinks);
            std::hint::black_box(&sinks);
        });
        let mut sinks8: [CriteriaSink; 8] = Default::default();
        let eight = best_of(args.repeat * 4, || {
            run_criteria(
                &inputs,
                &[case.settings; 8],
                lp.block,
                &[n / 2],
                &mut sinks8,
            );
            std::hint::black_box(&sinks8);
        });
        println!(
            "track-free pass (one core): {:.2} ms alone; per pass {:.2} ms two side by side, {:.2} ms four, {:.2} ms eight",
            one * 1e3,
            two * 1e3 / 2.0,
            four * 1e3 / 4.0,
            eight * 1e3 / 8.0
        );
        // The same over segments (what the methods run), and the segments' integration.
        use unz_stages::strapdown::run_criteria_segments;
        use unz_stages::strapdown::segments::{OdoColumns, SegmentPlan, integrate};
        let plan = SegmentPlan::new(n, lp.block, [n / 2]);
        let mut segments = None;
        let integrate_s = best_of(args.repeat * 4, || {
            segments = Some(integrate(
                inputs.dt_s,
                inputs.dtheta_rad,
                &plan,
                true,
                &mut [inputs.odo_dist_m.iter().copied()],
                OdoColumns::read_by(&[case.settings]),
            ));
        });
        let (imu, odo) = segments.expect("integrated");
        let (imu, odo) = (imu.expect("the IMU's segments"), &odo[0]);
        let seg_one = best_of(args.repeat * 4, || {
            let [sink, ..] = &mut sinks;
            run_criteria_segments(
                &imu,
                [odo],
                &[case.settings],
                &[n / 2],
                std::array::from_mut(sink),
            );
            std::hint::black_box(&sinks);
        });
        let seg_two = best_of(args.repeat * 4, || {
            let [a, b, ..] = &mut sinks;
            let mut two = [std::mem::take(a), std::mem::take(b)];
            run_criteria_segments(&imu, [odo; 2], &[case.settings; 2], &[n / 2], &mut two);
            std::hint::black_box(&two);
            [*a, *b] = two;
        });
        let seg_four = best_of(args.repeat * 4, || {
            run_criteria_segments(&imu, [odo; 4], &[case.settings; 4], &[n / 2], &mut sinks);
            std::hint::black_box(&sinks);
        });
        let seg_eight = best_of(args.repeat * 4, || {
            run_criteria_segments(&imu, [odo; 8], &[case.settings; 8], &[n / 2], &mut sinks8);
            std::hint::black_box(&sinks8);
        });
        println!(
            "track-free pass over 0.1-s segments (one core): {:.2} ms alone; per pass {:.2} ms two side by side, {:.2} ms four, {:.2} ms eight; the segments integrated once in {:.2} ms",
            seg_one * 1e3,
            seg_two * 1e3 / 2.0,
            seg_four * 1e3 / 4.0,
            seg_eight * 1e3 / 8.0,
            integrate_s * 1e3
        );
    }
    println!(
        "navigate kernel: {n} samples in {:.2} ms = {:.1} M samples/s (one core)",
        nav_s * 1e3,
        n as f64 / nav_s / 1e6
    );
    println!(
        "criteria evaluation (navigation + Kryt1 + Kryt2): {:.2} ms per run",
        crit_s * 1e3
    );
    Ok(ExitCode::SUCCESS)
}

fn bench_disupt(args: &BenchArgs) -> anyhow::Result<ExitCode> {
    use rayon::prelude::*;
    use unz_stages::disupt::{self, DisuptParams};

    use crate::disupt_stage::problem_of;
    use crate::flow::{Overrides, Params, load_case};

    let (_tmp, ctx) = simulated_run(args, 41)?;
    let params = Params::default();
    let case = load_case(&ctx, &params, &Overrides::default())?;
    let p = DisuptParams::default();
    let mut best = f64::INFINITY;
    let mut report = String::new();
    let mut cpu = String::new();
    for _ in 0..args.repeat.max(1) {
        // A fresh problem each time: nothing is reused between repetitions.
        let problem = problem_of(&case, &params);
        let (t0, cpu0) = (Instant::now(), process_cpu_s());
        let results: Vec<_> = [0, 1, 2]
            .par_iter()
            .map(|&m| match m {
                0 => ("OEPI", disupt::oepi(&problem, &p)),
                1 => ("OWPI", disupt::owpi(&problem, &p)),
                _ => ("joint", disupt::joint(&problem, &p)),
            })
            .collect();
        let wall = t0.elapsed().as_secs_f64();
        let cpu_s = cpu_s_since(cpu0);
        if wall < best {
            best = wall;
            cpu = cpu_suffix(cpu_s, wall, available_cores());
            report = results
                .iter()
                .map(|(n, r)| match r {
                    Ok(r) => format!("{n} {} passes {:.3} s", r.evaluations, r.wall_s),
                    Err(e) => format!("{n} failed: {e}"),
                })
                .collect::<Vec<_>>()
                .join(", ");
        }
    }
    println!(
        "disupt: OEPI + OWPI + joint on a {:.0} s run in {best:.3} s on {} threads{cpu} ({report}; plus the shared first linearisation, 8 passes)",
        args.duration_s,
        rayon::current_num_threads()
    );
    bench_lag_trials(args, &ctx, &case, &params)?;
    Ok(ExitCode::SUCCESS)
}

/// One round of the joint fit's odometer lag search: three trials' re-derives and
/// segments in one walk over the run (as the search runs them).
fn bench_lag_trials(
    args: &BenchArgs,
    ctx: &crate::flow::RunCtx,
    case: &crate::flow::NavCase,
    params: &crate::flow::Params,
) -> anyhow::Result<()> {
    use unz_stages::odo_lag::{Rederive, TrialWalks};
    use unz_stages::strapdown::segments::OdoColumns;

    use crate::artifacts::StageName;
    use crate::disupt_stage::spec_of;
    use crate::flow::IngestedSeries;

    let odometer = IngestedSeries::load_odometer_tags(&ctx.layout().dir(StageName::Ingest))?;
    let g_mps2 = crate::flow::site_gravity_mps2(&ctx.manifest);
    let rederive = Rederive::of_odometer(
        &case.derived,
        &odometer.t_ns,
        &odometer.distance_m,
        params.derive,
        g_mps2,
    );
    let spec = spec_of(case, case.settings, params);
    let plan = spec.moved_segment_plan(&case.derived);
    let columns = OdoColumns::read_by(&[case.settings]);
    let lags_s = [-0.1, 0.0, 0.1];
    // The simulated run's odometer counts pulses: its fit holds the speed bias, and the
    // trials take ru's blocks alone.
    let bias = false;
    let cpu0 = process_cpu_s();
    let wall_s = best_of(args.repeat, || {
        std::hint::black_box(rederive.at_moved_with_segments(
            &lags_s,
            &plan,
            columns,
            bias,
            TrialWalks::Fused,
        ));
    });
    let cpu = cpu_s_since(cpu0).map_or(String::new(), |s| {
        format!(
            "; {:.2} ms CPU on average",
            s * 1e3 / f64::from(args.repeat.max(1))
        )
    });
    println!(
        "lag trials: {} re-derives with their segments in one walk over a {:.0} s run in {:.2} ms (best of {}{cpu})",
        lags_s.len(),
        args.duration_s,
        wall_s * 1e3,
        args.repeat.max(1),
    );
    Ok(())
}

fn bench_review(args: &BenchArgs) -> anyhow::Result<ExitCode> {
    use crate::flow::Params;
    use crate::review::ensure_review;

    let (_tmp, ctx) = simulated_run(args, 1)?;
    let params = Params::default();
    // Every stage before it once; then only the review, from the cached tables.
    let first = ensure_review(&ctx, &params)?;
    let record = first.rrd.with_file_name(crate::stage::RECORD);
    let wall_s = best_of(args.repeat, || {
        let _ = std::fs::remove_file(&record);
        if let Err(e) = ensure_review(&ctx, &params) {
            eprintln!("review failed: {e:#}");
        }
    });
    println!(
        "review: {:.0} s run → {:.1} MB recording in {:.3} s (best of {})",
        args.duration_s,
        first.bytes as f64 / 1e6,
        wall_s,
        args.repeat.max(1)
    );
    Ok(ExitCode::SUCCESS)
}

fn bench_campaign(args: &BenchArgs) -> anyhow::Result<ExitCode> {
    use rayon::prelude::*;

    use crate::campaign::{Plan, STAGES, find_runs, run_campaign};

    let tmp = tempfile::tempdir()?;
    let camp = tmp.path().join("campaign");
    let t0 = Instant::now();
    (0..args.runs).into_par_iter().try_for_each(|i| {
        let mut c = SimConfig::new(&format!("run-{i:03}"), 1000 + u64::from(i));
        c.duration_s = args.duration_s;
        crate::simulate_io::write_run(&simulate(&c), &camp).map(|_| ())
    })?;
    println!(
        "simulated {} runs of {:.0} s in {:.1} s",
        args.runs,
        args.duration_s,
        t0.elapsed().as_secs_f64()
    );
    let out = tmp.path().join("out");
    std::fs::create_dir_all(&out)?;
    let manifests = find_runs(&camp, &out)?.manifests;
    let plan = Plan::every_stage(out.clone());
    for label in ["cold", "cached"] {
        // What a new process does: it knows the hashes the last one saved.
        crate::file_hashes::forget_hashes();
        let (t, cpu0) = (Instant::now(), process_cpu_s());
        crate::file_hashes::load(&out);
        let outcomes = run_campaign(&manifests, &plan);
        crate::file_hashes::save(&out)?;
        let wall = t.elapsed().as_secs_f64();
        let cpu = cpu_suffix(cpu_s_since(cpu0), wall, available_cores());
        let failed = outcomes.iter().filter(|o| o.error.is_some()).count();
        let mut per_stage = std::collections::BTreeMap::<&str, f64>::new();
        for o in &outcomes {
            for (stage, _, s) in &o.stages {
                if let Some(k) = STAGES.iter().find(|x| *x == stage) {
                    *per_stage.entry(k).or_default() += s;
                }
            }
        }
        let stages: Vec<String> = STAGES
            .iter()
            .map(|s| format!("{s} {:.1}", per_stage.get(s).copied().unwrap_or(0.0)))
            .collect();
        println!(
            "{label}: {} runs ({failed} failed) in {wall:.2} s on {} threads{cpu}; summed stage times (s): {}",
            outcomes.len(),
            rayon::current_num_threads(),
            stages.join(", ")
        );
    }
    Ok(ExitCode::SUCCESS)
}
