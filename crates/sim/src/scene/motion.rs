//! The object's motion, the ground truth a frame shows: its displacement at a time and in
//! each row, with the rows' lags and gains and the average over an exposure.

use super::Model;

/// Midpoint-rule sub-samples of the exposure box average (rolling shutter).
pub const EXPOSURE_SUBSAMPLES: usize = 16;

impl Model {
    pub(super) fn displacement(&self, t_s: f64) -> f64 {
        self.spec.amplitude_px * self.signal.value(t_s)
    }

    /// See [`Scene::row_gain`](super::Scene::row_gain).
    pub(super) fn row_gain(&self, y: usize) -> f64 {
        let lags = &self.spec.row_lag_s;
        match lags.partition_point(|&(r, _)| r as usize <= y) {
            0 => 1.0,
            k => self.spec.row_gain.get(k - 1).copied().unwrap_or(1.0),
        }
    }

    /// See [`Scene::row_lag_s`](super::Scene::row_lag_s).
    pub(super) fn row_lag(&self, y: usize) -> f64 {
        let lags = &self.spec.row_lag_s;
        match lags.partition_point(|&(r, _)| r as usize <= y) {
            0 => 0.0,
            k => lags[k - 1].1,
        }
    }

    /// See [`Scene::row_displacement_px`](super::Scene::row_displacement_px). Times before 0 (a lagged row
    /// early in the recording) read the signal there: periodic signals
    /// continue, sampled ones (WAV, noise, resonances) are 0, the object
    /// still at rest.
    pub(super) fn row_displacement(
        &self,
        t_s: f64,
        y: usize,
        line_delay_s: f64,
        exposure_s: f64,
    ) -> f64 {
        let ld = if line_delay_s.is_finite() {
            line_delay_s
        } else {
            0.0
        };
        // Minus a lag of 0 leaves every time bit for bit.
        let t0 = t_s + y as f64 * ld - self.row_lag(y);
        if exposure_s.is_finite() && exposure_s > 0.0 {
            let n = EXPOSURE_SUBSAMPLES as f64;
            let mut acc = 0.0;
            for i in 0..EXPOSURE_SUBSAMPLES {
                acc += self.displacement(t0 + (i as f64 + 0.5) / n * exposure_s);
            }
            acc / n * self.row_gain(y)
        } else {
            // Times a gain of 1 leaves every value bit for bit.
            self.displacement(t0) * self.row_gain(y)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{spec16, tone};
    use super::super::Scene;

    #[test]
    fn exposure_averages_the_displacement() {
        let spec = spec16(32, 32, [8, 8, 16, 16], 1.0, 0.0);
        let f = 100.0;
        let s = Scene::new(spec, tone(f)).unwrap();
        // A whole period of exposure averages a tone out.
        assert!(s.row_displacement_px(0.0012, 5, 1e-5, 1.0 / f).abs() < 1e-12);
        // Partial exposure: the analytic box average.
        for (t, e) in [(0.0, 1e-3), (0.0031, 2.5e-3), (0.007, 4e-3)] {
            let w = std::f64::consts::TAU * f;
            let want = ((w * t).cos() - (w * (t + e)).cos()) / (w * e);
            let got = s.row_displacement_px(t, 0, 1e-4, e);
            assert!((got - want).abs() < 2e-3, "t {t} e {e}: {got} vs {want}");
        }
        // Zero or invalid exposure: the instant value.
        assert_eq!(
            s.row_displacement_px(0.001, 3, 1e-4, 0.0),
            s.displacement_px(0.0013)
        );
        assert_eq!(
            s.row_displacement_px(0.001, 3, 1e-4, -1.0),
            s.displacement_px(0.0013)
        );
    }
}
