//! Bounded work per client: how many analyses run and wait at once (more
//! get 429), how large an analysis a request may ask for, how large an
//! answer may be, and the work of a request whose client went away
//! stopped. Also what no answer may carry: the root's absolute path.

use crate::error::ApiError;
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use vibroscope::pipeline::Cancel;

/// Analyses (motion, spectrum, modal image, sound, damping, IDV basis)
/// computed at once: the machine's two cores are each given one.
pub const ANALYSES_RUNNING: usize = 2;
/// Analyses waiting for a turn; a request beyond these gets 429.
pub const ANALYSES_WAITING: usize = 8;
/// Frames and probes read at once, and waiting (cheap, but a large
/// recording's frame can take a decoder's time).
pub const READS_RUNNING: usize = 2;
pub const READS_WAITING: usize = 16;
/// The largest answer sent, bytes: above the largest modal basis the IDV
/// route lets through (64 MiB of base64, `api::idv::MAX_PAYLOAD`, plus the
/// JSON around it); a region's sound of 600 s is 9.6 MB of WAV in base64.
pub const MAX_ANSWER: usize = 96 << 20;
/// The largest analysis a request may ask for by default: region width x
/// height x frames (4 G pixel-frames is 1920x1080 for 2000 frames, about
/// a minute of work on two cores).
pub const MAX_PIXEL_FRAMES: u64 = 4 << 30;

/// A queue of computations: at most `running` at once, `waiting` more
/// waiting for a turn, and the rest refused with 429.
pub struct Queue {
    what: &'static str,
    running: usize,
    waiting: usize,
    turns: Arc<tokio::sync::Semaphore>,
    admitted: Arc<AtomicUsize>,
}

/// One admitted computation: leaves the count when dropped.
struct Admitted(Arc<AtomicUsize>);

impl Drop for Admitted {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Cancels the computation when the request's future is dropped before it
/// ended: the client went away (hyper drops a handler whose connection
/// closed).
struct CancelOnDrop(Option<Arc<Cancel>>);

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        if let Some(c) = self.0.take() {
            c.cancel();
        }
    }
}

impl Queue {
    pub fn new(what: &'static str, running: usize, waiting: usize) -> Queue {
        Queue {
            what,
            running,
            waiting,
            turns: Arc::new(tokio::sync::Semaphore::new(running)),
            admitted: Arc::new(AtomicUsize::new(0)),
        }
    }

    /// (running, waiting) now.
    pub fn load(&self) -> (usize, usize) {
        let admitted = self.admitted.load(Ordering::SeqCst);
        let running = self.running - self.turns.available_permits();
        (running, admitted.saturating_sub(running))
    }

    /// Runs `f` off the async threads when its turn comes, or refuses it
    /// (429) when `running + waiting` are admitted already. The turn is
    /// held until `f` returns, even after the client went away: then `f`'s
    /// pipeline runs are stopped ([`Cancel`]) and the turn comes back as
    /// soon as they end. A panic in `f` becomes a 500.
    pub async fn run<T: Send + 'static>(
        &self,
        f: impl FnOnce() -> Result<T, ApiError> + Send + 'static,
    ) -> Result<T, ApiError> {
        let before = self.admitted.fetch_add(1, Ordering::SeqCst);
        let admitted = Admitted(self.admitted.clone());
        if before >= self.running + self.waiting {
            return Err(ApiError::new(
                StatusCode::TOO_MANY_REQUESTS,
                format!(
                    "too many {} at once ({} running, {} waiting): try again when one has finished",
                    self.what, self.running, self.waiting
                ),
            ));
        }
        let turn = self.turns.clone().acquire_owned().await.map_err(|_| {
            ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "the studio is stopping")
        })?;
        let cancel = Cancel::new();
        let mut on_drop = CancelOnDrop(Some(cancel.clone()));
        let r = tokio::task::spawn_blocking(move || {
            let r = Cancel::scope(&cancel, f);
            drop(turn);
            drop(admitted);
            r
        })
        .await;
        on_drop.0 = None;
        r.map_err(|e| {
            ApiError::new(
                StatusCode::INTERNAL_SERVER_ERROR,
                format!("internal error in the computation: {e}"),
            )
        })?
    }
}

/// Refuses an analysis larger than `max` pixel-frames (width x height x
/// frames; a video of unknown length is let through: its sound is bounded
/// by its duration elsewhere).
pub fn check_work(w: u64, h: u64, frames: Option<u64>, max: u64) -> Result<(), ApiError> {
    let Some(n) = frames else {
        return Ok(());
    };
    let work = w.saturating_mul(h).saturating_mul(n);
    if work > max {
        return Err(ApiError::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            format!(
                "a {w}x{h} region over {n} frames is {:.2} G pixel-frames, over this studio's bound of {:.2} G (draw a smaller region, or start the studio with a larger --max-work)",
                work as f64 / (1u64 << 30) as f64,
                max as f64 / (1u64 << 30) as f64
            ),
        ));
    }
    Ok(())
}

/// The forms in which `dir` could appear in an answer: as written, and
/// escaped as JSON writes it.
pub fn path_forms(dir: &std::path::Path) -> Vec<String> {
    let plain = dir.to_string_lossy().into_owned();
    let json = serde_json::to_string(&plain).unwrap_or_default();
    let json = json
        .strip_prefix('"')
        .and_then(|j| j.strip_suffix('"'))
        .unwrap_or("")
        .to_owned();
    let mut v = vec![plain];
    if !json.is_empty() && !v.contains(&json) {
        v.push(json);
    }
    v.retain(|f| f.len() > 1);
    v
}

/// `text` with each of `forms` (a directory) taken out: `FORM/x` becomes
/// `x`, a bare `FORM` becomes `.`.
pub fn scrub(text: &str, forms: &[String]) -> String {
    let mut out = text.to_owned();
    for f in forms {
        if out.contains(f.as_str()) {
            out = out
                .replace(&format!("{f}/"), "")
                .replace(&format!("{f}\\/"), "")
                .replace(f.as_str(), ".");
        }
    }
    out
}

/// An answer checked on its way out: over [`MAX_ANSWER`] it is replaced by
/// a 500 saying so; a JSON or text answer has the root's absolute path
/// taken out. Binary answers (PNG) and protocol switches pass as they are.
pub async fn bounded(resp: Response, forms: &[String]) -> Response {
    use axum::body::HttpBody;
    let status = resp.status();
    if status == StatusCode::SWITCHING_PROTOCOLS {
        return resp;
    }
    let too_large = |n: String| {
        ApiError::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!(
                "the answer is {n} bytes, over the studio's bound of {MAX_ANSWER}: ask for a smaller region or a shorter range"
            ),
        )
        .into_response()
    };
    let hint = resp.body().size_hint();
    if hint.lower() > MAX_ANSWER as u64 {
        return too_large(hint.lower().to_string());
    }
    let textual = resp
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.starts_with("application/json") || v.starts_with("text/plain"));
    if !textual {
        return resp;
    }
    let (mut parts, body) = resp.into_parts();
    let Ok(bytes) = axum::body::to_bytes(body, MAX_ANSWER).await else {
        return too_large(format!("over {MAX_ANSWER}"));
    };
    let text = String::from_utf8_lossy(&bytes);
    if !forms.iter().any(|f| text.contains(f.as_str())) {
        return Response::from_parts(parts, axum::body::Body::from(bytes));
    }
    parts.headers.remove(header::CONTENT_LENGTH);
    Response::from_parts(parts, axum::body::Body::from(scrub(&text, forms)))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn scrubs_the_root() {
        let forms = path_forms(std::path::Path::new("/work/shared/data"));
        assert_eq!(
            scrub(
                "{\"file\":\"/work/shared/data/guitar.mp4\",\"root\":\"/work/shared/data\"}",
                &forms
            ),
            "{\"file\":\"guitar.mp4\",\"root\":\".\"}"
        );
        let q = path_forms(std::path::Path::new("/tmp/a\"b"));
        assert!(q.contains(&"/tmp/a\\\"b".to_string()), "{q:?}");
        assert_eq!(scrub("x /tmp/a\\\"b/v.y4m", &q), "x v.y4m");
    }

    #[test]
    fn work_bound() {
        assert!(check_work(64, 64, Some(1000), MAX_PIXEL_FRAMES).is_ok());
        assert!(check_work(64, 64, None, 1).is_ok());
        let e = check_work(1920, 1080, Some(100_000), MAX_PIXEL_FRAMES).unwrap_err();
        assert_eq!(e.status, StatusCode::UNPROCESSABLE_ENTITY);
        assert!(e.message.contains("1920x1080"), "{}", e.message);
    }
}
