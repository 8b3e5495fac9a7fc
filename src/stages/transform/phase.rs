//! `phase`: per-band weighted local motion signals (thesis Eq. 3.1-3.4).
//!
//! Each frame goes through a complex steerable pyramid (`pyramid = "csp"`,
//! Eq. 3.1) or a Riesz pyramid (`"riesz"`, the fast alternative). Per band
//! `l` and pixel, the local displacement u = φ(t) - φ(t0) (Eq. 3.2) is the
//! wrapped phase difference against the first frame; the band signal is
//! a_l(t) = Σ_{x,y in roi} A(t0)² u(t) (Eq. 3.3-3.4). The weights are the
//! reference frame's contrast: with A(t)², which moves with the object, the
//! reference frame's fixed phase noise is modulated by the signal and the
//! error grows with the motion (measured: +3.3 dB instead of +6 dB for
//! twice the motion at 12 dB SNR); for the sub-pixel motions of a visual
//! microphone A(t) ≈ A(t0) anyway.
//!
//! Why not a running sum of frame-to-frame increments (which would follow
//! motions beyond half a wavelength)? In low-contrast pixels the phase is
//! noise, increments wrap, and the sum becomes a random walk of ±2π steps
//! that swamps sub-pixel signals even after A² weighting (measured: -12.7 dB
//! instead of +20 dB on the synthetic scene). Large, slow drifts are left to
//! a re-referencing scheme not built yet. The output carries one
//! channel per band (scale-major: `scale * orientations + orientation`)
//! at each frame's capture time. All bands are divided by one constant, the
//! total A² of the first frame over all bands, which keeps their relative
//! weights (Eq. 3.6 sums them unnormalised) and gives values of the order
//! of radians of phase instead of millions.

use super::roi::{Roi, RoiParam};
use crate::dsp::pyramid::{ComplexSteerablePyramid, PhaseBands, PyramidCoeffs};
use crate::dsp::riesz::{RieszCoeffs, RieszPyramid};
use crate::engine::*;
use serde::Deserialize;
use std::sync::Arc;

#[derive(Deserialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
pub enum PyramidKind {
    Csp,
    Riesz,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct P {
    #[serde(default = "d_pyr")]
    pyramid: PyramidKind,
    #[serde(default = "d_scales")]
    scales: usize,
    #[serde(default = "d_orient")]
    orientations: usize,
    roi: Option<RoiParam>,
    /// Frames per emitted block.
    #[serde(default = "d_block")]
    block: usize,
}
fn d_pyr() -> PyramidKind {
    PyramidKind::Csp
}
fn d_scales() -> usize {
    4
}
fn d_orient() -> usize {
    2
}
fn d_block() -> usize {
    64
}

pub const KIND: KindSpec = KindSpec {
    name: "phase",
    summary: "pyramid (csp or riesz) local phase, A²-weighted and summed per band (Eq. 3.1-3.4) -> one channel per band",
    accepts: &[PortType::Frames],
    max_inputs: 1,
    output: Output::Fixed(PortType::Samples),
    plan: |p| {
        let v: P = p.parse()?;
        if !(1..=8).contains(&v.scales) {
            return Err(p.error("scales", format!("must be 1..=8, got {}", v.scales)));
        }
        if !(1..=8).contains(&v.orientations) {
            return Err(p.error("orientations", format!("must be 1..=8, got {}", v.orientations)));
        }
        if !(1..=65536).contains(&v.block) {
            return Err(p.error("block", format!("must be 1..=65536, got {}", v.block)));
        }
        if let Some(r) = &v.roi {
            r.check().map_err(|m| p.error("roi", m))?;
        }
        Ok(Box::new(PhasePlan(v)))
    },
};

struct PhasePlan(P);

impl Plan for PhasePlan {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        let v = self.0;
        Ok(Node::Stage(Box::new(Phase {
            kind: v.pyramid,
            scales: v.scales,
            orientations: v.orientations,
            roi: v.roi,
            block: v.block,
            state: None,
            out: Vec::new(),
            t0_ns: 0,
            rate: 0.0,
            frames_in_block: 0,
        })))
    }
}

/// One pyramid with the coefficients of the current and previous frame.
enum Pyr {
    Csp(Box<ComplexSteerablePyramid>, Box<[PyramidCoeffs; 2]>),
    Riesz(Box<RieszPyramid>, Box<[RieszCoeffs; 2]>),
}

struct BandState {
    /// Region of the band grid that maps into the ROI.
    x0: usize,
    x1: usize,
    y0: usize,
    y1: usize,
    width: usize,
    len: usize,
    /// A(t0)² over the band (Eq. 3.3 weights), set on the first frame.
    weight: Vec<f32>,
}

struct State {
    /// Coefficient set 0 holds the reference (first) frame, set 1 the current one.
    pyr: Pyr,
    frames: u64,
    input: Vec<f32>,
    bands: Vec<BandState>,
    amp: Vec<f32>,
    dphi: Vec<f32>,
    width: usize,
    height: usize,
    /// Σ A² over every band's region in the first frame (output scale).
    norm: f64,
    sums: Vec<f64>,
}

struct Phase {
    kind: PyramidKind,
    scales: usize,
    orientations: usize,
    roi: Option<RoiParam>,
    block: usize,
    state: Option<State>,
    out: Vec<f32>,
    t0_ns: i64,
    rate: f64,
    frames_in_block: usize,
}

fn err(e: crate::dsp::pyramid::PyramidError) -> StageError {
    StageError::msg(format!("pyramid: {e}"))
}

impl Phase {
    fn init(&mut self, f: &Frame) -> Result<(), StageError> {
        let (w, h) = (f.width(), f.height());
        let roi = Roi::resolve(self.roi.as_ref(), w, h)?;
        let pyr = match self.kind {
            PyramidKind::Csp => {
                let p = ComplexSteerablePyramid::new(w, h, self.scales, self.orientations)
                    .map_err(err)?;
                let c = Box::new([p.alloc_coeffs(), p.alloc_coeffs()]);
                Pyr::Csp(Box::new(p), c)
            }
            PyramidKind::Riesz => {
                let p = RieszPyramid::new(w, h, self.scales, self.orientations).map_err(err)?;
                let c = Box::new([p.alloc_coeffs(), p.alloc_coeffs()]);
                Pyr::Riesz(Box::new(p), c)
            }
        };
        let infos: Vec<_> = match &pyr {
            Pyr::Csp(_, c) => (0..c[0].num_bands())
                .filter_map(|i| c[0].band_info(i).cloned())
                .collect(),
            Pyr::Riesz(_, c) => (0..c[0].num_bands())
                .filter_map(|i| c[0].band_info(i).cloned())
                .collect(),
        };
        let mut bands = Vec::with_capacity(infos.len());
        let mut largest = 0;
        for b in &infos {
            // Band pixel x' sits at input x = x' * step.
            let to_band =
                |v: usize, step: f32, n: usize| ((v as f32 / step).ceil() as usize).min(n);
            let x0 = to_band(roi.x, b.step_x, b.width);
            let x1 = to_band(roi.x + roi.w, b.step_x, b.width).max(x0);
            let y0 = to_band(roi.y, b.step_y, b.height);
            let y1 = to_band(roi.y + roi.h, b.step_y, b.height).max(y0);
            largest = largest.max(b.len());
            bands.push(BandState {
                x0,
                x1,
                y0,
                y1,
                width: b.width,
                len: b.len(),
                weight: vec![0.0; b.len()],
            });
        }
        self.state = Some(State {
            pyr,
            frames: 0,
            input: vec![0.0; w * h],
            amp: vec![0.0; largest],
            dphi: vec![0.0; largest],
            sums: vec![0.0; bands.len()],
            bands,
            width: w,
            height: h,
            norm: 0.0,
        });
        self.out = Vec::with_capacity(self.block * infos.len());
        Ok(())
    }

    fn flush(&mut self, out: &mut Emitter) {
        let Some(st) = &self.state else { return };
        if self.frames_in_block == 0 {
            return;
        }
        let data: Arc<[f32]> = Arc::from(&self.out[..]);
        self.out.clear();
        self.frames_in_block = 0;
        let _ = out.emit(Item::Samples(SampleBlock {
            t0_ns: self.t0_ns,
            rate_hz: self.rate,
            channels: st.bands.len(),
            data,
            times_ns: None,
        }));
    }
}

/// Eq. 3.2-3.4 for one band: returns (Σ A(t0)² u, Σ A(t0)²) over the
/// band's region, u the phase change from `reference` to `cur`. On the
/// first frame (`cur` is the reference) it records the weights.
fn band_signal<C: PhaseBands>(
    cur: &C,
    reference: &C,
    first: bool,
    i: usize,
    b: &mut BandState,
    amp: &mut [f32],
    dphi: &mut [f32],
) -> Result<(f64, f64), StageError> {
    let n = b.len;
    let dphi = &mut dphi[..n];
    if first {
        let amp = &mut amp[..n];
        reference.amplitude_into(i, amp).map_err(err)?;
        b.weight
            .iter_mut()
            .zip(amp.iter())
            .for_each(|(w, a)| *w = a * a);
        dphi.fill(0.0);
    } else {
        cur.phase_delta_into(reference, i, dphi).map_err(err)?;
    }
    let (mut sum, mut weight) = (0.0f64, 0.0f64);
    for y in b.y0..b.y1 {
        let row = y * b.width;
        let (mut acc, mut wacc) = (0.0f32, 0.0f32);
        for x in b.x0..b.x1 {
            let a2 = b.weight[row + x];
            acc += a2 * dphi[row + x];
            wacc += a2;
        }
        sum += acc as f64;
        weight += wacc as f64;
    }
    Ok((sum, weight))
}

/// Eq. 3.2-3.4 for every band of one frame: fills `sums` and returns the
/// total A². Coefficient set 0 is the reference frame, set 1 the current
/// one (on the first frame the reference is the current frame).
fn frame_signals<C: PhaseBands>(
    c: &[C; 2],
    first: bool,
    bands: &mut [BandState],
    amp: &mut [f32],
    dphi: &mut [f32],
    sums: &mut [f64],
) -> Result<f64, StageError> {
    let [reference, now] = c;
    let mut weight = 0.0;
    for (i, band) in bands.iter_mut().enumerate() {
        let (s, w) = band_signal(now, reference, first, i, band, amp, dphi)?;
        sums[i] = s;
        weight += w;
    }
    Ok(weight)
}

impl Stage for Phase {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        let Item::Frame(f) = item else {
            return Err(StageError::msg("expected frames"));
        };
        if self.state.is_none() {
            self.init(&f)?;
        }
        let Some(st) = self.state.as_mut() else {
            return Ok(());
        };
        if (f.width(), f.height()) != (st.width, st.height) {
            return Err(StageError::msg("the frame size changed mid-stream"));
        }
        match f.pixels() {
            PixelsRef::U8(p) => st.input.iter_mut().zip(p).for_each(|(d, &s)| *d = s as f32),
            PixelsRef::U16(p) => st.input.iter_mut().zip(p).for_each(|(d, &s)| *d = s as f32),
        }
        let first = st.frames == 0;
        let slot = usize::from(!first);
        if self.frames_in_block == 0 {
            self.t0_ns = f.meta().t_ns;
            self.rate = f.format().fps;
        }
        let (bands, amp, dphi, sums) = (
            &mut st.bands[..],
            &mut st.amp[..],
            &mut st.dphi[..],
            &mut st.sums[..],
        );
        let weight = match &mut st.pyr {
            Pyr::Csp(p, c) => {
                p.analyze(&st.input, &mut c[slot]).map_err(err)?;
                frame_signals(c, first, bands, amp, dphi, sums)?
            }
            Pyr::Riesz(p, c) => {
                p.analyze(&st.input, &mut c[slot]).map_err(err)?;
                frame_signals(c, first, bands, amp, dphi, sums)?
            }
        };
        if first {
            st.norm = weight;
        }
        if first && st.norm <= 0.0 {
            return Err(StageError::msg(
                "the region has no texture (zero local contrast in every band)",
            ));
        }
        let norm = st.norm;
        self.out.extend(st.sums.iter().map(|&s| (s / norm) as f32));
        st.frames += 1;
        self.frames_in_block += 1;
        if self.frames_in_block >= self.block {
            self.flush(out);
        }
        Ok(())
    }

    fn finish(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        self.flush(out);
        Ok(())
    }
}
