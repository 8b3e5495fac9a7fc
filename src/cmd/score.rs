//! `vibroscope score`.

use std::path::PathBuf;
use std::process::ExitCode;

/// Score a recovered sound against the reference (SNR, segmental SNR, LLR, STOI).
///
/// Score a recovered signal against the reference sound: SNR, segmental
/// SNR (Hansen & Pellom), LLR and STOI (Taal et al. 2011), printed as JSON,
/// after finding the best lag and gain (a recovery's scale and sign are
/// arbitrary). The test is resampled to the reference's rate when they
/// differ.
///
/// `wiener_bound_db` is the SNR the best fixed filter would reach on the
/// test: a stationary Wiener filter built from the test's true signal and
/// noise spectra (which only a known reference gives). Score a recovery
/// before denoising to get the bound, then its denoised version to see how
/// far a denoiser is from it (`listen --denoise wiener` adapts to speech's
/// changing spectrum and can exceed it).
#[derive(clap::Args)]
#[command(after_help = "Example:\n  vibroscope score speech.wav recovered.wav --json score.json")]
pub struct Args {
    /// The reference sound (WAV, first channel).
    reference: PathBuf,
    /// The recovered sound (WAV, first channel).
    test: PathBuf,
    /// Largest lag searched, in seconds.
    #[arg(long, default_value_t = 0.5, value_name = "S")]
    max_lag_s: f64,
    /// Also write the scores as JSON to this file.
    #[arg(long, value_name = "OUT.json")]
    json: Option<PathBuf>,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    super::check_json(&[&a.reference, &a.test], a.json.as_deref())?;
    let r = vibroscope::score::score(&a.reference, &a.test, a.max_lag_s)?;
    let text = serde_json::to_string_pretty(&r)?;
    super::outln!("{text}");
    eprintln!(
        "SNR {} dB (a fixed Wiener filter would reach {} dB), segmental SNR {} dB, LLR {}, STOI {} (lag {} samples at {} Hz)",
        super::num(r.snr_db, 2),
        super::num(r.wiener_bound_db, 2),
        super::num(r.ssnr_db, 2),
        super::num(r.llr, 3),
        super::num(r.stoi, 3),
        r.lag_samples,
        r.sample_rate_hz
    );
    for n in &r.notes {
        eprintln!("note: {n}");
    }
    if let Some(p) = &a.json {
        vibroscope::files::write_atomic(p, (text + "\n").as_bytes())?;
        super::wrote(p);
    }
    Ok(ExitCode::SUCCESS)
}
