//! A region's sound: the `listen` recipe on the selected region, sent as a WAV with its
//! spectrogram, within the bounds a browser can play.

use axum::body::Bytes;
use axum::extract::State;
use axum::http::StatusCode;
use serde_json::{json, Value};
use std::path::Path;
use std::sync::Arc;

use super::base64::base64;
use super::region::region_answer;
use super::selection::Selection;
use super::{ApiError, ApiResult, App};

/// The playback rate of a region's sound: a standard rate every browser
/// decodes, well above twice any frame rate a region's motion is sampled at
/// by the cameras we read (up to 4 kHz of motion).
const LISTEN_RATE_HZ: u32 = 8000;
/// The lowest frame rate the studio makes a sound from: below it the
/// sound's content, which ends at half the frame rate, is all under 10 Hz,
/// below hearing (the motion view shows slow vibration). A rate a request
/// can set also bounds the work: the sound lasts frames / fps.
const MIN_LISTEN_FPS: f64 = 20.0;
/// The longest sound the studio makes: its WAV, sent in the answer, is then
/// at most 9.6 MB (`vibroscope listen` has no such limit).
const MAX_LISTEN_S: f64 = 600.0;

pub(super) async fn listen(State(app): State<Arc<App>>, b: Bytes) -> ApiResult<axum::Json<Value>> {
    region_answer(app, &b, "listen", region_sound).await
}

/// The `listen` recipe on a region (16-bit WAV at [`LISTEN_RATE_HZ`]), and
/// the sound's spectrogram up to half the frame rate (where the motion's
/// content ends) in dB.
fn region_sound(path: &Path, fps: Option<f64>, sel: &Selection) -> ApiResult<Value> {
    let frame_rate = sel.probe.fps;
    if let Some(rate) = frame_rate {
        if rate < MIN_LISTEN_FPS {
            return Err(ApiError::unprocessable(format!(
                "fps {rate}: a sound needs at least {MIN_LISTEN_FPS} frames per second (its content ends at half the frame rate, {} Hz here, below hearing); the motion view shows slow vibration",
                rate / 2.0
            )));
        }
        if let Some(frames) = sel.probe.frames {
            let seconds = frames as f64 / rate;
            if seconds > MAX_LISTEN_S {
                return Err(ApiError::unprocessable(format!(
                    "{frames} frames at fps {rate} make {seconds:.0} s of sound; the studio plays at most {MAX_LISTEN_S} s (use `vibroscope listen` for longer recordings)"
                )));
            }
        }
    }
    let wav = vibroscope::files::TempPath::new("studio-listen.wav");
    let o = vibroscope::listen::ListenOptions {
        video: path.to_path_buf(),
        output: wav.path().to_path_buf(),
        fps,
        region: sel.region(),
        method: None,
        sources: None,
        denoise: Default::default(),
        speaker: None,
        calibration: None,
        unfold: Default::default(),
        rolling_shutter: None,
        filters: Vec::new(),
        rate: vibroscope::listen::OutputRate::Hz(LISTEN_RATE_HZ),
        float: false,
        half_grids: false,
        run: Default::default(),
    };
    let report = vibroscope::listen::listen(&o)?;
    let internal = |m: String| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, m);
    let bytes = std::fs::read(wav.path()).map_err(|e| internal(format!("the sound's WAV: {e}")))?;
    let (rate, x) = vibroscope::files::read_wav_mono(wav.path())
        .map_err(|e| internal(format!("the sound's WAV: {e}")))?;
    let rate = f64::from(rate);
    // Bins up to half the frame rate, about 64 of them; windows overlap 3/4.
    let top = frame_rate.map_or(rate / 2.0, |f| (f / 2.0).min(rate / 2.0));
    let nfft = ((rate / top * 64.0).ceil() as usize)
        .next_power_of_two()
        .clamp(64, 1 << 16);
    let hop = (nfft / 4).max(1);
    let bin_hz = rate / nfft as f64;
    let bins = ((top / bin_hz).floor() as usize + 1).min(nfft / 2 + 1);
    let columns: Vec<Vec<f32>> = vibroscope::spectrum::stft(&x, nfft, hop)
        .iter()
        .map(|col| {
            col[..bins]
                .iter()
                .map(|c| (10.0 * c.norm_sqr().max(1e-30).log10()) as f32)
                .collect()
        })
        .collect();
    Ok(json!({
        "sample_rate_hz": report.sample_rate_hz,
        "samples": report.samples,
        "duration_s": report.samples as f64 / rate,
        "encoding": report.encoding,
        "notes": report.notes,
        "wav": format!("data:audio/wav;base64,{}", base64(&bytes)),
        "spectrogram": {
            "nfft": nfft,
            "hop_s": hop as f64 / rate,
            "bin_hz": bin_hz,
            "top_hz": top,
            "db": columns,
        },
    }))
}
