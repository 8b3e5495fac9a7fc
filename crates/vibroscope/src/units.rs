//! Physical units of motion: a scale from pixels to millimetres (given, or
//! measured from a feature of known length in the frame), the quantity
//! reported (displacement, velocity, acceleration) and the unit that
//! travels with every number a recipe reports.
//!
//! The unit rule: without a scale, motion is in pixels (`px`, `px/s`,
//! `px/s²`). With one, a report picks **µm when its largest value is below
//! 1 mm** (1000 µm, or 1000 µm/s, ...) and mm otherwise, once for the whole
//! report, so every number in one output shares one unit.

use crate::error::UsageError;
use serde::Serialize;
use std::f64::consts::TAU;
use std::fmt;
use std::str::FromStr;

/// Length unit of a reported motion.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub enum Length {
    /// Pixels of the image (no scale given).
    #[default]
    #[serde(rename = "px")]
    Px,
    #[serde(rename = "µm")]
    Um,
    #[serde(rename = "mm")]
    Mm,
}

impl Length {
    /// Pixels, or millimetres, to this unit (`mm_per_px` for a scaled length).
    fn per_mm(self) -> f64 {
        match self {
            Length::Px => 1.0,
            Length::Um => 1000.0,
            Length::Mm => 1.0,
        }
    }

    pub fn symbol(self) -> &'static str {
        match self {
            Length::Px => "px",
            Length::Um => "µm",
            Length::Mm => "mm",
        }
    }
}

/// What is reported: the motion or one of its time derivatives.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Quantity {
    #[default]
    Displacement,
    /// jω·X in the frequency domain.
    Velocity,
    /// −ω²·X in the frequency domain.
    Acceleration,
}

impl Quantity {
    /// The power of ω (0, 1, 2) the quantity multiplies a displacement by.
    pub fn order(self) -> i32 {
        match self {
            Quantity::Displacement => 0,
            Quantity::Velocity => 1,
            Quantity::Acceleration => 2,
        }
    }

    /// |quantity| / |displacement| at `f_hz`: ω^order.
    pub fn gain(self, f_hz: f64) -> f64 {
        (TAU * f_hz).powi(self.order())
    }

    pub fn name(self) -> &'static str {
        match self {
            Quantity::Displacement => "displacement",
            Quantity::Velocity => "velocity",
            Quantity::Acceleration => "acceleration",
        }
    }
}

impl FromStr for Quantity {
    type Err = UsageError;
    fn from_str(s: &str) -> Result<Quantity, UsageError> {
        match s {
            "displacement" => Ok(Quantity::Displacement),
            "velocity" => Ok(Quantity::Velocity),
            "acceleration" => Ok(Quantity::Acceleration),
            _ => Err(UsageError::new(
                "--quantity",
                format!("expected displacement, velocity or acceleration, got `{s}`"),
            )),
        }
    }
}

/// The unit of a reported motion: a length unit and the quantity
/// (`µm`, `mm/s`, `px/s²`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Unit {
    pub length: Length,
    pub quantity: Quantity,
}

impl fmt::Display for Unit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let per = match self.quantity {
            Quantity::Displacement => "",
            Quantity::Velocity => "/s",
            Quantity::Acceleration => "/s²",
        };
        write!(f, "{}{per}", self.length.symbol())
    }
}

impl Serialize for Unit {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// Two points on a feature of known length: `X1,Y1,X2,Y2=LENGTH_MM`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct KnownLength {
    /// The points, in pixels (centre of pixel (0, 0) at (0, 0)).
    pub from_px: [f64; 2],
    pub to_px: [f64; 2],
    pub length_mm: f64,
}

impl KnownLength {
    /// Their distance in pixels.
    pub fn distance_px(&self) -> f64 {
        (self.to_px[0] - self.from_px[0]).hypot(self.to_px[1] - self.from_px[1])
    }

    /// Checks the points against a `width`×`height` frame.
    pub fn check_frame(&self, width: u32, height: u32) -> Result<(), UsageError> {
        for p in [self.from_px, self.to_px] {
            let inside = (-0.5..=f64::from(width) - 0.5).contains(&p[0])
                && (-0.5..=f64::from(height) - 0.5).contains(&p[1]);
            if !inside {
                return Err(UsageError::new(
                    "--known-length",
                    format!(
                        "the point {},{} is outside the {width}x{height} frame (x from 0 to {}, y from 0 to {})",
                        p[0],
                        p[1],
                        width.saturating_sub(1),
                        height.saturating_sub(1)
                    ),
                ));
            }
        }
        Ok(())
    }
}

impl FromStr for KnownLength {
    type Err = UsageError;
    /// `X1,Y1,X2,Y2=LENGTH_MM`; the length positive, the points distinct.
    fn from_str(s: &str) -> Result<KnownLength, UsageError> {
        let bad = |m: String| UsageError::new("--known-length", m);
        let form = "expected X1,Y1,X2,Y2=LENGTH_MM (two points in pixels on a feature whose length is known, in mm)";
        let (pts, len) = s
            .split_once('=')
            .ok_or_else(|| bad(format!("{form}, got `{s}`")))?;
        let v: Result<Vec<f64>, _> = pts.split(',').map(|v| v.trim().parse::<f64>()).collect();
        let v = match v.as_deref() {
            Ok([a, b, c, d]) if [a, b, c, d].iter().all(|x| x.is_finite()) => [*a, *b, *c, *d],
            _ => return Err(bad(format!("{form}, got `{s}`"))),
        };
        let length_mm: f64 = len
            .trim()
            .parse()
            .map_err(|_| bad(format!("the length `{len}` is not a number ({form})")))?;
        if !(length_mm > 0.0 && length_mm.is_finite()) {
            return Err(bad(format!(
                "the length must be a positive number of mm, got {len}"
            )));
        }
        let k = KnownLength {
            from_px: [v[0], v[1]],
            to_px: [v[2], v[3]],
            length_mm,
        };
        if k.distance_px() < 1.0 {
            return Err(bad(format!(
                "the two points {},{} and {},{} are {} px apart: give two distinct points on the feature, at least 1 px apart (farther is more accurate)",
                v[0],
                v[1],
                v[2],
                v[3],
                k.distance_px()
            )));
        }
        Ok(k)
    }
}

/// How the pixel size is given: `--scale MM_PER_PX` or `--known-length`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ScaleArg {
    MmPerPx(f64),
    KnownLength(KnownLength),
}

impl ScaleArg {
    /// `--scale MM_PER_PX`: a positive, finite number.
    pub fn mm_per_px(text: &str) -> Result<ScaleArg, UsageError> {
        let v: f64 = text.trim().parse().map_err(|_| {
            UsageError::new(
                "--scale",
                format!("expected millimetres per pixel (a positive number), got `{text}`"),
            )
        })?;
        if !(v > 0.0 && v.is_finite()) {
            return Err(UsageError::new(
                "--scale",
                format!("millimetres per pixel must be a positive number, got {text}"),
            ));
        }
        Ok(ScaleArg::MmPerPx(v))
    }

    /// The scale, the points checked against a `width`×`height` frame.
    pub fn resolve(&self, width: u32, height: u32) -> Result<Scale, UsageError> {
        match *self {
            ScaleArg::MmPerPx(v) => {
                if !(v > 0.0 && v.is_finite()) {
                    return Err(UsageError::new(
                        "--scale",
                        format!("millimetres per pixel must be a positive number, got {v}"),
                    ));
                }
                Ok(Scale {
                    mm_per_px: v,
                    known_length: None,
                })
            }
            ScaleArg::KnownLength(k) => {
                k.check_frame(width, height)?;
                Ok(Scale {
                    mm_per_px: k.length_mm / k.distance_px(),
                    known_length: Some(k),
                })
            }
        }
    }
}

/// The size of a pixel on the object, and where it came from.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Scale {
    pub mm_per_px: f64,
    /// The feature it was measured on (`--known-length`); none for `--scale`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub known_length: Option<KnownLength>,
}

impl Scale {
    /// The unit for values whose largest magnitude is `largest_px` (in
    /// pixels, or pixels/s...): px without a scale, else µm below 1 mm
    /// and mm from 1 mm (see the module docs).
    pub fn unit(scale: Option<&Scale>, quantity: Quantity, largest_px: f64) -> Unit {
        let length = match scale {
            None => Length::Px,
            Some(s) if (largest_px * s.mm_per_px).abs() < 1.0 => Length::Um,
            Some(_) => Length::Mm,
        };
        Unit { length, quantity }
    }
}

/// Pixels to a unit: multiply a value in px (or px/s...) by this.
pub fn px_to(unit: Unit, scale: Option<&Scale>) -> f64 {
    match (unit.length, scale) {
        (Length::Px, _) | (_, None) => 1.0,
        (l, Some(s)) => s.mm_per_px * l.per_mm(),
    }
}

/// The mean and a least-squares linear drift of `y`, removed.
fn detrend(y: &[f32]) -> Vec<f32> {
    let nf = y.len() as f64;
    let mean_i = (nf - 1.0) / 2.0;
    let mean_y = y.iter().map(|&v| f64::from(v)).sum::<f64>() / nf;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (i, &v) in y.iter().enumerate() {
        let di = i as f64 - mean_i;
        sxy += di * (f64::from(v) - mean_y);
        sxx += di * di;
    }
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    y.iter()
        .enumerate()
        .map(|(i, &v)| (f64::from(v) - mean_y - slope * (i as f64 - mean_i)) as f32)
        .collect()
}

/// A motion's amplitude (peak of a sinusoid) at `f_hz` in the channels
/// `ys` (x and y of one region, samples at `rate_hz`): per channel the
/// mean and a linear drift removed, then a least-squares sine and cosine;
/// the channels' amplitudes added in quadrature (a motion along any
/// direction gives its amplitude along that direction). The frequency is
/// refined to the largest amplitude within `± search_hz` (the spectrum's
/// resolution: a peak's frequency is known to a fraction of a bin, and a
/// fit a bin off over the record loses most of it). Returns the amplitude
/// and the frequency used.
pub fn tone_amplitude(ys: &[&[f32]], rate_hz: f64, f_hz: f64, search_hz: f64) -> (f64, f64) {
    let n = ys.iter().map(|y| y.len()).min().unwrap_or(0);
    if n < 3 || rate_hz.is_nan() || rate_hz <= 0.0 || !f_hz.is_finite() {
        return (f64::NAN, f_hz);
    }
    let rs: Vec<Vec<f32>> = ys.iter().map(|y| detrend(&y[..n])).collect();
    let fit = |f: f64| {
        rs.iter()
            .map(|r| {
                crate::math::numeric::fit_tone(r, f, rate_hz, 0..n)
                    .0
                    .powi(2)
            })
            .sum::<f64>()
            .sqrt()
    };
    // A scan, then a parabola through the best point and its neighbours.
    const STEPS: usize = 16;
    let step = search_hz.max(0.0) / STEPS as f64;
    if step.is_nan() || step <= 0.0 {
        return (fit(f_hz), f_hz);
    }
    let fs: Vec<f64> = (0..=2 * STEPS)
        .map(|k| f_hz + (k as f64 - STEPS as f64) * step)
        .collect();
    let a: Vec<f64> = fs.iter().map(|&f| fit(f)).collect();
    let best = (0..a.len())
        .max_by(|&i, &j| a[i].total_cmp(&a[j]))
        .unwrap_or(STEPS);
    if best == 0 || best == a.len() - 1 {
        return (a[best], fs[best]);
    }
    let (l, c, h) = (a[best - 1], a[best], a[best + 1]);
    let den = l - 2.0 * c + h;
    let off = if den < 0.0 { 0.5 * (l - h) / den } else { 0.0 };
    let f = fs[best] + off.clamp(-1.0, 1.0) * step;
    let af = fit(f);
    if af >= c {
        (af, f)
    } else {
        (c, fs[best])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_length_parses_and_refuses() {
        let k: KnownLength = "10,20,110,20=5".parse().unwrap();
        assert_eq!(k.distance_px(), 100.0);
        let s = ScaleArg::KnownLength(k).resolve(200, 100).unwrap();
        assert!((s.mm_per_px - 0.05).abs() < 1e-12);
        for bad in [
            "10,20,110,20=0",
            "10,20,110,20=-3",
            "10,20,10,20=5",
            "10,20,110=5",
            "10,20,110,20",
            "10,20,110,20=nan",
        ] {
            let e = bad.parse::<KnownLength>().unwrap_err();
            assert_eq!(e.option, "--known-length", "{bad}");
        }
        let e = ScaleArg::KnownLength(k).resolve(100, 100).unwrap_err();
        assert!(e.message.contains("outside"), "{e}");
        for bad in ["0", "-1", "NaN", "inf", "x"] {
            assert!(ScaleArg::mm_per_px(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn units_by_magnitude() {
        let s = Scale {
            mm_per_px: 0.1,
            known_length: None,
        };
        let u = Scale::unit(Some(&s), Quantity::Displacement, 0.05);
        assert_eq!(u.to_string(), "µm");
        assert!((0.05 * px_to(u, Some(&s)) - 5.0).abs() < 1e-12);
        let u = Scale::unit(Some(&s), Quantity::Acceleration, 20.0);
        assert_eq!(u.to_string(), "mm/s²");
        assert_eq!(
            Scale::unit(None, Quantity::Velocity, 3.0).to_string(),
            "px/s"
        );
    }

    #[test]
    fn tone_amplitude_between_bins() {
        let rate = 1000.0;
        let y: Vec<f32> = (0..1000)
            .map(|i| {
                let t = i as f64 / rate;
                (0.3 * (TAU * 123.37 * t + 0.4).sin() + 0.5 + 2.0 * t) as f32
            })
            .collect();
        let z = vec![0.0f32; y.len()];
        let (a, f) = tone_amplitude(&[&y, &z], rate, 123.0, 1.0);
        assert!((a - 0.3).abs() < 0.003, "{a} at {f}");
        assert!((f - 123.37).abs() < 0.05, "{f}");
    }
}
