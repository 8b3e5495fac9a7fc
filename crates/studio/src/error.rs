//! The studio's error answers: a status and a message the page shows, as
//! `{"error": MESSAGE}` JSON.

use crate::guard::Refusal;
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use serde_json::json;

/// An error answer: a status and a message the page shows.
#[derive(Debug)]
pub struct ApiError {
    pub status: StatusCode,
    pub message: String,
}

impl ApiError {
    pub(crate) fn new(status: StatusCode, message: impl Into<String>) -> ApiError {
        ApiError {
            status,
            message: message.into(),
        }
    }
    pub(crate) fn bad(message: impl Into<String>) -> ApiError {
        ApiError::new(StatusCode::BAD_REQUEST, message)
    }
    pub(crate) fn unprocessable(message: impl Into<String>) -> ApiError {
        ApiError::new(StatusCode::UNPROCESSABLE_ENTITY, message)
    }
}

impl From<Refusal> for ApiError {
    fn from(r: Refusal) -> ApiError {
        match r {
            Refusal::Bad(m) => ApiError::bad(m),
            Refusal::Outside(m) => ApiError::new(StatusCode::FORBIDDEN, m),
            Refusal::Missing(m) => ApiError::new(StatusCode::NOT_FOUND, m),
        }
    }
}

impl From<vibroscope::Error> for ApiError {
    /// The recipe's message; a usage error (a bad value or file) is the
    /// request's fault (422), anything else the computation's (500).
    fn from(e: vibroscope::Error) -> ApiError {
        let status = match e.kind() {
            vibroscope::ErrorKind::Usage => StatusCode::UNPROCESSABLE_ENTITY,
            _ => StatusCode::INTERNAL_SERVER_ERROR,
        };
        ApiError::new(status, e.to_string())
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        (self.status, axum::Json(json!({ "error": self.message }))).into_response()
    }
}
