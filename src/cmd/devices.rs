//! `vibroscope devices`.

use std::process::ExitCode;

/// List the cameras with their formats, sizes and frame rates.
///
/// List the cameras (V4L2 capture devices) with their formats, sizes and
/// frame rates. Exits 1 with "no camera found" when there is none.
#[derive(clap::Args)]
pub struct Args {}

pub fn run(_: Args) -> anyhow::Result<ExitCode> {
    let list = vibroscope::devices::devices()?;
    if list.is_empty() {
        eprintln!("no camera found (no V4L2 video capture device among /dev/video*)");
        return Ok(ExitCode::from(vibroscope::ErrorKind::Runtime.exit_code()));
    }
    for d in list {
        super::out!("{d}");
    }
    Ok(ExitCode::SUCCESS)
}
