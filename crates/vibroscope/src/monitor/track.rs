//! Resonance tracks of one source and the alarm test (the thesis's 5.6
//! comparison of two recordings, made continuous).
//!
//! - **Tracks.** The first `baseline` peak sets of a source are pooled;
//!   frequencies within `cluster_rel` of each other form one cluster, and
//!   every cluster seen in at least half of those sets becomes a track.
//! - **Observations.** Each later set gives each track the peak nearest to
//!   the track's median within `gate_rel` of it (or nothing).
//! - **The test.** A track's own history is its last `window` normal
//!   observations: median m and spread σ, the larger of 1.4826 MAD and the
//!   99th percentile of |f − m| over 2.576 (both σ for a normal law; the
//!   second follows the heavier tails of peak picking on a noisy spectrum),
//!   never below the median of the peaks' own frequency uncertainties, nor
//!   10 ppm of m.
//!   An observation is anomalous when |f − m| > k σ. `persist` anomalous
//!   observations in a row raise an alarm; `persist` normal ones clear it.
//!   `3 persist` sets in a row with no peak in the gate raise a "lost" alarm
//!   (the resonance moved beyond the gate, or vanished). Anomalous
//!   observations do not enter the history, so a shift stays alarmed
//!   instead of becoming the new normal.

use crate::engine::{PeakSet, Resonance};
use serde::Serialize;
use std::collections::VecDeque;

/// The tracker's settings (`vibroscope monitor`'s options).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TrackConfig {
    /// Alarm threshold, standard deviations of the track's own history.
    pub k: f64,
    /// Observations in a row that raise (or clear) an alarm.
    pub persist: usize,
    /// Peak sets pooled to find a source's tracks.
    pub baseline: usize,
    /// Normal observations kept as a track's history.
    pub window: usize,
    /// Peaks within this fraction of each other are one resonance.
    pub cluster_rel: f64,
    /// A track takes the nearest peak within this fraction of its median.
    pub gate_rel: f64,
}

impl Default for TrackConfig {
    fn default() -> Self {
        TrackConfig {
            k: 6.0,
            persist: 3,
            baseline: 20,
            window: 600,
            cluster_rel: 0.02,
            gate_rel: 0.1,
        }
    }
}

/// One observation of a track (a row of the history).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Obs {
    pub t_ns: i64,
    pub peak: Resonance,
    /// Distance from the history's median in its σ (0 in the baseline).
    pub z: f64,
    pub anomalous: bool,
}

/// What a track's statistics are now.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Stats {
    pub frequency_hz: f64,
    pub sigma_hz: f64,
    pub damping_ratio: f64,
    pub damping_sigma: f64,
    pub power_db: f64,
    pub power_sigma_db: f64,
    pub n: usize,
}

/// A change a caller reports (and stores).
#[derive(Clone, Debug, PartialEq)]
pub enum Event {
    /// A track was found in the baseline.
    Track { track: u32, stats: Stats },
    /// `persist` anomalous observations in a row.
    Alarm {
        track: u32,
        t_ns: i64,
        /// The first anomalous observation's time.
        since_ns: i64,
        frequency_hz: f64,
        z: f64,
        stats: Stats,
    },
    /// `3 persist` sets in a row without a peak in the track's gate (a
    /// weak peak is missed now and then; a resonance gone is missed always).
    Lost {
        track: u32,
        t_ns: i64,
        since_ns: i64,
        stats: Stats,
    },
    /// `persist` normal observations after an alarm.
    Cleared {
        track: u32,
        t_ns: i64,
        frequency_hz: f64,
        stats: Stats,
    },
}

/// One resonance followed over time.
#[derive(Clone, Debug)]
pub struct Track {
    pub id: u32,
    /// Normal observations, oldest first (at most `window`).
    pub history: VecDeque<Obs>,
    pub alarmed: bool,
    /// Consecutive anomalous (or, when alarmed, normal) observations.
    run: usize,
    run_since: i64,
    /// Consecutive sets with no peak in the gate.
    missing: usize,
    missing_since: i64,
}

impl Track {
    pub fn new(id: u32, history: VecDeque<Obs>, alarmed: bool) -> Track {
        Track {
            id,
            history,
            alarmed,
            run: 0,
            run_since: 0,
            missing: 0,
            missing_since: 0,
        }
    }

    /// Median and robust spread of the history.
    pub fn stats(&self) -> Stats {
        let col = |f: &dyn Fn(&Obs) -> f64| -> Vec<f64> { self.history.iter().map(f).collect() };
        let freqs = col(&|o| o.peak.frequency_hz);
        let (f, sf) = median_sigma(freqs.clone());
        // Peak frequencies of a noise-driven resonance have heavier tails
        // than a normal law: the spread is also read off the 99th
        // percentile of the deviations (2.576 σ for a normal law), and the
        // larger of the two is used.
        let mut dev: Vec<f64> = freqs
            .iter()
            .filter(|x| x.is_finite())
            .map(|x| (x - f).abs())
            .collect();
        dev.sort_by(|a, b| a.total_cmp(b));
        let tail = dev
            .get(((dev.len() as f64 * 0.99) as usize).min(dev.len().saturating_sub(1)))
            .map_or(0.0, |d| d / 2.576);
        let (d, sd) = median_sigma(col(&|o| o.peak.damping_ratio));
        let (p, sp) = median_sigma(col(&|o| o.peak.power_db));
        let (own, _) = median_sigma(col(&|o| o.peak.frequency_std_hz));
        Stats {
            frequency_hz: f,
            sigma_hz: sf.max(tail).max(own).max(1e-5 * f.abs()),
            damping_ratio: d,
            damping_sigma: sd,
            power_db: p,
            power_sigma_db: sp,
            n: self.history.len(),
        }
    }
}

/// Median and 1.4826 × median absolute deviation (0, 0 when empty;
/// non-finite values ignored).
pub fn median_sigma(mut v: Vec<f64>) -> (f64, f64) {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return (0.0, 0.0);
    }
    let m = median(&mut v);
    let mut dev: Vec<f64> = v.iter().map(|x| (x - m).abs()).collect();
    (m, 1.4826 * median(&mut dev))
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The tracks of one source.
#[derive(Clone, Debug)]
pub struct SourceTracker {
    pub cfg: TrackConfig,
    /// Peak sets pooled while no track exists yet.
    pub pending: Vec<PeakSet>,
    pub tracks: Vec<Track>,
    /// The tracks were found (even if none was: then nothing is tracked).
    pub established: bool,
}

impl SourceTracker {
    pub fn new(cfg: TrackConfig) -> SourceTracker {
        SourceTracker {
            cfg,
            pending: Vec::new(),
            tracks: Vec::new(),
            established: false,
        }
    }

    /// Takes one peak set; returns the observations made (track, obs) and
    /// the events raised.
    pub fn observe(&mut self, set: &PeakSet) -> (Vec<(u32, Obs)>, Vec<Event>) {
        if !self.established {
            self.pending.push(set.clone());
            if self.pending.len() < self.cfg.baseline.max(1) {
                return (Vec::new(), Vec::new());
            }
            return self.establish();
        }
        let mut obs = Vec::new();
        let mut events = Vec::new();
        let (k, persist, window, gate) = (
            self.cfg.k,
            self.cfg.persist.max(1),
            self.cfg.window.max(1),
            self.cfg.gate_rel,
        );
        for tr in &mut self.tracks {
            let st = tr.stats();
            let nearest = set
                .peaks
                .iter()
                .filter(|p| (p.frequency_hz - st.frequency_hz).abs() <= gate * st.frequency_hz)
                .min_by(|a, b| {
                    (a.frequency_hz - st.frequency_hz)
                        .abs()
                        .total_cmp(&(b.frequency_hz - st.frequency_hz).abs())
                });
            let Some(p) = nearest else {
                if tr.missing == 0 {
                    tr.missing_since = set.t_ns;
                }
                tr.missing += 1;
                if tr.missing == 3 * persist && !tr.alarmed {
                    tr.alarmed = true;
                    tr.run = 0;
                    events.push(Event::Lost {
                        track: tr.id,
                        t_ns: set.t_ns,
                        since_ns: tr.missing_since,
                        stats: st,
                    });
                }
                continue;
            };
            tr.missing = 0;
            let z = (p.frequency_hz - st.frequency_hz).abs() / st.sigma_hz;
            let anomalous = z > k;
            let o = Obs {
                t_ns: set.t_ns,
                peak: *p,
                z,
                anomalous,
            };
            obs.push((tr.id, o));
            // `run` counts what would change the state.
            let against = if tr.alarmed { !anomalous } else { anomalous };
            if against {
                if tr.run == 0 {
                    tr.run_since = set.t_ns;
                }
                tr.run += 1;
            } else {
                tr.run = 0;
            }
            if tr.run >= persist {
                tr.run = 0;
                if tr.alarmed {
                    tr.alarmed = false;
                    events.push(Event::Cleared {
                        track: tr.id,
                        t_ns: set.t_ns,
                        frequency_hz: p.frequency_hz,
                        stats: st,
                    });
                } else {
                    tr.alarmed = true;
                    events.push(Event::Alarm {
                        track: tr.id,
                        t_ns: set.t_ns,
                        since_ns: tr.run_since,
                        frequency_hz: p.frequency_hz,
                        z,
                        stats: st,
                    });
                }
            }
            if !anomalous {
                tr.history.push_back(o);
                while tr.history.len() > window {
                    tr.history.pop_front();
                }
            }
        }
        (obs, events)
    }

    /// Finds the tracks in the pooled sets.
    fn establish(&mut self) -> (Vec<(u32, Obs)>, Vec<Event>) {
        let sets = std::mem::take(&mut self.pending);
        let mut all: Vec<f64> = sets
            .iter()
            .flat_map(|s| s.peaks.iter().map(|p| p.frequency_hz))
            .filter(|f| f.is_finite() && *f > 0.0)
            .collect();
        all.sort_by(|a, b| a.total_cmp(b));
        // Greedy clusters in frequency order.
        let mut clusters: Vec<Vec<f64>> = Vec::new();
        for f in all {
            match clusters.last_mut() {
                Some(c) if f - c[0] <= self.cfg.cluster_rel * c[0] => c.push(f),
                _ => clusters.push(vec![f]),
            }
        }
        let need = sets.len().div_ceil(2);
        let mut obs = Vec::new();
        let mut events = Vec::new();
        for c in clusters.into_iter().filter(|c| c.len() >= need) {
            let (centre, _) = median_sigma(c.clone());
            let (lo, hi) = (c[0], c[c.len() - 1]);
            let id = self.tracks.len() as u32;
            let mut history = VecDeque::new();
            for s in &sets {
                let nearest = s
                    .peaks
                    .iter()
                    .filter(|p| p.frequency_hz >= lo && p.frequency_hz <= hi)
                    .min_by(|a, b| {
                        (a.frequency_hz - centre)
                            .abs()
                            .total_cmp(&(b.frequency_hz - centre).abs())
                    });
                if let Some(p) = nearest {
                    let o = Obs {
                        t_ns: s.t_ns,
                        peak: *p,
                        z: 0.0,
                        anomalous: false,
                    };
                    history.push_back(o);
                    obs.push((id, o));
                }
            }
            let tr = Track::new(id, history, false);
            events.push(Event::Track {
                track: id,
                stats: tr.stats(),
            });
            self.tracks.push(tr);
        }
        self.established = true;
        (obs, events)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn set(t: i64, fs: &[f64]) -> PeakSet {
        PeakSet {
            t_ns: t,
            peaks: fs
                .iter()
                .map(|&f| Resonance {
                    frequency_hz: f,
                    frequency_std_hz: 0.01,
                    power_db: -40.0,
                    prominence_db: 20.0,
                    damping_ratio: 0.01,
                    damping_ratio_std: 0.001,
                })
                .collect(),
        }
    }

    /// A deterministic jitter in [-1, 1].
    fn jitter(i: i64) -> f64 {
        ((i * 7919 % 200) as f64 - 100.0) / 100.0
    }

    #[test]
    fn a_shift_alarms_after_persist_and_clears_on_return() {
        let cfg = TrackConfig::default();
        let mut tr = SourceTracker::new(cfg.clone());
        let mut events = Vec::new();
        for i in 0..200 {
            let f = if (100..150).contains(&i) { 42.0 } else { 40.0 } + 0.05 * jitter(i);
            let (_, e) = tr.observe(&set(i, &[f, 90.0 + 0.05 * jitter(i + 3)]));
            events.extend(e.into_iter().map(|e| (i, e)));
        }
        let tracks = events
            .iter()
            .filter(|(_, e)| matches!(e, Event::Track { .. }))
            .count();
        assert_eq!(tracks, 2, "{events:?}");
        let alarms: Vec<_> = events
            .iter()
            .filter(|(_, e)| matches!(e, Event::Alarm { .. }))
            .collect();
        assert_eq!(alarms.len(), 1, "{events:?}");
        assert_eq!(alarms[0].0, 100 + cfg.persist as i64 - 1);
        match &alarms[0].1 {
            Event::Alarm {
                track, since_ns, ..
            } => {
                assert_eq!(*track, 0);
                assert_eq!(*since_ns, 100);
            }
            _ => unreachable!(),
        }
        let cleared: Vec<_> = events
            .iter()
            .filter(|(_, e)| matches!(e, Event::Cleared { .. }))
            .collect();
        assert_eq!(cleared.len(), 1, "{events:?}");
        assert_eq!(cleared[0].0, 150 + cfg.persist as i64 - 1);
    }

    #[test]
    fn a_resonance_that_leaves_the_gate_is_lost_and_noise_alone_never_alarms() {
        let mut tr = SourceTracker::new(TrackConfig::default());
        let mut events = Vec::new();
        for i in 0..2000 {
            let f = if i >= 1500 {
                60.0
            } else {
                40.0 + 0.05 * jitter(i)
            };
            let (_, e) = tr.observe(&set(i, &[f]));
            events.extend(e.into_iter().map(|e| (i, e)));
        }
        let not_track: Vec<_> = events
            .iter()
            .filter(|(_, e)| !matches!(e, Event::Track { .. }))
            .collect();
        assert_eq!(not_track.len(), 1, "{events:?}");
        assert!(
            matches!(not_track[0], (1508, Event::Lost { .. })),
            "{not_track:?}"
        );
    }
}
