//! What changes in the image besides the object (issue 50): the camera or
//! its mount moving the whole image, other things in view that vibrate
//! (the background inside a rectangle moving on its own), a light whose
//! brightness changes over time by an amount that varies across the image,
//! and the sensor's rows each taking an offset per frame. None of these is
//! the object's motion; each reaches a recovery of the object in its own
//! way, and each can be seen elsewhere in the frame: the effects the
//! calibration's residual explainer must find without being told of them.
//!
//! Every effect is applied to the noise-free frame before the sensor's
//! noise and quantisation, so a scene with none renders bit for bit as
//! before. Motions are rendered exactly for a global shutter (one shift per
//! frame); with a rolling shutter each row takes the shift at its own
//! capture time (exposure does not average them).

use crate::rng::{hash2, Xoshiro256, Ziggurat};
use crate::texture::{Interp, TapMemo, PAD, TAPS};
use crate::{detmath, Signal, SignalSpec, SimError};
use serde::Deserialize;

use super::spec::{BACKGROUND_SIGMA_PX, MAX_AMPLITUDE_PX};

/// A motion of its own: `amplitude_px · signal(t)` along `direction_deg`
/// (0 = +x, 90 = +y).
#[derive(Deserialize, Clone, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MotionSpec {
    pub signal: SignalSpec,
    pub amplitude_px: f64,
    #[serde(default)]
    pub direction_deg: f64,
}

/// Something else in view that vibrates: the background inside `rect`
/// (`[x, y, w, h]`; the whole frame when absent) moves by `motion`, behind
/// the object.
#[derive(Deserialize, Clone, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MoverSpec {
    #[serde(default)]
    pub rect: Option<[u32; 4]>,
    pub signal: SignalSpec,
    pub amplitude_px: f64,
    #[serde(default)]
    pub direction_deg: f64,
}

impl MoverSpec {
    /// Its motion.
    pub fn motion(&self) -> MotionSpec {
        MotionSpec {
            signal: self.signal.clone(),
            amplitude_px: self.amplitude_px,
            direction_deg: self.direction_deg,
        }
    }
}

/// A light whose brightness changes: every pixel is multiplied by
/// `1 + depth · signal(t) · r`, where `r` runs from -1 to 1 across the
/// frame along `direction_deg` (0: left to right) and `uniform` adds a
/// part the same everywhere (`r + uniform`).
#[derive(Deserialize, Clone, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LightSpec {
    pub signal: SignalSpec,
    pub depth: f64,
    #[serde(default)]
    pub direction_deg: f64,
    #[serde(default)]
    pub uniform: f64,
}

/// Everything of [`Surroundings`], as declared.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SurroundSpec {
    /// The whole image moves (the camera or its mount).
    pub camera: Option<MotionSpec>,
    /// Other vibrating things (parts of the background).
    pub movers: Vec<MoverSpec>,
    pub light: Option<LightSpec>,
    /// Standard deviation (DN) of an offset each row takes per frame.
    pub row_noise_dn: f64,
    /// Standard deviation (DN) of an offset each column takes per frame.
    pub column_noise_dn: f64,
}

impl SurroundSpec {
    /// Every check [`super::Scene::with_surroundings`] makes on a
    /// `w`×`h` frame (a WAV signal is read).
    pub fn check(&self, (w, h): (u32, u32)) -> Result<(), SimError> {
        Surroundings::new(self, (w as usize, h as usize), 0).map(|_| ())
    }

    pub fn is_empty(&self) -> bool {
        self.camera.is_none()
            && self.movers.is_empty()
            && self.light.is_none()
            && self.row_noise_dn == 0.0
            && self.column_noise_dn == 0.0
    }
}

/// Most movers a scene may hold.
pub const MAX_MOVERS: usize = 16;
/// Largest light `depth` (the brightness stays positive).
pub const MAX_LIGHT_DEPTH: f64 = 0.5;

pub(super) struct Motion {
    signal: Signal,
    amplitude_px: f64,
    dir: (f64, f64),
    /// [`Motion::peak`], found once (a recorded signal's peak is a pass
    /// over its samples, and the shift is asked for every row).
    peak_px: f64,
}

impl Motion {
    fn new(spec: &MotionSpec, field: &str) -> Result<Motion, SimError> {
        let bad = |msg: String| SimError::Invalid {
            field: field.to_string(),
            msg,
        };
        let signal = Signal::new(&spec.signal).map_err(|e| bad(format!("signal: {e}")))?;
        if !(spec.amplitude_px.is_finite() && spec.amplitude_px.abs() <= MAX_AMPLITUDE_PX) {
            return Err(bad(format!(
                "amplitude_px must be finite and at most {MAX_AMPLITUDE_PX} px in magnitude, got {}",
                spec.amplitude_px
            )));
        }
        if !spec.direction_deg.is_finite() {
            return Err(bad(format!(
                "direction_deg must be finite, got {}",
                spec.direction_deg
            )));
        }
        let (sin, cos) = detmath::sin_cos_turns(spec.direction_deg / 360.0);
        let peak_px = spec.amplitude_px.abs() * signal.peak_bound().max(1.0);
        Ok(Motion {
            signal,
            amplitude_px: spec.amplitude_px,
            dir: (cos, sin),
            peak_px,
        })
    }

    /// The largest excursion, px.
    pub(super) fn peak(&self) -> f64 {
        self.peak_px
    }

    /// The shift `(x, y)` at `t_s`, px (bounded by [`Motion::peak`]).
    pub(super) fn shift(&self, t_s: f64) -> (f64, f64) {
        let d = self.amplitude_px * self.signal.value(t_s);
        let p = self.peak();
        let d = if d.is_finite() { d.clamp(-p, p) } else { 0.0 };
        (d * self.dir.0, d * self.dir.1)
    }
}

struct Mover {
    /// Columns `[x0, x1)` and rows `[y0, y1)`.
    x: (usize, usize),
    y: (usize, usize),
    motion: Motion,
}

struct Light {
    signal: Signal,
    depth: f64,
    dir: (f64, f64),
    uniform: f64,
}

/// The effects of a [`SurroundSpec`], ready to render.
pub(super) struct Surroundings {
    pub(super) camera: Option<Motion>,
    movers: Vec<Mover>,
    light: Option<Light>,
    row_noise_dn: f64,
    row_key: u64,
    column_noise_dn: f64,
    column_key: u64,
    /// The columns' offsets of the frame [`Surroundings::begin_frame`]
    /// was last called for (empty without column noise).
    column_offsets: Vec<f32>,
    interp: Interp,
    /// The interpolator's taps for this frame's shifts.
    taps: TapMemo,
    zig: Ziggurat,
    /// One row of the background shifted, and a column buffer.
    tmp: Vec<f32>,
}

impl Surroundings {
    pub(super) fn new(
        spec: &SurroundSpec,
        (w, h): (usize, usize),
        seed: u64,
    ) -> Result<Surroundings, SimError> {
        let camera = match &spec.camera {
            Some(c) => Some(Motion::new(c, "camera_motion")?),
            None => None,
        };
        if spec.movers.len() > MAX_MOVERS {
            return Err(SimError::Invalid {
                field: "background_motion".into(),
                msg: format!("at most {MAX_MOVERS} movers, got {}", spec.movers.len()),
            });
        }
        let mut movers = Vec::new();
        for (k, m) in spec.movers.iter().enumerate() {
            let field = format!("background_motion[{k}]");
            let [x, y, rw, rh] = m.rect.unwrap_or([0, 0, w as u32, h as u32]).map(u64::from);
            if rw == 0 || rh == 0 || x + rw > w as u64 || y + rh > h as u64 {
                return Err(SimError::Invalid {
                    field,
                    msg: format!(
                        "rect {:?} (x, y, w, h) must be non-empty and inside the {w}x{h} frame",
                        m.rect
                    ),
                });
            }
            movers.push(Mover {
                x: (x as usize, (x + rw) as usize),
                y: (y as usize, (y + rh) as usize),
                motion: Motion::new(&m.motion(), &field)?,
            });
        }
        let light = match &spec.light {
            Some(l) => {
                let bad = |msg: String| SimError::Invalid {
                    field: "light".into(),
                    msg,
                };
                let signal = Signal::new(&l.signal).map_err(|e| bad(format!("signal: {e}")))?;
                let reach = (l.depth.abs() * (1.0 + l.uniform.abs())) * signal.peak_bound();
                if !(l.depth.is_finite() && l.uniform.is_finite() && reach <= MAX_LIGHT_DEPTH) {
                    return Err(bad(format!(
                        "depth x (1 + |uniform|) x the signal's peak must be finite and at most {MAX_LIGHT_DEPTH}, got depth {} and uniform {}",
                        l.depth, l.uniform
                    )));
                }
                if !l.direction_deg.is_finite() {
                    return Err(bad(format!(
                        "direction_deg must be finite, got {}",
                        l.direction_deg
                    )));
                }
                let (sin, cos) = detmath::sin_cos_turns(l.direction_deg / 360.0);
                Some(Light {
                    signal,
                    depth: l.depth,
                    dir: (cos, sin),
                    uniform: l.uniform,
                })
            }
            None => None,
        };
        if !(spec.row_noise_dn.is_finite() && spec.row_noise_dn >= 0.0) {
            return Err(SimError::Invalid {
                field: "row_noise_dn".into(),
                msg: format!("must be a finite std >= 0 DN, got {}", spec.row_noise_dn),
            });
        }
        if !(spec.column_noise_dn.is_finite() && spec.column_noise_dn >= 0.0) {
            return Err(SimError::Invalid {
                field: "column_noise_dn".into(),
                msg: format!("must be a finite std >= 0 DN, got {}", spec.column_noise_dn),
            });
        }
        Ok(Surroundings {
            camera,
            movers,
            light,
            row_noise_dn: spec.row_noise_dn,
            row_key: hash2(seed, 5),
            column_noise_dn: spec.column_noise_dn,
            column_key: hash2(seed, 6),
            column_offsets: Vec::with_capacity(if spec.column_noise_dn > 0.0 { w } else { 0 }),
            interp: Interp::new(BACKGROUND_SIGMA_PX),
            taps: TapMemo::default(),
            zig: Ziggurat::new(),
            tmp: vec![0.0; w],
        })
    }

    /// The camera's shift at `t_s` (zero without one).
    pub(super) fn camera_shift(&self, t_s: f64) -> (f64, f64) {
        self.camera.as_ref().map_or((0.0, 0.0), |c| c.shift(t_s))
    }

    /// The camera's largest excursion, px.
    pub(super) fn camera_peak(&self) -> f64 {
        self.camera.as_ref().map_or(0.0, Motion::peak)
    }

    /// Row `y` of the background `bg` (`w` wide), as this row shows it at
    /// `t_s` with the camera at `cam`: shifted by the camera, and inside
    /// each mover's rectangle by the mover too.
    pub(super) fn background_row(
        &mut self,
        bg: &[f32],
        w: usize,
        y: usize,
        (t_s, cam): (f64, (f64, f64)),
        line: &mut [f32],
    ) {
        let h = bg.len() / w;
        if cam != (0.0, 0.0) {
            shifted_row(
                (&self.interp, &mut self.taps),
                bg,
                (w, h),
                y,
                cam,
                (0, w),
                &mut self.tmp,
                line,
            );
        } else {
            line.copy_from_slice(&bg[y * w..(y + 1) * w]);
        }
        for m in &self.movers {
            if y < m.y.0 || y >= m.y.1 {
                continue;
            }
            let (mx, my) = m.motion.shift(t_s);
            let s = (cam.0 + mx, cam.1 + my);
            shifted_row(
                (&self.interp, &mut self.taps),
                bg,
                (w, h),
                y,
                s,
                m.x,
                &mut self.tmp,
                line,
            );
        }
    }

    /// Draws the columns' offsets of frame `frame` (`w` columns; none
    /// without column noise or a frame index), which
    /// [`Surroundings::light_and_rows`] adds to every row of it.
    pub(super) fn begin_frame(&mut self, w: usize, frame: Option<u64>) {
        self.column_offsets.clear();
        if let (true, Some(f)) = (self.column_noise_dn > 0.0, frame) {
            let mut rng = Xoshiro256::new(hash2(self.column_key, f));
            for _ in 0..w {
                let off = (self.zig.sample(&mut rng) * self.column_noise_dn) as f32;
                self.column_offsets.push(off);
            }
        }
    }

    /// The light and the row and column offsets on a finished row `line`
    /// (row `y` of a `w`×`h` frame, shown at `t_s`; `frame` keys the row
    /// noise, [`Surroundings::begin_frame`] drew the columns').
    pub(super) fn light_and_rows(
        &self,
        (w, h): (usize, usize),
        y: usize,
        t_s: f64,
        frame: Option<u64>,
        line: &mut [f32],
    ) {
        if let Some(l) = &self.light {
            let a = l.depth * l.signal.value(t_s);
            if a != 0.0 && a.is_finite() {
                let half = (w.max(h) as f64 / 2.0).max(0.5);
                let cy = (y as f64 + 0.5 - h as f64 / 2.0) * l.dir.1;
                for (x, v) in line.iter_mut().enumerate() {
                    let r = ((x as f64 + 0.5 - w as f64 / 2.0) * l.dir.0 + cy) / half;
                    *v *= (1.0 + a * (r.clamp(-1.0, 1.0) + l.uniform)) as f32;
                }
            }
        }
        if self.row_noise_dn > 0.0 {
            if let Some(f) = frame {
                let mut rng = Xoshiro256::new(hash2(hash2(self.row_key, f), y as u64));
                let off = (self.zig.sample(&mut rng) * self.row_noise_dn) as f32;
                for v in line.iter_mut() {
                    *v += off;
                }
            }
        }
        if frame.is_some() && self.column_offsets.len() == line.len() {
            for (v, o) in line.iter_mut().zip(&self.column_offsets) {
                *v += o;
            }
        }
    }
}

/// Columns `[x0, x1)` of row `y` of the image `img` (`w`×`h`) shifted by
/// `s = (sx, sy)` px (`out(x, y) = img(x - sx, y - sy)`, band-limited
/// interpolation of the background's texture, edges extended), into
/// `line`; `tmp` holds the vertical pass (`w` long).
#[allow(clippy::too_many_arguments)]
fn shifted_row(
    (interp, taps): (&Interp, &mut TapMemo),
    img: &[f32],
    (w, h): (usize, usize),
    y: usize,
    (sx, sy): (f64, f64),
    (x0, x1): (usize, usize),
    tmp: &mut [f32],
    line: &mut [f32],
) {
    let split = |s: f64| {
        let i = s.floor();
        (i as i64, s - i)
    };
    let (iy, fy) = split(sy);
    let (ix, fx) = split(sx);
    let ty = taps.taps_f32_reversed(interp, fy);
    let tx = taps.taps_f32_reversed(interp, fx);
    let clamp = |v: i64, n: usize| v.clamp(0, n as i64 - 1) as usize;
    // Columns the horizontal pass reads.
    let lo = clamp(x0 as i64 - ix - PAD as i64, w);
    let hi = clamp(x1 as i64 - 1 - ix - PAD as i64 + TAPS as i64 - 1, w) + 1;
    let col = &mut tmp[lo..hi];
    col.fill(0.0);
    for (s, &t) in ty.iter().enumerate() {
        let r = clamp(y as i64 - iy - PAD as i64 + s as i64, h);
        for (o, &v) in col.iter_mut().zip(&img[r * w + lo..r * w + hi]) {
            *o += t * v;
        }
    }
    for (x, out) in line.iter_mut().enumerate().take(x1).skip(x0) {
        let first = x as i64 - ix - PAD as i64;
        let mut acc = 0.0f32;
        if first >= 0 && first + TAPS as i64 <= w as i64 {
            // Inside the image: no column to clamp (the same sum, in the
            // same order).
            let first = first as usize;
            for (&t, &v) in tx.iter().zip(&tmp[first..first + TAPS]) {
                acc += t * v;
            }
        } else {
            for (s, &t) in tx.iter().enumerate() {
                acc += t * tmp[clamp(first + s as i64, w)];
            }
        }
        *out = acc;
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// A shifted row of a smooth image is the image at the shifted place:
    /// a whole-pixel shift is exact, a fraction within the interpolator's
    /// error of the analytic value.
    #[test]
    fn a_shifted_row_is_the_image_at_the_shifted_place() {
        let (w, h) = (40usize, 30usize);
        let f = |x: f64, y: f64| (0.31 * x).sin() * 10.0 + (0.23 * y).cos() * 7.0 + 0.1 * x * y;
        let img: Vec<f32> = (0..w * h)
            .map(|i| f((i % w) as f64, (i / w) as f64) as f32)
            .collect();
        let interp = Interp::new(BACKGROUND_SIGMA_PX);
        let mut tmp = vec![0.0; w];
        let mut line = vec![0.0; w];
        for (sx, sy, tol) in [(2.0, -1.0, 1e-3), (0.3, 0.0, 0.05), (-0.45, 0.7, 0.05)] {
            let y = 15;
            shifted_row(
                (&interp, &mut TapMemo::default()),
                &img,
                (w, h),
                y,
                (sx, sy),
                (0, w),
                &mut tmp,
                &mut line,
            );
            // Away from the edges (extended there).
            for (x, &v) in line.iter().enumerate().take(w - 12).skip(12) {
                let want = f(x as f64 - sx, y as f64 - sy);
                assert!(
                    (v as f64 - want).abs() < tol,
                    "shift ({sx}, {sy}) x {x}: {v} vs {want}"
                );
            }
        }
    }

    #[test]
    fn bad_surroundings_are_refused_naming_the_field() {
        let tone = SignalSpec::Tone {
            freq_hz: 30.0,
            phase_rad: 0.0,
        };
        let motion = MotionSpec {
            signal: tone.clone(),
            amplitude_px: 0.1,
            direction_deg: 0.0,
        };
        let cases = [
            (
                SurroundSpec {
                    movers: vec![MoverSpec {
                        rect: Some([60, 0, 10, 10]),
                        signal: tone.clone(),
                        amplitude_px: 0.1,
                        direction_deg: 0.0,
                    }],
                    ..Default::default()
                },
                "background_motion[0]",
            ),
            (
                SurroundSpec {
                    camera: Some(MotionSpec {
                        amplitude_px: f64::NAN,
                        ..motion.clone()
                    }),
                    ..Default::default()
                },
                "camera_motion",
            ),
            (
                SurroundSpec {
                    light: Some(LightSpec {
                        signal: tone.clone(),
                        depth: 0.9,
                        direction_deg: 0.0,
                        uniform: 0.0,
                    }),
                    ..Default::default()
                },
                "light",
            ),
            (
                SurroundSpec {
                    row_noise_dn: -1.0,
                    ..Default::default()
                },
                "row_noise_dn",
            ),
        ];
        for (spec, field) in cases {
            let e = Surroundings::new(&spec, (64, 64), 1).err().unwrap();
            assert_eq!(e.field(), field, "{e}");
        }
    }

    fn scene(spec: &SurroundSpec) -> super::super::Scene {
        use super::super::tests::spec16;
        let spec16 = spec16(48, 40, [12, 10, 20, 16], 0.0, 0.0);
        let tone = Signal::new(&SignalSpec::Tone {
            freq_hz: 1.0,
            phase_rad: 0.0,
        })
        .unwrap();
        super::super::Scene::new(spec16, tone)
            .unwrap()
            .with_surroundings(spec)
            .unwrap()
    }

    /// The camera's motion moves everything, background and object: at a
    /// whole-pixel shift the frame is the still frame moved by it.
    #[test]
    fn the_camera_moves_the_whole_image() {
        // sin(π/2) = 1 at t = 0: a shift of 2 px along +x.
        let cam = SurroundSpec {
            camera: Some(MotionSpec {
                signal: SignalSpec::Tone {
                    freq_hz: 5.0,
                    phase_rad: std::f64::consts::FRAC_PI_2,
                },
                amplitude_px: 2.0,
                direction_deg: 0.0,
            }),
            ..Default::default()
        };
        let (w, h) = (48usize, 40usize);
        let mut still = vec![0.0f32; w * h];
        scene(&SurroundSpec::default()).render_clean(0.0, &mut still);
        let mut moved = vec![0.0f32; w * h];
        let mut s = scene(&cam);
        assert_eq!(s.camera_shift_px(0.0), (2.0, 0.0));
        s.render_clean(0.0, &mut moved);
        // The object's outline stays put in the default edge mode (its
        // texture moves inside it): its two columns of pixels each side
        // are left out.
        for y in 0..h {
            for x in (2..w).filter(|x| !(12..14).contains(x) && !(32..34).contains(x)) {
                let (a, b) = (moved[y * w + x], still[y * w + x - 2]);
                assert!(
                    (a - b).abs() < 1e-6 * b.abs() + 1e-2,
                    "({x}, {y}): {a} vs {b}"
                );
            }
        }
    }

    /// A mover moves the background inside its rectangle only; the light
    /// scales pixels by a ramp across the frame; row noise offsets whole
    /// rows.
    #[test]
    fn movers_light_and_rows_act_where_declared() {
        let (w, h) = (48usize, 40usize);
        let mut still = vec![0.0f32; w * h];
        scene(&SurroundSpec::default()).render_clean(0.0, &mut still);
        let mover = SurroundSpec {
            movers: vec![MoverSpec {
                rect: Some([0, 30, 20, 10]),
                signal: SignalSpec::Tone {
                    freq_hz: 5.0,
                    phase_rad: std::f64::consts::FRAC_PI_2,
                },
                amplitude_px: 1.0,
                direction_deg: 90.0,
            }],
            ..Default::default()
        };
        let mut f = vec![0.0f32; w * h];
        scene(&mover).render_clean(0.0, &mut f);
        for y in 0..h {
            for x in 0..w {
                let inside = (30..40).contains(&y) && x < 20;
                let want = if inside && y >= 31 {
                    still[(y - 1) * w + x]
                } else if inside {
                    continue;
                } else {
                    still[y * w + x]
                };
                let got = f[y * w + x];
                assert!((got - want).abs() < 1e-2, "({x}, {y}): {got} vs {want}");
            }
        }
        let light = SurroundSpec {
            light: Some(LightSpec {
                signal: SignalSpec::Tone {
                    freq_hz: 5.0,
                    phase_rad: std::f64::consts::FRAC_PI_2,
                },
                depth: 0.2,
                direction_deg: 0.0,
                uniform: 0.0,
            }),
            ..Default::default()
        };
        scene(&light).render_clean(0.0, &mut f);
        for (x, y) in [(0usize, 3usize), (47, 20), (24, 39)] {
            let r = (x as f64 + 0.5 - 24.0) / 24.0;
            let want = still[y * w + x] as f64 * (1.0 + 0.2 * r);
            let got = f[y * w + x] as f64;
            assert!(
                (got - want).abs() < 1e-6 * want,
                "({x}, {y}): {got} vs {want}"
            );
        }
        let rows = SurroundSpec {
            row_noise_dn: 50.0,
            ..Default::default()
        };
        let mut p = vec![0u16; w * h];
        scene(&rows).render(3, 0.0, crate::Dest::U16(&mut p));
        let mut q = vec![0u16; w * h];
        scene(&SurroundSpec::default()).render(3, 0.0, crate::Dest::U16(&mut q));
        let mut offsets = Vec::new();
        for y in 0..h {
            let d: Vec<i32> = (0..w)
                .map(|x| p[y * w + x] as i32 - q[y * w + x] as i32)
                .collect();
            assert!(d.iter().all(|&v| (v - d[0]).abs() <= 1), "row {y}: {d:?}");
            offsets.push(d[0] as f64);
        }
        let rms = (offsets.iter().map(|o| o * o).sum::<f64>() / h as f64).sqrt();
        assert!((25.0..100.0).contains(&rms), "row offsets' rms {rms}");
        // Columns: one offset down each column, another draw next frame.
        let cols = SurroundSpec {
            column_noise_dn: 50.0,
            ..Default::default()
        };
        let column_offsets = |frame: u64| -> Vec<i32> {
            let mut p = vec![0u16; w * h];
            scene(&cols).render(frame, 0.0, crate::Dest::U16(&mut p));
            let mut q = vec![0u16; w * h];
            scene(&SurroundSpec::default()).render(frame, 0.0, crate::Dest::U16(&mut q));
            (0..w)
                .map(|x| {
                    let d: Vec<i32> = (0..h)
                        .map(|y| p[y * w + x] as i32 - q[y * w + x] as i32)
                        .collect();
                    assert!(
                        d.iter().all(|&v| (v - d[0]).abs() <= 1),
                        "column {x}: {d:?}"
                    );
                    d[0]
                })
                .collect()
        };
        let (a, b) = (column_offsets(3), column_offsets(4));
        let rms = (a.iter().map(|&o| f64::from(o * o)).sum::<f64>() / w as f64).sqrt();
        assert!((25.0..100.0).contains(&rms), "column offsets' rms {rms}");
        assert_ne!(a, b, "the columns' offsets change from frame to frame");
        assert!(cols.check((w as u32, h as u32)).is_ok());
        let bad = SurroundSpec {
            column_noise_dn: -1.0,
            ..Default::default()
        };
        assert!(bad.check((w as u32, h as u32)).is_err());
    }
}
