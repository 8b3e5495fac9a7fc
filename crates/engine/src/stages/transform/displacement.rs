//! `displacement`: the 2-D sub-pixel displacement of one or more regions,
//! in pixels, one sample per frame and region: channels `x0, y0, x1, y1, ...`
//! (region `k` gives channels `2k` and `2k + 1`; +x right, +y down).
//!
//! Per region, by linearised least squares against the first frame R:
//! I_t(x) = R(x - d) ≈ R(x) - d·∇R(x), so d solves the 2×2 normal
//! equations M d = b with M = Σ ∇R ∇Rᵀ, b = Σ ∇R (R - I_t) (a joint
//! solve: with a texture whose x and y gradients are correlated, two
//! separate one-direction fits would see x motion as y motion too).
//!
//! The gradient is a 7-tap central difference (6th order: response
//! (45 sin k - 9 sin 2k + sin 3k) / 30k, 0.994 at one radian per pixel),
//! not the 3-tap one of `gradient_motion` (sin k / k, 0.84 there), whose
//! short derivative overstates sub-pixel motion by ~6% on a texture of
//! σ = 2 px; this stage is the one that reports motion in pixels (and
//! millimetres, after a scale). Pixels within 3 of the frame's edge are
//! left out of a region.
//!
//! ```toml
//! [[stage]]
//! id = "disp"
//! kind = "displacement"
//! input = "src"
//! rois = [10, 10, 100, 80, 150, 10, 60, 60]   # x, y, w, h per region
//! ```
//!
//! With `mask` (an image the frame's size, > 0 inside), only the pixels
//! inside it count, in every region: the others' gradients are zero, so
//! they add nothing to M or b (a region must keep texture inside it).
//!
//! The reference R is the mean of the first `reference_frames` frames
//! (default 16), not the first frame alone: the gradient of a noisy
//! reference has noise in the "known" variable of the fit, which shrinks
//! every estimate by Σ|∇R|² / (Σ|∇R|² + Σ|∇n|²) (measured: 3% low on the
//! simulator's default scene with one frame, 0.3% with 16). Those frames
//! are held (their region pixels, as f32) until the reference is made,
//! then measured against it; output starts `reference_frames` frames late.
//! A reference averaged over a motion blurs by the motion's variance
//! (second order: negligible for sub-pixel vibration).
//!
//! Nothing is allocated per frame but the emitted blocks.

use super::audio_out::Batcher;
use super::gradient_motion::px;
use super::roi::{Mask, Roi};
use crate::*;
use std::path::PathBuf;

/// Most regions in one stage.
/// (A calibration's survey measures its tiles and the sensor's lines
/// around a region: up to 293.)
pub const MAX_REGIONS: usize = 512;
/// Half-width of the derivative filter (pixels left out at the frame's edge).
pub const MARGIN: usize = 3;

params! {
    /// `displacement`'s parameters.
    pub struct DisplacementParams for "displacement" {
        rois: Option<Vec<u32>> = ParamSpec::of(ParamType::Ints, Def::Optional)
            .ints(0, u32::MAX as i64)
            .unit("px")
            .doc("regions, four numbers x, y, w, h each; the whole frame when absent"),
        mask: Option<PathBuf> = ParamSpec::of(ParamType::Path, Def::Optional)
            .doc("only pixels inside this image (the frame's size, PGM/PNG, > 0 inside) count, in every region"),
        block: usize = ParamSpec::of(ParamType::Int, Def::Int(64))
            .ints(1, 1 << 20)
            .unit("samples")
            .doc("frames per emitted block"),
        reference_frames: usize = ParamSpec::of(ParamType::Int, Def::Int(16))
            .ints(1, 256)
            .unit("frames")
            .doc("the reference is the mean of this many first frames (less noise in its gradient)"),
        intensity: bool = ParamSpec::of(ParamType::Bool, Def::Bool(false))
            .doc("a third channel per region, its mean intensity (DN): channels x0, y0, i0, x1, ..."),
        untextured: Untextured = ParamSpec::of(ParamType::Choice(&["error", "zero"]), Def::Str("error"))
            .doc("a region with no texture in two directions: an error, or zero motion (its intensity still measured)"),
    }
}

type P = DisplacementParams;

/// What a region with no texture in two directions gives.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Untextured {
    /// The run stops with an error naming the region.
    #[default]
    Error,
    /// Zero motion (a calibration's survey of the whole frame).
    Zero,
}

pub const KIND: KindSpec = KindSpec {
    name: "displacement",
    summary: "2-D sub-pixel displacement (px) of one or more regions, channels x0, y0, x1, y1, ...",
    inputs: &[InPort::one(&[PortType::Frames])],
    outputs: &[OutPort::out(PortType::Samples)],
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        let rois = match &v.rois {
            None => None,
            Some(r) => Some(parse_rois(r).map_err(|m| p.error("rois", m))?),
        };
        // Read once, here, so a bad mask is a configuration error.
        let mask = match &v.mask {
            Some(m) => Some((m.clone(), Mask::load(m).map_err(|e| p.error("mask", e))?)),
            None => None,
        };
        Ok(Box::new(DisplacementPlan {
            rois,
            block: v.block,
            reference_frames: v.reference_frames,
            mask,
            intensity: v.intensity,
            untextured: v.untextured,
        }))
    },
};

/// `[x, y, w, h, ...]` as regions (a multiple of four, each non-empty).
fn parse_rois(r: &[u32]) -> Result<Vec<[u32; 4]>, String> {
    if r.is_empty() || !r.len().is_multiple_of(4) {
        return Err(format!(
            "needs four numbers (x, y, w, h) per region, got {} numbers",
            r.len()
        ));
    }
    if r.len() / 4 > MAX_REGIONS {
        return Err(format!(
            "at most {MAX_REGIONS} regions, got {}",
            r.len() / 4
        ));
    }
    r.chunks_exact(4)
        .map(|c| {
            if c[2] == 0 || c[3] == 0 {
                Err(format!("width and height must be > 0, got {c:?}"))
            } else {
                Ok([c[0], c[1], c[2], c[3]])
            }
        })
        .collect()
}

struct DisplacementPlan {
    rois: Option<Vec<[u32; 4]>>,
    block: usize,
    reference_frames: usize,
    mask: Option<(PathBuf, Mask)>,
    intensity: bool,
    untextured: Untextured,
}

impl Plan for DisplacementPlan {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        let n = self.rois.as_ref().map_or(1, Vec::len);
        let per = if self.intensity { 3 } else { 2 };
        Ok(Node::Stage(Box::new(Displacement {
            rois: self.rois,
            regions: Vec::new(),
            values: vec![0.0; per * n],
            out: Batcher::samples(self.block, per * n),
            reference_frames: self.reference_frames,
            mask: self.mask,
            intensity: self.intensity,
            untextured: self.untextured,
            held: Vec::new(),
            held_meta: Vec::new(),
            frame_w: 0,
        })))
    }
}

/// One region's reference: intensities, gradients and the inverse normal matrix.
struct Region {
    roi: Roi,
    reference: Vec<f32>,
    gx: Vec<f32>,
    gy: Vec<f32>,
    /// M⁻¹ (symmetric): [a, b; b, c].
    inv: [f64; 3],
}

struct Displacement {
    rois: Option<Vec<[u32; 4]>>,
    regions: Vec<Region>,
    values: Vec<f32>,
    out: Batcher,
    reference_frames: usize,
    /// Only pixels inside count (checked against the frame size first).
    mask: Option<(PathBuf, Mask)>,
    /// Each region's mean intensity as a third channel.
    intensity: bool,
    untextured: Untextured,
    /// The first frames' region pixels, frame after frame, region after
    /// region (until the reference is made).
    held: Vec<f32>,
    /// Their capture times and rates.
    held_meta: Vec<(i64, f64)>,
    frame_w: usize,
}

impl Displacement {
    /// The regions of a `w`×`h` frame, clipped to keep [`MARGIN`] pixels
    /// from its edge.
    fn place(&mut self, w: usize, h: usize) -> Result<(), StageError> {
        if let Some((path, m)) = &self.mask {
            m.check_size(path, w, h)?;
        }
        let whole = [[0, 0, w as u32, h as u32]];
        let rois: &[[u32; 4]] = self.rois.as_deref().unwrap_or(&whole);
        for (k, r) in rois.iter().enumerate() {
            let full = Roi::resolve(Some(&super::roi::RoiParam(*r)), w, h)
                .map_err(|e| StageError::config("rois", format!("region {}: {e}", k + 1)))?;
            let (x0, y0) = (full.x.max(MARGIN), full.y.max(MARGIN));
            let x1 = (full.x + full.w).min(w.saturating_sub(MARGIN));
            let y1 = (full.y + full.h).min(h.saturating_sub(MARGIN));
            if x1 <= x0 || y1 <= y0 {
                return Err(StageError::config(
                    "rois",
                    format!(
                        "region {} {r:?} keeps no pixel {MARGIN} or more from the edge of a {w}x{h} frame",
                        k + 1
                    ),
                ));
            }
            let roi = Roi {
                x: x0,
                y: y0,
                w: x1 - x0,
                h: y1 - y0,
            };
            if let Some((path, m)) = &self.mask {
                let inside =
                    (roi.y..roi.y + roi.h).any(|y| (roi.x..roi.x + roi.w).any(|x| m.at(x, y)));
                if !inside {
                    return Err(StageError::config(
                        "mask",
                        format!(
                            "region {} {r:?} has no pixel inside {} ({MARGIN} or more from the frame's edge)",
                            k + 1,
                            path.display()
                        ),
                    ));
                }
            }
            // Room for the region with MARGIN pixels around it, for the
            // reference's gradient.
            let n = (roi.w + 2 * MARGIN) * (roi.h + 2 * MARGIN);
            self.regions.push(Region {
                roi,
                reference: vec![0.0; n],
                gx: Vec::with_capacity(roi.w * roi.h),
                gy: Vec::with_capacity(roi.w * roi.h),
                inv: [0.0; 3],
            });
        }
        self.frame_w = w;
        let held: usize = self.regions.iter().map(|r| r.reference.len()).sum();
        self.held = Vec::with_capacity(held * self.reference_frames);
        Ok(())
    }

    /// Copies the padded regions of frame `p` to the held frames.
    fn hold(&mut self, p: PixelsRef<'_>, t_ns: i64, fps: f64) {
        let w = self.frame_w;
        for r in &self.regions {
            let (pw, ph) = (r.roi.w + 2 * MARGIN, r.roi.h + 2 * MARGIN);
            for yy in 0..ph {
                let row = (r.roi.y + yy - MARGIN) * w + r.roi.x - MARGIN;
                self.held.extend((0..pw).map(|xx| px(p, row + xx)));
            }
        }
        self.held_meta.push((t_ns, fps));
    }

    /// The reference (mean of the held frames), its gradients and normal
    /// matrices.
    fn make_reference(&mut self) -> Result<(), StageError> {
        let frames = self.held_meta.len().max(1);
        let per_frame: usize = self.regions.iter().map(|r| r.reference.len()).sum();
        let mut off = 0;
        let mask = self.mask.as_ref().map(|(_, m)| m);
        for (k, r) in self.regions.iter_mut().enumerate() {
            let n = r.reference.len();
            for f in 0..frames {
                let src = &self.held[f * per_frame + off..f * per_frame + off + n];
                for (a, &b) in r.reference.iter_mut().zip(src) {
                    *a += b;
                }
            }
            for a in &mut r.reference {
                *a /= frames as f32;
            }
            off += n;
            let pw = r.roi.w + 2 * MARGIN;
            let padded = PixelsF32(&r.reference);
            let (mut sxx, mut sxy, mut syy) = (0.0f64, 0.0f64, 0.0f64);
            for yy in 0..r.roi.h {
                for xx in 0..r.roi.w {
                    let i = (yy + MARGIN) * pw + xx + MARGIN;
                    let inside = mask.is_none_or(|m| m.at(r.roi.x + xx, r.roi.y + yy));
                    let (a, b) = if inside {
                        (padded.deriv(i, 1), padded.deriv(i, pw))
                    } else {
                        (0.0, 0.0)
                    };
                    r.gx.push(a);
                    r.gy.push(b);
                    sxx += (a as f64) * (a as f64);
                    sxy += (a as f64) * (b as f64);
                    syy += (b as f64) * (b as f64);
                }
            }
            let det = sxx * syy - sxy * sxy;
            // A region whose gradients all point one way (a straight edge, a
            // flat patch) cannot say where it moved along the other axis.
            if det.is_nan() || det <= 1e-9 * (sxx + syy).powi(2) {
                if self.untextured == Untextured::Zero {
                    r.inv = [0.0; 3];
                    continue;
                }
                let r = &r.roi;
                return Err(StageError::dsp(format!(
                    "region {} [{}, {}, {}, {}] has no texture in two directions (flat, or only straight edges): its 2-D motion cannot be measured",
                    k + 1, r.x, r.y, r.w, r.h
                )));
            }
            r.inv = [syy / det, -sxy / det, sxx / det];
        }
        Ok(())
    }

    /// Measures frame `k` of the held ones (`None`: `p`) and emits it.
    fn measure(
        &mut self,
        p: Option<PixelsRef<'_>>,
        k: usize,
        t_ns: i64,
        fps: f64,
        out: &mut Emitter,
    ) {
        let w = self.frame_w;
        let per_frame: usize = self.regions.iter().map(|r| r.reference.len()).sum();
        let mut off = 0;
        for (j, r) in self.regions.iter().enumerate() {
            let pw = r.roi.w + 2 * MARGIN;
            let (mut bx, mut by, mut sum) = (0.0f64, 0.0f64, 0.0f64);
            for yy in 0..r.roi.h {
                let o = yy * r.roi.w;
                let ro = (yy + MARGIN) * pw + MARGIN;
                let (mut ax, mut ay, mut ai) = (0.0f32, 0.0f32, 0.0f32);
                match p {
                    Some(p) => {
                        let row = (r.roi.y + yy) * w + r.roi.x;
                        for xx in 0..r.roi.w {
                            let v = px(p, row + xx);
                            let e = r.reference[ro + xx] - v;
                            ax += r.gx[o + xx] * e;
                            ay += r.gy[o + xx] * e;
                            ai += v;
                        }
                    }
                    None => {
                        let h = &self.held[k * per_frame + off..];
                        for xx in 0..r.roi.w {
                            let e = r.reference[ro + xx] - h[ro + xx];
                            ax += r.gx[o + xx] * e;
                            ay += r.gy[o + xx] * e;
                            ai += h[ro + xx];
                        }
                    }
                }
                bx += ax as f64;
                by += ay as f64;
                sum += ai as f64;
            }
            off += r.reference.len();
            let [a, b, c] = r.inv;
            let per = if self.intensity { 3 } else { 2 };
            self.values[per * j] = (a * bx + b * by) as f32;
            self.values[per * j + 1] = (b * bx + c * by) as f32;
            if self.intensity {
                self.values[per * j + 2] = (sum / (r.roi.w * r.roi.h) as f64) as f32;
            }
        }
        self.out.push(t_ns, fps, self.values.iter().copied(), out);
    }

    /// Makes the reference from the held frames and measures them.
    fn release(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        self.make_reference()?;
        let meta = std::mem::take(&mut self.held_meta);
        for (k, &(t, fps)) in meta.iter().enumerate() {
            self.measure(None, k, t, fps, out);
        }
        self.held = Vec::new();
        Ok(())
    }
}

/// A padded f32 region and its derivative.
struct PixelsF32<'a>(&'a [f32]);

impl PixelsF32<'_> {
    /// The 7-tap central derivative at `i` with neighbours `step` apart.
    fn deriv(&self, i: usize, step: usize) -> f32 {
        let d = |k: usize| self.0[i + k * step] - self.0[i - k * step];
        (45.0 * d(1) - 9.0 * d(2) + d(3)) / 60.0
    }
}

impl Stage for Displacement {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        let Item::Frame(f) = item else {
            return Err(StageError::expected("frames"));
        };
        let (t_ns, fps) = (f.meta().t_ns, f.format().fps);
        if self.regions.is_empty() {
            self.place(f.width(), f.height())?;
        }
        if f.width() != self.frame_w {
            return Err(StageError::dsp(format!(
                "the frame width changed from {} to {}",
                self.frame_w,
                f.width()
            )));
        }
        if self.held_meta.len() < self.reference_frames && self.regions[0].gx.is_empty() {
            self.hold(f.pixels(), t_ns, fps);
            if self.held_meta.len() == self.reference_frames {
                self.release(out)?;
            }
            return Ok(());
        }
        self.measure(Some(f.pixels()), 0, t_ns, fps, out);
        Ok(())
    }

    fn finish(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        if !self.held_meta.is_empty() {
            self.release(out)?;
        }
        self.out.flush(out);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rois_come_in_fours() {
        assert!(parse_rois(&[1, 2, 3]).is_err());
        assert!(parse_rois(&[]).is_err());
        assert!(parse_rois(&[0, 0, 0, 5]).is_err());
        assert_eq!(
            parse_rois(&[1, 2, 3, 4, 5, 6, 7, 8]).unwrap(),
            vec![[1, 2, 3, 4], [5, 6, 7, 8]]
        );
    }

    #[test]
    fn derivative_is_exact_on_a_cubic() {
        // f(x) = x³ on a row: the 6th-order difference is exact for cubics.
        let row: Vec<f32> = (0..16u16).map(|x| f32::from(x).powi(3)).collect();
        let p = PixelsF32(&row);
        for x in 3..13usize {
            let want = 3.0 * (x * x) as f32;
            assert!((p.deriv(x, 1) - want).abs() < 1e-3, "x = {x}");
        }
    }
}
