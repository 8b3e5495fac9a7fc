//! The scene and the camera: a band-limited textured object translating
//! sub-pixel over a still background, sampled with a global or rolling
//! shutter, plus Gaussian sensor noise and quantisation.
//!
//! # Model
//! Frame coordinates put pixel `(x, y)`'s centre at `(x, y)`, `x` rightwards,
//! `y` downwards, top row first. At time `t` the object is displaced by
//! `d(t) = amplitude_px · signal(t)` along `(cos θ, sin θ)`; the pixel shows
//!
//! ```text
//! I(x, y) = mean_obj + T(x - ox - d·cos θ, y - oy - d·sin θ)   inside the object
//!         = B(x, y)                                             elsewhere
//! ```
//!
//! where `T` is the object's continuous texture ([`super::texture`], std
//! `contrast` DN over the object, mean half of full scale) and `B` the
//! background (σ = 2.5 px texture, half the contrast, mean 40% of full
//! scale). Then `round(clamp(I + n, 0, 2^bits - 1))`, `n ~ N(0, noise_std²)`.
//!
//! Regions of rows may move with a lag ([`SceneSpec::row_lag_s`]: two objects
//! stacked vertically that hear a sound at different times, or a
//! non-rigid one): row `y` then shows `d(t - lag(y))`, where `t` is the
//! row's capture time (the frame's, or `t_s + y · line_delay_s` with a
//! rolling shutter).
//!
//! "Inside the object" depends on the [`EdgeMode`]. By default
//! ([`EdgeMode::Fixed`]) it is the rest rectangle: the textured surface moves
//! within its outline, so every one of the `w·h` object pixels carries the
//! same kind of motion signal and none other does — the SNR of a motion
//! estimator then follows Eq. 4.3 (`∝ |D_p| √n_p / σ_n`) exactly. With
//! [`EdgeMode::Moving`] the outline translates with the texture and edge
//! pixels mix object and background by their exact area coverage (hard,
//! anti-aliased edges); the edges then add a perimeter term to the signal
//! (an object/background step is ~10× a texture gradient), which bends the
//! `√n_p` law for small objects.
//!
//! # Cost
//! Global shutter: one 16-tap horizontal pass over the object's rows and
//! one 16-tap vertical pass (skipped when a component of the shift is an
//! integer), then noise and quantisation over the frame; no allocation per
//! frame. Rolling shutter (and row lags) filters each row on its own (up
//! to 17·16 MACs per object pixel when both shift components are
//! fractional).
//!
//! Benchmark: `cargo test --release bench_render_speed -- --nocapture`
//! (on the 2-core dev machine: ~240 Mpix/s global shutter with noise,
//! ~900 without noise, ~75 for rolling shutter at 30° with exposure).

use super::rng::{hash2, Xoshiro256, Ziggurat};
use super::texture::{Interp, Texture};
use super::{Signal, SimError};

pub use super::texture::OBJECT_SIGMA_PX;

mod build;
mod motion;
mod output;
mod render;
mod spec;
mod surround;

pub use build::{BACKGROUND_CONTRAST, BACKGROUND_MEAN, OBJECT_MEAN};
pub use motion::EXPOSURE_SUBSAMPLES;
pub use output::Dest;
pub use spec::{
    EdgeMode, Look, SceneSpec, BACKGROUND_SIGMA_PX, MAX_AMPLITUDE_PX, MAX_ROW_LAGS, MAX_ROW_LAG_S,
};
pub use surround::{LightSpec, MotionSpec, MoverSpec, SurroundSpec, MAX_LIGHT_DEPTH, MAX_MOVERS};

use output::{dest_out, quantise, Out};

/// Storage depth of output pixels (the video crate's).
pub use vibroscope_io::Depth;

#[derive(Clone, Copy, Debug)]
enum Timing {
    /// One displacement (px) for the whole frame.
    Global(f64),
    /// A modal beam's column-wise displacement at this time ([`super::modal`]).
    Modal(f64),
    Rolling {
        t_s: f64,
        line_delay_s: f64,
        exposure_s: f64,
    },
}

/// Everything fixed after construction.
struct Model {
    spec: SceneSpec,
    signal: Signal,
    edges: EdgeMode,
    w: usize,
    h: usize,
    ox: usize,
    oy: usize,
    ow: usize,
    oh: usize,
    dir: (f64, f64),
    amp_max: f64,
    full: f32,
    obj_mean: f32,
    tex: Texture,
    tex_shift: f64,
    tex_scale: f64,
    /// Lattice margin of `grid` on every side.
    pad: usize,
    /// Zero-mean object texture in DN on lattice `[-pad, ow + pad) x [-pad, oh + pad)`.
    grid: Vec<f32>,
    gw: usize,
    /// Background in DN, `w x h`.
    bg: Vec<f32>,
    /// Object coverage per frame pixel (see [`Look::mask`]).
    mask: Option<Vec<f32>>,
    interp: Interp,
    zig: Ziggurat,
    noise_key: u64,
    modal: Option<super::ModalBeam>,
    fabric: Option<super::Fabric>,
    /// Effects outside the object ([`surround`]), if any.
    surround: Option<surround::Surroundings>,
    /// The camera's shift for the frame or row being drawn (px).
    cam: (f64, f64),
}

/// Per-frame working memory, allocated once.
struct Scratch {
    hbuf: Vec<f32>,
    rows8: Vec<f32>,
    obj: Vec<f32>,
    covx: Vec<f32>,
    line: Vec<f32>,
    noise: Vec<f32>,
    /// The modal beam's object, `ow x oh` (empty without one).
    modal_obj: Vec<f32>,
    /// The object's interpolator's taps for this frame's shifts.
    taps: crate::texture::TapMemo,
}

/// The forward model: see the module docs.
pub struct Scene {
    m: Model,
    s: Scratch,
}

impl Scene {
    /// Chooses what happens at the object's outline (default [`EdgeMode::Fixed`]).
    pub fn with_edges(mut self, edges: EdgeMode) -> Self {
        self.m.edges = edges;
        self
    }

    pub fn edge_mode(&self) -> EdgeMode {
        self.m.edges
    }

    pub fn spec(&self) -> &SceneSpec {
        &self.m.spec
    }

    pub fn signal(&self) -> &Signal {
        &self.m.signal
    }

    /// Unit vector of the motion, `(cos θ, sin θ)` (+y is down).
    pub fn direction(&self) -> (f64, f64) {
        self.m.dir
    }

    /// Mean level of the object in DN.
    pub fn object_mean_dn(&self) -> f64 {
        self.m.obj_mean as f64
    }

    /// Ground-truth displacement (px, along the direction) at time `t_s`
    /// (of the rows without a lag, [`SceneSpec::row_lag_s`]).
    pub fn displacement_px(&self, t_s: f64) -> f64 {
        self.m.displacement(t_s)
    }

    /// The motion's lag (s) in row `y`: that of the last region of
    /// [`SceneSpec::row_lag_s`] starting at or above it, 0 above them all.
    /// The camera's shift `(x, y)` at `t_s` (px; zero without one).
    pub fn camera_shift_px(&self, t_s: f64) -> (f64, f64) {
        self.m
            .surround
            .as_ref()
            .map_or((0.0, 0.0), |su| su.camera_shift(t_s))
    }

    pub fn row_lag_s(&self, y: u32) -> f64 {
        self.m.row_lag(y as usize)
    }

    /// The motion's gain in row `y`: that of the last region of
    /// [`SceneSpec::row_lag_s`] starting at or above it
    /// ([`SceneSpec::row_gain`]), 1 above them all.
    pub fn row_gain(&self, y: u32) -> f64 {
        self.m.row_gain(y as usize)
    }

    /// Ground-truth displacement of row `y`: the mean of the displacement
    /// over `[t_row, t_row + exposure_s]` with
    /// `t_row = t_s + y · line_delay_s - lag(y)` and the row's lag
    /// [`Scene::row_lag_s`] (a midpoint rule with [`EXPOSURE_SUBSAMPLES`]
    /// points; the instant `t_row` when `exposure_s` is 0). Non-finite
    /// delays count as 0, as do negative exposures. A global-shutter frame
    /// rendered at `t_s` shows this with `line_delay_s` and `exposure_s` 0.
    pub fn row_displacement_px(&self, t_s: f64, y: u32, line_delay_s: f64, exposure_s: f64) -> f64 {
        self.m
            .row_displacement(t_s, y as usize, line_delay_s, exposure_s)
    }

    /// The object's noise-free intensity (DN) at object-local point
    /// `(u, v)` — `(0, 0)` is the centre of its top-left pixel at rest —
    /// evaluated directly from the continuous texture (slow; for tests).
    pub fn texture_value(&self, u: f64, v: f64) -> f64 {
        let m = &self.m;
        m.obj_mean as f64 + (m.tex.raw_at(u, v) - m.tex_shift) * m.tex_scale
    }

    /// The noise-free intensity the object shows at frame pixel `(x, y)`
    /// when displaced by `d_px`, from the continuous texture (slow).
    pub fn object_value(&self, x: f64, y: f64, d_px: f64) -> f64 {
        let m = &self.m;
        self.texture_value(
            x - m.ox as f64 - d_px * m.dir.0,
            y - m.oy as f64 - d_px * m.dir.1,
        )
    }

    /// The background's intensity (DN) at pixel `(x, y)`.
    pub fn background_value(&self, x: u32, y: u32) -> f64 {
        let m = &self.m;
        m.bg.get(y as usize * m.w + x as usize)
            .map_or(0.0, |&v| v as f64)
    }

    /// Checks that `dst` holds a whole frame of the spec's depth.
    pub fn check_dest(&self, dst: &Dest<'_>) -> Result<(), SimError> {
        let need = self.m.w * self.m.h;
        if dst.len() != need {
            return Err(SimError::Invalid {
                field: "dst".into(),
                msg: format!("holds {} pixels, the frame has {need}", dst.len()),
            });
        }
        if dst.depth() != self.m.spec.depth {
            return Err(SimError::Invalid {
                field: "dst".into(),
                msg: format!(
                    "is {:?}, the scene renders {:?}",
                    dst.depth(),
                    self.m.spec.depth
                ),
            });
        }
        Ok(())
    }

    /// Renders frame `index` captured at `t_s` with a global shutter (one
    /// displacement for the whole frame, or one per region of
    /// [`SceneSpec::row_lag_s`]) into `dst`. Noise depends only on
    /// `(seed, index)`. A `dst` of the other depth gets values clamped to its
    /// own range too; a short `dst` gets its whole rows only.
    pub fn render(&mut self, index: u64, t_s: f64, dst: Dest<'_>) {
        let timing = self.timing(t_s);
        self.run(Some(index), t_s, timing, dest_out(dst));
    }

    /// Rolling shutter (thesis Eq. 4.4): row `y` shows the displacement
    /// [`Scene::row_displacement_px`]`(t_s, y, line_delay_s, exposure_s)`
    /// (row lags included). With zero delay and exposure this equals
    /// [`Scene::render`] bit for bit.
    pub fn render_rows(
        &mut self,
        index: u64,
        t_s: f64,
        line_delay_s: f64,
        exposure_s: f64,
        dst: Dest<'_>,
    ) {
        let timing = Timing::Rolling {
            t_s,
            line_delay_s,
            exposure_s,
        };
        self.run(Some(index), t_s, timing, dest_out(dst));
    }

    /// Like [`Scene::render`] with an explicit displacement (px) instead of
    /// a time, the same for every row (row lags do not apply).
    pub fn render_displaced(&mut self, index: u64, d_px: f64, dst: Dest<'_>) {
        self.run(Some(index), 0.0, Timing::Global(d_px), dest_out(dst));
    }

    /// The noise-free, unquantised frame (DN) at `t_s`, global shutter.
    pub fn render_clean(&mut self, t_s: f64, dst: &mut [f32]) {
        let timing = self.timing(t_s);
        self.run(None, t_s, timing, Out::F32(dst));
    }

    /// The modal beam, if the object is one.
    pub fn modal(&self) -> Option<&super::ModalBeam> {
        self.m.modal.as_ref()
    }

    /// The hanging fabric, if the object is one.
    pub fn fabric(&self) -> Option<&super::Fabric> {
        self.m.fabric.as_ref()
    }

    fn timing(&self, t_s: f64) -> Timing {
        if self.m.modal.is_some() || self.m.fabric.is_some() {
            Timing::Modal(t_s)
        } else if !self.m.spec.row_lag_s.is_empty() {
            // Rows differ: the per-row path at the frame's one capture time.
            Timing::Rolling {
                t_s,
                line_delay_s: 0.0,
                exposure_s: 0.0,
            }
        } else {
            Timing::Global(self.displacement_px(t_s))
        }
    }

    /// The noise-free, unquantised frame (DN) for displacement `d_px`.
    pub fn render_clean_displaced(&mut self, d_px: f64, dst: &mut [f32]) {
        self.run(None, 0.0, Timing::Global(d_px), Out::F32(dst));
    }

    /// The noise-free, unquantised rolling-shutter frame (DN).
    pub fn render_rows_clean(
        &mut self,
        t_s: f64,
        line_delay_s: f64,
        exposure_s: f64,
        dst: &mut [f32],
    ) {
        let timing = Timing::Rolling {
            t_s,
            line_delay_s,
            exposure_s,
        };
        self.run(None, t_s, timing, Out::F32(dst));
    }

    /// Draws a frame: `t_s` is its capture time (the surroundings' clock;
    /// `timing` says how the object moves).
    fn run(&mut self, index: Option<u64>, t_s: f64, timing: Timing, mut out: Out<'_>) {
        let Scene { m, s } = self;
        let w = m.w;
        let rows = (out.len() / w).min(m.h);
        let std = m.spec.noise_std;
        let mut rng = match index {
            Some(i) if std > 0.0 => Some(Xoshiro256::new(hash2(m.noise_key, i))),
            _ => None,
        };
        // The camera's shift at the frame's time (each row's own, below,
        // with a rolling shutter); the object moves with it.
        m.cam = m
            .surround
            .as_ref()
            .map_or((0.0, 0.0), |su| su.camera_shift(t_s));
        if let Some(su) = m.surround.as_mut() {
            su.begin_frame(w, index);
        }
        let global = match timing {
            Timing::Global(d) => m.prepare_global(d, s),
            Timing::Modal(t) => {
                m.prepare_modal(t, &mut s.modal_obj);
                None
            }
            Timing::Rolling { .. } => None,
        };
        for y in 0..rows {
            // The row's capture time (a rolling shutter reads rows later).
            let t_row = match timing {
                Timing::Rolling {
                    t_s, line_delay_s, ..
                } if line_delay_s.is_finite() => t_s + y as f64 * line_delay_s,
                _ => t_s,
            };
            match m.surround.as_mut() {
                Some(su) => {
                    if matches!(timing, Timing::Rolling { .. }) {
                        m.cam = su.camera_shift(t_row);
                    }
                    su.background_row(&m.bg, w, y, (t_row, m.cam), &mut s.line);
                }
                None => s.line.copy_from_slice(&m.bg[y * w..(y + 1) * w]),
            }
            match timing {
                Timing::Global(_) => {
                    if let Some((sx, sy)) = &global {
                        m.global_row(sx, sy, s, y);
                    }
                }
                Timing::Modal(_) => m.modal_row(&s.modal_obj, y, &mut s.line),
                Timing::Rolling {
                    t_s,
                    line_delay_s,
                    exposure_s,
                } => {
                    let d = m.row_displacement(t_s, y, line_delay_s, exposure_s);
                    m.rolling_row(d, s, y);
                }
            }
            if let Some(su) = m.surround.as_ref() {
                su.light_and_rows((w, m.h), y, t_row, index, &mut s.line);
            }
            let noise = match rng.as_mut() {
                Some(r) => {
                    m.zig.fill_scaled_f32(r, std, &mut s.noise);
                    Some(&s.noise[..])
                }
                None => None,
            };
            let line = &s.line[..];
            let span = y * w..(y + 1) * w;
            match &mut out {
                Out::U8(p) => quantise(line, noise, m.full.min(255.0), &mut p[span]),
                Out::U16(p) => quantise(line, noise, m.full.min(65535.0), &mut p[span]),
                Out::F32(p) => p[span].copy_from_slice(line),
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::rng::Xoshiro256;
    use crate::SignalSpec;

    pub(super) fn tone(f: f64) -> Signal {
        Signal::new(&SignalSpec::Tone {
            freq_hz: f,
            phase_rad: 0.0,
        })
        .unwrap()
    }

    pub(super) fn spec16(w: u32, h: u32, object: [u32; 4], amp: f64, dir: f64) -> SceneSpec {
        SceneSpec {
            width: w,
            height: h,
            object,
            amplitude_px: amp,
            direction_deg: dir,
            noise_std: 0.0,
            depth: Depth::U16,
            bits: 16,
            contrast: SceneSpec::default_contrast(16),
            seed: 11,
            row_lag_s: Vec::new(),
            row_gain: Vec::new(),
        }
    }

    fn frame8(scene: &mut Scene, index: u64, t: f64) -> Vec<u8> {
        let s = scene.spec();
        let mut v = vec![0u8; (s.width * s.height) as usize];
        scene.render(index, t, Dest::U8(&mut v));
        v
    }

    fn frame16(scene: &mut Scene, index: u64, t: f64) -> Vec<u16> {
        let s = scene.spec();
        let mut v = vec![0u16; (s.width * s.height) as usize];
        scene.render(index, t, Dest::U16(&mut v));
        v
    }

    fn clean(scene: &mut Scene, d: f64) -> Vec<f32> {
        let s = scene.spec();
        let mut v = vec![0f32; (s.width * s.height) as usize];
        scene.render_clean_displaced(d, &mut v);
        v
    }

    /// 6th-order central difference along x (or y) at (x, y).
    fn grad(img: &[f64], w: usize, x: usize, y: usize, vertical: bool) -> f64 {
        let at = |k: i64| {
            let (xx, yy) = if vertical {
                (x as i64, y as i64 + k)
            } else {
                (x as i64 + k, y as i64)
            };
            img[yy as usize * w + xx as usize]
        };
        (at(3) - 9.0 * at(2) + 45.0 * at(1) - 45.0 * at(-1) + 9.0 * at(-2) - at(-3)) / 60.0
    }

    /// Least-squares shift (dx, dy) from `a` to `b` over `rect`, fitting
    /// b - a ≈ -(dx ∂x + dy ∂y) with the gradient of the midpoint image.
    fn ls_shift(a: &[f64], b: &[f64], w: usize, rect: [usize; 4]) -> (f64, f64) {
        let mid: Vec<f64> = a.iter().zip(b).map(|(p, q)| 0.5 * (p + q)).collect();
        let (mut sxx, mut sxy, mut syy, mut bx, mut by) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for y in rect[1]..rect[1] + rect[3] {
            for x in rect[0]..rect[0] + rect[2] {
                let gx = grad(&mid, w, x, y, false);
                let gy = grad(&mid, w, x, y, true);
                let dt = b[y * w + x] - a[y * w + x];
                sxx += gx * gx;
                sxy += gx * gy;
                syy += gy * gy;
                bx -= gx * dt;
                by -= gy * dt;
            }
        }
        let det = sxx * syy - sxy * sxy;
        ((syy * bx - sxy * by) / det, (sxx * by - sxy * bx) / det)
    }

    fn to_f64<T: Copy + Into<f64>>(v: &[T]) -> Vec<f64> {
        v.iter().map(|&x| x.into()).collect()
    }

    #[test]
    fn same_seed_gives_identical_bytes_and_frames_are_independent() {
        let spec = SceneSpec {
            width: 64,
            height: 48,
            object: [16, 12, 32, 24],
            amplitude_px: 0.3,
            ..SceneSpec::default()
        };
        let mut a = Scene::new(spec.clone(), tone(440.0)).unwrap();
        let mut b = Scene::new(spec.clone(), tone(440.0)).unwrap();
        let seq: Vec<Vec<u8>> = (0..6)
            .map(|k| frame8(&mut a, k, k as f64 / 2200.0))
            .collect();
        for (k, f) in seq.iter().enumerate() {
            assert_eq!(*f, frame8(&mut b, k as u64, k as f64 / 2200.0), "frame {k}");
        }
        // Frame 5 alone on a fresh scene equals frame 5 after 0..4.
        let mut c = Scene::new(spec.clone(), tone(440.0)).unwrap();
        assert_eq!(frame8(&mut c, 5, 5.0 / 2200.0), seq[5]);
        // Noise differs between frames and between seeds.
        assert_ne!(seq[0], seq[1]);
        let mut d = Scene::new(SceneSpec { seed: 2, ..spec }, tone(440.0)).unwrap();
        assert_ne!(frame8(&mut d, 0, 0.0), seq[0]);
    }

    #[test]
    fn golden_frame_checksum() {
        // Pins the whole model (textures, interpolator, noise, rounding):
        // must be identical on every platform and run.
        let spec = SceneSpec {
            width: 40,
            height: 30,
            object: [10, 8, 20, 14],
            amplitude_px: 0.37,
            direction_deg: 30.0,
            ..SceneSpec::default()
        };
        let mut s = Scene::new(spec, tone(100.0)).unwrap();
        let f = frame8(&mut s, 3, 0.0021);
        let mut h = 0xcbf2_9ce4_8422_2325u64;
        for &b in &f {
            h = (h ^ b as u64).wrapping_mul(0x100_0000_01b3);
        }
        assert_eq!(h, GOLDEN_FRAME_FNV, "checksum {h:#x}");
    }
    const GOLDEN_FRAME_FNV: u64 = 0x6aea_87ed_e2f2_120c;

    #[test]
    fn zero_amplitude_and_noise_gives_identical_frames() {
        let spec = SceneSpec {
            width: 50,
            height: 40,
            object: [5, 5, 30, 20],
            amplitude_px: 0.0,
            noise_std: 0.0,
            ..SceneSpec::default()
        };
        let mut s = Scene::new(spec, tone(440.0)).unwrap();
        let f0 = frame8(&mut s, 0, 0.0);
        for k in 1..5 {
            assert_eq!(frame8(&mut s, k, k as f64 * 1.3e-4), f0);
        }
        // And the object is actually textured, the background too.
        let distinct: std::collections::BTreeSet<u8> = f0.iter().copied().collect();
        assert!(distinct.len() > 20, "{} levels", distinct.len());
    }

    #[test]
    fn subpixel_shift_matches_the_continuous_texture() {
        // Noise-free, unquantised render vs direct evaluation of T(x - d).
        let mut worst = 0.0f64;
        let contrast = SceneSpec::default_contrast(16);
        for dir in [0.0, 30.0, 90.0, 200.0] {
            let mut s = Scene::new(spec16(48, 40, [12, 10, 24, 20], 2.0, dir), tone(1.0)).unwrap();
            for d in [0.0, 0.01, 0.1, 0.25, 0.5, 0.77, -1.3] {
                let img = clean(&mut s, d);
                for y in 10..30 {
                    for x in 12..36 {
                        let want = s.object_value(x as f64, y as f64, d);
                        worst = worst.max((img[y * 48 + x] as f64 - want).abs());
                    }
                }
            }
        }
        eprintln!(
            "render vs continuous texture: worst {worst:.4} DN at contrast {contrast:.0} DN ({:.1e} relative)",
            worst / contrast
        );
        assert!(worst < 0.05, "worst {worst} DN");
    }

    #[test]
    fn least_squares_recovers_a_quarter_pixel() {
        let (w, h) = (160usize, 120usize);
        let rect = [40u32, 30, 80, 60];
        // Tone of 1 Hz: d(0) = 0 and d(0.25 s) = amplitude exactly.
        for (amp, dir) in [
            (0.25, 0.0),
            (0.01, 0.0),
            (0.5, 0.0),
            (0.25, 90.0),
            (0.25, 45.0),
        ] {
            let mut s = Scene::new(spec16(w as u32, h as u32, rect, amp, dir), tone(1.0)).unwrap();
            assert_eq!(s.displacement_px(0.25), amp);
            let a = to_f64(&frame16(&mut s, 0, 0.0));
            let b = to_f64(&frame16(&mut s, 1, 0.25));
            let inner = [46, 36, 68, 48];
            let (dx, dy) = ls_shift(&a, &b, w, inner);
            let (ex, ey) = (amp * s.direction().0, amp * s.direction().1);
            eprintln!("amp {amp} dir {dir}: estimated ({dx:.5}, {dy:.5}), true ({ex:.5}, {ey:.5})");
            let tol = 0.02 * amp;
            assert!(
                (dx - ex).abs() < tol && (dy - ey).abs() < tol,
                "({dx}, {dy}) vs ({ex}, {ey})"
            );
        }
    }

    #[test]
    fn direction_90_moves_rows_not_columns() {
        let (w, h) = (64usize, 64usize);
        let mut s = Scene::new(spec16(64, 64, [8, 8, 48, 48], 3.0, 90.0), tone(1.0)).unwrap();
        let a = frame16(&mut s, 0, 0.0);
        let b = frame16(&mut s, 0, 0.25); // d = 3 px exactly: an integer shift
        for y in 14..50 {
            for x in 8..56 {
                assert_eq!(b[y * w + x], a[(y - 3) * w + x], "({x}, {y})");
            }
        }
        // Rows outside the object (and the background) are untouched.
        assert_eq!(a[..8 * w], b[..8 * w]);
        assert_eq!(a[(h - 8) * w..], b[(h - 8) * w..]);
        // Horizontal integer shift likewise moves columns.
        let mut s = Scene::new(spec16(64, 64, [8, 8, 48, 48], 2.0, 0.0), tone(1.0)).unwrap();
        let a = frame16(&mut s, 0, 0.0);
        let b = frame16(&mut s, 0, 0.25);
        for y in 8..56 {
            for x in 10..56 {
                assert_eq!(b[y * w + x], a[y * w + x - 2], "({x}, {y})");
            }
        }
    }

    #[test]
    fn rolling_shutter_rows_follow_their_capture_times() {
        let (w, h) = (128usize, 160usize);
        let rect = [16u32, 8, 96, 144];
        let amp = 0.3;
        let (f, ld) = (50.0, 1e-4); // rows 8..152 span 14.4 ms ≈ 0.72 period
        let mut moving = Scene::new(spec16(w as u32, h as u32, rect, amp, 0.0), tone(f)).unwrap();
        let mut still = Scene::new(spec16(w as u32, h as u32, rect, 0.0, 0.0), tone(f)).unwrap();
        let reference = to_f64(&frame16(&mut still, 0, 0.0));
        let t0 = 0.0013;
        let mut img = vec![0u16; w * h];
        moving.render_rows(0, t0, ld, 0.0, Dest::U16(&mut img));
        let img = to_f64(&img);
        let mut worst = 0.0f64;
        let mut est = Vec::new();
        for y in 12..148 {
            // Per-row LS against the still frame, x-gradient only.
            let (mut sgg, mut sgd) = (0.0, 0.0);
            for x in 22..106 {
                let g = grad(&reference, w, x, y, false);
                sgg += g * g;
                sgd -= g * (img[y * w + x] - reference[y * w + x]);
            }
            let d = sgd / sgg;
            let want = moving.row_displacement_px(t0, y as u32, ld, 0.0);
            assert!(
                (want - amp * (std::f64::consts::TAU * f * (t0 + y as f64 * ld)).sin()).abs()
                    < 1e-12
            );
            worst = worst.max((d - want).abs());
            est.push((y, d, want));
        }
        eprintln!("rolling shutter: worst row error {worst:.5} px (amplitude {amp})");
        assert!(worst < 0.02 * amp, "worst {worst}");
        // Two rows far apart see clearly different shifts, as predicted.
        let (_, d_top, w_top) = est[0];
        let (_, d_bot, w_bot) = est[est.len() - 1];
        assert!((w_top - w_bot).abs() > 0.3, "{w_top} {w_bot}");
        assert!(((d_top - d_bot) - (w_top - w_bot)).abs() < 0.02 * amp);
    }

    #[test]
    fn rolling_shutter_without_delay_equals_global_shutter() {
        for dir in [0.0, 37.0, 90.0] {
            let spec = SceneSpec {
                width: 64,
                height: 50,
                object: [10, 7, 40, 30],
                amplitude_px: 0.8,
                direction_deg: dir,
                ..SceneSpec::default()
            };
            let mut s = Scene::new(spec, tone(300.0)).unwrap();
            for k in 0..4u64 {
                let t = k as f64 * 3.1e-4;
                let g = frame8(&mut s, k, t);
                let mut r = vec![0u8; 64 * 50];
                s.render_rows(k, t, 0.0, 0.0, Dest::U8(&mut r));
                assert_eq!(g, r, "dir {dir} frame {k}");
            }
        }
    }

    /// Issue 15 (per-region lag): rows in a lagged region show the
    /// displacement at their capture time minus the lag, with a global
    /// shutter and composed with a rolling shutter and an exposure, and
    /// times before 0 (a lag longer than the capture time) are the tone's.
    #[test]
    fn lagged_rows_follow_their_lagged_times() {
        let (w, h) = (128usize, 160usize);
        let rect = [16u32, 8, 96, 144];
        let amp = 0.3;
        let f = 50.0;
        // Rows 8..60 on time, 60..110 a quarter period late, 110.. 3 ms early.
        let lags = vec![(60u32, 5e-3), (110, -3e-3)];
        let spec = SceneSpec {
            row_lag_s: lags.clone(),
            ..spec16(w as u32, h as u32, rect, amp, 0.0)
        };
        let mut moving = Scene::new(spec, tone(f)).unwrap();
        let rigid = Scene::new(spec16(w as u32, h as u32, rect, amp, 0.0), tone(f)).unwrap();
        let mut still = Scene::new(spec16(w as u32, h as u32, rect, 0.0, 0.0), tone(f)).unwrap();
        let reference = to_f64(&frame16(&mut still, 0, 0.0));
        let lag_of = |y: usize| match y {
            0..60 => 0.0,
            60..110 => 5e-3,
            _ => -3e-3,
        };
        for y in [0u32, 59, 60, 109, 110, 159, 100_000] {
            assert_eq!(moving.row_lag_s(y), lag_of(y as usize), "row {y}");
        }
        let t0 = 0.0013; // row 60's lagged time is before 0
        for (ld, e) in [(0.0, 0.0), (1e-4, 0.0), (5e-5, 2e-3)] {
            let mut img = vec![0u16; w * h];
            if ld == 0.0 && e == 0.0 {
                moving.render(0, t0, Dest::U16(&mut img));
            } else {
                moving.render_rows(0, t0, ld, e, Dest::U16(&mut img));
            }
            let img = to_f64(&img);
            let mut worst = 0.0f64;
            for y in 12..148 {
                let (mut sgg, mut sgd) = (0.0, 0.0);
                for x in 22..106 {
                    let g = grad(&reference, w, x, y, false);
                    sgg += g * g;
                    sgd -= g * (img[y * w + x] - reference[y * w + x]);
                }
                let d = sgd / sgg;
                let want = moving.row_displacement_px(t0, y as u32, ld, e);
                // The truth: the rigid object's, that much earlier.
                let rigid_want = rigid.row_displacement_px(t0 - lag_of(y), y as u32, ld, e);
                assert!(
                    (want - rigid_want).abs() < 1e-12,
                    "row {y}: {want} vs {rigid_want}"
                );
                if e == 0.0 {
                    let t = t0 + y as f64 * ld - lag_of(y);
                    let analytic = amp * (std::f64::consts::TAU * f * t).sin();
                    assert!((want - analytic).abs() < 1e-12, "row {y}");
                }
                worst = worst.max((d - want).abs());
            }
            eprintln!("row lags, line delay {ld} s, exposure {e} s: worst row error {worst:.5} px");
            assert!(worst < 0.02 * amp, "ld {ld} e {e}: worst {worst}");
        }
        // The lags are large here: the regions clearly differ.
        let top = moving.row_displacement_px(t0, 30, 0.0, 0.0);
        let mid = moving.row_displacement_px(t0, 80, 0.0, 0.0);
        assert!((top - mid).abs() > 0.3, "{top} {mid}");
    }

    /// Without row lags nothing changes, and lags of 0 take the per-row
    /// path to the same bytes; rows above the first lagged region are
    /// untouched by it.
    #[test]
    fn zero_or_no_row_lag_equals_the_global_shutter() {
        for dir in [0.0, 37.0, 90.0] {
            let spec = SceneSpec {
                width: 64,
                height: 50,
                object: [10, 7, 40, 30],
                amplitude_px: 0.8,
                direction_deg: dir,
                ..SceneSpec::default()
            };
            let with = |lags: Vec<(u32, f64)>| {
                Scene::new(
                    SceneSpec {
                        row_lag_s: lags,
                        ..spec.clone()
                    },
                    tone(300.0),
                )
                .unwrap()
            };
            let mut plain = with(Vec::new());
            let mut zero = with(vec![(0, 0.0), (20, 0.0)]);
            let mut lagged = with(vec![(20, 1e-3)]);
            for k in 0..4u64 {
                let t = k as f64 * 3.1e-4;
                let g = frame8(&mut plain, k, t);
                assert_eq!(g, frame8(&mut zero, k, t), "dir {dir} frame {k}");
                let l = frame8(&mut lagged, k, t);
                assert_eq!(g[..20 * 64], l[..20 * 64], "dir {dir} frame {k}");
                assert_ne!(g[20 * 64..], l[20 * 64..], "dir {dir} frame {k}");
                let mut clean_g = vec![0f32; 64 * 50];
                let mut clean_z = vec![0f32; 64 * 50];
                plain.render_clean(t, &mut clean_g);
                zero.render_clean(t, &mut clean_z);
                assert_eq!(clean_g, clean_z);
            }
        }
    }

    /// Issue 15 (per-region gain): rows of a region with a gain show the
    /// rigid object's rows moved by the gain times its displacement (a
    /// negative gain: in antiphase); a gain of 1 renders bit for bit as
    /// none; bad gains are refused naming the entry.
    #[test]
    fn rows_with_a_gain_move_by_it() {
        let (w, h) = (64u32, 64u32);
        let rect = [8u32, 8, 48, 48];
        let lag = vec![(32u32, 0.0)];
        let scene = |gain: Vec<f64>, amp: f64| {
            let spec = SceneSpec {
                row_lag_s: lag.clone(),
                row_gain: gain,
                ..spec16(w, h, rect, amp, 0.0)
            };
            Scene::new(spec, tone(50.0)).unwrap()
        };
        let t = 0.004; // a displacement near the peak
        let mut one = scene(vec![1.0], 0.4);
        let mut none = scene(Vec::new(), 0.4);
        assert_eq!(frame16(&mut one, 0, t), frame16(&mut none, 0, t));
        let mut half = scene(vec![-0.5], 0.4);
        assert_eq!((half.row_gain(31), half.row_gain(32)), (1.0, -0.5));
        let d = half.displacement_px(t);
        // Rows 32 on equal the rigid scene moved by -d/2 (amplitude scaled:
        // the same texture, a displacement of -0.5 d).
        let mut back = scene(vec![1.0], -0.2);
        let (a, b) = (frame16(&mut half, 0, t), frame16(&mut back, 0, t));
        let row = (w * 32) as usize;
        assert_eq!(a[row..], b[row..], "d {d}");
        assert_eq!(a[..row], frame16(&mut none, 0, t)[..row]);
        for (g, field) in [
            (vec![1.0, 0.5], "row_gain"),
            (vec![1.5], "row_gain[0]"),
            (vec![f64::NAN], "row_gain[0]"),
        ] {
            let spec = SceneSpec {
                row_lag_s: lag.clone(),
                row_gain: g,
                ..spec16(w, h, rect, 0.4, 0.0)
            };
            let e = Scene::new(spec, tone(50.0)).err().expect("refused");
            assert_eq!(e.field(), field, "{e}");
        }
    }

    #[test]
    fn moving_edges_blend_by_area_coverage() {
        let spec = spec16(40, 30, [10, 8, 16, 12], 1.0, 0.0);
        let mut s = Scene::new(spec, tone(1.0))
            .unwrap()
            .with_edges(EdgeMode::Moving);
        let d = 0.3;
        let img = clean(&mut s, d);
        for y in 8..20 {
            // Left edge pixel 10 is 70% object, right pixel 26 is 30% object.
            for (x, c) in [(10u32, 0.7), (26, 0.3), (9, 0.0), (27, 0.0), (15, 1.0)] {
                let obj = s.object_value(x as f64, y as f64, d);
                let bg = s.background_value(x, y as u32);
                let want = bg + c * (obj - bg);
                let got = img[y * 40 + x as usize] as f64;
                assert!((got - want).abs() < 0.05, "({x}, {y}): {got} vs {want}");
            }
        }
        // Large excursions past the frame edge are fine.
        let spec = spec16(40, 30, [30, 20, 10, 10], 25.0, 45.0);
        let mut s = Scene::new(spec, tone(1.0))
            .unwrap()
            .with_edges(EdgeMode::Moving);
        for d in [-25.0, -3.7, 0.0, 4.2, 25.0] {
            clean(&mut s, d);
        }
        let mut f = vec![0u16; 1200];
        s.render_rows(0, 0.1, 3e-3, 1e-3, Dest::U16(&mut f));
    }

    #[test]
    fn fixed_edges_keep_the_outline() {
        let mut s = Scene::new(spec16(40, 30, [10, 8, 16, 12], 20.0, 30.0), tone(1.0)).unwrap();
        let a = clean(&mut s, 0.0);
        for d in [-20.0, -0.4, 7.3, 20.0] {
            let b = clean(&mut s, d);
            for y in 0..30 {
                for x in 0..40 {
                    let inside = (10..26).contains(&x) && (8..20).contains(&y);
                    let i = y * 40 + x;
                    if !inside {
                        assert_eq!(a[i], b[i]);
                    } else {
                        let want = s.object_value(x as f64, y as f64, d);
                        assert!((b[i] as f64 - want).abs() < 0.05);
                    }
                }
            }
        }
    }

    #[test]
    fn noise_has_the_requested_std_and_no_bias() {
        let spec = SceneSpec {
            width: 128,
            height: 128,
            object: [32, 32, 64, 64],
            amplitude_px: 0.0,
            noise_std: 3.0,
            depth: Depth::U16,
            bits: 12,
            contrast: SceneSpec::default_contrast(12),
            seed: 9,
            ..SceneSpec::default()
        };
        let mut s = Scene::new(spec, tone(1.0)).unwrap();
        let c = clean(&mut s, 0.0);
        let a = frame16(&mut s, 0, 0.0);
        let b = frame16(&mut s, 1, 0.0);
        let n = c.len() as f64;
        let diff: Vec<f64> = a
            .iter()
            .zip(&b)
            .map(|(&p, &q)| p as f64 - q as f64)
            .collect();
        let var = diff.iter().map(|v| v * v).sum::<f64>() / n;
        // Var(a - b) = 2 (σ² + 1/12) with rounding.
        let want = 2.0 * (9.0 + 1.0 / 12.0);
        assert!((var / want - 1.0).abs() < 0.03, "var {var} want {want}");
        let bias = a
            .iter()
            .zip(&c)
            .map(|(&p, &q)| p as f64 - q as f64)
            .sum::<f64>()
            / n;
        // Std of this mean: 3 / 128 ≈ 0.023.
        assert!(bias.abs() < 0.1, "bias {bias}");
        // Values clamp to 12 bits.
        assert!(a.iter().all(|&v| v <= 4095));
    }

    #[test]
    fn snr_follows_eq_4_3() {
        // SNR of a least-squares motion estimate rises 6 dB when the
        // amplitude doubles or the object's pixels quadruple, falls 6 dB
        // when the noise doubles (thesis Eq. 4.3), at 8 bits.
        fn snr_db(object: [u32; 4], amp: f64, noise: f64) -> f64 {
            let (w, h) = (96usize, 96usize);
            let spec = SceneSpec {
                width: w as u32,
                height: h as u32,
                object,
                amplitude_px: amp,
                noise_std: noise,
                seed: 5,
                ..SceneSpec::default()
            };
            let fps = 2000.0;
            let mut s = Scene::new(spec, tone(130.0)).unwrap();
            let reference: Vec<f64> = clean(&mut s, 0.0).iter().map(|&v| v as f64).collect();
            let [ox, oy, ow, oh] = object.map(|v| v as usize);
            let mut gs = Vec::new();
            for y in oy..oy + oh {
                for x in ox..ox + ow {
                    gs.push((y * w + x, grad(&reference, w, x, y, false)));
                }
            }
            let sgg: f64 = gs.iter().map(|(_, g)| g * g).sum();
            let mut frame = vec![0u8; w * h];
            let (mut sdd, mut sde, mut see) = (0.0, 0.0, 0.0);
            for k in 0..300u64 {
                let t = k as f64 / fps;
                s.render(k, t, Dest::U8(&mut frame));
                let est = -gs
                    .iter()
                    .map(|&(i, g)| g * (frame[i] as f64 - reference[i]))
                    .sum::<f64>()
                    / sgg;
                let truth = s.displacement_px(t);
                sdd += truth * truth;
                sde += truth * est;
                see += est * est;
            }
            // Gain-corrected SNR: signal = the part of the estimate
            // explained by the truth, noise = the rest.
            let gain = sde / sdd;
            let resid = see - gain * gain * sdd;
            10.0 * (gain * gain * sdd / resid).log10()
        }
        let base = snr_db([32, 32, 32, 32], 0.1, 2.0);
        let amp2 = snr_db([32, 32, 32, 32], 0.2, 2.0);
        let px4 = snr_db([16, 16, 64, 64], 0.1, 2.0);
        let noise2 = snr_db([32, 32, 32, 32], 0.1, 4.0);
        eprintln!("SNR: base {base:.2} dB, 2x amplitude {amp2:.2}, 4x pixels {px4:.2}, 2x noise {noise2:.2}");
        for (name, v, want) in [
            ("amplitude", amp2, 6.02),
            ("pixels", px4, 6.02),
            ("noise", noise2, -6.02),
        ] {
            let got = v - base;
            assert!((got - want).abs() < 1.2, "{name}: {got:.2} dB, want {want}");
        }
    }

    #[test]
    fn recovered_tone_is_clean_in_the_spectrum() {
        // Per-frame LS estimates of a 300 Hz tone at 2200 fps, noise-free
        // 16-bit: the spectrum has the tone, at the right amplitude, and
        // nothing else above -60 dB (no interpolation nonlinearity).
        use rustfft::{num_complex::Complex, FftPlanner};
        let (w, h) = (96usize, 80usize);
        let rect = [16u32, 12, 64, 56];
        let amp = 0.05;
        let mut s = Scene::new(spec16(w as u32, h as u32, rect, amp, 0.0), tone(300.0)).unwrap();
        let reference: Vec<f64> = clean(&mut s, 0.0).iter().map(|&v| v as f64).collect();
        let mut gs = Vec::new();
        for y in 16..64 {
            for x in 20..76 {
                gs.push((y * w + x, grad(&reference, w, x, y, false)));
            }
        }
        let sgg: f64 = gs.iter().map(|(_, g)| g * g).sum();
        let n = 220; // 300 Hz falls on bin 30
        let mut frame = vec![0u16; w * h];
        let mut x: Vec<Complex<f64>> = (0..n as u64)
            .map(|k| {
                s.render(k, k as f64 / 2200.0, Dest::U16(&mut frame));
                let est = -gs
                    .iter()
                    .map(|&(i, g)| g * (frame[i] as f64 - reference[i]))
                    .sum::<f64>()
                    / sgg;
                Complex::new(est, 0.0)
            })
            .collect();
        FftPlanner::new().plan_fft_forward(n).process(&mut x);
        let mag: Vec<f64> = x[..n / 2]
            .iter()
            .map(|c| c.norm() * 2.0 / n as f64)
            .collect();
        let fund = mag[30];
        assert!(
            (fund / amp - 1.0).abs() < 0.01,
            "recovered amplitude {fund}"
        );
        let spur = (1..n / 2)
            .filter(|&b| b != 30)
            .map(|b| mag[b])
            .fold(0.0, f64::max);
        let db = 20.0 * (spur / fund).log10();
        eprintln!("tone recovery: amplitude {fund:.6} (true {amp}), worst spur {db:.1} dB");
        assert!(db < -60.0, "spur {db} dB");
    }

    #[test]
    fn odd_destinations_do_not_panic() {
        let mut s = Scene::new(SceneSpec::default(), tone(440.0)).unwrap();
        let mut short = vec![0u8; 256 * 10 + 7];
        s.render(0, 0.0, Dest::U8(&mut short));
        assert!(s.check_dest(&Dest::U8(&mut short)).is_err());
        let mut full = vec![0u8; 256 * 256];
        s.render(0, 0.0, Dest::U8(&mut full));
        assert_eq!(short[..2560], full[..2560]);
        assert!(s.check_dest(&Dest::U8(&mut full)).is_ok());
        let mut wide = vec![0u16; 256 * 256];
        assert!(s.check_dest(&Dest::U16(&mut wide)).is_err());
        s.render(0, 0.0, Dest::U16(&mut wide));
        assert!(wide.iter().all(|&v| v <= 255));
        s.render(0, f64::NAN, Dest::U16(&mut wide));
        s.render_rows(0, 0.0, f64::NAN, f64::INFINITY, Dest::U16(&mut wide));
        s.render(0, 0.0, Dest::U8(&mut []));
    }

    /// The model evaluated pixel by pixel from the continuous textures.
    fn reference_pixel(s: &Scene, x: usize, y: usize, d: f64) -> f64 {
        let [ox, oy, ow, oh] = s.spec().object.map(|v| v as f64);
        let bg = s.background_value(x as u32, y as u32);
        let (xf, yf) = (x as f64, y as f64);
        let c = match s.edge_mode() {
            EdgeMode::Fixed => {
                let inside = xf >= ox && xf < ox + ow && yf >= oy && yf < oy + oh;
                if inside {
                    1.0
                } else {
                    0.0
                }
            }
            EdgeMode::Moving => {
                let (dx, dy) = (d * s.direction().0, d * s.direction().1);
                let overlap = |p: f64, lo: f64, len: f64| {
                    ((p + 0.5).min(lo + len) - (p - 0.5).max(lo)).clamp(0.0, 1.0)
                };
                overlap(xf, ox - 0.5 + dx, ow) * overlap(yf, oy - 0.5 + dy, oh)
            }
        };
        if c > 0.0 {
            bg + c * (s.object_value(xf, yf, d) - bg)
        } else {
            bg
        }
    }

    #[test]
    fn random_scenes_match_the_reference_renderer() {
        let mut rng = Xoshiro256::new(2024);
        let mut worst = 0.0f64;
        for case in 0..24 {
            let mut r = |lo: f64, hi: f64| lo + (hi - lo) * rng.next_f64();
            let (w, h) = (r(6.0, 26.0) as u32, r(6.0, 22.0) as u32);
            let (ow, oh) = (r(1.0, w as f64) as u32, r(1.0, h as f64) as u32);
            let (ox, oy) = (
                r(0.0, (w - ow + 1) as f64) as u32,
                r(0.0, (h - oh + 1) as f64) as u32,
            );
            let amp = r(0.0, 8.0);
            let dir = r(-360.0, 360.0);
            let edges = if case % 2 == 0 {
                EdgeMode::Fixed
            } else {
                EdgeMode::Moving
            };
            let spec = SceneSpec {
                seed: case,
                ..spec16(w, h, [ox, oy, ow, oh], amp, dir)
            };
            let mut s = Scene::new(spec, tone(r(1.0, 40.0)))
                .unwrap()
                .with_edges(edges);
            let n = (w * h) as usize;
            let mut img = vec![0f32; n];
            // Global shutter at a few random displacements, then rolling.
            for _ in 0..2 {
                let d = r(-amp, amp);
                s.render_clean_displaced(d, &mut img);
                for y in 0..h as usize {
                    for x in 0..w as usize {
                        let want = reference_pixel(&s, x, y, d);
                        worst = worst.max((img[y * w as usize + x] as f64 - want).abs());
                    }
                }
            }
            let (t, ld, e) = (r(0.0, 1.0), r(-2e-3, 2e-3), r(0.0, 3e-3));
            s.render_rows_clean(t, ld, e, &mut img);
            for y in 0..h as usize {
                let d = s.row_displacement_px(t, y as u32, ld, e);
                for x in 0..w as usize {
                    let want = reference_pixel(&s, x, y, d);
                    worst = worst.max((img[y * w as usize + x] as f64 - want).abs());
                }
            }
        }
        eprintln!("random scenes vs reference: worst {worst:.4} DN (16-bit, contrast 9830 DN)");
        assert!(worst < 0.08, "worst {worst} DN");
    }

    #[test]
    fn bench_render_speed() {
        // `cargo test --release bench_render_speed -- --nocapture`
        let frames = if cfg!(debug_assertions) { 5 } else { 400 };
        let spec = SceneSpec::default(); // 256x256, 128x128 object, noise 2 DN
        let mut s = Scene::new(spec, tone(440.0)).unwrap();
        let mut buf = vec![0u8; 256 * 256];
        let mpix = |dt: std::time::Duration| frames as f64 * 65536.0 / dt.as_secs_f64() / 1e6;
        let t = std::time::Instant::now();
        for k in 0..frames {
            s.render(k, k as f64 / 2200.0, Dest::U8(&mut buf));
        }
        let global = mpix(t.elapsed());
        let mut q = Scene::new(
            SceneSpec {
                noise_std: 0.0,
                ..SceneSpec::default()
            },
            tone(440.0),
        )
        .unwrap();
        let t = std::time::Instant::now();
        for k in 0..frames {
            q.render(k, k as f64 / 2200.0, Dest::U8(&mut buf));
        }
        let quiet = mpix(t.elapsed());
        let mut r = Scene::new(
            SceneSpec {
                direction_deg: 30.0,
                ..SceneSpec::default()
            },
            tone(440.0),
        )
        .unwrap();
        let t = std::time::Instant::now();
        for k in 0..frames {
            r.render_rows(
                k,
                k as f64 / 2200.0,
                1.0 / 2200.0 / 256.0,
                1e-4,
                Dest::U8(&mut buf),
            );
        }
        let rolling = mpix(t.elapsed());
        let t = std::time::Instant::now();
        for k in 0..frames {
            r.render(k, k as f64 / 2200.0, Dest::U8(&mut buf));
        }
        let diagonal = mpix(t.elapsed());
        eprintln!(
            "render 256x256 u8: global+noise {global:.0} Mpix/s ({:.0} fps), global no noise {quiet:.0} Mpix/s, \
             global 30° + noise {diagonal:.0} Mpix/s, rolling 30° + exposure + noise {rolling:.0} Mpix/s",
            global * 1e6 / 65536.0
        );
    }
}
