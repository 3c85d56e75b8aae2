//! Prometheus metrics in the text exposition format (version 0.0.4), written by hand: a few
//! counters and one histogram do not need a metrics framework.
//!
//! Labels are bounded: `route` is the matched route template (or "other"), `method` one of the
//! standard methods (or "OTHER"), `status` a three-digit code.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// Upper bounds (seconds) of the latency histogram's buckets.
const BUCKETS: [f64; 14] = [0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0];

#[derive(Default)]
struct Histogram {
    counts: [u64; BUCKETS.len()],
    count: u64,
    sum: f64,
}

pub struct Metrics {
    started: Instant,
    requests: Mutex<BTreeMap<(&'static str, String, u16), u64>>,
    latency: Mutex<BTreeMap<String, Histogram>>,
    pub jobs_succeeded: AtomicU64,
    pub jobs_failed: AtomicU64,
}

impl Default for Metrics {
    fn default() -> Self {
        Metrics {
            started: Instant::now(),
            requests: Mutex::default(),
            latency: Mutex::default(),
            jobs_succeeded: AtomicU64::new(0),
            jobs_failed: AtomicU64::new(0),
        }
    }
}

/// Gauges read from the rest of the server when metrics are scraped.
pub struct Gauges {
    pub ready: bool,
    pub asset_cache_bytes: u64,
    pub asset_cache_entries: usize,
    pub decode: crate::decode::DecodeGauges,
    pub jobs_pending: usize,
}

pub fn method_label(m: &axum::http::Method) -> &'static str {
    use axum::http::Method;
    match *m {
        Method::GET => "GET",
        Method::HEAD => "HEAD",
        Method::POST => "POST",
        Method::PUT => "PUT",
        Method::DELETE => "DELETE",
        Method::OPTIONS => "OPTIONS",
        Method::PATCH => "PATCH",
        _ => "OTHER",
    }
}

impl Metrics {
    pub fn record(&self, method: &'static str, route: &str, status: u16, elapsed: Duration) {
        *self.requests.lock().unwrap_or_else(|p| p.into_inner()).entry((method, route.to_string(), status)).or_default() += 1;
        let secs = elapsed.as_secs_f64();
        let mut lat = self.latency.lock().unwrap_or_else(|p| p.into_inner());
        let h = lat.entry(route.to_string()).or_default();
        h.count += 1;
        h.sum += secs;
        // Buckets are cumulative in the exposition; here each holds its own count.
        if let Some(i) = BUCKETS.iter().position(|&b| secs <= b) {
            h.counts[i] += 1;
        }
    }

    pub fn render(&self, g: &Gauges) -> String {
        let mut out = String::with_capacity(4096);
        let mut metric = |name: &str, kind: &str, help: &str, value: String| {
            let _ = writeln!(out, "# HELP {name} {help}\n# TYPE {name} {kind}\n{name} {value}");
        };
        metric("pmcodec_up_seconds", "gauge", "Seconds since the server started.", format!("{:.3}", self.started.elapsed().as_secs_f64()));
        metric("pmcodec_ready", "gauge", "1 when the server is ready to serve.", u8::from(g.ready).to_string());
        metric("pmcodec_asset_cache_bytes", "gauge", "Container bytes held in the asset LRU.", g.asset_cache_bytes.to_string());
        metric("pmcodec_asset_cache_entries", "gauge", "Assets held in the asset LRU.", g.asset_cache_entries.to_string());
        let d = &g.decode;
        metric(
            "pmcodec_decode_state_bytes",
            "gauge",
            "Estimated bytes of the decoder states kept (all workers).",
            d.state_bytes.to_string(),
        );
        metric("pmcodec_decode_states", "gauge", "Decoder states kept (all workers).", d.states.to_string());
        metric("pmcodec_decode_workers", "gauge", "Decode worker threads.", d.workers.to_string());
        metric("pmcodec_decode_queued", "gauge", "Mesh requests waiting for a decode worker.", d.queued.to_string());
        metric("pmcodec_decode_requests_total", "counter", "Mesh requests sent to the decode workers.", d.requests.to_string());
        metric("pmcodec_decode_state_hits_total", "counter", "Mesh requests served from a kept decoder state.", d.hits.to_string());
        metric(
            "pmcodec_decode_state_misses_total",
            "counter",
            "Mesh requests that found no state at their frame and built one.",
            d.misses.to_string(),
        );
        metric(
            "pmcodec_decode_keyframe_starts_total",
            "counter",
            "Misses that found no earlier state of the keyframe interval and decoded from the keyframe.",
            d.keyframe_starts.to_string(),
        );
        metric("pmcodec_jobs_pending", "gauge", "Encode jobs queued or running.", g.jobs_pending.to_string());
        let _ = writeln!(
            out,
            "# HELP pmcodec_jobs_finished_total Encode jobs finished, by result.\n# TYPE pmcodec_jobs_finished_total counter\npmcodec_jobs_finished_total{{result=\"succeeded\"}} {}\npmcodec_jobs_finished_total{{result=\"failed\"}} {}",
            self.jobs_succeeded.load(Ordering::Relaxed),
            self.jobs_failed.load(Ordering::Relaxed)
        );

        out.push_str(
            "# HELP pmcodec_http_requests_total HTTP requests by method, route and status.\n# TYPE pmcodec_http_requests_total counter\n",
        );
        for ((method, route, status), n) in self.requests.lock().unwrap_or_else(|p| p.into_inner()).iter() {
            let _ = writeln!(out, "pmcodec_http_requests_total{{method=\"{method}\",route=\"{}\",status=\"{status}\"}} {n}", escape(route));
        }
        out.push_str("# HELP pmcodec_http_request_duration_seconds Time to the response head, by route.\n# TYPE pmcodec_http_request_duration_seconds histogram\n");
        for (route, h) in self.latency.lock().unwrap_or_else(|p| p.into_inner()).iter() {
            let route = escape(route);
            let mut cumulative = 0;
            for (b, c) in BUCKETS.iter().zip(h.counts) {
                cumulative += c;
                let _ = writeln!(out, "pmcodec_http_request_duration_seconds_bucket{{route=\"{route}\",le=\"{b}\"}} {cumulative}");
            }
            let _ = writeln!(out, "pmcodec_http_request_duration_seconds_bucket{{route=\"{route}\",le=\"+Inf\"}} {}", h.count);
            let _ = writeln!(out, "pmcodec_http_request_duration_seconds_sum{{route=\"{route}\"}} {}", h.sum);
            let _ = writeln!(out, "pmcodec_http_request_duration_seconds_count{{route=\"{route}\"}} {}", h.count);
        }
        out
    }
}

/// Label values escape backslash, double quote and newline.
fn escape(s: &str) -> String {
    s.replace('\\', "\\\\").replace('"', "\\\"").replace('\n', "\\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histogram_buckets_are_cumulative() {
        let m = Metrics::default();
        m.record("GET", "/v1/assets", 200, Duration::from_micros(300));
        m.record("GET", "/v1/assets", 200, Duration::from_millis(3));
        m.record("GET", "/v1/assets", 404, Duration::from_secs(60));
        let g = Gauges {
            ready: true,
            asset_cache_bytes: 1,
            asset_cache_entries: 1,
            decode: crate::decode::DecodeGauges { workers: 2, keyframe_starts: 7, ..Default::default() },
            jobs_pending: 0,
        };
        let text = m.render(&g);
        assert!(text.contains("pmcodec_http_requests_total{method=\"GET\",route=\"/v1/assets\",status=\"200\"} 2"), "{text}");
        assert!(text.contains("le=\"0.0005\"} 1\n"), "{text}");
        assert!(text.contains("le=\"0.005\"} 2\n"), "{text}");
        assert!(text.contains("le=\"10\"} 2\n"), "{text}");
        assert!(text.contains("le=\"+Inf\"} 3\n"), "{text}");
        assert!(text.contains("pmcodec_ready 1\n"));
        assert!(text.contains("pmcodec_decode_keyframe_starts_total 7\n"), "{text}");
    }
}
