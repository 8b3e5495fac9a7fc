//! The studio's HTTP requests (`crates/studio`, issue 16): what a browser,
//! or anybody who can reach the port, sends. The whole router (the guard,
//! the token check, the query and JSON parsing, the handlers and the
//! recipes they call) answers arbitrary requests about a small recording
//! in a scratch root, with a token set, as when bound beyond loopback.
//!
//! Input layout: byte 0 picks the method and whether the token is sent
//! (query, header or cookie); then the request target up to the first
//! `\n`; then header lines `name: value` up to an empty line; the rest is
//! the body. Checked: no panic anywhere (libFuzzer aborts on one, also
//! inside the server's blocking tasks), every error answer is the
//! `{"error": ...}` JSON the page shows, nothing outside the root is ever
//! served, and the recording is never changed.
#![no_main]

#[path = "common.rs"]
mod common;

use axum::body::Body;
use axum::http::{Method, Request};
use libfuzzer_sys::fuzz_target;
use std::sync::{Arc, OnceLock};
use tower::ServiceExt;

const TOKEN: &str = "0123456789abcdef0123456789abcdef";
const W: usize = 16;
const H: usize = 12;
const FRAMES: usize = 24;

struct Fixture {
    rt: tokio::runtime::Runtime,
    router: axum::Router,
    video: Vec<u8>,
    video_path: std::path::PathBuf,
}

/// A 16x12 grey recording at 100 fps whose texture moves with a 10 Hz
/// tone, in `root/v.y4m`; beside the root, a file the guard must never
/// serve.
fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let base = common::scratch_dir();
        let root = base.join("root");
        std::fs::create_dir_all(root.join("sub")).expect("scratch root");
        std::fs::write(base.join("secret.y4m"), b"outside the root").expect("scratch");
        let mut video = format!("YUV4MPEG2 W{W} H{H} F100:1 Ip A1:1 Cmono\n").into_bytes();
        for t in 0..FRAMES {
            video.extend_from_slice(b"FRAME\n");
            let shift = 0.3 * (2.0 * std::f64::consts::PI * 10.0 * t as f64 / 100.0).sin();
            for y in 0..H {
                for x in 0..W {
                    let u = x as f64 + shift;
                    let v = 128.0 + 60.0 * (0.9 * u).sin() + 30.0 * (0.7 * y as f64 + 0.4 * u).cos();
                    video.push(v.round().clamp(0.0, 255.0) as u8);
                }
            }
        }
        let video_path = root.join("v.y4m");
        std::fs::write(&video_path, &video).expect("scratch video");
        let _ = std::os::unix::fs::symlink(base.join("secret.y4m"), root.join("sub/out.y4m"));
        let root = root.canonicalize().expect("scratch root");
        let app = Arc::new(vibroscope_studio::api::App::new(
            root,
            Some("v.y4m".into()),
            None,
            Some(TOKEN.into()),
        ));
        let router = vibroscope_studio::api::router(app, vibroscope_studio::MAX_BODY);
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .expect("runtime");
        Fixture {
            rt,
            router,
            video,
            video_path,
        }
    })
}

fuzz_target!(|data: &[u8]| {
    let Some((&sel, rest)) = data.split_first() else {
        return;
    };
    let f = fixture();
    let method = match sel & 3 {
        0 => Method::GET,
        1 => Method::POST,
        2 => Method::PUT,
        _ => Method::DELETE,
    };
    let (target, rest) = match rest.iter().position(|&b| b == b'\n') {
        Some(i) => (&rest[..i], &rest[i + 1..]),
        None => (rest, &[][..]),
    };
    let Ok(target) = std::str::from_utf8(target) else {
        return;
    };
    let mut target = target.to_owned();
    if sel & 4 != 0 {
        target.push(if target.contains('?') { '&' } else { '?' });
        target.push_str("token=");
        target.push_str(TOKEN);
    }
    let mut req = Request::builder().method(method).uri(target.as_str());
    if sel & 32 == 0 {
        // The studio answers only its own names (a foreign or missing Host is refused).
        req = req.header("host", "127.0.0.1");
    }
    if sel & 8 != 0 {
        req = req.header("x-vibroscope-token", TOKEN);
    }
    if sel & 16 != 0 {
        req = req.header("cookie", format!("vibroscope_token={TOKEN}"));
    }
    let mut body = rest;
    while let Some(i) = body.iter().position(|&b| b == b'\n') {
        let line = &body[..i];
        body = &body[i + 1..];
        if line.is_empty() {
            break;
        }
        if let Some(c) = line.iter().position(|&b| b == b':') {
            req = req.header(&line[..c], &line[c + 1..]);
        }
    }
    let Ok(req) = req.body(Body::from(body.to_vec())) else {
        return; // not a request the HTTP layer would hand to the router
    };
    let resp = f
        .rt
        .block_on(f.router.clone().oneshot(req))
        .expect("the router is infallible");
    let status = resp.status();
    let bytes = f
        .rt
        .block_on(axum::body::to_bytes(resp.into_body(), 64 << 20))
        .expect("a body under 64 MB");
    if status.is_client_error() || status.is_server_error() {
        let v: serde_json::Value =
            serde_json::from_slice(&bytes).expect("an error answer is JSON");
        assert!(v["error"].is_string(), "an error answer says why: {v}");
    }
    if status.is_success() {
        assert!(
            !bytes.windows(17).any(|w| w == b"outside the root"),
            "a file outside the root was served for {target:?}"
        );
    }
    assert_eq!(
        std::fs::read(&f.video_path).ok().as_deref(),
        Some(&f.video[..]),
        "the recording is unchanged"
    );
});
