//! The studio's security cases (issue 16, item 7), over raw HTTP/1.1 so
//! that paths reach the server exactly as written (no client normalises
//! `..` or decodes `%2F`): path traversal by `..`, an absolute path, a
//! symlink out of the root, encoded slashes; the token when bound beyond
//! the loopback address; oversized and garbage bodies; and the server
//! still answering after all of them.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::*;
use std::io::{Read, Write};
use std::net::{IpAddr, Ipv4Addr, TcpStream};
use std::path::Path;
use std::time::Duration;
use vibroscope_studio::{Studio, StudioOptions};

/// A root with a video, a file that is not one, and a symlink to a video
/// outside the root.
fn setup() -> (tempfile::TempDir, std::path::PathBuf) {
    let d = tempfile::tempdir().unwrap();
    let root = d.path().join("root");
    std::fs::create_dir_all(root.join("sub")).unwrap();
    std::fs::create_dir_all(d.path().join("outside")).unwrap();
    write_y4m(&root.join("sub/clip.y4m"));
    write_y4m(&d.path().join("outside/secret.y4m"));
    std::fs::write(root.join("notes.y4m"), b"this is not a video").unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(d.path().join("outside/secret.y4m"), root.join("link.y4m")).unwrap();
    (d, root)
}

#[test]
fn paths_bodies_and_malformed_requests_get_the_right_status() {
    let (_d, root) = setup();
    let s = Studio::start(&StudioOptions {
        root: Some(root.clone()),
        ..StudioOptions::default()
    })
    .unwrap();
    assert!(s.addr.ip().is_loopback(), "binds 127.0.0.1 by default");
    let t = s.token.as_deref().expect("a token on loopback too");
    assert!(s.url.ends_with(&format!("/?token={t}")), "{}", s.url);
    let a = &s;

    // What is allowed works.
    let (st, body) = get(a, "/api/info?video=sub/clip.y4m");
    assert_eq!(st, 200, "{body}");
    assert!(body.contains("\"width\":16"), "{body}");
    assert_eq!(
        get(a, "/api/info?video=sub%2Fclip.y4m").0,
        200,
        "an encoded slash in a query value is a value"
    );
    assert_eq!(get(a, "/api/frame?video=sub/clip.y4m&i=3").0, 200);
    assert_eq!(get(a, "/").0, 200);

    // Traversal, absolute paths, symlinks out: 403; encoded separators in the path: 400.
    for (target, want) in [
        ("/api/info?video=../outside/secret.y4m", 403),
        ("/api/info?video=sub/../../outside/secret.y4m", 403),
        ("/api/info?video=..%2Foutside%2Fsecret.y4m", 403),
        ("/api/info?video=%2Fetc%2Fpasswd", 403),
        ("/api/info?video=/etc/passwd", 403),
        ("/api/info?video=link.y4m", 403),
        ("/api/frame?video=link.y4m&i=0", 403),
        ("/api%2Finfo?video=sub/clip.y4m", 400),
        ("/api/..%2F..%2Fetc%2Fpasswd", 400),
        ("/api/info?video=sub%5Cclip.y4m", 400),
        ("/api/info?video=missing.y4m", 404),
        ("/../../../etc/passwd", 404),
        ("/api/info", 400),
        ("/api/frame?video=sub/clip.y4m&i=minus-one", 400),
        ("/api/frame?video=sub/clip.y4m&i=99", 404),
    ] {
        let (st, body) = get(a, target);
        assert_eq!(st, want, "{target}: {body}");
        assert!(!body.contains("root:"), "{target} leaked a file: {body}");
        if st != 404 || target.starts_with("/api/") {
            assert!(!error_of(&body).is_empty(), "{target}");
        }
    }

    // Bodies: oversized 413, garbage 400, wrong fields 400, bad values 422.
    let big = format!("{{\"video\":\"{}\"}}", "a".repeat(200_000));
    let (st, body) = post(a, "/api/motion", &big);
    assert_eq!(st, 413, "{body}");
    assert!(
        error_of(&body).contains("length limit"),
        "413 as JSON: {body}"
    );
    // A wrong method gets the page's JSON error too.
    let (st, body) = get(a, "/api/motion");
    assert_eq!(st, 405, "{body}");
    assert!(
        error_of(&body).contains("method not allowed"),
        "405 as JSON: {body}"
    );
    for (target, body, want) in [
        ("/api/motion", "not json {", 400),
        ("/api/motion", "", 400),
        ("/api/motion", "[1,2,3]", 400),
        (
            "/api/motion",
            "{\"video\":\"sub/clip.y4m\",\"extra\":1}",
            400,
        ),
        ("/api/mode", "{\"video\":\"sub/clip.y4m\"}", 400),
        (
            "/api/mode",
            "{\"video\":\"sub/clip.y4m\",\"freq_hz\":\"ten\"}",
            400,
        ),
        (
            "/api/mode",
            "{\"video\":\"../outside/secret.y4m\",\"freq_hz\":10}",
            403,
        ),
        (
            "/api/mode",
            "{\"video\":\"sub/clip.y4m\",\"freq_hz\":60}",
            422,
        ),
        (
            "/api/mode",
            "{\"video\":\"sub/clip.y4m\",\"freq_hz\":-1}",
            422,
        ),
        (
            "/api/mode",
            "{\"video\":\"sub/clip.y4m\",\"freq_hz\":10,\"roi\":[8,8,16,16]}",
            422,
        ),
        (
            "/api/motion",
            "{\"video\":\"sub/clip.y4m\",\"roi\":[0,0,4000,9]}",
            422,
        ),
        (
            "/api/motion",
            "{\"video\":\"sub/clip.y4m\",\"fps\":-3}",
            422,
        ),
        (
            "/api/listen",
            "{\"video\":\"sub/clip.y4m\",\"roi\":[0,0,4000,9]}",
            422,
        ),
        ("/api/listen", "{\"video\":\"../outside/secret.y4m\"}", 403),
        ("/api/listen", "{\"video\":\"sub/clip.y4m\",\"x\":1}", 400),
        ("/api/listen", "{\"video\":\"nothing.y4m\"}", 404),
        // A sound from 1.1 frames a second is 7000 times longer than the
        // recording's frames at 8 kHz, all of it under 1 Hz: refused.
        (
            "/api/listen",
            "{\"video\":\"sub/clip.y4m\",\"fps\":1.1}",
            422,
        ),
        (
            "/api/listen",
            "{\"video\":\"sub/clip.y4m\",\"fps\":1e-300}",
            422,
        ),
        (
            "/api/motion",
            "{\"video\":\"sub/clip.y4m\",\"scale_mm_per_px\":0}",
            422,
        ),
        (
            "/api/mode",
            "{\"video\":\"sub/clip.y4m\",\"freq_hz\":10,\"scale_mm_per_px\":-2}",
            422,
        ),
        ("/api/damping", "{\"video\":\"sub/clip.y4m\"}", 400),
        (
            "/api/damping",
            "{\"video\":\"sub/clip.y4m\",\"lo_hz\":10,\"hi_hz\":60}",
            422,
        ),
        (
            "/api/damping",
            "{\"video\":\"sub/clip.y4m\",\"lo_hz\":20,\"hi_hz\":10}",
            422,
        ),
        (
            "/api/damping",
            "{\"video\":\"sub/clip.y4m\",\"lo_hz\":-1,\"hi_hz\":10}",
            422,
        ),
        (
            "/api/damping",
            "{\"video\":\"sub/clip.y4m\",\"lo_hz\":1,\"hi_hz\":10,\"roi\":[0,0,99,99]}",
            422,
        ),
        (
            "/api/damping",
            "{\"video\":\"../outside/secret.y4m\",\"lo_hz\":1,\"hi_hz\":10}",
            403,
        ),
        (
            "/api/damping",
            "{\"video\":\"sub/clip.y4m\",\"lo_hz\":1,\"hi_hz\":10,\"q\":1}",
            400,
        ),
    ] {
        let (st, b) = post(a, target, body);
        assert_eq!(st, want, "{target} {body}: {b}");
        assert!(!error_of(&b).is_empty());
    }
    // Painted masks: not base64, not a picture, the wrong size, empty, too
    // few pixels in the region; each named.
    let png = |w: u32, h: u32, on: &[(u32, u32)]| -> String {
        let mut img = image::GrayImage::new(w, h);
        for &(x, y) in on {
            img.put_pixel(x, y, image::Luma([255]));
        }
        let mut out = std::io::Cursor::new(Vec::new());
        img.write_to(&mut out, image::ImageFormat::Png).unwrap();
        format!(
            "data:image/png;base64,{}",
            vibroscope_studio::api::base64(out.get_ref())
        )
    };
    let all: Vec<(u32, u32)> = (0..64).map(|k| (k % 8, k / 8)).collect();
    for (mask, roi, want, says) in [
        ("!!!".to_string(), None, 400, "base64"),
        ("aGVsbG8=".to_string(), None, 422, "mask"),
        (png(8, 8, &all), None, 422, "8x8, but the frames are 16x16"),
        (png(16, 16, &[]), None, 422, "empty"),
        (png(16, 16, &all[..4]), None, 422, "4 painted pixels"),
        (
            png(16, 16, &all),
            Some([8, 8, 8, 8]),
            422,
            "0 painted pixels",
        ),
    ] {
        let body =
            serde_json::json!({"video": "sub/clip.y4m", "mask": mask, "roi": roi}).to_string();
        for target in ["/api/motion", "/api/listen"] {
            let (st, b) = post(a, target, &body);
            assert_eq!(st, want, "{target} {says}: {b}");
            assert!(error_of(&b).contains(says), "{target}: {b}");
        }
    }
    // A file that is not a video: an error answer with a message, not a crash.
    let (st, b) = get(a, "/api/info?video=notes.y4m");
    assert!((400..600).contains(&st), "{st} {b}");
    assert!(error_of(&b).contains("notes.y4m"), "{b}");
    let (st, b) = get(a, "/api/frame?video=notes.y4m&i=0");
    assert!((400..600).contains(&st), "{st} {b}");

    // Still serving after all of that.
    assert_eq!(get(a, "/api/session").0, 200);
    assert_eq!(get(a, "/api/info?video=sub/clip.y4m").0, 200);
}

#[test]
fn beyond_loopback_every_request_needs_the_token() {
    let (_d, root) = setup();
    let s = Studio::start(&StudioOptions {
        root: Some(root),
        bind: Some(IpAddr::V4(Ipv4Addr::UNSPECIFIED)),
        ..StudioOptions::default()
    })
    .unwrap();
    let token = s.token.clone().expect("a token when not on loopback");
    assert_eq!(token.len(), 32);
    assert!(s.url.ends_with(&format!("?token={token}")), "{}", s.url);
    let a = s.addr;
    let wrong = "0".repeat(32);
    for path in [
        "/",
        "/app.js",
        "/api/session",
        "/api/info?video=sub/clip.y4m",
        "/api/live/ws",
        "/nothing",
    ] {
        let sep = if path.contains('?') { '&' } else { '?' };
        assert_eq!(raw_get(a, path).0, 403, "{path} without a token");
        assert_eq!(
            raw_get(a, &format!("{path}{sep}token={wrong}")).0,
            403,
            "{path} wrong token"
        );
        assert_eq!(
            raw_get(a, &format!("{path}{sep}token=")).0,
            403,
            "{path} empty token"
        );
        let right = raw_get(a, &format!("{path}{sep}token={token}")).0;
        // The page's URL with the token: the cookie, and the page without it.
        let right = if path == "/" {
            assert_eq!(right, 303);
            200
        } else {
            right
        };
        // No live pipeline here: its routes are 404 once the token passes.
        let want = if path == "/nothing" || path.starts_with("/api/live") {
            404
        } else {
            200
        };
        assert_eq!(right, want, "{path} right token");
    }
    let h = format!("x-vibroscope-token: {token}\r\n");
    assert_eq!(request(a, "GET", "/api/session", &h, b"").0, 200);
    let h = format!("x-vibroscope-token: {wrong}\r\n");
    assert_eq!(request(a, "GET", "/api/session", &h, b"").0, 403);
    assert_eq!(raw_post(a, "/api/motion", "{}").0, 403);
    // The page opened with the token gets it as a cookie, which its script
    // and stylesheet requests (URLs without the token) then carry.
    let mut s2 = TcpStream::connect(("127.0.0.1", a.port())).unwrap();
    write!(
        s2,
        "GET /?token={token} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut head = String::new();
    let _ = s2.read_to_string(&mut head);
    assert!(
        head.to_ascii_lowercase().contains(&format!(
            "set-cookie: vibroscope_token_{}={token}; httponly; samesite=strict",
            a.port()
        )),
        "{head}"
    );
    assert!(
        head.to_ascii_lowercase().contains("\r\nlocation: /\r\n"),
        "{head}"
    );
    let h = format!("Cookie: other=1; vibroscope_token_{}={token}\r\n", a.port());
    assert_eq!(request(a, "GET", "/app.js", &h, b"").0, 200);
    let h = format!("Cookie: vibroscope_token_{}={wrong}\r\n", a.port());
    assert_eq!(request(a, "GET", "/app.js", &h, b"").0, 403);
    // The guard runs before the body is looked at.
    let big = "x".repeat(200_000);
    assert_eq!(raw_post(a, "/api/motion", &big).0, 403);
}

#[test]
fn a_root_that_does_not_exist_is_a_usage_error() {
    let e = Studio::start(&StudioOptions {
        root: Some("/nonexistent/studio-root".into()),
        ..StudioOptions::default()
    })
    .err()
    .expect("refused");
    assert!(
        e.is_usage() && e.to_string().contains("/nonexistent/studio-root"),
        "{e}"
    );
    let d = tempfile::tempdir().unwrap();
    let v = d.path().join("v.y4m");
    write_y4m(&v);
    let other = tempfile::tempdir().unwrap();
    let e = Studio::start(&StudioOptions {
        video: Some(v),
        root: Some(other.path().to_path_buf()),
        ..StudioOptions::default()
    })
    .err()
    .expect("refused");
    assert!(
        e.is_usage() && e.to_string().contains("not under the root"),
        "{e}"
    );
}

#[test]
fn live_routes_without_and_with_a_pipeline() {
    let (_d, root) = setup();
    // Without --pipeline: 404 naming the option, for every live route.
    let s = Studio::start(&StudioOptions {
        root: Some(root.clone()),
        ..StudioOptions::default()
    })
    .unwrap();
    for path in ["/api/live", "/api/live/frame", "/api/live/ws"] {
        let (st, body) = get(&s, path);
        assert_eq!(st, 404, "{path}: {body}");
        assert!(error_of(&body).contains("--pipeline"), "{path}: {body}");
    }
    let (st, body) = upgrade(s.addr, "/api/live/ws", &auth(&s));
    assert_eq!(st, 404, "{body}");
    let (st, body) = post(&s, "/api/live/mode", "{\"freq_hz\":10}");
    assert_eq!(st, 404, "{body}");
    drop(s);
    // Bad pipelines are refused at start, naming what is wrong.
    for (p, set, want) in [
        ("no-such-pipeline", vec![], "no such file"),
        ("live-spectrum", vec!["spectrum.hop=0".to_owned()], "hop"),
        ("live-spectrum", vec!["nostage.x=1".to_owned()], "nostage"),
    ] {
        let e = Studio::start(&StudioOptions {
            root: Some(root.clone()),
            pipeline: Some(p.into()),
            set,
            ..StudioOptions::default()
        })
        .err()
        .expect("refused");
        assert!(e.is_usage() && e.to_string().contains(want), "{e}");
    }
    let e = Studio::start(&StudioOptions {
        root: Some(root.clone()),
        set: vec!["src.fps=10.0".into()],
        ..StudioOptions::default()
    })
    .err()
    .expect("--set without --pipeline");
    assert!(e.is_usage() && e.to_string().contains("--pipeline"), "{e}");
    // With a live pipeline: the update, the frame, the WebSocket upgrade
    // (101), a plain GET of the socket route (400), and the token guard.
    let s = Studio::start(&StudioOptions {
        bind: Some(IpAddr::V4(Ipv4Addr::UNSPECIFIED)),
        ..live_options(&root)
    })
    .unwrap();
    let t = s.token.clone().unwrap();
    let a = s.addr;
    assert_eq!(raw_get(a, "/api/live").0, 403);
    assert_eq!(upgrade(a, "/api/live/ws", "").0, 403);
    let t0 = std::time::Instant::now();
    let u = loop {
        let (st, body) = raw_get(a, &format!("/api/live?token={t}"));
        assert_eq!(st, 200, "{body}");
        let u: serde_json::Value = serde_json::from_str(&body).unwrap();
        if !u["spectrum"].is_null() && !u["frame"].is_null() {
            break u;
        }
        assert!(t0.elapsed() < Duration::from_secs(30), "no update: {u}");
        std::thread::sleep(Duration::from_millis(100));
    };
    assert_eq!(u["state"], "running", "{u}");
    assert_eq!(u["frame"]["width"], 32);
    assert!(u["stages"].as_array().unwrap().len() >= 7, "{u}");
    let (st, body) = raw_get(a, &format!("/api/live/frame?token={t}"));
    assert_eq!(st, 200);
    assert!(body.len() > 8, "a PNG");
    assert_eq!(upgrade(a, &format!("/api/live/ws?token={t}"), "").0, 101);
    let (st, body) = raw_get(a, &format!("/api/live/ws?token={t}"));
    assert_eq!(st, 400, "{body}");
    assert!(error_of(&body).contains("WebSocket"), "{body}");
    // A clicked peak's modal image from the last frames; bad requests.
    let mode = |b: &str| raw_post(a, &format!("/api/live/mode?token={t}"), b);
    assert_eq!(raw_post(a, "/api/live/mode", "{\"freq_hz\":10}").0, 403);
    for (b, want) in [
        ("{\"freq_hz\":\"ten\"}", 400),
        ("{\"freq_hz\":10,\"x\":1}", 400),
        ("{\"freq_hz\":-1}", 422),
        ("{\"freq_hz\":150}", 422),
    ] {
        let (st, body) = mode(b);
        assert_eq!(st, want, "{b}: {body}");
        assert!(!error_of(&body).is_empty());
    }
    let (st, body) = mode("{\"freq_hz\":150}");
    assert!(error_of(&body).contains("Nyquist"), "{st} {body}");
    let (st, body) = mode("{\"freq_hz\":20}");
    assert_eq!(st, 200, "{body}");
    let m: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert_eq!(
        (m["width"].as_u64(), m["height"].as_u64()),
        (Some(32), Some(32))
    );
    assert!(m["frames"].as_u64().unwrap() >= 32, "{}", m["frames"]);
    // Stopping the studio stops the pipeline; its sink finalises.
    drop(s);
    assert!(root.join("live.json").exists());
}

/// A still recording: a texture, 96 frames at 100 Hz, nothing moves.
fn write_still_y4m(p: &Path, w: u32, h: u32, frames: u32) {
    let mut v = format!("YUV4MPEG2 W{w} H{h} F100:1 Ip A1:1 Cmono\n").into_bytes();
    let tex: Vec<u8> = (0..w * h)
        .map(|k| {
            let (x, y) = (k % w, k / w);
            (((x / 4 + y / 4) % 2) * 120 + 60) as u8
        })
        .collect();
    for _ in 0..frames {
        v.extend_from_slice(b"FRAME\n");
        v.extend_from_slice(&tex);
    }
    std::fs::write(p, v).unwrap();
}

#[test]
fn idv_basis_refuses_bad_requests_with_json_errors() {
    let (_d, root) = setup();
    write_still_y4m(&root.join("still.y4m"), 32, 32, 96);
    // 2048x2048: 8 modes would be 715 MB of basis.
    write_still_y4m(&root.join("huge.y4m"), 2048, 2048, 2);
    let s = Studio::start(&StudioOptions {
        root: Some(root.clone()),
        ..StudioOptions::default()
    })
    .unwrap();
    let a = &s;
    let route = "/api/idv/basis";
    for (body, want, says) in [
        (
            r#"{"video":"../outside/secret.y4m"}"#,
            403,
            "`..` is not allowed",
        ),
        (r#"{"video":"/etc/passwd"}"#, 403, "absolute paths"),
        (r#"{"video":"link.y4m"}"#, 403, "root"),
        (r#"{"video":"no-such.y4m"}"#, 404, "no-such.y4m"),
        (
            r#"{"video":"sub/clip.y4m","modes":"7.3,abc"}"#,
            422,
            "modes: `abc`",
        ),
        (
            r#"{"video":"sub/clip.y4m","modes":"50-20"}"#,
            422,
            "modes: range",
        ),
        (r#"{"video":"sub/clip.y4m","modes":""}"#, 422, "modes:"),
        (
            r#"{"video":"sub/clip.y4m","max_modes":0}"#,
            422,
            "max_modes",
        ),
        (
            r#"{"video":"sub/clip.y4m","max_modes":1000}"#,
            422,
            "max_modes",
        ),
        (
            r#"{"video":"sub/clip.y4m","roi":[0,0,100,100]}"#,
            422,
            "region",
        ),
        (r#"{"video":"sub/clip.y4m","fps":-3}"#, 422, "fps"),
        (r#"{"video":"sub/clip.y4m","mask":"!!"}"#, 400, "mask"),
        (r#"{"video":"sub/clip.y4m","bogus":1}"#, 400, "bogus"),
        (r#"{"video":7}"#, 400, "request body"),
        (r#"{"video":"still.y4m"}"#, 422, "no significant peak"),
        (
            r#"{"video":"still.y4m","modes":"10-20"}"#,
            422,
            "no significant peak",
        ),
        (r#"{"video":"huge.y4m"}"#, 422, "roi/modes"),
    ] {
        let (st, got) = post(a, route, body);
        let msg = error_of(&got);
        println!("{body} -> {st} {msg}");
        assert_eq!(st, want, "{body}: {got}");
        assert!(msg.contains(says), "{body}: {msg:?} does not say {says:?}");
        assert!(
            !msg.contains("/tmp"),
            "{body}: {msg:?} names the server's path"
        );
    }
    // A region of the huge frame small enough is accepted past the size check
    // (it then finds no peak: the frame is still).
    let (st, got) = post(
        a,
        route,
        r#"{"video":"huge.y4m","roi":[0,0,64,64],"modes":"auto"}"#,
    );
    assert!(st >= 400, "{got}");
    assert!(!error_of(&got).contains("roi/modes"), "{got}");
    assert_eq!(
        get(a, "/api/info?video=sub/clip.y4m").0,
        200,
        "still answering"
    );
}

/// A refusal's body: only `{"error": ...}`, nothing of what was asked.
fn refused_without_data(status: u16, body: &str, what: &str) {
    assert_eq!(status, 403, "{what}: {body}");
    let v: serde_json::Value =
        serde_json::from_str(body).unwrap_or_else(|e| panic!("{what}: {e}: {body}"));
    let keys: Vec<&String> = v.as_object().expect("an object").keys().collect();
    assert_eq!(keys, ["error"], "{what}: {body}");
}

/// Issue 54: on loopback too, every route (WebSocket upgrades included)
/// refuses with 403 and no data a foreign Host, a cross-site Origin,
/// another port's Origin, `Sec-Fetch-Site: cross-site` or `same-site`, no
/// token, a wrong token, and the token of another studio (another port),
/// as header, query and cookie; and answers the right token, `localhost`,
/// its own Origin and the page's security headers.
#[test]
fn foreign_hosts_origins_and_tokens_are_refused_on_every_route() {
    let (_d, root) = setup();
    let s = Studio::start(&live_options(&root)).unwrap();
    let other = Studio::start(&StudioOptions {
        root: Some(root.clone()),
        ..StudioOptions::default()
    })
    .unwrap();
    let (a, port) = (s.addr, s.addr.port());
    let t = s.token.clone().expect("a token on loopback by default");
    let ot = other.token.clone().unwrap();
    assert_ne!(t, ot);
    let op = other.addr.port();
    let right = format!("x-vibroscope-token: {t}\r\n");
    let routes: [(&str, &str, &str); 7] = [
        ("GET", "/", ""),
        ("GET", "/app.js", ""),
        ("GET", "/api/session", ""),
        ("GET", "/api/info?video=sub/clip.y4m", ""),
        ("GET", "/api/frame?video=sub/clip.y4m&i=1", ""),
        ("POST", "/api/motion", "{\"video\":\"sub/clip.y4m\"}"),
        ("WS", "/api/live/ws", ""),
    ];
    let send = |method: &str, target: &str, headers: &str, body: &str| -> (u16, String) {
        if method == "WS" {
            upgrade(a, target, headers)
        } else {
            let h = format!("Content-Type: application/json\r\n{headers}");
            request(a, method, target, &h, body.as_bytes())
        }
    };
    for (method, target, body) in routes {
        let sep = if target.contains('?') { '&' } else { '?' };
        let cases: Vec<(String, String, String)> = vec![
            (
                "a foreign Host".into(),
                target.into(),
                format!("Host: attacker.example:{port}\r\n{right}"),
            ),
            (
                "a foreign Host without a port".into(),
                target.into(),
                format!("Host: attacker.example\r\n{right}"),
            ),
            (
                "a cross-site Origin".into(),
                target.into(),
                format!("Origin: http://attacker.example\r\n{right}"),
            ),
            (
                "another port's Origin".into(),
                target.into(),
                format!("Origin: http://127.0.0.1:{op}\r\n{right}"),
            ),
            (
                "an opaque Origin".into(),
                target.into(),
                format!("Origin: null\r\n{right}"),
            ),
            (
                "Sec-Fetch-Site: cross-site".into(),
                target.into(),
                format!("Sec-Fetch-Site: cross-site\r\n{right}"),
            ),
            (
                "Sec-Fetch-Site: same-site".into(),
                target.into(),
                format!("Sec-Fetch-Site: same-site\r\n{right}"),
            ),
            ("no token".into(), target.into(), String::new()),
            (
                "a wrong token".into(),
                target.into(),
                format!("x-vibroscope-token: {}\r\n", "f".repeat(32)),
            ),
            (
                "the other studio's token".into(),
                target.into(),
                format!("x-vibroscope-token: {ot}\r\n"),
            ),
            (
                "the other studio's token in its URL".into(),
                format!("{target}{sep}token={ot}"),
                String::new(),
            ),
            (
                "the other studio's cookie".into(),
                target.into(),
                format!("Cookie: vibroscope_token_{op}={ot}\r\n"),
            ),
            (
                "this token in the other port's cookie name".into(),
                target.into(),
                format!("Cookie: vibroscope_token_{op}={t}\r\n"),
            ),
        ];
        for (what, target, headers) in cases {
            let (st, b) = send(method, &target, &headers, body);
            refused_without_data(st, &b, &format!("{method} {target}, {what}"));
        }
        // What belongs gets in: the token, `localhost`, the page's own Origin.
        let want = match (method, target) {
            ("WS", _) => 101,
            _ => 200,
        };
        for headers in [
            right.clone(),
            format!("Host: localhost:{port}\r\n{right}"),
            format!("Origin: http://127.0.0.1:{port}\r\nSec-Fetch-Site: same-origin\r\n{right}"),
            format!("Cookie: vibroscope_token_{port}={t}\r\n"),
        ] {
            let (st, b) = send(method, target, &headers, body);
            assert_eq!(st, want, "{method} {target} {headers:?}: {b}");
        }
        let (st, _) = send(method, &format!("{target}{sep}token={t}"), "", body);
        let want = if target == "/" { 303 } else { want };
        assert_eq!(st, want, "{method} {target} with ?token=");
    }
    // Every refusal above was logged, without the token.
    let log = s.log();
    assert!(log.len() >= 7 * 13, "{} refusals logged", log.len());
    assert!(log.iter().any(|l| l.contains("attacker.example")));
    assert!(log.iter().all(|l| !l.contains(&t)), "{log:?}");
    // The page's security headers.
    let (st, head, _) = exchange(a, "GET", "/", &right, b"");
    assert_eq!(st, 200);
    let head = head.to_ascii_lowercase();
    for h in [
        "content-security-policy: default-src 'none'; script-src 'self'; style-src 'self';",
        "x-content-type-options: nosniff",
        "referrer-policy: no-referrer",
        "x-frame-options: deny",
    ] {
        assert!(head.contains(h), "{h}: {head}");
    }
    // Without a token, by choice: still Host and Origin.
    let open = Studio::start(&StudioOptions {
        root: Some(root.clone()),
        no_token: true,
        ..StudioOptions::default()
    })
    .unwrap();
    assert!(open.token.is_none() && !open.url.contains("token"));
    assert_eq!(raw_get(open.addr, "/api/session").0, 200);
    let h = "Host: attacker.example\r\n";
    assert_eq!(request(open.addr, "GET", "/api/session", h, b"").0, 403);
    let h = "Origin: http://attacker.example\r\n";
    assert_eq!(request(open.addr, "GET", "/api/session", h, b"").0, 403);
    // Names given with --allow-host are answered; bad ones are refused at start.
    let named = Studio::start(&StudioOptions {
        root: Some(root.clone()),
        allow_hosts: vec!["Studio.Lan".into()],
        ..StudioOptions::default()
    })
    .unwrap();
    let h = format!("Host: studio.lan:9000\r\n{}", auth(&named));
    assert_eq!(request(named.addr, "GET", "/api/session", &h, b"").0, 200);
    for (o, says) in [
        (
            StudioOptions {
                root: Some(root.clone()),
                no_token: true,
                bind: Some(IpAddr::V4(Ipv4Addr::UNSPECIFIED)),
                ..StudioOptions::default()
            },
            "--no-token",
        ),
        (
            StudioOptions {
                root: Some(root.clone()),
                allow_hosts: vec!["host:8080".into()],
                ..StudioOptions::default()
            },
            "--allow-host",
        ),
    ] {
        let e = Studio::start(&o).err().expect("refused");
        assert!(e.is_usage() && e.to_string().contains(says), "{e}");
    }
}

/// Issue 54: no answer of any route, error or not, holds the root's
/// absolute path, neither as resolved nor as given (through a symlink).
#[test]
fn no_answer_names_the_roots_absolute_path() {
    let (d, real_root) = setup();
    let given = d.path().join("via-link");
    std::os::unix::fs::symlink(&real_root, &given).unwrap();
    let s = Studio::start(&StudioOptions {
        root: Some(given.clone()),
        ..live_options(&given)
    })
    .unwrap();
    let forbidden = [
        real_root.display().to_string(),
        given.display().to_string(),
        d.path().display().to_string(),
    ];
    let mut answers = Vec::new();
    let mut ask = |method: &str, target: &str, body: &str| {
        let (st, b) = if method == "GET" {
            get(&s, target)
        } else {
            post(&s, target, body)
        };
        answers.push((format!("{method} {target} {body} -> {st}"), b));
    };
    let t0 = std::time::Instant::now();
    while get(&s, "/api/live").0 != 200 {
        assert!(t0.elapsed() < Duration::from_secs(30), "no live update");
        std::thread::sleep(Duration::from_millis(100));
    }
    for target in [
        "/",
        "/app.js",
        "/style.css",
        "/api/session",
        "/api/info?video=sub/clip.y4m",
        "/api/info?video=notes.y4m",
        "/api/info?video=missing.y4m",
        "/api/info?video=link.y4m",
        "/api/info?video=../outside/secret.y4m",
        "/api/frame?video=sub/clip.y4m&i=2",
        "/api/frame?video=notes.y4m&i=0",
        "/api/frame?video=sub/clip.y4m&i=99",
        "/api/monitor",
        "/api/live",
        "/api/live/frame",
        "/api/live/ws",
        "/nothing",
    ] {
        ask("GET", target, "");
    }
    for (target, body) in [
        ("/api/motion", "{\"video\":\"sub/clip.y4m\"}"),
        ("/api/motion", "{\"video\":\"notes.y4m\"}"),
        (
            "/api/motion",
            "{\"video\":\"sub/clip.y4m\",\"roi\":[0,0,99,99]}",
        ),
        ("/api/mode", "{\"video\":\"sub/clip.y4m\",\"freq_hz\":20}"),
        ("/api/mode", "{\"video\":\"notes.y4m\",\"freq_hz\":20}"),
        ("/api/listen", "{\"video\":\"sub/clip.y4m\"}"),
        ("/api/listen", "{\"video\":\"notes.y4m\"}"),
        (
            "/api/damping",
            "{\"video\":\"sub/clip.y4m\",\"lo_hz\":5,\"hi_hz\":30}",
        ),
        (
            "/api/damping",
            "{\"video\":\"notes.y4m\",\"lo_hz\":5,\"hi_hz\":30}",
        ),
        ("/api/idv/basis", "{\"video\":\"sub/clip.y4m\"}"),
        ("/api/idv/basis", "{\"video\":\"notes.y4m\"}"),
        ("/api/live/mode", "{\"freq_hz\":20}"),
        ("/api/motion", "not json"),
    ] {
        ask("POST", target, body);
    }
    let (st, b) = upgrade(s.addr, "/api/live/ws", &auth(&s));
    answers.push((format!("WS /api/live/ws -> {st}"), b));
    let mut errors = 0;
    for (what, body) in &answers {
        println!("{what}: {} bytes", body.len());
        errors += usize::from(body.contains("\"error\""));
        for f in &forbidden {
            assert!(!body.contains(f.as_str()), "{what} names {f}: {body}");
        }
    }
    assert!(errors >= 10, "the error answers were exercised: {errors}");
    let session: serde_json::Value = serde_json::from_str(&get(&s, "/api/session").1).unwrap();
    assert_eq!(session["root"], "root", "its name only: {session}");
}
