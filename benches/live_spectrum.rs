//! The live sliding spectrum (issue 5): a 2200 fps 256x256 8-bit stream,
//! 5 s rendered here by the engine and played back in real time by the
//! `file` source (`realtime = true`: a live source, stamped on the run
//! clock, dropping the oldest frame when a stage falls behind), through
//! the shipped `live-spectrum` graph's stages: Riesz `phase` (3 scales) ->
//! sliding `spectrum` (2048-frame Hann window, a spectrum every 220 frames,
//! Welch over 4) -> `peaks`. Target: at least 10 updates a second without
//! dropping frames.
//!
//! Printed: spectra emitted, frames dropped per stage, the update rate
//! (from the spectra's own capture times, written by a `json` sink), and
//! the capture -> sink latency of the spectra (a spectrum's time is its
//! window's centre, so about 0.47 s of that is the half window; if the
//! stages kept up, p99 stays near it, which is what makes the stream-time
//! rate a wall-clock rate too). A baseline from the same run: the same file
//! through the same source into a null sink (decoding and pacing only).
//!
//!     cargo bench --bench live_spectrum

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;
use std::process::Command;

const EXE: &str = env!("CARGO_BIN_EXE_vibroscope");
const FPS: f64 = 2200.0;
const SECONDS: f64 = 5.0;
const WINDOW: f64 = 2048.0;
const HOP: f64 = 220.0;

fn run(dir: &Path, args: &[&str]) -> String {
    let o = Command::new(EXE)
        .current_dir(dir)
        .args(args)
        .output()
        .expect("spawn vibroscope");
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "vibroscope {args:?} failed: {err}");
    err
}

/// Column `col` (0 = stage name) of a stage's `--stats` row.
fn column(stats: &str, stage: &str, col: usize) -> Option<f64> {
    let line = stats
        .lines()
        .find(|l| l.split_whitespace().next() == Some(stage))?;
    line.split_whitespace().nth(col)?.parse().ok()
}

fn latency(stats: &str, key: &str) -> f64 {
    stats
        .lines()
        .find(|l| l.starts_with("latency capture -> out:"))
        .and_then(|l| l.split(key).nth(1))
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.trim_end_matches(',').parse().ok())
        .unwrap_or(f64::NAN)
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    let dir = std::env::temp_dir().join(format!("vibroscope-spectrum-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    eprintln!("rendering {SECONDS} s of 2200 fps 256x256 video ...");
    run(
        &dir,
        &[
            "run",
            "render",
            "--quiet",
            "--set",
            "cam.width=256",
            "--set",
            "cam.height=256",
            "--set",
            &format!("cam.duration_s={SECONDS}"),
            "--set",
            "cam.amplitude_px=0.02",
            "--set",
            "cam.signal={type=\"tones\",freqs_hz=[180.0,440.0,610.0]}",
            "--set",
            "out.path=\"scene.y4m\"",
        ],
    );
    let src = "[[stage]]\nid = \"src\"\nkind = \"file\"\npath = \"scene.y4m\"\nrealtime = true\n\n";
    std::fs::write(
        dir.join("base.toml"),
        format!("{src}[[stage]]\nid = \"out\"\nkind = \"null\"\ninput = \"src\"\n"),
    )
    .expect("write pipeline");
    std::fs::write(
        dir.join("spectrum.toml"),
        format!(
            "{src}[[stage]]\nid = \"phase\"\nkind = \"phase\"\ninput = \"src\"\npyramid = \"riesz\"\nscales = 3\nblock = 16\n\n\
             [[stage]]\nid = \"spectrum\"\nkind = \"spectrum\"\ninput = \"phase\"\nmode = \"sliding\"\nwindow = {WINDOW}\nhop = {HOP}\ntaper = \"hann\"\nwelch = 4\n\n\
             [[stage]]\nid = \"out\"\nkind = \"peaks\"\ninput = \"spectrum\"\npath = \"spectrum.json\"\npeaks = 5\n\n\
             [[stage]]\nid = \"times\"\nkind = \"json\"\ninput = \"spectrum\"\npath = \"spectra.json\"\n"
        ),
    )
    .expect("write pipeline");
    let base = run(&dir, &["run", "base.toml", "--stats", "--quiet"]);
    let frames = FPS * SECONDS;
    println!(
        "baseline (file source in real time -> null): {} of {frames} frames delivered, {} dropped at the sink's edge",
        column(&base, "out", 2).unwrap_or(f64::NAN),
        column(&base, "out", 4).unwrap_or(f64::NAN),
    );
    let stats = run(&dir, &["run", "spectrum.toml", "--stats", "--quiet"]);
    let spectra = column(&stats, "out", 2).unwrap_or(f64::NAN);
    let dropped: f64 = ["phase", "spectrum", "out", "times"]
        .iter()
        .filter_map(|s| column(&stats, s, 4))
        .sum();
    // The update rate from the spectra's own times (each is its window's
    // centre on the capture clock).
    let doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("spectra.json")).expect("spectra.json"))
            .expect("spectra.json is JSON");
    let times: Vec<f64> = doc["spectra"]
        .as_array()
        .map(|a| a.iter().filter_map(|s| s["t_s"].as_f64()).collect())
        .unwrap_or_default();
    let rate = match (times.first(), times.last()) {
        (Some(a), Some(b)) if times.len() > 1 && b > a => (times.len() - 1) as f64 / (b - a),
        _ => f64::NAN,
    };
    println!(
        "live spectrum (2200 fps 256x256 in real time, Riesz 3 scales): {spectra} spectra, {rate:.2} updates/s by their capture times (target >= 10; {:.0} frames after the first window at a hop of {HOP}); frames dropped {dropped} (phase {}, spectrum {}); phase {:.0} us/frame",
        frames - WINDOW,
        column(&stats, "phase", 4).unwrap_or(f64::NAN),
        column(&stats, "spectrum", 4).unwrap_or(f64::NAN),
        column(&stats, "phase", 6).unwrap_or(f64::NAN),
    );
    println!(
        "capture -> peaks latency of each spectrum (window centre to arrival; the half window is {:.0} ms): p50 {} ms, p99 {} ms",
        WINDOW / 2.0 / FPS * 1e3,
        latency(&stats, "p50 "),
        latency(&stats, "p99 "),
    );
    let _ = std::fs::remove_dir_all(&dir);
}
