//! The feature vector of thesis 5.5.1: `n` uniform samples from `min_hz`
//! to `max_hz` (0-15 Hz, N = 150) of the global motion power spectrum
//! (Eq. 3.17, the `spectrum` recipe's), smoothed by a Gaussian of std
//! `15 / (2 (N - 1))` Hz and normalised to unit sum over the band; stored
//! as log10 so the weak higher modes count beside the fundamental
//! (`docs/learning.md`).

use crate::error::{Error, Result};
use crate::peaks::SpectrumDb;
use crate::pipeline::{Pyramid, Region, RunSettings};
use crate::spectrum::{run_spectrum, SpectrumOptions, SpectrumReport};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Floor of the normalised power before the log (1e-12 of the band's total).
const FLOOR: f64 = 1e-12;

/// Tiles per side of the local regions (8 x 8; `docs/learning.md` has
/// the comparison with 1 and 16).
pub const DEFAULT_TILES: usize = 8;

/// How features are computed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FeatureParams {
    pub min_hz: f64,
    pub max_hz: f64,
    pub n: usize,
    /// Gaussian std, Hz; `None` = the thesis's `(max - min) / (2 (n - 1))`.
    pub sigma_hz: Option<f64>,
    /// Welch segments of the spectrum (fewer: finer bins, noisier);
    /// `None` = the `spectrum` recipe's default.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub segments: Option<usize>,
    /// The region is cut into `tiles` x `tiles` local regions whose power
    /// spectra are added (Eq. 3.17 sums the power of local motion
    /// signals; the power of the mean motion loses the modes whose parts
    /// move in opposite phase). 1: the region's mean motion.
    pub tiles: usize,
    /// The pyramid that measures local phase. Riesz by default: on the
    /// simulated fabrics (64 px frames) the steerable pyramid's spectra
    /// have a noise floor about 7 dB higher and predict stiffness worse
    /// (R 0.68 against 0.84, `docs/learning.md`).
    pub pyramid: Pyramid,
    /// Take the spectrum's noise floor out before normalising: the median
    /// power from `max_hz + 1` Hz to 95% of the Nyquist frequency (where
    /// a fabric has nothing left) is subtracted from each smoothed sample,
    /// and what falls below a tenth of it is held there. Not in the thesis
    /// (5.5.1 normalises the spectrum as it is): the floor's height is the
    /// camera's (pixels, noise), and without this the upper samples carry
    /// the view as much as the cloth (`docs/learning.md`). Needs a frame
    /// rate above about `2 (max_hz + 1) / 0.95` (34 fps for 15 Hz).
    pub subtract_floor: bool,
    /// How the tiles' local motion signals are scaled before their power
    /// spectra are added. `channel` (the default): each tile and band by
    /// its own texture's A², so a tile's signal is its weighted mean phase
    /// change and every tile counts alike, as the cloth's own tiles do in
    /// the bound. `region`: all by the region's total A², so a tile weighs
    /// as the square of its texture's A², which differs from take to take
    /// (what features were before this setting; a file without it means
    /// that). `tile`: each tile by its own texture's A² over all bands, so
    /// tiles count alike and bands keep their weights within a tile
    /// (measured, not adopted). `docs/learning.md` has the comparisons.
    #[serde(
        default = "normalise_before",
        skip_serializing_if = "normalise_is_before"
    )]
    pub normalise: Normalise,
}

/// [`FeatureParams::normalise`]: the `phase` stage's `normalise`.
pub use crate::spectrum::PhaseNormalise as Normalise;

/// What a dataset, model or cache written without the setting used.
fn normalise_before() -> Normalise {
    Normalise::Region
}

/// Written as nothing, so files from before still match their caches.
fn normalise_is_before(n: &Normalise) -> bool {
    *n == normalise_before()
}

impl Default for FeatureParams {
    fn default() -> Self {
        Self {
            min_hz: 0.0,
            max_hz: 15.0,
            n: 150,
            sigma_hz: None,
            segments: None,
            tiles: DEFAULT_TILES,
            pyramid: Pyramid::Riesz,
            subtract_floor: false,
            normalise: Normalise::Channel,
        }
    }
}

impl FeatureParams {
    pub fn sigma(&self) -> f64 {
        self.sigma_hz
            .unwrap_or((self.max_hz - self.min_hz) / (2.0 * (self.n.max(2) - 1) as f64))
    }

    /// The sample frequencies, Hz.
    pub fn freqs(&self) -> Vec<f64> {
        let step = (self.max_hz - self.min_hz) / (self.n.max(2) - 1) as f64;
        (0..self.n).map(|i| self.min_hz + step * i as f64).collect()
    }

    /// Checks the fields; `what` names where they came from.
    pub fn validate(&self, what: &str) -> Result<()> {
        if !(self.min_hz.is_finite() && self.min_hz >= 0.0 && self.max_hz > self.min_hz) {
            return Err(Error::usage(
                what,
                format!(
                    "the band must be 0 <= min_hz < max_hz, got {}..{}",
                    self.min_hz, self.max_hz
                ),
            ));
        }
        if !(2..=10_000).contains(&self.n) {
            return Err(Error::usage(
                what,
                format!("n must be 2..=10000, got {}", self.n),
            ));
        }
        if !(1..=32).contains(&self.tiles) {
            return Err(Error::usage(
                what,
                format!("tiles must be 1..=32, got {}", self.tiles),
            ));
        }
        if !(self.sigma().is_finite() && self.sigma() > 0.0) {
            return Err(Error::usage(
                what,
                format!("sigma_hz must be > 0, got {}", self.sigma()),
            ));
        }
        Ok(())
    }

    /// The features of a spectrum in dB (bins `f0 + k · resolution`).
    ///
    /// Each sample is the Gaussian-weighted mean of the bins' power around
    /// its frequency; when the bins are coarser than the Gaussian the
    /// kernel widens to half a bin so every sample sees at least one bin.
    pub fn from_spectrum(&self, s: &SpectrumDb) -> std::result::Result<Vec<f64>, String> {
        if !(s.resolution_hz.is_finite() && s.resolution_hz > 0.0) || s.power_db.is_empty() {
            return Err(format!(
                "the spectrum is empty or its resolution ({} Hz) is not > 0",
                s.resolution_hz
            ));
        }
        let top = s.f0_hz + s.resolution_hz * (s.power_db.len() - 1) as f64;
        if top + 0.5 * s.resolution_hz < self.max_hz {
            return Err(format!(
                "the spectrum ends at {top:.2} Hz, below the features' {} Hz (a higher frame rate is needed)",
                self.max_hz
            ));
        }
        let power: Vec<f64> = s
            .power_db
            .iter()
            .map(|db| {
                if db.is_finite() {
                    10f64.powf(db / 10.0)
                } else {
                    0.0
                }
            })
            .collect();
        let sigma = self.sigma().max(0.5 * s.resolution_hz);
        let mut out: Vec<f64> = self
            .freqs()
            .iter()
            .map(|&f| {
                let (mut num, mut den) = (0.0, 0.0);
                let c = (f - s.f0_hz) / s.resolution_hz;
                let half = (4.0 * sigma / s.resolution_hz).ceil() as i64 + 1;
                let k0 = (c.round() as i64 - half).max(0);
                let k1 = (c.round() as i64 + half).min(power.len() as i64 - 1);
                for k in k0..=k1 {
                    let fk = s.f0_hz + k as f64 * s.resolution_hz;
                    let w = (-0.5 * ((fk - f) / sigma).powi(2)).exp();
                    num += w * power[k as usize];
                    den += w;
                }
                if den > 0.0 {
                    num / den
                } else {
                    0.0
                }
            })
            .collect();
        if self.subtract_floor {
            let (lo, hi) = (self.max_hz + 1.0, 0.95 * top);
            let mut tail: Vec<f64> = power
                .iter()
                .enumerate()
                .filter(|&(k, _)| {
                    let f = s.f0_hz + k as f64 * s.resolution_hz;
                    f >= lo && f <= hi
                })
                .map(|(_, &p)| p)
                .collect();
            if tail.len() < 3 {
                return Err(format!(
                    "subtract_floor reads the noise floor from {lo:.1} to {hi:.2} Hz, and the spectrum's {:.3} Hz bins put fewer than 3 there (a frame rate above {:.0} fps, a longer video, or subtract_floor = false)",
                    s.resolution_hz,
                    2.0 * lo / 0.95
                ));
            }
            tail.sort_by(f64::total_cmp);
            let floor = tail[tail.len() / 2];
            for v in out.iter_mut() {
                *v = (*v - floor).max(0.1 * floor);
            }
        }
        let total: f64 = out.iter().sum();
        if !(total.is_finite() && total > 0.0) {
            return Err("the spectrum has no power in the band".into());
        }
        for v in out.iter_mut() {
            *v = (*v / total).max(FLOOR).log10();
        }
        Ok(out)
    }
}

/// The cache's format: a cache of another (or none, written before
/// versions) is recomputed.
pub const CACHE_VERSION: u32 = 3;

/// Features of one video, with what they came from (the cache's content).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct VideoFeatures {
    #[serde(default)]
    pub cache_version: u32,
    pub video: PathBuf,
    pub params: FeatureParams,
    /// Size (bytes) and modification time (s since the epoch) of the video.
    pub video_bytes: u64,
    pub video_mtime_s: f64,
    pub fps: Option<f64>,
    pub roi: Option<String>,
    pub mask: Option<PathBuf>,
    pub sample_rate_hz: f64,
    pub resolution_hz: f64,
    pub features: Vec<f64>,
}

fn stamp(p: &Path) -> Result<(u64, f64)> {
    let m = std::fs::metadata(p).map_err(|e| Error::input(p, format!("cannot read: {e}")))?;
    let t = m
        .modified()
        .ok()
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0.0, |d| d.as_secs_f64());
    Ok((m.len(), t))
}

/// What features are measured from.
#[derive(Clone, Copy, Debug)]
pub enum Source<'a> {
    /// A recording.
    Video(&'a Path),
    /// A scene file, rendered in memory through the forward model: the
    /// frames `vibroscope simulate` would write to a video, bit for bit.
    Scene(&'a Path),
}

impl Source<'_> {
    pub fn path(&self) -> &Path {
        match self {
            Source::Video(p) | Source::Scene(p) => p,
        }
    }

    /// The same kind of source at `p` (e.g. resolved against a directory).
    pub fn at<'b>(&self, p: &'b Path) -> Source<'b> {
        match self {
            Source::Video(_) => Source::Video(p),
            Source::Scene(_) => Source::Scene(p),
        }
    }

    /// What it is, for messages.
    pub fn noun(&self) -> &'static str {
        match self {
            Source::Video(_) => "video",
            Source::Scene(_) => "scene file",
        }
    }
}

/// Computes the features of a video or a scene (with `region`, at `fps`).
pub fn measure(
    source: Source,
    fps: Option<f64>,
    region: &Region,
    params: &FeatureParams,
    run: RunSettings,
) -> Result<VideoFeatures> {
    let video = source.path();
    if let (Source::Scene(p), Some(f)) = (source, fps) {
        return Err(Error::usage(
            "--fps",
            format!(
                "{f}: {} renders at its own `fps`; --fps states a recording's true rate",
                p.display()
            ),
        ));
    }
    let (bytes, mtime) = stamp(video)?;
    let mut o = SpectrumOptions::new(video, PathBuf::from("unused.json"));
    if let Source::Scene(p) = source {
        o.scene = Some(p.to_path_buf());
    }
    o.fps = fps;
    // The features' pyramid, whatever the caller's region says.
    o.region = Region {
        pyramid: params.pyramid,
        ..region.clone()
    };
    o.include_spectrum = true;
    o.segments = params.segments;
    o.tiles = params.tiles;
    o.normalise = params.normalise;
    // Eq. 3.17's plain sum of the local spectra: the relative heights of
    // a fabric's modes are the features, and weighing the tiles by their
    // own lines would make those heights depend on where the lines stood
    // out (the features and their cache predate `combine`).
    o.combine = crate::spectrum::Combine::Sum;
    o.peaks = 1;
    o.run = run;
    let (report, _) = run_spectrum(&o, false)?;
    let features = spectrum_features(&report, params).map_err(|m| Error::input(video, m))?;
    Ok(VideoFeatures {
        cache_version: CACHE_VERSION,
        video: video.to_path_buf(),
        params: *params,
        video_bytes: bytes,
        video_mtime_s: mtime,
        fps,
        roi: region.roi.as_ref().map(|r| r.to_string()),
        mask: region.mask.clone(),
        sample_rate_hz: report.sample_rate_hz,
        resolution_hz: report.resolution_hz,
        features,
    })
}

/// The features of a `spectrum` report (which must include its spectrum).
pub fn spectrum_features(
    report: &SpectrumReport,
    params: &FeatureParams,
) -> std::result::Result<Vec<f64>, String> {
    match &report.spectrum {
        Some(s) => params.from_spectrum(s),
        None => Err("holds no spectrum (run `vibroscope spectrum --include-spectrum`)".into()),
    }
}

/// The features of the expected spectrum of the video a scene file
/// renders ([`crate::sim::Fabric::expected_tile_power`] with the features'
/// `tiles`): what the features could be with nothing between the cloth
/// and the spectrum, for the learning bound (`learn evaluate --exact`).
/// The scene is read as the `synthetic` source reads it, and must hold a
/// `fabric` table.
pub fn exact_features(scene: &Path, params: &FeatureParams) -> Result<Vec<f64>> {
    let (_, f) = scene_fabric(scene)?;
    let power = f.expected_tile_power(params.tiles);
    // Nothing to take out: the expected spectrum has no noise floor.
    let params = FeatureParams {
        subtract_floor: false,
        ..*params
    };
    let df = crate::sim::fabric::LINE_SPACING_HZ;
    let s = SpectrumDb {
        f0_hz: 0.5 * df,
        resolution_hz: df,
        power_db: power.iter().map(|p| 10.0 * p.max(1e-300).log10()).collect(),
    };
    params.from_spectrum(&s).map_err(|m| Error::input(scene, m))
}

/// A fabric scene's settings and its cloth, as the `synthetic` source
/// builds them.
fn scene_fabric(
    scene: &Path,
) -> Result<(
    crate::stages::sources::synthetic::SyntheticParams,
    crate::sim::Fabric,
)> {
    let p = crate::pipeline::SceneFile::read(scene)?.synthetic()?;
    let fabric = p
        .fabric
        .as_ref()
        .ok_or_else(|| Error::input(scene, "has no `fabric` table (not a fabric scene)"))?;
    let [_, _, w, h] = p.object_rect();
    let f = crate::sim::Fabric::new(fabric, w as usize, h as usize, p.seed)
        .map_err(|e| Error::input(scene, e.to_string()))?;
    Ok((p, f))
}

/// The features of the true motion of the take a scene file renders:
/// the cloth cut into the features' tiles, each part's mean displacement
/// at every frame ([`crate::sim::Fabric::tile_shapes`]), through the
/// estimator the videos' spectra go through (the `spectrum` stage's
/// whole-recording Welch average, Hann segments) and the same features;
/// no texture, sensor noise or pyramid. Between the bound (the expected
/// spectrum) and the camera: what one take of this length holds.
pub fn true_motion_features(scene: &Path, params: &FeatureParams) -> Result<Vec<f64>> {
    use crate::stages::transform::spectrum::{whole_segments, SegmentFft, Taper};
    let (p, mut f) = scene_fabric(scene)?;
    let frames = p.frame_count() as usize;
    if frames < 8 {
        return Err(Error::input(
            scene,
            format!("{frames} frames: a spectrum needs at least 8"),
        ));
    }
    let shapes = f.tile_shapes(params.tiles);
    let ch = shapes.len();
    crate::engine::memory::check(
        (frames as u64).saturating_mul(ch as u64 * 4),
        &format!("the true motion of {frames} frames x {ch} tiles"),
        "a shorter scene or fewer `tiles`",
    )
    .map_err(|m| Error::input(scene, m))?;
    let mut data = vec![0f32; frames * ch];
    for (k, row) in data.chunks_exact_mut(ch).enumerate() {
        let q = f.coordinates(k as f64 / p.fps);
        for (x, w) in row.iter_mut().zip(&shapes) {
            *x = w.iter().zip(q).map(|(a, b)| a * b).sum::<f64>() as f32;
        }
    }
    let (n, starts) = whole_segments(frames, None, None, params.segments);
    let mut fft = SegmentFft::new(n, Taper::Hann, p.fps);
    let mut acc = vec![0.0; fft.bins()];
    for &a in &starts {
        for c in 0..ch {
            fft.accumulate(&data[a * ch..(a + n) * ch], ch, c, &mut acc);
        }
    }
    let s = SpectrumDb {
        f0_hz: 0.0,
        resolution_hz: p.fps / n as f64,
        power_db: acc
            .iter()
            .map(|v| 10.0 * (v / starts.len() as f64).max(1e-300).log10())
            .collect(),
    };
    params.from_spectrum(&s).map_err(|m| Error::input(scene, m))
}

/// The features of a stored spectrum JSON (`vibroscope spectrum --include-spectrum`).
pub fn from_spectrum_json(path: &Path, params: &FeatureParams) -> Result<Vec<f64>> {
    let text = std::fs::read(path).map_err(|e| Error::input(path, format!("cannot read: {e}")))?;
    let report: SpectrumReport = serde_json::from_slice(&text)
        .map_err(|e| Error::input(path, format!("not a spectrum JSON: {e}")))?;
    spectrum_features(&report, params).map_err(|m| Error::input(path, m))
}

/// The cache file beside a video (or scene): `VIDEO.features.json`.
pub fn cache_path(video: &Path) -> PathBuf {
    let mut s = video.as_os_str().to_owned();
    s.push(".features.json");
    PathBuf::from(s)
}

/// Features from the cache when it matches the video (or scene file) and
/// the settings, else computed and cached (written atomically). A scene's
/// cache is keyed on the scene file: a change to the simulator's physics
/// must raise [`CACHE_VERSION`].
pub fn cached(
    source: Source,
    fps: Option<f64>,
    region: &Region,
    params: &FeatureParams,
    run: RunSettings,
) -> Result<VideoFeatures> {
    let video = source.path();
    let (bytes, mtime) = stamp(video)?;
    let cache = cache_path(video);
    if let Ok(text) = std::fs::read(&cache) {
        // The settings are compared as written: a cache from before a
        // setting existed lacks it, and must not pass for its default.
        let written = serde_json::from_slice::<serde_json::Value>(&text)
            .ok()
            .and_then(|v| v.get("params").cloned());
        let same_params = written.is_some() && written == serde_json::to_value(params).ok();
        if let Ok(f) = serde_json::from_slice::<VideoFeatures>(&text) {
            if f.cache_version == CACHE_VERSION
                && same_params
                && f.params == *params
                && f.video_bytes == bytes
                && f.video_mtime_s == mtime
                && f.fps == fps
                && f.roi == region.roi.as_ref().map(|r| r.to_string())
                && f.mask == region.mask
                && f.features.len() == params.n
            {
                return Ok(f);
            }
        }
    }
    let f = measure(source, fps, region, params, run)?;
    if let Ok(bytes) = serde_json::to_vec(&f) {
        // A cache that cannot be written is only slower next time.
        let _ = crate::io::atomic::write_atomic(&cache, &bytes);
    }
    Ok(f)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// The cache is keyed on the video's mtime as an f64 of seconds, so it
    /// must read back exactly: serde_json's default float parser read
    /// some mtimes back one bit off (this one among them; 94 of one
    /// dataset's 720 takes, 2 of another's), and those takes were
    /// measured again on every run.
    #[test]
    fn a_cache_is_found_again_whatever_the_videos_mtime() {
        let d = tempfile::tempdir().unwrap();
        let video = d.path().join("v.y4m");
        // Not a video: a cache miss is an error, not a silent re-measure.
        std::fs::write(&video, b"not a video").unwrap();
        let t = std::time::UNIX_EPOCH + std::time::Duration::from_nanos(1_795_818_818_468_119_820);
        std::fs::File::options()
            .write(true)
            .open(&video)
            .unwrap()
            .set_modified(t)
            .unwrap();
        let (video_bytes, video_mtime_s) = stamp(&video).unwrap();
        let params = FeatureParams::default();
        let f = VideoFeatures {
            cache_version: CACHE_VERSION,
            video: video.clone(),
            params,
            video_bytes,
            video_mtime_s,
            fps: None,
            roi: Some("1,2,3,4".into()),
            mask: None,
            sample_rate_hz: 40.0,
            resolution_hz: 0.1,
            features: vec![-2.0; params.n],
        };
        std::fs::write(cache_path(&video), serde_json::to_vec(&f).unwrap()).unwrap();
        let region = Region {
            roi: Some("1,2,3,4".parse().unwrap()),
            ..Region::default()
        };
        let got = cached(
            Source::Video(&video),
            None,
            &region,
            &params,
            RunSettings::default(),
        )
        .unwrap_or_else(|e| panic!("the cache was not found again: {e}"));
        assert_eq!(got.features, f.features);
    }

    /// Settings written before `normalise` existed (a dataset, a model, a
    /// cache) read as `region`, what they were measured with, and `region`
    /// is written as nothing so they keep matching; new settings default
    /// to `channel` and say so.
    #[test]
    fn settings_without_normalise_mean_region() {
        let old: FeatureParams = toml::from_str("tiles = 8\nsubtract_floor = true").unwrap();
        assert_eq!(old.normalise, Normalise::Region);
        let json = serde_json::to_value(old).unwrap();
        assert!(json.get("normalise").is_none(), "{json}");
        let new = FeatureParams::default();
        assert_eq!(new.normalise, Normalise::Channel);
        let text = toml::to_string(&new).unwrap();
        assert!(text.contains("normalise = \"channel\""), "{text}");
        let back: FeatureParams = toml::from_str(&text).unwrap();
        assert_eq!(back, new);
        let tile: FeatureParams = toml::from_str("normalise = \"tile\"").unwrap();
        assert_eq!(tile.normalise, Normalise::Tile);
        assert!(toml::from_str::<FeatureParams>("normalise = \"band\"").is_err());
    }

    #[test]
    fn a_peak_lands_where_it_is_and_sums_to_one() {
        let p = FeatureParams::default();
        let mut db = vec![-80.0; 400];
        db[100] = 0.0; // 5 Hz at 0.05 Hz bins
        let s = SpectrumDb {
            f0_hz: 0.0,
            power_db: db,
            resolution_hz: 0.05,
        };
        let f = p.from_spectrum(&s).unwrap();
        assert_eq!(f.len(), 150);
        let sum: f64 = f.iter().map(|v| 10f64.powf(*v)).sum();
        assert!((sum - 1.0).abs() < 1e-9);
        let imax = (0..150).max_by(|&a, &b| f[a].total_cmp(&f[b])).unwrap();
        assert!((p.freqs()[imax] - 5.0).abs() < 0.06, "{}", p.freqs()[imax]);
        // Too low a frame rate is refused.
        let short = SpectrumDb {
            f0_hz: 0.0,
            power_db: vec![0.0; 100],
            resolution_hz: 0.1,
        };
        assert!(p.from_spectrum(&short).unwrap_err().contains("below"));
    }

    /// Two cameras see one spectrum over floors 10 dB apart: with the
    /// floor taken out their features agree where the cloth stands above
    /// both floors, and without it they do not.
    #[test]
    fn the_floor_is_taken_out() {
        let cloth = |f: f64| 1.0 / (1.0 + (f / 2.0).powi(6));
        let seen = |floor: f64| SpectrumDb {
            f0_hz: 0.0,
            power_db: (0..400)
                .map(|k| 10.0 * (cloth(k as f64 * 0.05) + floor).log10())
                .collect(),
            resolution_hz: 0.05,
        };
        let (a, b) = (seen(1e-5), seen(1e-4));
        let gap = |p: &FeatureParams| {
            let (fa, fb) = (p.from_spectrum(&a).unwrap(), p.from_spectrum(&b).unwrap());
            // Up to 6 Hz the cloth stands 10 dB or more above both floors.
            (0..60).map(|i| (fa[i] - fb[i]).abs()).fold(0.0, f64::max)
        };
        let plain = FeatureParams::default();
        let sub = FeatureParams {
            subtract_floor: true,
            ..plain
        };
        assert!(
            gap(&sub) < 0.005 && gap(&plain) > 0.02,
            "{} {}",
            gap(&sub),
            gap(&plain)
        );
        // A spectrum that ends at the band's top has no floor to read.
        let short = SpectrumDb {
            f0_hz: 0.0,
            power_db: vec![0.0; 310],
            resolution_hz: 0.05,
        };
        assert!(sub
            .from_spectrum(&short)
            .unwrap_err()
            .contains("subtract_floor"));
    }
}
