//! Request plumbing: request ids, the request log and metrics, timeouts, bearer tokens,
//! compression and CORS.

use crate::{ApiError, AppState};
use axum::extract::{FromRequestParts, MatchedPath, Request, State};
use axum::http::request::Parts;
use axum::http::{HeaderName, HeaderValue, Method, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use std::time::{Duration, Instant};
use tracing::Instrument;

pub static REQUEST_ID: HeaderName = HeaderName::from_static("x-request-id");

/// A client's own request id is kept when it is short and plain (so it can be logged safely);
/// otherwise the server makes one.
fn request_id(req: &Request) -> String {
    req.headers()
        .get(&REQUEST_ID)
        .and_then(|v| v.to_str().ok())
        .filter(|v| {
            !v.is_empty() && v.len() <= 128 && v.bytes().all(|b| b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_' | b'.' | b':'))
        })
        .map(str::to_string)
        .unwrap_or_else(|| uuid::Uuid::new_v4().simple().to_string())
}

/// Outermost layer: gives the request an id (echoed in `x-request-id`), runs it inside a span
/// carrying that id, writes one log line per request (method, path and query, range, status,
/// time) and counts it in the metrics under its route template.
pub async fn request_context(State(app): State<AppState>, mut req: Request, next: Next) -> Response {
    let id = request_id(&req);
    if let Ok(v) = HeaderValue::from_str(&id) {
        req.headers_mut().insert(REQUEST_ID.clone(), v);
    }
    let method = req.method().clone();
    let uri = clip(&req.uri().to_string()).into_owned();
    let route = req.extensions().get::<MatchedPath>().map_or_else(|| "other".to_string(), |p| p.as_str().to_string());
    let range = req.headers().get(header::RANGE).and_then(|v| v.to_str().ok()).map(str::to_string);
    let span = tracing::info_span!("request", id = %id);
    let start = Instant::now();
    let mut resp = next.run(req).instrument(span.clone()).await;
    let elapsed = start.elapsed();
    let status = resp.status().as_u16();
    span.in_scope(|| {
        tracing::info!(
            target: "pmcodec::request",
            "{method} {uri} range={} status={status} {:.1}ms",
            range.as_deref().unwrap_or("-"),
            elapsed.as_secs_f64() * 1e3
        )
    });
    app.metrics.record(crate::metrics::method_label(&method), &route, status, elapsed);
    if let Ok(v) = HeaderValue::from_str(&id) {
        resp.headers_mut().insert(REQUEST_ID.clone(), v);
    }
    // Every answer's type is the one it says (the viewer's files and JSON errors alike).
    resp.headers_mut().insert(header::X_CONTENT_TYPE_OPTIONS, HeaderValue::from_static("nosniff"));
    resp
}

/// Longest part of a URL echoed in an error body or a log line.
pub const MAX_ECHOED_URL: usize = 256;

/// A URL or path cut to [`MAX_ECHOED_URL`] bytes (at a character boundary) with a note of its
/// length: a 64 KB URL is not written back in full to the client or into the logs.
pub fn clip(s: &str) -> std::borrow::Cow<'_, str> {
    clip_to(s, MAX_ECHOED_URL)
}

/// `s` cut to at most `max` bytes (at a character boundary) with a note of its length.
pub fn clip_to(s: &str, max: usize) -> std::borrow::Cow<'_, str> {
    if s.len() <= max {
        return s.into();
    }
    let mut end = max;
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    format!("{}... ({} bytes)", &s[..end], s.len()).into()
}

/// Bounds the time to a response head (bodies stream on afterwards) with a JSON 503.
pub async fn timeout(State(limit): State<Duration>, req: Request, next: Next) -> Response {
    match tokio::time::timeout(limit, next.run(req)).await {
        Ok(resp) => resp,
        Err(_) => ApiError::Timeout(limit).into_response(),
    }
}

/// The bearer token of a request, if it sent one.
fn bearer(parts_headers: &axum::http::HeaderMap) -> Option<&str> {
    let v = parts_headers.get(header::AUTHORIZATION)?.to_str().ok()?;
    let (scheme, token) = v.split_once(' ')?;
    scheme.eq_ignore_ascii_case("bearer").then(|| token.trim())
}

/// Compares the SHA-256 digests of the two strings in time independent of where they differ,
/// so that response timing reveals neither a token prefix nor its length (comparing the
/// strings themselves returned early when their lengths differed).
fn same_secret(a: &str, b: &str) -> bool {
    use sha2::{Digest, Sha256};
    let (a, b) = (Sha256::digest(a.as_bytes()), Sha256::digest(b.as_bytes()));
    a.iter().zip(b.iter()).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// Reads under /v1 need the read token (or the write token) when one is configured.
pub async fn read_auth(State(app): State<AppState>, req: Request, next: Next) -> Response {
    if let Some(read) = &app.config.auth.read_token {
        let ok = bearer(req.headers()).is_some_and(|t| {
            same_secret(t, read.expose()) || app.config.auth.write_token.as_ref().is_some_and(|w| same_secret(t, w.expose()))
        });
        if !ok {
            return ApiError::Unauthorized("this server needs a bearer token for reads: send Authorization: Bearer <token>".into())
                .into_response();
        }
    }
    next.run(req).await
}

/// Proof that a request carries the write token: handlers that change assets take it as an
/// argument, so they cannot run without it.
pub struct WriteAccess;

impl FromRequestParts<AppState> for WriteAccess {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, app: &AppState) -> Result<Self, ApiError> {
        let Some(token) = &app.config.auth.write_token else {
            return Err(ApiError::Forbidden(
                "writes are disabled: the server has no write token configured (auth.write_token or PMCODEC_WRITE_TOKEN)".into(),
            ));
        };
        match bearer(&parts.headers) {
            Some(t) if same_secret(t, token.expose()) => Ok(WriteAccess),
            Some(_) => Err(ApiError::Unauthorized("the bearer token is not the write token".into())),
            None => Err(ApiError::Unauthorized("writes need a bearer token: send Authorization: Bearer <token>".into())),
        }
    }
}

/// Compress where it pays: JSON, text and the viewer's files, whole (200) and large enough.
/// Never containers, chunks and meshes (chunks are zstd frames already; float and index data
/// barely shrink), never partial content (206: the ranges are of the uncompressed bytes), never
/// event streams (compression would hold events back).
#[derive(Clone, Copy, Debug, Default)]
pub struct CompressWhenItPays;

/// Runs outside the compression layer: a compressed body is a different byte sequence from the
/// identity one, so the representation's strong entity tag (RFC 9110 8.8.1) becomes weak. Its
/// revalidations still match (If-None-Match compares weakly) and no cache can pair the
/// compressed bytes with an identity range.
pub async fn weaken_etag_when_encoded(req: Request, next: Next) -> Response {
    let mut resp = next.run(req).await;
    let h = resp.headers_mut();
    if h.contains_key(header::CONTENT_ENCODING)
        && let Some(tag) = h.get(header::ETAG).and_then(|v| v.to_str().ok()).filter(|t| !t.starts_with("W/"))
        && let Ok(weak) = HeaderValue::from_str(&format!("W/{tag}"))
    {
        h.insert(header::ETAG, weak);
    }
    resp
}

impl tower_http::compression::Predicate for CompressWhenItPays {
    fn should_compress<B>(&self, response: &axum::http::Response<B>) -> bool
    where
        B: axum::body::HttpBody,
    {
        if response.status() != axum::http::StatusCode::OK {
            return false;
        }
        let ctype = response.headers().get(header::CONTENT_TYPE).and_then(|v| v.to_str().ok()).unwrap_or("");
        let compressible = [
            "application/json",
            "text/plain",
            "text/html",
            "text/css",
            "text/javascript",
            "application/javascript",
            "application/yaml",
            "image/svg+xml",
        ]
        .iter()
        .any(|t| ctype.starts_with(t));
        let big_enough = response.body().size_hint().exact().is_none_or(|n| n >= 512);
        compressible && big_enough
    }
}

/// CORS for the viewer and other browser clients.
pub fn cors(origins: &[String]) -> tower_http::cors::CorsLayer {
    use tower_http::cors::{AllowOrigin, CorsLayer};
    let allow = if origins.iter().any(|o| o == "*") {
        AllowOrigin::any()
    } else {
        AllowOrigin::list(origins.iter().filter_map(|o| HeaderValue::from_str(o).ok()))
    };
    CorsLayer::new()
        .allow_origin(allow)
        .allow_methods([Method::GET, Method::HEAD, Method::POST, Method::DELETE, Method::OPTIONS])
        .allow_headers([
            header::AUTHORIZATION,
            header::RANGE,
            header::IF_NONE_MATCH,
            header::IF_RANGE,
            header::CONTENT_TYPE,
            REQUEST_ID.clone(),
        ])
        .expose_headers([
            header::ETAG,
            header::CONTENT_RANGE,
            header::ACCEPT_RANGES,
            header::CONTENT_LENGTH,
            REQUEST_ID.clone(),
            HeaderName::from_static("x-pmc-version"),
            HeaderName::from_static("x-pmc-vertices"),
            HeaderName::from_static("x-pmc-triangles"),
            HeaderName::from_static("x-pmc-level"),
            HeaderName::from_static("x-pmc-from"),
            HeaderName::from_static("server-timing"),
            header::LOCATION,
        ])
        .max_age(Duration::from_secs(3600))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bearer_tokens_and_comparison() {
        let mut h = axum::http::HeaderMap::new();
        assert_eq!(bearer(&h), None);
        h.insert(header::AUTHORIZATION, HeaderValue::from_static("Bearer  s3cret "));
        assert_eq!(bearer(&h), Some("s3cret"));
        h.insert(header::AUTHORIZATION, HeaderValue::from_static("Basic abc"));
        assert_eq!(bearer(&h), None);
        assert!(same_secret("abc", "abc"));
        assert!(!same_secret("abc", "abd") && !same_secret("abc", "abcd") && !same_secret("", "abc"));
    }

    #[test]
    fn long_urls_are_clipped_at_a_character_boundary() {
        assert_eq!(clip("/v1/assets"), "/v1/assets");
        let long = format!("/{}", "é".repeat(40_000));
        let c = clip(&long);
        assert!(c.len() < MAX_ECHOED_URL + 40 && c.ends_with("(80001 bytes)"), "{c}");
    }
}
