//! `unz campaign merge OUT... --into FILE`.

use std::process::ExitCode;

use crate::campaign::merge_summaries;
use crate::cli::{CampaignArgs, CampaignCommand};

/// Runs the command.
pub fn run(args: &CampaignArgs) -> anyhow::Result<ExitCode> {
    match &args.command {
        CampaignCommand::Merge { outs, into, config } => {
            let config = crate::config::load(config.as_deref())?;
            let rows = merge_summaries(outs, into, &config)?;
            let (settings, md) = crate::campaign_pools::merged_names(into);
            println!(
                "{rows} runs from {} summaries → {}, pooled in {}{}",
                outs.len(),
                into.display(),
                md.display(),
                if settings.exists() {
                    format!(", settings to change in {}", settings.display())
                } else {
                    String::new()
                }
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}
