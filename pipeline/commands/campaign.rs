//! `unz campaign merge OUT... --into FILE`.

use std::process::ExitCode;

use crate::campaign::merge_summaries;
use crate::cli::{CampaignArgs, CampaignCommand};

/// Runs the command.
pub fn run(args: &CampaignArgs) -> anyhow::Result<ExitCode> {
    match &args.command {
        CampaignCommand::Merge { outs, into } => {
            let rows = merge_summaries(outs, into)?;
            println!(
                "{rows} runs from {} summaries → {}",
                outs.len(),
                into.display()
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}
