//! How much memory a stage may take for its per-frame buffers, and the
//! measured bound of what the `phase` stage takes for a frame size.
//!
//! A stage whose buffers grow with the frame (the `phase` stage's
//! pyramids, one set per worker) checks its need against [`limit`] when
//! the first frame tells it the size, before allocating, and refuses
//! with the figures and what to change. The limit is the memory the
//! system reports available (`MemAvailable` in `/proc/meminfo`) when the
//! process asks, or `VIBROSCOPE_MAX_MEMORY` (bytes, or with a `K`, `M`,
//! `G` or `T` suffix in powers of 1024; `0` means no limit).

/// The environment variable that sets the memory limit.
pub const ENV: &str = "VIBROSCOPE_MAX_MEMORY";

/// Memory the process may take for frame-sized buffers: `Ok(None)` for no
/// limit (none set and none known), an error naming the variable when
/// `VIBROSCOPE_MAX_MEMORY` does not parse.
pub fn limit() -> Result<Option<u64>, String> {
    match std::env::var(ENV) {
        Ok(v) => match parse_size(&v) {
            Some(0) => Ok(None),
            Some(n) => Ok(Some(n)),
            None => Err(format!(
                "{ENV}={v:?} is not a size: give bytes, or a number with K, M, G or T (powers of 1024), or 0 for no limit"
            )),
        },
        Err(_) => Ok(available()),
    }
}

/// `MemAvailable` from `/proc/meminfo`, in bytes.
fn available() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// `"12G"`, `"512M"`, `"1.5G"`, `"1000000"` as bytes.
pub fn parse_size(s: &str) -> Option<u64> {
    let s = s.trim();
    let (num, mult) = match s.char_indices().last()? {
        (i, c) if c.is_ascii_alphabetic() => {
            let m: u64 = match c.to_ascii_uppercase() {
                'K' => 1 << 10,
                'M' => 1 << 20,
                'G' => 1 << 30,
                'T' => 1 << 40,
                _ => return None,
            };
            (&s[..i], m)
        }
        _ => (s, 1),
    };
    let x: f64 = num.trim().parse().ok()?;
    let bytes = x * mult as f64;
    (x.is_finite() && x >= 0.0 && bytes < u64::MAX as f64).then_some(bytes as u64)
}

/// A size for people: "9.6 GB" (powers of 1000, as `free -h` does not;
/// the figure is an estimate, not an address).
pub fn human(bytes: u64) -> String {
    let b = bytes as f64;
    if b >= 1e9 {
        format!("{:.1} GB", b / 1e9)
    } else if b >= 1e6 {
        format!("{:.0} MB", b / 1e6)
    } else {
        format!("{:.0} kB", b / 1e3)
    }
}

/// Upper bound of the whole process's memory for the `phase` stage on
/// `width` x `height` frames with `orientations` bands a scale and
/// `workers` worker threads, for the steerable pyramid (`csp`) or the
/// Riesz pyramid. Measured (peak RSS of `vibroscope run
/// visual-microphone` on 512², 1024², 2048² and 4096² frames, 1 to 8
/// workers, 2 and 4 orientations, up to 300 frames; docs/hostile-input.md)
/// and rounded up by a quarter or more: the steerable pyramid took 130 MB
/// for 1024² with one worker, 224 MB with two and 554 MB with eight.
pub fn phase_bound(
    width: usize,
    height: usize,
    orientations: usize,
    workers: usize,
    csp: bool,
) -> u64 {
    let (fixed, per_band, per_band_worker) = if csp { (32, 32, 32) } else { (40, 20, 24) };
    let per_px = fixed + orientations as u64 * (per_band + per_band_worker * workers as u64);
    (width as u64 * height as u64).saturating_mul(per_px) + (64 << 20)
}

/// Bytes of one set of pyramid coefficients as the `pyramid` stage sends
/// it on: per scale (each half the size of the one before) and
/// orientation, a complex band (8 bytes a pixel) for the steerable
/// pyramid, with the full-size high-pass residual (4); for the Riesz
/// pyramid, the band, its two Riesz components, the amplitude and one
/// phase per orientation (4 bytes each).
pub fn pyramid_item_bytes(
    width: usize,
    height: usize,
    scales: usize,
    orientations: usize,
    csp: bool,
) -> u64 {
    let (w, h, k) = (width as u64, height as u64, orientations as u64);
    let levels: u64 = (0..scales.min(32) as u32)
        .map(|s| w.div_ceil(1 << s) * h.div_ceil(1 << s))
        .sum();
    if csp {
        levels.saturating_mul(8 * k) + w * h * 4
    } else {
        levels.saturating_mul(4 * (4 + k))
    }
}

/// Upper bound of the whole process's memory for a modal image (the
/// `modes` sink) of `width` x `height` pixels at pyramid `scale`, either
/// pyramid and either motion. The imager keeps 8 numbers per band pixel
/// and orientation (a quarter as many band pixels a scale down) beside the
/// pyramid's full-size buffers, and at the end analyses the mean frame and
/// its shifted copies with their own coefficients; frames are streamed, so
/// the length of the recording does not count. Measured (peak RSS of
/// `vibroscope modes` on 512², 1024² and 2048² frames, 8 and 40 frames,
/// scales 0, 1 and 3; docs/hostile-input.md) and rounded up: 2048² took
/// 1.59 GB at scale 0 and 774 MB at scale 1 (the default) with the
/// steerable pyramid and `motion = "sum"`, the most of the combinations.
pub fn modes_bound(width: usize, height: usize, scale: usize) -> u64 {
    let band = 240u64 >> (2 * scale.min(16));
    (width as u64 * height as u64).saturating_mul(160 + band) + (64 << 20)
}

/// Upper bound of the whole process's memory for the `magnify` stage on a
/// `width` x `height` region with `orientations` bands a scale (the
/// steerable pyramid keeps a filter state per band pixel and orientation;
/// the Riesz pyramid one per band pixel, whatever the orientations), plus
/// `extra_output_px`: the pixels its pooled output frames hold beyond the
/// region's (twice as wide with `side_by_side`, the whole frame with
/// `whole_frame`), two bytes each.
/// Measured (peak RSS of `vibroscope run magnify --replay V.y4m` on 1024²
/// and 2048² frames, 2, 4 and 8 orientations, 4 and 6 scales, both
/// pyramids; docs/hostile-input.md) and rounded up: 2048² took 1.79 GB with
/// the steerable pyramid and 8 orientations (the default; its two halves
/// each hold the pyramid's buffers; 2.77 GB before session 70 streamed its
/// bands), 987 MB with 2, and 862 MB with the Riesz pyramid; the scales
/// barely count.
pub fn magnify_bound(
    width: usize,
    height: usize,
    orientations: usize,
    csp: bool,
    extra_output_px: u64,
) -> u64 {
    let px = width as u64 * height as u64;
    let per_px = if csp {
        200 + 48 * orientations as u64
    } else {
        240
    };
    let wide = extra_output_px.saturating_mul(2);
    px.saturating_mul(per_px)
        .saturating_add(wide)
        .saturating_add(64 << 20)
}

/// Refuses `need` bytes when they exceed the limit ([`limit`]): `what`
/// says what needs them, `instead` what the user can change. The error
/// is a message for a configuration error on the `memory` field.
pub fn check(need: u64, what: &str, instead: &str) -> Result<(), String> {
    match limit()? {
        Some(limit) if need > limit => Err(format!(
            "{what} would need up to {} and {} may be used ({}); {instead}, or raise {ENV}",
            human(need),
            human(limit),
            if std::env::var_os(ENV).is_some() {
                ENV
            } else {
                "the memory available now"
            },
        )),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_or_are_refused() {
        assert_eq!(parse_size("1000"), Some(1000));
        assert_eq!(parse_size("12G"), Some(12 << 30));
        assert_eq!(parse_size("1.5k"), Some(1536));
        assert_eq!(parse_size(" 512 M "), Some(512 << 20));
        assert_eq!(parse_size("0"), Some(0));
        for bad in ["", "G", "-1G", "12X", "nan", "inf", "1e30T"] {
            assert_eq!(parse_size(bad), None, "{bad}");
        }
    }

    #[test]
    fn the_modes_bound_covers_the_measured_peaks() {
        // (side, scale, measured peak RSS in kB: CSP, motion = sum)
        for (side, scale, kb) in [
            (512, 1, 58_120u64),
            (1024, 1, 204_100),
            (2048, 0, 1_552_108),
            (2048, 1, 755_888),
            (2048, 3, 635_820),
        ] {
            let bound = modes_bound(side, side, scale);
            assert!(
                bound >= kb * 1024,
                "{side}² scale {scale}: {bound} < {kb} kB"
            );
            if side >= 1024 {
                assert!(
                    bound <= kb * 1024 * 2,
                    "{side}² scale {scale}: {bound} is loose"
                );
            }
        }
    }

    #[test]
    fn the_pyramid_stage_bound_covers_the_measured_peaks() {
        // `pyramid -> phase -> null` on a replay, 2 workers, 2
        // orientations, 4 scales, default edges (23 sets in flight at
        // most): (side, csp, measured peak RSS in kB).
        for (side, csp, kb) in [
            (1024, true, 235_604u64),
            (1024, false, 243_924),
            (2048, true, 1_078_720),
            (2048, false, 1_158_836),
        ] {
            let item = pyramid_item_bytes(side, side, 4, 2, csp);
            // A set is at least its finest band, at most twice the frame
            // in complex numbers per orientation and a residual.
            assert!(item >= (side * side * 4) as u64, "{side}² csp={csp}");
            assert!(
                item <= (side * side * (16 * 2 + 24)) as u64,
                "{side}² csp={csp}"
            );
            let bound = phase_bound(side, side, 2, 2, csp) + 23 * item;
            assert!(bound >= kb * 1024, "{side}² csp={csp}: {bound} < {kb} kB");
        }
    }

    #[test]
    fn the_magnify_bound_covers_the_measured_peaks() {
        // (side, orientations, csp, measured peak RSS in kB, 4 scales)
        // Session 71 (the steerable magnifier streaming its bands since
        // session 70): 1024² 8 frames, 2048² 40 frames. The Riesz 2048²
        // k=2 figure is session 58's.
        for (side, k, csp, kb) in [
            (1024, 2, true, 185_424u64),
            (1024, 8, true, 382_072),
            (2048, 2, true, 964_096),
            (2048, 4, true, 1_225_164),
            (2048, 8, true, 1_747_612),
            (1024, 8, false, 154_472),
            (2048, 2, false, 830_900),
            (2048, 8, false, 841_556),
        ] {
            let bound = magnify_bound(side, side, k, csp, 0);
            assert!(
                bound >= kb * 1024,
                "{side}² k={k} csp={csp}: {bound} < {kb} kB"
            );
            assert!(
                bound <= kb * 1024 * 5 / 2,
                "{side}² k={k} csp={csp}: {bound} is loose"
            );
        }
    }

    #[test]
    fn the_bound_covers_the_measured_peaks() {
        // (side, orientations, workers, csp, measured peak RSS in kB)
        for (side, k, t, csp, kb) in [
            (1024, 2, 1, true, 130_228u64),
            (1024, 2, 2, true, 223_744),
            (1024, 2, 8, true, 554_056),
            (1024, 4, 2, true, 288_864),
            (4096, 2, 2, true, 2_496_552),
            (1024, 2, 1, false, 123_028),
            (1024, 2, 2, false, 210_584),
            (1024, 2, 4, false, 253_188),
            (4096, 2, 2, false, 2_121_904),
        ] {
            let bound = phase_bound(side, side, k, t, csp);
            assert!(
                bound >= kb * 1024,
                "{side}² k={k} t={t} csp={csp}: {bound} < {kb} kB"
            );
            assert!(
                bound <= kb * 1024 * 2,
                "{side}² k={k} t={t} csp={csp}: {bound} is loose"
            );
        }
    }
}
