//! The invertible pyramid of the Riesz magnifier: a Laplacian pyramid
//! (Burt and Adelson) with the 5-tap binomial `[1 4 6 4 1]/16`, mirrored
//! borders. `L_l = G_l - expand(reduce(G_l))`, `G_(l+1) = reduce(G_l)`;
//! collapsing adds the levels back, `G_l = L_l + expand(G_(l+1))`, which
//! rebuilds the frame exactly (up to rounding) whatever `expand` does.
//! Wadhwa et al. (2014) build their Riesz pyramid on such a band-pass
//! pyramid; the analysis-only [`crate::riesz::RieszPyramid`] has no
//! low-pass residual to collapse with, so the magnifier uses this one and
//! a Riesz pair on its levels (a 7x7 filter, `super::riesz_fir`).

use crate::join::{both, simd_fn, Par, Serial, Simd};

const TAPS: [f32; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];

/// Mirror index (`x[-1] = x[1]`) into `0..n`.
#[inline(always)]
pub(crate) fn reflect(i: isize, n: usize) -> usize {
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
        let bands = dims
            .iter()
            .map(|&(w, h)| crate::numeric::zeros_touched(w * h))
            .collect();
        Self {
            dims,
            bands,
            tmp: crate::numeric::zeros_touched(width * height),
            up: crate::numeric::zeros_touched(width * height),
        }
    }

    pub fn levels(&self) -> usize {
        self.dims.len() - 1
    }

    /// Decomposes `frame` (row-major, the size given to `new`).
    pub fn analyze(&mut self, frame: &[f32]) {
        let par = Par {
            j: &Serial,
            simd: Simd::detect(),
        };
        self.analyze_with(frame, par);
    }

    /// [`Self::analyze`], each pass's rows in two halves through `j` (the
    /// same bits however `j` runs them).
    #[inline(always)]
    pub(crate) fn analyze_with(&mut self, frame: &[f32], j: Par<'_>) {
        self.bands[0].copy_from_slice(frame);
        self.analyze_loaded_with(j);
    }

    /// [`Self::analyze_with`] of the frame already in the first level.
    #[inline(always)]
    pub(crate) fn analyze_loaded_with(&mut self, j: Par<'_>) {
        let levels = self.levels();
        for l in 0..levels {
            let (w, h) = self.dims[l];
            let (nw, nh) = self.dims[l + 1];
            let (cur, rest) = self.bands.split_at_mut(l + 1);
            let g = &mut cur[l];
            let next = &mut rest[0];
            reduce(g, w, h, next, nw, nh, &mut self.tmp, j);
            // L = G - expand(reduce(G)), in the expansion's last pass.
            expand(next, nw, nh, g, w, h, &mut self.tmp, Put::Sub, j);
        }
    }

    /// Rebuilds the frame into `out` from the (possibly modified) levels.
    /// Leaves the levels as they were.
    pub fn collapse(&mut self, out: &mut [f32]) {
        let par = Par {
            j: &Serial,
            simd: Simd::detect(),
        };
        self.collapse_with(out, par);
    }

    /// [`Self::collapse`], each pass's rows in two halves through `j`.
    #[inline(always)]
    pub(crate) fn collapse_with(&mut self, out: &mut [f32], j: Par<'_>) {
        let levels = self.levels();
        let (lw, lh) = self.dims[levels];
        // Work upwards in `out` (large enough for every level).
        out[..lw * lh].copy_from_slice(&self.bands[levels]);
        for l in (0..levels).rev() {
            let (w, h) = self.dims[l];
            let (nw, nh) = self.dims[l + 1];
            self.up[..nw * nh].copy_from_slice(&out[..nw * nh]);
            let (src, dst) = (&self.up[..nw * nh], &mut out[..w * h]);
            // G_l = expand(G_(l+1)) + L_l, the sum in the last pass.
            let band = Put::Add(&self.bands[l]);
            expand(src, nw, nh, dst, w, h, &mut self.tmp, band, j);
        }
    }
}

/// Below this many pixels a pass is not split (the halves would cost more
/// to hand over than they save).
pub(crate) const SPLIT_MIN: usize = 8192;

/// Where `rows` rows are split in two (none below [`SPLIT_MIN`] pixels).
#[inline(always)]
pub(crate) fn mid_row(rows: usize, width: usize) -> usize {
    if rows * width >= SPLIT_MIN {
        rows / 2
    } else {
        rows
    }
}

/// Horizontal 5-tap binomial of `row` (`w` long) at its even columns, into
/// `out` (`ceil(w/2)` long): the interior without index mirroring, the
/// two ends with it. Sums in tap order (the same rounding everywhere).
#[inline(always)]
fn reduce_row(row: &[f32], w: usize, out: &mut [f32]) {
    let [t0, t1, t2, t3, t4] = TAPS;
    let edge = |i: usize| -> f32 {
        let x = 2 * i as isize;
        TAPS.iter()
            .enumerate()
            .map(|(k, t)| t * row[reflect(x + k as isize - 2, w)])
            .sum()
    };
    // Output i reads 2i-2..=2i+2: inside the row for 1 <= i <= (w-3)/2.
    let hi = if w >= 3 { (w - 3) / 2 + 1 } else { 0 };
    let lo = 1.min(hi);
    for (i, o) in out.iter_mut().enumerate().take(lo) {
        *o = edge(i);
    }
    if hi > lo {
        // Outputs lo..hi read row[2lo-2 .. 2hi+1]: by index from there, so
        // that the loop is one body with no iterator call a pixel.
        let src = &row[2 * lo - 2..2 * hi + 1];
        let dst = &mut out[lo..hi];
        for (i, o) in dst.iter_mut().enumerate() {
            let r = &src[2 * i..2 * i + 5];
            *o = t0 * r[0] + t1 * r[1] + t2 * r[2] + t3 * r[3] + t4 * r[4];
        }
    }
    for (i, o) in out.iter_mut().enumerate().skip(hi.max(lo)) {
        *o = edge(i);
    }
}

simd_fn! {
/// Whole rows of `src` (`w` wide) through [`reduce_row`] into `out`.
fn reduce_rows(src: &[f32], out: &mut [f32], w: usize, nw: usize) {
    for (r, o) in src.chunks_exact(w).zip(out.chunks_exact_mut(nw)) {
        reduce_row(r, w, o);
    }
}
}

simd_fn! {
/// Rows `y0..` (as many as `dst` holds) of the vertical 5-tap binomial at
/// even rows of `tmp` (`h` rows of `nw`).
fn reduce_cols(tmp: &[f32], nw: usize, h: usize, dst: &mut [f32], y0: usize) {
    let [t0, t1, t2, t3, t4] = TAPS;
    for (j, out) in dst.chunks_exact_mut(nw).enumerate() {
        let y = 2 * (y0 + j) as isize;
        let row = |k: isize| {
            let r = reflect(y + k - 2, h);
            &tmp[r * nw..(r + 1) * nw]
        };
        let (a, b, c, d, e) = (row(0), row(1), row(2), row(3), row(4));
        for (i, o) in out.iter_mut().enumerate() {
            *o = t0 * a[i] + t1 * b[i] + t2 * c[i] + t3 * d[i] + t4 * e[i];
        }
    }
}
}

/// `dst = (B * src)` at even rows and columns.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn reduce(
    src: &[f32],
    w: usize,
    h: usize,
    dst: &mut [f32],
    nw: usize,
    nh: usize,
    tmp: &mut [f32],
    j: Par<'_>,
) {
    // Horizontal blur at even columns: tmp is h x nw.
    let hm = mid_row(h, w);
    let (t0, t1) = tmp[..h * nw].split_at_mut(hm * nw);
    let v = j.simd;
    both(
        j,
        hm < h,
        || reduce_rows(v, &src[..hm * w], t0, w, nw),
        || reduce_rows(v, &src[hm * w..h * w], t1, w, nw),
    );
    // Vertical blur at even rows, the five rows in one pass.
    let tmp = &tmp[..h * nw];
    let nm = mid_row(nh, nw);
    let (d0, d1) = dst[..nh * nw].split_at_mut(nm * nw);
    both(
        j,
        nm < nh,
        || reduce_cols(v, tmp, nw, h, d0, 0),
        || reduce_cols(v, tmp, nw, h, d1, nm),
    );
}

/// Horizontal half of [`expand`] for one row: `out` (`w` long) = 4·B *
/// (`row` (`nw` long) upsampled by zero insertion), rows' half of the 4.
/// Output column x takes the source columns i with 2i = x + k - 2 (k the
/// tap), weight 2·t_k: an even x = 2j takes j-1, j, j+1 (2·t0, 2·t2,
/// 2·t4), an odd one j and j+1 (2·t1, 2·t3).
#[inline(always)]
fn expand_row(row: &[f32], nw: usize, out: &mut [f32], w: usize) {
    let edge = |x: usize| -> f32 {
        let mut acc = 0.0;
        for (k, t) in TAPS.iter().enumerate() {
            let p = reflect(x as isize + k as isize - 2, w);
            if p.is_multiple_of(2) {
                acc += 2.0 * t * row[(p / 2).min(nw - 1)];
            }
        }
        acc
    };
    let (a, b, c) = (2.0 * TAPS[0], 2.0 * TAPS[2], 2.0 * TAPS[4]);
    let (d, e) = (2.0 * TAPS[1], 2.0 * TAPS[3]);
    // Columns x with x-2..=x+2 inside the row: 2 <= x <= w-3; by pairs
    // (2j, 2j+1) for 1 <= j with 2j+1 <= w-3.
    let pairs_end = if w >= 4 { (w - 4) / 2 + 1 } else { 1 };
    let j0 = 1.min(pairs_end);
    for (x, o) in out.iter_mut().enumerate().take(2 * j0) {
        *o = edge(x);
    }
    if pairs_end > j0 {
        // Pairs j0..pairs_end read row[j0-1 ..= pairs_end]: by windows of
        // three, so that the loop has no bounds check a pixel.
        let src = &row[j0 - 1..pairs_end + 1];
        let dst = &mut out[2 * j0..2 * pairs_end];
        for (o, v) in dst.chunks_exact_mut(2).zip(src.windows(3)) {
            let (l, m, r) = (v[0], v[1], v[2]);
            o[0] = a * l + b * m + c * r;
            o[1] = d * m + e * r;
        }
    }
    for (x, o) in out.iter_mut().enumerate().skip(2 * pairs_end.max(j0)) {
        *o = edge(x);
    }
}

/// What [`expand`] does with each value `v` it makes for `dst[i]`.
#[derive(Clone, Copy)]
enum Put<'a> {
    /// `dst[i] -= v` (a Laplacian level from its Gaussian).
    Sub,
    /// `dst[i] = v + band[i]` (a Gaussian level from its Laplacian).
    Add(&'a [f32]),
}

simd_fn! {
/// Whole rows of `src` (`nw` wide) through [`expand_row`] into `out`.
fn expand_rows(src: &[f32], out: &mut [f32], nw: usize, w: usize) {
    for (r, o) in src.chunks_exact(nw).zip(out.chunks_exact_mut(w)) {
        expand_row(r, nw, o, w);
    }
}
}

simd_fn! {
/// Rows `y0..` (as many as `dst` holds, `w` wide) of the vertical half of
/// [`expand`] from `tmp` (`nh` rows of `w`): row y takes the rows r with
/// 2r = y + k - 2, weight 2·t_k, in tap order.
fn expand_cols(tmp: &[f32], w: usize, h: usize, nh: usize, dst: &mut [f32], y0: usize, put: Put<'_>) {
    for (dy, out) in dst.chunks_exact_mut(w).enumerate() {
        let y = y0 + dy;
        // (Up to 5 when h is 1: every tap mirrors onto row 0.)
        let mut taps: [(f32, usize); 5] = [(0.0, 0); 5];
        let mut n = 0;
        for (k, t) in TAPS.iter().enumerate() {
            let p = reflect(y as isize + k as isize - 2, h);
            if p.is_multiple_of(2) {
                taps[n] = (2.0 * t, (p / 2).min(nh - 1));
                n += 1;
            }
        }
        let row = |r: usize| &tmp[r * w..(r + 1) * w];
        let band = match put {
            Put::Sub => None,
            Put::Add(b) => Some(&b[y * w..(y + 1) * w]),
        };
        // The two common cases by zipped rows (no bounds check a pixel).
        match (n, band) {
            (3, None) => {
                let ((a, ra), (b, rb), (c, rc)) = (taps[0], taps[1], taps[2]);
                let rows = row(ra).iter().zip(row(rb)).zip(row(rc));
                for (o, ((x, y), z)) in out.iter_mut().zip(rows) {
                    *o -= a * x + b * y + c * z;
                }
            }
            (3, Some(bd)) => {
                let ((a, ra), (b, rb), (c, rc)) = (taps[0], taps[1], taps[2]);
                let rows = row(ra).iter().zip(row(rb)).zip(row(rc)).zip(bd);
                for (o, (((x, y), z), bv)) in out.iter_mut().zip(rows) {
                    *o = a * x + b * y + c * z + bv;
                }
            }
            (2, None) => {
                let ((a, ra), (b, rb)) = (taps[0], taps[1]);
                for (o, (x, y)) in out.iter_mut().zip(row(ra).iter().zip(row(rb))) {
                    *o -= a * x + b * y;
                }
            }
            (2, Some(bd)) => {
                let ((a, ra), (b, rb)) = (taps[0], taps[1]);
                let rows = row(ra).iter().zip(row(rb)).zip(bd);
                for (o, ((x, y), bv)) in out.iter_mut().zip(rows) {
                    *o = a * x + b * y + bv;
                }
            }
            _ => store_row(out, band, |i| {
                let mut acc = 0.0;
                for &(a, r) in &taps[..n] {
                    acc += a * tmp[r * w + i];
                }
                acc
            }),
        }
    }
}
}

/// `out[i] -= v(i)`, or `out[i] = v(i) + band[i]` with a band.
#[inline(always)]
fn store_row(out: &mut [f32], band: Option<&[f32]>, v: impl Fn(usize) -> f32) {
    match band {
        None => {
            for (i, o) in out.iter_mut().enumerate() {
                *o -= v(i);
            }
        }
        Some(b) => {
            for ((i, o), bv) in out.iter_mut().enumerate().zip(b) {
                *o = v(i) + bv;
            }
        }
    }
}

/// `dst` (`w x h`) combined by `put` with 4·B * (src upsampled by zero
/// insertion).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn expand(
    src: &[f32],
    nw: usize,
    nh: usize,
    dst: &mut [f32],
    w: usize,
    h: usize,
    tmp: &mut [f32],
    put: Put,
    j: Par<'_>,
) {
    // Horizontal: tmp is nh x w.
    let nm = mid_row(nh, w);
    let (t0, t1) = tmp[..nh * w].split_at_mut(nm * w);
    let v = j.simd;
    both(
        j,
        nm < nh,
        || expand_rows(v, &src[..nm * nw], t0, nw, w),
        || expand_rows(v, &src[nm * nw..nh * nw], t1, nw, w),
    );
    let tmp = &tmp[..nh * w];
    let hm = mid_row(h, w);
    let (d0, d1) = dst[..h * w].split_at_mut(hm * w);
    both(
        j,
        hm < h,
        || expand_cols(v, tmp, w, h, nh, d0, 0, put),
        || expand_cols(v, tmp, w, h, nh, d1, hm, put),
    );
}
