//! One motion sample per image row: 1-D local phase along x (thesis
//! ch. 4.5, Eq. 4.4: fronto-parallel horizontal motion, row y of frame n
//! shows B(x - α s(nT + y d), y)).
//!
//! Each row is filtered by complex Gabor filters (one per wavelength, so one
//! per scale) along x. Against a reference row (the same row of a reference
//! frame), the phase change at pixel x is Δφ(x) ≈ -ω(x) u, where ω(x) is
//! the local spatial frequency (the reference phase's x-derivative) and u
//! the row's displacement in pixels. The weighted least-squares estimate
//! over pixels and scales, with the weights A² of Eq. 3.3 (the reference
//! amplitude squared; phase noise variance goes as 1/A²), is
//!
//! ```text
//! u = - Σ A² ω Δφ / Σ A² ω²
//! ```
//!
//! so every row is in pixels whatever its texture: rows of different
//! contrast give the same gain, and the frame-periodic pattern a per-row
//! gain would add (harmonics of the frame rate) does not arise. Pixels whose
//! local frequency is not positive (phase singularities) get no weight.
//!
//! Memory is allocated in [`RowPhase::new`]; the per-row calls allocate nothing.

use super::fastmath::atan2;

/// Largest accepted Gabor wavelength, px.
pub const MAX_WAVELENGTH_PX: f64 = 1024.0;
/// Smallest accepted Gabor wavelength, px (below ~2.5 px the filter aliases).
pub const MIN_WAVELENGTH_PX: f64 = 2.5;

struct Gabor {
    re: Vec<f32>,
    im: Vec<f32>,
    radius: usize,
    /// Pixels `[lo, hi)` with a full support and both gradient neighbours.
    lo: usize,
    hi: usize,
    /// Offset of this scale's per-row block in the reference arrays.
    offset: usize,
}

/// Per-row local phase motion estimator for rows of a fixed width.
pub struct RowPhase {
    width: usize,
    rows: usize,
    filters: Vec<Gabor>,
    /// Sum over scales of the valid pixel counts (per-row stride).
    stride: usize,
    /// conj(c0) / |c0| of the reference, per row, scale and pixel.
    ref_re: Vec<f32>,
    ref_im: Vec<f32>,
    /// A0² ω per row, scale and pixel (0 where ω <= 0).
    weight: Vec<f32>,
    /// Σ A0² ω² per row.
    den: Vec<f64>,
    resp_re: Vec<f32>,
    resp_im: Vec<f32>,
}

/// Why [`RowPhase::new`] refused its geometry.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RowPhaseError {
    #[error("columns {x0}..{x1} do not fit a row of {width} px")]
    Columns { x0: usize, x1: usize, width: usize },
    #[error("at least one wavelength is needed")]
    NoWavelength,
    #[error("wavelength {0} px is outside {MIN_WAVELENGTH_PX}..={MAX_WAVELENGTH_PX}")]
    Wavelength(f64),
    #[error(
        "the region is {width} px wide; wavelength {wavelength} px needs more than {needed} px"
    )]
    TooNarrow {
        width: usize,
        wavelength: f64,
        needed: usize,
    },
}

impl RowPhase {
    /// Rows of `width` pixels, columns `[x0, x1)` used, `rows` rows, one
    /// Gabor filter per wavelength (σ = wavelength / 2, about one octave of
    /// bandwidth; zero response at DC).
    pub fn new(
        width: usize,
        x0: usize,
        x1: usize,
        rows: usize,
        wavelengths_px: &[f64],
    ) -> Result<Self, RowPhaseError> {
        if x1 > width || x0 >= x1 {
            return Err(RowPhaseError::Columns { x0, x1, width });
        }
        if wavelengths_px.is_empty() {
            return Err(RowPhaseError::NoWavelength);
        }
        let mut filters = Vec::with_capacity(wavelengths_px.len());
        let mut stride = 0;
        for &lambda in wavelengths_px {
            if !(MIN_WAVELENGTH_PX..=MAX_WAVELENGTH_PX).contains(&lambda) {
                return Err(RowPhaseError::Wavelength(lambda));
            }
            let sigma = 0.5 * lambda;
            let radius = (3.0 * sigma).ceil() as usize;
            let omega = 2.0 * std::f64::consts::PI / lambda;
            let env: Vec<f64> = (0..=2 * radius)
                .map(|k| {
                    let d = k as f64 - radius as f64;
                    (-d * d / (2.0 * sigma * sigma)).exp()
                })
                .collect();
            let mut re: Vec<f64> = env
                .iter()
                .enumerate()
                .map(|(k, e)| e * (omega * (k as f64 - radius as f64)).cos())
                .collect();
            // The taps are correlated with the row, so exp(-iωk) makes the
            // response of cos(ωx) turn as exp(+iωx): positive local frequency.
            // Remove the DC response so brightness offsets carry no phase.
            let dc = re.iter().sum::<f64>() / env.iter().sum::<f64>();
            re.iter_mut().zip(&env).for_each(|(r, e)| *r -= dc * e);
            let im: Vec<f64> = env
                .iter()
                .enumerate()
                .map(|(k, e)| -e * (omega * (k as f64 - radius as f64)).sin())
                .collect();
            let lo = x0 + radius + 1;
            let hi = x1.saturating_sub(radius + 1);
            if hi <= lo {
                return Err(RowPhaseError::TooNarrow {
                    width: x1 - x0,
                    wavelength: lambda,
                    needed: 2 * radius + 2,
                });
            }
            filters.push(Gabor {
                re: re.iter().map(|&v| v as f32).collect(),
                im: im.iter().map(|&v| v as f32).collect(),
                radius,
                lo,
                hi,
                offset: stride,
            });
            stride += hi - lo;
        }
        Ok(Self {
            width,
            rows,
            stride,
            ref_re: vec![0.0; rows * stride],
            ref_im: vec![0.0; rows * stride],
            weight: vec![0.0; rows * stride],
            den: vec![0.0; rows],
            resp_re: vec![0.0; width],
            resp_im: vec![0.0; width],
            filters,
        })
    }

    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Complex response of filter `g` at pixels `[lo, hi)` into the scratch.
    fn respond(g: &Gabor, line: &[f32], lo: usize, hi: usize, re: &mut [f32], im: &mut [f32]) {
        let n = g.re.len();
        for x in lo..hi {
            let src = &line[x - g.radius..x - g.radius + n];
            let (mut a, mut b) = (0.0f32, 0.0f32);
            for ((s, fr), fi) in src.iter().zip(&g.re).zip(&g.im) {
                a += fr * s;
                b += fi * s;
            }
            re[x] = a;
            im[x] = b;
        }
    }

    /// Records `line` as the reference of row `row`. Returns Σ A² ω² of the
    /// row (0: no usable texture; the row's displacement will read 0).
    pub fn set_reference(&mut self, row: usize, line: &[f32]) -> f64 {
        assert!(
            row < self.rows && line.len() >= self.width,
            "row {row} out of range"
        );
        let mut den = 0.0f64;
        for g in &self.filters {
            let (re, im) = (&mut self.resp_re, &mut self.resp_im);
            Self::respond(g, line, g.lo - 1, g.hi + 1, re, im);
            let base = row * self.stride + g.offset;
            for x in g.lo..g.hi {
                let (cr, ci) = (re[x], im[x]);
                let a2 = cr * cr + ci * ci;
                // ω = arg(c(x+1) conj(c(x-1))) / 2, the phase slope.
                let zr = re[x + 1] * re[x - 1] + im[x + 1] * im[x - 1];
                let zi = im[x + 1] * re[x - 1] - re[x + 1] * im[x - 1];
                let omega = 0.5 * atan2(zi, zr);
                let i = base + x - g.lo;
                let a = a2.sqrt();
                if a > 0.0 && omega > 0.0 {
                    self.ref_re[i] = cr / a;
                    self.ref_im[i] = -ci / a;
                    self.weight[i] = a2 * omega;
                    den += (a2 * omega * omega) as f64;
                } else {
                    self.ref_re[i] = 0.0;
                    self.ref_im[i] = 0.0;
                    self.weight[i] = 0.0;
                }
            }
        }
        self.den[row] = den;
        den
    }

    /// Displacement of row `row` (px, positive rightwards) relative to its reference.
    pub fn displacement(&mut self, row: usize, line: &[f32]) -> f64 {
        assert!(
            row < self.rows && line.len() >= self.width,
            "row {row} out of range"
        );
        let den = self.den[row];
        if den <= 0.0 {
            return 0.0;
        }
        let mut num = 0.0f64;
        for g in &self.filters {
            let (re, im) = (&mut self.resp_re, &mut self.resp_im);
            Self::respond(g, line, g.lo, g.hi, re, im);
            let base = row * self.stride + g.offset;
            let n = g.hi - g.lo;
            let (rr, ri, w) = (
                &self.ref_re[base..base + n],
                &self.ref_im[base..base + n],
                &self.weight[base..base + n],
            );
            let mut acc = 0.0f32;
            for ((((&cr, &ci), &qr), &qi), &wt) in re[g.lo..g.hi]
                .iter()
                .zip(&im[g.lo..g.hi])
                .zip(rr)
                .zip(ri)
                .zip(w)
            {
                // Δφ = arg(c · conj(c0)).
                let zr = cr * qr - ci * qi;
                let zi = cr * qi + ci * qr;
                acc += wt * atan2(zi, zr);
            }
            num += acc as f64;
        }
        -num / den
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth random texture shifted by `u` px (exact, by its Fourier series).
    fn row(u: f64, n: usize) -> Vec<f32> {
        let comps = [
            (0.061, 0.3, 30.0),
            (0.093, 1.1, 25.0),
            (0.121, 2.0, 18.0),
            (0.047, 0.7, 22.0),
        ];
        (0..n)
            .map(|x| {
                let x = x as f64 - u;
                let v: f64 = comps
                    .iter()
                    .map(|(f, p, a)| a * (2.0 * std::f64::consts::PI * f * x + p).cos())
                    .sum();
                (128.0 + v) as f32
            })
            .collect()
    }

    #[test]
    fn recovers_subpixel_shifts_in_pixels() {
        let mut rp = RowPhase::new(200, 0, 200, 1, &[8.0, 16.0]).unwrap();
        assert!(rp.set_reference(0, &row(0.0, 200)) > 0.0);
        for u in [0.01, -0.05, 0.2] {
            let got = rp.displacement(0, &row(u, 200));
            assert!((got - u).abs() < 0.1 * u.abs(), "shift {u}: got {got}");
        }
    }

    #[test]
    fn bad_geometry_is_an_error_not_a_panic() {
        assert!(RowPhase::new(20, 0, 20, 4, &[16.0]).is_err());
        assert!(RowPhase::new(20, 5, 30, 4, &[4.0]).is_err());
        assert!(RowPhase::new(200, 0, 200, 4, &[1.0]).is_err());
        assert!(RowPhase::new(200, 0, 200, 4, &[]).is_err());
        let mut flat = RowPhase::new(100, 0, 100, 1, &[8.0]).unwrap();
        assert_eq!(flat.set_reference(0, &[7.0; 100]), 0.0);
        assert_eq!(flat.displacement(0, &[9.0; 100]), 0.0);
    }
}
