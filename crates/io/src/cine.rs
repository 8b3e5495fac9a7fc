//! Phantom `.cine` files (Vision Research), little-endian.
//!
//! Layout: CINEFILEHEADER at 0 (`"CI"`, image count and the offsets of the
//! other parts), BITMAPINFOHEADER (size and pixel format), SETUP (camera
//! settings: frame rate, exposure, bit depth), tagged information blocks
//! (per-image times and exposures), the table of image offsets (one `i64`
//! per image), and the images, each an annotation (`u32` size including
//! itself, then data) followed by its pixels.
//!
//! Pixels: 8-bit, 16-bit little-endian, or Phantom's packed 10-bit
//! (`biCompression` 256: four pixels in five bytes, most significant bit
//! first), whose codes are mapped to 12-bit linear values through the table
//! published in the cine file format specification. Uncompressed images
//! with a positive `biHeight` are stored bottom-up and are flipped; packed
//! images are stored top-down (both checked against the vendor's own TIFF
//! exports of the same frames).

use super::{
    check_dest, check_dimensions, display_name, io_error, read_full, Depth, FrameDest, FrameRead,
    VideoError, VideoInfo, VideoReader,
};
use std::fs::File;
use std::io::{Seek, SeekFrom};
use std::path::Path;

const FILE_HEADER_LEN: u64 = 44;
const BITMAP_HEADER_LEN: u64 = 40;
const BI_RGB: u32 = 0;
const BI_PACKED: u32 = 256;
const BI_PACKED_12L: u32 = 1024;
/// Tagged block holding one TIME64 (u32 fractions of 2^-32 s, u32 seconds) per image.
const TIME_ONLY_BLOCK: u16 = 1002;
/// Tagged block holding one exposure (u32 fractions of 2^-32 s) per image.
const EXPOSURE_ONLY_BLOCK: u16 = 1003;
/// Most tagged blocks looked at (real files have a handful).
const MAX_BLOCKS: usize = 256;

/// Byte offsets of the SETUP fields used (the structure is packed, 1-byte aligned).
mod setup {
    pub const FRAME_RATE16: usize = 0;
    pub const SHUTTER16_US: usize = 2;
    pub const MARK: usize = 140;
    pub const LENGTH: usize = 142;
    pub const FLIP_V: usize = 760;
    pub const FRAME_RATE: usize = 768;
    pub const SHUTTER_US: usize = 772;
    pub const CAMERA_VERSION: usize = 792;
    pub const SOFTWARE_VERSION: usize = 800;
    pub const CFA: usize = 808;
    pub const REAL_BPP: usize = 896;
    pub const SHUTTER_NS: usize = 1568;
}

/// Phantom's mapping of packed 10-bit codes to 12-bit linear values
/// ("LinLUT", Appendix 1 of the Vision Research cine file format
/// specification).
#[rustfmt::skip]
static LIN_LUT: [u16; 1024] = [
    2, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 17, 18,
    19, 20, 21, 22, 23, 24, 25, 26, 27, 28, 29, 30, 31, 32, 33, 33,
    34, 35, 36, 37, 38, 39, 40, 41, 42, 43, 44, 45, 46, 47, 48, 48,
    49, 50, 51, 52, 53, 54, 55, 56, 57, 58, 59, 60, 61, 62, 63, 63,
    64, 65, 66, 67, 68, 69, 70, 71, 72, 73, 74, 75, 76, 77, 78, 79,
    79, 80, 81, 82, 83, 84, 85, 86, 87, 88, 89, 90, 91, 92, 93, 94,
    94, 95, 96, 97, 98, 99, 100, 101, 102, 103, 104, 105, 106, 107, 108, 109,
    110, 110, 111, 112, 113, 114, 115, 116, 117, 118, 119, 120, 121, 122, 123, 124,
    125, 125, 126, 127, 128, 129, 130, 131, 132, 133, 134, 135, 136, 137, 137, 138,
    139, 140, 141, 142, 143, 144, 145, 146, 147, 148, 149, 150, 151, 152, 153, 154,
    156, 157, 158, 159, 160, 161, 162, 163, 164, 165, 167, 168, 169, 170, 171, 172,
    173, 175, 176, 177, 178, 179, 181, 182, 183, 184, 186, 187, 188, 189, 191, 192,
    193, 194, 196, 197, 198, 200, 201, 202, 204, 205, 206, 208, 209, 210, 212, 213,
    215, 216, 217, 219, 220, 222, 223, 225, 226, 227, 229, 230, 232, 233, 235, 236,
    238, 239, 241, 242, 244, 245, 247, 249, 250, 252, 253, 255, 257, 258, 260, 261,
    263, 265, 266, 268, 270, 271, 273, 275, 276, 278, 280, 281, 283, 285, 287, 288,
    290, 292, 294, 295, 297, 299, 301, 302, 304, 306, 308, 310, 312, 313, 315, 317,
    319, 321, 323, 325, 327, 328, 330, 332, 334, 336, 338, 340, 342, 344, 346, 348,
    350, 352, 354, 356, 358, 360, 362, 364, 366, 368, 370, 372, 374, 377, 379, 381,
    383, 385, 387, 389, 391, 394, 396, 398, 400, 402, 404, 407, 409, 411, 413, 416,
    418, 420, 422, 425, 427, 429, 431, 434, 436, 438, 441, 443, 445, 448, 450, 452,
    455, 457, 459, 462, 464, 467, 469, 472, 474, 476, 479, 481, 484, 486, 489, 491,
    494, 496, 499, 501, 504, 506, 509, 511, 514, 517, 519, 522, 524, 527, 529, 532,
    535, 537, 540, 543, 545, 548, 551, 553, 556, 559, 561, 564, 567, 570, 572, 575,
    578, 581, 583, 586, 589, 592, 594, 597, 600, 603, 606, 609, 611, 614, 617, 620,
    623, 626, 629, 632, 635, 637, 640, 643, 646, 649, 652, 655, 658, 661, 664, 667,
    670, 673, 676, 679, 682, 685, 688, 691, 694, 698, 701, 704, 707, 710, 713, 716,
    719, 722, 726, 729, 732, 735, 738, 742, 745, 748, 751, 754, 758, 761, 764, 767,
    771, 774, 777, 781, 784, 787, 790, 794, 797, 800, 804, 807, 811, 814, 817, 821,
    824, 828, 831, 834, 838, 841, 845, 848, 852, 855, 859, 862, 866, 869, 873, 876,
    880, 883, 887, 890, 894, 898, 901, 905, 908, 912, 916, 919, 923, 927, 930, 934,
    938, 941, 945, 949, 952, 956, 960, 964, 967, 971, 975, 979, 982, 986, 990, 994,
    998, 1001, 1005, 1009, 1013, 1017, 1021, 1025, 1028, 1032, 1036, 1040, 1044, 1048, 1052, 1056,
    1060, 1064, 1068, 1072, 1076, 1080, 1084, 1088, 1092, 1096, 1100, 1104, 1108, 1112, 1116, 1120,
    1124, 1128, 1132, 1137, 1141, 1145, 1149, 1153, 1157, 1162, 1166, 1170, 1174, 1178, 1183, 1187,
    1191, 1195, 1200, 1204, 1208, 1212, 1217, 1221, 1225, 1230, 1234, 1238, 1243, 1247, 1251, 1256,
    1260, 1264, 1269, 1273, 1278, 1282, 1287, 1291, 1295, 1300, 1304, 1309, 1313, 1318, 1322, 1327,
    1331, 1336, 1340, 1345, 1350, 1354, 1359, 1363, 1368, 1372, 1377, 1382, 1386, 1391, 1396, 1400,
    1405, 1410, 1414, 1419, 1424, 1428, 1433, 1438, 1443, 1447, 1452, 1457, 1462, 1466, 1471, 1476,
    1481, 1486, 1490, 1495, 1500, 1505, 1510, 1515, 1520, 1524, 1529, 1534, 1539, 1544, 1549, 1554,
    1559, 1564, 1569, 1574, 1579, 1584, 1589, 1594, 1599, 1604, 1609, 1614, 1619, 1624, 1629, 1634,
    1639, 1644, 1649, 1655, 1660, 1665, 1670, 1675, 1680, 1685, 1691, 1696, 1701, 1706, 1711, 1717,
    1722, 1727, 1732, 1738, 1743, 1748, 1753, 1759, 1764, 1769, 1775, 1780, 1785, 1791, 1796, 1801,
    1807, 1812, 1818, 1823, 1828, 1834, 1839, 1845, 1850, 1856, 1861, 1867, 1872, 1878, 1883, 1889,
    1894, 1900, 1905, 1911, 1916, 1922, 1927, 1933, 1939, 1944, 1950, 1956, 1961, 1967, 1972, 1978,
    1984, 1989, 1995, 2001, 2007, 2012, 2018, 2024, 2030, 2035, 2041, 2047, 2053, 2058, 2064, 2070,
    2076, 2082, 2087, 2093, 2099, 2105, 2111, 2117, 2123, 2129, 2135, 2140, 2146, 2152, 2158, 2164,
    2170, 2176, 2182, 2188, 2194, 2200, 2206, 2212, 2218, 2224, 2231, 2237, 2243, 2249, 2255, 2261,
    2267, 2273, 2279, 2286, 2292, 2298, 2304, 2310, 2317, 2323, 2329, 2335, 2341, 2348, 2354, 2360,
    2366, 2373, 2379, 2385, 2392, 2398, 2404, 2411, 2417, 2423, 2430, 2436, 2443, 2449, 2455, 2462,
    2468, 2475, 2481, 2488, 2494, 2501, 2507, 2514, 2520, 2527, 2533, 2540, 2546, 2553, 2559, 2566,
    2572, 2579, 2586, 2592, 2599, 2605, 2612, 2619, 2625, 2632, 2639, 2645, 2652, 2659, 2666, 2672,
    2679, 2686, 2693, 2699, 2706, 2713, 2720, 2726, 2733, 2740, 2747, 2754, 2761, 2767, 2774, 2781,
    2788, 2795, 2802, 2809, 2816, 2823, 2830, 2837, 2844, 2850, 2857, 2864, 2871, 2878, 2885, 2893,
    2900, 2907, 2914, 2921, 2928, 2935, 2942, 2949, 2956, 2963, 2970, 2978, 2985, 2992, 2999, 3006,
    3013, 3021, 3028, 3035, 3042, 3049, 3057, 3064, 3071, 3078, 3086, 3093, 3100, 3108, 3115, 3122,
    3130, 3137, 3144, 3152, 3159, 3166, 3174, 3181, 3189, 3196, 3204, 3211, 3218, 3226, 3233, 3241,
    3248, 3256, 3263, 3271, 3278, 3286, 3294, 3301, 3309, 3316, 3324, 3331, 3339, 3347, 3354, 3362,
    3370, 3377, 3385, 3393, 3400, 3408, 3416, 3423, 3431, 3439, 3447, 3454, 3462, 3470, 3478, 3486,
    3493, 3501, 3509, 3517, 3525, 3533, 3540, 3548, 3556, 3564, 3572, 3580, 3588, 3596, 3604, 3612,
    3620, 3628, 3636, 3644, 3652, 3660, 3668, 3676, 3684, 3692, 3700, 3708, 3716, 3724, 3732, 3740,
    3749, 3757, 3765, 3773, 3781, 3789, 3798, 3806, 3814, 3822, 3830, 3839, 3847, 3855, 3863, 3872,
    3880, 3888, 3897, 3905, 3913, 3922, 3930, 3938, 3947, 3955, 3963, 3972, 3980, 3989, 3997, 4006,
    4014, 4022, 4031, 4039, 4048, 4056, 4064, 4095, 4095, 4095, 4095, 4095, 4095, 4095, 4095, 4095,
];

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Pixels {
    U8,
    U16Le,
    Packed10,
}

fn u16_at(b: &[u8], off: usize) -> Option<u16> {
    Some(u16::from_le_bytes(b.get(off..off + 2)?.try_into().ok()?))
}

fn u32_at(b: &[u8], off: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(off..off + 4)?.try_into().ok()?))
}

fn i32_at(b: &[u8], off: usize) -> Option<i32> {
    Some(i32::from_le_bytes(b.get(off..off + 4)?.try_into().ok()?))
}

fn i64_at(b: &[u8], off: usize) -> Option<i64> {
    Some(i64::from_le_bytes(b.get(off..off + 8)?.try_into().ok()?))
}

pub(crate) struct CineReader {
    name: String,
    info: VideoInfo,
    file: File,
    file_len: u64,
    width: usize,
    height: usize,
    pixels: Pixels,
    /// Bytes from one row to the next (uncompressed images).
    stride: usize,
    /// Bytes of pixel data read per image.
    image_bytes: usize,
    flip: bool,
    offsets: Vec<i64>,
    timestamps: Option<Vec<Option<i64>>>,
    /// Images to attempt: the whole ones, plus a cut-off one (an error when reached).
    readable: usize,
    buf: Vec<u8>,
    next: usize,
    done: bool,
}

/// Reads `len` bytes at `off`, which the caller has checked lie within the file.
fn read_at(file: &mut File, name: &str, off: u64, len: usize) -> Result<Vec<u8>, VideoError> {
    file.seek(SeekFrom::Start(off))
        .map_err(|e| io_error(name, e))?;
    let mut buf = vec![0u8; len];
    let got = read_full(file, &mut buf).map_err(|e| io_error(name, e))?;
    if got < len {
        return Err(VideoError::Malformed {
            path: name.to_string(),
            message: format!("the file ended early reading {len} bytes at offset {off}"),
        });
    }
    Ok(buf)
}

/// Frame rate, exposure and notes from the SETUP structure.
struct SetupFacts {
    fps: Option<f64>,
    exposure_s: Option<f64>,
    /// Where the tagged blocks may start (the end of SETUP).
    end: Option<u64>,
}

fn read_setup(
    file: &mut File,
    name: &str,
    off: u64,
    file_len: u64,
    notes: &mut Vec<String>,
) -> Result<SetupFacts, VideoError> {
    let mut facts = SetupFacts {
        fps: None,
        exposure_s: None,
        end: None,
    };
    if off.saturating_add(setup::LENGTH as u64 + 2) > file_len {
        notes.push(format!(
            "no camera setup (offset {off} is beyond the file); frame rate unknown"
        ));
        return Ok(facts);
    }
    let head = read_at(file, name, off, setup::LENGTH + 2)?;
    let modern = head.get(setup::MARK..setup::MARK + 2) == Some(b"ST".as_slice());
    let declared = if modern {
        usize::from(u16_at(&head, setup::LENGTH).unwrap_or(0))
    } else {
        setup::LENGTH + 2
    };
    let len = declared.min((file_len - off) as usize).max(head.len());
    let s = read_at(file, name, off, len)?;
    if modern {
        facts.end = Some(off + declared as u64);
    }
    // A field counts only if the SETUP version that wrote the file has it.
    let field = |at: usize| {
        if modern && at + 4 <= declared {
            u32_at(&s, at)
        } else {
            None
        }
    };
    let fr32 = field(setup::FRAME_RATE).filter(|&v| v > 0);
    let fr16 = u16_at(&s, setup::FRAME_RATE16).filter(|&v| v > 0);
    facts.fps = fr32.map(f64::from).or(fr16.map(f64::from));
    match (fr32, fr16) {
        (Some(f), _) => notes.push(format!("frame rate {f} fps (SETUP.FrameRate)")),
        (None, Some(f)) => notes.push(format!("frame rate {f} fps (SETUP.FrameRate16)")),
        (None, None) => notes.push("the setup states no frame rate".to_string()),
    }
    let ns = field(setup::SHUTTER_NS).filter(|&v| v > 0);
    let us = field(setup::SHUTTER_US).filter(|&v| v > 0);
    let us16 = u16_at(&s, setup::SHUTTER16_US).filter(|&v| v > 0);
    facts.exposure_s = match (ns, us, us16) {
        (Some(ns), _, _) => {
            notes.push(format!(
                "exposure {} us (SETUP.ShutterNs {ns} ns)",
                f64::from(ns) / 1000.0
            ));
            Some(f64::from(ns) / 1e9)
        }
        (None, Some(us), _) => Some(f64::from(us) / 1e6),
        (None, None, Some(us)) => Some(f64::from(us) / 1e6),
        _ => None,
    };
    if let Some(bpp) = field(setup::REAL_BPP).filter(|&v| v > 0) {
        notes.push(format!("sensor bit depth {bpp} (SETUP.RealBPP)"));
    }
    if let (Some(cam), Some(sw)) = (field(setup::CAMERA_VERSION), field(setup::SOFTWARE_VERSION)) {
        notes.push(format!(
            "Phantom camera version {cam}, software version {sw}"
        ));
    }
    if let Some(cfa) = field(setup::CFA).filter(|&v| v & 0xff != 0) {
        notes.push(format!(
            "colour filter array code {cfa}: values are raw sensor levels, not demosaiced"
        ));
    }
    if field(setup::FLIP_V).is_some_and(|v| v != 0) {
        notes.push(
            "the setup asks for a vertical flip on display (bFlipV); frames are as stored"
                .to_string(),
        );
    }
    Ok(facts)
}

/// Per-image timestamps relative to the first image, with implausible
/// entries (going backwards, or jumping by over 1000 frame intervals) set
/// to None. Returns None when most entries are implausible.
fn relative_times(raw: &[(u32, u32)], notes: &mut Vec<String>) -> Option<Vec<Option<i64>>> {
    let abs: Vec<i128> = raw
        .iter()
        .map(|&(frac, sec)| {
            i128::from(sec) * 1_000_000_000 + ((i128::from(frac) * 1_000_000_000) >> 32)
        })
        .collect();
    let first = *abs.first()?;
    let mut deltas: Vec<i128> = abs
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|&d| d > 0)
        .collect();
    deltas.sort_unstable();
    let median = deltas.get(deltas.len() / 2).copied();
    let limit = median.map_or(i128::MAX, |m| m.saturating_mul(1000));
    let mut out = Vec::with_capacity(abs.len());
    out.push(Some(0));
    let mut last = first;
    let mut bad = Vec::new();
    for (i, &t) in abs.iter().enumerate().skip(1) {
        let d = t - last;
        if d <= 0 || d > limit {
            out.push(None);
            bad.push((i, d));
        } else {
            out.push(i64::try_from(t - first).ok());
            last = t;
        }
    }
    if let Some(m) = median {
        notes.push(format!(
            "time block: median frame interval {:.3} us ({:.3} fps)",
            m as f64 / 1000.0,
            1e9 / m as f64
        ));
    }
    if bad.len() * 2 > abs.len() {
        notes.push(format!(
            "time block: {} of {} image times are inconsistent; ignored",
            bad.len(),
            abs.len()
        ));
        return None;
    }
    if let Some(&(i, d)) = bad.first() {
        notes.push(format!(
            "time block: {} of {} image times are implausible (image {i} jumps {:+.6} s); those frames carry no timestamp",
            bad.len(),
            abs.len(),
            d as f64 / 1e9
        ));
    }
    Some(out)
}

impl CineReader {
    pub(crate) fn open(path: &Path) -> Result<Self, VideoError> {
        let name = display_name(path);
        let mut file = File::open(path).map_err(|e| io_error(&name, e))?;
        let file_len = file.metadata().map_err(|e| io_error(&name, e))?.len();
        let malformed = |message: String| VideoError::Malformed {
            path: name.clone(),
            message,
        };
        let unsupported = |message: String| VideoError::Unsupported {
            path: name.clone(),
            message,
        };

        let h = read_at(&mut file, &name, 0, file_len.min(FILE_HEADER_LEN) as usize)?;
        if h.get(0..2) != Some(b"CI".as_slice()) {
            let magic = match u16_at(&h, 0) {
                Some(m) => format!("0x{m:04x}"),
                None => format!("{} bytes", h.len()),
            };
            return Err(malformed(format!(
                "not a Phantom cine file (magic {magic}, expected \"CI\")"
            )));
        }
        if (h.len() as u64) < FILE_HEADER_LEN {
            return Err(malformed(format!(
                "{file_len} bytes is too short for a cine file header"
            )));
        }
        let field32 = |off: usize| u32_at(&h, off).unwrap_or(0);
        let compression = u16_at(&h, 4).unwrap_or(0);
        let first_image_no = i32_at(&h, 16).unwrap_or(0);
        let image_count = field32(20);
        let off_image_header = u64::from(field32(24));
        let off_setup = u64::from(field32(28));
        let off_image_offsets = u64::from(field32(32));
        let mut notes = Vec::new();
        match compression {
            0 => {}
            1 => {
                return Err(unsupported(
                    "JPEG-compressed cine (Compression 1)".to_string(),
                ))
            }
            2 => {
                notes.push("uninterpolated sensor data (Compression 2): not demosaiced".to_string())
            }
            c => return Err(unsupported(format!("cine Compression {c}"))),
        }

        // BITMAPINFOHEADER: size and pixel format.
        if off_image_header.saturating_add(BITMAP_HEADER_LEN) > file_len {
            return Err(malformed(format!(
                "the bitmap header at offset {off_image_header} lies beyond the end of the file ({file_len} bytes)"
            )));
        }
        let bi = read_at(
            &mut file,
            &name,
            off_image_header,
            BITMAP_HEADER_LEN as usize,
        )?;
        let bi_width = i32_at(&bi, 4).unwrap_or(0);
        let bi_height = i32_at(&bi, 8).unwrap_or(0);
        let bit_count = u16_at(&bi, 14).unwrap_or(0);
        let bi_compression = u32_at(&bi, 16).unwrap_or(0);
        let size_image = u64::from(u32_at(&bi, 20).unwrap_or(0));
        if bi_width <= 0 || bi_height == 0 {
            return Err(VideoError::Header {
                path: name.clone(),
                message: format!("image size {bi_width}x{bi_height} is invalid"),
            });
        }
        let width = u64::from(bi_width.unsigned_abs());
        let height = u64::from(bi_height.unsigned_abs());
        let n = check_dimensions(&name, width, height)? as u64;
        let (pixels, depth) = match (bi_compression, bit_count) {
            (BI_RGB, 8) => (Pixels::U8, Depth::U8),
            (BI_RGB, 16) => (Pixels::U16Le, Depth::U16),
            (BI_RGB, 24 | 48) => {
                return Err(unsupported(format!(
                    "colour cine ({bit_count}-bit BGR); record in grey"
                )))
            }
            (BI_RGB, b) => return Err(unsupported(format!("{b} bits per pixel"))),
            (BI_PACKED, _) => (Pixels::Packed10, Depth::U16),
            (BI_PACKED_12L, _) => {
                return Err(unsupported(
                    "packed 12-bit images (biCompression 1024)".to_string(),
                ))
            }
            (c, _) => return Err(unsupported(format!("biCompression {c}"))),
        };
        let row = width * if pixels == Pixels::U16Le { 2 } else { 1 };
        let (stride, image_bytes) = match pixels {
            Pixels::Packed10 => (0, (n * 10).div_ceil(8)),
            _ => {
                let padded = row.next_multiple_of(4);
                if padded != row && size_image == padded * height {
                    (padded, padded * height)
                } else {
                    (row, row * height)
                }
            }
        };
        if size_image != 0 && size_image < image_bytes {
            return Err(malformed(format!(
                "biSizeImage {size_image} is smaller than a {width}x{height} image needs ({image_bytes} bytes)"
            )));
        }
        if image_bytes > file_len {
            return Err(malformed(format!(
                "one {width}x{height} image ({image_bytes} bytes) is larger than the whole file ({file_len} bytes)"
            )));
        }
        let flip = pixels != Pixels::Packed10 && bi_height > 0;
        match pixels {
            Pixels::Packed10 => notes.push(
                "pixels: Phantom packed 10-bit (biCompression 256), mapped to 12-bit linear (0..4095) by the cine format's LinLUT"
                    .to_string(),
            ),
            Pixels::U16Le => notes.push("pixels: 16-bit little-endian".to_string()),
            Pixels::U8 => notes.push("pixels: 8-bit".to_string()),
        }
        if flip {
            notes
                .push("rows are stored bottom-up; frames are flipped to top row first".to_string());
        }

        // Image offsets.
        let count = image_count as usize;
        let table_end = off_image_offsets.saturating_add(8 * u64::from(image_count));
        if table_end > file_len {
            return Err(malformed(format!(
                "the table of {image_count} image offsets at {off_image_offsets} runs past the end of the file ({file_len} bytes)"
            )));
        }
        let table = read_at(&mut file, &name, off_image_offsets, count * 8)?;
        let offsets: Vec<i64> = table
            .chunks_exact(8)
            .map(|c| i64_at(c, 0).unwrap_or(-1))
            .collect();
        let whole = offsets
            .iter()
            .position(|&o| {
                u64::try_from(o).map_or(true, |o| {
                    o.saturating_add(8).saturating_add(image_bytes) > file_len
                })
            })
            .unwrap_or(count);
        let readable = if whole < count {
            notes.push(format!(
                "the file is cut short: {whole} of its {count} images are complete (image {whole} is beyond the end)"
            ));
            whole + 1
        } else {
            count
        };
        if first_image_no != 0 {
            notes.push(format!(
                "the first image is number {first_image_no} relative to the trigger"
            ));
        }

        // SETUP, then the tagged blocks (between SETUP and the offset table,
        // or else after the offset table).
        let facts = read_setup(&mut file, &name, off_setup, file_len, &mut notes)?;
        let first_image = offsets
            .iter()
            .filter_map(|&o| u64::try_from(o).ok())
            .min()
            .unwrap_or(file_len)
            .min(file_len);
        let mut regions = Vec::new();
        if let Some(end) = facts.end.filter(|&e| e <= off_image_offsets) {
            regions.push((end, off_image_offsets));
        }
        regions.push((table_end, first_image));
        let mut timestamps = None;
        for (start, end) in regions {
            if let Some(t) = Self::tagged_blocks(&mut file, &name, start, end, count, &mut notes)? {
                timestamps = Some(t);
                break;
            }
        }

        let info = VideoInfo {
            format_name: "cine",
            width: width as u32,
            height: height as u32,
            depth,
            bits: bit_count.min(255) as u8,
            frame_count: Some(whole as u64),
            fps: facts.fps,
            has_timestamps: timestamps.is_some(),
            exposure_s: facts.exposure_s,
            notes,
        };
        Ok(CineReader {
            name,
            info,
            file,
            file_len,
            width: width as usize,
            height: height as usize,
            pixels,
            stride: stride as usize,
            image_bytes: image_bytes as usize,
            flip,
            offsets,
            timestamps,
            readable,
            buf: vec![0u8; image_bytes as usize],
            next: 0,
            done: false,
        })
    }

    /// Looks through the tagged blocks in `start..end` for image times (and exposures).
    fn tagged_blocks(
        file: &mut File,
        name: &str,
        start: u64,
        end: u64,
        count: usize,
        notes: &mut Vec<String>,
    ) -> Result<Option<Vec<Option<i64>>>, VideoError> {
        let mut pos = start;
        let mut times = None;
        for _ in 0..MAX_BLOCKS {
            if pos.saturating_add(8) > end || count == 0 {
                break;
            }
            let head = read_at(file, name, pos, 8)?;
            let size = u64::from(u32_at(&head, 0).unwrap_or(0));
            let kind = u16_at(&head, 4).unwrap_or(0);
            if size < 8 || pos + size > end {
                break;
            }
            let data_len = size - 8;
            match kind {
                TIME_ONLY_BLOCK if times.is_none() => {
                    if data_len < 8 * count as u64 {
                        notes.push(format!(
                            "time block too short ({data_len} bytes for {count} images); ignored"
                        ));
                    } else {
                        let data = read_at(file, name, pos + 8, 8 * count)?;
                        let raw: Vec<(u32, u32)> = data
                            .chunks_exact(8)
                            .map(|c| (u32_at(c, 0).unwrap_or(0), u32_at(c, 4).unwrap_or(0)))
                            .collect();
                        times = Some(relative_times(&raw, notes));
                    }
                }
                EXPOSURE_ONLY_BLOCK if data_len >= 4 => {
                    let data = read_at(file, name, pos + 8, 4)?;
                    let e = f64::from(u32_at(&data, 0).unwrap_or(0)) / 4_294_967_296.0;
                    notes.push(format!(
                        "exposure block: first image exposed {:.3} us",
                        e * 1e6
                    ));
                }
                _ => {}
            }
            pos += size;
        }
        Ok(times.flatten())
    }

    fn next_frame(&mut self, dst: FrameDest<'_>) -> Result<Option<FrameRead>, VideoError> {
        let i = self.next;
        if i >= self.readable {
            return Ok(None);
        }
        let frame = i as u64;
        let expected = self.image_bytes as u64;
        let truncated = |name: &str, got: u64| VideoError::Truncated {
            path: name.to_string(),
            frame,
            got,
            expected,
        };
        let off = u64::try_from(self.offsets[i]).map_err(|_| VideoError::BadFrame {
            path: self.name.clone(),
            frame,
            message: format!("image offset {} is negative", self.offsets[i]),
        })?;
        if off.saturating_add(4) > self.file_len {
            return Err(truncated(&self.name, 0));
        }
        self.file
            .seek(SeekFrom::Start(off))
            .map_err(|e| io_error(&self.name, e))?;
        let mut ann = [0u8; 4];
        if read_full(&mut self.file, &mut ann).map_err(|e| io_error(&self.name, e))? < 4 {
            return Err(truncated(&self.name, 0));
        }
        let ann = u64::from(u32::from_le_bytes(ann));
        if ann < 8 {
            return Err(VideoError::BadFrame {
                path: self.name.clone(),
                frame,
                message: format!("annotation size {ann} is below the minimum of 8"),
            });
        }
        let start = off + ann;
        if start > self.file_len {
            return Err(truncated(&self.name, 0));
        }
        self.file
            .seek(SeekFrom::Start(start))
            .map_err(|e| io_error(&self.name, e))?;
        let got = read_full(&mut self.file, &mut self.buf).map_err(|e| io_error(&self.name, e))?;
        if got < self.image_bytes {
            return Err(truncated(&self.name, got as u64));
        }
        let (w, h, stride) = (self.width, self.height, self.stride);
        match (self.pixels, dst) {
            (Pixels::U8, FrameDest::U8(px)) => {
                for (r, out) in px.chunks_exact_mut(w).enumerate().take(h) {
                    out.copy_from_slice(&self.buf[r * stride..r * stride + w]);
                }
                if self.flip {
                    super::flip_rows(px, w);
                }
            }
            (Pixels::U16Le, FrameDest::U16(px)) => {
                for (r, out) in px.chunks_exact_mut(w).enumerate().take(h) {
                    for (d, s) in out
                        .iter_mut()
                        .zip(self.buf[r * stride..r * stride + 2 * w].chunks_exact(2))
                    {
                        *d = u16::from_le_bytes([s[0], s[1]]);
                    }
                }
                if self.flip {
                    super::flip_rows(px, w);
                }
            }
            (Pixels::Packed10, FrameDest::U16(px)) => {
                unpack10(&self.buf, px);
                if self.flip {
                    super::flip_rows(px, w);
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
        let timestamp_ns = self
            .timestamps
            .as_ref()
            .and_then(|t| t.get(i).copied().flatten());
        Ok(Some(FrameRead { timestamp_ns }))
    }
}

/// Unpacks 10-bit codes (4 pixels in 5 bytes, most significant bit first)
/// and maps them to 12-bit linear values.
fn unpack10(src: &[u8], dst: &mut [u16]) {
    let mut groups = src.chunks(5);
    for out in dst.chunks_mut(4) {
        let mut g = [0u8; 5];
        if let Some(c) = groups.next() {
            g[..c.len()].copy_from_slice(c);
        }
        let v = g.iter().fold(0u64, |acc, &b| (acc << 8) | u64::from(b));
        for (k, d) in out.iter_mut().enumerate() {
            let code = ((v >> (30 - 10 * k)) & 0x3ff) as usize;
            *d = LIN_LUT[code];
        }
    }
}

impl VideoReader for CineReader {
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

    /// Builds a small cine file: `frames` images of `w`x`h` with the given
    /// bit count and compression, a time block, and SETUP fields.
    struct Builder {
        w: i32,
        h: i32,
        bit_count: u16,
        compression: u32,
        images: Vec<Vec<u8>>,
        times: Option<Vec<(u32, u32)>>,
    }

    impl Builder {
        fn build(&self) -> Vec<u8> {
            let n = self.images.len();
            let setup_len = 1600usize;
            let mut f = vec![0u8; 44];
            f[0..2].copy_from_slice(b"CI");
            f[2..4].copy_from_slice(&44u16.to_le_bytes());
            f[6..8].copy_from_slice(&1u16.to_le_bytes());
            f[20..24].copy_from_slice(&(n as u32).to_le_bytes());
            f[24..28].copy_from_slice(&44u32.to_le_bytes());
            f[28..32].copy_from_slice(&84u32.to_le_bytes());
            // Bitmap header.
            let image_len = self.images.first().map_or(0, Vec::len) as u32;
            let mut bi = vec![0u8; 40];
            bi[0..4].copy_from_slice(&40u32.to_le_bytes());
            bi[4..8].copy_from_slice(&self.w.to_le_bytes());
            bi[8..12].copy_from_slice(&self.h.to_le_bytes());
            bi[12..14].copy_from_slice(&1u16.to_le_bytes());
            bi[14..16].copy_from_slice(&self.bit_count.to_le_bytes());
            bi[16..20].copy_from_slice(&self.compression.to_le_bytes());
            bi[20..24].copy_from_slice(&image_len.to_le_bytes());
            f.extend_from_slice(&bi);
            // SETUP.
            let mut s = vec![0u8; setup_len];
            s[0..2].copy_from_slice(&500u16.to_le_bytes());
            s[140..142].copy_from_slice(b"ST");
            s[142..144].copy_from_slice(&(setup_len as u16).to_le_bytes());
            s[768..772].copy_from_slice(&2200u32.to_le_bytes());
            s[896..900].copy_from_slice(&12u32.to_le_bytes());
            s[1568..1572].copy_from_slice(&123_000u32.to_le_bytes());
            f.extend_from_slice(&s);
            // Tagged time block.
            if let Some(times) = &self.times {
                f.extend_from_slice(&(8 + 8 * times.len() as u32).to_le_bytes());
                f.extend_from_slice(&TIME_ONLY_BLOCK.to_le_bytes());
                f.extend_from_slice(&0u16.to_le_bytes());
                for (frac, sec) in times {
                    f.extend_from_slice(&frac.to_le_bytes());
                    f.extend_from_slice(&sec.to_le_bytes());
                }
            }
            // Offsets, then images with an 8-byte annotation.
            let table = f.len();
            f[32..36].copy_from_slice(&(table as u32).to_le_bytes());
            let mut at = table + 8 * n;
            for img in &self.images {
                f.extend_from_slice(&(at as i64).to_le_bytes());
                at += 8 + img.len();
            }
            for img in &self.images {
                f.extend_from_slice(&8u32.to_le_bytes());
                f.extend_from_slice(&(img.len() as u32).to_le_bytes());
                f.extend_from_slice(img);
            }
            f
        }
    }

    fn write(dir: &tempfile::TempDir, name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).expect("write");
        p
    }

    fn pack10(codes: &[u16]) -> Vec<u8> {
        let mut out = Vec::new();
        for g in codes.chunks(4) {
            let mut v = 0u64;
            for k in 0..4 {
                v = (v << 10) | u64::from(g.get(k).copied().unwrap_or(0) & 0x3ff);
            }
            out.extend_from_slice(&v.to_be_bytes()[3..]);
        }
        out
    }

    #[test]
    fn lut_is_the_published_table() {
        assert_eq!(LIN_LUT[0], 2);
        assert_eq!(LIN_LUT[1023], 4095);
        assert!(LIN_LUT.windows(2).all(|w| w[0] <= w[1]));
        // Checksums of the table as transcribed (guards against accidental edits).
        assert_eq!(
            LIN_LUT.iter().map(|&v| u64::from(v)).sum::<u64>(),
            1_398_175
        );
        assert_eq!(
            LIN_LUT
                .iter()
                .enumerate()
                .map(|(i, &v)| i as u64 * u64::from(v))
                .sum::<u64>(),
            1_066_879_377
        );
    }

    #[test]
    fn unpack10_bit_order() {
        let codes = [0u16, 1023, 512, 5, 1, 2];
        let mut out = [0u16; 6];
        unpack10(&pack10(&codes), &mut out);
        let want: Vec<u16> = codes.iter().map(|&c| LIN_LUT[c as usize]).collect();
        assert_eq!(out.to_vec(), want);
    }

    #[test]
    fn synthetic_8_bit_bottom_up_is_flipped() {
        let dir = tempfile::tempdir().expect("tempdir");
        // Stored bottom row first: rows [3 4 5] then [0 1 2] means the image is [0 1 2 / 3 4 5].
        let b = Builder {
            w: 3,
            h: 2,
            bit_count: 8,
            compression: BI_RGB,
            images: vec![vec![3, 4, 5, 0, 1, 2], vec![13, 14, 15, 10, 11, 12]],
            times: Some(vec![(0, 100), (1 << 31, 100)]),
        };
        let p = write(&dir, "a.cine", &b.build());
        let mut r = open(&p, Format::Auto).expect("open");
        let info = r.info().clone();
        assert_eq!(
            (info.width, info.height, info.depth, info.bits),
            (3, 2, Depth::U8, 8)
        );
        assert_eq!(info.frame_count, Some(2));
        assert_eq!(info.fps, Some(2200.0));
        assert_eq!(info.exposure_s, Some(123e-6));
        assert!(info.has_timestamps);
        let mut px = [0u8; 6];
        let f = r
            .read_frame(FrameDest::U8(&mut px))
            .expect("0")
            .expect("frame 0");
        assert_eq!(px, [0, 1, 2, 3, 4, 5]);
        assert_eq!(f.timestamp_ns, Some(0));
        let f = r
            .read_frame(FrameDest::U8(&mut px))
            .expect("1")
            .expect("frame 1");
        assert_eq!(px, [10, 11, 12, 13, 14, 15]);
        assert_eq!(f.timestamp_ns, Some(500_000_000));
        assert!(r.read_frame(FrameDest::U8(&mut px)).expect("end").is_none());
    }

    #[test]
    fn synthetic_16_bit_top_down_and_packed() {
        let dir = tempfile::tempdir().expect("tempdir");
        let img: Vec<u8> = [1u16, 2, 3, 4000]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let b = Builder {
            w: 2,
            h: -2,
            bit_count: 16,
            compression: BI_RGB,
            images: vec![img],
            times: None,
        };
        let p = write(&dir, "b.cine", &b.build());
        let mut r = open(&p, Format::Cine).expect("open");
        assert!(!r.info().has_timestamps);
        let mut px = [0u16; 4];
        let f = r
            .read_frame(FrameDest::U16(&mut px))
            .expect("0")
            .expect("frame");
        assert_eq!(px, [1, 2, 3, 4000]);
        assert_eq!(f.timestamp_ns, None);

        let codes = [7u16, 100, 1000, 1023, 0, 512];
        let b = Builder {
            w: 3,
            h: 2,
            bit_count: 16,
            compression: BI_PACKED,
            images: vec![pack10(&codes)],
            times: None,
        };
        let p = write(&dir, "c.cine", &b.build());
        let mut r = open(&p, Format::Cine).expect("open");
        assert_eq!((r.info().depth, r.info().bits), (Depth::U16, 16));
        let mut px = [0u16; 6];
        assert!(r.read_frame(FrameDest::U16(&mut px)).expect("0").is_some());
        // Packed images are stored top-down: no flip.
        assert_eq!(
            px.to_vec(),
            codes
                .iter()
                .map(|&c| LIN_LUT[c as usize])
                .collect::<Vec<_>>()
        );
    }

    #[test]
    fn implausible_times_are_dropped() {
        let mut notes = Vec::new();
        let t = relative_times(
            &[(0, 10), (0, 11), (0, 12), (0, 99_999), (0, 13)],
            &mut notes,
        )
        .expect("times");
        assert_eq!(
            t,
            vec![
                Some(0),
                Some(1_000_000_000),
                Some(2_000_000_000),
                None,
                Some(3_000_000_000)
            ]
        );
        assert!(
            notes
                .iter()
                .any(|n| n.contains("1 of 5 image times are implausible (image 3")),
            "{notes:?}"
        );
        let mut notes = Vec::new();
        assert!(relative_times(&[(0, 10), (0, 9), (0, 8), (0, 7)], &mut notes).is_none());
    }

    #[test]
    fn not_a_cine() {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = write(&dir, "x.cine", b"RIFF1234WAVEfmt ");
        let e = open(&p, Format::Auto).err().expect("error");
        assert!(
            e.to_string()
                .ends_with("x.cine: not a Phantom cine file (magic 0x4952, expected \"CI\")"),
            "{e}"
        );
        let p = write(&dir, "y.cine", b"CI\x2c\x00");
        let e = open(&p, Format::Auto).err().expect("error");
        assert!(
            e.to_string().contains("too short for a cine file header"),
            "{e}"
        );
        let p = write(&dir, "z.cine", b"");
        assert!(open(&p, Format::Auto).is_err());
    }

    #[test]
    fn small_cine() {
        let Some(path) = data_file("small.cine") else {
            return;
        };
        let mut r = open(&path, Format::Auto).expect("open");
        let info = r.info().clone();
        assert_eq!(info.format_name, "cine");
        assert_eq!(
            (info.width, info.height, info.bits, info.depth),
            (256, 32, 16, Depth::U16)
        );
        assert_eq!(info.frame_count, Some(235));
        assert_eq!(info.fps, Some(100.0));
        assert_eq!(info.exposure_s, Some(70e-6));
        assert!(info.has_timestamps);
        let mut px = vec![0u16; 256 * 32];
        let mut n = 0u64;
        let mut times = Vec::new();
        while let Some(f) = r.read_frame(FrameDest::U16(&mut px)).expect("frame") {
            assert!(px.iter().all(|&v| v <= 4095));
            times.push(f.timestamp_ns);
            n += 1;
        }
        assert_eq!(n, 235);
        assert_eq!(times[0], Some(0));
        // 100 fps: 10 ms apart (to within the 2^-32 s clock).
        let t1 = times[1].expect("t1");
        assert!((t1 - 10_000_000).abs() < 100, "{t1}");
        let t233 = times[233].expect("t233");
        assert!((t233 - 2_330_000_000).abs() < 10_000, "{t233}");
        // The last image's recorded time is garbage (a jump of ~292 days).
        assert_eq!(times[234], None);
        eprintln!("small.cine: {n} frames; notes: {:#?}", info.notes);
    }

    #[test]
    fn truncated_small_cine_copies() {
        let Some(path) = data_file("small.cine") else {
            return;
        };
        let bytes = std::fs::read(&path).expect("read");
        let dir = tempfile::tempdir().expect("tempdir");
        // Cut inside image 10 (images start at 14144 and are 8 + 10240 bytes apart).
        let p = write(&dir, "cut.cine", &bytes[..14144 + 10 * 10248 + 8 + 500]);
        let mut r = open(&p, Format::Auto).expect("open");
        assert_eq!(r.info().frame_count, Some(10));
        assert!(
            r.info()
                .notes
                .iter()
                .any(|n| n.contains("10 of its 235 images are complete")),
            "{:?}",
            r.info().notes
        );
        let mut px = vec![0u16; 256 * 32];
        for _ in 0..10 {
            assert!(r
                .read_frame(FrameDest::U16(&mut px))
                .expect("frame")
                .is_some());
        }
        let e = r
            .read_frame(FrameDest::U16(&mut px))
            .expect_err("truncated");
        assert!(
            matches!(
                e,
                VideoError::Truncated {
                    frame: 10,
                    got: 500,
                    expected: 10240,
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(
            e.to_string()
                .contains("cut.cine: frame 10 is truncated (got 500 of 10240 bytes)"),
            "{e}"
        );
        assert!(matches!(r.read_frame(FrameDest::U16(&mut px)), Ok(None)));

        // Every cut in the header region, and a spread of cuts beyond, give a result or a clear error.
        let mut cuts: Vec<usize> = (0..200).chain((200..14_200).step_by(37)).collect();
        cuts.extend((14_200..bytes.len()).step_by(49_999));
        for cut in cuts {
            let p = write(&dir, "c.cine", &bytes[..cut]);
            match open(&p, Format::Auto) {
                Ok(mut r) => {
                    let mut px = vec![0u16; (r.info().width * r.info().height) as usize];
                    for _ in 0..300 {
                        match r.read_frame(FrameDest::U16(&mut px)) {
                            Ok(Some(_)) => {}
                            Ok(None) => break,
                            Err(e) => {
                                assert!(e.to_string().starts_with(&p.display().to_string()), "{e}");
                                break;
                            }
                        }
                    }
                }
                Err(e) => assert!(
                    e.to_string().starts_with(&p.display().to_string()),
                    "cut {cut}: {e}"
                ),
            }
        }
    }

    #[test]
    fn garbage_never_panics() {
        let dir = tempfile::tempdir().expect("tempdir");
        let b = Builder {
            w: 4,
            h: 3,
            bit_count: 16,
            compression: BI_RGB,
            images: vec![vec![1u8; 24], vec![2u8; 24], vec![3u8; 24]],
            times: Some(vec![(0, 1), (5, 1), (10, 1)]),
        };
        let good = b.build();
        let header_end = good.len() - 3 * 32;
        let mut rng = Rng(7);
        for i in 0..500 {
            let mut bytes = good.clone();
            match i % 4 {
                0 => bytes.truncate(rng.below(good.len() as u64 + 1) as usize),
                1 => {
                    // Corrupt a few bytes of the fixed headers, where the sizes and offsets are.
                    for _ in 0..1 + rng.below(4) {
                        let at = rng.below(84) as usize;
                        bytes[at] = rng.next() as u8;
                    }
                }
                2 => {
                    for _ in 0..1 + rng.below(6) {
                        let at = rng.below(header_end as u64) as usize;
                        bytes[at] = rng.next() as u8;
                    }
                }
                _ => {
                    // Big values in the count, offset and size fields.
                    let fields = [20usize, 24, 28, 32, 44 + 4, 44 + 8, 44 + 20, 84 + 142];
                    let at = fields[rng.below(fields.len() as u64) as usize];
                    let v = [u32::MAX, 0x7fff_ffff, 0, 1, 0x8000_0000, rng.next() as u32]
                        [rng.below(6) as usize];
                    bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
                }
            }
            let p = write(&dir, "g.cine", &bytes);
            if let Ok(mut r) = open(&p, Format::Auto) {
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
