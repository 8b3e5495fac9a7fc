//! `vibroscope kinds [KIND]`.

use std::process::ExitCode;
use vibroscope::error::UsageError;

/// List the stage kinds a pipeline can use (name, role, what it does); with
/// KIND, that kind's input and output ports and its parameters: name, type,
/// default, valid range or choices, unit and what it does.
#[derive(clap::Args)]
pub struct Args {
    /// A kind to describe in full (`vibroscope kinds phase`).
    kind: Option<String>,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    match a.kind {
        None => super::out!("{}", vibroscope::pipeline::kind_listing()),
        Some(k) => match vibroscope::pipeline::kind_table(&k) {
            Some(t) => super::out!("{t}"),
            None => {
                return Err(UsageError::new(
                    "KIND",
                    format!("unknown kind `{k}` (`vibroscope kinds` lists them)"),
                )
                .into())
            }
        },
    }
    Ok(ExitCode::SUCCESS)
}
