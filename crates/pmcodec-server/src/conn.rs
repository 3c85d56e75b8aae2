//! The accept loop, with the bounds a connection can hold the server to:
//!
//! - **a cap on open connections**: a permit is taken before `accept`, so beyond the cap new
//!   connections wait in the kernel's listen backlog (they hold no descriptor of ours) until
//!   one closes, and the server never runs out of descriptors for its own files;
//! - **a header-read timeout** (hyper's): a client that does not send a whole request head in
//!   time (a slow-loris trickle) is disconnected;
//! - **an idle timeout**: a connection with no request in progress and no byte read or written
//!   for that long is closed, so idle keep-alive sockets do not hold permits forever; one that
//!   has not sent a request yet gets only the header-read timeout (hyper's own timer starts
//!   with the first byte, so a socket that sends nothing would otherwise wait for the longer
//!   idle timeout while connections beyond the cap queue behind it).
//!
//! These protect the server itself; a reverse proxy in front (README, proto/http.md) is still
//! expected for TLS, per-client rate limits and buffering of slow clients.

use axum::Router;
use axum::body::Body;
use hyper::body::Incoming;
use hyper_util::rt::{TokioExecutor, TokioIo, TokioTimer};
use std::future::Future;
use std::io;
use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::task::{Context, Poll};
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::Semaphore;
use tokio::time::Instant;

/// The connection bounds, from [`crate::config::LimitsConfig`].
#[derive(Clone, Copy, Debug)]
pub struct ConnLimits {
    pub max_connections: usize,
    pub header_read_timeout: Duration,
    pub idle_timeout: Duration,
}

/// What a connection did last, shared by its I/O wrapper, its service and its idle watch.
struct Activity {
    start: Instant,
    /// Milliseconds from `start` to the last byte read or written.
    last_ms: AtomicU64,
    /// Requests whose handler has not answered yet.
    in_flight: AtomicUsize,
    /// Requests begun on this connection.
    requests: AtomicU64,
}

impl Activity {
    fn new() -> Activity {
        Activity { start: Instant::now(), last_ms: AtomicU64::new(0), in_flight: AtomicUsize::new(0), requests: AtomicU64::new(0) }
    }
    fn touch(&self) {
        self.last_ms.store(self.start.elapsed().as_millis() as u64, Ordering::Relaxed);
    }
    fn quiet_for(&self) -> Duration {
        self.start.elapsed().saturating_sub(Duration::from_millis(self.last_ms.load(Ordering::Relaxed)))
    }
}

/// Resolves once the connection has been idle (no request being handled, no byte moved) for
/// `limit`, or for `first` before its first request. Wakes at most a few times per limit.
async fn idle(activity: &Activity, first: Duration, later: Duration) {
    loop {
        let limit = if activity.requests.load(Ordering::Relaxed) == 0 { first } else { later };
        let quiet = activity.quiet_for();
        if quiet >= limit && activity.in_flight.load(Ordering::Relaxed) == 0 {
            return;
        }
        let wait = if quiet >= limit { limit } else { limit - quiet };
        tokio::time::sleep(wait.max(Duration::from_millis(50))).await;
    }
}

/// A TCP stream that records when bytes last moved.
struct Watched {
    inner: TcpStream,
    activity: Arc<Activity>,
}

impl AsyncRead for Watched {
    fn poll_read(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        let before = buf.filled().len();
        let r = Pin::new(&mut self.inner).poll_read(cx, buf);
        if matches!(r, Poll::Ready(Ok(()))) && buf.filled().len() > before {
            self.activity.touch();
        }
        r
    }
}

impl AsyncWrite for Watched {
    fn poll_write(mut self: Pin<&mut Self>, cx: &mut Context<'_>, data: &[u8]) -> Poll<io::Result<usize>> {
        let r = Pin::new(&mut self.inner).poll_write(cx, data);
        if matches!(r, Poll::Ready(Ok(n)) if n > 0) {
            self.activity.touch();
        }
        r
    }
    fn poll_write_vectored(mut self: Pin<&mut Self>, cx: &mut Context<'_>, bufs: &[io::IoSlice<'_>]) -> Poll<io::Result<usize>> {
        let r = Pin::new(&mut self.inner).poll_write_vectored(cx, bufs);
        if matches!(r, Poll::Ready(Ok(n)) if n > 0) {
            self.activity.touch();
        }
        r
    }
    fn is_write_vectored(&self) -> bool {
        self.inner.is_write_vectored()
    }
    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_flush(cx)
    }
    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }
}

/// Counts a request as in flight until its handler answers (its body may stream on; the
/// bytes it moves keep the connection from looking idle).
struct InFlight(Arc<Activity>);

impl InFlight {
    fn new(activity: Arc<Activity>) -> InFlight {
        activity.in_flight.fetch_add(1, Ordering::Relaxed);
        activity.requests.fetch_add(1, Ordering::Relaxed);
        InFlight(activity)
    }
}

impl Drop for InFlight {
    fn drop(&mut self) {
        self.0.in_flight.fetch_sub(1, Ordering::Relaxed);
        self.0.touch();
    }
}

/// Errors of `accept` that concern one connection (the listener is fine): try the next.
fn per_connection(e: &io::Error) -> bool {
    matches!(e.kind(), io::ErrorKind::ConnectionRefused | io::ErrorKind::ConnectionAborted | io::ErrorKind::ConnectionReset)
}

/// Serves `app` on `listener` until `shutdown` resolves; then accepts no more connections,
/// asks open ones to finish their requests and close, and returns when they have.
pub async fn serve(listener: TcpListener, app: Router, limits: ConnLimits, shutdown: impl Future<Output = ()>) {
    let permits = Arc::new(Semaphore::new(limits.max_connections.max(1)));
    let graceful = hyper_util::server::graceful::GracefulShutdown::new();
    tokio::pin!(shutdown);
    let mut last_warning = None;
    loop {
        // Taken before accepting: past the cap, connections wait in the listen backlog.
        let permit = tokio::select! {
            p = permits.clone().acquire_owned() => match p {
                Ok(p) => p,
                // The semaphore is never closed.
                Err(_) => break,
            },
            () = &mut shutdown => break,
        };
        let stream = tokio::select! {
            r = listener.accept() => match r {
                Ok((stream, _)) => stream,
                Err(e) if per_connection(&e) => continue,
                Err(e) => {
                    // Out of descriptors or memory: wait a moment rather than spin, and say so
                    // at most once a second.
                    if last_warning.is_none_or(|t: Instant| t.elapsed() >= Duration::from_secs(1)) {
                        tracing::warn!(error = %e, "accepting a connection failed (limits.max_connections above the descriptor limit?)");
                        last_warning = Some(Instant::now());
                    }
                    tokio::select! {
                        () = tokio::time::sleep(Duration::from_millis(100)) => continue,
                        () = &mut shutdown => break,
                    }
                }
            },
            () = &mut shutdown => break,
        };
        let _ = stream.set_nodelay(true);
        let activity = Arc::new(Activity::new());
        let io = TokioIo::new(Watched { inner: stream, activity: activity.clone() });
        let service = {
            let (app, activity) = (app.clone(), activity.clone());
            hyper::service::service_fn(move |req: hyper::Request<Incoming>| {
                use tower::ServiceExt;
                let in_flight = InFlight::new(activity.clone());
                let call = app.clone().oneshot(req.map(Body::new));
                async move {
                    let resp = call.await;
                    drop(in_flight);
                    resp
                }
            })
        };
        let mut builder = hyper_util::server::conn::auto::Builder::new(TokioExecutor::new());
        builder.http1().timer(TokioTimer::new()).header_read_timeout(limits.header_read_timeout);
        let conn = graceful.watch(builder.serve_connection_with_upgrades(io, service).into_owned());
        let (first_limit, idle_limit) = (limits.header_read_timeout, limits.idle_timeout);
        tokio::spawn(async move {
            let _permit = permit;
            tokio::select! {
                r = conn => if let Err(e) = r {
                    tracing::debug!(error = %e, "connection ended with an error");
                },
                () = idle(&activity, first_limit, idle_limit) => tracing::debug!("closing an idle connection"),
            }
        });
    }
    drop(listener);
    graceful.shutdown().await;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn idle_waits_for_quiet_and_for_requests_to_finish() {
        let a = Arc::new(Activity::new());
        let (first, limit) = (Duration::from_millis(50), Duration::from_millis(200));
        // Before any request, the first (header-read) limit applies.
        let t = Instant::now();
        tokio::time::timeout(Duration::from_secs(30), idle(&a, first, limit)).await.expect("idle before a request");
        assert!(t.elapsed() >= first && t.elapsed() < limit * 10, "{:?}", t.elapsed());
        let held = InFlight::new(a.clone());
        // A request in progress keeps the connection however long it is quiet.
        assert!(tokio::time::timeout(limit * 3, idle(&a, first, limit)).await.is_err());
        // Its end counts as activity: the quiet time starts again, with the idle limit.
        drop(held);
        let t = Instant::now();
        tokio::time::timeout(Duration::from_secs(30), idle(&a, first, limit)).await.expect("idle after the limit");
        assert!(t.elapsed() >= limit, "{:?}", t.elapsed());
    }
}
