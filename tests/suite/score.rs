//! `vibroscope score` finds the lag and gain, resamples when rates differ,
//! and prints the four metrics as JSON.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common::*;

#[test]
fn score_undoes_delay_sign_and_gain() {
    let dir = tempfile::tempdir().unwrap();
    // A speech-like test signal: a few harmonics with a slow envelope.
    let fs = 16000u32;
    let x: Vec<f32> = (0..fs * 2)
        .map(|n| {
            let t = n as f32 / fs as f32;
            let env = 0.5 + 0.5 * (2.0 * std::f32::consts::PI * 3.0 * t).sin();
            env * (1..6)
                .map(|k| (2.0 * std::f32::consts::PI * 180.0 * k as f32 * t).sin() / k as f32)
                .sum::<f32>()
        })
        .collect();
    let mut y = vec![0.0f32; 120];
    y.extend(x.iter().map(|v| -0.3 * v));
    y.truncate(x.len());
    write_wav_f32(&dir.path().join("ref.wav"), fs, &x);
    write_wav_f32(&dir.path().join("test.wav"), fs, &y);
    let o = run_in(dir.path(), &["score", "ref.wav", "test.wav"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["lag_samples"].as_i64(), Some(120), "{v}");
    assert!((v["gain"].as_f64().unwrap() + 0.3).abs() < 1e-3, "{v}");
    assert!(v["snr_db"].as_f64().unwrap() > 60.0, "{v}");
    assert!(v["stoi"].as_f64().unwrap() > 0.99, "{v}");
    // Missing file: runtime error naming it.
    let o = run_in(dir.path(), &["score", "ref.wav", "nope.wav"]);
    assert_eq!(code(&o), 1);
    assert!(stderr(&o).contains("nope.wav"), "{}", stderr(&o));
}

#[test]
fn score_reproduces_published_stoi_through_the_cli() {
    let (Some(clean), Some(noisy)) = (
        shared_data("speech-metrics/1_speech_16000_Hz.wav"),
        shared_data("speech-metrics/1_noisySpeech_16000_Hz.wav"),
    ) else {
        return;
    };
    let o = run_in(
        std::path::Path::new("."),
        &["score", clean.to_str().unwrap(), noisy.to_str().unwrap()],
    );
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    // The files are aligned: lag 0. STOI is scale-invariant, so the gain
    // correction leaves the published 0.8389 unchanged.
    assert_eq!(v["lag_samples"].as_i64(), Some(0), "{v}");
    assert!((v["stoi"].as_f64().unwrap() - 0.8389).abs() < 0.005, "{v}");
}
