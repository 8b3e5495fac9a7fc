//! The tile method's per-frame sums (`listen`'s default, the engine's
//! `tile_motion` stage): for every pixel of a region, the reference's
//! gradients times the frame's difference from the reference,
//! `gx·(ref − frame)` and `gy·(ref − frame)`, summed per tile.
//!
//! A tile's sum is made column by column: each row of the region adds its
//! products into one accumulator per column ([`TileSums::add_row_u8`],
//! [`TileSums::add_row_u16`]), a loop over contiguous rows that the
//! compiler vectorises (compiled for SSE2, AVX2 and AVX-512, the widest
//! the CPU has chosen at run time; every column is summed in the same
//! order at every width, so each gives the same bits), and the caller sums
//! each tile's columns once its rows are done. The pixel-by-pixel loop it
//! replaced summed each tile's row into one scalar, a chain of dependent
//! additions the compiler cannot vectorise without changing the result.

use crate::join::{simd_fn, Simd};

/// The loop both kernels run, inlined into each compiled copy.
#[inline(always)]
fn add_row<P: Copy + Into<f32>>(
    img: &[f32],
    gx: &[f32],
    gy: &[f32],
    frame: &[P],
    sx: &mut [f32],
    sy: &mut [f32],
) {
    let n = img.len().min(gx.len()).min(gy.len()).min(frame.len());
    let n = n.min(sx.len()).min(sy.len());
    let (img, gx, gy, frame) = (&img[..n], &gx[..n], &gy[..n], &frame[..n]);
    let (sx, sy) = (&mut sx[..n], &mut sy[..n]);
    for i in 0..n {
        let d = img[i] - frame[i].into();
        sx[i] += gx[i] * d;
        sy[i] += gy[i] * d;
    }
}

simd_fn! {
    fn add_u8(img: &[f32], gx: &[f32], gy: &[f32], frame: &[u8], sx: &mut [f32], sy: &mut [f32]) {
        add_row(img, gx, gy, frame, sx, sy)
    }
}

simd_fn! {
    fn add_u16(img: &[f32], gx: &[f32], gy: &[f32], frame: &[u16], sx: &mut [f32], sy: &mut [f32]) {
        add_row(img, gx, gy, frame, sx, sy)
    }
}

/// The row kernels, compiled for the running CPU's widest vectors.
#[derive(Clone, Copy, Debug)]
pub struct TileSums {
    simd: Simd,
}

impl Default for TileSums {
    fn default() -> Self {
        Self::new()
    }
}

impl TileSums {
    /// Detects the CPU's vectors once.
    pub fn new() -> Self {
        Self {
            simd: Simd::detect(),
        }
    }

    /// For each column `i` of one row: `sx[i] += gx[i]·(img[i] − frame[i])`
    /// and `sy[i] += gy[i]·(img[i] − frame[i])`, over the shortest of the
    /// slices.
    pub fn add_row_u8(
        &self,
        img: &[f32],
        gx: &[f32],
        gy: &[f32],
        frame: &[u8],
        sx: &mut [f32],
        sy: &mut [f32],
    ) {
        add_u8(self.simd, img, gx, gy, frame, sx, sy);
    }

    /// [`TileSums::add_row_u8`] for 16-bit pixels.
    pub fn add_row_u16(
        &self,
        img: &[f32],
        gx: &[f32],
        gy: &[f32],
        frame: &[u16],
        sx: &mut [f32],
        sy: &mut [f32],
    ) {
        add_u16(self.simd, img, gx, gy, frame, sx, sy);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every vector width gives the bits of the scalar loop, over lengths
    /// that leave every kind of tail.
    #[test]
    fn every_width_gives_the_bits_of_the_pixel_loop() {
        let mut s = 12345u64;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 33) as f32) / (1u64 << 31) as f32
        };
        for n in [1usize, 7, 15, 16, 17, 63, 254, 255] {
            let img: Vec<f32> = (0..n).map(|_| 255.0 * next()).collect();
            let gx: Vec<f32> = (0..n).map(|_| next() - 0.5).collect();
            let gy: Vec<f32> = (0..n).map(|_| next() - 0.5).collect();
            let f8: Vec<u8> = (0..n).map(|_| (255.0 * next()) as u8).collect();
            let f16: Vec<u16> = (0..n).map(|_| (65535.0 * next()) as u16).collect();
            let start: Vec<f32> = (0..n).map(|_| next()).collect();
            let mut want8 = (start.clone(), start.clone());
            let mut want16 = (start.clone(), start.clone());
            for i in 0..n {
                let d = img[i] - f8[i] as f32;
                want8.0[i] += gx[i] * d;
                want8.1[i] += gy[i] * d;
                let d = img[i] - f16[i] as f32;
                want16.0[i] += gx[i] * d;
                want16.1[i] += gy[i] * d;
            }
            for simd in [Simd::Sse2, Simd::detect()] {
                let k = TileSums { simd };
                let mut got = (start.clone(), start.clone());
                k.add_row_u8(&img, &gx, &gy, &f8, &mut got.0, &mut got.1);
                assert_eq!(got, want8, "u8, {n} columns, {}", simd.name());
                let mut got = (start.clone(), start.clone());
                k.add_row_u16(&img, &gx, &gy, &f16, &mut got.0, &mut got.1);
                assert_eq!(got, want16, "u16, {n} columns, {}", simd.name());
            }
        }
    }
}
