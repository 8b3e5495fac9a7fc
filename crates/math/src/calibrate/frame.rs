//! The recovery's physical frame (issue 50, item 2): a recovery's scale
//! and sign are chosen per recording (the bands' polarity by `align`, the
//! phase method's texture-dependent scale), so a correction that depends
//! on amplitude (a static nonlinearity) is stored against the object's
//! motion in pixels along a direction fixed in the image, and brought to a
//! new recording's recovery by that recording's own scale.
//!
//! The region's motion in pixels (`displacement`'s x and y, measured in the
//! same run) is high-passed like the recovery and projected on the
//! direction it moves along most (the principal axis, pointing to +x or
//! below it: an angle in (-90°, 90°]); the recovery's scale against it is
//! `sign(⟨y, p⟩) sqrt(⟨y, y⟩ / ⟨p, p⟩)`: both estimate the same motion
//! from the same pixels, so their noises bias the ratio about equally
//! either way, where a regression of one on the other would shrink it by
//! the other's noise.

use super::signal::centred_highpass;
use super::Correction;

/// The recovery against the region's motion in pixels.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PixelFrame {
    /// The direction in the image the motion is measured along (0 = +x,
    /// 90 = +y), degrees in (-90, 90].
    pub direction_deg: f64,
    /// Recovery units per pixel of motion along it (negative: the
    /// recovery's sign is opposite to the motion's).
    pub recovery_per_px: f64,
}

/// The frame of recovery `y` given the region's motion `px`, `py` (pixels,
/// one value per frame, as long as `y`), with the recovery's high-pass
/// `hp`: along `direction_deg` when given (a stored frame's), else along
/// the motion's principal axis. `None` when the region did not move
/// measurably or the lengths differ.
pub fn pixel_frame(
    y: &[f64],
    (px, py): (&[f64], &[f64]),
    fs: f64,
    hp: Option<(usize, f64)>,
    direction_deg: Option<f64>,
) -> Option<PixelFrame> {
    let n = y.len();
    if px.len() != n || py.len() != n || n == 0 {
        return None;
    }
    let (x, yy) = (centred_highpass(px, fs, hp), centred_highpass(py, fs, hp));
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(u, v)| u * v).sum::<f64>();
    let theta = match direction_deg {
        Some(d) => d.to_radians(),
        None => {
            let (sxx, sxy, syy) = (dot(&x, &x), dot(&x, &yy), dot(&yy, &yy));
            // The principal axis of [[sxx, sxy], [sxy, syy]].
            let t = 0.5 * (2.0 * sxy).atan2(sxx - syy);
            // Into (-90°, 90°].
            if t <= -std::f64::consts::FRAC_PI_2 {
                t + std::f64::consts::PI
            } else if t > std::f64::consts::FRAC_PI_2 {
                t - std::f64::consts::PI
            } else {
                t
            }
        }
    };
    let (c, s) = (theta.cos(), theta.sin());
    let p: Vec<f64> = x.iter().zip(&yy).map(|(a, b)| c * a + s * b).collect();
    let (pp, yp, yy2) = (dot(&p, &p), dot(y, &p), dot(y, y));
    if !(pp > 0.0 && yy2 > 0.0 && yp != 0.0 && yp.is_finite()) {
        return None;
    }
    Some(PixelFrame {
        direction_deg: theta.to_degrees(),
        recovery_per_px: yp.signum() * (yy2 / pp).sqrt(),
    })
}

impl Correction {
    /// This correction for a recovery `ratio` times the one it was fitted
    /// on (the new recording's recovery per pixel over the fitted one's):
    /// a static nonlinearity's terms and range follow the scale and sign;
    /// the others do not depend on amplitude and are returned as they are.
    pub fn rescaled(&self, ratio: f64) -> Correction {
        match self {
            Correction::Polynomial {
                coefs,
                range,
                highpass,
            } if ratio.is_finite() && ratio != 0.0 => Correction::Polynomial {
                // u' = ratio u: u + a u² + ... in u is, in u',
                // u' + (a / ratio) u'² + (a / ratio²) u'³ + ...
                coefs: coefs
                    .iter()
                    .enumerate()
                    .map(|(i, a)| a / ratio.powi(i as i32 + 1))
                    .collect(),
                range: range * ratio.abs(),
                highpass: *highpass,
            },
            Correction::SoftClip {
                a3,
                a5,
                level,
                highpass,
            } if ratio.is_finite() && ratio != 0.0 => Correction::SoftClip {
                a3: a3 / (ratio * ratio),
                a5: a5 / ratio.powi(4),
                level: *level,
                highpass: *highpass,
            },
            other => other.clone(),
        }
    }

    /// Whether applying this correction depends on the recovery's scale
    /// and sign (and so needs the new recording's [`PixelFrame`]).
    pub fn needs_frame(&self) -> bool {
        matches!(
            self,
            Correction::Polynomial { .. } | Correction::SoftClip { .. }
        )
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// A recovery -3 times the motion along 30°: the frame reads the
    /// direction and the scale with its sign; along a given direction, the
    /// projection.
    #[test]
    fn the_frame_reads_direction_scale_and_sign() {
        let n = 2000;
        let s: Vec<f64> = (0..n)
            .map(|i| (i as f64 * 0.31).sin() + 0.5 * (i as f64 * 0.77).sin())
            .collect();
        let (c, si) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let px: Vec<f64> = s.iter().map(|v| v * c).collect();
        let py: Vec<f64> = s.iter().map(|v| v * si).collect();
        let y: Vec<f64> = s.iter().map(|v| -3.0 * v).collect();
        let f = pixel_frame(&y, (&px, &py), 2200.0, None, None).unwrap();
        assert!((f.direction_deg - 30.0).abs() < 1e-6, "{f:?}");
        assert!((f.recovery_per_px + 3.0).abs() < 1e-4, "{f:?}");
        let g = pixel_frame(&y, (&px, &py), 2200.0, None, Some(0.0)).unwrap();
        assert!((g.recovery_per_px + 3.0 / c).abs() < 1e-4, "{g:?}");
    }

    /// A polynomial fitted on one recovery undoes the same response on a
    /// recovery of the opposite sign and another scale once rescaled.
    #[test]
    fn a_rescaled_polynomial_undoes_the_response_at_another_scale_and_sign() {
        // Motion m, response r = m + 0.25 m²; recovery 1: y1 = 2 r; its
        // inverse on y1 (to first order): y1 - (0.25 / 2) y1².
        let inv = Correction::Polynomial {
            coefs: vec![-0.125],
            range: 10.0,
            highpass: None,
        };
        let ratio = -0.7;
        let Correction::Polynomial { coefs, range, .. } = inv.rescaled(ratio) else {
            panic!()
        };
        // Recovery 2: y2 = -1.4 r; its inverse: y2 - (0.25 / -1.4) y2².
        assert!((coefs[0] - 0.25 / 1.4).abs() < 1e-12, "{coefs:?}");
        assert!((range - 7.0).abs() < 1e-12);
    }
}
