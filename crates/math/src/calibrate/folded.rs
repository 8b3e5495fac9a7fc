//! How a stored transfer table is applied to a new recording (`listen
//! --calibration`; issue 50, session 75): a Wiener inverse against what
//! folds into each bin from above the Nyquist frequency, not the table's
//! plain inverse.
//!
//! A camera samples the object's motion once a frame. What the recovery
//! holds at `f` is the object's motion at `f`, which the object's response
//! `H(f)` shaped and the table measured, plus the motion at `fs - f`,
//! `fs + f`, … folded onto it, which the object's response *there* shaped
//! (above the Nyquist frequency: no reference the camera can see measures
//! it). Where the object dips, the plain inverse `1/H(f)` boosts both:
//! the folded part by as much as the object's own. The protocol's dips
//! near the top of the band showed it (issue 50, session 75): on
//! `dip_at_875` the table matches the object's response within 0.5 dB
//! over 700-850 Hz, yet the object's exact inverse gains the speech 0.6 dB
//! where a fixed filter fitted by an oracle gains 6.3; the speech's
//! content at 1325 Hz, folded onto 875 Hz, outweighs its own there.
//!
//! The Wiener inverse for signal power `S(f)` and folded power `A(f)` that
//! passes through a response `H'` is `(H* S + H'* A) / (|H|² S + |H'|² A)`.
//! `H'` is not measured: taken as the table's median gain (relative 1).
//! `S` and `A` come from the new recording itself: its spectrum, as the
//! table corrects it, fitted as an exponential in frequency over the
//! band's middle ([`FIT_FROM`] to [`FIT_TO`] of the Nyquist frequency)
//! and extrapolated to the images `m fs ± f` ([`IMAGES`] of each sign),
//! no further above the Nyquist frequency than that band is wide (in
//! full to half its width). A trend that does not fall is taken as the
//! noise's, and the plain inverse applies. The extrapolation is checked
//! against the recording's top ([`TOP`] of the Nyquist frequency to it),
//! where the recovery holds `S(f) + A(f)` with `f` and `fs - f` close:
//! the folded part is scaled by the share of the model the recording
//! holds there over [`FULL_AT`], at most 1. A recording with nothing
//! above some frequency below the Nyquist frequency (a sweep that stops
//! short of it) holds little there and keeps the plain inverse. Where the
//! object's response is the median, the correction is the plain one.

use super::correction::Correction;
use super::signal::{equalize, stft_len, welch};
use crate::numeric::median;
use realfft::num_complex::Complex;

/// The band, as fractions of the Nyquist frequency, over which a new
/// recording's spectrum is fitted (its low end at least the table's
/// first measured row).
const FIT_FROM: f64 = 0.2;
const FIT_TO: f64 = 0.7;
/// From this fraction of the Nyquist frequency up to it, the recording's
/// spectrum checks the extrapolation.
const TOP: f64 = 0.9;
/// The share of the extrapolated model that the recording's top must
/// hold for the folded part to be taken at the model's full level; under
/// it, in proportion. A recording whose content stops short of the
/// Nyquist frequency holds its noise there, orders of magnitude under the
/// trend; one whose content goes on holds the trend give or take what
/// the object's response (unmeasured there, taken as the median) and the
/// trend's curvature do to it.
const FULL_AT: f64 = 0.25;
/// Images of each sign summed (`m fs ± f`, `m = 1..=IMAGES`).
const IMAGES: usize = 3;

/// What [`apply`] found on a recording, for its note.
#[derive(Clone, Debug, PartialEq)]
pub struct Folding {
    /// The band (Hz) the spectrum was fitted over.
    pub fit_hz: [f64; 2],
    /// The fitted trend, dB per kHz (below zero).
    pub slope_db_per_khz: f64,
    /// The share of the extrapolated model the recording holds at its
    /// top (at most 1).
    pub share_at_top: f64,
    /// Where the Wiener inverse departs most from the plain one: the
    /// frequency (Hz), and the plain inverse's and the Wiener inverse's
    /// gain there (dB, relative to the table's median gain).
    pub most_at_hz: f64,
    pub plain_db: f64,
    pub wiener_db: f64,
}

/// The transfer table `c` applied to the recovery `z` (at `fs`) as a
/// Wiener inverse against folded content (the module's doc), and what it
/// found; `None` for any other correction, a recording too short to fit
/// (under two STFT lengths, or under four bins to fit), or one whose
/// spectrum does not fall over the band's middle, which then takes the
/// plain inverse ([`Correction::apply`]).
pub fn apply(c: &Correction, z: &[f64], fs: f64) -> Option<(Vec<f64>, Folding)> {
    let Correction::Transfer {
        coef_db,
        k,
        measured_hz: [lo, _],
        ..
    } = c
    else {
        return None;
    };
    let nfft = stft_len(fs);
    if z.len() < 2 * nfft || coef_db.is_empty() || fs.is_nan() || fs <= 0.0 {
        return None;
    }
    let nyq = fs / 2.0;
    let df = fs / nfft as f64;
    let p = welch(z, nfft);
    let plain: Vec<Complex<f64>> = (0..p.len())
        .map(|b| c.response(b as f64 * df).unwrap_or(Complex::new(1.0, 0.0)))
        .collect();
    // The recording as the table corrects it.
    let s: Vec<f64> = p
        .iter()
        .zip(&plain)
        .map(|(p, r)| p * r.norm_sqr())
        .collect();
    let fit_hz = [lo.max(FIT_FROM * nyq), FIT_TO * nyq];
    let pts: Vec<(f64, f64)> = (0..s.len())
        .map(|b| (b as f64 * df, s[b]))
        .filter(|&(f, v)| f >= fit_hz[0] && f <= fit_hz[1] && v > 0.0 && v.is_finite())
        .map(|(f, v)| (f, v.ln()))
        .collect();
    if pts.len() < 4 {
        return None;
    }
    let (mf, mv, slope) = crate::numeric::line_fit(&pts)?;
    // A spectrum that does not fall over the band's middle is taken as
    // the noise's (a recovery near its noise floor, or speech that left
    // little above it), not a signal's whose trend goes on above the
    // Nyquist frequency: noise does not pass through the object's
    // response, and a Wiener weighting against it would cut the boosts
    // the table needs (issue 50, session 75: on `table_4_2_equalised_speech`
    // two of six noisy sentences fitted a flat or rising trend, and the
    // folding model took the table's +9.9 dB at 180 Hz to +0.7).
    if slope.is_nan() || slope >= 0.0 {
        return None;
    }
    // The trend relative to its level at the fit's centre (`exp(mv)`),
    // so that nothing overflows or underflows.
    let ext = |f: f64| (slope * (f - mf)).exp();
    // The trend is carried above the Nyquist frequency no further than
    // the band it was fitted over is wide: in full up to half that width
    // above it, then less, to nothing at the whole width. A recording's
    // spectrum can fall faster above the band it was fitted on (a sound
    // low-passed, an exposure's boxcar), and an image far above it is a
    // guess (issue 50, session 75: without this, two noisy sentences of
    // `table_4_2_equalised_speech` on the simulator's seeds 7 and 99 lost
    // their gain, +0.74 -> -0.06 and +0.98 -> -0.05 dB: the trend carried
    // to 2 kHz took the table's boost at 180 Hz for folded speech).
    let span = fit_hz[1] - fit_hz[0];
    let reach = |image: f64| ((nyq + span - image) / (0.5 * span)).clamp(0.0, 1.0);
    let folded = |f: f64| -> f64 {
        (1..=IMAGES)
            .flat_map(|m| [m as f64 * fs - f, m as f64 * fs + f])
            .map(|image| reach(image) * ext(image))
            .sum()
    };
    let (held, model) = (0..s.len())
        .map(|b| b as f64 * df)
        .zip(&s)
        .filter(|(f, _)| *f >= TOP * nyq && *f <= nyq)
        .fold((0.0, 0.0), |(h, m), (f, v)| (h + v, m + ext(f) + folded(f)));
    let share = if model > 0.0 && held > 0.0 && held.is_finite() {
        ((held.ln() - mv - model.ln()).exp() / FULL_AT).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut rows = coef_db.clone();
    let med = median(&mut rows);
    let unit = super::correction::transfer_gain(*k, med);
    let mut most = (0.0, 0.0, 0.0, 0.0);
    let gains: Vec<Complex<f64>> = plain
        .iter()
        .enumerate()
        .map(|(b, &r)| {
            let f = b as f64 * df;
            if r.norm() == 0.0 || !r.is_finite() {
                return r;
            }
            // The object's response relative to the table's median.
            let h = Complex::new(unit, 0.0) / r;
            let w = share * folded(f) / ext(f);
            let g = (h.conj() + w) / (h.norm_sqr() + w) * unit;
            let (pd, wd) = (
                20.0 * (r.norm() / unit).log10(),
                20.0 * (g.norm() / unit).log10(),
            );
            if (pd - wd).abs() > most.0 {
                most = ((pd - wd).abs(), f, pd, wd);
            }
            if g.is_finite() {
                g
            } else {
                r
            }
        })
        .collect();
    let out = equalize(z, fs, |f| {
        gains[((f / df).round() as usize).min(gains.len() - 1)]
    });
    Some((
        out,
        Folding {
            fit_hz,
            slope_db_per_khz: slope * 1000.0 * 10.0 / std::f64::consts::LN_10,
            share_at_top: share,
            most_at_hz: most.1,
            plain_db: most.2,
            wiener_db: most.3,
        },
    ))
}

impl Folding {
    /// In words, for `listen --calibration`'s notes.
    pub fn note(&self, fs: f64) -> String {
        format!(
            "transfer_function applied as a Wiener inverse against what folds into the band from above the Nyquist frequency ({:.0} Hz), which the object's response there shaped and no reference measured (taken as the table's median gain): this recording's spectrum, as the table corrects it, falls {:.1} dB per kHz over {:.0}-{:.0} Hz, and extrapolated above the Nyquist frequency it is scaled by {:.2} to what the recording holds at its top; the table's correction departs most from its plain inverse at {:.0} Hz ({:+.1} dB against the table's median gain instead of {:+.1})",
            fs / 2.0,
            -self.slope_db_per_khz,
            self.fit_hz[0],
            self.fit_hz[1],
            self.share_at_top,
            self.most_at_hz,
            self.wiener_db,
            self.plain_db
        )
    }
}
