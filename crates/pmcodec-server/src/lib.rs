//! The pmcodec HTTP server (proto/http.md, proto/openapi.yaml).
//!
//! - Assets are `.pmc` containers in an [`AssetStore`]: a local folder (default), an
//!   S3-compatible bucket shared by any number of stateless servers, or memory (the built-in
//!   samples, encoded at start when no store is configured).
//! - **LOD on demand**: any frame at a triangle budget, level or error bound, as GLB or a compact
//!   binary, decoded on worker threads that keep decoder states in a bounded LRU (module `decode`).
//! - **Streaming**: the container, its chunk table and each chunk at content-addressed,
//!   immutable URLs with strong ETags, conditional requests and (multi-)range support
//!   (module `ranges`), and a playback-order stream limited to the levels a client draws.
//! - **Uploads** (bearer token) become encode jobs with progress over SSE (module `jobs`); the asset
//!   appears with one atomic store write when the job succeeds.
//! - **Operations**: request ids and tracing, Prometheus metrics, health and readiness, body
//!   limits, timeouts, compression of JSON, CORS, graceful shutdown (module `middleware`).

#![warn(missing_docs)]

mod assets;
pub mod config;
mod conn;
mod decode;
mod error;
mod id;
mod jobs;
mod looks;
mod lru;
mod meshfmt;
mod metrics;
mod middleware;
mod ranges;
mod routes;
pub mod store;
mod upload;

pub use config::Config;
pub use error::{ApiError, ServerError};
pub use id::AssetId;
pub use meshfmt::{MESH_MAGIC, MeshFormat, decode_bin, decode_bin_appearance, encode_bin, encode_bin_v3};
pub use routes::{mounted_routes, router};
pub use store::{AssetStore, PutMode, StoreError};

use assets::AssetCache;
use decode::DecodePool;
use jobs::Jobs;
use metrics::Metrics;
use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use tokio::sync::watch;

/// Everything a handler can reach, passed explicitly as axum state.
#[derive(Clone)]
pub struct AppState(Arc<Inner>);

/// The server's shared state behind [`AppState`]: configuration, store, caches, jobs, metrics.
pub struct Inner {
    /// The configuration the server started with (read only after start).
    pub config: Config,
    /// The asset store every server of a deployment shares.
    pub store: Arc<dyn AssetStore>,
    pub(crate) assets: AssetCache,
    pub(crate) decoder: Arc<DecodePool>,
    pub(crate) jobs: Jobs,
    pub(crate) metrics: Metrics,
    /// False until the store is filled (samples) and after shutdown began.
    pub ready: AtomicBool,
    /// Flips to true when shutdown begins; long responses (SSE) end on it.
    pub shutdown: watch::Sender<bool>,
}

impl std::ops::Deref for AppState {
    type Target = Inner;
    fn deref(&self) -> &Inner {
        &self.0
    }
}

impl AppState {
    /// State over a store; `ready` starts false.
    pub fn new(config: Config, store: Arc<dyn AssetStore>) -> Result<AppState, ServerError> {
        config.validate().map_err(ServerError::Config)?;
        if let Some(dir) = &config.upload_dir
            && !dir.is_dir()
        {
            return Err(ServerError::Config(format!("upload_dir {}: not a folder", dir.display())));
        }
        let c = &config.cache;
        let decoder = Arc::new(
            DecodePool::new(c.decode_workers, c.decode_bytes, config.limits.decode_queue)
                .map_err(|e| ServerError::Config(format!("starting decode workers: {e}")))?,
        );
        let purge = decoder.clone();
        let assets = AssetCache::new(
            store.clone(),
            c.asset_bytes,
            std::time::Duration::from_millis(c.revalidate_ms),
            Box::new(move |version| purge.purge(version)),
        );
        let l = &config.limits;
        let jobs = Jobs::new(l.encode_concurrency, l.max_pending_jobs, l.finished_jobs_kept);
        Ok(AppState(Arc::new(Inner {
            store,
            assets,
            decoder,
            jobs,
            metrics: Metrics::default(),
            ready: AtomicBool::new(false),
            shutdown: watch::channel(false).0,
            config,
        })))
    }

    /// Opens or closes `/readyz`: it answers 503 while `ready` is false.
    pub fn set_ready(&self, ready: bool) {
        self.ready.store(ready, Ordering::SeqCst);
    }

    /// Whether `/readyz` answers 200.
    pub fn is_ready(&self) -> bool {
        self.ready.load(Ordering::SeqCst)
    }

    /// Encodes the built-in sample animations into the store (a few seconds of CPU).
    pub async fn load_samples(&self) -> Result<(), ServerError> {
        let tasks: Vec<_> = pmcodec_mesh::samples::NAMES
            .iter()
            .map(|&name| {
                let (keyframes, motion) = (self.config.keyframe_interval, self.config.motion);
                tokio::task::spawn_blocking(move || -> Result<(AssetId, Vec<u8>), String> {
                    let seq = pmcodec_mesh::samples::by_name(name).ok_or_else(|| format!("no sample {name}"))?;
                    let opts = pmcodec_container::EncodeOptions { keyframe_interval: keyframes, motion, ..Default::default() };
                    let bytes = pmcodec_container::encode(&seq, &opts, |_| {}).map_err(|e| format!("{name}: {e}"))?;
                    Ok((AssetId::parse(name).map_err(|e| e.to_string())?, bytes))
                })
            })
            .collect();
        for t in tasks {
            let (id, bytes) = t.await.map_err(|e| ServerError::Samples(e.to_string()))?.map_err(ServerError::Samples)?;
            self.store.put(&id, bytes.into(), PutMode::Overwrite).await?;
            tracing::info!(asset = %id, "built-in sample ready");
        }
        Ok(())
    }

    /// Serves on `listener` until `shutdown` completes, then lets open requests finish for at
    /// most the configured grace period.
    pub async fn serve(
        self,
        listener: tokio::net::TcpListener,
        shutdown: impl Future<Output = ()> + Send + 'static,
    ) -> Result<(), ServerError> {
        let app = router(self.clone());
        let grace = std::time::Duration::from_secs(self.config.limits.shutdown_grace_secs);
        let mut begun = self.shutdown.subscribe();
        let state = self.clone();
        let l = &self.config.limits;
        let limits = conn::ConnLimits {
            max_connections: l.max_connections,
            header_read_timeout: l.header_read_timeout(),
            idle_timeout: l.idle_timeout(),
        };
        let server = conn::serve(listener, app, limits, async move {
            shutdown.await;
            tracing::info!("shutting down: no new connections; finishing open requests");
            state.set_ready(false);
            let _ = state.shutdown.send(true);
        });
        tokio::select! {
            () = server => Ok(()),
            _ = async {
                let _ = begun.wait_for(|stop| *stop).await;
                tokio::time::sleep(grace).await;
            } => {
                tracing::warn!("requests still open {grace:?} after shutdown began; stopping anyway");
                Ok(())
            }
        }
    }
}

/// Resolves on SIGINT (Ctrl-C) or SIGTERM (container runtimes).
pub async fn shutdown_signal() {
    let ctrl_c = async {
        if tokio::signal::ctrl_c().await.is_err() {
            // No handler could be installed: never resolve from here.
            std::future::pending::<()>().await;
        }
    };
    #[cfg(unix)]
    {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut term) => tokio::select! { _ = ctrl_c => {}, _ = term.recv() => {} },
            Err(_) => ctrl_c.await,
        }
    }
    #[cfg(not(unix))]
    ctrl_c.await;
}

/// A server running in the background of the current tokio runtime (tests, embedding).
pub struct RunningServer {
    /// The address actually bound (the OS picks the port when the configuration says 0).
    pub addr: SocketAddr,
    /// The server's state, for tests that look at or change it while it runs.
    pub state: AppState,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    task: tokio::task::JoinHandle<Result<(), ServerError>>,
}

impl RunningServer {
    /// `http://addr`, for clients.
    pub fn url(&self) -> String {
        format!("http://{}", self.addr)
    }

    /// Begins a graceful shutdown and waits for it.
    pub async fn stop(mut self) -> Result<(), ServerError> {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        (&mut self.task).await.map_err(|e| ServerError::Serve(std::io::Error::other(e)))?
    }
}

impl Drop for RunningServer {
    fn drop(&mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
    }
}

/// Starts a server from a configuration on the current runtime and returns once it listens
/// and is ready (the built-in samples, when configured, are encoded first). Port 0 in
/// `config.listen` picks a free port; [`RunningServer::addr`] says which.
pub async fn start(config: Config) -> Result<RunningServer, ServerError> {
    let store = store::from_config(&config.store)?;
    let samples = matches!(config.store, config::StoreConfig::Samples);
    let listen = config.listen;
    let state = AppState::new(config, store)?;
    let listener = tokio::net::TcpListener::bind(listen).await.map_err(|source| ServerError::Bind { addr: listen, source })?;
    let addr = listener.local_addr().map_err(ServerError::Serve)?;
    if samples {
        state.load_samples().await?;
    }
    state.set_ready(true);
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let task = tokio::spawn(state.clone().serve(listener, async move {
        let _ = stopped.await;
    }));
    Ok(RunningServer { addr, state, stop: Some(stop), task })
}

/// Starts a server from a configuration: builds the store, binds, calls `on_bound` with the
/// address, fills the samples store when that is the configured one, and serves until SIGINT
/// or SIGTERM.
pub async fn run(config: Config, on_bound: impl FnOnce(SocketAddr)) -> Result<(), ServerError> {
    config.validate().map_err(ServerError::Config)?;
    let store = store::from_config(&config.store)?;
    tracing::info!(store = %store.describe(), "asset store");
    let samples = matches!(config.store, config::StoreConfig::Samples);
    let listen = config.listen;
    let state = AppState::new(config, store)?;
    let listener = tokio::net::TcpListener::bind(listen).await.map_err(|source| ServerError::Bind { addr: listen, source })?;
    let addr = listener.local_addr().map_err(ServerError::Serve)?;
    on_bound(addr);
    if samples {
        // Listen at once (health checks answer) and become ready when the samples are in.
        let s = state.clone();
        tokio::spawn(async move {
            match s.load_samples().await {
                Ok(()) => s.set_ready(true),
                Err(e) => tracing::error!(error = %e, "the built-in samples could not be prepared; staying not ready"),
            }
        });
    } else {
        state.set_ready(true);
    }
    state.serve(listener, shutdown_signal()).await
}
