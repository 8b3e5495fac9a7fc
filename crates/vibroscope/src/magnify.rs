//! Motion magnification of a recording (Wadhwa et al. 2013, 2014): the
//! shipped `magnify` pipeline (`magnify` stage, then the `y4m` sink)
//! replayed on a video. The Y4M is written to a temporary sibling and
//! renamed when complete; any other extension goes through `ffmpeg`
//! (Y4M in, the container the name asks for out), also via a temporary
//! sibling. Nothing is left behind on an error.
//!
//! Colour: the engine magnifies the luma (the motion is in it). When the
//! input has colour and ffmpeg is installed, the chroma of the input (its
//! region, twice side by side) is put back beside the magnified luma by
//! ffmpeg, frame by frame (`extractplanes`, `mergeplanes`, 4:4:4, so the input's chroma is
//! not resampled twice); the output is then colour (Y4M `C444`, or
//! yuv420p in any other container). Without ffmpeg the output is grey and
//! the report says so.

use crate::engine::pipelines::stage;
use crate::engine::RunReport;
use crate::error::{Error, Result};
use crate::io;
use crate::math::magnify::{MagnifyError, MagnifyParams};
use crate::pipeline::{self, by, BandFilter, PipelineOptions, Pyramid, Roi, RunSettings};
use crate::stages::params::{MagnifyParams as M, Y4mParams};
use crate::stages::transform::roi::RoiParam;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::Command;

/// What `magnify` is asked.
#[derive(Clone, Debug, Default)]
pub struct MagnifyOptions {
    pub video: PathBuf,
    /// `.y4m`, or any container ffmpeg writes (`.mp4`, `.mkv`, ...).
    pub output: PathBuf,
    /// Band edges, Hz.
    pub lo_hz: f64,
    pub hi_hz: f64,
    /// Motion in the band is multiplied by this (0 removes it).
    pub factor: f64,
    /// Capture frame rate (Hz) when the file states the wrong one.
    pub fps: Option<f64>,
    /// Process and write only this region.
    pub roi: Option<Roi>,
    pub pyramid: Pyramid,
    /// Pyramid scales (default 4).
    pub scales: Option<usize>,
    /// Original (left) and magnified (right) in one frame.
    pub side_by_side: bool,
    /// Motion removed after the magnification: `--notch F[,WIDTH]`, each
    /// a further `magnify` stage with factor 0 on F ± WIDTH/2.
    pub notches: Vec<BandFilter>,
    pub run: RunSettings,
}

/// What `magnify` wrote.
#[derive(Debug, Serialize)]
pub struct MagnifyReport {
    pub output: PathBuf,
    /// Frames written and their size.
    pub frames: u64,
    pub width: u32,
    pub height: u32,
    /// The frame rate used, Hz.
    pub fps: f64,
    /// Where the temporal band-pass has unit gain and zero phase, Hz.
    pub centre_hz: f64,
    pub notes: Vec<String>,
    #[serde(skip)]
    pub run: Option<RunReport>,
}

/// Checks the request against the video (rate, band, factor) before
/// anything runs; every error names its flag.
fn check(o: &MagnifyOptions, fps: f64) -> Result<MagnifyParams> {
    let p = MagnifyParams::new(fps, o.lo_hz, o.hi_hz, o.factor as f32);
    if !(o.factor.is_finite() && o.factor >= 0.0) {
        return Err(Error::usage(
            "--factor",
            format!("must be a number >= 0, got {}", o.factor),
        ));
    }
    p.check().map_err(|e| match e {
        MagnifyError::Param { field, message } => {
            let flag = match field {
                "band" => "--band",
                "factor" => "--factor",
                "fps" => "--fps",
                _ => "magnify",
            };
            Error::usage(flag, message)
        }
        MagnifyError::Pyramid(e) => Error::Math(e.into()),
    })?;
    Ok(p)
}

/// Whether the output needs ffmpeg (anything but `.y4m`).
pub(crate) fn needs_ffmpeg(output: &Path) -> bool {
    !output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("y4m"))
}

/// A sibling of `path` that keeps its extension (ffmpeg picks the
/// container from it): `.STEM.PID-N.partial.EXT`.
fn temp_with_ext(path: &Path) -> PathBuf {
    let t = io::atomic::temp_sibling(path);
    match path.extension() {
        Some(e) => {
            let mut s = t.into_os_string();
            s.push(".");
            s.push(e);
            PathBuf::from(s)
        }
        None => t,
    }
}

/// The graph `file -> magnify [-> notch1 -> ...] -> y4m` with the options
/// set; `size` is the region's (or the frame's) width and height. Each
/// notch is a `magnify` stage with factor 0 on its band after the first;
/// with `--side-by-side` it works on the right half only (`roi` and
/// `whole_frame`), so the left stays the original.
pub fn magnify_pipeline(
    o: &MagnifyOptions,
    y4m: &Path,
    size: (u32, u32),
) -> Result<crate::engine::PipelineDecl> {
    let mut decl = pipeline::prepare(&PipelineOptions {
        pipeline: stage::magnify::PIPELINE.into(),
        set: Vec::new(),
        replay: Some(o.video.clone()),
        fps: o.fps,
    })?;
    let (mag, out) = (stage::magnify::MAG, stage::magnify::OUT);
    pipeline::set(&mut decl, out, Y4mParams::path, y4m.to_path_buf(), by("-o"))?;
    let band = format!("--band {},{}", o.lo_hz, o.hi_hz);
    pipeline::set(&mut decl, mag, M::lo_hz, o.lo_hz, by(&band))?;
    pipeline::set(&mut decl, mag, M::hi_hz, o.hi_hz, by(&band))?;
    pipeline::set(&mut decl, mag, M::factor, o.factor, by("--factor"))?;
    pipeline::set(&mut decl, mag, M::pyramid, o.pyramid, by("--pyramid"))?;
    if let Some(s) = o.scales {
        pipeline::set(&mut decl, mag, M::scales, s, by("--scales"))?;
    }
    if let Some(r) = &o.roi {
        let origin = by(&format!("--roi {r}"));
        pipeline::set(&mut decl, mag, M::roi, Some(r.param()), origin)?;
    }
    if o.side_by_side {
        pipeline::set(&mut decl, mag, M::side_by_side, true, by("--side-by-side"))?;
    }
    let mut last = mag.id.to_string();
    for (i, n) in o.notches.iter().enumerate() {
        let ("bandstop", lo_hz, hi_hz) = n.stage() else {
            continue;
        };
        let id = format!("notch{}", i + 1);
        let origin = by(&n.flag());
        let mut st = pipeline::new_stage::<M>(&id, &[&last], origin.clone());
        pipeline::put(&mut st, M::lo_hz, lo_hz, origin.clone())?;
        pipeline::put(&mut st, M::hi_hz, hi_hz, origin.clone())?;
        pipeline::put(&mut st, M::factor, 0.0, origin.clone())?;
        pipeline::put(&mut st, M::pyramid, o.pyramid, origin.clone())?;
        if let Some(sc) = o.scales {
            pipeline::put(&mut st, M::scales, sc, origin.clone())?;
        }
        if o.side_by_side {
            let roi = RoiParam([size.0, 0, size.0, size.1]);
            pipeline::put(&mut st, M::roi, Some(roi), origin.clone())?;
            pipeline::put(&mut st, M::whole_frame, true, origin.clone())?;
        }
        let at = decl
            .stages
            .iter()
            .position(|s| s.id == out.id)
            .unwrap_or(decl.stages.len());
        decl.stages.insert(at, st);
        last = id;
    }
    if last != mag.id {
        decl.stage_mut(out)?.inputs[0].from = last;
    }
    Ok(decl)
}

/// Runs `magnify`.
pub fn magnify(o: &MagnifyOptions) -> Result<MagnifyReport> {
    pipeline::check_fps(o.fps)?;
    if !(o.factor.is_finite() && o.factor >= 0.0) {
        return Err(Error::usage(
            "--factor",
            format!("must be a number >= 0, got {}", o.factor),
        ));
    }
    // Asked once, and only when needed (a Y4M in and out never starts
    // ffmpeg: `ffmpeg -version` took 5% of a 0.5 s magnification).
    let have_ffmpeg = std::cell::OnceCell::new();
    let present = || *have_ffmpeg.get_or_init(ffmpeg_present);
    let ffmpeg = output_needs_ffmpeg(&o.output, present)?;
    let (reader, fps) = open_video(&o.video, o.fps)?;
    let info = reader.info().clone();
    drop(reader);
    let params = check(o, fps)?;
    if let Some(r) = &o.roi {
        if r.w == 0 || r.h == 0 || r.x + r.w > info.width || r.y + r.h > info.height {
            return Err(Error::usage(
                "--roi",
                format!(
                    "{r} does not fit in the {}x{} frame",
                    info.width, info.height
                ),
            ));
        }
    }
    let mut notes = Vec::new();
    let colour = has_colour(&o.video, &info);
    let chroma = match colour {
        Colour::Grey => None,
        Colour::Yes { video_range } if info.depth == io::Depth::U8 && present() => Some(Chroma {
            video: o.video.clone(),
            fps,
            roi: o.roi,
            side_by_side: o.side_by_side,
            video_range,
        }),
        Colour::Yes { .. } => {
            notes.push(if info.depth == io::Depth::U8 {
                "colour is not kept: keeping the chroma needs ffmpeg, which is not installed; the luma is magnified and written as grey".to_string()
            } else {
                "colour is not kept for inputs over 8 bits; the luma is magnified and written as grey".to_string()
            });
            None
        }
    };
    if chroma.is_some() {
        notes.push(
            "colour kept: the luma is magnified, the input's chroma written beside it".to_string(),
        );
    }
    let y4m = if ffmpeg || chroma.is_some() {
        io::atomic::temp_sibling(&o.output.with_extension("y4m"))
    } else {
        io::atomic::temp_sibling(&o.output)
    };
    for n in &o.notches {
        if let ("bandstop", lo_hz, hi_hz) = n.stage() {
            let mut q = params;
            (q.lo_hz, q.hi_hz, q.factor) = (lo_hz, hi_hz, 0.0);
            q.check()
                .map_err(|e| Error::usage("--notch", format!("{}: {e}", n.flag())))?;
        }
    }
    let (w, h) = match &o.roi {
        Some(r) => (r.w, r.h),
        None => (info.width, info.height),
    };
    let decl = magnify_pipeline(o, &y4m, (w, h))?;
    let result = pipeline::run(&decl, o.run);
    let run = match result {
        Ok(r) => r,
        Err(e) => {
            let _ = std::fs::remove_file(&y4m);
            return Err(e);
        }
    };
    match &chroma {
        Some(c) => finish_colour(&y4m, &o.output, c)?,
        None => finish_output(&y4m, &o.output, ffmpeg)?,
    }
    let frames = run
        .stages
        .iter()
        .find(|s| s.id == "out")
        .map(|s| s.items_in)
        .unwrap_or(0);
    let design = crate::math::magnify::temporal::design(
        params.order,
        params.lo_hz,
        params.hi_hz,
        params.fps,
    );
    Ok(MagnifyReport {
        output: o.output.clone(),
        frames,
        width: if o.side_by_side { 2 * w } else { w },
        height: h,
        fps,
        centre_hz: design.centre_hz,
        notes,
        run: Some(run),
    })
}

/// Whether an input has chroma worth keeping.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Colour {
    Grey,
    /// `video_range`: ffmpeg decoded it from video-range YUV (16-235), and
    /// its grey (the luma the engine magnified) was stretched to 0-255.
    Yes {
        video_range: bool,
    },
}

/// A Y4M whose reader kept only its luma, or a file ffmpeg decodes from a
/// pixel format that is not grey (asked of `ffprobe`; when it cannot say,
/// grey).
pub(crate) fn has_colour(video: &Path, info: &io::VideoInfo) -> Colour {
    if info.notes.iter().any(|n| n.contains("luma plane only")) {
        // The Y4M reader reads the luma plane as it is.
        return Colour::Yes { video_range: false };
    }
    if info.format_name != "ffmpeg" {
        return Colour::Grey;
    }
    let probe = Command::new("ffprobe")
        .args([
            "-v",
            "error",
            "-select_streams",
            "v:0",
            "-show_entries",
            "stream=pix_fmt,color_range",
            "-of",
            "csv=p=0",
        ])
        .arg(io::ffmpeg_input(video))
        .output();
    match probe {
        Ok(o) if o.status.success() => {
            let out = String::from_utf8_lossy(&o.stdout).trim().to_string();
            let mut f = out.split(',');
            let (fmt, range) = (f.next().unwrap_or(""), f.next().unwrap_or(""));
            if fmt.is_empty() || fmt.starts_with("gray") || fmt.starts_with("mono") {
                Colour::Grey
            } else {
                Colour::Yes {
                    video_range: !(fmt.starts_with("yuvj") || range == "pc"),
                }
            }
        }
        _ => Colour::Grey,
    }
}

/// Whether ffmpeg runs here.
pub(crate) fn ffmpeg_present() -> bool {
    Command::new("ffmpeg").arg("-version").output().is_ok()
}

/// Whether writing `output` needs ffmpeg (anything but `.y4m`), refused
/// with a usage error naming `-o` when it does and `present` says ffmpeg
/// is missing (asked only then).
pub(crate) fn output_needs_ffmpeg(output: &Path, present: impl FnOnce() -> bool) -> Result<bool> {
    let ffmpeg = needs_ffmpeg(output);
    if ffmpeg && !present() {
        return Err(Error::usage(
            "-o",
            format!(
                "{}: writing anything but .y4m needs ffmpeg, which is not installed (write a .y4m, or install ffmpeg)",
                output.display()
            ),
        ));
    }
    Ok(ffmpeg)
}

/// Where the chroma of a colour input comes from.
struct Chroma {
    video: PathBuf,
    fps: f64,
    roi: Option<Roi>,
    side_by_side: bool,
    /// The magnified luma goes back from 0-255 to 16-235 (see [`Colour`]).
    video_range: bool,
}

impl Chroma {
    /// The ffmpeg filter graph: input 0 the magnified luma (grey Y4M),
    /// input 1 the original; both re-timed to frame index / fps, so that
    /// frame k meets frame k whatever rate the container states.
    fn filter(&self) -> String {
        let pts = format!("settb=AVTB,setpts=N/({}*TB),setsar=1", self.fps);
        let crop = match &self.roi {
            Some(r) => format!(",crop={}:{}:{}:{}:exact=1", r.w, r.h, r.x, r.y),
            None => String::new(),
        };
        let stack = if self.side_by_side {
            "[c0]split[c1][c2];[c1][c2]hstack,format=yuv444p"
        } else {
            "[c0]format=yuv444p"
        };
        // Three grey planes merged (mergeplanes negotiates a two-input
        // luma-plus-chroma mapping to grey and fails).
        let range = if self.video_range {
            ",lut=c0='floor(16+val*219/255+0.5)'"
        } else {
            ""
        };
        format!(
            "[0:v]format=gray{range},{pts}[y];[1:v]format=yuv444p{crop},{pts}[c0];{stack},extractplanes=u+v[u][v];[y][u][v]mergeplanes=0x001020:yuv444p[o]"
        )
    }
}

/// Writes `output` from the magnified luma `y4m` and the chroma of the
/// input (see the module docs), through [`via_temporary`].
fn finish_colour(y4m: &Path, output: &Path, c: &Chroma) -> Result<()> {
    via_temporary(y4m, output, |tmp| {
        let mut cmd = Command::new("ffmpeg");
        cmd.args(["-v", "error", "-nostdin", "-y", "-i"])
            .arg(y4m)
            .arg("-i")
            .arg(io::ffmpeg_input(&c.video))
            .args(["-filter_complex", &c.filter(), "-map", "[o]"])
            .args(["-r", &format!("{}", c.fps)]);
        if needs_ffmpeg(output) {
            cmd.args(["-pix_fmt", "yuv420p"]);
        } else {
            cmd.args(["-f", "yuv4mpegpipe", "-pix_fmt", "yuv444p"]);
        }
        run_ffmpeg(cmd.arg(tmp), || {
            format!(
                "could not put the colour of {} back into {}",
                c.video.display(),
                output.display()
            )
        })
    })
}

/// Runs ffmpeg as `cmd` says; its error output, after `what`, on failure.
fn run_ffmpeg(cmd: &mut Command, what: impl FnOnce() -> String) -> Result<()> {
    let o = cmd.output().map_err(|e| Error::Program {
        program: "ffmpeg",
        message: format!("cannot run it: {e}"),
    })?;
    if o.status.success() {
        Ok(())
    } else {
        Err(Error::Program {
            program: "ffmpeg",
            message: format!("{}: {}", what(), String::from_utf8_lossy(&o.stderr).trim()),
        })
    }
}

/// `write` fills a temporary sibling of `output` (keeping its extension,
/// for ffmpeg) from the finished Y4M `y4m`; the sibling is then renamed to
/// `output`. `y4m` is removed either way, and a failure leaves nothing.
pub(crate) fn via_temporary(
    y4m: &Path,
    output: &Path,
    write: impl FnOnce(&Path) -> Result<()>,
) -> Result<()> {
    let tmp = temp_with_ext(output);
    let done = write(&tmp).and_then(|()| {
        std::fs::rename(&tmp, output).map_err(|source| {
            Error::from(io::atomic::WriteError {
                path: output.to_path_buf(),
                source,
            })
        })
    });
    let _ = std::fs::remove_file(y4m);
    if done.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    done
}

/// Opens `video` and its capture rate (`fps`, else the file's): an input
/// error for a file the reader cannot use, a usage error naming `--fps`
/// when the file states no rate.
pub(crate) fn open_video(
    video: &Path,
    fps: Option<f64>,
) -> Result<(Box<dyn io::VideoReader>, f64)> {
    let reader = io::open(video, io::Format::Auto).map_err(|e| match e {
        io::VideoError::Io { .. } => Error::from(e),
        // A header, colour format or structure this reader cannot use.
        other => Error::input(video, other.to_string()),
    })?;
    let Some(fps) = fps.or(reader.info().fps) else {
        return Err(Error::usage(
            "--fps",
            format!(
                "{}: the file states no frame rate; give it with --fps",
                video.display()
            ),
        ));
    };
    Ok((reader, fps))
}

/// Writes an 8-bit grey video of `frames` frames of `size` (w, h) at `rate`
/// Hz to `output` (Y4M, or any container through ffmpeg), frame `k` drawn
/// into the buffer by `draw(k, buf)`, each stamped k / rate. The Y4M goes
/// to a temporary sibling first, so `output` is whole or absent.
pub(crate) fn write_gray_video(
    output: &Path,
    ffmpeg: bool,
    (w, h): (usize, usize),
    rate: f64,
    frames: u64,
    mut draw: impl FnMut(u64, &mut [u8]) -> Result<()>,
) -> Result<()> {
    write_via_y4m(output, ffmpeg, |file, werr| {
        let mut wr = io::Y4mWriter::new(
            std::io::BufWriter::new(file),
            w as u32,
            h as u32,
            io::Depth::U8,
            rate,
        )
        .map_err(werr)?;
        let mut out = vec![0u8; w * h];
        for k in 0..frames {
            draw(k, &mut out)?;
            let ts = (k as f64 / rate * 1e9).round() as i64;
            wr.write_frame(io::FrameDestRef::U8(&out), Some(ts))
                .map_err(werr)?;
        }
        wr.finish().map_err(werr)?;
        Ok(())
    })
}

/// A video written as a Y4M by `write` (given the new file and the error
/// for a failed write of `output`) into a temporary sibling, then renamed
/// to `output` or, with `ffmpeg`, encoded into it ([`finish_output`]):
/// `output` is whole or absent, and nothing else is left behind.
pub(crate) fn write_via_y4m(
    output: &Path,
    ffmpeg: bool,
    write: impl FnOnce(std::fs::File, &dyn Fn(std::io::Error) -> Error) -> Result<()>,
) -> Result<()> {
    let y4m = if ffmpeg {
        io::atomic::temp_sibling(&output.with_extension("y4m"))
    } else {
        io::atomic::temp_sibling(output)
    };
    let werr = |source: std::io::Error| {
        Error::from(io::atomic::WriteError {
            path: output.to_path_buf(),
            source,
        })
    };
    let written = std::fs::File::create(&y4m)
        .map_err(werr)
        .and_then(|file| write(file, &werr));
    if let Err(e) = written {
        let _ = std::fs::remove_file(&y4m);
        return Err(e);
    }
    finish_output(&y4m, output, ffmpeg)
}

/// Moves the finished Y4M `y4m` to `output`: renamed, or with `ffmpeg`
/// encoded into a temporary sibling that is then renamed; `y4m` is
/// removed either way and a failed encode leaves nothing behind.
pub(crate) fn finish_output(y4m: &Path, output: &Path, ffmpeg: bool) -> Result<()> {
    if ffmpeg {
        via_temporary(y4m, output, |tmp| encode(y4m, tmp))
    } else {
        std::fs::rename(y4m, output).map_err(|source| {
            let _ = std::fs::remove_file(y4m);
            Error::from(io::atomic::WriteError {
                path: output.to_path_buf(),
                source,
            })
        })
    }
}

/// `ffmpeg -i Y4M OUT` (yuv420p, which every player takes).
fn encode(y4m: &Path, out: &Path) -> Result<()> {
    run_ffmpeg(
        Command::new("ffmpeg")
            .args(["-v", "error", "-nostdin", "-y", "-i"])
            .arg(y4m)
            .args(["-pix_fmt", "yuv420p"])
            .arg(out),
        || format!("could not write {}", out.display()),
    )
}
