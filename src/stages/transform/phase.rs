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
    /// Worker threads for the per-pixel phase sums (0 = one per core, at
    /// most 8). The output is bit-identical for any value: rows are summed
    /// in fixed chunks and the chunks added in order.
    #[serde(default)]
    threads: usize,
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
        if v.threads > 256 {
            return Err(p.error("threads", format!("must be 0..=256, got {}", v.threads)));
        }
        Ok(Box::new(PhasePlan(v)))
    },
};

struct PhasePlan(P);

impl Plan for PhasePlan {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        let v = self.0;
        let threads = match v.threads {
            0 => std::thread::available_parallelism()
                .map_or(1, |n| n.get())
                .min(8),
            n => n,
        };
        Ok(Node::Stage(Box::new(Phase {
            pool: super::reduce::thread_pool(threads)?,
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
    width: usize,
    height: usize,
    /// Σ A² over every band's region in the first frame (output scale).
    norm: f64,
    sums: Vec<f64>,
    /// Fixed work items (band, first row, end row) and their partial sums.
    items: Vec<(usize, usize, usize)>,
    partial: Vec<f64>,
}

struct Phase {
    pool: Option<rayon::ThreadPool>,
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
        let mut bands: Vec<BandState> = Vec::with_capacity(infos.len());
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
        let items: Vec<(usize, usize, usize)> = bands
            .iter()
            .enumerate()
            .flat_map(|(i, b)| {
                (b.y0..b.y1)
                    .step_by(ROWS_PER_ITEM)
                    .map(move |y| (i, y, (y + ROWS_PER_ITEM).min(b.y1)))
            })
            .collect();
        self.state = Some(State {
            pyr,
            frames: 0,
            input: vec![0.0; w * h],
            amp: vec![0.0; largest],
            sums: vec![0.0; bands.len()],
            partial: vec![0.0; items.len()],
            items,
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

/// Rows of one band per parallel work item.
const ROWS_PER_ITEM: usize = 8;

/// Eq. 3.2-3.4 for every band of one frame: fills `sums` with
/// Σ A(t0)² (φ(t) - φ(t0)) per band and returns the total A(t0)². Set 0 of
/// `c` is the reference frame, set 1 the current one; on the first frame
/// the weights are recorded and the sums are zero.
#[allow(clippy::too_many_arguments)]
fn frame_signals<C: PhaseBands + Sync>(
    c: &[C; 2],
    first: bool,
    bands: &mut [BandState],
    amp: &mut [f32],
    items: &[(usize, usize, usize)],
    partial: &mut [f64],
    pool: Option<&rayon::ThreadPool>,
    sums: &mut [f64],
) -> Result<f64, StageError> {
    use rayon::prelude::*;
    let [reference, now] = c;
    if first {
        let mut total = 0.0f64;
        for (i, b) in bands.iter_mut().enumerate() {
            let amp = &mut amp[..b.len];
            reference.amplitude_into(i, amp).map_err(err)?;
            b.weight
                .iter_mut()
                .zip(amp.iter())
                .for_each(|(w, a)| *w = a * a);
            for y in b.y0..b.y1 {
                total += b.weight[y * b.width + b.x0..y * b.width + b.x1]
                    .iter()
                    .map(|&w| w as f64)
                    .sum::<f64>();
            }
            sums[i] = 0.0;
        }
        return Ok(total);
    }
    let bands = &*bands;
    let work = |(slot, &(i, y0, y1)): (&mut f64, &(usize, usize, usize))| {
        let b = &bands[i];
        *slot = now
            .weighted_phase_delta_sum(reference, i, &b.weight, y0..y1, b.x0..b.x1)
            .unwrap_or(f64::NAN);
    };
    match pool {
        Some(pool) => pool.install(|| partial.par_iter_mut().zip(items.par_iter()).for_each(work)),
        None => partial.iter_mut().zip(items.iter()).for_each(work),
    }
    sums.iter_mut().for_each(|s| *s = 0.0);
    for (&p, &(i, _, _)) in partial.iter().zip(items) {
        sums[i] += p;
    }
    if sums.iter().any(|s| s.is_nan()) {
        return Err(StageError::msg(
            "pyramid: coefficients do not match the region (internal error)",
        ));
    }
    Ok(0.0)
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
        let (bands, amp, items, partial, sums) = (
            &mut st.bands[..],
            &mut st.amp[..],
            &st.items[..],
            &mut st.partial[..],
            &mut st.sums[..],
        );
        let pool = self.pool.as_ref();
        let weight = match &mut st.pyr {
            Pyr::Csp(p, c) => {
                p.analyze(&st.input, &mut c[slot]).map_err(err)?;
                frame_signals(c, first, bands, amp, items, partial, pool, sums)?
            }
            Pyr::Riesz(p, c) => {
                p.analyze(&st.input, &mut c[slot]).map_err(err)?;
                frame_signals(c, first, bands, amp, items, partial, pool, sums)?
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
