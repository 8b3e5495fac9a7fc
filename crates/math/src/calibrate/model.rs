//! The plain linear model `y ≈ g T` (delay and gain) on a recovery, the
//! split into fit and held-out parts, and the errors on the held-out part.

use super::signal::{gain_sse, golden, redo_highpass, sample_at, stft, stft_len};
use super::{Correction, Errors, Options};
use crate::metrics;

pub(super) struct Model<'a> {
    pub(super) r: &'a [f64],
    pub(super) fr: f64,
    pub(super) fs: f64,
    pub(super) opts: &'a Options,
    /// The STFT bins where the gain a sweep measures holds only at its
    /// level, each with its harmonics-to-fundamental ratio (dB) and the
    /// gain error that implies over the band's median (dB), read once on
    /// the recording as recovered (the transfer family's
    /// `level_dependent`):
    /// the transfer table leaves them out and the residual's report names
    /// them.
    pub(super) level: &'a [(usize, f64, f64)],
    /// The samples where the sweep stood in [`Model::level`]'s bins (one
    /// flag per sample of the recording; shorter means the rest are not
    /// left out): left out of every fit and of the held-out score, since
    /// what the object did there held only at the sweep's level and no
    /// linear effect measured there (a clock error that reads a
    /// compressed resonance's phase as a lag moving with time, a gain)
    /// carries to a recording at another.
    pub(super) skip: &'a [bool],
    /// The object's static response, where it stops rising within the
    /// sweep, read once on the recording as recovered (the polynomial
    /// family's `fold`): the residual's report names it.
    pub(super) fold: Option<&'a Fold>,
}

/// A static response that stops rising within the sweep (the polynomial family's `fold`).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Fold {
    /// Where its slope first turns, as a share of the sweep's peak motion
    /// (signed: the side it turns on).
    pub(super) at: f64,
    /// The response `u + c2 u² + …` with `u` the motion over the sweep's
    /// peak: `[c2, …]`.
    pub(super) response: Vec<f64>,
    /// How much less the cross-validated error is than that of the best
    /// response that rises (dB).
    pub(super) better_db: f64,
}

/// The linear model on a recovery.
#[derive(Clone, Debug)]
pub(super) struct Fit {
    pub(super) tau: f64,
    pub(super) g: f64,
    /// The target at `tau` for every sample of the recovery.
    pub(super) t: Vec<f64>,
}

impl Model<'_> {
    /// `T[n]` for `n` in `-pre..len`: reference at `n / (fs (1 + ppm)) - tau`,
    /// high-passed from `n = -pre`.
    pub(super) fn target(&self, len: usize, pre: usize, tau: f64, ppm: f64) -> Vec<f64> {
        self.target_about(len, pre, tau, ppm, 0.0)
    }

    /// [`Model::target`] with the rate error applied about sample `centre`
    /// (which stays at `centre / fs - tau`).
    pub(super) fn target_about(
        &self,
        len: usize,
        pre: usize,
        tau: f64,
        ppm: f64,
        centre: f64,
    ) -> Vec<f64> {
        let rate = self.fs * (1.0 + ppm * 1e-6);
        let c = centre / self.fs;
        let t = sample_at(
            self.r,
            self.fr,
            (0..len + pre).map(|i| (i as f64 - pre as f64 - centre) / rate + c - tau),
        );
        redo_highpass(&t, self.fs, self.opts.highpass)
    }

    /// The reference at `n / fs - tau` for `n` in `0..len`, not high-passed.
    pub(super) fn unfiltered_target(&self, len: usize, tau: f64) -> Vec<f64> {
        sample_at(self.r, self.fr, (0..len).map(|i| i as f64 / self.fs - tau))
    }

    /// Whether sample `i` is in the fit part: blocks of one STFT length
    /// (about 0.1 s), blocks 0, 2 and 4 of every five fitted, 1 and 3 held
    /// out (60% / 40%, interleaved, so both parts see every frequency of a
    /// sweep and every stretch of a drift).
    pub(super) fn is_fit(&self, i: usize) -> bool {
        !self.held_block(i) && !self.skipped(i)
    }

    /// Whether sample `i` is in the held-out part (neither fitted nor
    /// left out).
    pub(super) fn is_held(&self, i: usize) -> bool {
        self.held_block(i) && !self.skipped(i)
    }

    /// Whether sample `i` lies in a held-out block (1 or 3 of every five).
    fn held_block(&self, i: usize) -> bool {
        matches!((i / stft_len(self.fs)) % 5, 1 | 3)
    }

    /// Whether sample `i` is left out of every fit and score
    /// ([`Model::skip`]).
    pub(super) fn skipped(&self, i: usize) -> bool {
        self.skip.get(i).copied().unwrap_or(false)
    }

    /// The fit part of `0..len`, one range per block (the units a
    /// jackknife deletes, long enough that a coloured residual stays
    /// mostly within one): the blocks that are fitted, each with the
    /// samples [`Model::skip`] leaves out still in it (test [`Model::is_fit`]).
    pub(super) fn fit_blocks(&self, len: usize) -> Vec<std::ops::Range<usize>> {
        let b = stft_len(self.fs);
        (0..len.div_ceil(b))
            .map(|k| k * b..((k + 1) * b).min(len))
            .filter(|r| r.clone().any(|i| self.is_fit(i)))
            .collect()
    }

    /// `x` with the held-out samples set to zero.
    pub(super) fn masked(&self, x: &[f64]) -> Vec<f64> {
        x.iter()
            .enumerate()
            .map(|(i, &v)| if self.is_fit(i) { v } else { 0.0 })
            .collect()
    }

    /// The held-out samples of `x`, in order.
    pub(super) fn held(&self, x: &[f64]) -> Vec<f64> {
        x.iter()
            .enumerate()
            .filter(|(i, _)| self.is_held(*i))
            .map(|(_, &v)| v)
            .collect()
    }

    /// Number of fit samples among the first `len`.
    pub(super) fn nfit(&self, len: usize) -> usize {
        (0..len).filter(|&i| self.is_fit(i)).count().max(1)
    }

    /// Delay (integer by cross-correlation, then fractional by golden
    /// section) and gain, on the fit part.
    pub(super) fn fit_linear(&self, z: &[f64]) -> Fit {
        let n = z.len();
        let zm = self.masked(z);
        let t0 = self.target(n, 0, 0.0, 0.0);
        let max_lag = (self.opts.max_lag_s * self.fs).round() as usize;
        let (lag, _) = metrics::best_lag_gain(&t0, &zm, max_lag.min(n / 2));
        let sse = |tau: f64| gain_sse(&self.masked(&self.target(n, 0, tau, 0.0)), &zm).1;
        let c = lag as f64 / self.fs;
        let (tau, _) = golden(sse, c - 1.0 / self.fs, c + 1.0 / self.fs, 24);
        let t = self.target(z.len(), 0, tau, 0.0);
        let (g, _) = gain_sse(&self.masked(&t), &zm);
        Fit { tau, g, t }
    }

    pub(super) fn errors(&self, z: &[f64], fit: &Fit) -> Errors {
        let g = if fit.g != 0.0 { fit.g } else { 1.0 };
        let zh: Vec<f64> = self.held(z).iter().map(|v| v / g).collect();
        let t = &self.held(&fit.t);
        Errors {
            snr_db: metrics::snr_db(t, &zh),
            ssnr_db: metrics::segmental_snr_db(t, &zh, self.fs),
            lsd_db: self.lsd_db(t, &zh),
        }
    }

    /// Log-spectral distance: RMS of the dB difference over the bins above
    /// the high-pass cutoff where the target is within 40 dB of its peak in
    /// that frame, averaged over frames where the target has energy (within
    /// 40 dB of its loudest frame).
    pub(super) fn lsd_db(&self, t: &[f64], z: &[f64]) -> f64 {
        let nfft = stft_len(self.fs)
            .min(t.len().max(2).next_power_of_two() / 2)
            .max(16);
        let (ft, fz) = (stft(t, nfft), stft(z, nfft));
        let lo = self
            .opts
            .highpass
            .map_or(1, |(_, c)| (c * nfft as f64 / self.fs).ceil() as usize + 1);
        let e: Vec<f64> = ft
            .iter()
            .map(|f| f.iter().map(|c| c.norm_sqr()).sum())
            .collect();
        let emax = e.iter().cloned().fold(0.0, f64::max);
        let pmax = ft
            .iter()
            .flat_map(|f| f.iter().map(|c| c.norm_sqr()))
            .fold(0.0, f64::max);
        let floor = pmax * 1e-6 + 1e-300;
        let mut acc = 0.0;
        let mut count = 0usize;
        for (i, (a, b)) in ft.iter().zip(&fz).enumerate() {
            if e[i] < emax * 1e-4 || a.len() <= lo {
                continue;
            }
            let peak = a[lo..].iter().map(|c| c.norm_sqr()).fold(0.0, f64::max);
            let (mut d, mut bins) = (0.0, 0usize);
            for (x, y) in a[lo..].iter().zip(&b[lo..]) {
                if x.norm_sqr() < 1e-4 * peak {
                    continue;
                }
                let v = 10.0 * ((x.norm_sqr() + floor) / (y.norm_sqr() + floor)).log10();
                d += v * v;
                bins += 1;
            }
            if bins > 0 {
                acc += (d / bins as f64).sqrt();
                count += 1;
            }
        }
        if count == 0 {
            f64::NAN
        } else {
            acc / count as f64
        }
    }
}

/// Fit-part squared error after a zero-phase equaliser, gain refitted.
pub(super) fn eq_sse(m: &Model, z: &[f64], fit: &Fit, c: &Correction) -> f64 {
    let y = c.apply(z, m.fs);
    gain_sse(&m.masked(&fit.t), &m.masked(&y)).1
}
