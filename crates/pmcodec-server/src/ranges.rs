//! Immutable representations over HTTP (RFC 9110): strong ETags, `If-None-Match` (304),
//! `Range` with one range (206) or several (206 `multipart/byteranges`), `If-Range`, 416 for
//! valid ranges that select nothing, and invalid ones ignored (200). Bodies are slices of the shared container bytes, not copies.

use crate::ApiError;
use axum::body::Body;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use bytes::Bytes;
use std::ops::Range;

/// `Cache-Control` of every content-addressed URL: its bytes can never change.
pub const IMMUTABLE: &str = "public, max-age=31536000, immutable";

/// A representation to serve.
pub struct Representation {
    pub bytes: Bytes,
    /// A strong entity tag, quotes included.
    pub etag: String,
    pub content_type: &'static str,
    pub cache_control: &'static str,
}

/// What a `Range` header asks for, given the representation's length.
#[derive(Debug, PartialEq)]
pub enum RangeRequest {
    /// Send the whole representation (200): another unit, a syntactically invalid range set
    /// (RFC 9110 section 14.1.1: the recipient MUST ignore the field), or more ranges than we
    /// serve (section 14.2 allows ignoring them).
    Ignore,
    /// Satisfiable ranges, in the order asked, end exclusive.
    Ranges(Vec<Range<u64>>),
}

/// Parses a `Range` header value. A valid byte-range set whose every range starts beyond the
/// end (or is an empty suffix) is an error (416, with the length); unsatisfiable members of a
/// set that has satisfiable ones are dropped.
pub fn parse_range(value: &str, len: u64, max_ranges: usize) -> Result<RangeRequest, ApiError> {
    let Some((unit, set)) = value.split_once('=') else {
        return Ok(RangeRequest::Ignore);
    };
    if !unit.trim().eq_ignore_ascii_case("bytes") {
        return Ok(RangeRequest::Ignore);
    }
    // Empty list elements are allowed by the list syntax (RFC 9110 section 5.6.1), but a set
    // needs at least one range.
    let specs: Vec<&str> = set.split(',').map(str::trim).filter(|s| !s.is_empty()).collect();
    if specs.is_empty() || specs.len() > max_ranges {
        return Ok(RangeRequest::Ignore);
    }
    // A position: decimal digits; more than u64 holds is a position beyond any representation.
    let number = |s: &str| (!s.is_empty() && s.bytes().all(|b| b.is_ascii_digit())).then(|| s.parse().unwrap_or(u64::MAX));
    let mut out = Vec::with_capacity(specs.len());
    for spec in specs {
        let Some((first, last)) = spec.split_once('-') else {
            return Ok(RangeRequest::Ignore);
        };
        if first.is_empty() {
            let Some(suffix) = number(last) else {
                return Ok(RangeRequest::Ignore);
            };
            if suffix > 0 && len > 0 {
                out.push(len - suffix.min(len)..len);
            }
            continue;
        }
        let Some(start) = number(first) else {
            return Ok(RangeRequest::Ignore);
        };
        let end = if last.is_empty() {
            len
        } else {
            match number(last) {
                // first-last with last < first is syntactically invalid.
                Some(l) if l >= start => l.saturating_add(1).min(len),
                _ => return Ok(RangeRequest::Ignore),
            }
        };
        if start < len {
            out.push(start..end);
        }
    }
    if out.is_empty() {
        return Err(ApiError::RangeNotSatisfiable {
            detail: format!("Range {value:?}: no range overlaps the representation, which has {len} bytes"),
            len,
        });
    }
    Ok(RangeRequest::Ranges(out))
}

/// Entity-tag list membership. `weak` comparison (for If-None-Match) ignores `W/`; strong
/// comparison (for If-Range) needs both tags strong and equal.
fn etag_matches(list: &str, etag: &str, weak: bool) -> bool {
    list.split(',').map(str::trim).any(|t| {
        if t == "*" {
            return true;
        }
        if weak { t.trim_start_matches("W/") == etag.trim_start_matches("W/") } else { !t.starts_with("W/") && t == etag }
    })
}

fn header_str(h: &HeaderMap, name: header::HeaderName) -> Option<&str> {
    h.get(name).and_then(|v| v.to_str().ok())
}

/// Answers a GET (or HEAD) of an immutable representation.
pub fn serve(req: &HeaderMap, rep: Representation, max_ranges: usize) -> Result<Response, ApiError> {
    let etag = HeaderValue::from_str(&rep.etag).map_err(|e| ApiError::Internal(format!("etag {:?}: {e}", rep.etag)))?;
    let mut base = HeaderMap::new();
    base.insert(header::ETAG, etag);
    base.insert(header::CACHE_CONTROL, HeaderValue::from_static(rep.cache_control));
    base.insert(header::ACCEPT_RANGES, HeaderValue::from_static("bytes"));

    if header_str(req, header::IF_NONE_MATCH).is_some_and(|v| etag_matches(v, &rep.etag, true)) {
        return Ok((StatusCode::NOT_MODIFIED, base).into_response());
    }
    base.insert(header::CONTENT_TYPE, HeaderValue::from_static(rep.content_type));
    let len = rep.bytes.len() as u64;
    let whole = |base: HeaderMap| Ok((StatusCode::OK, base, Body::from(rep.bytes.clone())).into_response());

    let Some(range) = header_str(req, header::RANGE) else {
        return whole(base);
    };
    // If-Range: the client's partial copy is of this representation only if its validator
    // is our strong ETag; otherwise (another tag, or a date: we send no Last-Modified) it must
    // get everything again.
    if header_str(req, header::IF_RANGE).is_some_and(|v| !etag_matches(v, &rep.etag, false) || v.trim() == "*") {
        return whole(base);
    }
    let ranges = match parse_range(range, len, max_ranges)? {
        RangeRequest::Ignore => return whole(base),
        RangeRequest::Ranges(r) => r,
    };
    // Many overlapping ranges could ask for far more than the file: serve it whole instead
    // (RFC 9110 section 14.2 lets a server ignore such requests).
    if ranges.iter().map(|r| r.end - r.start).sum::<u64>() > 2 * len.max(1) {
        return whole(base);
    }
    if let [r] = ranges.as_slice() {
        let mut h = base;
        h.insert(header::CONTENT_RANGE, value(&format!("bytes {}-{}/{len}", r.start, r.end - 1))?);
        return Ok((StatusCode::PARTIAL_CONTENT, h, Body::from(rep.bytes.slice(r.start as usize..r.end as usize))).into_response());
    }
    // multipart/byteranges (RFC 9110 section 14.6): each part has its own Content-Type and
    // Content-Range. The boundary is random, so it cannot occur in the data by design.
    let boundary = uuid::Uuid::new_v4().simple().to_string();
    let mut parts: Vec<Bytes> = Vec::with_capacity(2 * ranges.len() + 1);
    for r in &ranges {
        let head = format!(
            "\r\n--{boundary}\r\nContent-Type: {}\r\nContent-Range: bytes {}-{}/{len}\r\n\r\n",
            rep.content_type,
            r.start,
            r.end - 1
        );
        parts.push(Bytes::from(head));
        parts.push(rep.bytes.slice(r.start as usize..r.end as usize));
    }
    parts.push(Bytes::from(format!("\r\n--{boundary}--\r\n")));
    let total: usize = parts.iter().map(Bytes::len).sum();
    let mut h = base;
    h.insert(header::CONTENT_TYPE, value(&format!("multipart/byteranges; boundary={boundary}"))?);
    h.insert(header::CONTENT_LENGTH, value(&total.to_string())?);
    let body = Body::from_stream(futures_util::stream::iter(parts.into_iter().map(Ok::<_, std::convert::Infallible>)));
    Ok((StatusCode::PARTIAL_CONTENT, h, body).into_response())
}

fn value(s: &str) -> Result<HeaderValue, ApiError> {
    HeaderValue::from_str(s).map_err(|e| ApiError::Internal(format!("header {s:?}: {e}")))
}

#[cfg(test)]
#[allow(clippy::single_range_in_vec_init)] // one-range sets are what these tests check
mod tests {
    use super::*;

    fn ranges(v: &str, len: u64) -> Result<Vec<Range<u64>>, String> {
        match parse_range(v, len, 4) {
            Ok(RangeRequest::Ranges(r)) => Ok(r),
            Ok(RangeRequest::Ignore) => Err("ignore".into()),
            Err(e) => Err(e.to_string()),
        }
    }

    #[test]
    fn single_suffix_open_and_clamped_ranges() {
        assert_eq!(ranges("bytes=0-9", 100), Ok(vec![0..10]));
        assert_eq!(ranges("bytes=90-", 100), Ok(vec![90..100]));
        assert_eq!(ranges("bytes=-10", 100), Ok(vec![90..100]));
        assert_eq!(ranges("bytes=-1000", 100), Ok(vec![0..100]));
        assert_eq!(ranges("bytes=50-1000", 100), Ok(vec![50..100]));
        assert_eq!(ranges("BYTES = 1-1", 100), Ok(vec![1..2]));
        assert!(ranges("bytes=99999999999999999999999-", 100).unwrap_err().contains("overlaps"));
        assert_eq!(ranges("bytes=0-99999999999999999999999", 100), Ok(vec![0..100]));
    }

    #[test]
    fn sets_drop_unsatisfiable_members_and_fail_when_empty() {
        assert_eq!(ranges("bytes=0-1, ,5-6", 100), Ok(vec![0..2, 5..7]));
        assert_eq!(ranges("bytes=0-1,200-300", 100), Ok(vec![0..2]));
        for unsatisfiable in ["bytes=100-", "bytes=-0", "bytes=100-200,-0"] {
            assert!(ranges(unsatisfiable, 100).unwrap_err().contains("overlaps"), "{unsatisfiable}");
        }
        assert!(ranges("bytes=0-", 0).is_err(), "nothing is satisfiable in an empty representation");
    }

    /// RFC 9110 section 14.1.1: a set with a syntactically invalid member is ignored whole.
    #[test]
    fn invalid_sets_are_ignored() {
        for bad in ["bytes=5-1", "bytes=5-1,0-0", "bytes=", "bytes=a-b", "bytes=1", "bytes=--1", "bytes=zz", "0-1", "bytes=1-2-3"] {
            assert_eq!(ranges(bad, 100), Err("ignore".into()), "{bad}");
        }
    }

    #[test]
    fn other_units_and_too_many_ranges_are_ignored() {
        assert_eq!(ranges("items=0-1", 100), Err("ignore".into()));
        assert_eq!(ranges("bytes=0-0,1-1,2-2,3-3,4-4", 100), Err("ignore".into()));
    }

    #[test]
    fn etag_comparison() {
        assert!(etag_matches("\"a\", \"b\"", "\"b\"", true));
        assert!(etag_matches("W/\"b\"", "\"b\"", true));
        assert!(!etag_matches("W/\"b\"", "\"b\"", false));
        assert!(etag_matches("*", "\"b\"", true));
        assert!(!etag_matches("\"c\"", "\"b\"", true));
    }
}
