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
    let r = vibroscope::probe::probe(&a.file, a.fps)?;
    println!("file:        {}", r.file.display());
    println!("format:      {}", r.format);
    println!("size:        {}x{}", r.width, r.height);
    println!("bit depth:   {} bits", r.bits);
    match r.frames {
        Some(n) => println!("frames:      {n}"),
        None => println!("frames:      unknown (stream)"),
    }
    match (r.fps_given, r.fps, r.fps_stated) {
        (true, Some(f), Some(s)) => println!("frame rate:  {f} Hz (given; the file states {s} Hz)"),
        (true, Some(f), None) => println!("frame rate:  {f} Hz (given)"),
        (_, _, Some(s)) => println!("frame rate:  {s} Hz"),
        _ => println!("frame rate:  not stated (pass --fps)"),
    }
    if let (Some(n), Some(rate)) = (r.frames, r.fps) {
        println!("duration:    {:.3} s", n as f64 / rate);
    }
    let ts = if r.timestamps { "present" } else { "absent" };
    println!("timestamps:  {ts}");
    if let Some(e) = r.exposure_s {
        println!("exposure:    {:.3} us", e * 1e6);
    }
    for n in &r.notes {
        println!("note:        {n}");
    }
    super::warn_playback_rate(&a.file, a.fps);
    if let Some(p) = &a.json {
        vibroscope::io::atomic::write_atomic(p, &serde_json::to_vec_pretty(&r)?)?;
        super::wrote(p);
    }
    Ok(ExitCode::SUCCESS)
}
