//! Access control: the gate every request passes before any route (Host, Origin, the
//! token and its cookie), and the security headers every answer carries.

use axum::extract::{Request, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use std::sync::Arc;

use super::{ApiError, App};
use crate::guard;
use crate::limits;

/// The cookie that carries the token for the page's own requests, once
/// the page's URL has set it (its script, stylesheet and API calls go
/// without `?token=`): this name, then `_PORT` ([`App::with_access`]).
pub(super) const TOKEN_COOKIE: &str = "vibroscope_token";

/// Every request, WebSocket upgrades included, before any route:
/// - no encoded separators in the path (400);
/// - a `Host` that names this studio ([`Hosts::accepts`](crate::guard::Hosts::accepts)), else 403: a
///   page whose name was rebound to this machine's address is refused;
/// - no other site's page ([`guard::cross_origin`]: `Origin`,
///   `Sec-Fetch-Site`), else 403, another port of this machine included;
/// - the token when one is set (query `token=`, header
///   `x-vibroscope-token`, or the cookie set when the page was opened
///   with it), else 403. The page's URL with `?token=` answers with the
///   cookie (`HttpOnly`, `SameSite=Strict`) and a redirect to the page
///   without the token, so it stays out of the address bar and history.
///
/// Every refusal is logged ([`App::log`]). Answers carry the security
/// headers, are bounded in size and never hold the root's absolute path
/// ([`limits::bounded`]).
pub(super) async fn gate(State(app): State<Arc<App>>, req: Request, next: Next) -> Response {
    let set_cookie = match access(&app, &req) {
        Access::Answer(resp) => return resp,
        Access::Pass { set_cookie } => set_cookie,
    };
    let resp = next.run(req).await;
    let mut resp = limits::bounded(resp, &app.root_forms).await;
    security_headers(&mut resp);
    if let Some(c) = set_cookie {
        resp.headers_mut().insert(header::SET_COOKIE, c);
    }
    resp
}

/// What [`gate`] decides before the request goes on.
enum Access {
    /// Refused, or redirected: this is the answer.
    Answer(Response),
    /// Let in, setting the token's cookie when it came in the query.
    Pass { set_cookie: Option<HeaderValue> },
}

fn header_text(req: &Request, name: &str) -> Option<String> {
    req.headers().get(name).map(|v| {
        v.to_str()
            .map_or_else(|_| "(not text)".to_owned(), str::to_owned)
    })
}

fn access(app: &App, req: &Request) -> Access {
    if guard::has_encoded_separator(req.uri().path()) {
        return Access::Answer(
            ApiError::bad("encoded slashes, backslashes or NULs are not allowed in a path")
                .into_response(),
        );
    }
    let Some(host) =
        header_text(req, "host").or_else(|| req.uri().authority().map(|a| a.to_string()))
    else {
        return Access::Answer(app.refuse(req, StatusCode::BAD_REQUEST, "no Host header".into()));
    };
    if !app.hosts.accepts(&host) {
        let message = format!(
            "Host: {host} does not name this studio (it answers localhost and its own address; start it with --allow-host NAME for another name)"
        );
        return Access::Answer(app.refuse(req, StatusCode::FORBIDDEN, message));
    }
    let origin = header_text(req, "origin");
    let site = header_text(req, "sec-fetch-site");
    if let Some(why) = guard::cross_origin(origin.as_deref(), site.as_deref(), &host) {
        let message = format!("cross-origin request refused: {why}");
        return Access::Answer(app.refuse(req, StatusCode::FORBIDDEN, message));
    }
    let Some(expected) = &app.token else {
        return Access::Pass { set_cookie: None };
    };
    let from_query = req.uri().query().and_then(|q| {
        q.split('&')
            .find_map(|kv| kv.strip_prefix("token=").map(str::to_owned))
    });
    let from_cookie = || {
        req.headers()
            .get_all(header::COOKIE)
            .iter()
            .filter_map(|v| v.to_str().ok())
            .flat_map(|v| v.split(';'))
            .find_map(|kv| {
                kv.trim()
                    .strip_prefix(app.cookie.as_str())
                    .and_then(|r| r.strip_prefix('='))
                    .map(str::to_owned)
            })
    };
    let in_query = from_query.is_some();
    let given = from_query
        .or_else(|| header_text(req, "x-vibroscope-token"))
        .or_else(from_cookie);
    match given {
        None => {
            let message =
                "this studio needs its token: open the URL it printed (it ends in ?token=...)"
                    .to_owned();
            Access::Answer(app.refuse(req, StatusCode::FORBIDDEN, message))
        }
        Some(t) if !guard::same_token(&t, expected) => {
            Access::Answer(app.refuse(req, StatusCode::FORBIDDEN, "wrong token".into()))
        }
        Some(_) if in_query => {
            let set_cookie = HeaderValue::from_str(&format!(
                "{}={expected}; HttpOnly; SameSite=Strict; Path=/",
                app.cookie
            ))
            .ok();
            if req.method() != axum::http::Method::GET || req.uri().path() != "/" {
                return Access::Pass { set_cookie };
            }
            // The page's URL: the cookie, and the page again without the token.
            let rest: Vec<&str> = req
                .uri()
                .query()
                .unwrap_or("")
                .split('&')
                .filter(|kv| !kv.is_empty() && !kv.starts_with("token="))
                .collect();
            let to = if rest.is_empty() {
                "/".to_owned()
            } else {
                format!("/?{}", rest.join("&"))
            };
            let mut resp = StatusCode::SEE_OTHER.into_response();
            if let Ok(to) = HeaderValue::from_str(&to) {
                resp.headers_mut().insert(header::LOCATION, to);
            }
            if let Some(c) = set_cookie {
                resp.headers_mut().insert(header::SET_COOKIE, c);
            }
            security_headers(&mut resp);
            Access::Answer(resp)
        }
        Some(_) => Access::Pass { set_cookie: None },
    }
}

/// The page may run only its own script and style, load images and sound
/// from itself or from `data:`/`blob:` URLs it made, and talk only to the
/// studio; no other site may frame it.
const CSP: &str = "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' data: blob:; media-src 'self' data: blob:; connect-src 'self' data: blob:; base-uri 'none'; form-action 'none'; frame-ancestors 'none'";

fn security_headers(resp: &mut Response) {
    let h = resp.headers_mut();
    h.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(CSP),
    );
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    h.insert(
        header::REFERRER_POLICY,
        HeaderValue::from_static("no-referrer"),
    );
    h.insert(header::X_FRAME_OPTIONS, HeaderValue::from_static("DENY"));
}
