//! Drawing the object into a frame's rows: placing it with a sub-pixel shift, the
//! separable interpolation passes over its texture (or a modal beam's or fabric's
//! object), and blending it over the background by edge coverage and silhouette.

use crate::texture::{correlate, PAD, TAPS};

use super::{EdgeMode, Model, Scratch};

/// One axis of the object's placement in a frame.
#[derive(Clone, Copy, Debug)]
pub(super) struct Span {
    /// Output pixels `[p0, p1)` that show the object.
    p0: usize,
    p1: usize,
    /// Grid index where the interpolation window of pixel `p0` starts.
    g0: usize,
    /// Fractional part of the shift, in [0, 1).
    frac: f64,
    /// Continuous extent `[lo, hi)` of the object (±inf with fixed edges).
    lo: f64,
    hi: f64,
}

impl Span {
    fn len(&self) -> usize {
        self.p1 - self.p0
    }

    /// Fraction of pixel `p`'s area `[p - 1/2, p + 1/2)` the object covers.
    fn coverage(&self, p: usize) -> f32 {
        let p = p as f64;
        ((p + 0.5).min(self.hi) - (p - 0.5).max(self.lo)).clamp(0.0, 1.0) as f32
    }
}

/// `out = Σ_s taps[s] · rows[s]` over `TAPS` contiguous rows of `out.len()`.
fn vcombine(taps: &[f32; TAPS], rows: &[f32], out: &mut [f32]) {
    let n = out.len();
    out.fill(0.0);
    for (t, src) in taps.iter().zip(rows.chunks_exact(n)) {
        for (o, v) in out.iter_mut().zip(src) {
            *o += t * v;
        }
    }
}

impl Model {
    /// Renders the modal beam's object for time `t` into `obj`.
    pub(super) fn prepare_modal(&mut self, t: f64, obj: &mut [f32]) {
        let lat = crate::modal::Lattice {
            grid: &self.grid,
            gw: self.gw,
            pad: self.pad,
            interp: &self.interp,
            amp_max: self.amp_max,
        };
        if let Some(b) = self.modal.as_mut() {
            b.render(t, &lat, self.oh, obj);
        } else if let Some(f) = self.fabric.as_mut() {
            f.render(t, &lat, self.oh, obj);
        }
    }

    /// Row `y` of the modal beam's object over the background (fixed outline).
    pub(super) fn modal_row(&self, obj: &[f32], y: usize, line: &mut [f32]) {
        if y < self.oy || y >= self.oy + self.oh || obj.is_empty() {
            return;
        }
        let src = &obj[(y - self.oy) * self.ow..][..self.ow];
        let dst = &mut line[self.ox..self.ox + self.ow];
        match &self.mask {
            Some(mask) => {
                let m = &mask[y * self.w + self.ox..][..self.ow];
                for ((d, &o), &c) in dst.iter_mut().zip(src).zip(m) {
                    *d += c * (self.obj_mean + o - *d);
                }
            }
            None => {
                for (d, &o) in dst.iter_mut().zip(src) {
                    *d = self.obj_mean + o;
                }
            }
        }
    }

    /// The shift vector for displacement `d` (clamped to the amplitude, so
    /// every lookup stays inside the padded texture).
    fn shift(&self, d: f64) -> (f64, f64) {
        let d = if d.is_finite() {
            d.clamp(-self.amp_max, self.amp_max)
        } else {
            0.0
        };
        // `+ 0.0` turns -0.0 into +0.0; the camera's shift is zero
        // without one (bit for bit the same).
        (
            d * self.dir.0 + self.cam.0 + 0.0,
            d * self.dir.1 + self.cam.1 + 0.0,
        )
    }

    /// Places the object along one axis: rest origin `o`, length `len`,
    /// frame size `size`, shift `d`.
    fn span(&self, o: usize, len: usize, size: usize, d: f64) -> Option<Span> {
        let i = d.floor();
        let frac = d - i;
        let (frac, i) = if frac >= 1.0 {
            (0.0, i + 1.0)
        } else {
            (frac, i)
        };
        let ii = i as i64;
        let (of, lf) = (o as f64, len as f64);
        let (a, b, lo, hi) = match self.edges {
            EdgeMode::Fixed => (o as i64, (o + len) as i64, f64::NEG_INFINITY, f64::INFINITY),
            EdgeMode::Moving => {
                let lo = of - 0.5 + d;
                // Pixel p touches [lo, lo + len) iff o - 1 + d < p < o + len + d.
                (
                    (of - 1.0 + d).floor() as i64 + 1,
                    (of + lf + d).ceil() as i64,
                    lo,
                    lo + lf,
                )
            }
        };
        // Pixel p reads lattice k = p - o - i, its window grid indices
        // k - PAD + pad ..= k + pad + (TAPS - 1 - PAD); keep them in the grid
        // (always true by construction; this guards against rounding).
        let (o, pad, len) = (o as i64, self.pad as i64, len as i64);
        let kmin = PAD as i64 - pad;
        let kmax = len + pad - 1 - (TAPS - 1 - PAD) as i64;
        let a = a.max(0).max(kmin + o + ii);
        let b = b.min(size as i64).min(kmax + o + ii + 1);
        if a >= b {
            return None;
        }
        Some(Span {
            p0: a as usize,
            p1: b as usize,
            g0: (a - o - ii - PAD as i64 + pad) as usize,
            frac,
            lo,
            hi,
        })
    }

    fn spans(&self, d: f64) -> Option<(Span, Span)> {
        let (dx, dy) = self.shift(d);
        let sx = self.span(self.ox, self.ow, self.w, dx)?;
        let sy = self.span(self.oy, self.oh, self.h, dy)?;
        Some((sx, sy))
    }

    /// Filters one grid row horizontally into `out` (`sx.len()` values).
    fn hrow(&self, taps: &[f32; TAPS], sx: &Span, grid_row: usize, out: &mut [f32]) {
        let src = &self.grid[grid_row * self.gw + sx.g0..(grid_row + 1) * self.gw];
        if sx.frac == 0.0 {
            out.copy_from_slice(&src[PAD..PAD + out.len()]);
        } else {
            correlate(taps, src, out);
        }
    }

    fn fill_covx(&self, sx: &Span, covx: &mut [f32]) {
        for (c, v) in covx.iter_mut().enumerate() {
            *v = sx.coverage(sx.p0 + c);
        }
    }

    /// Per-frame work of a global-shutter frame: the horizontal pass.
    pub(super) fn prepare_global(&self, d: f64, s: &mut Scratch) -> Option<(Span, Span)> {
        let (sx, sy) = self.spans(d)?;
        let n = sx.len();
        let tx = s.taps.taps_f32_reversed(&self.interp, sx.frac);
        let rows = sy.len() + TAPS - 1;
        for (r, out) in s.hbuf[..rows * n].chunks_exact_mut(n).enumerate() {
            self.hrow(&tx, &sx, sy.g0 + r, out);
        }
        if self.edges == EdgeMode::Moving {
            self.fill_covx(&sx, &mut s.covx[..n]);
        }
        Some((sx, sy))
    }

    pub(super) fn global_row(&self, sx: &Span, sy: &Span, s: &mut Scratch, y: usize) {
        if y < sy.p0 || y >= sy.p1 {
            return;
        }
        let n = sx.len();
        let r = y - sy.p0;
        let obj = &mut s.obj[..n];
        if sy.frac == 0.0 {
            obj.copy_from_slice(&s.hbuf[(r + PAD) * n..(r + PAD + 1) * n]);
        } else {
            let ty = s.taps.taps_f32_reversed(&self.interp, sy.frac);
            vcombine(&ty, &s.hbuf[r * n..(r + TAPS) * n], obj);
        }
        self.blend(
            sx,
            (y, sy.coverage(y)),
            &s.obj[..n],
            &s.covx[..n],
            &mut s.line,
        );
    }

    pub(super) fn rolling_row(&self, d: f64, s: &mut Scratch, y: usize) {
        let Some((sx, sy)) = self.spans(d) else {
            return;
        };
        if y < sy.p0 || y >= sy.p1 {
            return;
        }
        let n = sx.len();
        let tx = s.taps.taps_f32_reversed(&self.interp, sx.frac);
        let g = sy.g0 + (y - sy.p0);
        if sy.frac == 0.0 {
            self.hrow(&tx, &sx, g + PAD, &mut s.obj[..n]);
        } else {
            for (t, out) in s.rows8[..TAPS * n].chunks_exact_mut(n).enumerate() {
                self.hrow(&tx, &sx, g + t, out);
            }
            let ty = s.taps.taps_f32_reversed(&self.interp, sy.frac);
            vcombine(&ty, &s.rows8[..TAPS * n], &mut s.obj[..n]);
        }
        if self.edges == EdgeMode::Moving {
            self.fill_covx(&sx, &mut s.covx[..n]);
        }
        self.blend(
            &sx,
            (y, sy.coverage(y)),
            &s.obj[..n],
            &s.covx[..n],
            &mut s.line,
        );
    }

    /// Writes the object's values over the background in `line` (row `y`,
    /// vertical coverage `cy`).
    fn blend(&self, sx: &Span, (y, cy): (usize, f32), obj: &[f32], covx: &[f32], line: &mut [f32]) {
        let mean = self.obj_mean;
        let dst = &mut line[sx.p0..sx.p1];
        if let Some(mask) = &self.mask {
            let m = &mask[y * self.w + sx.p0..y * self.w + sx.p1];
            let fixed = self.edges == EdgeMode::Fixed;
            for (((d, &o), &cx), &mk) in dst.iter_mut().zip(obj).zip(covx).zip(m) {
                let c = if fixed { mk } else { cx * cy * mk };
                *d += c * (mean + o - *d);
            }
            return;
        }
        match self.edges {
            EdgeMode::Fixed => {
                for (d, &o) in dst.iter_mut().zip(obj) {
                    *d = mean + o;
                }
            }
            EdgeMode::Moving => {
                for ((d, &o), &cx) in dst.iter_mut().zip(obj).zip(covx) {
                    let c = cx * cy;
                    let v = mean + o;
                    *d = if c >= 1.0 { v } else { *d + c * (v - *d) };
                }
            }
        }
    }
}
