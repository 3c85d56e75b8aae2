//! Several byte ranges in one request (RFC 9110 section 14.2): the answer is one range (206
//! with `Content-Range`), several (206 `multipart/byteranges`, section 14.6), or the whole
//! representation (200, which a server may send instead); each case gives the ranges asked.

use crate::ClientError;
use std::ops::Range;

/// Most ranges asked in one request: the browser player's bound too, below the server's
/// default limit (64), past which a server may answer with the whole file.
pub const MAX_RANGES_PER_REQUEST: usize = 16;

/// The `Range` header value asking for `ranges` (end exclusive).
pub fn range_header(ranges: &[Range<u64>]) -> String {
    let set: Vec<String> = ranges.iter().map(|r| format!("{}-{}", r.start, r.end - 1)).collect();
    format!("bytes={}", set.join(","))
}

/// `bytes a-b/len` (a `Content-Range` value): the range, end exclusive.
fn content_range(v: &str) -> Option<Range<u64>> {
    let spec = v.trim().strip_prefix("bytes ")?;
    let (span, _) = spec.split_once('/')?;
    let (a, b) = span.split_once('-')?;
    let (a, b): (u64, u64) = (a.trim().parse().ok()?, b.trim().parse().ok()?);
    // A server's numbers: `b = u64::MAX` must not overflow the exclusive end.
    (b >= a).then_some(a..b.checked_add(1)?)
}

/// A range of the file and its bytes.
type Part = (Range<u64>, Vec<u8>);

/// Parts of a `multipart/byteranges` body: each part's range and bytes. Parts are read by their
/// `Content-Range` lengths, not by searching for the boundary in the data.
fn parts(body: &[u8], boundary: &str) -> Result<Vec<Part>, ClientError> {
    let bad = |what: &str| ClientError::Protocol(format!("multipart/byteranges: {what}"));
    let delimiter = format!("--{boundary}");
    let find =
        |from: usize, needle: &[u8]| body.get(from..).and_then(|b| b.windows(needle.len()).position(|w| w == needle)).map(|i| from + i);
    let mut at = find(0, delimiter.as_bytes()).ok_or_else(|| bad("no boundary"))?;
    let mut out = Vec::new();
    loop {
        at += delimiter.len();
        if body.get(at..at + 2) == Some(b"--") {
            return Ok(out);
        }
        let head_end = find(at, b"\r\n\r\n").ok_or_else(|| bad("a part without headers"))?;
        let head = std::str::from_utf8(&body[at..head_end]).map_err(|_| bad("headers not UTF-8"))?;
        let range = head
            .lines()
            .filter_map(|l| l.split_once(':'))
            .find(|(k, _)| k.trim().eq_ignore_ascii_case("content-range"))
            .and_then(|(_, v)| content_range(v))
            .ok_or_else(|| bad("a part without a Content-Range"))?;
        let start = head_end + 4;
        // The part's length as the server states it, at most what the body holds after it.
        let end = usize::try_from(range.end - range.start).ok().and_then(|n| start.checked_add(n));
        let bytes = end.and_then(|end| body.get(start..end)).ok_or_else(|| bad("a part cut short"))?;
        let end = start + bytes.len();
        out.push((range, bytes.to_vec()));
        at = find(end, delimiter.as_bytes()).ok_or_else(|| bad("no closing boundary"))?;
    }
}

/// The bytes of each of `ranges` from an answer of `status` with `content_type`,
/// `content_range` and `body`.
pub fn split_answer(
    ranges: &[Range<u64>],
    status: u16,
    content_type: Option<&str>,
    content_range_value: Option<&str>,
    body: &[u8],
) -> Result<Vec<Vec<u8>>, ClientError> {
    let held: Vec<Part> = match (status, content_type) {
        (200, _) => vec![(0..body.len() as u64, body.to_vec())],
        (206, Some(ct)) if ct.to_ascii_lowercase().starts_with("multipart/byteranges") => {
            let boundary = ct
                .split(';')
                .filter_map(|p| p.trim().split_once('='))
                .find(|(k, _)| k.trim().eq_ignore_ascii_case("boundary"))
                .map(|(_, v)| v.trim().trim_matches('"').to_string())
                .ok_or_else(|| ClientError::Protocol("multipart/byteranges without a boundary".into()))?;
            parts(body, &boundary)?
        }
        (206, _) => {
            let r =
                content_range_value.and_then(content_range).ok_or_else(|| ClientError::Protocol("206 without a Content-Range".into()))?;
            if r.end - r.start != body.len() as u64 {
                return Err(ClientError::Protocol(format!("Content-Range of {} bytes, body of {}", r.end - r.start, body.len())));
            }
            vec![(r, body.to_vec())]
        }
        _ => return Err(ClientError::Protocol(format!("HTTP {status} to a range request"))),
    };
    ranges
        .iter()
        .map(|want| {
            held.iter()
                .find(|(r, _)| r.start <= want.start && want.end <= r.end)
                .map(|(r, b)| b[(want.start - r.start) as usize..(want.end - r.start) as usize].to_vec())
                .ok_or_else(|| ClientError::Protocol(format!("bytes {}..{} missing from the answer", want.start, want.end)))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::single_range_in_vec_init)] // one-range sets are what some of these check
    use super::*;

    #[test]
    fn multipart_answers_split_by_their_ranges() {
        let body = b"\r\n--xyz\r\nContent-Type: a/b\r\nContent-Range: bytes 2-4/10\r\n\r\n--x\r\n--xyz\r\nContent-Range: bytes 7-7/10\r\n\r\nq\r\n--xyz--\r\n";
        let got = split_answer(&[2..5, 7..8, 3..4], 206, Some("multipart/byteranges; boundary=xyz"), None, body).unwrap();
        assert_eq!(got, vec![b"--x".to_vec(), b"q".to_vec(), b"-".to_vec()]);
        assert!(split_answer(&[0..1], 206, Some("multipart/byteranges; boundary=xyz"), None, body).is_err());
        assert!(split_answer(&[2..5], 206, Some("multipart/byteranges; boundary=xyz"), None, &body[..40]).is_err());
    }

    #[test]
    fn single_and_whole_answers() {
        assert_eq!(split_answer(&[3..5], 206, Some("x"), Some("bytes 3-4/9"), b"ab").unwrap(), vec![b"ab".to_vec()]);
        assert!(split_answer(&[3..5], 206, Some("x"), Some("bytes 3-5/9"), b"ab").is_err());
        assert_eq!(split_answer(&[1..3, 0..1], 200, None, None, b"abc").unwrap(), vec![b"bc".to_vec(), b"a".to_vec()]);
        assert_eq!(range_header(&[0..10, 12..13]), "bytes=0-9,12-12");
    }

    /// A server's numbers at their limits are errors, not overflows: a range ending at
    /// u64::MAX, a part longer than the body, a 206 whose single range is that long.
    #[test]
    fn ranges_at_the_limits_are_refused() {
        let max = u64::MAX;
        assert!(split_answer(&[0..1], 206, Some("x"), Some(&format!("bytes 0-{max}/{max}")), b"a").is_err());
        for head in [format!("bytes 0-{max}/*"), format!("bytes {}-{max}/*", max - 1), format!("bytes 1-{}/*", max - 1)] {
            let body = format!("--b\r\nContent-Range: {head}\r\n\r\nabc\r\n--b--\r\n");
            let e = split_answer(&[0..1], 206, Some("multipart/byteranges; boundary=b"), None, body.as_bytes()).unwrap_err();
            assert!(e.to_string().contains("multipart/byteranges"), "{head}: {e}");
        }
    }

    /// Damaged multipart answers (every cut and every byte changed of a good one, and random
    /// bytes) give an answer or an error, never a panic.
    #[test]
    fn damaged_multipart_answers_never_panic() {
        let good = b"\r\n--xyz\r\nContent-Range: bytes 2-4/10\r\n\r\n--x\r\n--xyz\r\nContent-Range: bytes 7-7/10\r\n\r\nq\r\n--xyz--\r\n";
        let ct = Some("multipart/byteranges; boundary=xyz");
        for cut in 0..good.len() {
            let _ = split_answer(&[2..5, 7..8], 206, ct, None, &good[..cut]);
        }
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for at in 0..good.len() {
            for b in [0u8, b'-', b'9', b'\r', 0xff] {
                let mut d = good.to_vec();
                d[at] = b;
                let _ = split_answer(&[2..5, 7..8], 206, ct, None, &d);
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let noise: Vec<u8> = (0..(state % 64) as usize).map(|i| (state >> (i % 8 * 8)) as u8).collect();
                d.splice(at..at, noise);
                let _ = split_answer(&[2..5, 7..8], 206, ct, None, &d);
            }
        }
    }
}
