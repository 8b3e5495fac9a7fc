//! `v4l2`: a live camera through Video4Linux2 (Linux, cargo feature `v4l2`,
//! on by default).
//!
//! - **Format.** The driver is asked for `width`x`height` in `format`
//!   (`auto` picks the first of GREY, YUYV, MJPEG the device offers) and
//!   what it grants is read back: drivers round sizes to what they support,
//!   so the frames have the granted size, and a differing grant is reported.
//!   A format the device does not offer is an error listing what it does.
//! - **Gray.** GREY rows are copied (honouring the driver's stride), YUYV
//!   keeps its luma bytes, MJPEG is decoded to luma (zune-jpeg).
//! - **Rate.** `fps` is requested with `VIDIOC_S_PARM` and the granted frame
//!   interval is read back; it is the stream's nominal rate.
//! - **Time.** Frames are mmap-streamed. `FrameMeta::t_ns` is the driver's
//!   buffer timestamp, taken on `CLOCK_MONOTONIC`
//!   (V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC), moved onto the run clock
//!   ([`Control::now_ns`], ns since the run started; `Instant` is
//!   `CLOCK_MONOTONIC` on Linux, so this is a constant offset read once), so
//!   capture-to-sink latency is `now - t_ns`. A driver that stamps on
//!   another clock gets the dequeue time instead, with a warning.
//!   `FrameMeta::seq` is the driver's sequence number
//!   (widened to 64 bits, counted from the first frame), so a gap is a frame
//!   the device dropped: gaps and buffers flagged as corrupt are counted in
//!   the source's `dropped` column of `--stats`.
//! - **Row timing.** Exposure (`V4L2_CID_EXPOSURE_ABSOLUTE`) and line time
//!   (`V4L2_CID_PIXEL_RATE` with `V4L2_CID_HBLANK`) are read when the driver
//!   exposes them; with a line time the format carries a [`RowTiming`].
//! - **Faults.** A missing, busy or non-capture device fails before anything
//!   runs, naming the path; an error mid-stream (EIO, ENODEV when unplugged)
//!   ends the run with that error, and sinks finalise what they received.
//!
//! It is a live source: its output edges drop the oldest frame when
//! downstream lags. `duration_s` / `max_frames` end the stream (recording).

use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use vibroscope_core::*;
use vibroscope_engine::stages::sources::fps_param;

/// Pixel formats this source turns into gray frames.
#[derive(Deserialize, Serialize, Clone, Copy, Debug, PartialEq, Eq, Default)]
#[serde(rename_all = "lowercase")]
pub enum PixelFormat {
    /// The first of GREY, YUYV, MJPEG the device offers.
    #[default]
    Auto,
    Grey,
    Yuyv,
    Mjpeg,
}

impl PixelFormat {
    /// The V4L2 FourCC of a concrete format.
    pub fn fourcc(self) -> Option<[u8; 4]> {
        match self {
            PixelFormat::Auto => None,
            PixelFormat::Grey => Some(*b"GREY"),
            PixelFormat::Yuyv => Some(*b"YUYV"),
            PixelFormat::Mjpeg => Some(*b"MJPG"),
        }
    }

    /// The concrete format of a FourCC, if this source converts it.
    pub fn from_fourcc(f: [u8; 4]) -> Option<PixelFormat> {
        match &f {
            b"GREY" => Some(PixelFormat::Grey),
            b"YUYV" => Some(PixelFormat::Yuyv),
            b"MJPG" | b"JPEG" => Some(PixelFormat::Mjpeg),
            _ => None,
        }
    }
}

/// Printable FourCC (`YUYV`), with unprintable bytes escaped.
pub fn fourcc_str(f: [u8; 4]) -> String {
    f.iter()
        .map(|&b| {
            if b.is_ascii_graphic() || b == b' ' {
                (b as char).to_string()
            } else {
                format!("\\x{b:02x}")
            }
        })
        .collect::<String>()
        .trim_end()
        .to_string()
}

/// Picks the format to request among those the device offers (`offered`,
/// FourCCs in the driver's order). The error lists what the device offers.
pub fn choose_format(
    device: &str,
    wanted: PixelFormat,
    offered: &[[u8; 4]],
) -> Result<[u8; 4], String> {
    let list = || {
        if offered.is_empty() {
            "none".to_string()
        } else {
            offered
                .iter()
                .map(|&f| fourcc_str(f))
                .collect::<Vec<_>>()
                .join(", ")
        }
    };
    match wanted.fourcc() {
        Some(f) => {
            if offered.contains(&f) || (f == *b"MJPG" && offered.contains(b"JPEG")) {
                Ok(if offered.contains(&f) { f } else { *b"JPEG" })
            } else {
                Err(format!(
                    "{device}: the device does not offer {} (it offers: {})",
                    fourcc_str(f),
                    list()
                ))
            }
        }
        None => [*b"GREY", *b"YUYV", *b"MJPG", *b"JPEG"]
            .into_iter()
            .find(|f| offered.contains(f))
            .ok_or_else(|| {
                format!(
                    "{device}: none of the formats vibroscope converts (GREY, YUYV, MJPEG) is offered (the device offers: {})",
                    list()
                )
            }),
    }
}

/// Converts one captured buffer to 8-bit gray, `width`x`height`, into `out`.
/// `stride` is the driver's bytes per line (0: tightly packed). GREY and
/// YUYV allocate nothing; the MJPEG decoder keeps per-frame working buffers
/// of its own.
pub fn to_gray(
    format: PixelFormat,
    src: &[u8],
    width: usize,
    height: usize,
    stride: usize,
    out: &mut [u8],
) -> Result<(), String> {
    let n = width * height;
    if out.len() != n {
        return Err(format!(
            "internal: gray buffer holds {} pixels, frame has {n}",
            out.len()
        ));
    }
    match format {
        PixelFormat::Grey => {
            let stride = if stride == 0 { width } else { stride };
            let need = stride * (height.max(1) - 1) + width;
            if src.len() < need {
                return Err(format!(
                    "short GREY frame: {} bytes, {need} needed for {width}x{height}",
                    src.len()
                ));
            }
            for (y, row) in out.chunks_exact_mut(width).enumerate() {
                row.copy_from_slice(&src[y * stride..y * stride + width]);
            }
            Ok(())
        }
        PixelFormat::Yuyv => {
            let stride = if stride == 0 { 2 * width } else { stride };
            let need = stride * (height.max(1) - 1) + 2 * width;
            if src.len() < need {
                return Err(format!(
                    "short YUYV frame: {} bytes, {need} needed for {width}x{height}",
                    src.len()
                ));
            }
            for (y, row) in out.chunks_exact_mut(width).enumerate() {
                let line = &src[y * stride..y * stride + 2 * width];
                for (d, s) in row.iter_mut().zip(line.chunks_exact(2)) {
                    *d = s[0];
                }
            }
            Ok(())
        }
        PixelFormat::Mjpeg => mjpeg_to_gray(src, width, height, out),
        PixelFormat::Auto => Err("internal: no concrete pixel format".into()),
    }
}

/// Decodes a (motion) JPEG frame to its luma plane. Streams that omit the
/// Huffman tables (common in MJPEG) use the standard ones.
pub fn mjpeg_to_gray(
    src: &[u8],
    width: usize,
    height: usize,
    out: &mut [u8],
) -> Result<(), String> {
    use zune_jpeg::zune_core::bytestream::ZCursor;
    use zune_jpeg::zune_core::colorspace::ColorSpace;
    use zune_jpeg::zune_core::options::DecoderOptions;
    let opts = DecoderOptions::default().jpeg_set_out_colorspace(ColorSpace::Luma);
    let mut dec = zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(src), opts);
    dec.decode_headers()
        .map_err(|e| format!("bad MJPEG frame: {e:?}"))?;
    let (w, h) = dec
        .dimensions()
        .ok_or_else(|| "bad MJPEG frame: no size".to_string())?;
    if (w, h) != (width, height) {
        return Err(format!(
            "MJPEG frame is {w}x{h}, the negotiated size is {width}x{height}"
        ));
    }
    dec.decode_into(out)
        .map_err(|e| format!("bad MJPEG frame: {e:?}"))
}

/// Widens 32-bit driver sequence numbers to 64 bits and counts gaps.
#[derive(Default, Debug)]
pub struct SeqTracker {
    last: Option<u32>,
    seq: u64,
}

impl SeqTracker {
    /// The widened sequence number of a frame (0 for the first) and how many
    /// frames are missing before it.
    pub fn next(&mut self, driver_seq: u32) -> (u64, u64) {
        let out = match self.last {
            None => (0, 0),
            Some(prev) => {
                let step = u64::from(driver_seq.wrapping_sub(prev));
                if step == 0 || step > u64::from(u32::MAX / 2) {
                    // A repeated or backwards number: the driver does not count
                    // frames (some fill 0); treat every frame as the next.
                    (self.seq + 1, 0)
                } else {
                    (self.seq + step, step - 1)
                }
            }
        };
        self.last = Some(driver_seq);
        self.seq = out.0;
        out
    }
}

params! {
    /// `v4l2`'s parameters.
    pub struct V4l2Params for "v4l2" {
        device: PathBuf = ParamSpec::of(ParamType::Path, Def::Str("/dev/video0"))
            .doc("the device node"),
        width: Option<u32> = ParamSpec::of(ParamType::Int, Def::Optional)
            .ints(1, 16384)
            .unit("px")
            .doc("requested width; the driver may grant another (read back)"),
        height: Option<u32> = ParamSpec::of(ParamType::Int, Def::Optional)
            .ints(1, 16384)
            .unit("px")
            .doc("requested height; the driver may grant another (read back)"),
        fps: Option<f64> = fps_param(
            Def::Optional,
            "requested frame rate; the granted interval is read back",
        ),
        format: PixelFormat = ParamSpec::of(
            ParamType::Choice(&["auto", "grey", "yuyv", "mjpeg"]),
            Def::Str("auto"),
        )
        .doc("pixel format; auto: the first of GREY, YUYV, MJPEG the device offers"),
        buffers: u32 = ParamSpec::of(ParamType::Int, Def::Int(4))
            .ints(2, 32)
            .doc("driver buffers for mmap streaming"),
        duration_s: Option<f64> = ParamSpec::of(ParamType::Float, Def::Optional)
            .above(0.0)
            .unit("s")
            .doc("stop after this long (by the driver's timestamps)"),
        max_frames: Option<u64> = ParamSpec::of(ParamType::Int, Def::Optional)
            .ints(0, i64::MAX)
            .doc("stop after this many frames"),
    }
}

pub const KIND: KindSpec = KindSpec {
    name: "v4l2",
    summary: "live camera through Video4Linux2 (device, width, height, fps, format = grey|yuyv|mjpeg|auto)",
    inputs: NO_INPUTS,
    outputs: &[OutPort::out(PortType::Frames)],
    params: V4l2Params::PARAMS,
    plan: |p| {
        let v: V4l2Params = p.resolve_typed()?;
        if v.device.as_os_str().is_empty() {
            return Err(p.error("device", "must not be empty"));
        }
        Ok(Box::new(v))
    },
};

impl Plan for V4l2Params {
    fn build(self: Box<Self>, ctx: &BuildCtx) -> Result<Node, StageError> {
        imp::open(*self, ctx.pool_frames).map(Node::Source)
    }

    fn is_live(&self) -> bool {
        true
    }
}

/// One capture device as `vibroscope devices` lists it.
#[derive(Clone, Debug, Default)]
pub struct DeviceInfo {
    pub path: PathBuf,
    pub card: String,
    pub driver: String,
    pub bus: String,
    pub formats: Vec<FormatInfo>,
    /// Exposure and line timing, when the driver exposes them.
    pub timing: Vec<String>,
}

#[derive(Clone, Debug, Default)]
pub struct FormatInfo {
    pub fourcc: [u8; 4],
    pub description: String,
    /// Sizes, each with its frame rates (`"320x180: 60, 30 fps"`).
    pub sizes: Vec<String>,
}

impl std::fmt::Display for DeviceInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "{}: {} (driver {}, {})",
            self.path.display(),
            self.card,
            self.driver,
            self.bus
        )?;
        for t in &self.timing {
            writeln!(f, "  {t}")?;
        }
        let (usable, other): (Vec<&FormatInfo>, Vec<&FormatInfo>) = self
            .formats
            .iter()
            .partition(|fmt| PixelFormat::from_fourcc(fmt.fourcc).is_some());
        if usable.is_empty() {
            writeln!(f, "  no format vibroscope converts (GREY, YUYV, MJPEG)")?;
        }
        for fmt in usable {
            writeln!(f, "  {} ({})", fourcc_str(fmt.fourcc), fmt.description)?;
            for s in &fmt.sizes {
                writeln!(f, "    {s}")?;
            }
        }
        if !other.is_empty() {
            let names: Vec<String> = other.iter().map(|fmt| fourcc_str(fmt.fourcc)).collect();
            writeln!(f, "  also offers (not converted): {}", names.join(", "))?;
        }
        Ok(())
    }
}

/// Capture devices on this machine. `Err` says why none could be listed.
pub fn list_devices() -> Result<Vec<DeviceInfo>, String> {
    imp::list_devices()
}

/// Device nodes `/dev/video*`, in numeric order.
pub fn video_nodes() -> Vec<PathBuf> {
    let mut v: Vec<(u32, PathBuf)> = std::fs::read_dir("/dev")
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let n = name.strip_prefix("video")?.parse::<u32>().ok()?;
            Some((n, e.path()))
        })
        .collect();
    v.sort();
    v.into_iter().map(|(_, p)| p).collect()
}

#[cfg(all(target_os = "linux", feature = "v4l2"))]
mod imp {
    use super::*;
    use std::io;
    use v4l::buffer::Type;
    use v4l::io::mmap::Stream;
    use v4l::io::traits::{CaptureStream, Stream as _};
    use v4l::video::Capture;
    use v4l::{Device, FourCC};
    use vibroscope_engine::stages::sources::{check_fps, describe};

    const CID_EXPOSURE_ABSOLUTE: u32 = 0x009a_0902;
    const CID_HBLANK: u32 = 0x009e_0902;
    const CID_PIXEL_RATE: u32 = 0x009f_0902;
    /// How long to wait for a frame before calling the device stalled.
    const STALL_MS: i32 = 10_000;
    /// Poll slice while waiting, so a stop request is seen promptly.
    const POLL_MS: i32 = 100;

    /// An OS error on `path`, said plainly.
    pub(super) fn device_error(path: &str, what: &str, e: &io::Error) -> StageError {
        let hint = match e.raw_os_error() {
            Some(libc::ENOENT) => {
                let found: Vec<String> = list_devices()
                    .unwrap_or_default()
                    .iter()
                    .map(|d| d.path.display().to_string())
                    .collect();
                if found.is_empty() {
                    "no such device; no camera found".to_string()
                } else {
                    format!(
                        "no such device; cameras: {}; see `vibroscope devices`",
                        found.join(", ")
                    )
                }
            }
            Some(libc::EBUSY) => "the device is busy: another program is using it".into(),
            Some(libc::EACCES) | Some(libc::EPERM) => {
                "permission denied: join the `video` group or check the node's mode".into()
            }
            Some(libc::ENODEV) => "the device is gone: unplugged or its driver unloaded".into(),
            Some(libc::EIO) => "I/O error: the device failed or was unplugged".into(),
            _ => String::new(),
        };
        let err = StageError::device(path, format!("{what}: {e}"));
        if hint.is_empty() {
            err
        } else {
            err.with_hint(hint)
        }
    }

    /// Nanoseconds from C seconds and a sub-second count in units of
    /// `unit` ns (`time_t` and `long` are 32-bit on some targets).
    fn to_ns<S: Into<i64>, F: Into<i64>>(sec: S, frac: F, unit: i64) -> i64 {
        sec.into() * 1_000_000_000 + frac.into() * unit
    }

    fn monotonic_ns() -> i64 {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: clock_gettime writes into the timespec we own.
        unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
        to_ns(ts.tv_sec, ts.tv_nsec, 1)
    }

    fn int_control(dev: &Device, id: u32) -> Option<i64> {
        match dev.control(id).ok()?.value {
            v4l::control::Value::Integer(v) => Some(v),
            _ => None,
        }
    }

    /// Exposure (ns) and line time (ns) when the driver exposes them.
    fn row_timing(dev: &Device, width: u32) -> (Option<f64>, Option<f64>) {
        let exposure = int_control(dev, CID_EXPOSURE_ABSOLUTE).map(|v| v as f64 * 100_000.0);
        let line = match (
            int_control(dev, CID_PIXEL_RATE),
            int_control(dev, CID_HBLANK),
        ) {
            (Some(rate), Some(hblank)) if rate > 0 => {
                Some((f64::from(width) + hblank as f64) * 1e9 / rate as f64)
            }
            _ => None,
        };
        (exposure, line)
    }

    fn open_device(path: &str) -> Result<Device, StageError> {
        let dev = Device::with_path(path).map_err(|e| device_error(path, "cannot open", &e))?;
        let caps = dev
            .query_caps()
            .map_err(|e| device_error(path, "not a V4L2 device", &e))?;
        use v4l::capability::Flags;
        if !caps.capabilities.contains(Flags::VIDEO_CAPTURE) {
            return Err(StageError::device(
                path,
                format!(
                    "{} ({}) is not a video capture node; see `vibroscope devices`",
                    caps.card, caps.driver
                ),
            ));
        }
        if !caps.capabilities.contains(Flags::STREAMING) {
            return Err(StageError::device(
                path,
                format!("{} does not support streaming I/O", caps.card),
            ));
        }
        Ok(dev)
    }

    pub(super) fn open(p: V4l2Params, pool_frames: usize) -> Result<Box<dyn Source>, StageError> {
        let path = p.device.display().to_string();
        let dev = open_device(&path)?;
        let err = |what: &str, e: io::Error| device_error(&path, what, &e);
        let offered: Vec<[u8; 4]> = dev
            .enum_formats()
            .map_err(|e| err("cannot list formats", e))?
            .iter()
            .map(|d| d.fourcc.repr)
            .collect();
        let fourcc = choose_format(&path, p.format, &offered).map_err(StageError::format)?;
        let mut want = dev.format().map_err(|e| err("cannot read the format", e))?;
        want.fourcc = FourCC::new(&fourcc);
        if let Some(w) = p.width {
            want.width = w;
        }
        if let Some(h) = p.height {
            want.height = h;
        }
        dev.set_format(&want)
            .map_err(|e| err("cannot set the format", e))?;
        // Read back what the driver granted: it rounds to sizes it supports.
        let got = dev.format().map_err(|e| err("cannot read the format", e))?;
        let Some(pixfmt) = PixelFormat::from_fourcc(got.fourcc.repr) else {
            return Err(StageError::format(format!(
                "{path}: asked for {}, the driver gave {} (offered: {})",
                fourcc_str(fourcc),
                fourcc_str(got.fourcc.repr),
                offered
                    .iter()
                    .map(|&f| fourcc_str(f))
                    .collect::<Vec<_>>()
                    .join(", ")
            )));
        };
        if got.width == 0 || got.height == 0 || got.width > 16384 || got.height > 16384 {
            return Err(StageError::format(format!(
                "{path}: the driver granted an unusable size {}x{}",
                got.width, got.height
            )));
        }
        if (p.width.is_some() && p.width != Some(got.width))
            || (p.height.is_some() && p.height != Some(got.height))
        {
            tracing::warn!(
                device = %path,
                "asked for {}x{}, the driver granted {}x{}",
                p.width.unwrap_or(want.width),
                p.height.unwrap_or(want.height),
                got.width,
                got.height
            );
        }
        // Frame rate: request, then read back the granted interval.
        if let Some(fps) = p.fps {
            // The frame interval 1/fps as a fraction of seconds.
            let frac = v4l::Fraction::new(
                1000,
                (fps * 1000.0).round().clamp(1.0, f64::from(u32::MAX)) as u32,
            );
            if let Err(e) = dev.set_params(&v4l::video::capture::Parameters::new(frac)) {
                tracing::warn!(device = %path, "cannot set the frame rate to {fps} Hz: {e}");
            }
        }
        let granted_fps = dev.params().ok().and_then(|pr| {
            let f = pr.interval;
            (f.numerator > 0 && f.denominator > 0)
                .then(|| f64::from(f.denominator) / f64::from(f.numerator))
        });
        let fps = match (granted_fps, p.fps) {
            (Some(g), Some(req)) => {
                if (g - req).abs() > 1e-3 * req {
                    tracing::warn!(device = %path, "asked for {req} fps, the driver granted {g} fps");
                }
                g
            }
            (Some(g), None) => g,
            (None, Some(req)) => req,
            (None, None) => {
                return Err(StageError::config(
                    "fps",
                    format!("{path}: the driver states no frame rate; set it"),
                ))
            }
        };
        let fps = check_fps(fps)
            .map_err(|m| StageError::format(format!("{path}: granted frame rate: {m}")))?;
        let (exposure_ns, line_ns) = row_timing(&dev, got.width);
        let row_timing = line_ns.map(|l| RowTiming {
            line_delay_ns: l,
            exposure_ns: exposure_ns.unwrap_or(0.0),
        });
        let format = FrameFormat {
            width: got.width,
            height: got.height,
            depth: vibroscope_io::Depth::U8,
            bits: 8,
            fps,
            row_timing,
        };
        tracing::info!(
            device = %path,
            fourcc = %fourcc_str(got.fourcc.repr),
            stride = got.stride,
            exposure_ns = ?exposure_ns,
            line_ns = ?line_ns,
            "negotiated {}",
            describe(&format)
        );
        let mut stream = Stream::with_buffers(&dev, Type::VideoCapture, p.buffers)
            .map_err(|e| err("cannot allocate capture buffers", e))?;
        stream.set_timeout(std::time::Duration::from_millis(STALL_MS as u64));
        Ok(Box::new(V4l2Source {
            path,
            stream: Some(stream),
            dev,
            started: false,
            pixfmt,
            width: got.width as usize,
            height: got.height as usize,
            stride: got.stride as usize,
            pool: FramePool::new(format, pool_frames),
            seqs: SeqTracker::default(),
            emitted: 0,
            t_first: None,
            duration_ns: p.duration_s.map(|d| (d * 1e9).round() as i64),
            max_frames: p.max_frames,
            total: p
                .max_frames
                .or(p.duration_s.map(|d| (d * fps).round() as u64)),
            warned_clock: false,
            clock_offset: None,
        }))
    }

    struct V4l2Source {
        path: String,
        stream: Option<Stream<'static>>,
        dev: Device,
        started: bool,
        pixfmt: PixelFormat,
        width: usize,
        height: usize,
        stride: usize,
        pool: FramePool,
        seqs: SeqTracker,
        emitted: u64,
        t_first: Option<i64>,
        duration_ns: Option<i64>,
        max_frames: Option<u64>,
        total: Option<u64>,
        warned_clock: bool,
        /// CLOCK_MONOTONIC at the run clock's zero, in ns.
        clock_offset: Option<i64>,
    }

    impl V4l2Source {
        /// Waits for a filled buffer, waking every POLL_MS to see a stop.
        /// `false` when the run is stopping.
        fn wait_ready(&self, ctx: &SourceCtx<'_>) -> Result<bool, StageError> {
            let mut waited = 0;
            loop {
                if ctx.should_stop() {
                    return Ok(false);
                }
                let n = self
                    .dev
                    .handle()
                    .poll(libc::POLLIN, POLL_MS)
                    .map_err(|e| device_error(&self.path, "capture failed", &e))?;
                if n > 0 {
                    return Ok(true);
                }
                waited += POLL_MS;
                if waited >= STALL_MS {
                    return Err(StageError::device(
                        self.path.clone(),
                        format!("no frame for {} s: the device stalled", STALL_MS / 1000),
                    ));
                }
            }
        }
    }

    impl Source for V4l2Source {
        fn next(&mut self, ctx: &SourceCtx<'_>) -> Result<Option<Item>, StageError> {
            if self.max_frames.is_some_and(|m| self.emitted >= m) {
                return Ok(None);
            }
            loop {
                // The first call queues every buffer and starts streaming
                // (bounded by the stream's timeout); later ones poll first so
                // a stop request is seen within POLL_MS.
                if self.started && !self.wait_ready(ctx)? {
                    return Ok(None);
                }
                let Some(stream) = self.stream.as_mut() else {
                    return Ok(None);
                };
                let (buf, meta) = stream
                    .next()
                    .map_err(|e| device_error(&self.path, "capture failed", &e))?;
                self.started = true;
                let (seq, gap) = self.seqs.next(meta.sequence);
                if gap > 0 {
                    ctx.count_dropped(gap);
                }
                use v4l::buffer::Flags;
                if meta.flags.contains(Flags::ERROR) {
                    // The driver says this buffer is corrupt: a dropped frame.
                    ctx.count_dropped(1);
                    continue;
                }
                let monotonic = (meta.flags.bits() & Flags::TIMESTAMP_MASK.bits())
                    == Flags::TIMESTAMP_MONOTONIC.bits();
                let t_ns = if monotonic {
                    // CLOCK_MONOTONIC minus where the run clock started on it.
                    let offset = *self
                        .clock_offset
                        .get_or_insert_with(|| monotonic_ns() - ctx.control.now_ns());
                    to_ns(meta.timestamp.sec, meta.timestamp.usec, 1000) - offset
                } else {
                    if !self.warned_clock {
                        tracing::warn!(device = %self.path, "the driver's timestamps are not on CLOCK_MONOTONIC; using the dequeue time");
                        self.warned_clock = true;
                    }
                    ctx.control.now_ns()
                };
                let t0 = *self.t_first.get_or_insert(t_ns);
                if self.duration_ns.is_some_and(|d| t_ns - t0 >= d) {
                    return Ok(None);
                }
                let used = (meta.bytesused as usize).min(buf.len());
                let Some(mut f) = ctx.acquire(&self.pool) else {
                    return Ok(None);
                };
                let PixelsMut::U8(px) = f.pixels_mut() else {
                    return Err(StageError::Internal("8-bit pool expected"));
                };
                if let Err(m) = to_gray(
                    self.pixfmt,
                    &buf[..used],
                    self.width,
                    self.height,
                    self.stride,
                    px,
                ) {
                    // One bad frame (a torn MJPEG, a short buffer) is a drop,
                    // not the end of the stream.
                    tracing::warn!(device = %self.path, seq, "{m}; frame dropped");
                    ctx.count_dropped(1);
                    continue;
                }
                *f.meta_mut() = FrameMeta { seq, t_ns };
                self.emitted += 1;
                return Ok(Some(Item::Frame(f.freeze())));
            }
        }

        fn total_hint(&self) -> Option<u64> {
            self.total
        }

        fn is_live(&self) -> bool {
            true
        }
    }

    impl Drop for V4l2Source {
        fn drop(&mut self) {
            // v4l's Stream panics in its Drop when STREAMOFF fails with anything
            // but ENODEV; stop it here and leak it instead on a failure (the
            // device is broken and the process is ending).
            // (STREAMOFF on a stream never started is a no-op that succeeds.)
            if let Some(mut s) = self.stream.take() {
                if let Err(e) = s.stop() {
                    if e.raw_os_error() != Some(libc::ENODEV) {
                        tracing::warn!(device = %self.path, "cannot stop streaming: {e}");
                        std::mem::forget(s);
                        return;
                    }
                }
                drop(s);
            }
        }
    }

    fn describe_sizes(dev: &Device, fourcc: FourCC) -> Vec<String> {
        use v4l::framesize::FrameSizeEnum;
        let Ok(sizes) = dev.enum_framesizes(fourcc) else {
            return Vec::new();
        };
        let mut out = Vec::new();
        for s in sizes {
            match s.size {
                FrameSizeEnum::Discrete(d) => {
                    let rates = describe_rates(dev, fourcc, d.width, d.height);
                    out.push(format!("{}x{}{rates}", d.width, d.height));
                }
                FrameSizeEnum::Stepwise(s) => {
                    let rates = describe_rates(dev, fourcc, s.max_width, s.max_height);
                    out.push(format!(
                        "{}x{} to {}x{} in steps of {}x{}{rates}",
                        s.min_width,
                        s.min_height,
                        s.max_width,
                        s.max_height,
                        s.step_width,
                        s.step_height
                    ));
                }
            }
        }
        out
    }

    fn describe_rates(dev: &Device, fourcc: FourCC, w: u32, h: u32) -> String {
        use v4l::frameinterval::FrameIntervalEnum;
        let Ok(ivs) = dev.enum_frameintervals(fourcc, w, h) else {
            return String::new();
        };
        let fps = |f: v4l::Fraction| {
            if f.numerator == 0 {
                "?".to_string()
            } else {
                let r = f64::from(f.denominator) / f64::from(f.numerator);
                format!("{}", (r * 1000.0).round() / 1000.0)
            }
        };
        let parts: Vec<String> = ivs
            .into_iter()
            .map(|i| match i.interval {
                FrameIntervalEnum::Discrete(f) => fps(f),
                FrameIntervalEnum::Stepwise(s) => format!("{} to {}", fps(s.max), fps(s.min)),
            })
            .collect();
        if parts.is_empty() {
            String::new()
        } else {
            format!(": {} fps", parts.join(", "))
        }
    }

    pub(super) fn list_devices() -> Result<Vec<DeviceInfo>, String> {
        let mut out = Vec::new();
        for path in video_nodes() {
            let Ok(dev) = Device::with_path(&path) else {
                continue;
            };
            let Ok(caps) = dev.query_caps() else {
                continue;
            };
            if !caps
                .capabilities
                .contains(v4l::capability::Flags::VIDEO_CAPTURE)
            {
                continue;
            }
            let formats = dev
                .enum_formats()
                .unwrap_or_default()
                .into_iter()
                .map(|d| FormatInfo {
                    fourcc: d.fourcc.repr,
                    description: d.description.clone(),
                    sizes: describe_sizes(&dev, d.fourcc),
                })
                .collect();
            let width = dev.format().map(|f| f.width).unwrap_or(0);
            let (exposure, line) = row_timing(&dev, width);
            let mut timing = Vec::new();
            if let Some(e) = exposure {
                timing.push(format!("exposure {:.1} us", e / 1e3));
            }
            if let Some(l) = line {
                timing.push(format!("line time {:.3} us (rolling shutter)", l / 1e3));
            }
            out.push(DeviceInfo {
                path,
                card: caps.card,
                driver: caps.driver,
                bus: caps.bus,
                formats,
                timing,
            });
        }
        Ok(out)
    }
}

#[cfg(not(all(target_os = "linux", feature = "v4l2")))]
mod imp {
    use super::*;

    const WHY: &str =
        "this vibroscope was built without V4L2 support (Linux, cargo feature `v4l2`)";

    pub(super) fn open(p: V4l2Params, _pool_frames: usize) -> Result<Box<dyn Source>, StageError> {
        Err(StageError::device(p.device.display().to_string(), WHY))
    }

    pub(super) fn list_devices() -> Result<Vec<DeviceInfo>, String> {
        Err(WHY.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grey_copies_rows_and_honours_stride() {
        // 3x2 image in rows of 5 bytes (2 bytes of padding each).
        let src = [1, 2, 3, 99, 99, 4, 5, 6, 99, 99];
        let mut out = [0u8; 6];
        to_gray(PixelFormat::Grey, &src, 3, 2, 5, &mut out).unwrap();
        assert_eq!(out, [1, 2, 3, 4, 5, 6]);
        // Packed (stride 0) and a short buffer.
        to_gray(PixelFormat::Grey, &[7, 8, 9, 10, 11, 12], 3, 2, 0, &mut out).unwrap();
        assert_eq!(out, [7, 8, 9, 10, 11, 12]);
        let e = to_gray(PixelFormat::Grey, &src[..7], 3, 2, 5, &mut out).unwrap_err();
        assert!(e.contains("short GREY frame"), "{e}");
    }

    #[test]
    fn yuyv_keeps_luma() {
        // 2x2: Y0 U Y1 V per pair, stride 6 (2 bytes padding).
        let src = [10, 128, 20, 128, 0, 0, 30, 1, 40, 2, 0, 0];
        let mut out = [0u8; 4];
        to_gray(PixelFormat::Yuyv, &src, 2, 2, 6, &mut out).unwrap();
        assert_eq!(out, [10, 20, 30, 40]);
        assert!(to_gray(PixelFormat::Yuyv, &src[..9], 2, 2, 6, &mut out).is_err());
    }

    #[test]
    fn mjpeg_decodes_to_luma_close_to_the_source() {
        let (w, h) = (32u16, 16u16);
        let gray: Vec<u8> = (0..w as usize * h as usize)
            .map(|i| ((i % w as usize) * 8) as u8)
            .collect();
        let mut jpeg = Vec::new();
        jpeg_encoder::Encoder::new(&mut jpeg, 95)
            .encode(&gray, w, h, jpeg_encoder::ColorType::Luma)
            .unwrap();
        let mut out = vec![0u8; gray.len()];
        to_gray(PixelFormat::Mjpeg, &jpeg, 32, 16, 0, &mut out).unwrap();
        let worst = gray
            .iter()
            .zip(&out)
            .map(|(&a, &b)| (a as i32 - b as i32).abs())
            .max()
            .unwrap();
        assert!(worst <= 6, "largest error {worst}");
        // Wrong size and garbage are errors, not panics.
        let mut small = vec![0u8; 16 * 16];
        let e = to_gray(PixelFormat::Mjpeg, &jpeg, 16, 16, 0, &mut small).unwrap_err();
        assert!(e.contains("32x16"), "{e}");
        assert!(to_gray(PixelFormat::Mjpeg, b"\xff\xd8garbage", 32, 16, 0, &mut out).is_err());
        // A torn frame must not panic (zune-jpeg may fill what is missing).
        let _ = to_gray(
            PixelFormat::Mjpeg,
            &jpeg[..jpeg.len() / 3],
            32,
            16,
            0,
            &mut out,
        );
    }

    #[test]
    fn format_choice_and_unsupported_format_message() {
        let vivid = [*b"YUYV", *b"UYVY", *b"GREY", *b"RGB3"];
        assert_eq!(
            choose_format("/dev/video0", PixelFormat::Auto, &vivid).unwrap(),
            *b"GREY"
        );
        assert_eq!(
            choose_format("/dev/video0", PixelFormat::Yuyv, &vivid).unwrap(),
            *b"YUYV"
        );
        let e = choose_format("/dev/video0", PixelFormat::Mjpeg, &vivid).unwrap_err();
        assert!(e.contains("/dev/video0") && e.contains("MJPG"), "{e}");
        assert!(
            e.contains("YUYV, UYVY, GREY, RGB3"),
            "lists what it offers: {e}"
        );
        let e = choose_format("/dev/video2", PixelFormat::Auto, &[*b"RGB3", *b"NV12"]).unwrap_err();
        assert!(e.contains("/dev/video2") && e.contains("RGB3, NV12"), "{e}");
        assert_eq!(
            choose_format("d", PixelFormat::Mjpeg, &[*b"JPEG"]).unwrap(),
            *b"JPEG"
        );
    }

    #[test]
    fn sequence_gaps_are_counted_and_wrap() {
        let mut t = SeqTracker::default();
        assert_eq!(t.next(7), (0, 0));
        assert_eq!(t.next(8), (1, 0));
        assert_eq!(t.next(11), (4, 2));
        let mut t = SeqTracker::default();
        t.next(u32::MAX - 1);
        assert_eq!(t.next(u32::MAX), (1, 0));
        assert_eq!(t.next(1), (3, 1), "wraps through 0");
        // A driver that never counts: every frame is the next one.
        let mut t = SeqTracker::default();
        t.next(0);
        assert_eq!(t.next(0), (1, 0));
    }
}
