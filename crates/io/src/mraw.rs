//! Photron `.mraw` raw frames with their `.cih` (text, `Key : Value` lines)
//! or `.cihx` (XML) header beside them.
//!
//! Frames follow each other with no framing, row-major, top row first:
//! 8-bit (one byte per pixel), 12-bit packed (two pixels in three bytes,
//! big-endian bit order: `p0 = b0<<4 | b1>>4`, `p1 = (b1&15)<<8 | b2`) or
//! 16-bit (little-endian words, as Photron's software writes them; checked
//! on real 16-bit files, whose 12 effective bits sit in the low bits).

use super::{
    check_dest, check_dimensions, display_name, io_error, read_full, Depth, FrameDest, FrameRead,
    VideoError, VideoInfo, VideoReader, MAX_HEADER_LINE,
};
use std::collections::HashMap;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

/// Largest header file accepted (real ones are about 10-20 KiB).
const MAX_HEADER_FILE: u64 = 1 << 20;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Packing {
    U8,
    Packed12,
    U16Le,
}

pub(crate) struct MrawReader {
    name: String,
    info: VideoInfo,
    src: BufReader<File>,
    packing: Packing,
    frame_bytes: u64,
    /// Frames to attempt: the whole ones, plus a partial last one (an error when reached).
    readable: u64,
    buf: Vec<u8>,
    next: u64,
    done: bool,
}

/// The header pair for `path`: (header file, mraw file).
fn pair(path: &Path) -> Result<(PathBuf, PathBuf), VideoError> {
    let name = display_name(path);
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    let sibling = |exts: &[&str]| -> Option<PathBuf> {
        exts.iter()
            .map(|e| path.with_extension(e))
            .find(|p| p.is_file())
    };
    match ext.as_str() {
        "cih" | "cihx" => {
            std::fs::metadata(path).map_err(|e| io_error(&name, e))?;
            let mraw = sibling(&["mraw", "MRAW", "Mraw"]).ok_or_else(|| VideoError::Malformed {
                path: name.clone(),
                message: format!(
                    "no raw data file beside it (looked for {})",
                    path.with_extension("mraw").display()
                ),
            })?;
            Ok((path.to_path_buf(), mraw))
        }
        _ => {
            std::fs::metadata(path).map_err(|e| io_error(&name, e))?;
            let header =
                sibling(&["cih", "CIH", "Cih", "cihx", "CIHX", "Cihx"]).ok_or_else(|| {
                    VideoError::Malformed {
                        path: name.clone(),
                        message: format!(
                            "no header file beside it (looked for {} and {})",
                            path.with_extension("cih").display(),
                            path.with_extension("cihx").display()
                        ),
                    }
                })?;
            Ok((header, path.to_path_buf()))
        }
    }
}

/// Reads a header file, refusing oversized ones.
fn read_header_file(path: &Path) -> Result<Vec<u8>, VideoError> {
    let name = display_name(path);
    let file = File::open(path).map_err(|e| io_error(&name, e))?;
    let len = file.metadata().map_err(|e| io_error(&name, e))?.len();
    if len > MAX_HEADER_FILE {
        return Err(VideoError::Header {
            path: name,
            message: format!(
                "{len} bytes is too large for a camera header (limit {MAX_HEADER_FILE})"
            ),
        });
    }
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(MAX_HEADER_FILE)
        .read_to_end(&mut bytes)
        .map_err(|e| io_error(&name, e))?;
    Ok(bytes)
}

/// Parses `.cih` text: `Key : Value` lines (the first `:` splits).
fn parse_cih(name: &str, bytes: &[u8]) -> Result<HashMap<String, String>, VideoError> {
    let mut map = HashMap::new();
    for (i, line) in bytes.split(|&b| b == b'\n').enumerate() {
        if line.len() > MAX_HEADER_LINE {
            return Err(VideoError::Header {
                path: name.to_string(),
                message: format!("line {} is longer than {MAX_HEADER_LINE} bytes", i + 1),
            });
        }
        let line = String::from_utf8_lossy(line);
        let line = line.trim();
        if line.starts_with('#') {
            continue;
        }
        if let Some((k, v)) = line.split_once(':') {
            map.entry(k.trim().to_string())
                .or_insert_with(|| v.trim().to_string());
        }
    }
    Ok(map)
}

/// The text of the first `<tag>text</tag>` in `xml`.
fn xml_value<'a>(xml: &'a str, tag: &str) -> Option<&'a str> {
    let open = format!("<{tag}>");
    let start = xml.find(&open)? + open.len();
    let end = xml[start..].find('<')? + start;
    Some(xml[start..end].trim())
}

/// Parses `.cihx` (a short binary preamble, then XML) into `.cih` key names.
fn parse_cihx(name: &str, bytes: &[u8]) -> Result<HashMap<String, String>, VideoError> {
    let text = String::from_utf8_lossy(bytes);
    let start = text.find("<cih>").ok_or_else(|| VideoError::Header {
        path: name.to_string(),
        message: "no <cih> element in the .cihx file".to_string(),
    })?;
    let xml = &text[start..];
    let mut map = HashMap::new();
    for (tag, key) in [
        ("recordRate", "Record Rate(fps)"),
        ("skipFrame", "Save Step"),
        ("totalFrame", "Total Frame"),
        ("recordedFrame", "Original Total Frame"),
        ("width", "Image Width"),
        ("height", "Image Height"),
        ("bit", "Color Bit"),
        ("depth", "EffectiveBit Depth"),
        ("side", "EffectiveBit Side"),
        ("fileFormat", "File Format"),
        ("deviceName", "Camera Type"),
        ("shutterSpeedNsec", "Shutter Speed(ns)"),
        ("date", "Date"),
        ("time", "Time"),
    ] {
        if let Some(v) = xml_value(xml, tag) {
            map.insert(key.to_string(), v.to_string());
        }
    }
    // `<type>` also appears in other elements; the colour's is inside <colorInfo>.
    if let Some(ci) = xml.find("<colorInfo>") {
        if let Some(v) = xml_value(&xml[ci..], "type") {
            map.insert("Color Type".to_string(), v.to_string());
        }
    }
    // `<shutterSpeed>N</shutterSpeed>` means 1/N s.
    if let Some(v) = xml_value(xml, "shutterSpeed") {
        map.insert("Shutter Speed(s)".to_string(), format!("1/{v}"));
    }
    Ok(map)
}

/// Parses an exposure like `1/15371` or `0.000065` (seconds).
fn parse_exposure(s: &str) -> Option<f64> {
    let v = match s.split_once('/') {
        Some((n, d)) => n.trim().parse::<f64>().ok()? / d.trim().parse::<f64>().ok()?,
        None => s.trim().parse::<f64>().ok()?,
    };
    (v.is_finite() && v > 0.0).then_some(v)
}

impl MrawReader {
    pub(crate) fn open(path: &Path) -> Result<Self, VideoError> {
        let (header_path, mraw_path) = pair(path)?;
        let hname = display_name(&header_path);
        let name = display_name(&mraw_path);
        let bytes = read_header_file(&header_path)?;
        let is_xml = header_path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("cihx"));
        let map = if is_xml {
            parse_cihx(&hname, &bytes)?
        } else {
            parse_cih(&hname, &bytes)?
        };
        let herr = |message: String| VideoError::Header {
            path: hname.clone(),
            message,
        };
        let get = |k: &str| map.get(k).map(String::as_str).filter(|v| !v.is_empty());
        let int = |k: &str| -> Result<u64, VideoError> {
            let v = get(k).ok_or_else(|| herr(format!("missing `{k}`")))?;
            v.parse::<u64>()
                .map_err(|_| herr(format!("`{k}` is {v:?}, not a whole number")))
        };
        let number = |k: &str| -> Result<Option<f64>, VideoError> {
            match get(k) {
                None => Ok(None),
                Some(v) => match v.parse::<f64>() {
                    Ok(f) if f.is_finite() && f > 0.0 => Ok(Some(f)),
                    _ => Err(herr(format!("`{k}` is {v:?}, not a positive number"))),
                },
            }
        };

        if let Some(ff) = get("File Format") {
            if !ff.eq_ignore_ascii_case("mraw") {
                return Err(VideoError::Unsupported {
                    path: hname.clone(),
                    message: format!("File Format {ff}: only MRaw files are read"),
                });
            }
        }
        let width = int("Image Width")?;
        let height = int("Image Height")?;
        let pixels = check_dimensions(&hname, width, height)?;
        let total = int("Total Frame")?;
        let bits = int("Color Bit")?;
        let mut notes = Vec::new();
        match get("Color Type") {
            Some(t) if t.eq_ignore_ascii_case("mono") => {}
            Some(t) if t.eq_ignore_ascii_case("raw") => {
                notes.push("colour type Raw: sensor values as stored, no demosaicing".to_string())
            }
            Some(t) => {
                return Err(VideoError::Unsupported {
                    path: hname.clone(),
                    message: format!("Color Type {t}: only Mono recordings are read"),
                })
            }
            None => return Err(herr("missing `Color Type`".to_string())),
        }
        let (packing, depth, frame_bytes) = match bits {
            8 => (Packing::U8, Depth::U8, pixels as u64),
            12 => {
                if pixels % 2 != 0 {
                    return Err(VideoError::Unsupported {
                        path: hname.clone(),
                        message: format!("12-bit packing of an odd pixel count ({width}x{height})"),
                    });
                }
                (Packing::Packed12, Depth::U16, pixels as u64 / 2 * 3)
            }
            16 => (Packing::U16Le, Depth::U16, pixels as u64 * 2),
            b => {
                return Err(VideoError::Unsupported {
                    path: hname.clone(),
                    message: format!("Color Bit {b}: only 8, 12 (packed) and 16 are read"),
                })
            }
        };

        let record_rate = number("Record Rate(fps)")?;
        let save_step = match get("Save Step") {
            None => 1,
            Some(_) => int("Save Step")?.max(1),
        };
        let fps = record_rate.map(|r| r / save_step as f64);
        if let Some(r) = record_rate {
            notes.push(format!("record rate {r} fps, save step {save_step}"));
        }
        let exposure_s = get("Shutter Speed(s)")
            .and_then(parse_exposure)
            .or_else(|| {
                get("Shutter Speed(ns)")
                    .and_then(|v| v.parse::<f64>().ok())
                    .filter(|v| *v > 0.0)
                    .map(|ns| ns * 1e-9)
            });
        if let Some(d) = get("EffectiveBit Depth") {
            let side = get("EffectiveBit Side")
                .map(|s| format!(" ({s} side)"))
                .unwrap_or_default();
            notes.push(format!(
                "effective bit depth {d}{side}, stored in {bits} bits"
            ));
        }
        if let Some(cam) = get("Camera Type") {
            notes.push(format!("camera: {cam}"));
        }

        let file = File::open(&mraw_path).map_err(|e| io_error(&name, e))?;
        let file_len = file.metadata().map_err(|e| io_error(&name, e))?.len();
        let whole = file_len / frame_bytes;
        let frame_count = whole.min(total);
        let mut readable = frame_count;
        if whole < total {
            notes.push(format!(
                "the raw file holds only {whole} whole frames of the {total} its header declares"
            ));
            if file_len % frame_bytes != 0 {
                readable += 1;
            }
        } else if file_len > total.saturating_mul(frame_bytes) {
            let extra = file_len - total.saturating_mul(frame_bytes);
            notes.push(format!(
                "{extra} bytes after the last declared frame are ignored"
            ));
        }
        let buf_len = frame_bytes.min(file_len) as usize;
        let info = VideoInfo {
            format_name: "mraw",
            width: width as u32,
            height: height as u32,
            depth,
            bits: bits as u8,
            frame_count: Some(frame_count),
            fps,
            has_timestamps: false,
            exposure_s,
            notes,
        };
        Ok(MrawReader {
            name,
            info,
            src: BufReader::with_capacity(64 * 1024, file),
            packing,
            frame_bytes,
            readable,
            buf: vec![0u8; buf_len],
            next: 0,
            done: false,
        })
    }

    fn next_frame(&mut self, dst: FrameDest<'_>) -> Result<Option<FrameRead>, VideoError> {
        if self.next >= self.readable {
            return Ok(None);
        }
        let got = read_full(&mut self.src, &mut self.buf).map_err(|e| io_error(&self.name, e))?;
        if (got as u64) < self.frame_bytes {
            return Err(VideoError::Truncated {
                path: self.name.clone(),
                frame: self.next,
                got: got as u64,
                expected: self.frame_bytes,
            });
        }
        match (self.packing, dst) {
            (Packing::U8, FrameDest::U8(px)) => px.copy_from_slice(&self.buf),
            (Packing::U16Le, FrameDest::U16(px)) => {
                for (d, s) in px.iter_mut().zip(self.buf.chunks_exact(2)) {
                    *d = u16::from_le_bytes([s[0], s[1]]);
                }
            }
            (Packing::Packed12, FrameDest::U16(px)) => {
                for (d, s) in px.chunks_exact_mut(2).zip(self.buf.chunks_exact(3)) {
                    let (b0, b1, b2) = (u16::from(s[0]), u16::from(s[1]), u16::from(s[2]));
                    d[0] = (b0 << 4) | (b1 >> 4);
                    d[1] = ((b1 & 0x0f) << 8) | b2;
                }
            }
            _ => {
                return Err(VideoError::Destination {
                    path: self.name.clone(),
                    message: "buffer variant does not match the video".to_string(),
                })
            }
        }
        self.next += 1;
        Ok(Some(FrameRead { timestamp_ns: None }))
    }
}

impl VideoReader for MrawReader {
    fn info(&self) -> &VideoInfo {
        &self.info
    }

    fn read_frame(&mut self, dst: FrameDest<'_>) -> Result<Option<FrameRead>, VideoError> {
        check_dest(&self.name, &self.info, &dst)?;
        if self.done {
            return Ok(None);
        }
        let r = self.next_frame(dst);
        if !matches!(r, Ok(Some(_))) {
            self.done = true;
        }
        r
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_util::{data_file, Rng};
    use super::super::{open, Format};
    use super::*;

    fn cih(w: u32, h: u32, frames: u64, bits: u32, colour: &str) -> String {
        format!(
            "#Camera Information Header\nRecord Rate(fps) : 20000\nShutter Speed(s) : 1/40000\nTotal Frame : {frames}\n\
             Save Step : 4\nImage Width : {w}\nImage Height : {h}\nColor Type : {colour}\nColor Bit : {bits}\n\
             File Format : MRaw\nEffectiveBit Depth : 12\nEffectiveBit Side : Lower\nDevice Last Error : -1:0xffffffff\n"
        )
    }

    #[test]
    fn showcase_pair() {
        let Some(cih_path) = data_file("showcase.cih") else {
            return;
        };
        let mraw_path = cih_path.with_extension("mraw");
        for p in [&cih_path, &mraw_path] {
            let mut r = open(p, Format::Auto).expect("open");
            let info = r.info().clone();
            assert_eq!(info.format_name, "mraw");
            assert_eq!(
                (info.width, info.height, info.bits, info.depth),
                (640, 40, 8, Depth::U8)
            );
            assert_eq!(info.frame_count, Some(75));
            assert_eq!(info.fps, Some(150.0));
            assert!(!info.has_timestamps);
            assert!(
                info.notes
                    .iter()
                    .any(|n| n == "record rate 15000 fps, save step 100"),
                "{:?}",
                info.notes
            );
            let e = info.exposure_s.expect("exposure");
            assert!((e - 1.0 / 15371.0).abs() < 1e-12, "{e}");
            let mut buf = vec![0u8; 640 * 40];
            let mut n = 0;
            let mut first = Vec::new();
            while r
                .read_frame(FrameDest::U8(&mut buf))
                .expect("frame")
                .is_some()
            {
                if n == 0 {
                    first = buf.clone();
                }
                n += 1;
            }
            assert_eq!(n, 75);
            let raw = std::fs::read(&mraw_path).expect("raw");
            assert_eq!(first, raw[..640 * 40]);
            assert_eq!(buf, raw[74 * 640 * 40..]);
            eprintln!("{}: {n} frames, notes {:?}", p.display(), info.notes);
        }
    }

    #[test]
    fn truncated_showcase_copy() {
        let Some(cih_path) = data_file("showcase.cih") else {
            return;
        };
        let dir = tempfile::tempdir().expect("tempdir");
        let raw = std::fs::read(cih_path.with_extension("mraw")).expect("raw");
        std::fs::copy(&cih_path, dir.path().join("cut.cih")).expect("copy");
        let frame = 640 * 40;
        std::fs::write(dir.path().join("cut.mraw"), &raw[..10 * frame + 123]).expect("write");
        let mut r = open(&dir.path().join("cut.mraw"), Format::Auto).expect("open");
        assert_eq!(r.info().frame_count, Some(10));
        assert!(
            r.info()
                .notes
                .iter()
                .any(|n| n.contains("only 10 whole frames of the 75")),
            "{:?}",
            r.info().notes
        );
        let mut buf = vec![0u8; frame];
        for _ in 0..10 {
            assert!(r
                .read_frame(FrameDest::U8(&mut buf))
                .expect("frame")
                .is_some());
        }
        let e = r
            .read_frame(FrameDest::U8(&mut buf))
            .expect_err("truncated");
        assert!(
            matches!(
                e,
                VideoError::Truncated {
                    frame: 10,
                    got: 123,
                    expected: 25600,
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(
            e.to_string()
                .contains("cut.mraw: frame 10 is truncated (got 123 of 25600 bytes)"),
            "{e}"
        );
        assert!(matches!(r.read_frame(FrameDest::U8(&mut buf)), Ok(None)));
    }

    #[test]
    fn packed_12_and_16_bit() {
        let dir = tempfile::tempdir().expect("tempdir");
        // 12-bit: pixels 0xABC, 0x123, 0xFFF, 0x001 in two frames of 2x1.
        std::fs::write(dir.path().join("p12.cih"), cih(2, 1, 2, 12, "Mono")).expect("cih");
        std::fs::write(
            dir.path().join("p12.mraw"),
            [0xAB, 0xC1, 0x23, 0xFF, 0xF0, 0x01],
        )
        .expect("mraw");
        let mut r = open(&dir.path().join("p12.cih"), Format::Auto).expect("open");
        assert_eq!((r.info().depth, r.info().bits), (Depth::U16, 12));
        assert_eq!(r.info().fps, Some(5000.0));
        let mut px = [0u16; 2];
        assert!(r.read_frame(FrameDest::U16(&mut px)).expect("0").is_some());
        assert_eq!(px, [0xABC, 0x123]);
        assert!(r.read_frame(FrameDest::U16(&mut px)).expect("1").is_some());
        assert_eq!(px, [0xFFF, 0x001]);
        assert!(r
            .read_frame(FrameDest::U16(&mut px))
            .expect("end")
            .is_none());

        std::fs::write(dir.path().join("p16.cih"), cih(2, 1, 1, 16, "Mono")).expect("cih");
        std::fs::write(dir.path().join("p16.mraw"), [0x34, 0x12, 0xFF, 0x0F]).expect("mraw");
        let mut r = open(&dir.path().join("p16.mraw"), Format::Mraw).expect("open");
        assert!(r.read_frame(FrameDest::U16(&mut px)).expect("0").is_some());
        assert_eq!(px, [0x1234, 0x0FFF]);
    }

    #[test]
    fn cihx_header() {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut x = b"!!! This file can not be edited. !!!".to_vec();
        x.extend_from_slice(&[0u8; 40]);
        x.extend_from_slice(
            b"<cih><fileInfo><date>2017/7/13</date><fileFormat>Mraw</fileFormat></fileInfo>\
              <imageDataInfo><resolution><width>4</width><height>2</height></resolution>\
              <colorInfo><type>Mono</type><bit>8</bit></colorInfo><effectiveBit><depth>8</depth><side>Lower</side></effectiveBit></imageDataInfo>\
              <frameInfo><recordedFrame>400</recordedFrame><totalFrame>3</totalFrame><skipFrame>2500</skipFrame></frameInfo>\
              <recordInfo><recordRate>50000</recordRate><shutterSpeed>200000</shutterSpeed><shutterSpeedNsec>5000</shutterSpeedNsec></recordInfo>\
              <timeCode><type>0</type></timeCode></cih>",
        );
        std::fs::write(dir.path().join("b.cihx"), &x).expect("cihx");
        std::fs::write(dir.path().join("b.mraw"), [7u8; 24]).expect("mraw");
        let mut r = open(&dir.path().join("b.mraw"), Format::Auto).expect("open");
        let info = r.info().clone();
        assert_eq!(
            (info.width, info.height, info.frame_count, info.fps),
            (4, 2, Some(3), Some(20.0))
        );
        assert_eq!(info.exposure_s, Some(1.0 / 200000.0));
        let mut px = [0u8; 8];
        let mut n = 0;
        while r
            .read_frame(FrameDest::U8(&mut px))
            .expect("frame")
            .is_some()
        {
            n += 1;
        }
        assert_eq!(n, 3);
    }

    #[test]
    fn header_errors() {
        let dir = tempfile::tempdir().expect("tempdir");
        let d = dir.path();
        std::fs::write(d.join("c.cih"), cih(4, 4, 1, 8, "Color")).expect("cih");
        std::fs::write(d.join("c.mraw"), [0u8; 16]).expect("mraw");
        let e = open(&d.join("c.cih"), Format::Auto).err().expect("colour");
        assert!(e.to_string().contains("Color Type Color: only Mono"), "{e}");

        std::fs::write(d.join("b.cih"), cih(4, 4, 1, 10, "Mono")).expect("cih");
        std::fs::write(d.join("b.mraw"), [0u8; 16]).expect("mraw");
        let e = open(&d.join("b.cih"), Format::Auto).err().expect("bits");
        assert!(e.to_string().contains("Color Bit 10"), "{e}");

        std::fs::write(d.join("m.cih"), "Image Width : 4\nColor Type : Mono\n").expect("cih");
        std::fs::write(d.join("m.mraw"), [0u8; 16]).expect("mraw");
        let e = open(&d.join("m.cih"), Format::Auto).err().expect("missing");
        assert!(
            e.to_string()
                .contains("m.cih: header: missing `Image Height`"),
            "{e}"
        );

        std::fs::write(d.join("lonely.mraw"), [0u8; 16]).expect("mraw");
        let e = open(&d.join("lonely.mraw"), Format::Auto)
            .err()
            .expect("no header");
        assert!(e.to_string().contains("no header file beside it"), "{e}");

        std::fs::write(d.join("alone.cih"), cih(4, 4, 1, 8, "Mono")).expect("cih");
        let e = open(&d.join("alone.cih"), Format::Auto)
            .err()
            .expect("no raw");
        assert!(e.to_string().contains("no raw data file beside it"), "{e}");

        std::fs::write(d.join("long.cih"), vec![b'x'; 5000]).expect("cih");
        std::fs::write(d.join("long.mraw"), [0u8; 16]).expect("mraw");
        let e = open(&d.join("long.cih"), Format::Auto)
            .err()
            .expect("long line");
        assert!(e.to_string().contains("longer than 4096"), "{e}");
    }

    #[test]
    fn garbage_headers_never_panic() {
        let dir = tempfile::tempdir().expect("tempdir");
        let good = cih(6, 2, 3, 12, "Mono").into_bytes();
        std::fs::write(dir.path().join("g.mraw"), [0x55u8; 40]).expect("mraw");
        let mut rng = Rng(99);
        for i in 0..400 {
            let bytes: Vec<u8> = match i % 3 {
                0 => good[..rng.below(good.len() as u64 + 1) as usize].to_vec(),
                1 => {
                    let mut b = good.clone();
                    for _ in 0..1 + rng.below(5) {
                        let at = rng.below(b.len() as u64) as usize;
                        b[at] = b"0123456789:\n x/"[rng.below(15) as usize];
                    }
                    b
                }
                _ => (0..rng.below(300)).map(|_| rng.next() as u8).collect(),
            };
            let ext = if i % 2 == 0 { "cih" } else { "cihx" };
            let _ = std::fs::remove_file(dir.path().join("g.cih"));
            let _ = std::fs::remove_file(dir.path().join("g.cihx"));
            std::fs::write(dir.path().join(format!("g.{ext}")), &bytes).expect("write");
            if let Ok(mut r) = open(&dir.path().join("g.mraw"), Format::Auto) {
                let n = (r.info().width * r.info().height) as usize;
                for _ in 0..5 {
                    let res = match r.info().depth {
                        Depth::U8 => r.read_frame(FrameDest::U8(&mut vec![0u8; n])),
                        Depth::U16 => r.read_frame(FrameDest::U16(&mut vec![0u16; n])),
                    };
                    if !matches!(res, Ok(Some(_))) {
                        break;
                    }
                }
            }
        }
    }
}
