//! Effect (d): frames the camera dropped or delivered twice, found as the
//! steps of the lag between recovery and target (Viterbi over offsets).

use super::model::{Fit, Model};
use super::signal::golden;
use super::{Candidate, Correction, FrameEvent, Uncertainty};
use crate::numeric::median;

/// Opposite frame events closer than this (samples) cancel.
pub(super) const MIN_EVENT_GAP: usize = 32;

pub(super) fn fit_frames(m: &Model, z: &[f64], fit: &Fit) -> Option<Candidate> {
    const D: usize = 3;
    let n = z.len();
    if n < 16 {
        return None;
    }
    let g = fit.g;
    // The fractional delay common to all segments: per block of 64
    // samples the best integer offset, summed (blind to where events are).
    let blocks = |tau: f64| -> f64 {
        let t = m.target(n + 2 * D, D, tau, 0.0);
        z.chunks(64)
            .enumerate()
            .map(|(b, c)| {
                (0..2 * D + 1)
                    .map(|j| {
                        c.iter()
                            .enumerate()
                            .map(|(i, v)| (v - g * t[b * 64 + i + j]).powi(2))
                            .sum::<f64>()
                    })
                    .fold(f64::INFINITY, f64::min)
            })
            .sum()
    };
    let (tau, _) = golden(blocks, fit.tau - 0.5 / m.fs, fit.tau + 0.5 / m.fs, 16);
    let t = m.target(n + 2 * D, D, tau, 0.0);
    let nd = 2 * D + 1;
    // Cost of offset d (index d + D) at sample i: (z[i] - g T[i + d])².
    let full = |i: usize, j: usize| -> f64 {
        let v = z[i] - g * t[i + j];
        v * v
    };
    // The path is found on the fit part only (held-out samples cost
    // nothing); each event is then placed within the stretch the path left
    // open by the whole recording.
    let cost = |i: usize, j: usize| -> f64 {
        if m.is_fit(i) {
            full(i, j)
        } else {
            0.0
        }
    };
    // Noise from the median error of the current alignment (the model's
    // residual, coloured noise included); not below -40 dB of the
    // recovery's power (a residual that small is model error, not noise).
    let mut cur: Vec<f64> = (0..n)
        .filter(|&i| m.is_fit(i))
        .map(|i| full(i, D))
        .collect();
    let power = z.iter().map(|v| v * v).sum::<f64>() / n as f64;
    let sigma2 = (median(&mut cur) / 0.455).max(1e-4 * power).max(1e-300);
    let lambda = 3.0 * (n as f64).ln() * sigma2;
    // Viterbi over offsets, steps of ±1.
    let mut acc: Vec<f64> = (0..nd)
        .map(|j| lambda * (j as f64 - D as f64).abs() + cost(0, j))
        .collect();
    let mut back = vec![0u8; n * nd];
    let mut next = vec![0.0; nd];
    for i in 1..n {
        for j in 0..nd {
            let mut bj = j;
            let mut bv = acc[j];
            for k in [j.wrapping_sub(1), j + 1] {
                if k < nd && acc[k] + lambda < bv {
                    bv = acc[k] + lambda;
                    bj = k;
                }
            }
            back[i * nd + j] = bj as u8;
            next[j] = bv + cost(i, j);
        }
        std::mem::swap(&mut acc, &mut next);
    }
    let mut j = (0..nd).min_by(|&a, &b| acc[a].total_cmp(&acc[b]))?;
    let mut path = vec![0usize; n];
    for i in (0..n).rev() {
        path[i] = j;
        if i > 0 {
            j = back[i * nd + j] as usize;
        }
    }
    let mut events: Vec<FrameEvent> = (1..n)
        .filter(|&i| path[i] != path[i - 1])
        .map(|i| FrameEvent {
            index: i,
            delta: path[i] as i32 - path[i - 1] as i32,
        })
        .collect();
    // A drop and a repeat within a few frames of each other are a local
    // wiggle of the lag (a phase error the model lacks), not two camera
    // faults: remove such opposite pairs.
    let mut k = 0;
    while k + 1 < events.len() {
        let (a, b) = (events[k], events[k + 1]);
        if a.delta == -b.delta && b.index - a.index < MIN_EVENT_GAP {
            for i in a.index..b.index {
                path[i] = path[a.index - 1];
            }
            events.drain(k..k + 2);
            k = k.saturating_sub(1);
        } else {
            k += 1;
        }
    }
    if events.is_empty() {
        return None;
    }
    // Place each event within the held-out stretch around it by the whole
    // recording; uncertainty: positions whose cost is within σ² of the best,
    // between the neighbouring events.
    let mut pos_sd = Vec::new();
    for k in 0..events.len() {
        let e = events[k];
        let (jb, ja) = (path[e.index - 1], path[e.index]);
        let open_lo = (1..e.index)
            .rev()
            .find(|&i| m.is_fit(i))
            .map_or(1, |i| i + 1);
        let open_hi = (e.index..n).find(|&i| m.is_fit(i)).unwrap_or(n - 1);
        let lo = if k > 0 { events[k - 1].index + 1 } else { 1 };
        let hi = events.get(k + 1).map_or(n - 1, |x| x.index - 1);
        // cost(p) = Σ_{i<p} c(i, jb) + Σ_{i>=p} c(i, ja), relative.
        let mut c = 0.0;
        let mut costs = vec![0.0; hi + 1 - lo];
        for (p, slot) in (lo..=hi).zip(costs.iter_mut()) {
            if p > lo {
                c += full(p - 1, jb) - full(p - 1, ja);
            }
            *slot = c;
        }
        let cmin = costs.iter().cloned().fold(f64::INFINITY, f64::min);
        let within: Vec<usize> = costs
            .iter()
            .enumerate()
            .filter(|(_, &v)| v <= cmin + sigma2)
            .map(|(i, _)| i)
            .collect();
        let spread = match (within.first(), within.last()) {
            (Some(a), Some(b)) => (b - a) as f64 / 2.0,
            _ => 0.0,
        };
        pos_sd.push(spread.max(0.5));
        let (a, b) = (open_lo.max(lo), open_hi.min(hi));
        if a <= b {
            if let Some(p) = (a..=b).min_by(|&x, &y| costs[x - lo].total_cmp(&costs[y - lo])) {
                events[k].index = p;
            }
        }
    }
    Some(Candidate {
        correction: Correction::Frames { events },
        uncertainty: Uncertainty::Frames { frame: pos_sd },
    })
}
