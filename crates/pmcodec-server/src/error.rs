//! Every error a request can meet, mapped to a status and a JSON body in one place, and the
//! errors of starting a server.

use crate::store::StoreError;
use axum::Json;
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use std::time::Duration;

/// What went wrong with a request. Each variant is one kind of answer; [`IntoResponse`] below is
/// the only place that turns them into statuses and bodies.
#[derive(Debug, thiserror::Error)]
pub enum ApiError {
    #[error("{0}")]
    BadRequest(String),
    #[error("invalid asset id {0:?}: an id is 1 to 64 characters from a-z 0-9 . _ - and starts with a letter or digit")]
    InvalidId(String),
    #[error("{0}")]
    Unauthorized(String),
    #[error("{0}")]
    Forbidden(String),
    #[error("{0}")]
    NotFound(String),
    #[error("{method} is not allowed on {path}")]
    MethodNotAllowed { method: String, path: String },
    #[error("{0}")]
    Conflict(String),
    #[error("the request body is larger than the limit of {limit} bytes")]
    PayloadTooLarge { limit: u64 },
    #[error("{0}")]
    UnsupportedMediaType(String),
    #[error("{detail}")]
    RangeNotSatisfiable { detail: String, len: u64 },
    /// A bounded queue is full: the client should retry later.
    #[error("{0}")]
    Busy(String),
    #[error("no response within {0:?}")]
    Timeout(Duration),
    #[error("asset store: {0}")]
    Store(#[from] StoreError),
    #[error("{0}")]
    Internal(String),
}

impl ApiError {
    /// The status and the machine-readable `error` kind of each variant.
    fn status_and_kind(&self) -> (StatusCode, &'static str) {
        match self {
            ApiError::BadRequest(_) => (StatusCode::BAD_REQUEST, "bad_request"),
            ApiError::InvalidId(_) => (StatusCode::BAD_REQUEST, "invalid_id"),
            ApiError::Unauthorized(_) => (StatusCode::UNAUTHORIZED, "unauthorized"),
            ApiError::Forbidden(_) => (StatusCode::FORBIDDEN, "forbidden"),
            ApiError::NotFound(_) => (StatusCode::NOT_FOUND, "not_found"),
            ApiError::MethodNotAllowed { .. } => (StatusCode::METHOD_NOT_ALLOWED, "method_not_allowed"),
            ApiError::Conflict(_) => (StatusCode::CONFLICT, "conflict"),
            ApiError::PayloadTooLarge { .. } => (StatusCode::PAYLOAD_TOO_LARGE, "payload_too_large"),
            ApiError::UnsupportedMediaType(_) => (StatusCode::UNSUPPORTED_MEDIA_TYPE, "unsupported_media_type"),
            ApiError::RangeNotSatisfiable { .. } => (StatusCode::RANGE_NOT_SATISFIABLE, "range_not_satisfiable"),
            ApiError::Busy(_) => (StatusCode::SERVICE_UNAVAILABLE, "busy"),
            ApiError::Timeout(_) => (StatusCode::SERVICE_UNAVAILABLE, "timeout"),
            ApiError::Store(StoreError::NotFound(_)) => (StatusCode::NOT_FOUND, "not_found"),
            ApiError::Store(StoreError::AlreadyExists(_)) => (StatusCode::CONFLICT, "conflict"),
            ApiError::Store(_) => (StatusCode::BAD_GATEWAY, "store_error"),
            ApiError::Internal(_) => (StatusCode::INTERNAL_SERVER_ERROR, "internal"),
        }
    }

    pub fn status(&self) -> StatusCode {
        self.status_and_kind().0
    }
}

/// Longest `detail` of an error body.
const MAX_DETAIL: usize = 1024;

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let (status, kind) = self.status_and_kind();
        // Server-side failures are logged in full (inside the request's span, so with its
        // request id) but not echoed: their text can name hosts, paths and keys.
        let detail = if status.is_server_error() && !matches!(self, ApiError::Busy(_) | ApiError::Timeout(_)) {
            tracing::error!(error = %self, "request failed");
            match &self {
                ApiError::Store(_) => "the asset store failed; the server log has the details".to_string(),
                _ => "internal error; the server log has the details".to_string(),
            }
        } else {
            // Client errors can quote the request (an id, a parameter's name): a quote of a
            // 64 KB URL is cut short.
            crate::middleware::clip_to(&self.to_string(), MAX_DETAIL).into_owned()
        };
        let mut resp = (status, Json(serde_json::json!({ "error": kind, "detail": detail }))).into_response();
        let h = resp.headers_mut();
        match &self {
            ApiError::Unauthorized(_) => {
                h.insert(header::WWW_AUTHENTICATE, HeaderValue::from_static("Bearer"));
            }
            ApiError::RangeNotSatisfiable { len, .. } => {
                if let Ok(v) = HeaderValue::from_str(&format!("bytes */{len}")) {
                    h.insert(header::CONTENT_RANGE, v);
                }
            }
            ApiError::Busy(_) | ApiError::Timeout(_) => {
                h.insert(header::RETRY_AFTER, HeaderValue::from_static("1"));
            }
            _ => {}
        }
        // Errors are about this request at this moment: never cache them.
        h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
        resp
    }
}

/// Why a server could not start.
#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    #[error("configuration: {0}")]
    Config(String),
    #[error("asset store: {0}")]
    Store(#[from] StoreError),
    #[error("binding {addr}: {source}")]
    Bind { addr: std::net::SocketAddr, source: std::io::Error },
    #[error("serving: {0}")]
    Serve(std::io::Error),
    #[error("encoding the built-in samples: {0}")]
    Samples(String),
}
