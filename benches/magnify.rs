//! Throughput of `vibroscope magnify` (issue 18) on 256x256 8-bit frames,
//! CSP and Riesz pyramids, against `vibroscope listen` on the same file in
//! the same run (the visual microphone reads the same pyramids but writes
//! no frames). 400 frames at 500 fps rendered here by the engine; each
//! command is timed end to end (process start, decoding, writing), best of
//! 3, and printed in Mpix/s with its ratio to `listen` with the same
//! pyramid.
//!
//!     cargo bench --bench magnify

#![allow(clippy::unwrap_used, clippy::expect_used)]

#[path = "util/timing.rs"]
mod timing;
use timing::{best_of, timed};

const FRAMES: usize = 400;
const PIX: f64 = 256.0 * 256.0;

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    let dir = std::env::temp_dir().join(format!("vibroscope-magnify-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    eprintln!("rendering {FRAMES} frames of 500 fps 256x256 video ...");
    timing::render_tones_scene(&dir, (256, 256), FRAMES);
    let mpix = |s: f64| FRAMES as f64 * PIX / s / 1e6;
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    println!("magnify vs listen, 256x256, {FRAMES} frames, {cores} cores, best of 3:");
    for pyr in ["csp", "riesz"] {
        let listen = best_of(3, || {
            timed(
                &dir,
                &[
                    "listen",
                    "scene.y4m",
                    "--method",
                    "phase",
                    "--pyramid",
                    pyr,
                    "-o",
                    "l.wav",
                ],
            )
        });
        let magnify = best_of(3, || timed(&dir, &timing::magnify_args(pyr, "m.y4m")));
        println!(
            "  {pyr:<5}  magnify {:7.1} Mpix/s ({:.2} s)   listen {:7.1} Mpix/s ({:.2} s)   magnify/listen {:.2}",
            mpix(magnify),
            magnify,
            mpix(listen),
            listen,
            listen / magnify
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
