//! The invertible pyramid of the Riesz magnifier: a Laplacian pyramid
//! (Burt and Adelson) with the 5-tap binomial `[1 4 6 4 1]/16`, mirrored
//! borders. `L_l = G_l - expand(reduce(G_l))`, `G_(l+1) = reduce(G_l)`;
//! collapsing adds the levels back, `G_l = L_l + expand(G_(l+1))`, which
//! rebuilds the frame exactly (up to rounding) whatever `expand` does.
//! Wadhwa et al. (2014) build their Riesz pyramid on such a band-pass
//! pyramid; the analysis-only [`crate::riesz::RieszPyramid`] has no
//! low-pass residual to collapse with, so the magnifier uses this one and
//! the exact Riesz pair on its levels (by FFT, [`super::riesz_fft`]).

const TAPS: [f32; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];

/// Mirror index (`x[-1] = x[1]`) into `0..n`.
#[inline(always)]
fn reflect(i: isize, n: usize) -> usize {
    if n == 1 {
        return 0;
    }
    let p = 2 * (n as isize - 1);
    let mut j = i.rem_euclid(p);
    if j >= n as isize {
        j = p - j;
    }
    j as usize
}

/// A Laplacian pyramid for one frame size, with its buffers.
#[derive(Clone, Debug)]
pub struct Laplacian {
    /// (width, height) of levels `0..=levels` (the last is the low-pass).
    pub dims: Vec<(usize, usize)>,
    /// Band-pass levels `0..levels`, then the low-pass residual.
    pub bands: Vec<Vec<f32>>,
    tmp: Vec<f32>,
    up: Vec<f32>,
}

impl Laplacian {
    /// `levels` band-pass levels over `width x height` frames.
    pub fn new(width: usize, height: usize, levels: usize) -> Self {
        let mut dims = Vec::with_capacity(levels + 1);
        let (mut w, mut h) = (width, height);
        for _ in 0..=levels {
            dims.push((w, h));
            w = w.div_ceil(2);
            h = h.div_ceil(2);
        }
        let bands = dims.iter().map(|&(w, h)| vec![0.0; w * h]).collect();
        Self {
            dims,
            bands,
            tmp: vec![0.0; width * height],
            up: vec![0.0; width * height],
        }
    }

    pub fn levels(&self) -> usize {
        self.dims.len() - 1
    }

    /// Decomposes `frame` (row-major, the size given to `new`).
    pub fn analyze(&mut self, frame: &[f32]) {
        let levels = self.levels();
        self.bands[0].copy_from_slice(frame);
        for l in 0..levels {
            let (w, h) = self.dims[l];
            let (nw, nh) = self.dims[l + 1];
            let (cur, rest) = self.bands.split_at_mut(l + 1);
            let g = &mut cur[l];
            let next = &mut rest[0];
            reduce(g, w, h, next, nw, nh, &mut self.tmp);
            expand(next, nw, nh, &mut self.up[..w * h], w, h, &mut self.tmp);
            for (v, u) in g.iter_mut().zip(&self.up[..w * h]) {
                *v -= u;
            }
        }
    }

    /// Rebuilds the frame into `out` from the (possibly modified) levels.
    /// Leaves the levels as they were.
    pub fn collapse(&mut self, out: &mut [f32]) {
        let levels = self.levels();
        let (lw, lh) = self.dims[levels];
        // Work upwards in `out` (large enough for every level).
        out[..lw * lh].copy_from_slice(&self.bands[levels]);
        for l in (0..levels).rev() {
            let (w, h) = self.dims[l];
            let (nw, nh) = self.dims[l + 1];
            self.up[..nw * nh].copy_from_slice(&out[..nw * nh]);
            let (src, dst) = (&self.up[..nw * nh], &mut out[..w * h]);
            expand(src, nw, nh, dst, w, h, &mut self.tmp);
            for (o, b) in out[..w * h].iter_mut().zip(&self.bands[l]) {
                *o += b;
            }
        }
    }
}

/// `dst = (B * src)` at even rows and columns.
fn reduce(src: &[f32], w: usize, h: usize, dst: &mut [f32], nw: usize, nh: usize, tmp: &mut [f32]) {
    // Horizontal blur at even columns: tmp is h x nw.
    for y in 0..h {
        let row = &src[y * w..(y + 1) * w];
        for (i, o) in tmp[y * nw..(y + 1) * nw].iter_mut().enumerate() {
            let x = 2 * i as isize;
            *o = TAPS
                .iter()
                .enumerate()
                .map(|(k, t)| t * row[reflect(x + k as isize - 2, w)])
                .sum();
        }
    }
    // Vertical blur at even rows.
    for (j, out) in dst.chunks_exact_mut(nw).take(nh).enumerate() {
        let y = 2 * j as isize;
        out.fill(0.0);
        for (k, t) in TAPS.iter().enumerate() {
            let r = reflect(y + k as isize - 2, h);
            for (o, v) in out.iter_mut().zip(&tmp[r * nw..(r + 1) * nw]) {
                *o += t * v;
            }
        }
    }
}

/// `dst` (`w x h`) = 4·B * (src upsampled by zero insertion).
fn expand(src: &[f32], nw: usize, nh: usize, dst: &mut [f32], w: usize, h: usize, tmp: &mut [f32]) {
    // Horizontal: tmp is nh x w. Output column x takes the source columns
    // i with 2i = x + k - 2 (k the tap), weight 2·t_k.
    for j in 0..nh {
        let row = &src[j * nw..(j + 1) * nw];
        for (x, o) in tmp[j * w..(j + 1) * w].iter_mut().enumerate() {
            let mut acc = 0.0;
            for (k, t) in TAPS.iter().enumerate() {
                let p = reflect(x as isize + k as isize - 2, w);
                if p.is_multiple_of(2) {
                    acc += 2.0 * t * row[(p / 2).min(nw - 1)];
                }
            }
            *o = acc;
        }
    }
    // Vertical.
    for (y, out) in dst.chunks_exact_mut(w).take(h).enumerate() {
        out.fill(0.0);
        for (k, t) in TAPS.iter().enumerate() {
            let p = reflect(y as isize + k as isize - 2, h);
            if p.is_multiple_of(2) {
                let r = (p / 2).min(nh - 1);
                for (o, v) in out.iter_mut().zip(&tmp[r * w..(r + 1) * w]) {
                    *o += 2.0 * t * v;
                }
            }
        }
    }
}
