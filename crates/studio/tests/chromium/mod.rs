//! Headless Chromium for the studio's browser test and its live-view
//! benchmark: chromedriver on a free port, a fresh profile, and the live
//! magnified view's scene, studio and rate measurement, shared so that the
//! benchmark measures exactly what the test drives.
//!
//! Included by `tests/browser.rs` and `benches/live_view.rs`
//! (`#[path]`): each uses part of it.

#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use fantoccini::{Client, ClientBuilder};
use serde_json::{json, Value};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use vibroscope_studio::{Studio, StudioOptions};

pub const CHROMIUM: &str = "/usr/bin/chromium";

pub const CHROMEDRIVER: &str = "/usr/bin/chromedriver";

/// chromedriver on a free port, killed when dropped.
pub struct Driver {
    child: Child,
    pub port: u16,
}

impl Drop for Driver {
    /// Ends chromedriver and the browsers it started (its process group),
    /// also when a test failed before closing its session.
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .args(["-KILL", "--", &format!("-{}", self.child.id())])
            .status();
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

pub fn start_driver() -> Driver {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let child = Command::new(CHROMEDRIVER)
        .process_group(0)
        .arg(format!("--port={port}"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start chromedriver");
    let d = Driver { child, port };
    let t0 = Instant::now();
    while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "chromedriver did not listen"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    d
}

pub async fn connect(port: u16, profile: &Path) -> Client {
    let caps = json!({
        "goog:chromeOptions": {
            "binary": CHROMIUM,
            "args": [
                "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                "--no-first-run", "--disable-quic", "--disable-component-update", "--disable-sync",
                "--disable-dev-shm-usage", "--window-size=1400,1000",
                "--autoplay-policy=no-user-gesture-required",
                format!("--user-data-dir={}", profile.display()),
            ]
        }
    });
    let Value::Object(caps) = caps else {
        unreachable!()
    };
    let connector = hyper_util::client::legacy::connect::HttpConnector::new();
    ClientBuilder::new(connector)
        .capabilities(caps)
        .connect(&format!("http://127.0.0.1:{port}"))
        .await
        .expect("a WebDriver session")
}

pub async fn js(c: &Client, script: &str) -> Value {
    c.execute(script, vec![]).await.unwrap()
}

pub fn browser_missing() -> bool {
    for p in [CHROMIUM, CHROMEDRIVER] {
        if !Path::new(p).exists() {
            println!("skipped: {p} is missing (apt-get install chromium chromium-driver)");
            return true;
        }
    }
    false
}

/// Runs `f` on a fresh headless Chromium session (chromedriver on a free
/// port, a fresh profile); `f` gives the session back to be closed.
pub fn in_browser<F: std::future::Future<Output = Client>>(f: impl FnOnce(Client) -> F) {
    let driver = start_driver();
    let profile = tempfile::tempdir().unwrap();
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        let c = f(connect(driver.port, profile.path()).await).await;
        let _ = c.close().await;
    });
}

pub async fn live(c: &Client, expr: &str) -> Value {
    js(
        c,
        &format!("return window.studio && window.studio.live ? {expr} : null"),
    )
    .await
}

/// The magnified view's clip: 640x480 at 60 fps, a textured object moving
/// at 4 and 12 Hz; 25 s, so that the browser test's band changes after the
/// 10 s measured (and Chromium's start before it) find frames left on a
/// machine where the page takes 30 frames a second or fewer.
pub const MAG_FPS: f64 = 60.0;
pub const MAG_FRAMES: usize = 1500;

/// A scene (the simulator's TOML) rendered into `dir` as `NAME.y4m` (the
/// scene kept beside it as `NAME.toml`).
pub fn render(dir: &Path, name: &str, scene: &str) -> PathBuf {
    let scene_path = dir.join(format!("{name}.toml"));
    std::fs::write(&scene_path, scene).unwrap();
    let video = dir.join(format!("{name}.y4m"));
    vibroscope::simulate::simulate(&vibroscope::simulate::SimulateOptions {
        scene: scene_path,
        output: video.clone(),
        ..Default::default()
    })
    .unwrap();
    video
}

/// Renders the magnified view's clip into `dir` (`clip.y4m`).
pub fn magnified_clip(dir: &Path) -> PathBuf {
    render(
        dir,
        "clip",
        &format!(
            "width = 640\nheight = 480\nfps = {MAG_FPS}\nframes = {MAG_FRAMES}\n\
             signal = {{ type = \"tones\", freqs_hz = [4.0, 12.0] }}\n"
        ),
    )
}

/// The studio running the shipped `live-magnify` graph on a replay of
/// `clip` at its own pace (60 fps), Riesz pyramid, 3-5 Hz x20, its output
/// written to `dir/out.y4m`.
pub fn magnified_studio(dir: &Path, clip: &Path) -> Studio {
    Studio::start(&StudioOptions {
        root: Some(dir.to_path_buf()),
        pipeline: Some("live-magnify".into()),
        replay: Some(clip.to_path_buf()),
        set: vec![
            "mag.pyramid=\"riesz\"".into(),
            "mag.lo_hz=3.0".into(),
            "mag.hi_hz=5.0".into(),
            "mag.factor=20.0".into(),
            format!("out.path=\"{}\"", dir.join("out.y4m").display()),
            // Headless Chromium's renderer runs at nice -8 and can hold
            // both cores for tens of milliseconds: the ring before the
            // magnifier holds a quarter second (the shipped 4 frames are
            // 67 ms). The drops that remain are counted and shown.
            "mag.input={ from = \"cam\", capacity = 16 }".into(),
        ],
        ..StudioOptions::default()
    })
    .unwrap()
}

/// The frame count of the `magnify` stage's drops in the page's last update.
pub async fn mag_dropped(c: &Client) -> u64 {
    live(
        c,
        "window.studio.live.last.stages.find((s) => s.id === 'mag').dropped",
    )
    .await
    .as_u64()
    .unwrap()
}

/// Opens the studio's page and waits (30 s at most) until the live
/// view's `counter` reaches `n`; panics with the page's error if it shows
/// one, or saying that no `what` reached the page.
pub async fn open_live(c: &Client, studio: &Studio, counter: &str, n: u64, what: &str) {
    c.set_window_size(1400, 1000).await.unwrap();
    c.goto(&studio.url).await.unwrap();
    let t0 = Instant::now();
    while live(c, &format!("window.studio.live.{counter}"))
        .await
        .as_u64()
        .unwrap_or(0)
        < n
    {
        let e = js(c, "return window.studio ? window.studio.lastError : null").await;
        assert!(e.is_null(), "the page shows an error: {e}");
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "no {what} reached the page"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// Ten seconds of the magnified view, on the page's own clock.
pub struct MagnifiedRate {
    /// Magnified frames drawn on the page.
    pub shown: f64,
    /// The page's seconds they were drawn in.
    pub secs: f64,
    /// Frames the replay gave in that time (the last frame number's advance).
    pub made: f64,
    /// Frame numbers the page skipped: dropped before the magnifier, or
    /// made and not sent to the page because it was slower.
    pub skipped: f64,
    /// The magnifier's drops (its input ring's) at the start and the end.
    pub dropped: (u64, u64),
    /// The page's own line about the view.
    pub info: String,
}

impl MagnifiedRate {
    /// Frames drawn a second.
    pub fn rate(&self) -> f64 {
        self.shown / self.secs
    }
}

/// Opens the studio's page, waits for 30 magnified frames on it, then
/// counts what the page draws for 10 s.
pub async fn magnified_rate(c: &Client, studio: &Studio) -> MagnifiedRate {
    open_live(c, studio, "magShown", 30, "magnified frames").await;
    let q = "[window.studio.live.magShown, performance.now(), window.studio.live.magFrame, window.studio.live.magGaps]";
    let a = live(c, q).await;
    let dropped0 = mag_dropped(c).await;
    tokio::time::sleep(Duration::from_secs(10)).await;
    let b = live(c, q).await;
    let dropped1 = mag_dropped(c).await;
    let f = |v: &Value, i: usize| v[i].as_f64().unwrap();
    let info = js(
        c,
        "return document.getElementById('livemaginfo').textContent",
    )
    .await;
    MagnifiedRate {
        shown: f(&b, 0) - f(&a, 0),
        secs: (f(&b, 1) - f(&a, 1)) / 1e3,
        made: f(&b, 2) - f(&a, 2),
        skipped: f(&b, 3) - f(&a, 3),
        dropped: (dropped0, dropped1),
        info: info.as_str().unwrap_or_default().to_owned(),
    }
}

impl std::fmt::Display for MagnifiedRate {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "magnified view: {} frames drawn in {:.2} s = {:.1}/s of {} frames the replay gave \
             ({:.1}/s); frame numbers skipped {}; dropped before the magnifier {} -> {}\n  page: {}",
            self.shown,
            self.secs,
            self.rate(),
            self.made,
            self.made / self.secs,
            self.skipped,
            self.dropped.0,
            self.dropped.1,
            self.info
        )
    }
}
