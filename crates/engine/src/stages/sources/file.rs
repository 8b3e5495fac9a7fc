//! `file`: frames from a recording: Y4M (also `-` for stdin), Phantom
//! `.cine`, Photron `.mraw`/`.cih`, anything else through ffmpeg.
//!
//! Never drops: its edges default to `block`, so a replay is deterministic.
//! Timestamps come from the file when it has them (Y4M `Xts`, cine time
//! blocks); `fps` overrides the file's rate (containers often state the
//! playback rate, not the capture rate) and then times follow from it.

use super::{check_fps, nominal_time_ns};
use crate::*;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use vibroscope_io::{self as io, FrameDest, VideoReader};

#[derive(Deserialize, Serialize, Clone, Copy, Debug, PartialEq, Eq, Default)]
#[serde(rename_all = "lowercase")]
pub enum FormatName {
    #[default]
    Auto,
    Y4m,
    Cine,
    Mraw,
    Ffmpeg,
}

impl From<FormatName> for io::Format {
    fn from(f: FormatName) -> io::Format {
        match f {
            FormatName::Auto => io::Format::Auto,
            FormatName::Y4m => io::Format::Y4m,
            FormatName::Cine => io::Format::Cine,
            FormatName::Mraw => io::Format::Mraw,
            FormatName::Ffmpeg => io::Format::Ffmpeg,
        }
    }
}

params! {
    /// `file`'s parameters.
    pub struct FileParams for "file" {
        path: PathBuf = ParamSpec::of(ParamType::Path, Def::Required)
            .doc("the recording; `-` reads Y4M from standard input"),
        format: FormatName = ParamSpec::of(
            ParamType::Choice(&["auto", "y4m", "cine", "mraw", "ffmpeg"]),
            Def::Str("auto"),
        )
        .doc("container; auto: from the file name"),
        fps: Option<f64> = super::fps_param(Def::Optional, "capture rate, overriding the file's"),
        max_frames: Option<u64> = ParamSpec::of(ParamType::Int, Def::Optional)
            .ints(0, i64::MAX)
            .doc("stop after this many frames"),
        /// (A live source: edges drop the oldest when downstream lags, times
        /// move onto the run clock, first frame at 0, so sinks can report
        /// capture-to-sink latency. For rehearsing live pipelines.)
        realtime: bool = ParamSpec::of(ParamType::Bool, Def::Bool(false))
            .doc("play at the recording's own pace, like the camera that made it (a live source)"),
    }
}

type P = FileParams;

pub const KIND: KindSpec = KindSpec {
    name: "file",
    summary:
        "frames from a recording: .y4m (or - for stdin), .cine, .mraw/.cih, other video via ffmpeg",
    inputs: NO_INPUTS,
    outputs: &[OutPort::out(PortType::Frames)],
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        if v.path.as_os_str().is_empty() {
            return Err(p.error("path", "must not be empty"));
        }
        Ok(Box::new(FilePlan {
            path: v.path,
            format: v.format,
            fps: v.fps,
            max_frames: v.max_frames,
            realtime: v.realtime,
        }))
    },
};

struct FilePlan {
    path: PathBuf,
    format: FormatName,
    fps: Option<f64>,
    max_frames: Option<u64>,
    realtime: bool,
}

impl Plan for FilePlan {
    fn is_live(&self) -> bool {
        self.realtime
    }

    fn build(self: Box<Self>, ctx: &BuildCtx) -> Result<Node, StageError> {
        let reader = io::open(&self.path, self.format.into())?;
        let info = reader.info().clone();
        let fps = match (self.fps, info.fps) {
            (Some(f), _) => f,
            (None, Some(f)) => check_fps(f).map_err(|m| {
                StageError::config(
                    "fps",
                    format!("{}: {m}; set it (or pass --fps)", self.path.display()),
                )
            })?,
            (None, None) => {
                return Err(StageError::config(
                    "fps",
                    format!(
                        "{}: the file states no frame rate; set it (or pass --fps)",
                        self.path.display()
                    ),
                ))
            }
        };
        let format = FrameFormat {
            width: info.width,
            height: info.height,
            depth: info.depth,
            bits: info.bits,
            fps,
            row_timing: None,
        };
        if self.fps.is_some() && info.has_timestamps {
            tracing::warn!(path = %self.path.display(), "fps given: ignoring the file's own timestamps");
        }
        tracing::info!(path = %self.path.display(), format = info.format_name, "{}", super::describe(&format));
        Ok(Node::Source(Box::new(FileSource {
            total: match (info.frame_count, self.max_frames) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            },
            use_file_times: self.fps.is_none() && info.has_timestamps,
            pool: FramePool::new(format, ctx.pool_frames),
            reader,
            seq: 0,
            max_frames: self.max_frames,
            fps,
            realtime: self.realtime,
            first_ns: None,
        })))
    }
}

struct FileSource {
    reader: Box<dyn VideoReader>,
    pool: FramePool,
    seq: u64,
    max_frames: Option<u64>,
    total: Option<u64>,
    use_file_times: bool,
    fps: f64,
    realtime: bool,
    /// File time of the first frame (real-time mode).
    first_ns: Option<i64>,
}

impl Source for FileSource {
    fn next(&mut self, ctx: &SourceCtx<'_>) -> Result<Option<Item>, StageError> {
        if self.max_frames.is_some_and(|m| self.seq >= m) {
            return Ok(None);
        }
        let Some(mut f) = ctx.acquire(&self.pool) else {
            return Ok(None);
        };
        let dst = match f.pixels_mut() {
            PixelsMut::U8(p) => FrameDest::U8(p),
            PixelsMut::U16(p) => FrameDest::U16(p),
        };
        let Some(read) = self.reader.read_frame(dst)? else {
            return Ok(None);
        };
        let mut t_ns = match read.timestamp_ns {
            Some(t) if self.use_file_times => t,
            _ => nominal_time_ns(self.seq, self.fps),
        };
        if self.realtime {
            // Due at the file's own spacing on the run clock.
            let t = t_ns - *self.first_ns.get_or_insert(t_ns);
            let due = ctx.control.epoch() + std::time::Duration::from_nanos(t.max(0) as u64);
            let now = std::time::Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
            t_ns = t;
        }
        *f.meta_mut() = FrameMeta {
            seq: self.seq,
            t_ns,
        };
        self.seq += 1;
        Ok(Some(Item::Frame(f.freeze())))
    }

    fn total_hint(&self) -> Option<u64> {
        self.total
    }

    fn is_live(&self) -> bool {
        self.realtime
    }
}
