//! `vibroscope kinds`.

use std::process::ExitCode;

/// List the stage kinds a pipeline can use: name, role (source, stage,
/// sink) and what it does.
#[derive(clap::Args)]
pub struct Args {}

pub fn run(_: Args) -> anyhow::Result<ExitCode> {
    for k in vibroscope::pipeline::kinds() {
        println!("{:<16} {:<7} {}", k.name, k.role, k.summary);
    }
    Ok(ExitCode::SUCCESS)
}
