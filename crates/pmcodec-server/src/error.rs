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
    /// 400: a malformed query, header or body (the text says which parameter and why).
    #[error("{0}")]
    BadRequest(String),
    /// 400: a path names an asset id outside [`crate::AssetId`]'s alphabet.
    #[error("invalid asset id {0:?}: an id is 1 to 64 characters from a-z 0-9 . _ - and starts with a letter or digit")]
    InvalidId(String),
    /// 401: no bearer token, or the wrong one, where one is needed.
    #[error("{0}")]
    Unauthorized(String),
    /// 403: writes are disabled because no write token is configured.
    #[error("{0}")]
    Forbidden(String),
    /// 404: no such asset, job, chunk, level or frame.
    #[error("{0}")]
    NotFound(String),
    /// 405: the path exists but not with this method (the router's fallback).
    #[error("{method} is not allowed on {path}")]
    MethodNotAllowed {
        /// The request's method.
        method: String,
        /// The request's path, clipped for the message.
        path: String,
    },
    /// 409: the asset exists (create without `replace=true`), a job for it is running, or a
    /// finished job was cancelled.
    #[error("{0}")]
    Conflict(String),
    /// 413: the body is over the configured limit.
    #[error("the request body is larger than the limit of {limit} bytes")]
    PayloadTooLarge {
        /// The limit that applied, in bytes.
        limit: u64,
    },
    /// 415: an upload that is neither OBJ, glTF/GLB nor a zip of them.
    #[error("{0}")]
    UnsupportedMediaType(String),
    /// 416: no range of the `Range` header overlaps the representation.
    #[error("{detail}")]
    RangeNotSatisfiable {
        /// Which range and why.
        detail: String,
        /// The representation's length, sent as `Content-Range: bytes */len`.
        len: u64,
    },
    /// A bounded queue is full: the client should retry later.
    #[error("{0}")]
    Busy(String),
    /// 503 with `Retry-After`: the handler did not answer within the request timeout.
    #[error("no response within {0:?}")]
    Timeout(Duration),
    /// 502, or 404/409 for the store's own not-found and already-exists: the asset store failed.
    #[error("asset store: {0}")]
    Store(#[from] StoreError),
    /// 500: an asset that cannot be read or a broken invariant; logged in full, answered with a generic text.
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

    /// The HTTP status this error is answered with.
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
    /// The configuration is inconsistent (see `Config::validate`), or decode workers or the upload folder could not be set up.
    #[error("configuration: {0}")]
    Config(String),
    /// The configured store could not be opened (a missing folder, a bad S3 configuration).
    #[error("asset store: {0}")]
    Store(#[from] StoreError),
    /// The listen address could not be bound (in use, no permission).
    #[error("binding {addr}: {source}")]
    Bind {
        /// The address.
        addr: std::net::SocketAddr,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// The accept loop or the server task failed.
    #[error("serving: {0}")]
    Serve(std::io::Error),
    /// Encoding the built-in sample animations for a `samples` store failed.
    #[error("encoding the built-in samples: {0}")]
    Samples(String),
}
