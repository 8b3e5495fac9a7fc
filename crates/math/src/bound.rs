//! The Cramér-Rao bound on sub-pixel motion, from the video itself.
//!
//! A region that moves rigidly by `d = (dx, dy)` shows
//! `I_t(p) = R(p - d) + n_t(p)`, with white Gaussian sensor noise of
//! variance σ². The Fisher information of `d` in one frame is
//! `F = Σ_p ∇R(p) ∇R(p)ᵀ / σ²`, so no unbiased estimator of `d` from one
//! frame has a smaller covariance than `F⁻¹`: the floor, in pixels RMS,
//! is `√(F⁻¹)_xx` along x and `√(F⁻¹)_yy` along y. A tone of amplitude `A`
//! px then has at best an SNR of `(A²/2) / (F⁻¹)_xx` per frame (a filter
//! to the signal's band gains the ratio of the Nyquist band to it).
//!
//! Both ingredients are estimated from the recording:
//!
//! - `R` is the mean of the first `reference_frames` frames; its gradient
//!   is the 7-tap central difference of the `displacement` stage. The
//!   reference's own noise (σ²/K per pixel) adds `σ²/K · Σk²` to every
//!   pixel's squared gradient (`Σk²` = 4214/3600 for these taps); that
//!   amount is subtracted.
//! - σ from each later frame's residual after the region's own
//!   least-squares motion is taken out (`I_t - R - ∇R·d_t`): the median of
//!   its absolute value over the region, × 1.4826 (a Gaussian's σ), over
//!   √(1 + 1/K) (the reference's noise is in the residual too); the median
//!   over frames. The median keeps edges and parts that move differently
//!   from dominating; quantisation (1/12 DN²) is part of the noise, as it is
//!   for any estimator.
//!
//! Pixels within 3 of the frame's edge are left out of a region. The bound
//! is for the whole region moving as one: on a region that is partly
//! static it is optimistic (the still part's texture counts as
//! information).

/// Frames averaged into the reference by default (as `displacement`).
pub const REFERENCE_FRAMES: usize = 16;

/// `Σ k²` of the 7-tap derivative `(45, -9, 1)/60` (both sides).
const DERIV_ENERGY: f64 = 2.0 * (45.0 * 45.0 + 9.0 * 9.0 + 1.0) / 3600.0;

/// Why a bound cannot be given.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BoundError {
    #[error("{frames} frames were read; the bound needs at least {need} ({reference} for the reference, then two to measure the noise)")]
    TooShort {
        frames: usize,
        need: usize,
        reference: usize,
    },
    #[error("region {region} ({x},{y},{w},{h}) {message}")]
    Region {
        region: usize,
        x: usize,
        y: usize,
        w: usize,
        h: usize,
        message: String,
    },
    #[error("frame of {got} pixels, expected {want}")]
    FrameSize { got: usize, want: usize },
}

/// The bound of one region.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RegionBound {
    /// `[x, y, w, h]` as asked.
    pub roi: [usize; 4],
    /// Pixels used (the region less the 3-pixel frame margin).
    pub pixels: usize,
    /// Sensor noise σ, DN (the image's units).
    pub noise_dn: f64,
    /// `Σ ∂R/∂x²`, `Σ ∂R/∂y²`, `Σ ∂R/∂x ∂R/∂y` over the region, DN²/px²
    /// (the reference's noise removed).
    pub gradient_energy: [f64; 3],
    /// The Cramér-Rao floor per frame, px RMS, along x and y.
    pub crb_px: [f64; 2],
    /// Frames the noise was measured on.
    pub noise_frames: usize,
}

impl RegionBound {
    /// The best per-frame SNR (dB) of a tone of `amplitude_px` along x
    /// (`axis` 0) or y (1).
    pub fn snr_db(&self, amplitude_px: f64, axis: usize) -> f64 {
        let var = self.crb_px[axis.min(1)].powi(2);
        10.0 * (amplitude_px * amplitude_px / 2.0 / var).log10()
    }
}

/// One region's running sums.
struct RegionAcc {
    roi: [usize; 4],
    /// The region's usable pixel indices (frame-linear).
    idx: Vec<usize>,
    sxx: f64,
    syy: f64,
    sxy: f64,
    sigmas: Vec<f64>,
}

/// Streams frames and gives the bound of each region at the end.
/// Allocates only when the reference is made and to keep one σ per frame.
pub struct BoundAccumulator {
    w: usize,
    h: usize,
    reference_frames: usize,
    frames: usize,
    mean: Vec<f64>,
    reference: Vec<f32>,
    gx: Vec<f32>,
    gy: Vec<f32>,
    resid: Vec<f32>,
    regions: Vec<RegionAcc>,
}

impl BoundAccumulator {
    /// For `w x h` frames, regions `rois` (`[x, y, w, h]`; none: the whole
    /// frame), the reference the mean of `reference_frames` frames.
    pub fn new(
        w: usize,
        h: usize,
        rois: &[[usize; 4]],
        reference_frames: usize,
    ) -> Result<Self, BoundError> {
        let whole = [[0, 0, w, h]];
        let rois = if rois.is_empty() { &whole[..] } else { rois };
        let mut regions = Vec::with_capacity(rois.len());
        for (k, &[x, y, rw, rh]) in rois.iter().enumerate() {
            let err = |message: String| BoundError::Region {
                region: k + 1,
                x,
                y,
                w: rw,
                h: rh,
                message,
            };
            if x.saturating_add(rw) > w || y.saturating_add(rh) > h || rw == 0 || rh == 0 {
                return Err(err(format!("is not inside the {w}x{h} frame")));
            }
            let mut idx = Vec::new();
            for yy in y.max(3)..(y + rh).min(h.saturating_sub(3)) {
                for xx in x.max(3)..(x + rw).min(w.saturating_sub(3)) {
                    idx.push(yy * w + xx);
                }
            }
            if idx.len() < 16 {
                return Err(err(format!(
                    "has {} pixels away from the frame's 3-pixel margin; the bound needs 16",
                    idx.len()
                )));
            }
            regions.push(RegionAcc {
                roi: [x, y, rw, rh],
                idx,
                sxx: 0.0,
                syy: 0.0,
                sxy: 0.0,
                sigmas: Vec::new(),
            });
        }
        let n = w * h;
        let longest = regions.iter().map(|r| r.idx.len()).max().unwrap_or(0);
        Ok(Self {
            w,
            h,
            reference_frames: reference_frames.max(1),
            frames: 0,
            mean: vec![0.0; n],
            reference: Vec::new(),
            gx: Vec::new(),
            gy: Vec::new(),
            resid: vec![0.0; longest],
            regions,
        })
    }

    /// Adds one frame (row-major, DN).
    pub fn push(&mut self, frame: &[f32]) -> Result<(), BoundError> {
        let n = self.w * self.h;
        if frame.len() != n {
            return Err(BoundError::FrameSize {
                got: frame.len(),
                want: n,
            });
        }
        self.frames += 1;
        if self.frames <= self.reference_frames {
            for (m, &v) in self.mean.iter_mut().zip(frame) {
                *m += f64::from(v);
            }
            if self.frames == self.reference_frames {
                self.make_reference();
            }
            return Ok(());
        }
        let k = 1.0 / self.reference_frames as f64;
        for r in &mut self.regions {
            // The region's own motion, by the 2x2 normal equations.
            let (mut bx, mut by) = (0.0f64, 0.0f64);
            for &i in &r.idx {
                let d = f64::from(frame[i] - self.reference[i]);
                bx += f64::from(self.gx[i]) * d;
                by += f64::from(self.gy[i]) * d;
            }
            let det = r.sxx * r.syy - r.sxy * r.sxy;
            let (ux, uy) = if det > 0.0 {
                (
                    (r.syy * bx - r.sxy * by) / det,
                    (r.sxx * by - r.sxy * bx) / det,
                )
            } else {
                (0.0, 0.0)
            };
            let res = &mut self.resid[..r.idx.len()];
            for (o, &i) in res.iter_mut().zip(&r.idx) {
                let pred = f64::from(self.gx[i]) * ux + f64::from(self.gy[i]) * uy;
                *o = (f64::from(frame[i] - self.reference[i]) - pred).abs() as f32;
            }
            let mid = res.len() / 2;
            let (_, m, _) = res.select_nth_unstable_by(mid, f32::total_cmp);
            r.sigmas.push(1.4826 * f64::from(*m) / (1.0 + k).sqrt());
        }
        Ok(())
    }

    fn make_reference(&mut self) {
        let k = self.reference_frames as f32;
        self.reference = self
            .mean
            .iter()
            .map(|&m| (m / f64::from(k)) as f32)
            .collect();
        let (w, n) = (self.w, self.w * self.h);
        self.gx = vec![0.0; n];
        self.gy = vec![0.0; n];
        let r = &self.reference;
        let d = |i: usize, s: usize| {
            let t = |j: usize| r[i + j * s] - r[i - j * s];
            (45.0 * t(1) - 9.0 * t(2) + t(3)) / 60.0
        };
        for reg in &mut self.regions {
            for &i in &reg.idx {
                let (x, y) = (d(i, 1), d(i, w));
                self.gx[i] = x;
                self.gy[i] = y;
                reg.sxx += f64::from(x * x);
                reg.syy += f64::from(y * y);
                reg.sxy += f64::from(x * y);
            }
        }
    }

    /// Frames seen so far.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// The bound of each region, in the order given.
    pub fn finish(&self) -> Result<Vec<RegionBound>, BoundError> {
        let need = self.reference_frames + 2;
        if self.frames < need {
            return Err(BoundError::TooShort {
                frames: self.frames,
                need,
                reference: self.reference_frames,
            });
        }
        let k = self.reference_frames as f64;
        let mut out = Vec::with_capacity(self.regions.len());
        for (j, r) in self.regions.iter().enumerate() {
            let [x, y, w, h] = r.roi;
            let err = |message: String| BoundError::Region {
                region: j + 1,
                x,
                y,
                w,
                h,
                message,
            };
            let mut s = r.sigmas.clone();
            let sigma = crate::numeric::median(&mut s);
            if sigma.is_nan() || sigma <= 0.0 {
                return Err(err(
                    "does not change between frames (no noise measured): a still image or repeated frames has no bound"
                        .into(),
                ));
            }
            let bias = r.idx.len() as f64 * sigma * sigma / k * DERIV_ENERGY;
            let (sxx, syy, sxy) = (r.sxx - bias, r.syy - bias, r.sxy);
            let det = sxx * syy - sxy * sxy;
            if !(sxx > 0.0 && syy > 0.0 && det > 1e-9 * sxx * syy) {
                return Err(err(format!(
                    "has no texture above the noise (gradient energy {:.1}, {:.1} DN²/px² after the noise's share): motion there has no bound",
                    sxx, syy
                )));
            }
            let s2 = sigma * sigma;
            out.push(RegionBound {
                roi: r.roi,
                pixels: r.idx.len(),
                noise_dn: sigma,
                gradient_energy: [sxx, syy, sxy],
                crb_px: [(s2 * syy / det).sqrt(), (s2 * sxx / det).sqrt()],
                noise_frames: r.sigmas.len(),
            });
        }
        Ok(out)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::rng::{Xoshiro256 as Rng, Ziggurat};

    /// Standard normal samples.
    struct Gauss(Rng, Ziggurat);

    impl Gauss {
        fn new(seed: u64) -> Self {
            Gauss(Rng::new(seed), Ziggurat::new())
        }
        fn next(&mut self) -> f64 {
            self.1.sample(&mut self.0)
        }
    }

    /// A smooth random texture (sum of sinusoids) displaced by `(dx, dy)`,
    /// with Gaussian noise `sigma`; its exact gradient energy.
    fn frame(w: usize, h: usize, dx: f64, dy: f64, sigma: f64, rng: &mut Gauss) -> Vec<f32> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64 - dx, (i / w) as f64 - dy);
                let v =
                    100.0 + 20.0 * (0.3 * x + 0.1 * y).sin() + 15.0 * (0.05 * x - 0.4 * y).cos();
                (v + sigma * rng.next()) as f32
            })
            .collect()
    }

    #[test]
    fn noise_and_floor_match_the_model() {
        let (w, h, sigma) = (80, 60, 1.5);
        let mut rng = Gauss::new(7);
        let mut acc = BoundAccumulator::new(w, h, &[], REFERENCE_FRAMES).unwrap();
        for t in 0..80 {
            let d = 0.05 * (t as f64 * 0.7).sin();
            acc.push(&frame(w, h, d, 0.5 * d, sigma, &mut rng)).unwrap();
        }
        let b = &acc.finish().unwrap()[0];
        // The exact gradients of the texture over the same pixels.
        let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
        for y in 3..h - 3 {
            for x in 3..w - 3 {
                let (x, y) = (x as f64, y as f64);
                let gx = 20.0 * 0.3 * (0.3 * x + 0.1 * y).cos()
                    - 15.0 * 0.05 * (0.05 * x - 0.4 * y).sin();
                let gy = 20.0 * 0.1 * (0.3 * x + 0.1 * y).cos()
                    + 15.0 * 0.4 * (0.05 * x - 0.4 * y).sin();
                sxx += gx * gx;
                syy += gy * gy;
                sxy += gx * gy;
            }
        }
        let det = sxx * syy - sxy * sxy;
        let crb_x = (sigma * sigma * syy / det).sqrt();
        eprintln!(
            "noise {:.4} (true {sigma}), crb x {:.5} px (true {crb_x:.5}), energy {:.0} vs {sxx:.0}",
            b.noise_dn, b.crb_px[0], b.gradient_energy[0]
        );
        assert!((b.noise_dn / sigma - 1.0).abs() < 0.05);
        assert!((b.gradient_energy[0] / sxx - 1.0).abs() < 0.03);
        assert!((b.crb_px[0] / crb_x - 1.0).abs() < 0.05);
    }

    #[test]
    fn still_or_flat_or_short_input_is_refused() {
        let (w, h) = (32, 32);
        let mut rng = Gauss::new(1);
        let still = frame(w, h, 0.0, 0.0, 0.0, &mut rng);
        let mut acc = BoundAccumulator::new(w, h, &[], 4).unwrap();
        for _ in 0..10 {
            acc.push(&still).unwrap();
        }
        assert!(matches!(acc.finish(), Err(BoundError::Region { .. })));
        let mut acc = BoundAccumulator::new(w, h, &[], 4).unwrap();
        for _ in 0..10 {
            let flat: Vec<f32> = (0..w * h).map(|_| (50.0 + rng.next()) as f32).collect();
            acc.push(&flat).unwrap();
        }
        let e = acc.finish().unwrap_err().to_string();
        assert!(e.contains("no texture"), "{e}");
        let mut acc = BoundAccumulator::new(w, h, &[], 4).unwrap();
        acc.push(&still).unwrap();
        assert!(matches!(acc.finish(), Err(BoundError::TooShort { .. })));
        assert!(BoundAccumulator::new(w, h, &[[30, 0, 8, 8]], 4).is_err());
        assert!(BoundAccumulator::new(w, h, &[[0, 0, 4, 4]], 4).is_err());
    }
}
