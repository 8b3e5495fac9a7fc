//! `vibroscope probe`.

use std::path::PathBuf;
use std::process::ExitCode;

/// Describe a video file: format, size, bit depth, frames, frame rate,
/// timestamps.
#[derive(clap::Args)]
#[command(after_help = "Examples:\n  vibroscope probe clip.cine\n  \
    vibroscope probe guitar.mp4 --fps 600 --json guitar-info.json")]
pub struct Args {
    file: PathBuf,
    /// Capture rate in Hz, when the file states the wrong one.
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    fps: Option<f64>,
    /// Also write the description as JSON to this file.
    #[arg(long, value_name = "OUT.json")]
    json: Option<PathBuf>,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    super::check_json(&[&a.file], a.json.as_deref())?;
    let r = vibroscope::probe::probe(&a.file, a.fps)?;
    super::outln!("file:        {}", r.file.display());
    super::outln!("format:      {}", r.format);
    super::outln!("size:        {}x{}", r.width, r.height);
    super::outln!("bit depth:   {} bits", r.bits);
    match r.frames {
        Some(n) => super::outln!("frames:      {n}"),
        None => super::outln!("frames:      unknown (stream)"),
    }
    match (r.fps_given, r.fps, r.fps_stated) {
        (true, Some(f), Some(s)) => {
            super::outln!("frame rate:  {f} Hz (given; the file states {s} Hz)")
        }
        (true, Some(f), None) => super::outln!("frame rate:  {f} Hz (given)"),
        (_, _, Some(s)) => super::outln!("frame rate:  {s} Hz"),
        _ => super::outln!("frame rate:  not stated (pass --fps)"),
    }
    if let (Some(n), Some(rate)) = (r.frames, r.fps) {
        super::outln!("duration:    {:.3} s", n as f64 / rate);
    }
    let ts = if r.timestamps { "present" } else { "absent" };
    super::outln!("timestamps:  {ts}");
    if let Some(e) = r.exposure_s {
        super::outln!("exposure:    {:.3} us", e * 1e6);
    }
    for n in &r.notes {
        super::outln!("note:        {n}");
    }
    super::warn_playback_rate(&a.file, a.fps);
    if let Some(p) = &a.json {
        vibroscope::files::write_atomic(p, &serde_json::to_vec_pretty(&r)?)?;
        super::wrote(p);
    }
    Ok(ExitCode::SUCCESS)
}
