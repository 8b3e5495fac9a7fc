//! `vibroscope pipelines`.

use std::process::ExitCode;

/// List the shipped pipelines (run one with `vibroscope run NAME`).
#[derive(clap::Args)]
pub struct Args {}

pub fn run(_: Args) -> anyhow::Result<ExitCode> {
    for (name, description) in vibroscope::pipeline::shipped() {
        super::outln!("{name:<12} {description}");
    }
    Ok(ExitCode::SUCCESS)
}
