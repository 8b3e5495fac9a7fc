//! `tile_motion`: sub-pixel motion per tile of the region, two channels a
//! tile, whitened so that a principal component of all of them is the
//! maximum-likelihood combination (`align` with `weights = "principal"`).
//!
//! Per tile k, against a reference frame R with central-difference
//! gradients g = (g_x, g_y), the least-squares equations of a small
//! translation d are
//!
//! P_k = Σ g (R - I_t) ≈ M_k d,   M_k = Σ g gᵀ (the tile's Fisher matrix / σ²),
//!
//! A change of the region's brightness (flicker of mains lighting, auto
//! exposure) would read as motion wherever a tile's gradients do not sum to
//! zero: an offset c adds c Σ g to P_k, a gain ε adds ε Σ g R. Both are
//! known directions in the whitened channels, and every frame's values are
//! projected off them (two of the channels' dimensions, which costs the
//! motion next to nothing; an offset per tile would cost 2 dB on 6 px
//! tiles of the simulator's texture).
//! and with independent pixel noise of variance σ², P_k has covariance
//! σ² M_k. The stage emits z_k = L_k⁻¹ P_k, with M_k = L_k L_kᵀ (Cholesky):
//! z_k = L_kᵀ d + noise of covariance σ² I. The first channel of a tile
//! is its motion along +x scaled by √M_xx, the second the part along +y
//! that x does not explain. A flat tile, or one whose texture has a single
//! direction (the aperture problem), gets zero where it has no information.
//!
//! Every channel then has the same white noise, and where the region moves
//! as one (or in one shape: a mode), z = a s(t) + noise for a fixed vector
//! a: the maximum-likelihood estimate of s is the projection of z on its
//! first principal component. On textured rigid motion this reaches the
//! Cramér-Rao bound of the moving pixels without knowing which ones move
//! (issue 14: within 1 dB of it on simulated speech, `tests/suite/microphone.rs`),
//! where the pyramid's A²-weighted phase sums lose 5-9 dB to the still
//! background and to the bands' shared noise.
//!
//! The linearisation holds for motions under a pixel or so: when the
//! motion read on the textured tiles (those at or above the median Fisher
//! trace) passes 1.1 px RMS in more than 2% of the frames (about 2 px of
//! true motion: the read is low for large motion), the stage warns at the
//! end and points to the phase method. The reference
//! is renewed every `reference_interval_s` as in `phase` (the frame due
//! becomes the next reference; both run side by side for
//! `reference_overlap` frames and the next takes over with an offset per
//! channel, the mean difference over the overlap), so a slow drift only has
//! to stay small within an interval.

use super::audio_out::Batcher;
use super::gradient_motion::px;
use super::phase::{REFERENCE_INTERVAL, REFERENCE_OVERLAP};
use super::reduce::ROI;
use super::roi::{plan_region, resolve_region, Mask, Roi, RoiParam, MASK};
use crate::*;
use vibroscope_math::tile_sums::TileSums;

/// Smallest automatic tile side, px.
const MIN_TILE_PX: usize = 6;
/// Most tiles the automatic size gives (two channels each).
const MAX_AUTO_TILES: usize = 256;

params! {
    /// `tile_motion`'s parameters.
    pub struct TileMotionParams for "tile_motion" {
        roi: Option<RoiParam> = ROI,
        mask: Option<std::path::PathBuf> = MASK,
        tile_px: Option<usize> = ParamSpec::of(ParamType::Int, Def::Optional)
            .ints(2, 1 << 16)
            .unit("px")
            .doc("tile side; default: 6 px, larger when the region would hold more than 256 tiles"),
        block: usize = ParamSpec::of(ParamType::Int, Def::Int(64))
            .ints(1, 65536)
            .unit("frames")
            .doc("frames per emitted block"),
        reference_interval_s: f64 = REFERENCE_INTERVAL,
        reference_overlap: usize = REFERENCE_OVERLAP,
    }
}

type P = TileMotionParams;

pub const KIND: KindSpec = KindSpec {
    name: "tile_motion",
    summary: "sub-pixel motion per tile (gradient least squares along x and y, whitened by the tile's Fisher matrix) -> two channels per tile",
    inputs: &[InPort::one(&[PortType::Frames])],
    outputs: &[OutPort::out(PortType::Samples)],
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        let mask = plan_region(p, v.roi.as_ref(), v.mask.as_ref())?;
        Ok(Box::new(TilePlan { p: v, mask }))
    },
};

struct TilePlan {
    p: P,
    mask: Option<(std::path::PathBuf, Mask)>,
}

impl Plan for TilePlan {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        let TilePlan { p, mask } = *self;
        Ok(Node::Stage(Box::new(TileMotion {
            p,
            mask,
            layout: None,
            reference: None,
            handover: None,
            spare: None,
            raw: Vec::new(),
            next_raw: Vec::new(),
            vals: Vec::new(),
            cols: Cols::default(),
            acc: Vec::new(),
            batch: None,
            frames: 0,
            large: 0,
            largest_px: 0.0,
        })))
    }
}

/// Where the tiles are: frame size, region (1 px inside the frame, for
/// the central differences) and each tile's pixel ranges.
struct Layout {
    width: usize,
    height: usize,
    region: Roi,
    /// Region pixels inside the mask (all, without one).
    inside: Vec<bool>,
    /// Tile boundaries in frame coordinates (`nx + 1` and `ny + 1`).
    xs: Vec<usize>,
    ys: Vec<usize>,
}

impl Layout {
    fn tiles(&self) -> usize {
        (self.xs.len() - 1) * (self.ys.len() - 1)
    }
}

/// Per tile: z1 = P_x · a, z2 = (P_y - b z1) · c (the inverse Cholesky
/// factor; zeros where the tile has no information).
#[derive(Clone, Copy, Default)]
struct Whiten {
    a: f64,
    b: f64,
    c: f64,
}

/// A reference frame: its region's pixels and gradients, each tile's
/// whitening, and the offsets that continue the output across renewals.
struct Reference {
    img: Vec<f32>,
    gx: Vec<f32>,
    gy: Vec<f32>,
    whiten: Vec<Whiten>,
    /// Orthonormal directions, in the whitened channels, of what a change
    /// of the region's brightness (an offset, then a gain) puts in them;
    /// taken out of every frame's values.
    nuisance: [Vec<f64>; 2],
    /// Each tile's Fisher trace, and the tiles (both directions measured)
    /// at or above the median: where the motion's size is read.
    trace: Vec<f64>,
    textured: Vec<usize>,
    t_ns: i64,
    offset: Vec<f64>,
}

struct Handover {
    next: Reference,
    left: usize,
    n: usize,
}

struct TileMotion {
    p: P,
    mask: Option<(std::path::PathBuf, Mask)>,
    layout: Option<Layout>,
    reference: Option<Reference>,
    handover: Option<Handover>,
    spare: Option<Reference>,
    /// This frame's whitened values against the reference (and the next).
    raw: Vec<f64>,
    next_raw: Vec<f64>,
    vals: Vec<f32>,
    /// Column sums for [`Reference::measure`] (empty until the first frame).
    cols: Cols,
    /// Σ (output - next reference's value) per channel, during a handover.
    acc: Vec<f64>,
    batch: Option<Batcher>,
    /// Frames seen, frames whose motion passed [`LARGE_MOTION_PX`], and
    /// the largest motion read (px RMS over the textured tiles).
    frames: usize,
    large: usize,
    largest_px: f64,
}

/// Motion read (RMS over the textured tiles) beyond which the linearised
/// least squares distort. The read is low for large motion (on the
/// simulator's texture a 100 Hz tone of 1, 2 and 3 px peak reads 0.69,
/// 1.20 and 1.50 px), and on simulated speech the phase method is as good
/// at 2 px peak and better beyond. The recordings in ../shared/data read
/// at most 0.95 px (the Photron sample; the tuning forks 0.48-0.79).
const LARGE_MOTION_PX: f64 = 1.1;
/// Share of the frames over [`LARGE_MOTION_PX`] that makes the warning.
const LARGE_MOTION_SHARE: f64 = 0.02;

/// The edges of `n` tiles over `len` pixels from `start` (`n + 1` cuts).
fn cuts(start: usize, len: usize, n: usize) -> Vec<usize> {
    (0..=n).map(|t| start + t * len / n).collect()
}

fn layout(
    p: &P,
    mask: Option<(std::path::PathBuf, Mask)>,
    w: usize,
    h: usize,
) -> Result<Layout, StageError> {
    let (roi, mask) = resolve_region(p.roi.as_ref(), mask, w, h)?;
    // Central differences need a neighbour on each side.
    let (x0, y0) = (roi.x.max(1), roi.y.max(1));
    let x1 = (roi.x + roi.w).min(w.saturating_sub(1));
    let y1 = (roi.y + roi.h).min(h.saturating_sub(1));
    if x1 <= x0 || y1 <= y0 {
        return Err(StageError::config(
            "roi",
            format!(
                "the region is too small in a {w}x{h} frame (a tile needs a pixel on each side)"
            ),
        ));
    }
    let region = Roi {
        x: x0,
        y: y0,
        w: x1 - x0,
        h: y1 - y0,
    };
    let side = p.tile_px.unwrap_or_else(|| {
        let area = (region.w * region.h) as f64;
        MIN_TILE_PX.max((area / MAX_AUTO_TILES as f64).sqrt().ceil() as usize)
    });
    let (nx, ny) = ((region.w / side).max(1), (region.h / side).max(1));
    let inside = (0..region.h)
        .flat_map(|yy| (0..region.w).map(move |xx| (region.x + xx, region.y + yy)))
        .map(|(x, y)| mask.as_ref().is_none_or(|m| m.at(x, y)))
        .collect();
    Ok(Layout {
        width: w,
        height: h,
        region,
        inside,
        xs: cuts(region.x, region.w, nx),
        ys: cuts(region.y, region.h, ny),
    })
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

/// Scales `v` to unit length; leaves it zero when it has (next to) none.
fn normalise(v: &mut [f64]) {
    let n = dot(v, v).sqrt();
    let scale = if n > 1e-12 { 1.0 / n } else { 0.0 };
    v.iter_mut().for_each(|x| *x *= scale);
}

/// The inverse Cholesky factor of [[sxx, sxy], [sxy, syy]], with zero
/// where the matrix has (relative to `scale`) no information.
fn whitening(sxx: f64, sxy: f64, syy: f64, scale: f64) -> Whiten {
    let tiny = 1e-9 * scale.max(f64::MIN_POSITIVE);
    if sxx > tiny {
        let l11 = sxx.sqrt();
        let b = sxy / l11;
        let r = syy - b * b;
        Whiten {
            a: 1.0 / l11,
            b,
            c: if r > 1e-6 * syy && r > tiny {
                1.0 / r.sqrt()
            } else {
                0.0
            },
        }
    } else {
        Whiten {
            a: 0.0,
            b: 0.0,
            c: if syy > tiny { 1.0 / syy.sqrt() } else { 0.0 },
        }
    }
}

impl Reference {
    fn alloc(l: &Layout) -> Self {
        let n = l.region.w * l.region.h;
        Self {
            img: vec![0.0; n],
            gx: vec![0.0; n],
            gy: vec![0.0; n],
            whiten: vec![Whiten::default(); l.tiles()],
            nuisance: [vec![0.0; 2 * l.tiles()], vec![0.0; 2 * l.tiles()]],
            trace: vec![0.0; l.tiles()],
            textured: Vec::with_capacity(l.tiles()),
            t_ns: 0,
            offset: vec![0.0; 2 * l.tiles()],
        }
    }

    /// Takes frame `f` as this reference. False when the region has no
    /// texture at all.
    fn fill(&mut self, l: &Layout, f: &Frame) -> bool {
        let (w, p, r) = (l.width, f.pixels(), l.region);
        for yy in 0..r.h {
            for xx in 0..r.w {
                let (k, i) = (yy * r.w + xx, (r.y + yy) * w + r.x + xx);
                self.img[k] = px(p, i);
                let keep = l.inside[k];
                self.gx[k] = if keep {
                    0.5 * (px(p, i + 1) - px(p, i - 1))
                } else {
                    0.0
                };
                self.gy[k] = if keep {
                    0.5 * (px(p, i + w) - px(p, i - w))
                } else {
                    0.0
                };
            }
        }
        let mut largest = 0.0f64;
        let nx = l.xs.len() - 1;
        for t in 0..l.tiles() {
            let (tx, ty) = (t % nx, t / nx);
            let (mut sxx, mut sxy, mut syy) = (0.0f64, 0.0f64, 0.0f64);
            let (mut ox, mut oy, mut gx_r, mut gy_r) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
            for y in l.ys[ty]..l.ys[ty + 1] {
                let row = (y - r.y) * r.w;
                for x in l.xs[tx]..l.xs[tx + 1] {
                    let k = row + x - r.x;
                    let (gx, gy) = (self.gx[k] as f64, self.gy[k] as f64);
                    sxx += gx * gx;
                    sxy += gx * gy;
                    syy += gy * gy;
                    let v = self.img[k] as f64;
                    ox += gx;
                    oy += gy;
                    gx_r += gx * v;
                    gy_r += gy * v;
                }
            }
            largest = largest.max(sxx + syy);
            self.trace[t] = sxx + syy;
            // Kept in the whitening slot until the scale is known; what a
            // brightness offset and a gain change put in P, beside.
            self.whiten[t] = Whiten {
                a: sxx,
                b: sxy,
                c: syy,
            };
            self.nuisance[0][2 * t..2 * t + 2].copy_from_slice(&[ox, oy]);
            self.nuisance[1][2 * t..2 * t + 2].copy_from_slice(&[gx_r, gy_r]);
        }
        for (t, wt) in self.whiten.iter_mut().enumerate() {
            *wt = whitening(wt.a, wt.b, wt.c, largest);
            for v in &mut self.nuisance {
                let z1 = v[2 * t] * wt.a;
                v[2 * t + 1] = (v[2 * t + 1] - wt.b * z1) * wt.c;
                v[2 * t] = z1;
            }
        }
        // The median trace, from a sorted copy kept in `offset` (zeroed below).
        let n = self.trace.len();
        self.offset[..n].copy_from_slice(&self.trace);
        self.offset[..n].sort_unstable_by(f64::total_cmp);
        let median = self.offset[n / 2];
        self.textured.clear();
        for (t, wt) in self.whiten.iter().enumerate() {
            if self.trace[t] >= median && wt.a > 0.0 && wt.c > 0.0 {
                self.textured.push(t);
            }
        }
        // Orthonormal (Gram-Schmidt); a direction with nothing left is zero.
        let [e1, e2] = &mut self.nuisance;
        normalise(e1);
        let along = dot(e1, e2);
        e2.iter_mut()
            .zip(e1.iter())
            .for_each(|(b, a)| *b -= along * a);
        normalise(e2);
        self.t_ns = f.meta().t_ns;
        self.offset.iter_mut().for_each(|o| *o = 0.0);
        largest > 0.0
    }

    /// The whitened tile motions of `f` against this reference, into `out`.
    /// Each band of tile rows is summed column by column in `cols` (the
    /// math crate's vectorised row kernel), then each tile's columns.
    fn measure(&self, l: &Layout, f: &Frame, cols: &mut Cols, out: &mut [f64]) {
        let (w, p, r) = (l.width, f.pixels(), l.region);
        let nx = l.xs.len() - 1;
        for (ty, band) in l.ys.windows(2).enumerate() {
            cols.sx.iter_mut().for_each(|v| *v = 0.0);
            cols.sy.iter_mut().for_each(|v| *v = 0.0);
            for y in band[0]..band[1] {
                let k = (y - r.y) * r.w..(y - r.y + 1) * r.w;
                let (img, gx, gy) = (&self.img[k.clone()], &self.gx[k.clone()], &self.gy[k]);
                let fr = y * w + r.x..y * w + r.x + r.w;
                match p {
                    PixelsRef::U8(d) => {
                        cols.kernel
                            .add_row_u8(img, gx, gy, &d[fr], &mut cols.sx, &mut cols.sy)
                    }
                    PixelsRef::U16(d) => {
                        cols.kernel
                            .add_row_u16(img, gx, gy, &d[fr], &mut cols.sx, &mut cols.sy)
                    }
                }
            }
            for (tx, span) in l.xs.windows(2).enumerate() {
                let t = ty * nx + tx;
                let c = span[0] - r.x..span[1] - r.x;
                let sx: f64 = cols.sx[c.clone()].iter().map(|&v| v as f64).sum();
                let sy: f64 = cols.sy[c].iter().map(|&v| v as f64).sum();
                let wt = self.whiten[t];
                let z1 = sx * wt.a;
                out[2 * t] = z1;
                out[2 * t + 1] = (sy - wt.b * z1) * wt.c;
            }
        }
        for e in &self.nuisance {
            let along = dot(e, out);
            out.iter_mut().zip(e).for_each(|(o, e)| *o -= along * e);
        }
    }
}

/// Per column of the region, the sums of one band of tile rows (see
/// [`Reference::measure`]), and the row kernel.
#[derive(Default)]
struct Cols {
    sx: Vec<f32>,
    sy: Vec<f32>,
    kernel: TileSums,
}

impl Cols {
    fn new(l: &Layout) -> Self {
        Self {
            sx: vec![0.0; l.region.w],
            sy: vec![0.0; l.region.w],
            kernel: TileSums::new(),
        }
    }
}

impl TileMotion {
    fn init(&mut self, f: &Frame) -> Result<(), StageError> {
        let (w, h) = (f.width(), f.height());
        // Three references (current, next, a spare) of three f32 planes,
        // and the mask's flags.
        crate::memory::check(
            (w as u64) * (h as u64) * 37,
            &format!("{w}x{h} frames in `tile_motion`"),
            "crop the frames before this stage (a `roi` stage or --roi)",
        )
        .map_err(|message| StageError::Config {
            field: "memory",
            message,
        })?;
        let l = layout(&self.p, self.mask.take(), w, h)?;
        let c = 2 * l.tiles();
        let mut r = Reference::alloc(&l);
        if !r.fill(&l, f) {
            return Err(StageError::dsp(
                "the region has no texture (zero gradient everywhere)",
            ));
        }
        self.raw = vec![0.0; c];
        self.cols = Cols::new(&l);
        self.next_raw = vec![0.0; c];
        self.vals = vec![0.0; c];
        self.acc = vec![0.0; c];
        self.batch = Some(Batcher::samples(self.p.block, c));
        self.reference = Some(r);
        self.layout = Some(l);
        Ok(())
    }

    fn due(&self, t_ns: i64) -> bool {
        match &self.reference {
            Some(r) if self.handover.is_none() && self.p.reference_interval_s > 0.0 => {
                t_ns.saturating_sub(r.t_ns) >= (self.p.reference_interval_s * 1e9) as i64
            }
            _ => false,
        }
    }

    fn take_over(&mut self) {
        if let Some(mut h) = self.handover.take() {
            let n = h.n.max(1) as f64;
            for (o, a) in h.next.offset.iter_mut().zip(&self.acc) {
                *o = a / n;
            }
            self.spare = self.reference.replace(h.next);
        }
    }

    fn frame(&mut self, f: &Frame, out: &mut Emitter) -> Result<(), StageError> {
        let (Some(l), Some(reference)) = (self.layout.as_ref(), self.reference.as_ref()) else {
            return Ok(());
        };
        if (f.width(), f.height()) != (l.width, l.height) {
            return Err(StageError::format("the frame size changed mid-stream"));
        }
        reference.measure(l, f, &mut self.cols, &mut self.raw);
        // The motion's size: each textured tile's d = L⁻ᵀ z.
        if !reference.textured.is_empty() {
            let mut sum = 0.0;
            for &t in &reference.textured {
                let wt = reference.whiten[t];
                let dy = wt.c * self.raw[2 * t + 1];
                let dx = wt.a * (self.raw[2 * t] - wt.b * dy);
                sum += dx * dx + dy * dy;
            }
            let rms = (sum / reference.textured.len() as f64).sqrt();
            self.frames += 1;
            if rms > LARGE_MOTION_PX {
                self.large += 1;
            }
            self.largest_px = self.largest_px.max(rms);
        }
        for ((v, r), o) in self.vals.iter_mut().zip(&self.raw).zip(&reference.offset) {
            *v = (r + o) as f32;
        }
        if let Some(h) = self.handover.as_mut() {
            h.next.measure(l, f, &mut self.cols, &mut self.next_raw);
            for ((a, v), n) in self.acc.iter_mut().zip(&self.vals).zip(&self.next_raw) {
                *a += *v as f64 - n;
            }
            h.n += 1;
            h.left = h.left.saturating_sub(1);
        }
        if let Some(b) = self.batch.as_mut() {
            b.push(
                f.meta().t_ns,
                f.format().fps,
                self.vals.iter().copied(),
                out,
            );
        }
        if self.handover.as_ref().is_some_and(|h| h.left == 0) {
            self.take_over();
        } else if self.due(f.meta().t_ns) {
            // This frame becomes the next reference (it reads zero on itself).
            let mut next = self.spare.take().unwrap_or_else(|| Reference::alloc(l));
            if next.fill(l, f) {
                for (a, &v) in self.acc.iter_mut().zip(&self.vals) {
                    *a = v as f64;
                }
                self.handover = Some(Handover {
                    next,
                    left: self.p.reference_overlap,
                    n: 1,
                });
                if self.p.reference_overlap == 0 {
                    self.take_over();
                }
            } else {
                // No texture to renew from: try again an interval later.
                self.spare = Some(next);
                if let Some(r) = self.reference.as_mut() {
                    r.t_ns = f.meta().t_ns;
                }
            }
        }
        Ok(())
    }
}

impl Stage for TileMotion {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        let Item::Frame(f) = item else {
            return Err(StageError::expected("frames"));
        };
        if self.layout.is_none() {
            self.init(&f)?;
        }
        self.frame(&f, out)
    }

    fn finish(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        if let Some(b) = self.batch.as_mut() {
            b.flush(out);
        }
        tracing::info!(
            largest_px = self.largest_px,
            frames = self.frames,
            large = self.large,
            "tile_motion: motion read on the textured tiles"
        );
        if self.large as f64 > LARGE_MOTION_SHARE * self.frames as f64 {
            tracing::warn!(
                "tile_motion: the motion reads up to {:.1} px (RMS over the textured tiles; over {LARGE_MOTION_PX} px in {:.0}% of the frames; the read is low for large motion), where its least squares, linearised for sub-pixel motion, distort the sound; the phase method (`listen --method phase`) follows larger motions",
                self.largest_px,
                100.0 * self.large as f64 / self.frames.max(1) as f64
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vibroscope_core::frame::{FrameFormat, FramePool, PixelsMut};
    use vibroscope_io::Depth;

    /// A frame of `depth` whose pixels are `f(x, y)`.
    fn frame(w: usize, h: usize, depth: Depth, f: impl Fn(usize, usize) -> u32) -> Frame {
        let format = FrameFormat {
            width: w as u32,
            height: h as u32,
            depth,
            bits: if depth == Depth::U8 { 8 } else { 16 },
            fps: 100.0,
            row_timing: None,
        };
        let pool = FramePool::new(format, 1);
        let mut m = pool.try_acquire().expect("a free buffer");
        match m.pixels_mut() {
            PixelsMut::U8(p) => p
                .iter_mut()
                .enumerate()
                .for_each(|(i, v)| *v = f(i % w, i / w) as u8),
            PixelsMut::U16(p) => p
                .iter_mut()
                .enumerate()
                .for_each(|(i, v)| *v = f(i % w, i / w) as u16),
        }
        m.freeze()
    }

    /// The sums made column by column (the vectorised row kernel) are each
    /// tile's own: the same bits on 8-bit frames (every product and sum is
    /// exact in f32 there, for tiles up to 258 px a side), within f32
    /// rounding on 16-bit ones, against
    /// the pixel-by-pixel sum in f64, over uneven tiles and a mask.
    #[test]
    fn column_sums_are_each_tiles_own_sums() {
        let (w, h) = (53, 37);
        let region = Roi {
            x: 1,
            y: 1,
            w: w - 2,
            h: h - 2,
        };
        let inside: Vec<bool> = (0..region.w * region.h).map(|k| k % 11 != 3).collect();
        let l = Layout {
            width: w,
            height: h,
            region,
            inside,
            xs: cuts(region.x, region.w, 4),
            ys: cuts(region.y, region.h, 3),
        };
        let hash = |x: usize, y: usize, k: u32| -> u32 {
            let v = (x as u32).wrapping_mul(73_856_093) ^ (y as u32).wrapping_mul(19_349_663) ^ k;
            v.wrapping_mul(2_654_435_761) >> 8
        };
        for (depth, full) in [(Depth::U8, 255u32), (Depth::U16, 65_535)] {
            let reference = frame(w, h, depth, |x, y| hash(x, y, 1) % (full + 1));
            let moved = frame(w, h, depth, |x, y| hash(x, y, 2) % (full + 1));
            let mut r = Reference::alloc(&l);
            assert!(r.fill(&l, &reference));
            let mut got = vec![0.0; 2 * l.tiles()];
            r.measure(&l, &moved, &mut Cols::new(&l), &mut got);
            // The same, pixel by pixel in f64.
            let mut want = vec![0.0; 2 * l.tiles()];
            let nx = l.xs.len() - 1;
            for (t, wt) in r.whiten.iter().enumerate() {
                let (tx, ty) = (t % nx, t / nx);
                let (mut sx, mut sy) = (0.0f64, 0.0f64);
                for y in l.ys[ty]..l.ys[ty + 1] {
                    for x in l.xs[tx]..l.xs[tx + 1] {
                        let k = (y - region.y) * region.w + x - region.x;
                        let d = r.img[k] as f64 - px(moved.pixels(), y * w + x) as f64;
                        sx += r.gx[k] as f64 * d;
                        sy += r.gy[k] as f64 * d;
                    }
                }
                let z1 = sx * wt.a;
                want[2 * t] = z1;
                want[2 * t + 1] = (sy - wt.b * z1) * wt.c;
            }
            for e in &r.nuisance {
                let along = dot(e, &want);
                want.iter_mut().zip(e).for_each(|(o, e)| *o -= along * e);
            }
            let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(scale > 0.0);
            for (t, (g, v)) in got.iter().zip(&want).enumerate() {
                if depth == Depth::U8 {
                    assert_eq!(g, v, "8-bit, channel {t}");
                } else {
                    assert!(
                        (g - v).abs() <= 1e-6 * scale,
                        "16-bit, channel {t}: {g} against {v}"
                    );
                }
            }
        }
    }

    #[test]
    fn whitening_inverts_the_cholesky_factor() {
        let (sxx, sxy, syy) = (4.0, 1.0, 3.0);
        let w = whitening(sxx, sxy, syy, 7.0);
        // z = L⁻¹ P for P = M d must give Lᵀ d, whose norm² is dᵀ M d.
        let d = [0.3, -0.7];
        let p = [sxx * d[0] + sxy * d[1], sxy * d[0] + syy * d[1]];
        let z1 = p[0] * w.a;
        let z2 = (p[1] - w.b * z1) * w.c;
        let quad = d[0] * p[0] + d[1] * p[1];
        assert!((z1 * z1 + z2 * z2 - quad).abs() < 1e-12);
        // One direction only (the aperture problem): the second is dropped.
        let w = whitening(1.0, 2.0, 4.0, 5.0);
        assert_eq!(w.c, 0.0);
        // Flat along x: only y is measured.
        let w = whitening(0.0, 0.0, 9.0, 9.0);
        assert_eq!((w.a, w.c), (0.0, 1.0 / 3.0));
    }
}
