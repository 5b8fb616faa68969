//! `unz run PATH --out OUT [--from STAGE] [--until STAGE] [--jobs N] [--shard I/N]`.

use std::process::ExitCode;

use anyhow::bail;

use crate::campaign::{Plan, STAGES, find_runs, parse_shard, run_campaign, write_summary};
use crate::cli::RunArgs;

fn stage_index(name: &str) -> anyhow::Result<usize> {
    match STAGES.iter().position(|s| *s == name) {
        Some(i) => Ok(i),
        None => bail!("unknown stage {name:?}; stages: {}", STAGES.join(", ")),
    }
}

/// Runs the command.
pub fn run(args: &RunArgs) -> anyhow::Result<ExitCode> {
    let from = args.from.as_deref().map(stage_index).transpose()?;
    let until = match args.until.as_deref() {
        Some(name) => stage_index(name)?,
        None => STAGES.len() - 1,
    };
    if from.is_some_and(|f| f > until) {
        bail!("--from comes after --until");
    }
    let plan = Plan {
        out: args.out.clone(),
        from,
        until,
        config: crate::config::load(args.config.as_deref())?,
        shard: args.shard.as_deref().map(parse_shard).transpose()?,
        // A terminal gets progress bars; a log file gets one line per stage.
        verbose: !std::io::IsTerminal::is_terminal(&std::io::stderr()),
        progress: std::io::IsTerminal::is_terminal(&std::io::stderr()),
    };
    std::fs::create_dir_all(&args.out)?;
    let found = find_runs(&args.path, &args.out)?;
    for (path, why) in &found.skipped {
        eprintln!("skipped {}: {why}", path.display());
    }
    let manifests = found.manifests;
    if manifests.is_empty() {
        bail!("no run.toml under {}", args.path.display());
    }
    // One run at a time: its threads share one malloc arena, which keeps what is freed
    // (before the pool's threads take arenas of their own).
    if manifests.len() == 1 || args.jobs == Some(1) {
        crate::memory::one_run_at_a_time();
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.jobs.unwrap_or(0))
        .build()?;
    let t0 = std::time::Instant::now();
    let outcomes = pool.install(|| run_campaign(&manifests, &plan));
    write_summary(&args.out, &outcomes, &plan.config)?;
    let failed: Vec<_> = outcomes.iter().filter(|o| o.error.is_some()).collect();
    let cached = outcomes
        .iter()
        .filter(|o| o.error.is_none() && o.stages.iter().all(|s| !s.1))
        .count();
    println!(
        "{} run{}: {} ok ({} fully cached), {} failed, in {:.2} s → {}",
        outcomes.len(),
        if outcomes.len() == 1 { "" } else { "s" },
        outcomes.len() - failed.len(),
        cached,
        failed.len(),
        t0.elapsed().as_secs_f64(),
        args.out.join("campaign.md").display()
    );
    for o in &failed {
        println!("FAILED {}: {}", o.name, o.error.as_deref().unwrap_or(""));
    }
    Ok(if failed.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
