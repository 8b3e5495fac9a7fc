//! `nokhwa`: a live camera through the nokhwa crate, for platforms without
//! V4L2 (macOS: cargo feature `input-avfoundation`, Windows: `input-msmf`;
//! on Linux `input-v4l`, though the `v4l2` kind does more there).
//!
//! nokhwa picks the format closest to the requested size and rate (GREY,
//! YUYV, NV12 or MJPEG), read back; the frames are converted to gray with
//! the `v4l2` kind's converters (nokhwa 0.10 cannot decode into a caller's
//! luma buffer), and nokhwa allocates each raw frame it hands over. It
//! gives neither driver timestamps nor sequence numbers, so frames are
//! stamped on the run clock when they arrive ([`Control::now_ns`]) and
//! numbered in arrival order: drops inside the camera stack are not seen.
//!
//! Built without any of those features, the kind still exists (pipelines
//! validate everywhere) and fails at start with a message saying how to
//! enable it.

use vibroscope_core::*;

params! {
    /// `nokhwa`'s parameters.
    pub struct NokhwaParams for "nokhwa" {
        index: u32 = ParamSpec::of(ParamType::Int, Def::Int(0))
            .ints(0, u32::MAX as i64)
            .doc("camera index, as nokhwa's query lists them"),
        width: Option<u32> = ParamSpec::of(ParamType::Int, Def::Optional)
            .ints(1, 16384)
            .unit("px")
            .doc("requested width; default: the camera's"),
        height: Option<u32> = ParamSpec::of(ParamType::Int, Def::Optional)
            .ints(1, 16384)
            .unit("px")
            .doc("requested height; default: the camera's"),
        fps: Option<u32> = ParamSpec::of(ParamType::Int, Def::Optional)
            .ints(1, u32::MAX as i64)
            .unit("Hz")
            .doc("requested frame rate (whole numbers)"),
        duration_s: Option<f64> = ParamSpec::of(ParamType::Float, Def::Optional)
            .above(0.0)
            .unit("s")
            .doc("stop after this long (run clock)"),
        max_frames: Option<u64> = ParamSpec::of(ParamType::Int, Def::Optional)
            .ints(0, i64::MAX)
            .doc("stop after this many frames"),
    }
}

pub const KIND: KindSpec = KindSpec {
    name: "nokhwa",
    summary: "live camera through nokhwa (macOS/Windows; features input-avfoundation, input-msmf, input-v4l)",
    inputs: NO_INPUTS,
    outputs: &[OutPort::out(PortType::Frames)],
    params: NokhwaParams::PARAMS,
    plan: |p| {
        let v: NokhwaParams = p.resolve_typed()?;
        Ok(Box::new(v))
    },
};

impl Plan for NokhwaParams {
    fn build(self: Box<Self>, ctx: &BuildCtx) -> Result<Node, StageError> {
        imp::open(*self, ctx.pool_frames).map(Node::Source)
    }

    fn is_live(&self) -> bool {
        true
    }
}

#[cfg(any(
    feature = "input-v4l",
    feature = "input-avfoundation",
    feature = "input-msmf"
))]
mod imp {
    use super::*;
    use crate::v4l2::{to_gray, PixelFormat};
    use nokhwa::pixel_format::LumaFormat;
    use nokhwa::utils::{
        CameraFormat, CameraIndex, FrameFormat as Fourcc, RequestedFormat, RequestedFormatType,
        Resolution,
    };
    use nokhwa::Camera;
    use vibroscope_engine::stages::sources::{check_fps, describe};

    pub(super) fn open(p: NokhwaParams, pool_frames: usize) -> Result<Box<dyn Source>, StageError> {
        let name = format!("nokhwa camera {}", p.index);
        let err =
            |what: &str, e: nokhwa::NokhwaError| StageError::device(&name, format!("{what}: {e}"));
        // nokhwa matches a requested size only within one pixel format: try
        // the ones that convert to gray cheaply first.
        let open = |want: RequestedFormatType| {
            Camera::new(
                CameraIndex::Index(p.index),
                RequestedFormat::new::<LumaFormat>(want),
            )
        };
        let mut cam = match (p.width, p.height) {
            (Some(w), Some(h)) => {
                let try_fmt = |fourcc| {
                    let fmt = CameraFormat::new(Resolution::new(w, h), fourcc, p.fps.unwrap_or(30));
                    open(RequestedFormatType::Closest(fmt))
                };
                try_fmt(Fourcc::GRAY)
                    .or_else(|_| try_fmt(Fourcc::YUYV))
                    .or_else(|_| try_fmt(Fourcc::NV12))
                    .or_else(|_| try_fmt(Fourcc::MJPEG))
                    .map_err(|e| err("cannot open", e))?
            }
            _ => open(match p.fps {
                Some(f) => RequestedFormatType::HighestFrameRate(f),
                None => RequestedFormatType::AbsoluteHighestFrameRate,
            })
            .map_err(|e| err("cannot open", e))?,
        };
        cam.open_stream()
            .map_err(|e| err("cannot start streaming", e))?;
        let res = cam.resolution();
        let fps = f64::from(cam.frame_rate());
        let fps = check_fps(fps)
            .map_err(|m| StageError::format(format!("{name}: granted frame rate: {m}")))?;
        if res.width_x == 0 || res.height_y == 0 || res.width_x > 16384 || res.height_y > 16384 {
            return Err(StageError::format(format!(
                "{name}: unusable size {}x{}",
                res.width_x, res.height_y
            )));
        }
        let format = FrameFormat {
            width: res.width_x,
            height: res.height_y,
            depth: vibroscope_io::Depth::U8,
            bits: 8,
            fps,
            row_timing: None,
        };
        tracing::info!(camera = %name, format = %cam.frame_format(), "negotiated {}", describe(&format));
        Ok(Box::new(NokhwaSource {
            name,
            cam,
            pool: FramePool::new(format, pool_frames),
            seq: 0,
            t_first: None,
            duration_ns: p.duration_s.map(|d| (d * 1e9).round() as i64),
            max_frames: p.max_frames,
        }))
    }

    struct NokhwaSource {
        name: String,
        cam: Camera,
        pool: FramePool,
        seq: u64,
        t_first: Option<i64>,
        duration_ns: Option<i64>,
        max_frames: Option<u64>,
    }

    impl Source for NokhwaSource {
        fn next(&mut self, ctx: &SourceCtx<'_>) -> Result<Option<Item>, StageError> {
            if self.max_frames.is_some_and(|m| self.seq >= m) || ctx.should_stop() {
                return Ok(None);
            }
            let Some(mut f) = ctx.acquire(&self.pool) else {
                return Ok(None);
            };
            let PixelsMut::U8(px) = f.pixels_mut() else {
                return Err(StageError::Internal("8-bit pool expected"));
            };
            // nokhwa 0.10 cannot decode YUYV or MJPEG into a caller's luma
            // buffer, so the raw frame is converted here, as for `v4l2`.
            let buf = self
                .cam
                .frame()
                .map_err(|e| StageError::device(&self.name, format!("capture failed: {e}")))?;
            let res = buf.resolution();
            let (w, h) = (res.width_x as usize, res.height_y as usize);
            if w * h != px.len() {
                return Err(StageError::format(format!(
                    "{}: the camera switched to {w}x{h} mid-stream",
                    self.name
                )));
            }
            let kind = match buf.source_frame_format() {
                // NV12 starts with its full-size luma plane.
                Fourcc::GRAY | Fourcc::NV12 => PixelFormat::Grey,
                Fourcc::YUYV => PixelFormat::Yuyv,
                Fourcc::MJPEG => PixelFormat::Mjpeg,
                other => {
                    return Err(StageError::format(format!(
                    "{}: the camera delivers {other}, which vibroscope does not convert to gray",
                    self.name
                )))
                }
            };
            to_gray(kind, buf.buffer(), w, h, 0, px)
                .map_err(|m| StageError::format(format!("{}: {m}", self.name)))?;
            let t_ns = ctx.control.now_ns();
            let t0 = *self.t_first.get_or_insert(t_ns);
            if self.duration_ns.is_some_and(|d| t_ns - t0 >= d) {
                return Ok(None);
            }
            *f.meta_mut() = FrameMeta {
                seq: self.seq,
                t_ns,
            };
            self.seq += 1;
            Ok(Some(Item::Frame(f.freeze())))
        }

        fn is_live(&self) -> bool {
            true
        }
    }

    impl Drop for NokhwaSource {
        fn drop(&mut self) {
            if let Err(e) = self.cam.stop_stream() {
                tracing::warn!(camera = %self.name, "cannot stop streaming: {e}");
            }
        }
    }
}

#[cfg(not(any(
    feature = "input-v4l",
    feature = "input-avfoundation",
    feature = "input-msmf"
)))]
mod imp {
    use super::*;

    pub(super) fn open(
        p: NokhwaParams,
        _pool_frames: usize,
    ) -> Result<Box<dyn Source>, StageError> {
        Err(StageError::device(
            format!("nokhwa camera {}", p.index),
            "this vibroscope was built without nokhwa",
        )
        .with_hint(
            "rebuild with --features input-avfoundation (macOS), input-msmf (Windows) \
             or input-v4l (Linux)",
        ))
    }
}
