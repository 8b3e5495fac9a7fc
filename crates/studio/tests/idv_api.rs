//! `POST /api/idv/basis` (issue 17) without a browser: the answer decodes
//! to exactly the library's basis (`vibroscope::idv::extract_basis` over
//! the same region), cropped to the region's box; the rest frame is the
//! library's; the second request answers from the cache.
//!
//!     cargo test --release -p vibroscope-studio --test idv_api

#![allow(clippy::unwrap_used, clippy::expect_used)]

use serde_json::Value;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;
use vibroscope::idv::{extract_basis, BasisOptions, ModeChoice};
use vibroscope::pipeline::{Region, Roi};
use vibroscope_studio::api::base64_decode;
use vibroscope_studio::{Studio, StudioOptions};

fn post(studio: &Studio, target: &str, body: &str) -> (u16, Value) {
    let mut s = TcpStream::connect(("127.0.0.1", studio.addr.port())).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(120))).unwrap();
    let token = studio.token.as_deref().unwrap_or("");
    let head = format!(
        "POST {target} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\nx-vibroscope-token: {token}\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n",
        body.len()
    );
    s.write_all(head.as_bytes()).unwrap();
    s.write_all(body.as_bytes()).unwrap();
    let mut out = Vec::new();
    s.read_to_end(&mut out).unwrap();
    let text = String::from_utf8_lossy(&out).into_owned();
    let status = text.split(' ').nth(1).unwrap().parse().unwrap();
    let (head, body) = text.split_once("\r\n\r\n").unwrap();
    let body = if head
        .to_ascii_lowercase()
        .contains("transfer-encoding: chunked")
    {
        dechunk(body)
    } else {
        body.to_string()
    };
    (status, serde_json::from_str(&body).unwrap())
}

fn dechunk(mut s: &str) -> String {
    let mut out = String::new();
    loop {
        let (len, rest) = s.split_once("\r\n").unwrap();
        let n = usize::from_str_radix(len.trim(), 16).unwrap();
        if n == 0 {
            return out;
        }
        out.push_str(&rest[..n]);
        s = &rest[n + 2..];
    }
}

#[test]
fn the_basis_answer_is_the_library_basis_over_the_region() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("beam.toml");
    std::fs::write(
        &scene,
        "width = 96\nheight = 48\nfps = 300.0\nframes = 600\nobject = [8, 8, 80, 32]\n\
         noise_std = 2.0\nseed = 5\nmodal = { modes = [\n\
         { freq_hz = 7.3, amplitude_px = 0.3, shape = 1, damping = 0.02 },\n\
         { freq_hz = 45.8, amplitude_px = 0.15, shape = 2, damping = 0.01 },\n] }\n",
    )
    .unwrap();
    let video = dir.path().join("beam.y4m");
    vibroscope::simulate::simulate(&vibroscope::simulate::SimulateOptions {
        scene,
        output: video.clone(),
        ..Default::default()
    })
    .unwrap();
    let studio = Studio::start(&StudioOptions {
        video: Some(video.clone()),
        ..StudioOptions::default()
    })
    .unwrap();
    let roi = [4u32, 6, 88, 36];
    let body = format!(r#"{{"video":"beam.y4m","roi":{roi:?},"modes":"7.3,45.8"}}"#);
    let (st, v) = post(&studio, "/api/idv/basis", &body);
    assert_eq!(st, 200, "{v}");
    assert_eq!(v["cached"], Value::Bool(false));

    let mut o = BasisOptions::new(&video);
    o.region = Region {
        roi: Some(Roi {
            x: roi[0],
            y: roi[1],
            w: roi[2],
            h: roi[3],
        }),
        ..Region::default()
    };
    o.modes = "7.3,45.8".parse::<ModeChoice>().unwrap();
    let lib = extract_basis(&o).unwrap();
    assert_eq!(v["width"].as_u64(), Some(lib.width as u64));
    assert_eq!(v["height"].as_u64(), Some(lib.height as u64));
    assert_eq!(v["box"], serde_json::json!(roi));
    assert_eq!(
        base64_decode(v["rest"].as_str().unwrap()).unwrap(),
        lib.rest,
        "the rest frame"
    );
    let modes = v["modes"].as_array().unwrap();
    assert_eq!(modes.len(), lib.modes.len());
    let [bx, by, bw, bh] = roi.map(|v| v as usize);
    for (m, l) in modes.iter().zip(&lib.modes) {
        assert_eq!(m["freq_hz"].as_f64(), Some(l.freq_hz));
        assert_eq!(m["damping_ratio"].as_f64(), Some(l.damping));
        let bytes = base64_decode(m["shape"].as_str().unwrap()).unwrap();
        assert_eq!(bytes.len(), bw * bh * 16);
        let f: Vec<f32> = bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        let mut peak = 0.0f32;
        for y in 0..bh {
            for x in 0..bw {
                let i = (by + y) * lib.width + bx + x;
                let k = 4 * (y * bw + x);
                let want = [
                    l.shape.x[i].re,
                    l.shape.x[i].im,
                    l.shape.y[i].re,
                    l.shape.y[i].im,
                ];
                assert_eq!(&f[k..k + 4], &want, "mode {} at {x},{y}", l.freq_hz);
                peak = peak.max(want[2].abs());
            }
        }
        assert!(peak > 0.0, "the shape moves somewhere");
    }
    let (st, again) = post(&studio, "/api/idv/basis", &body);
    assert_eq!(st, 200);
    assert_eq!(again["cached"], Value::Bool(true));
    assert_eq!(again["modes"], v["modes"]);
}
