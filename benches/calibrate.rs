//! Wall time of `vibroscope calibrate` (issue 15, part 5) on the clip the
//! calibration tests use: 64x64, 2200 fps, 2 s of a 100-1000 Hz linear
//! chirp seen through a camera whose clock is 2000 ppm fast, rendered here
//! by `vibroscope simulate`. Printed against `vibroscope listen` on the
//! same file in the same run (the recovery alone, which calibrate runs
//! first), and as a real-time factor (clip duration / wall time; above 1
//! is faster than real time). Each command is timed end to end, best of 3.
//!
//!     cargo bench --bench calibrate

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::f64::consts::PI;

#[path = "util/timing.rs"]
#[allow(dead_code)] // `render_tones_scene` serves the magnifier benches
mod timing;
use timing::{best_of, timed};

const SECS: f64 = 2.0;

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    let dir = std::env::temp_dir().join(format!("vibroscope-calibrate-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    // The reference: 2.2 s (longer than the clip), 32 kHz float.
    let rate = 32_000u32;
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: rate,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(dir.join("chirp.wav"), spec).unwrap();
    let (len, f0, f1) = (SECS + 0.2, 100.0, 1000.0);
    for i in 0..(len * rate as f64) as usize {
        let t = i as f64 / rate as f64;
        let v = 0.9 * (2.0 * PI * (f0 * t + (f1 - f0) * t * t / (2.0 * len))).sin();
        w.write_sample(v as f32).unwrap();
    }
    w.finalize().unwrap();
    std::fs::write(
        dir.join("scene.toml"),
        format!(
            "width = 64\nheight = 64\nfps = 2200.0\nnoise_std = 0.5\nduration_s = {SECS}\namplitude_px = 0.05\nclock_error_ppm = 2000.0\nsignal = {{ type = \"wav\", path = \"chirp.wav\" }}\n"
        ),
    )
    .unwrap();
    eprintln!("rendering {SECS} s of 64x64 video at 2200 fps ...");
    timed(&dir, &["simulate", "scene.toml", "-o", "scene.y4m"]);
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    let listen = best_of(3, || timed(&dir, &["listen", "scene.y4m", "-o", "l.wav"]));
    let cal = best_of(3, || {
        timed(
            &dir,
            &[
                "calibrate",
                "scene.y4m",
                "--reference",
                "chirp.wav",
                "--json",
                "r.json",
            ],
        )
    });
    println!("calibrate, 64x64, 2200 fps, {SECS} s clip, {cores} cores, best of 3:");
    println!(
        "  calibrate {cal:.2} s ({:.2}x real time)   listen {listen:.2} s ({:.2}x real time)   calibrate/listen {:.2}",
        SECS / cal,
        SECS / listen,
        cal / listen
    );
    let _ = std::fs::remove_dir_all(&dir);
}
