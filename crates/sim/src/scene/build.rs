//! Building a scene: the checks every constructor runs, and the textures precomputed
//! once (the object's on its padded lattice, the still background), normalised to the
//! spec's contrast and levels.

use crate::rng::{hash2, Ziggurat};
use crate::texture::{Interp, Texture, OBJECT_SIGMA_PX, PAD, TAPS};
use crate::{detmath, Signal, SimError};

use super::spec::BACKGROUND_SIGMA_PX;
use super::surround::{SurroundSpec, Surroundings};
use super::{EdgeMode, Look, Model, Scene, SceneSpec, Scratch, MAX_AMPLITUDE_PX};

/// Object mean level, as a fraction of full scale.
pub const OBJECT_MEAN: f64 = 0.5;
/// Background mean level, as a fraction of full scale.
pub const BACKGROUND_MEAN: f64 = 0.4;
/// Background texture std as a fraction of the object's `contrast`.
pub const BACKGROUND_CONTRAST: f64 = 0.5;
/// Objects smaller than this are normalised with the texture's expected
/// statistics rather than their own.
const MIN_PIXELS_FOR_EMPIRICAL_NORM: usize = 64;

fn mean_std(values: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let (mut n, mut sum) = (0usize, 0.0);
    for v in values.clone() {
        n += 1;
        sum += v;
    }
    if n == 0 {
        return (0.0, 0.0);
    }
    let mean = sum / n as f64;
    let var = values.map(|v| (v - mean) * (v - mean)).sum::<f64>() / n as f64;
    (mean, var.sqrt())
}

/// The object's texture on its lattice padded by `pad` on every side,
/// normalised to `contrast` over the object (`ow`×`oh`): the grid, its
/// width, and the shift and scale applied to the raw texture.
fn object_grid(
    tex: &Texture,
    pad: usize,
    (ow, oh): (usize, usize),
    contrast: f64,
) -> (Vec<f32>, usize, f64, f64) {
    let (gw, gh) = (ow + 2 * pad, oh + 2 * pad);
    let raw = tex.sample_grid(-(pad as i64), -(pad as i64), gw, gh);
    let (tex_shift, tex_std) = if ow * oh >= MIN_PIXELS_FOR_EMPIRICAL_NORM {
        mean_std((0..oh).flat_map(|v| raw[(v + pad) * gw + pad..][..ow].iter().copied()))
    } else {
        (0.0, 0.0)
    };
    let tex_std = if tex_std > 0.0 {
        tex_std
    } else {
        tex.expected_var().sqrt()
    };
    let tex_scale = contrast / tex_std;
    let grid = raw
        .iter()
        .map(|r| ((r - tex_shift) * tex_scale) as f32)
        .collect();
    (grid, gw, tex_shift, tex_scale)
}

impl Scene {
    /// The scene with effects outside the object ([`super::surround`]):
    /// the whole image moving, other things in view vibrating, a light
    /// changing across the image, row offsets. An empty `spec` leaves the
    /// scene as it was. The camera's motion needs a rigid object (a modal
    /// beam or a fabric does not move with it).
    pub fn with_surroundings(mut self, spec: &SurroundSpec) -> Result<Scene, SimError> {
        if spec.is_empty() {
            self.m.surround = None;
            return Ok(self);
        }
        let m = &mut self.m;
        let su = Surroundings::new(spec, (m.w, m.h), m.spec.seed)?;
        let cam = su.camera_peak();
        if cam > 0.0 {
            if m.modal.is_some() || m.fabric.is_some() {
                return Err(SimError::Invalid {
                    field: "camera_motion".into(),
                    msg: "needs a rigid object (no modal or fabric)".into(),
                });
            }
            if m.amp_max + cam > MAX_AMPLITUDE_PX {
                return Err(SimError::Invalid {
                    field: "camera_motion".into(),
                    msg: format!(
                        "the object's and the camera's largest excursions add to {:.3e} px; at most {MAX_AMPLITUDE_PX} px",
                        m.amp_max + cam
                    ),
                });
            }
            // Room on the lattice for the object's excursion and the camera's.
            let pad = PAD + (m.amp_max + cam).ceil() as usize + 1;
            let (grid, gw, _, _) = object_grid(&m.tex, pad, (m.ow, m.oh), m.spec.contrast);
            m.pad = pad;
            m.grid = grid;
            m.gw = gw;
        }
        self.m.surround = Some(su);
        Ok(self)
    }

    /// Validates `spec` and precomputes the textures.
    pub fn new(spec: SceneSpec, signal: Signal) -> Result<Scene, SimError> {
        Self::build(spec, signal, None, None, Look::default())
    }

    /// [`Scene::new`] with a picture for the texture and/or a silhouette.
    pub fn with_look(spec: SceneSpec, signal: Signal, look: Look) -> Result<Scene, SimError> {
        Self::build(spec, signal, None, None, look)
    }

    /// A scene whose object vibrates as a modal beam instead of moving
    /// rigidly (see [`crate::modal`]; global shutter only).
    pub fn with_modal(
        spec: SceneSpec,
        signal: Signal,
        modal: &crate::ModalSpec,
        look: Look,
    ) -> Result<Scene, SimError> {
        let beam = crate::ModalBeam::new(
            modal,
            spec.object[2] as usize,
            spec.object[3] as usize,
            spec.seed,
        )?;
        Self::build(spec, signal, Some(beam), None, look)
    }

    /// A scene whose object is a hanging fabric moving out of its plane,
    /// seen as horizontal image motion (see [`crate::fabric`]; global
    /// shutter only).
    pub fn with_fabric(
        spec: SceneSpec,
        signal: Signal,
        fabric: &crate::FabricSpec,
        look: Look,
    ) -> Result<Scene, SimError> {
        let f = crate::Fabric::new(
            fabric,
            spec.object[2] as usize,
            spec.object[3] as usize,
            spec.seed,
        )?;
        Self::build(spec, signal, None, Some(f), look)
    }

    /// Runs every check [`Scene::with_look`], [`Scene::with_modal`] or
    /// [`Scene::with_fabric`] would, without precomputing the textures
    /// (which cost time and memory in proportion to the frame and the
    /// excursion): what a graph's validation needs. `modal` and `fabric`
    /// are exclusive, as in the constructors.
    pub fn check(
        spec: &SceneSpec,
        signal: &Signal,
        modal: Option<&crate::ModalSpec>,
        fabric: Option<&crate::FabricSpec>,
        look: &Look,
    ) -> Result<(), SimError> {
        let beam = match modal {
            Some(m) => Some(crate::ModalBeam::new(
                m,
                spec.object[2] as usize,
                spec.object[3] as usize,
                spec.seed,
            )?),
            None => None,
        };
        let f = match fabric {
            Some(f) => Some(crate::Fabric::new(
                f,
                spec.object[2] as usize,
                spec.object[3] as usize,
                spec.seed,
            )?),
            None => None,
        };
        Self::checked(spec, signal, beam.as_ref(), f.as_ref(), look).map(|_| ())
    }

    /// The checks shared by [`Scene::check`] and the constructors; returns
    /// the largest excursion and the object's texture.
    fn checked(
        spec: &SceneSpec,
        signal: &Signal,
        modal: Option<&crate::ModalBeam>,
        fabric: Option<&crate::Fabric>,
        look: &Look,
    ) -> Result<(f64, Texture), SimError> {
        spec.validate()?;
        if !spec.row_lag_s.is_empty() && (modal.is_some() || fabric.is_some()) {
            return Err(SimError::Invalid {
                field: "row_lag_s".into(),
                msg: "needs a rigid object (no modal beam or fabric)".into(),
            });
        }
        let (w, h) = (spec.width as usize, spec.height as usize);
        // Room for the largest excursion (a resonance or interference can
        // exceed the unit-peak signal).
        let amp_max = (spec.amplitude_px.abs() * signal.peak_bound().max(1.0))
            .max(modal.as_ref().map_or(0.0, |b| b.peak_bound()))
            .max(fabric.as_ref().map_or(0.0, |f| f.peak_bound()));
        // The texture is padded by the largest excursion: bound it before
        // allocating (a huge interference or resonance would need terabytes).
        if !(amp_max.is_finite() && amp_max <= MAX_AMPLITUDE_PX) {
            return Err(SimError::Invalid {
                field: "amplitude_px".into(),
                msg: format!(
                    "the object's largest excursion, amplitude_px x the signal's peak \
                     (with resonances and interference), is {amp_max:.3e} px; at most \
                     {MAX_AMPLITUDE_PX} px"
                ),
            });
        }

        // Object texture on its padded lattice, normalised over the object.
        let tex = match &look.texture {
            Some((pixels, tw, th)) => Texture::from_image(pixels, *tw, *th, OBJECT_SIGMA_PX)
                .ok_or_else(|| SimError::Invalid {
                    field: "texture".into(),
                    msg: format!("the picture ({tw}x{th}) is empty or has no contrast"),
                })?,
            None => Texture::new(hash2(spec.seed, 1), OBJECT_SIGMA_PX),
        };
        if let Some(m) = &look.mask {
            if m.len() != w * h {
                return Err(SimError::Invalid {
                    field: "object_mask".into(),
                    msg: format!("has {} pixels, the frame {w}x{h}", m.len()),
                });
            }
        }
        Ok((amp_max, tex))
    }

    fn build(
        spec: SceneSpec,
        signal: Signal,
        modal: Option<crate::ModalBeam>,
        fabric: Option<crate::Fabric>,
        look: Look,
    ) -> Result<Scene, SimError> {
        let (amp_max, tex) = Self::checked(&spec, &signal, modal.as_ref(), fabric.as_ref(), &look)?;
        let (w, h) = (spec.width as usize, spec.height as usize);
        let [ox, oy, ow, oh] = spec.object.map(|v| v as usize);
        let full = spec.full_scale();
        let (sin, cos) = detmath::sin_cos_turns(spec.direction_deg / 360.0);
        let pad = PAD + amp_max.ceil() as usize + 1;
        let (grid, gw, tex_shift, tex_scale) = object_grid(&tex, pad, (ow, oh), spec.contrast);

        // Background: still, lower contrast, its own seed.
        let bgt = Texture::new(hash2(spec.seed, 2), BACKGROUND_SIGMA_PX);
        let raw = bgt.sample_grid(0, 0, w, h);
        let (bmean, bstd) = mean_std(raw.iter().copied());
        let bstd = if bstd > 0.0 && w * h >= MIN_PIXELS_FOR_EMPIRICAL_NORM {
            bstd
        } else {
            bgt.expected_var().sqrt()
        };
        let bscale = BACKGROUND_CONTRAST * spec.contrast / bstd;
        let blevel = BACKGROUND_MEAN * full;
        let bg = raw
            .iter()
            .map(|r| (blevel + (r - bmean) * bscale) as f32)
            .collect();

        let ncols = ow + 1;
        let s = Scratch {
            hbuf: vec![0.0; (oh + TAPS) * ncols],
            rows8: vec![0.0; TAPS * ncols],
            obj: vec![0.0; ncols],
            covx: vec![1.0; ncols],
            line: vec![0.0; w],
            noise: vec![0.0; w],
            taps: Default::default(),
            modal_obj: vec![
                0.0;
                if modal.is_some() || fabric.is_some() {
                    ow * oh
                } else {
                    0
                }
            ],
        };
        let m = Model {
            noise_key: hash2(spec.seed, 3),
            spec,
            signal,
            edges: EdgeMode::default(),
            w,
            h,
            ox,
            oy,
            ow,
            oh,
            dir: (cos, sin),
            amp_max,
            full: full as f32,
            obj_mean: (OBJECT_MEAN * full) as f32,
            tex,
            tex_shift,
            tex_scale,
            pad,
            grid,
            gw,
            bg,
            mask: look
                .mask
                .map(|m| m.iter().map(|v| v.clamp(0.0, 1.0)).collect()),
            interp: Interp::new(OBJECT_SIGMA_PX),
            zig: Ziggurat::new(),
            modal,
            fabric,
            surround: None,
            cam: (0.0, 0.0),
        };
        Ok(Scene { m, s })
    }
}
