//! A hanging fabric (thesis 5.5): a cloth sheet of bending rigidity `B`
//! (N·m), area weight `ρ_A` (kg/m²), length `L` and width `W`, hanging from
//! a bar, moving out of its plane, seen by a camera off its normal so the
//! out-of-plane motion shows as horizontal image motion. The ground truth
//! for learning material properties from motion spectra
//! (`docs/learning.md` has the physics, its sources and its limits).
//!
//! Modes `(n, m)`: `n` = 1, 2, … along the hanging length (the hanging
//! chain, shape `J0(j_n √(1 - s))`, `s` = distance from the bar / L, `j_n`
//! the n-th zero of J0), `m` = 0, 1, 2 across the width (`cos(m π u)`,
//! `u` = across / W). Frequencies (an additive Rayleigh-type approximation):
//!
//! ```text
//! k²      = (j_n / L)² + (m π / W)²
//! ω_g²    = g j_n² / (4 L) + g (L / 2) (m π / W)²     hanging chain + mean tension across
//! R_b     = ∫(φ'' - (mπ/W)² φ)² dz / ∫φ² dz           bending Rayleigh quotient of the chain shape
//! m_a     = ρ_air / k                                 air moved with the cloth (added mass)
//! ω²      = (ρ_A ω_g² + B R_b) / (ρ_A + m_a)
//! ξ       = ξ_mat + c_air / (2 (ρ_A + m_a) ω)          linearised air drag + material loss
//! ```
//!
//! Excitation is a force per area with a known spectrum: `ambient` (air
//! currents: each mode driven independently, power ∝ 1 / (1 + (f/f_c)²),
//! the low-frequency tilt), `sound` (a logarithmic chirp, one pressure
//! field for all modes, slightly uneven across the width) or `kick` (the
//! thesis's sound condition: the ambient forcing plus a one-second
//! 15-100 Hz sweep through that pressure field, at `kick_db` over it). Each modal
//! coordinate is the exact steady-state response of its mode to a
//! multisine of [`LINES`] lines (0.02 Hz apart, jittered) with that
//! spectrum, so it is a function of continuous time, deterministic from the
//! seed, like [`super::modal`]. `amplitude_px` is √2 × the RMS image
//! displacement averaged over the visible cloth.
//!
//! ```toml
//! fabric = { stiffness_nm = 1e-5, area_weight_kg_m2 = 0.12, excitation = "ambient" }
//! ```

use super::detmath;
use super::rng::{hash2, Xoshiro256};
use super::texture::{Interp, PAD, TAPS};
use super::SimError;
use std::f64::consts::PI;

/// Lines of the excitation multisine.
pub const LINES: usize = 1000;
/// Their spacing, Hz (the force has lines up to `LINES * LINE_SPACING_HZ`).
pub const LINE_SPACING_HZ: f64 = 0.02;
/// Gravity, m/s².
pub const G: f64 = 9.81;
/// Fractional-shift taps are tabulated at this many steps per pixel.
const TAP_STEPS: usize = 256;
/// Pixels a row's interpolation sums side by side (each its own sum).
const LANES: usize = 8;

/// How the fabric is excited.
#[derive(serde::Deserialize, serde::Serialize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Excitation {
    /// Air currents in the room: independent broadband forces with a low-frequency tilt.
    #[default]
    Ambient,
    /// A loudspeaker's logarithmic chirp: one coherent pressure field.
    Sound,
    /// The thesis's sound condition (5.5): the ambient forcing throughout,
    /// plus a loudspeaker's short logarithmic sweep (a "kick", one second
    /// from 15 to 100 Hz) at one time in the take: one coherent pressure
    /// field.
    Kick,
}

/// The `fabric` key of a scene. Defaults: the thesis's hanging length and
/// width (29-32 in, 44 in), room air.
#[derive(serde::Deserialize, serde::Serialize, Clone, Debug, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct FabricSpec {
    /// Bending rigidity B, N·m (the thesis's "stiffness").
    pub stiffness_nm: f64,
    /// Area weight ρ_A, kg/m².
    pub area_weight_kg_m2: f64,
    /// Hanging length L and width W, m.
    pub length_m: f64,
    pub width_m: f64,
    pub excitation: Excitation,
    /// √2 × RMS image displacement over the visible cloth, px.
    pub amplitude_px: f64,
    /// The part of the cloth the object's rectangle shows: `[u0, s0, u1, s1]`
    /// (fractions of width and of length from the bar).
    pub view: [f64; 4],
    /// Perspective of an oblique view: the image motion scales by
    /// `1 + perspective (u - 1/2)` across the width.
    pub perspective: f64,
    /// Ambient tilt corner f_c, Hz.
    pub corner_hz: f64,
    /// Sound: the chirp's band, Hz.
    pub chirp_hz: [f64; 2],
    /// Kick: the sweep's band, Hz, its length and start, s, and its motion
    /// power over the ambient forcing's (over the lines' period,
    /// 1 / [`LINE_SPACING_HZ`] = 50 s), dB.
    pub kick_hz: [f64; 2],
    pub kick_s: f64,
    pub kick_at_s: f64,
    pub kick_db: f64,
    /// Air density, kg/m³, and linearised drag, N·s/m³.
    pub air_density: f64,
    pub air_drag: f64,
    /// Material damping ratio ξ_mat.
    pub material_damping: f64,
    /// Modes along the length (n = 1..=this) and across (m = 0..=this).
    pub modes_along: u32,
    pub modes_across: u32,
}

impl Default for FabricSpec {
    fn default() -> Self {
        Self {
            stiffness_nm: 1e-5,
            area_weight_kg_m2: 0.15,
            length_m: 0.78,
            width_m: 1.12,
            excitation: Excitation::Ambient,
            amplitude_px: 0.3,
            view: [0.0, 0.0, 1.0, 1.0],
            perspective: 0.0,
            corner_hz: 2.0,
            chirp_hz: [0.3, 20.0],
            kick_hz: [15.0, 100.0],
            kick_s: 1.0,
            kick_at_s: 10.0,
            kick_db: 0.0,
            air_density: 1.2,
            air_drag: 0.15,
            material_damping: 0.02,
            modes_along: 30,
            modes_across: 2,
        }
    }
}

/// One mode's physics (for the docs and tests).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FabricMode {
    pub along: u32,
    pub across: u32,
    pub freq_hz: f64,
    pub damping: f64,
    /// ρ_A + m_a, kg/m².
    pub mass_kg_m2: f64,
}

/// n-th zero of J0 (n >= 1): the first five tabulated, then McMahon's expansion.
pub fn bessel_j0_zero(n: u32) -> f64 {
    const Z: [f64; 5] = [
        2.404_825_557_695_773,
        5.520_078_110_286_311,
        8.653_727_912_911_013,
        11.791_534_439_014_281,
        14.930_917_708_487_787,
    ];
    match n {
        0 => 0.0,
        1..=5 => Z[n as usize - 1],
        n => {
            let b = (n as f64 - 0.25) * PI;
            let e = 8.0 * b;
            b + 1.0 / e - 124.0 / (3.0 * e.powi(3)) + 120_928.0 / (15.0 * e.powi(5))
        }
    }
}

/// J0(x), Abramowitz & Stegun 9.4.1 / 9.4.3 (|error| < 1e-7).
pub fn bessel_j0(x: f64) -> f64 {
    let ax = x.abs();
    if ax <= 3.0 {
        let y = (x / 3.0).powi(2);
        1.0 + y
            * (-2.249_999_7
                + y * (1.265_620_8
                    + y * (-0.316_386_6
                        + y * (0.044_447_9 + y * (-0.003_944_4 + y * 0.000_210_0)))))
    } else {
        let y = 3.0 / ax;
        let f0 = 0.797_884_56
            + y * (-0.000_000_77
                + y * (-0.005_527_40
                    + y * (-0.000_095_12
                        + y * (0.001_372_37 + y * (-0.000_728_05 + y * 0.000_144_76)))));
        let t0 = ax - std::f64::consts::FRAC_PI_4
            + y * (-0.041_663_97
                + y * (-0.000_039_54
                    + y * (0.002_625_73
                        + y * (-0.000_541_25 + y * (-0.000_293_33 + y * 0.000_135_58)))));
        f0 * detmath::sin_cos_turns(t0 / std::f64::consts::TAU).1 / ax.sqrt()
    }
}

/// J1(x), Abramowitz & Stegun 9.4.4 / 9.4.6 (|error| < 1e-7).
pub fn bessel_j1(x: f64) -> f64 {
    let ax = x.abs();
    if ax <= 3.0 {
        let y = (x / 3.0).powi(2);
        x * (0.5
            + y * (-0.562_499_85
                + y * (0.210_935_73
                    + y * (-0.039_542_89
                        + y * (0.004_433_19 + y * (-0.000_317_61 + y * 0.000_011_09))))))
    } else {
        let y = 3.0 / ax;
        let f1 = 0.797_884_56
            + y * (0.000_001_56
                + y * (0.016_596_67
                    + y * (0.000_171_05
                        + y * (-0.002_495_11 + y * (0.001_136_53 - y * 0.000_200_33)))));
        let t1 = ax - 3.0 * std::f64::consts::FRAC_PI_4
            + y * (0.124_996_12
                + y * (0.000_056_5
                    + y * (-0.006_378_79
                        + y * (0.000_743_48 + y * (0.000_798_24 - y * 0.000_291_66)))));
        let v = f1 * detmath::sin_cos_turns(t1 / std::f64::consts::TAU).1 / ax.sqrt();
        if x < 0.0 {
            -v
        } else {
            v
        }
    }
}

/// The bending Rayleigh quotient `∫(φ'' - kx² φ)² dz / ∫φ² dz` (1/m⁴) of the
/// chain shape `φ(z) = J0(j √(z/L))`, `z` up from the free end. `φ'` and
/// `φ''` are exact: `φ' = -a² J1(x) / (2x)` with `x = a √z`, `a = j / √L`,
/// and the chain's equation `(z φ')' + (a²/4) φ = 0` gives `φ''`.
pub fn bending_quotient(j: f64, l: f64, kx: f64) -> f64 {
    let a2 = j * j / l;
    let steps = 2000;
    let h = l / steps as f64;
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..steps {
        let z = (i as f64 + 0.5) * h;
        let x = (a2 * z).sqrt();
        let phi = bessel_j0(x);
        let d1 = -a2 * bessel_j1(x) / (2.0 * x);
        let d2 = -(d1 + a2 * phi / 4.0) / z;
        num += (d2 - kx * kx * phi).powi(2);
        den += phi * phi;
    }
    num / den
}

impl FabricSpec {
    /// The modes' frequencies, damping and mass (see the module docs).
    pub fn modes(&self) -> Vec<FabricMode> {
        let (l, w, rho) = (self.length_m, self.width_m, self.area_weight_kg_m2);
        let mut out = Vec::new();
        for n in 1..=self.modes_along {
            for m in 0..=self.modes_across {
                let j = bessel_j0_zero(n);
                let kx = m as f64 * PI / w;
                let k2 = (j / l).powi(2) + kx * kx;
                let wg2 = G * j * j / (4.0 * l) + G * (l / 2.0) * kx * kx;
                let ma = self.air_density / k2.sqrt();
                let mass = rho + ma;
                let bend = bending_quotient(j, l, kx);
                let om = ((rho * wg2 + self.stiffness_nm * bend) / mass).sqrt();
                let xi = (self.material_damping + self.air_drag / (2.0 * mass * om)).min(0.45);
                out.push(FabricMode {
                    along: n,
                    across: m,
                    freq_hz: om / (2.0 * PI),
                    damping: xi,
                    mass_kg_m2: mass,
                });
            }
        }
        out
    }

    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), SimError> {
        let bad = |f: &str, msg: String| {
            Err(SimError::Invalid {
                field: format!("fabric.{f}"),
                msg,
            })
        };
        let pos = [
            ("stiffness_nm", self.stiffness_nm),
            ("area_weight_kg_m2", self.area_weight_kg_m2),
            ("length_m", self.length_m),
            ("width_m", self.width_m),
            ("corner_hz", self.corner_hz),
            ("air_density", self.air_density),
        ];
        for (f, v) in pos {
            if !(v.is_finite() && v > 0.0 && v < 1e6) {
                return bad(f, format!("must be > 0 (and < 1e6), got {v}"));
            }
        }
        if !(self.air_drag.is_finite() && self.air_drag >= 0.0 && self.air_drag < 1e6) {
            return bad("air_drag", format!("must be >= 0, got {}", self.air_drag));
        }
        if !(self.material_damping.is_finite()
            && self.material_damping > 0.0
            && self.material_damping < 0.45)
        {
            return bad(
                "material_damping",
                format!("must be in (0, 0.45), got {}", self.material_damping),
            );
        }
        if !(self.amplitude_px.is_finite() && self.amplitude_px.abs() <= 100.0) {
            return bad(
                "amplitude_px",
                format!("must be within ±100 px, got {}", self.amplitude_px),
            );
        }
        let [u0, s0, u1, s1] = self.view;
        if !(self
            .view
            .iter()
            .all(|v| v.is_finite() && (0.0..=1.0).contains(v))
            && u0 < u1
            && s0 < s1)
        {
            return bad(
                "view",
                format!(
                    "must be [u0, s0, u1, s1] within [0, 1] with u0 < u1, s0 < s1, got {:?}",
                    self.view
                ),
            );
        }
        if !(self.perspective.is_finite() && self.perspective.abs() < 2.0) {
            return bad(
                "perspective",
                format!("must be within ±2, got {}", self.perspective),
            );
        }
        let [a, b] = self.chirp_hz;
        if !(a.is_finite() && b.is_finite() && a > 0.0 && a < b) {
            return bad(
                "chirp_hz",
                format!("must be [lo, hi] with 0 < lo < hi, got {:?}", self.chirp_hz),
            );
        }
        let [a, b] = self.kick_hz;
        if !(a.is_finite() && b.is_finite() && a > 0.0 && a < b && b <= 1000.0) {
            return bad(
                "kick_hz",
                format!(
                    "must be [lo, hi] with 0 < lo < hi <= 1000, got {:?}",
                    self.kick_hz
                ),
            );
        }
        let period = 1.0 / LINE_SPACING_HZ;
        if !(self.kick_s.is_finite() && self.kick_s >= 0.01 && self.kick_s <= 10.0) {
            return bad(
                "kick_s",
                format!("must be 0.01..=10 s, got {}", self.kick_s),
            );
        }
        if !(self.kick_at_s.is_finite()
            && self.kick_at_s >= 0.0
            && self.kick_at_s + self.kick_s <= period)
        {
            return bad(
                "kick_at_s",
                format!(
                    "must be >= 0 with kick_at_s + kick_s <= {period} s (the forcing repeats every {period} s), got {}",
                    self.kick_at_s
                ),
            );
        }
        if !(self.kick_db.is_finite() && self.kick_db.abs() <= 60.0) {
            return bad(
                "kick_db",
                format!("must be within ±60 dB, got {}", self.kick_db),
            );
        }
        if !(1..=60).contains(&self.modes_along) || self.modes_across > 8 {
            return bad(
                "modes_along",
                format!(
                    "modes_along must be 1..=60 and modes_across 0..=8, got {} and {}",
                    self.modes_along, self.modes_across
                ),
            );
        }
        Ok(())
    }

    /// Force spectrum amplitude (relative) and phase (turns) of line `f`.
    fn force(&self, f: f64, rng: &mut Xoshiro256) -> (f64, f64) {
        match self.excitation {
            Excitation::Ambient | Excitation::Kick => (
                1.0 / (1.0 + (f / self.corner_hz).powi(2)).sqrt(),
                rng.next_f64(),
            ),
            Excitation::Sound => {
                // Log sweep: power ∝ 1/f in its band (time spent per Hz),
                // half-cosine tapers an octave wide at each end; the phase is
                // the stationary phase of a sweep over one second.
                let [lo, hi] = self.chirp_hz;
                let taper = |x: f64| {
                    if x <= 0.0 {
                        0.0
                    } else if x >= 1.0 {
                        1.0
                    } else {
                        0.5 - 0.5 * detmath::sin_cos_turns(0.5 * x).1
                    }
                };
                let g = taper((f / lo).log2() + 1.0) * taper((hi / f).log2() + 1.0);
                let r = (hi / lo).ln();
                // ∫ τ(f) df with τ = ln(f / lo) / r seconds.
                let phase = if f > 0.0 {
                    -(f * ((f / lo).ln() - 1.0) + lo) / r
                } else {
                    0.0
                };
                (g / f.max(1e-3).sqrt(), phase.rem_euclid(1.0))
            }
        }
    }
}

/// A validated [`FabricSpec`] for an object of `ow x oh` pixels.
#[derive(Clone, Debug)]
pub struct Fabric {
    /// Line frequencies, Hz.
    freqs: Vec<f64>,
    /// Per mode, per line: complex response (re, im), px at unit shape.
    coef: Vec<Vec<(f64, f64)>>,
    /// Per mode: shape along the rows (`oh`) and across the columns (`ow`,
    /// with the perspective scale).
    along: Vec<Vec<f64>>,
    across: Vec<Vec<f64>>,
    modes: Vec<FabricMode>,
    peak: f64,
    /// Per-frame work: the line phasors, the modal coordinates, the
    /// row sums per across-index, the displacements.
    z: Vec<(f64, f64)>,
    q: Vec<f64>,
    rows: Vec<f64>,
    /// A row's displacements (`ow`).
    row_d: Vec<f64>,
    n_across: usize,
    taps: Vec<[f32; TAPS]>,
    /// The time `q` was computed for.
    q_t: f64,
    /// Sound: one pressure field drives every mode with the same line
    /// phases; ambient: each mode's phases are its own.
    coherent: bool,
    /// Kick: the sweep's part of `coef` (one field); the rest is ambient.
    kick: Option<Vec<Vec<(f64, f64)>>>,
}

/// Mean square displacement over an 8x8 grid of the object of modal line
/// coefficients `coef` (this realisation's phases).
fn grid_mean_square(
    coef: &[Vec<(f64, f64)>],
    modes: &[FabricMode],
    along: &[Vec<f64>],
    across: &[Vec<f64>],
    ow: usize,
    oh: usize,
) -> f64 {
    let pts = 8usize;
    let lines = coef.first().map_or(0, Vec::len);
    let mut ms = 0.0;
    let mut re = vec![0.0; lines];
    let mut im = vec![0.0; lines];
    for pr in 0..pts {
        let r = (pr * oh + oh / 2) / pts;
        for pc in 0..pts {
            let c = (pc * ow + ow / 2) / pts;
            re.fill(0.0);
            im.fill(0.0);
            for (k, md) in modes.iter().enumerate() {
                let phi = along[md.along as usize - 1][r.min(oh - 1)]
                    * across[md.across as usize][c.min(ow - 1)];
                for (j, &(a, b)) in coef[k].iter().enumerate() {
                    re[j] += phi * a;
                    im[j] += phi * b;
                }
            }
            ms += re.iter().zip(&im).map(|(a, b)| a * a + b * b).sum::<f64>() / 2.0;
        }
    }
    ms / (pts * pts) as f64
}

/// The kick's force lines: complex amplitude at each of `freqs`
/// of a logarithmic sweep `sin(2π φ(t))`, `φ(t) = f0 T (r^(t/T) - 1) / ln r`,
/// `r = f1 / f0`, from `kick_at_s` for `kick_s` seconds, started and
/// stopped abruptly: its Fourier transform (the midpoint rule at 20
/// samples per cycle of `f1`), so the lines below `f0` hold the leakage
/// of its onset and end.
fn sweep_lines(spec: &FabricSpec, freqs: &[f64]) -> Vec<(f64, f64)> {
    let [f0, f1] = spec.kick_hz;
    let t_len = spec.kick_s;
    let n = (20.0 * f1 * t_len).ceil().max(16.0) as usize;
    let dt = t_len / n as f64;
    let lr = detmath::ln(f1 / f0);
    let x: Vec<f64> = (0..n)
        .map(|i| {
            let t = (i as f64 + 0.5) * dt;
            let phi = f0 * t_len * (detmath::exp(lr * t / t_len) - 1.0) / lr;
            detmath::sin_cos_turns(phi.rem_euclid(1.0)).0
        })
        .collect();
    freqs
        .iter()
        .map(|&f| {
            // X(f) = Σ x(t) e^{-2πi f (t0 + t)} dt, the phasor advanced by a
            // rotation each sample.
            let (s0, c0) =
                detmath::sin_cos_turns((-f * (spec.kick_at_s + 0.5 * dt)).rem_euclid(1.0));
            let (sw, cw) = detmath::sin_cos_turns((-f * dt).rem_euclid(1.0));
            let (mut zr, mut zi) = (c0, s0);
            let (mut ar, mut ai) = (0.0, 0.0);
            for &v in &x {
                ar += v * zr;
                ai += v * zi;
                (zr, zi) = (zr * cw - zi * sw, zr * sw + zi * cw);
            }
            (ar * dt, ai * dt)
        })
        .collect()
}

impl Fabric {
    pub fn new(spec: &FabricSpec, ow: usize, oh: usize, seed: u64) -> Result<Self, SimError> {
        spec.validate()?;
        let modes = spec.modes();
        let [u0, s0, u1, s1] = spec.view;
        let us: Vec<f64> = (0..ow)
            .map(|c| u0 + (u1 - u0) * (c as f64 + 0.5) / ow as f64)
            .collect();
        let ss: Vec<f64> = (0..oh)
            .map(|r| s0 + (s1 - s0) * (r as f64 + 0.5) / oh as f64)
            .collect();
        let n_across = spec.modes_across as usize + 1;
        let across: Vec<Vec<f64>> = (0..n_across)
            .map(|m| {
                us.iter()
                    .map(|&u| {
                        detmath::sin_cos_turns(0.5 * m as f64 * u).1
                            * (1.0 + spec.perspective * (u - 0.5))
                    })
                    .collect()
            })
            .collect();
        let along: Vec<Vec<f64>> = (1..=spec.modes_along)
            .map(|n| {
                let j = bessel_j0_zero(n);
                ss.iter()
                    .map(|&s| bessel_j0(j * (1.0 - s).max(0.0).sqrt()))
                    .collect()
            })
            .collect();

        // Generalised force per mode: ambient = independent unit forces;
        // sound = the projection of a pressure 1 + 0.3 (u - 1/2) on the shape.
        let projection = |md: &FabricMode| -> f64 {
            let k = 400;
            let (mut num, mut den) = (0.0, 0.0);
            for i in 0..k {
                let u = (i as f64 + 0.5) / k as f64;
                let x = detmath::sin_cos_turns(0.5 * md.across as f64 * u).1;
                num += (1.0 + 0.3 * (u - 0.5)) * x;
                den += x * x;
            }
            let (mut ny, mut dy) = (0.0, 0.0);
            let j = bessel_j0_zero(md.along);
            for i in 0..k {
                let s = (i as f64 + 0.5) / k as f64;
                let y = bessel_j0(j * (1.0 - s).sqrt());
                ny += y;
                dy += y * y;
            }
            (num / den) * (ny / dy)
        };
        let participation: Vec<f64> = modes
            .iter()
            .map(|md| match spec.excitation {
                Excitation::Ambient | Excitation::Kick => 1.0,
                Excitation::Sound => projection(md),
            })
            .collect();
        // The mode's response to a unit force line: px at unit shape,
        // H = 1 / (m (ωk² - ω² + 2iξωkω)), times `a` of phase `ph` turns.
        let respond = |md: &FabricMode, f: f64, a: f64, ph: f64| -> (f64, f64) {
            let wk = 2.0 * PI * md.freq_hz;
            let w = 2.0 * PI * f;
            let (re, im) = (wk * wk - w * w, 2.0 * md.damping * wk * w);
            let d = md.mass_kg_m2 * (re * re + im * im);
            let (hr, hi) = (re / d, -im / d);
            let (s, c) = detmath::sin_cos_turns(ph);
            (a * (hr * c - hi * s), a * (hr * s + hi * c))
        };

        let mut rng = Xoshiro256::new(hash2(seed ^ 0x6661_6272_6963, 0));
        let freqs: Vec<f64> = (0..LINES)
            .map(|j| (j as f64 + 0.25 + 0.5 * rng.next_f64()) * LINE_SPACING_HZ)
            .collect();
        let shared: Vec<(f64, f64)> = freqs.iter().map(|&f| spec.force(f, &mut rng)).collect();
        let mut coef: Vec<Vec<(f64, f64)>> = Vec::with_capacity(modes.len());
        for (k, md) in modes.iter().enumerate() {
            let mut mrng = Xoshiro256::new(hash2(seed ^ 0x6661_6272_6963, 1 + k as u64));
            let row = freqs
                .iter()
                .zip(&shared)
                .map(|(&f, &(amp, ph))| {
                    let ph = match spec.excitation {
                        Excitation::Ambient | Excitation::Kick => mrng.next_f64(),
                        Excitation::Sound => ph,
                    };
                    respond(md, f, amp * participation[k], ph)
                })
                .collect();
            coef.push(row);
        }
        let ms = |coef: &[Vec<(f64, f64)>]| grid_mean_square(coef, &modes, &along, &across, ow, oh);
        // Kick: the sweep's lines through each mode's projection, at
        // `kick_db` over the ambient part's power; the two add.
        let mut kick = None;
        if spec.excitation == Excitation::Kick {
            let x = sweep_lines(spec, &freqs);
            let mut kc: Vec<Vec<(f64, f64)>> = modes
                .iter()
                .map(|md| {
                    let p = projection(md);
                    freqs
                        .iter()
                        .zip(&x)
                        .map(|(&f, &(xr, xi))| {
                            let (hr, hi) = respond(md, f, p, 0.0);
                            (hr * xr - hi * xi, hr * xi + hi * xr)
                        })
                        .collect()
                })
                .collect();
            let (ma, mk) = (ms(&coef), ms(&kc));
            let g = if mk > 0.0 {
                (detmath::exp(spec.kick_db / 10.0 * std::f64::consts::LN_10) * ma / mk).sqrt()
            } else {
                0.0
            };
            for (row, krow) in coef.iter_mut().zip(kc.iter_mut()) {
                for (v, kv) in row.iter_mut().zip(krow.iter_mut()) {
                    kv.0 *= g;
                    kv.1 *= g;
                    v.0 += kv.0;
                    v.1 += kv.1;
                }
            }
            kick = Some(kc);
        }

        // Scale: √2 × RMS displacement over an 8x8 grid of the object = amplitude_px.
        let rms = ms(&coef).sqrt();
        let scale = if rms > 0.0 {
            spec.amplitude_px / (2f64.sqrt() * rms)
        } else {
            0.0
        };
        if let Some(kc) = kick.as_mut() {
            for v in kc.iter_mut().flatten() {
                v.0 *= scale;
                v.1 *= scale;
            }
        }
        let mut peak = 0.0;
        for (k, md) in modes.iter().enumerate() {
            let pa = along[md.along as usize - 1]
                .iter()
                .fold(0.0f64, |m, v| m.max(v.abs()));
            let pc = across[md.across as usize]
                .iter()
                .fold(0.0f64, |m, v| m.max(v.abs()));
            let mut sum = 0.0;
            for v in coef[k].iter_mut() {
                v.0 *= scale;
                v.1 *= scale;
                sum += v.0.hypot(v.1);
            }
            peak += pa * pc * sum;
        }
        let interp = Interp::new(super::texture::OBJECT_SIGMA_PX);
        let taps = (0..=TAP_STEPS)
            .map(|i| interp.taps_f32_reversed(i as f64 / TAP_STEPS as f64))
            .collect();
        Ok(Self {
            z: vec![(0.0, 0.0); LINES],
            q: vec![0.0; modes.len()],
            rows: vec![0.0; n_across * oh],
            row_d: vec![0.0; ow],
            freqs,
            coef,
            along,
            across,
            n_across,
            modes,
            peak,
            taps,
            q_t: f64::NAN,
            coherent: spec.excitation == Excitation::Sound,
            kick,
        })
    }

    /// The modes (frequency, damping, mass), in the order of the coordinates.
    pub fn modes(&self) -> &[FabricMode] {
        &self.modes
    }

    /// The expected motion power spectrum of thesis Eq. 3.17 with nothing
    /// between the cloth and the spectrum: the object cut into `tiles` x
    /// `tiles` equal parts, each part's mean displacement, their power
    /// spectra added; no texture, sensor, pyramid or estimation noise, the
    /// expectation over the forcing's random phases (ambient: the modes'
    /// powers add; sound: one field, their amplitudes add; kick: both). One value per
    /// excitation line, px² (line `j` lies within 0.005 Hz of
    /// `(j + 1/2) ·` [`LINE_SPACING_HZ`]). What the features could see at
    /// best: the learning bound of `docs/learning.md`.
    pub fn expected_tile_power(&self, tiles: usize) -> Vec<f64> {
        let mut power = vec![0.0; self.freqs.len()];
        for w in self.tile_shapes(tiles) {
            for (j, p) in power.iter_mut().enumerate() {
                if self.coherent {
                    let (mut re, mut im) = (0.0, 0.0);
                    for (wk, row) in w.iter().zip(&self.coef) {
                        re += wk * row[j].0;
                        im += wk * row[j].1;
                    }
                    *p += 0.5 * (re * re + im * im);
                } else if let Some(kick) = &self.kick {
                    // Ambient (the rest of `coef`) plus one field.
                    let (mut re, mut im) = (0.0, 0.0);
                    for ((wk, row), krow) in w.iter().zip(&self.coef).zip(kick) {
                        let (kr, ki) = krow[j];
                        let (ar, ai) = (row[j].0 - kr, row[j].1 - ki);
                        *p += 0.5 * wk * wk * (ar * ar + ai * ai);
                        re += wk * kr;
                        im += wk * ki;
                    }
                    *p += 0.5 * (re * re + im * im);
                } else {
                    for (wk, row) in w.iter().zip(&self.coef) {
                        let (re, im) = row[j];
                        *p += 0.5 * wk * wk * (re * re + im * im);
                    }
                }
            }
        }
        power
    }

    /// The object cut into `tiles` x `tiles` equal parts (row-major): per
    /// part, each mode's shape averaged over it (at least one sample), so
    /// that a part's mean displacement is `Σ_k shape[k] · q_k` with `q` the
    /// [`Fabric::coordinates`].
    pub fn tile_shapes(&self, tiles: usize) -> Vec<Vec<f64>> {
        let tiles = tiles.max(1);
        let part = |v: &[f64], i: usize| -> f64 {
            let n = v.len();
            let a = i * n / tiles;
            let b = ((i + 1) * n / tiles).max(a + 1).min(n);
            if a >= b {
                0.0
            } else {
                v[a..b].iter().sum::<f64>() / (b - a) as f64
            }
        };
        let mut out = Vec::with_capacity(tiles * tiles);
        for tr in 0..tiles {
            for tc in 0..tiles {
                out.push(
                    self.modes
                        .iter()
                        .map(|md| {
                            part(&self.along[md.along as usize - 1], tr)
                                * part(&self.across[md.across as usize], tc)
                        })
                        .collect(),
                );
            }
        }
        out
    }

    /// The modal coordinates at `t_s` (px at unit shape), in the order of
    /// [`Fabric::modes`]: what every pixel's displacement is made of.
    pub fn coordinates(&mut self, t_s: f64) -> &[f64] {
        self.phasors(t_s);
        &self.q
    }

    /// An upper bound of |displacement| anywhere, px.
    pub fn peak_bound(&self) -> f64 {
        self.peak
    }

    fn phasors(&mut self, t_s: f64) {
        if t_s == self.q_t {
            return;
        }
        self.q_t = t_s;
        for (z, &f) in self.z.iter_mut().zip(&self.freqs) {
            let (s, c) = detmath::sin_cos_turns((f * t_s).rem_euclid(1.0));
            *z = (c, s);
        }
        for (q, row) in self.q.iter_mut().zip(&self.coef) {
            *q = row
                .iter()
                .zip(&self.z)
                .map(|(&(a, b), &(c, s))| a * c - b * s)
                .sum();
        }
    }

    /// Horizontal image displacement (px, +x right) of object pixel `(c, r)` at `t_s`.
    pub fn displacement_px(&mut self, c: usize, r: usize, t_s: f64) -> f64 {
        self.phasors(t_s);
        self.modes
            .iter()
            .zip(&self.q)
            .map(|(md, q)| {
                self.along[md.along as usize - 1]
                    .get(r)
                    .copied()
                    .unwrap_or(0.0)
                    * self.across[md.across as usize]
                        .get(c)
                        .copied()
                        .unwrap_or(0.0)
                    * q
            })
            .sum()
    }

    /// Renders the zero-mean object (`ow x oh`, row-major) at `t_s` into `out`.
    pub(super) fn render(
        &mut self,
        t_s: f64,
        lat: &super::modal::Lattice<'_>,
        oh: usize,
        out: &mut [f32],
    ) {
        self.phasors(t_s);
        let ow = self.across.first().map_or(0, |a| a.len());
        let na = self.n_across;
        self.rows.fill(0.0);
        for (md, &q) in self.modes.iter().zip(&self.q) {
            let m = md.across as usize;
            for (r, &y) in self.along[md.along as usize - 1].iter().enumerate() {
                self.rows[r * na + m] += y * q;
            }
        }
        // Each pixel's sums are made in the order they always were (over
        // the modes, then over the taps), several pixels side by side.
        if self.row_d.len() != ow {
            self.row_d.resize(ow, 0.0);
        }
        let row_d = &mut self.row_d[..];
        for r in 0..oh {
            let sums = &self.rows[r * na..(r + 1) * na];
            let grow = &lat.grid[(r + lat.pad) * lat.gw..(r + lat.pad + 1) * lat.gw];
            row_d.fill(0.0);
            for (across, &s) in self.across.iter().zip(sums) {
                for (d, &a) in row_d.iter_mut().zip(&across[..ow]) {
                    *d += a * s;
                }
            }
            // Pixel `c`'s two neighbouring tap sets, the weight between
            // them and its window of the texture.
            let taps = &self.taps;
            let pixel = |c: usize| {
                let d = row_d[c].clamp(-lat.amp_max, lat.amp_max);
                let i = d.floor();
                let x = (d - i) * TAP_STEPS as f64;
                let b = (x as usize).min(TAP_STEPS - 1);
                let w = (x - b as f64) as f32;
                // Lattice column k = c - i; its window starts at grid column k - PAD + pad.
                let g0 = (c as i64 - i as i64 - PAD as i64 + lat.pad as i64) as usize;
                (&taps[b], &taps[b + 1], w, &grow[g0..g0 + TAPS])
            };
            // (A row's last lanes past its end repeat its last pixel.)
            let out = &mut out[r * ow..(r + 1) * ow];
            for (k, o) in out.chunks_mut(LANES).enumerate() {
                let p: [_; LANES] = std::array::from_fn(|j| pixel((k * LANES + j).min(ow - 1)));
                let mut v = [0.0f32; LANES];
                for s in 0..TAPS {
                    for (v, (t0, t1, w, win)) in v.iter_mut().zip(&p) {
                        *v += (t0[s] + w * (t1[s] - t0[s])) * win[s];
                    }
                }
                o.copy_from_slice(&v[..o.len()]);
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// Under sound the expected power is the realised one (one field, its
    /// phases fixed): Parseval against the mean square of each part's mean
    /// displacement at random times.
    #[test]
    fn expected_tile_power_is_the_parts_mean_square() {
        let spec = FabricSpec {
            excitation: Excitation::Sound,
            modes_along: 3,
            modes_across: 1,
            ..FabricSpec::default()
        };
        let (ow, oh) = (8, 6);
        let mut f = Fabric::new(&spec, ow, oh, 3).unwrap();
        let want: f64 = f.expected_tile_power(2).iter().sum();
        let mut rng = Xoshiro256::new(11);
        let n = 20_000;
        let mut got = 0.0;
        for _ in 0..n {
            let t = 1e6 * rng.next_f64();
            for (r0, r1, c0, c1) in [(0, 3, 0, 4), (0, 3, 4, 8), (3, 6, 0, 4), (3, 6, 4, 8)] {
                let mut m = 0.0;
                for r in r0..r1 {
                    for c in c0..c1 {
                        m += f.displacement_px(c, r, t);
                    }
                }
                m /= ((r1 - r0) * (c1 - c0)) as f64;
                got += m * m;
            }
        }
        got /= n as f64;
        assert!((got / want - 1.0).abs() < 0.05, "{got} vs {want}");
        // Ambient: the modes' powers add, whatever the phases drawn.
        let amb = Fabric::new(
            &FabricSpec {
                excitation: Excitation::Ambient,
                ..spec
            },
            ow,
            oh,
            3,
        )
        .unwrap();
        let one = amb.expected_tile_power(1);
        assert_eq!(one.len(), LINES);
        assert!(one.iter().all(|p| p.is_finite() && *p >= 0.0));
    }

    /// A part's mean displacement is its shapes times the coordinates
    /// (what `learn evaluate --true-motion` measures), parts row-major.
    #[test]
    fn tile_shapes_times_coordinates_are_the_parts_mean_displacement() {
        let spec = FabricSpec {
            excitation: Excitation::Kick,
            ..FabricSpec::default()
        };
        let (ow, oh) = (9, 7);
        let mut f = Fabric::new(&spec, ow, oh, 5).unwrap();
        let shapes = f.tile_shapes(2);
        assert_eq!(shapes.len(), 4);
        let mut moved = 0.0;
        for t in [0.0, 0.37, 12.5, 31.25] {
            let q = f.coordinates(t).to_vec();
            for (i, (r0, r1, c0, c1)) in [(0, 3, 0, 4), (0, 3, 4, 9), (3, 7, 0, 4), (3, 7, 4, 9)]
                .into_iter()
                .enumerate()
            {
                let mut m = 0.0;
                for r in r0..r1 {
                    for c in c0..c1 {
                        m += f.displacement_px(c, r, t);
                    }
                }
                m /= ((r1 - r0) * (c1 - c0)) as f64;
                let got: f64 = shapes[i].iter().zip(&q).map(|(w, q)| w * q).sum();
                assert!((got - m).abs() < 1e-9, "part {i} at {t} s: {got} vs {m}");
                moved += m.abs();
            }
        }
        assert!(moved > 1e-3, "the cloth should move: {moved}");
    }

    /// The kick is a transient where `kick_at_s` says, at `kick_db` over
    /// the ambient part, and the expectation adds the two parts.
    #[test]
    fn the_kick_rings_when_it_is_played_over_the_ambient_forcing() {
        let spec = FabricSpec {
            excitation: Excitation::Kick,
            kick_db: 20.0,
            kick_at_s: 20.0,
            modes_along: 6,
            modes_across: 1,
            ..FabricSpec::default()
        };
        let (ow, oh) = (8, 8);
        let mut f = Fabric::new(&spec, ow, oh, 5).unwrap();
        let mut ms = |t0: f64, t1: f64| {
            let n = 400;
            (0..n)
                .map(|i| {
                    let d = f.displacement_px(4, 6, t0 + (t1 - t0) * i as f64 / n as f64);
                    d * d
                })
                .sum::<f64>()
                / n as f64
        };
        let (before, during, later) = (ms(8.0, 18.0), ms(20.0, 22.0), ms(35.0, 45.0));
        // 20 dB over the 50 s period, most of it in a few seconds.
        assert!(during > 30.0 * before, "{during} vs {before}");
        assert!(during > 30.0 * later, "{during} vs {later}");
        // The expected power is the ambient part's plus the kick's, so it
        // exceeds the ambient part alone by about the kick's share.
        let amb = FabricSpec {
            excitation: Excitation::Ambient,
            ..spec.clone()
        };
        let quiet = FabricSpec {
            kick_db: -40.0,
            ..spec.clone()
        };
        let sum = |s: &FabricSpec| -> f64 {
            Fabric::new(s, ow, oh, 5)
                .unwrap()
                .expected_tile_power(2)
                .iter()
                .sum()
        };
        let (a, q) = (sum(&amb), sum(&quiet));
        assert!((q / a - 1.0).abs() < 0.02, "{q} vs {a}");
        let bad = FabricSpec {
            kick_at_s: 49.5,
            ..spec.clone()
        };
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .contains("kick_at_s"));
        let bad = FabricSpec {
            kick_hz: [100.0, 15.0],
            ..spec
        };
        assert!(bad.validate().unwrap_err().to_string().contains("kick_hz"));
    }

    #[test]
    fn j1_is_minus_the_derivative_of_j0() {
        for i in 1..200 {
            let x = i as f64 * 0.1 + 0.05;
            let d = (bessel_j0(x + 1e-4) - bessel_j0(x - 1e-4)) / 2e-4;
            assert!((d + bessel_j1(x)).abs() < 2e-6, "x {x}");
        }
    }

    #[test]
    fn bending_quotient_of_a_cosine_like_shape_is_positive_and_grows() {
        let q: Vec<f64> = (1..=6)
            .map(|n| bending_quotient(bessel_j0_zero(n), 0.78, 0.0))
            .collect();
        assert!(q.windows(2).all(|w| w[1] > w[0]), "{q:?}");
    }

    #[test]
    fn j0_and_its_zeros_agree() {
        for n in 1..=40 {
            let z = bessel_j0_zero(n);
            assert!(
                bessel_j0(z).abs() < 2e-6,
                "n {n}: J0({z}) = {}",
                bessel_j0(z)
            );
        }
        assert!((bessel_j0(0.0) - 1.0).abs() < 1e-7);
        assert!((bessel_j0(1.0) - 0.765_197_686_6).abs() < 1e-7);
        assert!((bessel_j0(10.0) + 0.245_935_764_5).abs() < 1e-7);
    }

    #[test]
    fn limp_fabric_in_vacuum_is_a_hanging_chain() {
        // B -> 0, no air: f_n = j_n √(g / L) / (4π), independent of weight.
        let s = FabricSpec {
            stiffness_nm: 1e-12,
            air_density: 1e-9,
            ..FabricSpec::default()
        };
        let m = s.modes();
        let f1 = bessel_j0_zero(1) * (G / s.length_m).sqrt() / (4.0 * PI);
        assert!(
            (m[0].freq_hz - f1).abs() < 1e-4 * f1,
            "{} vs {f1}",
            m[0].freq_hz
        );
        let heavy = FabricSpec {
            area_weight_kg_m2: 0.4,
            ..s.clone()
        };
        assert!((heavy.modes()[0].freq_hz - f1).abs() < 1e-4 * f1);
    }

    #[test]
    fn stiffer_and_heavier_fabrics_ring_higher() {
        let base = FabricSpec::default();
        let f = |s: &FabricSpec| s.modes()[3 * 10].freq_hz;
        let stiff = FabricSpec {
            stiffness_nm: 1e-4,
            ..base.clone()
        };
        let heavy = FabricSpec {
            area_weight_kg_m2: 0.4,
            ..base.clone()
        };
        assert!(f(&stiff) > 1.05 * f(&base));
        // The fundamental: less of its inertia is air.
        assert!(heavy.modes()[0].freq_hz > 1.2 * base.modes()[0].freq_hz);
        // Heavier cloth: less air damping.
        assert!(heavy.modes()[0].damping < base.modes()[0].damping);
    }

    #[test]
    fn amplitude_is_the_stated_rms_and_deterministic() {
        let spec = FabricSpec {
            amplitude_px: 0.4,
            ..FabricSpec::default()
        };
        let mut a = Fabric::new(&spec, 16, 16, 7).unwrap();
        let mut b = Fabric::new(&spec, 16, 16, 7).unwrap();
        assert_eq!(
            a.displacement_px(3, 9, 1.234),
            b.displacement_px(3, 9, 1.234)
        );
        // Time average over 200 s at the 8x8 points the scale was set on.
        let n = 2000;
        let mut ms = 0.0;
        for i in 0..n {
            let t = i as f64 * 0.1 + 0.013;
            for r in (1..16).step_by(2) {
                for c in (1..16).step_by(2) {
                    ms += a.displacement_px(c, r, t).powi(2);
                }
            }
        }
        let amp = (2.0 * ms / (n * 64) as f64).sqrt();
        assert!((amp - 0.4).abs() < 0.06, "{amp}");
        assert!(a.peak_bound() >= 0.4);
    }

    #[test]
    fn bad_fields_are_named() {
        let e = FabricSpec {
            area_weight_kg_m2: 0.0,
            ..FabricSpec::default()
        }
        .validate()
        .unwrap_err();
        assert_eq!(e.field(), "fabric.area_weight_kg_m2");
    }
}
