//! Capture-to-sink latency: how old each sample is when it reaches a sink,
//! on the run clock ([`super::Control::now_ns`]). Live sources stamp their
//! frames on that clock, so `now - capture time` is the delay a listener
//! hears, batching and queueing included.

use super::item::Item;

/// 10 µs buckets up to 100 ms, then 1 ms buckets up to 10 s, then one
/// overflow bucket: fine where live audio lives, bounded memory (80 KiB).
const FINE_NS: i64 = 10_000;
const FINE_BUCKETS: usize = 10_000;
const COARSE_NS: i64 = 1_000_000;
const COARSE_BUCKETS: usize = 9_900;
const BUCKETS: usize = FINE_BUCKETS + COARSE_BUCKETS + 1;

/// A fixed-size latency histogram (allocated once, no allocation per item).
pub struct LatencyHist {
    counts: Vec<u64>,
    total: u64,
    max_ns: i64,
}

/// Quantiles of one sink's latency.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LatencySummary {
    /// Samples (or frames) measured.
    pub count: u64,
    pub p50_ms: f64,
    pub p99_ms: f64,
    pub max_ms: f64,
}

impl Default for LatencyHist {
    fn default() -> Self {
        Self::new()
    }
}

impl LatencyHist {
    pub fn new() -> Self {
        Self {
            counts: vec![0; BUCKETS],
            total: 0,
            max_ns: 0,
        }
    }

    fn bucket(ns: i64) -> usize {
        let ns = ns.max(0);
        if ns < FINE_NS * FINE_BUCKETS as i64 {
            (ns / FINE_NS) as usize
        } else {
            let c = ((ns - FINE_NS * FINE_BUCKETS as i64) / COARSE_NS) as usize;
            FINE_BUCKETS + c.min(COARSE_BUCKETS)
        }
    }

    /// Upper edge of a bucket, in ns (the conservative reading).
    fn upper_ns(b: usize) -> i64 {
        if b < FINE_BUCKETS {
            (b as i64 + 1) * FINE_NS
        } else {
            FINE_NS * FINE_BUCKETS as i64 + (b - FINE_BUCKETS) as i64 * COARSE_NS + COARSE_NS
        }
    }

    pub fn record(&mut self, latency_ns: i64) {
        self.counts[Self::bucket(latency_ns)] += 1;
        self.total += 1;
        self.max_ns = self.max_ns.max(latency_ns);
    }

    /// Records every sample (or row) an item carries, each at its own
    /// capture time, against arrival at `now_ns`.
    pub fn record_item(&mut self, item: &Item, now_ns: i64) {
        match item {
            Item::Frame(f) => self.record(now_ns - f.meta().t_ns),
            Item::Audio(a) => {
                let period = 1e9 / a.rate_hz;
                for i in 0..a.samples.len() {
                    self.record(now_ns - a.t0_ns - (i as f64 * period) as i64);
                }
            }
            Item::Samples(s) => {
                let n = s.data.len() / s.channels.max(1);
                match &s.times_ns {
                    Some(t) => t.iter().take(n).for_each(|&t| self.record(now_ns - t)),
                    None => {
                        let period = 1e9 / s.rate_hz;
                        for i in 0..n {
                            self.record(now_ns - s.t0_ns - (i as f64 * period) as i64);
                        }
                    }
                }
            }
            Item::Spectrum(s) => self.record(now_ns - s.t_ns),
            Item::Pyramid(p) => self.record(now_ns - p.t_ns),
            Item::Peaks(p) => self.record(now_ns - p.t_ns),
        }
    }

    pub fn summary(&self) -> Option<LatencySummary> {
        if self.total == 0 {
            return None;
        }
        let q = |p: f64| {
            let rank = ((p * self.total as f64).ceil() as u64).max(1);
            let mut acc = 0u64;
            for (b, &c) in self.counts.iter().enumerate() {
                acc += c;
                if acc >= rank {
                    return Self::upper_ns(b).min(self.max_ns.max(0)) as f64 * 1e-6;
                }
            }
            self.max_ns as f64 * 1e-6
        };
        Some(LatencySummary {
            count: self.total,
            p50_ms: q(0.50),
            p99_ms: q(0.99),
            max_ms: self.max_ns as f64 * 1e-6,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_of_a_known_spread() {
        let mut h = LatencyHist::new();
        // 1..=1000 ms in 1 ms steps: p50 = 500 ms, p99 = 990 ms.
        for ms in 1..=1000i64 {
            h.record(ms * 1_000_000);
        }
        let s = h.summary().unwrap();
        assert_eq!(s.count, 1000);
        assert!((s.p50_ms - 500.0).abs() <= 1.0, "{s:?}");
        assert!((s.p99_ms - 990.0).abs() <= 1.0, "{s:?}");
        assert!((s.max_ms - 1000.0).abs() < 1e-9);
        // Fine buckets: 10 µs resolution below 100 ms.
        let mut h = LatencyHist::new();
        for us in 0..100 {
            h.record(3_000_000 + us * 1_000);
        }
        let s = h.summary().unwrap();
        assert!((s.p50_ms - 3.05).abs() <= 0.011, "{s:?}");
    }

    #[test]
    fn audio_samples_each_count_at_their_own_time() {
        let mut h = LatencyHist::new();
        let a = Item::Audio(crate::AudioBlock {
            t0_ns: 0,
            rate_hz: 1000.0,
            samples: vec![0.0f32; 100].into(),
        });
        // Arrives 100 ms after the first sample: ages 100 ms .. 1 ms.
        h.record_item(&a, 100_000_000);
        let s = h.summary().unwrap();
        assert_eq!(s.count, 100);
        assert!((s.max_ms - 100.0).abs() < 1e-9);
        assert!((s.p50_ms - 50.0).abs() <= 0.011, "{s:?}");
    }
}
