//! The recovery's physical frame (issue 50, item 2): a recovery's scale
//! and sign are chosen per recording (the bands' polarity by `align`, the
//! phase method's texture-dependent scale), so a correction that depends
//! on amplitude (a static nonlinearity) is stored against the object's
//! motion in pixels along a direction fixed in the image, and brought to a
//! new recording's recovery by that recording's own scale.
//!
//! The motion in pixels comes from `displacement`'s x and y, measured in
//! the same run, high-passed like the recovery and projected on a
//! direction (a stored frame's, or the region's principal axis, pointing
//! to +x or below it: an angle in (-90°, 90°]). It is the object's motion
//! only where the pixels measured are the object's: a region holding
//! still background as well (the usual box drawn around an object) moves
//! by the object's share of its texture, which changes with the texture
//! and the framing (measured in issue 50's protocol: 0.38 and 0.50 of the
//! object's motion on two recordings of one object, so the scale carried
//! from one to the other was 1.17 where the object asked for 1.56). So
//! the motion is read on the tiles of the region that move with the
//! recovery ([`pixel_frame_on_tiles`]): those whose motion the recovery
//! explains (R² at least [`FOLLOWS_R2`]) and that move most (at least
//! [`TOP_SHARE`] of the largest such motion per unit of recovery). On a
//! rigid object these are the tiles wholly on it; tiles astride its
//! outline move less and still background not at all. Without tiles (or
//! none that follow), the region's own motion is used.
//!
//! The recovery's scale against that motion is `sign(⟨y, p⟩) sqrt(⟨y, y⟩ /
//! ⟨p, p⟩)` with `p` the chosen tiles' mean motion: both estimate the
//! same motion, so their noises bias the ratio about equally either way,
//! where a regression of one on the other would shrink it by the other's
//! noise.

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
    /// How many of the region's tiles the motion was read on (0: the
    /// region's own motion; reports written before it: 0).
    #[serde(default)]
    pub tiles: usize,
}

/// The least share of a tile's motion (along the direction) the recovery
/// must explain for the tile to count as moving with it.
pub const FOLLOWS_R2: f64 = 0.5;

/// Of the tiles that follow the recovery, those moving at least this share
/// of the largest motion per unit of recovery are read as the object's.
pub const TOP_SHARE: f64 = 0.8;

/// The frame of recovery `y` given the region's motion `px`, `py` (pixels,
/// one value per frame, as long as `y`), with the recovery's high-pass
/// `hp`: along `direction_deg` when given (a stored frame's), else along
/// the motion's principal axis. `None` when the region did not move
/// measurably or the lengths differ.
pub fn pixel_frame(
    y: &[f64],
    region: (&[f64], &[f64]),
    fs: f64,
    hp: Option<(usize, f64)>,
    direction_deg: Option<f64>,
) -> Option<PixelFrame> {
    pixel_frame_on_tiles(y, region, &[], fs, hp, direction_deg)
}

/// [`pixel_frame`] read on the region's `tiles` (each a tile's motion x
/// and y in pixels, as long as `y`) that move with the recovery (see the
/// module docs); the region's own motion `region` gives the direction
/// when none is given, and the scale when no tile follows the recovery.
pub fn pixel_frame_on_tiles(
    y: &[f64],
    (px, py): (&[f64], &[f64]),
    tiles: &[(&[f64], &[f64])],
    fs: f64,
    hp: Option<(usize, f64)>,
    direction_deg: Option<f64>,
) -> Option<PixelFrame> {
    let n = y.len();
    if px.len() != n || py.len() != n || n == 0 {
        return None;
    }
    let (x, yy) = (centred_highpass(px, fs, hp), centred_highpass(py, fs, hp));
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
    let along = |x: &[f64], y: &[f64]| -> Vec<f64> {
        x.iter().zip(y).map(|(a, b)| c * a + s * b).collect()
    };
    let y2 = dot(y, y);
    // Each tile's motion along the direction, and its motion per unit of
    // recovery where the recovery explains it.
    let moving: Vec<(Vec<f64>, f64)> = tiles
        .iter()
        .filter(|(tx, ty)| tx.len() == n && ty.len() == n)
        .filter_map(|(tx, ty)| {
            let p = along(&centred_highpass(tx, fs, hp), &centred_highpass(ty, fs, hp));
            let (yp, pp) = (dot(y, &p), dot(&p, &p));
            let r2 = yp * yp / (y2 * pp);
            (r2.is_finite() && r2 >= FOLLOWS_R2).then_some((p, (yp / y2).abs()))
        })
        .collect();
    let most = moving.iter().map(|m| m.1).fold(0.0f64, f64::max);
    let top: Vec<&Vec<f64>> = moving
        .iter()
        .filter(|m| m.1 >= TOP_SHARE * most)
        .map(|m| &m.0)
        .collect();
    let p: Vec<f64> = if top.is_empty() {
        along(&x, &yy)
    } else {
        (0..n)
            .map(|i| top.iter().map(|t| t[i]).sum::<f64>() / top.len() as f64)
            .collect()
    };
    let (pp, yp) = (dot(&p, &p), dot(y, &p));
    if !(pp > 0.0 && y2 > 0.0 && yp != 0.0 && yp.is_finite()) {
        return None;
    }
    Some(PixelFrame {
        direction_deg: theta.to_degrees(),
        recovery_per_px: yp.signum() * (y2 / pp).sqrt(),
        tiles: top.len(),
    })
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(u, v)| u * v).sum::<f64>()
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
                from_response,
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
                from_response: *from_response,
            },
            Correction::SoftClip {
                a3,
                a5,
                level,
                range,
                highpass,
            } if ratio.is_finite() && ratio != 0.0 => Correction::SoftClip {
                a3: a3 / (ratio * ratio),
                a5: a5 / ratio.powi(4),
                level: *level,
                range: range * ratio.abs(),
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

    /// A region holding still background around the object: its motion is
    /// the object's times the object's share of the texture, so its frame
    /// reads a recovery per pixel too large by that share. Read on the
    /// tiles that move with the recovery, the frame is the object's: the
    /// tiles wholly on it set the scale, those astride its outline (which
    /// move less) and the still ones (which the recovery does not
    /// explain) are left out. With no tile following, the region's.
    #[test]
    fn the_frame_is_read_on_the_tiles_that_move_with_the_recovery() {
        let n = 4000;
        let mut rng = crate::rng::Xoshiro256::new(3);
        let s: Vec<f64> = (0..n)
            .map(|i| (i as f64 * 0.21).sin() + 0.6 * (i as f64 * 0.53).sin())
            .collect();
        let noisy = |scale: f64, rng: &mut crate::rng::Xoshiro256| -> Vec<f64> {
            s.iter()
                .map(|v| scale * v + 0.02 * (rng.next_f64() - 0.5))
                .collect()
        };
        let zero = vec![0.0; n];
        // The object moves 0.2 px a unit of s along x; the recovery reads
        // -0.5 a px of it.
        let y: Vec<f64> = s.iter().map(|v| -0.5 * 0.2 * v).collect();
        let region = noisy(0.2 * 0.4, &mut rng);
        let on_object = [noisy(0.2, &mut rng), noisy(0.2, &mut rng)];
        let astride = noisy(0.2 * 0.5, &mut rng);
        let still: Vec<f64> = (0..n).map(|_| 0.02 * (rng.next_f64() - 0.5)).collect();
        let whole = pixel_frame(&y, (&region, &zero), 2200.0, None, None).unwrap();
        assert!(
            (whole.recovery_per_px + 0.5 / 0.4).abs() < 0.01,
            "{whole:?}"
        );
        assert_eq!(whole.tiles, 0);
        let tiles: Vec<(&[f64], &[f64])> = vec![
            (&on_object[0], &zero),
            (&astride, &zero),
            (&still, &zero),
            (&on_object[1], &zero),
        ];
        let f = pixel_frame_on_tiles(&y, (&region, &zero), &tiles, 2200.0, None, None).unwrap();
        assert!((f.recovery_per_px + 0.5).abs() < 0.005, "{f:?}");
        assert_eq!(f.tiles, 2, "{f:?}");
        assert!(f.direction_deg.abs() < 1e-6, "{f:?}");
        // Only still tiles: the region's motion.
        let only_still: Vec<(&[f64], &[f64])> = vec![(&still, &zero)];
        let g =
            pixel_frame_on_tiles(&y, (&region, &zero), &only_still, 2200.0, None, None).unwrap();
        assert_eq!(g.tiles, 0);
        assert!(
            (g.recovery_per_px - whole.recovery_per_px).abs() < 1e-12,
            "{g:?}"
        );
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
            from_response: true,
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
