//! A spatially varying vibration: the object as a horizontal cantilever
//! beam (clamped at its left edge, free at its right) whose vertical
//! displacement at column x is Σ_k q_k(t) φ_k(x), with known mode shapes
//! φ_k and modal coordinates q_k (thesis Eq. 3.8-3.11). The ground truth
//! for modal images (ch. 3.5).
//!
//! Mode shapes are the Euler-Bernoulli clamped-free ones,
//! φ_n(s) = cosh βs - cos βs - σ_n (sinh βs - sin βs), s = x/L in [0, 1],
//! β = β_n L (1.8751, 4.6941, 7.8548, 10.9955, then (2n - 1)π/2),
//! σ_n = (sinh β - sin β) / (cosh β + cos β), scaled so that the free end
//! is +1: mode n has n - 1 nodes, and the sign flips across each.
//!
//! Each modal coordinate is either a tone, q(t) = a sin(2π f t + phase), or
//! (`drive = "noise"`, the default) the stationary response of the mode to
//! a broadband force near its resonance: a random-phase multisine of
//! [`noise_lines`] lines spaced evenly over f ± 10 ξ f with amplitudes
//! ∝ 1/√(1 + ((f' - f)/(ξ f))²) (the Lorentzian power of Eq. 3.14), so its
//! power spectrum has the mode's half width ξ f. It is a function of
//! continuous time (any frame time, exact), deterministic from the seed.
//! `amplitude_px` is the free end's peak for a tone, √2 × its RMS for noise.
//!
//! ```toml
//! modal = { modes = [
//!   { freq_hz = 7.3, amplitude_px = 0.3, shape = 1 },
//!   { freq_hz = 58.3, amplitude_px = 0.2, shape = 2, damping = 0.01, drive = "tone" },
//! ] }
//! ```
//!
//! A mode with `across = 1` also varies across the object's rows,
//! linearly from -1 at the top row to +1 at the bottom: the object is then
//! a cantilever plate seen edge-on from slightly above (its out-of-plane
//! motion shows as vertical image motion), and that mode twists it about
//! its centre line. The shapes stay separable (along × across), an
//! approximation of a real plate's that is exact for this simulator's
//! ground truth: `{ freq_hz = 21.0, amplitude_px = 0.2, shape = 1, across = 1 }`.
//!
//! With `modal`, the object's rigid motion (`signal`, `amplitude_px`) is
//! not applied; the texture moves vertically column by column inside the
//! object's rest rectangle (fixed outline), rendered with the same 16-tap
//! interpolator as the rigid motion.

use super::detmath;
use super::rng::{hash2, Xoshiro256};
use super::texture::{Interp, PAD, TAPS};
use super::SimError;

/// Lines of a noise-driven modal coordinate, at least: more where the
/// recording is long enough to resolve them (see [`noise_lines`]).
pub const NOISE_COMPONENTS: usize = 96;
/// Lines of a noise-driven modal coordinate, at most.
pub const MAX_NOISE_COMPONENTS: usize = 4096;
/// Half span of those lines, in half widths ξ f.
const NOISE_SPAN: f64 = 10.0;

/// How a mode is driven.
#[derive(serde::Deserialize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Drive {
    #[default]
    Noise,
    Tone,
}

/// One mode of a [`ModalSpec`].
#[derive(serde::Deserialize, Clone, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ModeSpec {
    pub freq_hz: f64,
    pub amplitude_px: f64,
    /// Cantilever mode number (1 = fundamental), which sets the shape
    /// along the object (columns, clamped at the left edge).
    pub shape: u32,
    /// The shape across the object (rows): 0 = uniform, every row moves
    /// alike (a beam); 1 = linear, -1 at the top row to +1 at the bottom
    /// (a twist about the centre line: a cantilever plate's torsion mode).
    #[serde(default)]
    pub across: u32,
    /// Damping ratio ξ (the width of a noise-driven mode's line).
    #[serde(default = "d_damping")]
    pub damping: f64,
    #[serde(default)]
    pub drive: Drive,
    /// Phase of a tone, radians.
    #[serde(default)]
    pub phase_rad: f64,
}
fn d_damping() -> f64 {
    0.01
}

/// The `modal` key of a scene.
#[derive(serde::Deserialize, Clone, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ModalSpec {
    pub modes: Vec<ModeSpec>,
    /// The recording's length, s (0: unknown). Not a key of the scene: the
    /// source sets it from `frames` and `fps`, so that a noise-driven
    /// mode's lines are closer than a spectral bin of the recording.
    #[serde(skip)]
    pub duration_s: f64,
}

/// The lines of a noise-driven mode of `freq_hz` and damping ratio `xi`
/// seen for `duration_s`: at least two per spectral bin 1/T over the
/// span f ± 10 ξ f, so that every frequency of the recording's spectrum
/// near the mode holds random-phase lines, as a noise-driven mode's does
/// (fewer, and a long recording resolves them into a comb whose gaps have
/// no energy at all: a modal image at a frequency between two lines is
/// empty);
/// [`NOISE_COMPONENTS`]..=[`MAX_NOISE_COMPONENTS`].
pub fn noise_lines(freq_hz: f64, xi: f64, duration_s: f64) -> usize {
    let span = 2.0 * NOISE_SPAN * xi * freq_hz;
    let n = (2.0 * span * duration_s).ceil() + 1.0;
    if n.is_finite() {
        (n as usize).clamp(NOISE_COMPONENTS, MAX_NOISE_COMPONENTS)
    } else {
        NOISE_COMPONENTS
    }
}

/// β_n L of the clamped-free beam.
fn beta(n: u32) -> f64 {
    match n {
        1 => 1.875_104_068_711_961,
        2 => 4.694_091_132_974_175,
        3 => 7.854_757_438_237_613,
        4 => 10.995_540_734_875_467,
        n => (2.0 * n as f64 - 1.0) * std::f64::consts::FRAC_PI_2,
    }
}

fn raw_shape(b: f64, sigma: f64, s: f64) -> f64 {
    let x = b * s;
    let (ep, em) = (detmath::exp(x), detmath::exp(-x));
    let (sin, cos) = detmath::sin_cos_turns(x / std::f64::consts::TAU);
    let (ch, sh) = (0.5 * (ep + em), 0.5 * (ep - em));
    ch - cos - sigma * (sh - sin)
}

/// Cantilever mode shape `n` (>= 1) at `s = x/L` in [0, 1]: 0 at the
/// clamped end, +1 at the free end.
pub fn cantilever_shape(n: u32, s: f64) -> f64 {
    let b = beta(n.max(1));
    let (eb, emb) = (detmath::exp(b), detmath::exp(-b));
    let (sin, cos) = detmath::sin_cos_turns(b / std::f64::consts::TAU);
    let sigma = (0.5 * (eb - emb) - sin) / (0.5 * (eb + emb) + cos);
    raw_shape(b, sigma, s) / raw_shape(b, sigma, 1.0)
}

/// One mode, ready to evaluate.
#[derive(Clone, Debug)]
struct Mode {
    /// φ at the centre of each object column.
    shape: Vec<f64>,
    /// The factor across at the centre of each object row (all 1 for `across = 0`).
    across: Vec<f64>,
    /// Frequency (Hz), damping ratio and amplitude (px) of the spec.
    freq_hz: f64,
    damping: f64,
    amplitude_px: f64,
    /// (frequency Hz, amplitude px, phase turns) of each line.
    lines: Vec<(f64, f64, f64)>,
}

impl Mode {
    /// The shape at object pixel (`c`, `r`) (0 outside).
    fn phi(&self, c: usize, r: usize) -> f64 {
        self.shape.get(c).copied().unwrap_or(0.0) * self.across.get(r).copied().unwrap_or(0.0)
    }

    /// The modal displacement `t_s` after a unit impulse on a point where
    /// the shape is `phi_p`: unit modal mass, mass-normalised shape
    /// `amplitude_px φ`, so `amplitude_px φ_p e^{-ξωt} sin(ω_d t) / ω_d`.
    fn free_response(&self, phi_p: f64, t_s: f64) -> f64 {
        let wd = std::f64::consts::TAU * self.freq_hz;
        let w = wd / (1.0 - self.damping * self.damping).sqrt();
        self.amplitude_px * phi_p * (-self.damping * w * t_s).exp() * (wd * t_s).sin() / wd
    }
}

/// A validated [`ModalSpec`] for an object `width` columns wide and
/// `height` rows tall.
#[derive(Clone, Debug)]
pub struct ModalBeam {
    modes: Vec<Mode>,
    /// Column displacements and modal coordinates of the current frame.
    column: Vec<f64>,
    /// Whether some mode varies across the rows (a plate, not a beam).
    two_d: bool,
    /// Per-pixel displacements of the current frame (`two_d` only).
    field: Vec<f64>,
    q: Vec<f64>,
    peak: f64,
}

/// Where the object's texture lives (the scene's padded lattice).
pub(super) struct Lattice<'a> {
    /// Zero-mean texture on `[-pad, ow + pad) x [-pad, oh + pad)`.
    pub grid: &'a [f32],
    pub gw: usize,
    pub pad: usize,
    pub interp: &'a Interp,
    /// Displacements are clamped to ±this (the lattice covers it).
    pub amp_max: f64,
}

impl ModalBeam {
    /// Validates `spec` for an object `width` columns wide; `seed` drives
    /// the random phases.
    pub fn new(spec: &ModalSpec, width: usize, height: usize, seed: u64) -> Result<Self, SimError> {
        let bad = |field: String, msg: String| SimError::Invalid { field, msg };
        if spec.modes.is_empty() || spec.modes.len() > 64 {
            return Err(bad(
                "modal.modes".into(),
                format!("must list 1..=64 modes, got {}", spec.modes.len()),
            ));
        }
        let mut modes = Vec::with_capacity(spec.modes.len());
        let mut peak = 0.0;
        for (k, m) in spec.modes.iter().enumerate() {
            let f = |name: &str| format!("modal.modes[{k}].{name}");
            if !(m.freq_hz.is_finite() && m.freq_hz > 0.0) {
                return Err(bad(
                    f("freq_hz"),
                    format!("must be > 0 Hz, got {}", m.freq_hz),
                ));
            }
            if !(m.amplitude_px.is_finite() && m.amplitude_px.abs() <= 100.0) {
                return Err(bad(
                    f("amplitude_px"),
                    format!("must be within ±100 px, got {}", m.amplitude_px),
                ));
            }
            if !(1..=20).contains(&m.shape) {
                return Err(bad(f("shape"), format!("must be 1..=20, got {}", m.shape)));
            }
            if m.across > 1 {
                return Err(bad(
                    f("across"),
                    format!(
                        "must be 0 (uniform) or 1 (linear, a twist), got {}",
                        m.across
                    ),
                ));
            }
            if !(m.damping.is_finite() && m.damping > 0.0 && m.damping < 0.5) {
                return Err(bad(
                    f("damping"),
                    format!("must be in (0, 0.5), got {}", m.damping),
                ));
            }
            if !m.phase_rad.is_finite() {
                return Err(bad(
                    f("phase_rad"),
                    format!("must be finite, got {}", m.phase_rad),
                ));
            }
            let shape = (0..width)
                .map(|c| cantilever_shape(m.shape, (c as f64 + 0.5) / width as f64))
                .collect();
            let across = (0..height)
                .map(|r| match m.across {
                    0 => 1.0,
                    _ => 2.0 * (r as f64 + 0.5) / height as f64 - 1.0,
                })
                .collect();
            let lines = match m.drive {
                Drive::Tone => vec![(
                    m.freq_hz,
                    m.amplitude_px,
                    m.phase_rad / std::f64::consts::TAU - 0.25,
                )],
                Drive::Noise => {
                    let mut rng = Xoshiro256::new(hash2(seed ^ 0x6d6f_6461_6c00, k as u64));
                    let n = noise_lines(m.freq_hz, m.damping, spec.duration_s);
                    let raw: Vec<(f64, f64)> = (0..n)
                        .map(|j| {
                            let x = NOISE_SPAN * (2.0 * j as f64 / (n - 1) as f64 - 1.0);
                            (x, 1.0 / (1.0 + x * x).sqrt())
                        })
                        .collect();
                    let norm = raw.iter().map(|(_, a)| a * a).sum::<f64>().sqrt();
                    raw.iter()
                        .map(|&(x, a)| {
                            let fj = m.freq_hz * (1.0 + m.damping * x);
                            (fj, m.amplitude_px * a / norm, rng.next_f64())
                        })
                        .collect()
                }
            };
            peak += lines.iter().map(|l| l.1.abs()).sum::<f64>();
            modes.push(Mode {
                shape,
                across,
                freq_hz: m.freq_hz,
                damping: m.damping,
                amplitude_px: m.amplitude_px,
                lines,
            });
        }
        let two_d = spec.modes.iter().any(|m| m.across != 0);
        Ok(Self {
            q: vec![0.0; modes.len()],
            modes,
            column: vec![0.0; width],
            two_d,
            field: if two_d {
                vec![0.0; width * height]
            } else {
                Vec::new()
            },
            peak,
        })
    }

    /// An upper bound of |displacement| anywhere, px.
    pub fn peak_bound(&self) -> f64 {
        self.peak
    }

    /// Modal coordinate `k` (the free end's displacement from mode `k`) at `t_s`.
    pub fn coordinate(&self, k: usize, t_s: f64) -> f64 {
        self.modes.get(k).map_or(0.0, |m| {
            m.lines
                .iter()
                .map(|&(f, a, ph)| a * detmath::sin_cos_turns(f * t_s + ph).1)
                .sum()
        })
    }

    /// Vertical displacement (px, +y down) of object column `c` at `t_s`
    /// (of its top row where a mode varies across the rows).
    pub fn displacement_px(&self, c: usize, t_s: f64) -> f64 {
        self.displacement_at(c, 0, t_s)
    }

    /// Vertical displacement (px, +y down) of object pixel (`c`, `r`) at `t_s`.
    pub fn displacement_at(&self, c: usize, r: usize, t_s: f64) -> f64 {
        self.modes
            .iter()
            .enumerate()
            .map(|(k, m)| m.phi(c, r) * self.coordinate(k, t_s))
            .sum()
    }

    /// The beam's response to a unit vertical impulse at object column
    /// `poke`, at `t_s` seconds after it: per object column, px (+y down),
    /// into `out`. The ground truth of interactive dynamic video (thesis
    /// 6.3): each mode is a unit-mass oscillator at its damped frequency
    /// and damping ratio whose mass-normalised shape is the ambient one,
    /// ψ_k = amplitude_px φ_k (the broad-spectrum forcing of 6.3.1, true
    /// here by construction), so mode k contributes
    /// ψ_k(c) ψ_k(poke) e^{-ξωt} sin(ω_d t) / ω_d.
    pub fn impulse_response(&self, poke: usize, t_s: f64, out: &mut [f64]) {
        out.fill(0.0);
        if t_s < 0.0 {
            return;
        }
        for m in &self.modes {
            let rho = m.free_response(m.shape.get(poke).copied().unwrap_or(0.0), t_s);
            for (o, &phi) in out.iter_mut().zip(&m.shape) {
                *o += m.amplitude_px * phi * rho;
            }
        }
    }

    /// [`ModalBeam::impulse_response`] of every object pixel to a unit
    /// vertical impulse at object pixel (`pc`, `pr`), row-major `ow x oh`
    /// into `out`: the same truth where modes vary across the rows.
    pub fn impulse_response_at(&self, pc: usize, pr: usize, t_s: f64, out: &mut [f64]) {
        out.fill(0.0);
        if t_s < 0.0 {
            return;
        }
        let ow = self.column.len();
        for m in &self.modes {
            let rho = m.free_response(m.phi(pc, pr), t_s);
            for (i, o) in out.iter_mut().enumerate() {
                *o += m.amplitude_px * m.phi(i % ow, i / ow) * rho;
            }
        }
    }

    /// Renders the zero-mean object (`ow x oh`, row-major) at `t_s` into `out`.
    pub(super) fn render(&mut self, t_s: f64, lat: &Lattice<'_>, oh: usize, out: &mut [f32]) {
        let ow = self.column.len();
        for k in 0..self.q.len() {
            self.q[k] = self.coordinate(k, t_s);
        }
        if self.two_d {
            return self.render_2d(lat, oh, out);
        }
        for (c, d) in self.column.iter_mut().enumerate() {
            *d = self
                .modes
                .iter()
                .zip(&self.q)
                .map(|(m, q)| m.shape[c] * q)
                .sum();
        }
        for c in 0..ow {
            let d = self.column[c].clamp(-lat.amp_max, lat.amp_max);
            let i = d.floor();
            let taps = lat.interp.taps_f32_reversed(d - i);
            let col = c + lat.pad;
            for r in 0..oh {
                // Lattice row k = r - i; its window starts at grid row k - PAD + pad.
                let g0 = (r as i64 - i as i64 - PAD as i64 + lat.pad as i64) as usize;
                let mut v = 0.0f32;
                for (s, &t) in taps.iter().enumerate().take(TAPS) {
                    v += t * lat.grid[(g0 + s) * lat.gw + col];
                }
                out[r * ow + c] = v;
            }
        }
    }

    /// [`ModalBeam::render`] where modes vary across the rows: each pixel
    /// shifted vertically by its own displacement, with the same taps.
    fn render_2d(&mut self, lat: &Lattice<'_>, oh: usize, out: &mut [f32]) {
        let ow = self.column.len();
        self.field.fill(0.0);
        for (m, &q) in self.modes.iter().zip(&self.q) {
            for (r, &a) in m.across.iter().enumerate() {
                let row = &mut self.field[r * ow..(r + 1) * ow];
                for (d, &phi) in row.iter_mut().zip(&m.shape) {
                    *d += phi * a * q;
                }
            }
        }
        // Each pixel's taps are its own fraction's; they are made eight
        // pixels at a time (the same bits, the solves in vector lanes).
        const MANY: usize = 8;
        for r in 0..oh {
            let row = &self.field[r * ow..(r + 1) * ow];
            for c0 in (0..ow).step_by(MANY) {
                let n = MANY.min(ow - c0);
                let mut whole = [0.0f64; MANY];
                let mut fracs = [0.0f64; MANY];
                for (j, (w, f)) in whole.iter_mut().zip(&mut fracs).enumerate().take(n) {
                    let d = row[c0 + j].clamp(-lat.amp_max, lat.amp_max);
                    *w = d.floor();
                    *f = d - *w;
                }
                let taps = lat.interp.taps_f32_reversed_many(&fracs);
                for (j, (taps, &i)) in taps.iter().zip(&whole).enumerate().take(n) {
                    let c = c0 + j;
                    let col = c + lat.pad;
                    let g0 = (r as i64 - i as i64 - PAD as i64 + lat.pad as i64) as usize;
                    let mut v = 0.0f32;
                    for (s, &t) in taps.iter().enumerate().take(TAPS) {
                        v += t * lat.grid[(g0 + s) * lat.gw + col];
                    }
                    out[r * ow + c] = v;
                }
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn shapes_have_their_nodes_and_free_end() {
        // Nodes of the clamped-free beam (x/L): mode 2 at 0.783, mode 3 at 0.504 and 0.868.
        let sign_changes = |n: u32| -> Vec<f64> {
            let mut v = Vec::new();
            let steps = 10_000;
            for i in 1..steps {
                let (a, b) = (i as f64 / steps as f64, (i + 1) as f64 / steps as f64);
                if cantilever_shape(n, a).signum() != cantilever_shape(n, b).signum() {
                    v.push(a);
                }
            }
            v
        };
        assert!(sign_changes(1).is_empty());
        let n2 = sign_changes(2);
        assert!(n2.len() == 1 && (n2[0] - 0.7834).abs() < 1e-3, "{n2:?}");
        let n3 = sign_changes(3);
        assert!(n3.len() == 2 && (n3[0] - 0.5036).abs() < 1e-3 && (n3[1] - 0.8677).abs() < 1e-3);
        for n in 1..=5 {
            assert!((cantilever_shape(n, 1.0) - 1.0).abs() < 1e-12);
            assert!(cantilever_shape(n, 0.0).abs() < 1e-12);
        }
    }

    #[test]
    fn noise_drive_has_the_stated_rms_and_is_deterministic() {
        let spec = ModalSpec {
            duration_s: 0.0,
            modes: vec![ModeSpec {
                freq_hz: 50.0,
                amplitude_px: 0.2,
                shape: 1,
                across: 0,
                damping: 0.02,
                drive: Drive::Noise,
                phase_rad: 0.0,
            }],
        };
        let a = ModalBeam::new(&spec, 8, 4, 3).unwrap();
        let b = ModalBeam::new(&spec, 8, 4, 3).unwrap();
        let n = 200_000;
        let ms: f64 = (0..n)
            .map(|i| a.coordinate(0, i as f64 * 1e-3).powi(2))
            .sum::<f64>()
            / n as f64;
        // √2 × RMS = amplitude_px (the lines are incommensurate over 200 s).
        assert!(
            ((2.0 * ms).sqrt() - 0.2).abs() < 0.01,
            "{}",
            (2.0 * ms).sqrt()
        );
        assert_eq!(a.coordinate(0, 1.2345), b.coordinate(0, 1.2345));
    }

    #[test]
    fn a_twist_moves_the_rows_oppositely_and_the_2d_truth_extends_the_columns() {
        let mode = |freq_hz: f64, amplitude_px: f64, shape: u32, across: u32| ModeSpec {
            freq_hz,
            amplitude_px,
            shape,
            across,
            damping: 0.01,
            drive: Drive::Noise,
            phase_rad: 0.0,
        };
        let spec = |modes: Vec<ModeSpec>| ModalSpec {
            modes,
            duration_s: 0.0,
        };
        let spec2 = spec(vec![mode(10.0, 0.2, 1, 0), mode(25.0, 0.1, 1, 1)]);
        let b = ModalBeam::new(&spec2, 20, 10, 3).unwrap();
        let t = 0.123;
        // The twist alone: top and bottom rows opposite, about the centre line.
        let twist = |c: usize, r: usize| b.modes[1].phi(c, r) * b.coordinate(1, t);
        assert!((twist(19, 0) + twist(19, 9)).abs() < 1e-12);
        assert!(twist(19, 0).abs() > 0.0);
        let sum = b.displacement_at(19, 0, t) + b.displacement_at(19, 9, t);
        assert!((sum - 2.0 * b.modes[0].phi(19, 0) * b.coordinate(0, t)).abs() < 1e-12);
        // Without a twist the 2-D truth is the column truth on every row.
        let b = ModalBeam::new(&spec(vec![mode(10.0, 0.2, 2, 0)]), 20, 4, 3).unwrap();
        let (mut col, mut all) = (vec![0.0; 20], vec![0.0; 80]);
        b.impulse_response(15, 0.07, &mut col);
        b.impulse_response_at(15, 2, 0.07, &mut all);
        for (i, v) in all.iter().enumerate() {
            assert_eq!(*v, col[i % 20]);
        }
        assert!(ModalBeam::new(&spec(vec![mode(1.0, 0.1, 1, 2)]), 4, 4, 1).is_err());
    }

    #[test]
    fn noise_lines_are_closer_than_a_bin_of_the_recording() {
        // Short recordings keep the minimum; long ones get 2 per bin.
        assert_eq!(noise_lines(7.3, 0.02, 2.0), NOISE_COMPONENTS);
        let (f, xi, t) = (7.3, 0.05, 130.0);
        let n = noise_lines(f, xi, t);
        let spacing = 2.0 * NOISE_SPAN * xi * f / (n - 1) as f64;
        assert!(spacing <= 0.5 / t + 1e-12, "{n} lines, {spacing} Hz apart");
        assert_eq!(noise_lines(100.0, 0.4, 1e9), MAX_NOISE_COMPONENTS);
        assert_eq!(noise_lines(f64::NAN, 0.4, 1.0), NOISE_COMPONENTS);
    }
}
