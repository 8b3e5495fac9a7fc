//! A versioned, compact binary encoding of the items that cross a process
//! edge (issue 21): audio blocks, per-band samples, spectra, peak sets and,
//! on request, frames. Every item keeps its capture timestamps.
//!
//! Layout (all numbers little-endian):
//!
//! ```text
//! "VBW" | version u8 (= 1) | kind u8 | body
//! ```
//!
//! Bodies, by kind:
//! - 1 audio: `t0_ns i64, rate_hz f64, n u32, n × f32`
//! - 2 samples: `t0_ns i64, rate_hz f64, channels u32, n u32, n × f32,
//!   has_times u8, [frames u32, frames × i64]`
//! - 3 spectrum: `t_ns i64, f0_hz f64, resolution_hz f64, rate_hz f64,
//!   window u32, taper u8, segments u32, n u32, n × f32`
//! - 4 peaks: `t_ns i64, n u32, n × (frequency_hz, frequency_std_hz,
//!   power_db, prominence_db, damping_ratio, damping_ratio_std: f64)`
//! - 5 frame: `seq u64, t_ns i64, width u32, height u32, depth u8, bits u8,
//!   fps f64, has_timing u8, [line_delay_ns f64, exposure_ns f64],
//!   width × height pixels (u8 or u16)`
//!
//! Decoding never panics: an unknown version or kind, a truncated body, an
//! invalid value or trailing bytes is a [`WireError`] naming what was wrong.
//! Lengths are checked against the bytes actually present before anything is
//! allocated, so garbage cannot make the decoder allocate huge buffers.
//! [`encode_into`] reuses the caller's buffer: a stage that keeps one buffer
//! allocates nothing per item once it has grown to the largest item.

use crate::frame::{Depth, Frame, FrameFormat, FrameMeta, PixelsRef, RowTiming};
use crate::item::{AudioBlock, SampleBlock, Spectrum, Taper};
use std::sync::Arc;

/// The first three bytes of every encoded item.
pub const MAGIC: &[u8; 3] = b"VBW";
/// The version this build writes and reads.
pub const VERSION: u8 = 1;

/// What went wrong decoding bytes received on an edge.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WireError {
    #[error("not a vibroscope item: expected magic \"VBW\", got {0:02x?}")]
    BadMagic(Vec<u8>),
    #[error("unknown encoding version {got} (this build reads version {VERSION})")]
    UnknownVersion { got: u8 },
    #[error("unknown item kind {0} (known: 1 audio, 2 samples, 3 spectrum, 4 peaks, 5 frame)")]
    UnknownKind(u8),
    #[error("truncated item: {what} needs {need} bytes at offset {at}, only {have} left")]
    Truncated {
        what: &'static str,
        at: usize,
        need: usize,
        have: usize,
    },
    #[error("invalid {what}: {value}")]
    Invalid { what: &'static str, value: String },
    #[error("{0} trailing bytes after the item")]
    Trailing(usize),
}

pub use crate::item::PeakSet;
/// One resonance as it travels (the item type, under its wire name).
pub use crate::item::Resonance as WirePeak;

/// Pixels of a decoded frame, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub enum WirePixels {
    U8(Vec<u8>),
    U16(Vec<u16>),
}

/// A decoded frame (owned: the receiving source copies it into its pool).
#[derive(Clone, Debug, PartialEq)]
pub struct WireFrame {
    pub format: FrameFormat,
    pub meta: FrameMeta,
    pub pixels: WirePixels,
}

/// Borrowed view of what to encode.
#[derive(Clone, Copy, Debug)]
pub enum WireRef<'a> {
    Audio(&'a AudioBlock),
    Samples(&'a SampleBlock),
    Spectrum(&'a Spectrum),
    Peaks(&'a PeakSet),
    Frame(&'a Frame),
}

/// A decoded item.
#[derive(Clone, Debug, PartialEq)]
pub enum WireItem {
    Audio(AudioBlock),
    Samples(SampleBlock),
    Spectrum(Spectrum),
    Peaks(PeakSet),
    Frame(WireFrame),
}

impl WireItem {
    /// Capture time the item refers to, ns on the source clock.
    pub fn t_ns(&self) -> i64 {
        match self {
            WireItem::Audio(a) => a.t0_ns,
            WireItem::Samples(s) => s.t0_ns,
            WireItem::Spectrum(s) => s.t_ns,
            WireItem::Peaks(p) => p.t_ns,
            WireItem::Frame(f) => f.meta.t_ns,
        }
    }
}

const K_AUDIO: u8 = 1;
const K_SAMPLES: u8 = 2;
const K_SPECTRUM: u8 = 3;
const K_PEAKS: u8 = 4;
const K_FRAME: u8 = 5;

fn len_u32(n: usize, what: &'static str) -> Result<u32, WireError> {
    u32::try_from(n).map_err(|_| WireError::Invalid {
        what,
        value: format!("{n} does not fit the 32-bit length field"),
    })
}

fn taper_code(t: Taper) -> u8 {
    match t {
        Taper::Hann => 0,
        Taper::Hamming => 1,
        Taper::Blackman => 2,
        Taper::Rect => 3,
    }
}

/// Encodes `item` into `out` (cleared first; its capacity is reused).
/// Fails only on lengths that do not fit the format's 32-bit fields.
pub fn encode_into(item: WireRef<'_>, out: &mut Vec<u8>) -> Result<(), WireError> {
    out.clear();
    out.extend_from_slice(MAGIC);
    out.push(VERSION);
    match item {
        WireRef::Audio(a) => {
            out.push(K_AUDIO);
            out.extend_from_slice(&a.t0_ns.to_le_bytes());
            out.extend_from_slice(&a.rate_hz.to_le_bytes());
            put_f32s(out, &a.samples, "audio sample count")?;
        }
        WireRef::Samples(s) => {
            out.push(K_SAMPLES);
            out.extend_from_slice(&s.t0_ns.to_le_bytes());
            out.extend_from_slice(&s.rate_hz.to_le_bytes());
            out.extend_from_slice(&len_u32(s.channels, "channel count")?.to_le_bytes());
            put_f32s(out, &s.data, "sample count")?;
            match &s.times_ns {
                None => out.push(0),
                Some(t) => {
                    out.push(1);
                    out.extend_from_slice(&len_u32(t.len(), "row-time count")?.to_le_bytes());
                    for v in t.iter() {
                        out.extend_from_slice(&v.to_le_bytes());
                    }
                }
            }
        }
        WireRef::Spectrum(s) => {
            out.push(K_SPECTRUM);
            out.extend_from_slice(&s.t_ns.to_le_bytes());
            out.extend_from_slice(&s.f0_hz.to_le_bytes());
            out.extend_from_slice(&s.resolution_hz.to_le_bytes());
            out.extend_from_slice(&s.rate_hz.to_le_bytes());
            out.extend_from_slice(&len_u32(s.window, "spectrum window")?.to_le_bytes());
            out.push(taper_code(s.taper));
            out.extend_from_slice(&len_u32(s.segments, "spectrum segments")?.to_le_bytes());
            put_f32s(out, &s.power, "spectrum length")?;
        }
        WireRef::Peaks(p) => {
            out.push(K_PEAKS);
            out.extend_from_slice(&p.t_ns.to_le_bytes());
            out.extend_from_slice(&len_u32(p.peaks.len(), "peak count")?.to_le_bytes());
            for k in &p.peaks {
                for v in [
                    k.frequency_hz,
                    k.frequency_std_hz,
                    k.power_db,
                    k.prominence_db,
                    k.damping_ratio,
                    k.damping_ratio_std,
                ] {
                    out.extend_from_slice(&v.to_le_bytes());
                }
            }
        }
        WireRef::Frame(f) => {
            out.push(K_FRAME);
            let fmt = f.format();
            let meta = f.meta();
            out.extend_from_slice(&meta.seq.to_le_bytes());
            out.extend_from_slice(&meta.t_ns.to_le_bytes());
            out.extend_from_slice(&fmt.width.to_le_bytes());
            out.extend_from_slice(&fmt.height.to_le_bytes());
            out.push(match fmt.depth {
                Depth::U8 => 8,
                Depth::U16 => 16,
            });
            out.push(fmt.bits);
            out.extend_from_slice(&fmt.fps.to_le_bytes());
            match fmt.row_timing {
                None => out.push(0),
                Some(rt) => {
                    out.push(1);
                    out.extend_from_slice(&rt.line_delay_ns.to_le_bytes());
                    out.extend_from_slice(&rt.exposure_ns.to_le_bytes());
                }
            }
            match f.pixels() {
                PixelsRef::U8(p) => out.extend_from_slice(p),
                PixelsRef::U16(p) => {
                    for v in p {
                        out.extend_from_slice(&v.to_le_bytes());
                    }
                }
            }
        }
    }
    Ok(())
}

fn put_f32s(out: &mut Vec<u8>, v: &[f32], what: &'static str) -> Result<(), WireError> {
    out.extend_from_slice(&len_u32(v.len(), what)?.to_le_bytes());
    out.reserve(v.len() * 4);
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
    Ok(())
}

struct Reader<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize, what: &'static str) -> Result<&'a [u8], WireError> {
        let have = self.b.len() - self.at;
        if n > have {
            return Err(WireError::Truncated {
                what,
                at: self.at,
                need: n,
                have,
            });
        }
        let s = &self.b[self.at..self.at + n];
        self.at += n;
        Ok(s)
    }
    fn arr<const N: usize>(&mut self, what: &'static str) -> Result<[u8; N], WireError> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N, what)?);
        Ok(a)
    }
    fn u8(&mut self, what: &'static str) -> Result<u8, WireError> {
        Ok(self.take(1, what)?[0])
    }
    fn u32(&mut self, what: &'static str) -> Result<u32, WireError> {
        Ok(u32::from_le_bytes(self.arr(what)?))
    }
    fn u64(&mut self, what: &'static str) -> Result<u64, WireError> {
        Ok(u64::from_le_bytes(self.arr(what)?))
    }
    fn i64(&mut self, what: &'static str) -> Result<i64, WireError> {
        Ok(i64::from_le_bytes(self.arr(what)?))
    }
    fn f64(&mut self, what: &'static str) -> Result<f64, WireError> {
        Ok(f64::from_le_bytes(self.arr(what)?))
    }
    /// A rate: finite and positive.
    fn rate(&mut self, what: &'static str) -> Result<f64, WireError> {
        let v = self.f64(what)?;
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(WireError::Invalid {
                what,
                value: format!("{v} (must be finite and > 0)"),
            })
        }
    }
    /// `count` elements of `size` bytes, checked present before allocating.
    fn block(
        &mut self,
        count: usize,
        size: usize,
        what: &'static str,
    ) -> Result<&'a [u8], WireError> {
        let need = count.checked_mul(size).ok_or(WireError::Invalid {
            what,
            value: format!("{count} elements overflow"),
        })?;
        self.take(need, what)
    }
    fn f32s(&mut self, what: &'static str) -> Result<Arc<[f32]>, WireError> {
        let n = self.u32(what)? as usize;
        let b = self.block(n, 4, what)?;
        Ok(b.chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect())
    }
}

/// Decodes one item; see the module doc for the layout.
pub fn decode(bytes: &[u8]) -> Result<WireItem, WireError> {
    let mut r = Reader { b: bytes, at: 0 };
    let magic = r
        .take(3, "magic")
        .map_err(|_| WireError::BadMagic(bytes.to_vec()))?;
    if magic != MAGIC {
        return Err(WireError::BadMagic(magic.to_vec()));
    }
    let version = r.u8("version")?;
    if version != VERSION {
        return Err(WireError::UnknownVersion { got: version });
    }
    let kind = r.u8("kind")?;
    let item = match kind {
        K_AUDIO => WireItem::Audio(AudioBlock {
            t0_ns: r.i64("audio t0_ns")?,
            rate_hz: r.rate("audio rate_hz")?,
            samples: r.f32s("audio samples")?,
        }),
        K_SAMPLES => {
            let t0_ns = r.i64("samples t0_ns")?;
            let rate_hz = r.rate("samples rate_hz")?;
            let channels = r.u32("samples channels")? as usize;
            let data = r.f32s("samples data")?;
            if channels == 0 || data.len() % channels != 0 {
                return Err(WireError::Invalid {
                    what: "samples channels",
                    value: format!("{channels} channels for {} values", data.len()),
                });
            }
            let times_ns = match r.u8("samples has_times")? {
                0 => None,
                1 => {
                    let n = r.u32("samples row-time count")? as usize;
                    if n != data.len() / channels {
                        return Err(WireError::Invalid {
                            what: "samples row-time count",
                            value: format!("{n} times for {} frames", data.len() / channels),
                        });
                    }
                    let b = r.block(n, 8, "samples row times")?;
                    Some(
                        b.chunks_exact(8)
                            .map(|c| i64::from_le_bytes(c.try_into().unwrap_or([0; 8])))
                            .collect::<Arc<[i64]>>(),
                    )
                }
                v => {
                    return Err(WireError::Invalid {
                        what: "samples has_times flag",
                        value: v.to_string(),
                    })
                }
            };
            WireItem::Samples(SampleBlock {
                t0_ns,
                rate_hz,
                channels,
                data,
                times_ns,
            })
        }
        K_SPECTRUM => {
            let t_ns = r.i64("spectrum t_ns")?;
            let f0_hz = r.f64("spectrum f0_hz")?;
            let resolution_hz = r.rate("spectrum resolution_hz")?;
            let rate_hz = r.rate("spectrum rate_hz")?;
            let window = r.u32("spectrum window")? as usize;
            let taper = match r.u8("spectrum taper")? {
                0 => Taper::Hann,
                1 => Taper::Hamming,
                2 => Taper::Blackman,
                3 => Taper::Rect,
                v => {
                    return Err(WireError::Invalid {
                        what: "spectrum taper",
                        value: format!("code {v} (0 hann, 1 hamming, 2 blackman, 3 rect)"),
                    })
                }
            };
            let segments = r.u32("spectrum segments")? as usize;
            if !f0_hz.is_finite() {
                return Err(WireError::Invalid {
                    what: "spectrum f0_hz",
                    value: f0_hz.to_string(),
                });
            }
            WireItem::Spectrum(Spectrum {
                t_ns,
                f0_hz,
                resolution_hz,
                rate_hz,
                window,
                taper,
                segments,
                power: r.f32s("spectrum power")?,
            })
        }
        K_PEAKS => {
            let t_ns = r.i64("peaks t_ns")?;
            let n = r.u32("peak count")? as usize;
            let b = r.block(n, 48, "peaks")?;
            let f = |c: &[u8], i: usize| {
                let mut a = [0u8; 8];
                a.copy_from_slice(&c[i * 8..i * 8 + 8]);
                f64::from_le_bytes(a)
            };
            let peaks = b
                .chunks_exact(48)
                .map(|c| WirePeak {
                    frequency_hz: f(c, 0),
                    frequency_std_hz: f(c, 1),
                    power_db: f(c, 2),
                    prominence_db: f(c, 3),
                    damping_ratio: f(c, 4),
                    damping_ratio_std: f(c, 5),
                })
                .collect();
            WireItem::Peaks(PeakSet { t_ns, peaks })
        }
        K_FRAME => {
            let seq = r.u64("frame seq")?;
            let t_ns = r.i64("frame t_ns")?;
            let width = r.u32("frame width")?;
            let height = r.u32("frame height")?;
            let depth = match r.u8("frame depth")? {
                8 => Depth::U8,
                16 => Depth::U16,
                v => {
                    return Err(WireError::Invalid {
                        what: "frame depth",
                        value: format!("{v} (8 or 16)"),
                    })
                }
            };
            let bits = r.u8("frame bits")?;
            let max_bits = if depth == Depth::U8 { 8 } else { 16 };
            if bits == 0 || bits > max_bits {
                return Err(WireError::Invalid {
                    what: "frame bits",
                    value: format!("{bits} for {max_bits}-bit pixels"),
                });
            }
            let fps = r.rate("frame fps")?;
            let row_timing = match r.u8("frame has_timing")? {
                0 => None,
                1 => Some(RowTiming {
                    line_delay_ns: r.f64("frame line_delay_ns")?,
                    exposure_ns: r.f64("frame exposure_ns")?,
                }),
                v => {
                    return Err(WireError::Invalid {
                        what: "frame has_timing flag",
                        value: v.to_string(),
                    })
                }
            };
            let n = (width as usize).saturating_mul(height as usize);
            let pixels = match depth {
                Depth::U8 => WirePixels::U8(r.block(n, 1, "frame pixels")?.to_vec()),
                Depth::U16 => WirePixels::U16(
                    r.block(n, 2, "frame pixels")?
                        .chunks_exact(2)
                        .map(|c| u16::from_le_bytes([c[0], c[1]]))
                        .collect(),
                ),
            };
            WireItem::Frame(WireFrame {
                format: FrameFormat {
                    width,
                    height,
                    depth,
                    bits,
                    fps,
                    row_timing,
                },
                meta: FrameMeta { seq, t_ns },
                pixels,
            })
        }
        k => return Err(WireError::UnknownKind(k)),
    };
    let left = bytes.len() - r.at;
    if left != 0 {
        return Err(WireError::Trailing(left));
    }
    Ok(item)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn roundtrip(item: WireRef<'_>) -> WireItem {
        let mut buf = Vec::new();
        encode_into(item, &mut buf).expect("encode");
        decode(&buf).expect("decode")
    }

    fn finite() -> impl Strategy<Value = f32> {
        -1e6f32..1e6
    }

    proptest! {
        #[test]
        fn audio_round_trips(t0 in any::<i64>(), rate in 1.0f64..1e6, s in prop::collection::vec(finite(), 0..300)) {
            let a = AudioBlock { t0_ns: t0, rate_hz: rate, samples: s.into() };
            prop_assert_eq!(roundtrip(WireRef::Audio(&a)), WireItem::Audio(a));
        }

        #[test]
        fn samples_round_trip(t0 in any::<i64>(), rate in 1.0f64..1e5, ch in 1usize..6, frames in 0usize..40, with_times in any::<bool>(), seed in any::<u32>()) {
            let data: Vec<f32> = (0..ch * frames).map(|i| (i as f32 + seed as f32).sin()).collect();
            let times = with_times.then(|| (0..frames as i64).map(|i| t0.wrapping_add(i * 1000)).collect::<Arc<[i64]>>());
            let s = SampleBlock { t0_ns: t0, rate_hz: rate, channels: ch, data: data.into(), times_ns: times };
            prop_assert_eq!(roundtrip(WireRef::Samples(&s)), WireItem::Samples(s));
        }

        #[test]
        fn spectrum_round_trips(t in any::<i64>(), f0 in -10.0f64..10.0, res in 0.01f64..100.0, taper in 0u8..4, p in prop::collection::vec(0.0f32..1e3, 0..200)) {
            let taper = [Taper::Hann, Taper::Hamming, Taper::Blackman, Taper::Rect][taper as usize];
            let s = Spectrum { t_ns: t, f0_hz: f0, resolution_hz: res, rate_hz: 2400.0, window: 1024, taper, segments: 3, power: p.into() };
            prop_assert_eq!(roundtrip(WireRef::Spectrum(&s)), WireItem::Spectrum(s));
        }

        #[test]
        fn peaks_round_trip(t in any::<i64>(), v in prop::collection::vec(prop::array::uniform6(-1e4f64..1e4), 0..12)) {
            let p = PeakSet { t_ns: t, peaks: v.iter().map(|a| WirePeak {
                frequency_hz: a[0], frequency_std_hz: a[1], power_db: a[2],
                prominence_db: a[3], damping_ratio: a[4], damping_ratio_std: a[5] }).collect() };
            prop_assert_eq!(roundtrip(WireRef::Peaks(&p)), WireItem::Peaks(p));
        }

        /// Garbage never panics: it decodes to something or to an error.
        #[test]
        fn garbage_never_panics(b in prop::collection::vec(any::<u8>(), 0..200)) {
            let _ = decode(&b);
        }

        /// Valid headers followed by garbage bodies never panic either.
        #[test]
        fn garbage_bodies_never_panic(kind in 0u8..7, b in prop::collection::vec(any::<u8>(), 0..200)) {
            let mut v = MAGIC.to_vec();
            v.push(VERSION);
            v.push(kind);
            v.extend_from_slice(&b);
            let _ = decode(&v);
        }

        /// Every truncation of a valid item is an error, not a panic.
        #[test]
        fn truncations_are_errors(s in prop::collection::vec(finite(), 1..50), cut in 0usize..1000) {
            let a = AudioBlock { t0_ns: 5, rate_hz: 48000.0, samples: s.into() };
            let mut buf = Vec::new();
            encode_into(WireRef::Audio(&a), &mut buf).unwrap();
            let cut = cut % buf.len();
            prop_assert!(decode(&buf[..cut]).is_err());
        }
    }

    #[test]
    fn frame_round_trips() {
        let fmt = FrameFormat {
            width: 5,
            height: 3,
            depth: Depth::U16,
            bits: 12,
            fps: 2400.0,
            row_timing: Some(RowTiming {
                line_delay_ns: 30.5,
                exposure_ns: 100.0,
            }),
        };
        let pool = crate::frame::FramePool::new(fmt, 1);
        let mut f = pool.try_acquire().expect("a frame");
        *f.meta_mut() = FrameMeta { seq: 42, t_ns: -7 };
        if let crate::frame::PixelsMut::U16(p) = f.pixels_mut() {
            for (i, v) in p.iter_mut().enumerate() {
                *v = (i * 271) as u16 & 0x0fff;
            }
        }
        let f = f.freeze();
        let expect: Vec<u16> = (0..15).map(|i| (i * 271) as u16 & 0x0fff).collect();
        assert_eq!(
            roundtrip(WireRef::Frame(&f)),
            WireItem::Frame(WireFrame {
                format: fmt,
                meta: FrameMeta { seq: 42, t_ns: -7 },
                pixels: WirePixels::U16(expect),
            })
        );
    }

    #[test]
    fn errors_name_what_was_wrong() {
        let a = AudioBlock {
            t0_ns: 1,
            rate_hz: 8000.0,
            samples: vec![1.0; 4].into(),
        };
        let mut buf = Vec::new();
        encode_into(WireRef::Audio(&a), &mut buf).unwrap();

        let mut v = buf.clone();
        v[3] = 9;
        let e = decode(&v).unwrap_err();
        assert_eq!(e, WireError::UnknownVersion { got: 9 });
        assert!(e.to_string().contains("version 9"), "{e}");

        let mut v = buf.clone();
        v[0] = b'X';
        assert!(matches!(decode(&v), Err(WireError::BadMagic(_))));

        let mut v = buf.clone();
        v[4] = 77;
        assert_eq!(decode(&v).unwrap_err(), WireError::UnknownKind(77));

        let mut v = buf.clone();
        v.push(0);
        assert_eq!(decode(&v).unwrap_err(), WireError::Trailing(1));

        // A length claiming 2^32-1 samples with 16 bytes present: an error
        // naming the field, without allocating.
        let mut v = buf.clone();
        v[21..25].copy_from_slice(&u32::MAX.to_le_bytes());
        let e = decode(&v).unwrap_err().to_string();
        assert!(
            e.contains("audio samples") && e.contains("truncated"),
            "{e}"
        );

        // A zero rate is refused by name.
        let mut v = buf.clone();
        v[13..21].copy_from_slice(&0f64.to_le_bytes());
        let e = decode(&v).unwrap_err().to_string();
        assert!(e.contains("audio rate_hz"), "{e}");
    }

    #[test]
    fn encoding_is_compact() {
        // 5 header bytes + t0 + rate + length + 4 bytes per sample.
        let a = AudioBlock {
            t0_ns: 0,
            rate_hz: 1.0,
            samples: vec![0.0; 100].into(),
        };
        let mut buf = Vec::new();
        encode_into(WireRef::Audio(&a), &mut buf).unwrap();
        assert_eq!(buf.len(), 5 + 8 + 8 + 4 + 400);
    }
}
