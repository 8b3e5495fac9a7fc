//! `modes`: a modal image (thesis ch. 3.5) of the frames that arrive, at
//! one frequency, written at the end as a PNG (phase as hue, amplitude as
//! brightness) and optionally as a `.npy` of the complex image (complex64,
//! shape (height, width), pixels of motion). The frames are streamed: per
//! pixel only the running Fourier sums are kept
//! ([`vibroscope_math::modal`]).
//!
//! ```toml
//! [[stage]]
//! id = "modes"
//! kind = "modes"
//! input = "src"
//! freq_hz = 80.8
//! path = "mode.png"
//! npy = "mode.npy"      # optional
//! roi = [0, 0, 200, 100] # optional
//! mask = "strings.png"  # optional: pixels > 0 are the object (zero elsewhere)
//! pyramid = "csp"       # or "riesz"
//! sigma_px = 3.0        # σ_b of the blur, input pixels
//! motion = "sum"        # "x", "y" or "sum"
//! scale = 1             # pyramid scale (0 = finest, 4 px wavelength)
//! exponent = 1.0        # brightness = amplitude^exponent (after min-max)
//! normalize = true      # divide by the blurred weights (ch. 3.5.2)
//! ```

use crate::stages::transform::pyramid::PyramidKind;
use crate::stages::transform::roi::{plan_region, resolve_region, Mask, Roi, RoiParam};
use crate::*;
use image::ImageEncoder;
use std::path::PathBuf;
use vibroscope_math::modal::{npy_complex64, render_rgb, ModalConfig, ModalImager, Motion, Visual};

/// Default σ_b, input pixels.
pub const DEFAULT_SIGMA_PX: f64 = 2.0;

/// Below this median texture-to-noise power (`ModalImage::texture_to_noise`)
/// the sink warns that the image is mostly noise.
const TEXTURE_TO_NOISE_WARN: f64 = 1.0;

params! {
    /// `modes`'s parameters.
    pub struct ModesParams for "modes" {
        freq_hz: f64 = ParamSpec::of(ParamType::Float, Def::Required)
            .above(0.0)
            .unit("Hz")
            .doc("frequency of the mode imaged"),
        path: PathBuf = ParamSpec::of(ParamType::Path, Def::Required)
            .doc("the PNG (phase as hue, amplitude as brightness)"),
        npy: Option<PathBuf> = ParamSpec::of(ParamType::Path, Def::Optional)
            .doc("also write the complex image as .npy (complex64, pixels of motion)"),
        roi: Option<RoiParam> = crate::stages::transform::reduce::ROI,
        mask: Option<PathBuf> = crate::stages::transform::roi::MASK,
        pyramid: PyramidKind = crate::stages::transform::pyramid::PYRAMID,
        sigma_px: f64 = ParamSpec::of(ParamType::Float, Def::Float(DEFAULT_SIGMA_PX))
            .floats(0.0, 1000.0)
            .unit("px")
            .doc("σ_b of the Gaussian blur, input pixels"),
        motion: Motion = ParamSpec::of(ParamType::Choice(&["x", "y", "sum"]), Def::Str("sum"))
            .doc("motion component imaged"),
        scale: usize = ParamSpec::of(ParamType::Int, Def::Int(1))
            .ints(0, 6)
            .doc("pyramid scale (0 = finest, 4 px wavelength)"),
        exponent: f64 = ParamSpec::of(ParamType::Float, Def::Float(1.0))
            .range(Range::Float {
                lo: 0.0,
                lo_open: true,
                hi: 100.0,
                hi_open: false,
            })
            .doc("brightness = amplitude^exponent (after min-max)"),
        normalize: bool = ParamSpec::of(ParamType::Bool, Def::Bool(true))
            .doc("divide by the blurred weights (ch. 3.5.2)"),
    }
}

type P = ModesParams;

pub const KIND: KindSpec = KindSpec {
    name: "modes",
    summary: "modal image at freq_hz (Eq. 3.18-3.19): A²-weighted, blurred and normalised spectral-volume slice of a region or mask, as PNG (phase = hue) and .npy",
    inputs: &[InPort::one(&[PortType::Frames])],
    outputs: NO_OUTPUTS,
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        let mask = plan_region(p, v.roi.as_ref(), v.mask.as_ref())?;
        Ok(Box::new(ModesPlan(v, mask)))
    },
};

struct ModesPlan(P, Option<(PathBuf, Mask)>);

impl Plan for ModesPlan {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        let ModesPlan(p, mask) = *self;
        Ok(Node::Stage(Box::new(Modes {
            p,
            mask,
            imager: None,
            roi: None,
            buf: Vec::new(),
        })))
    }
}

struct Modes {
    p: P,
    /// The mask until the first frame.
    mask: Option<(PathBuf, Mask)>,
    imager: Option<ModalImager>,
    roi: Option<Roi>,
    buf: Vec<f32>,
}

impl Modes {
    /// The modal imager failed.
    fn err(&self, m: impl std::fmt::Display) -> StageError {
        StageError::dsp(format!("{}: {m}", self.p.path.display()))
    }

    /// The image could not be encoded or written.
    fn write_err(&self, m: impl std::fmt::Display) -> StageError {
        StageError::file("write", &self.p.path, std::io::Error::other(m.to_string()))
    }

    fn start(&mut self, f: &Frame) -> Result<(), StageError> {
        let fps = f.format().fps;
        if fps > 0.0 && self.p.freq_hz >= fps / 2.0 {
            return Err(StageError::config("freq_hz", format!(
                "{} Hz is not below the Nyquist frequency {} Hz of {} fps frames (pass the capture rate with --fps)",
                self.p.freq_hz,
                fps / 2.0,
                fps
            )));
        }
        // The image covers the roi (or the frame), zero outside the mask;
        // the mask must fit the frame and overlap the roi.
        let roi = Roi::resolve(self.p.roi.as_ref(), f.width(), f.height())?;
        crate::memory::check(
            crate::memory::modes_bound(roi.w, roi.h, self.p.scale),
            &format!(
                "a modal image of {}x{} pixels at pyramid scale {}",
                roi.w, roi.h, self.p.scale
            ),
            "give a region (roi) or a coarser scale",
        )
        .map_err(|message| StageError::Config {
            field: "memory",
            message,
        })?;
        let (_, mask) =
            resolve_region(self.p.roi.as_ref(), self.mask.take(), f.width(), f.height())?;
        let cfg = ModalConfig {
            freq_hz: self.p.freq_hz,
            scale: self.p.scale,
            sigma_px: self.p.sigma_px,
            motion: self.p.motion,
            normalize: self.p.normalize,
            pyramid: self.p.pyramid,
        };
        let mut im = ModalImager::new(roi.w, roi.h, cfg).map_err(|e| self.err(e))?;
        if let Some(m) = &mask {
            let inside: Vec<bool> = (0..roi.w * roi.h)
                .map(|i| m.at(roi.x + i % roi.w, roi.y + i / roi.w))
                .collect();
            im.set_mask(&inside).map_err(|e| self.err(e))?;
        }
        self.buf = vec![0.0; roi.w * roi.h];
        self.roi = Some(roi);
        self.imager = Some(im);
        Ok(())
    }
}

impl Stage for Modes {
    fn process(&mut self, _: usize, item: Item, _: &mut Emitter) -> Result<(), StageError> {
        let Item::Frame(f) = item else {
            return Ok(());
        };
        if self.imager.is_none() {
            self.start(&f)?;
        }
        let (Some(roi), Some(im)) = (self.roi, self.imager.as_mut()) else {
            return Ok(());
        };
        let w = f.width();
        if f.height() < roi.y + roi.h || w < roi.x + roi.w {
            return Err(StageError::format(format!(
                "frame size changed to {}x{} mid-stream",
                w,
                f.height()
            )));
        }
        for (r, dst) in self.buf.chunks_exact_mut(roi.w).enumerate() {
            let s = (roi.y + r) * w + roi.x;
            match f.pixels() {
                PixelsRef::U8(p) => {
                    for (d, &v) in dst.iter_mut().zip(&p[s..s + roi.w]) {
                        *d = v as f32;
                    }
                }
                PixelsRef::U16(p) => {
                    for (d, &v) in dst.iter_mut().zip(&p[s..s + roi.w]) {
                        *d = v as f32;
                    }
                }
            }
        }
        im.push(&self.buf, f.meta().t_ns).map_err(|e| self.err(e))
    }

    fn finish(&mut self, _: &mut Emitter) -> Result<(), StageError> {
        let Some(mut im) = self.imager.take() else {
            return Err(StageError::format(format!(
                "{}: no frame arrived",
                self.p.path.display()
            )));
        };
        let img = im.finish().map_err(|e| self.err(e))?;
        let rgb = render_rgb(
            &img,
            Visual {
                exponent: self.p.exponent,
            },
        );
        let mut png = Vec::new();
        image::codecs::png::PngEncoder::new(&mut png)
            .write_image(
                &rgb,
                img.width as u32,
                img.height as u32,
                image::ExtendedColorType::Rgb8,
            )
            .map_err(|e| self.write_err(e))?;
        super::write_atomic(&self.p.path, &png)?;
        if let Some(npy) = &self.p.npy {
            super::write_atomic(npy, &npy_complex64(&img.data, img.width, img.height))?;
        }
        if img.texture_to_noise < TEXTURE_TO_NOISE_WARN {
            tracing::warn!(
                "modal image at {} Hz: at pyramid scale {} the texture is under the sensor noise over most of the image (median texture-to-noise power {:.3}): the image there is mostly noise; a coarser scale sees more of the texture",
                img.freq_hz,
                self.p.scale,
                img.texture_to_noise
            );
        }
        let peak = img.data.iter().map(|c| c.norm()).fold(0.0f32, f32::max);
        tracing::info!(
            frames = img.frames,
            span_s = img.span_s,
            peak_px = peak,
            texture_to_noise = img.texture_to_noise,
            "modal image at {} Hz",
            img.freq_hz
        );
        Ok(())
    }
}
