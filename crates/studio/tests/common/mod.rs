//! What the studio's HTTP tests share: requests written byte by byte
//! (no client normalises a path or adds a header), with or without the
//! studio's token, and small recordings.

#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::Path;
use std::time::Duration;
use vibroscope_studio::{Studio, StudioOptions};

/// `Host: 127.0.0.1:PORT` as a browser sends it, unless `headers` give a
/// Host of their own.
fn default_host(headers: &str, port: u16) -> String {
    let has_host = headers
        .split("\r\n")
        .any(|l| l.to_ascii_lowercase().starts_with("host:"));
    if has_host {
        String::new()
    } else {
        format!("Host: 127.0.0.1:{port}\r\n")
    }
}

/// One request; the status and the body.
pub fn request(
    addr: SocketAddr,
    method: &str,
    target: &str,
    headers: &str,
    body: &[u8],
) -> (u16, String) {
    let (status, _, body) = exchange(addr, method, target, headers, body);
    (status, body)
}

/// One request (`Host: 127.0.0.1:PORT` unless `headers` give one); the status,
/// the answer's head and its body.
pub fn exchange(
    addr: SocketAddr,
    method: &str,
    target: &str,
    headers: &str,
    body: &[u8],
) -> (u16, String, String) {
    let mut s = TcpStream::connect(("127.0.0.1", addr.port())).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    let host = default_host(headers, addr.port());
    let head = format!(
        "{method} {target} HTTP/1.1\r\n{host}Connection: close\r\n{headers}Content-Length: {}\r\n\r\n",
        body.len()
    );
    s.write_all(head.as_bytes()).unwrap();
    // The server may answer (413) and close before reading a large body.
    let _ = s.write_all(body);
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out);
    let text = String::from_utf8_lossy(&out).into_owned();
    let status = text
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or_else(|| panic!("no status line in {text:?}"));
    let (head, body) = text.split_once("\r\n\r\n").unwrap_or((&text, ""));
    (status, head.to_string(), body.to_string())
}

/// A GET without the token.
pub fn raw_get(addr: SocketAddr, target: &str) -> (u16, String) {
    request(addr, "GET", target, "", b"")
}

/// A POST of JSON without the token.
pub fn raw_post(addr: SocketAddr, target: &str, body: &str) -> (u16, String) {
    request(
        addr,
        "POST",
        target,
        "Content-Type: application/json\r\n",
        body.as_bytes(),
    )
}

/// The header carrying `s`'s token, as a script would send it.
pub fn auth(s: &Studio) -> String {
    s.token
        .as_ref()
        .map_or_else(String::new, |t| format!("x-vibroscope-token: {t}\r\n"))
}

/// A GET with the studio's token.
pub fn get(s: &Studio, target: &str) -> (u16, String) {
    request(s.addr, "GET", target, &auth(s), b"")
}

/// A POST of JSON with the studio's token.
pub fn post(s: &Studio, target: &str, body: &str) -> (u16, String) {
    let h = format!("Content-Type: application/json\r\n{}", auth(s));
    request(s.addr, "POST", target, &h, body.as_bytes())
}

/// A small valid Y4M (mono, 16x16, 8 frames at 100 Hz).
pub fn write_y4m(p: &Path) {
    let mut v = b"YUV4MPEG2 W16 H16 F100:1 Ip A1:1 Cmono\n".to_vec();
    for i in 0..8u8 {
        v.extend_from_slice(b"FRAME\n");
        v.extend((0..256u32).map(|k| (k as u8).wrapping_mul(7).wrapping_add(i)));
    }
    std::fs::write(p, v).unwrap();
}

pub fn error_of(body: &str) -> String {
    let v: serde_json::Value = serde_json::from_str(body).unwrap_or_else(|e| panic!("{e}: {body}"));
    v["error"].as_str().expect("an error message").to_string()
}

/// A WebSocket upgrade request for `target`: the status, and the body
/// when it is not a 101 (a 101 keeps the connection open for the socket).
pub fn upgrade(addr: SocketAddr, target: &str, headers: &str) -> (u16, String) {
    let host = default_host(headers, addr.port());
    let mut s = TcpStream::connect(("127.0.0.1", addr.port())).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    write!(
        s,
        "GET {target} HTTP/1.1\r\n{host}Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n{headers}\r\n"
    )
    .unwrap();
    let mut out = Vec::new();
    let mut b = [0u8; 1];
    while !out.ends_with(b"\r\n\r\n") && s.read(&mut b).unwrap_or(0) == 1 {
        out.push(b[0]);
    }
    let head = String::from_utf8_lossy(&out).into_owned();
    let status: u16 = head
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or_else(|| panic!("no status line in {head:?}"));
    // The connection stays open after the answer: read just its body.
    let len: usize = head
        .lines()
        .find_map(|l| {
            let (k, v) = l.split_once(':')?;
            k.eq_ignore_ascii_case("content-length")
                .then(|| v.trim().parse().ok())?
        })
        .unwrap_or(0);
    let mut body = vec![0u8; if status == 101 { 0 } else { len }];
    s.read_exact(&mut body).unwrap();
    (status, String::from_utf8_lossy(&body).into_owned())
}

/// The live pipeline the access tests run (small, a minute long), its
/// sink writing under `root`.
pub fn live_options(root: &Path) -> StudioOptions {
    StudioOptions {
        root: Some(root.to_path_buf()),
        pipeline: Some("live-spectrum".into()),
        set: vec![
            "src.fps=200.0".into(),
            "src.width=32".into(),
            "src.height=32".into(),
            "src.duration_s=60.0".into(),
            "spectrum.window=64".into(),
            "spectrum.hop=16".into(),
            format!("out.path=\"{}\"", root.join("live.json").display()),
        ],
        ..StudioOptions::default()
    }
}
