//! Where a rendered frame goes: the caller's 8- or 16-bit pixels ([`Dest`]) or a float
//! buffer for noise-free frames, and the rounding of each row, noise added, into them.

use vibroscope_io::Depth;

/// Where a frame goes: row-major pixels, top row first, `width * height`
/// of them (a shorter buffer gets its whole rows only).
pub enum Dest<'a> {
    U8(&'a mut [u8]),
    U16(&'a mut [u16]),
}

impl Dest<'_> {
    pub fn len(&self) -> usize {
        match self {
            Dest::U8(p) => p.len(),
            Dest::U16(p) => p.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn depth(&self) -> Depth {
        match self {
            Dest::U8(_) => Depth::U8,
            Dest::U16(_) => Depth::U16,
        }
    }
}

pub(super) enum Out<'a> {
    U8(&'a mut [u8]),
    U16(&'a mut [u16]),
    F32(&'a mut [f32]),
}

impl Out<'_> {
    pub(super) fn len(&self) -> usize {
        match self {
            Out::U8(p) => p.len(),
            Out::U16(p) => p.len(),
            Out::F32(p) => p.len(),
        }
    }
}

pub(super) fn dest_out(dst: Dest<'_>) -> Out<'_> {
    match dst {
        Dest::U8(p) => Out::U8(p),
        Dest::U16(p) => Out::U16(p),
    }
}

/// A pixel type the frame is stored as.
pub(super) trait Pixel: Copy {
    fn from_rounded(v: f32) -> Self;
}

impl Pixel for u8 {
    #[inline]
    fn from_rounded(v: f32) -> Self {
        v as u8
    }
}

impl Pixel for u16 {
    #[inline]
    fn from_rounded(v: f32) -> Self {
        v as u16
    }
}

/// `round(clamp(line + noise, 0, maxv))`: clamping first makes `+ 0.5` and
/// truncation a round-half-up, and maps NaN to 0.
pub(super) fn quantise<P: Pixel>(line: &[f32], noise: Option<&[f32]>, maxv: f32, out: &mut [P]) {
    match noise {
        Some(n) => {
            for ((o, &v), &z) in out.iter_mut().zip(line).zip(n) {
                *o = P::from_rounded((v + z).max(0.0).min(maxv) + 0.5);
            }
        }
        None => {
            for (o, &v) in out.iter_mut().zip(line) {
                *o = P::from_rounded(v.max(0.0).min(maxv) + 0.5);
            }
        }
    }
}
