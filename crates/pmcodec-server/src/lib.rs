//! The pmcodec HTTP server (see proto/http.md): a list of assets, LOD on demand (any frame at any
//! triangle budget, level or error bound, as GLB or a compact binary), and each asset's
//! container bytes at a stable, immutable URL with ETag and Range support for streaming clients.
//!
//! Assets are `.pmc` files held in memory. With no asset folder the server encodes its built-in
//! sample animations at start, so it runs with no data at all.

mod error;
mod routes;

pub use error::ApiError;
pub use routes::{MESH_MAGIC, ROUTES, parse_range, router};

use pmcodec_container::{EncodeOptions, Reader, encode};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

/// One servable asset.
#[derive(Debug)]
pub struct Asset {
    pub id: String,
    /// The whole container.
    pub bytes: Vec<u8>,
    /// Strong validator: CRC-32 of the bytes and their length (assets never change in place).
    pub etag: String,
}

impl Asset {
    /// Checks the bytes are a readable container before they are served.
    pub fn new(id: String, bytes: Vec<u8>) -> Result<Self, ApiError> {
        validate_id(&id)?;
        Reader::open(bytes.as_slice()).map_err(|e| ApiError::BadRequest(format!("asset {id}: {e}")))?;
        let etag = format!("\"{:08x}-{:x}\"", crc32fast::hash(&bytes), bytes.len());
        Ok(Asset { id, bytes, etag })
    }

    pub fn reader(&self) -> Result<Reader<&[u8]>, ApiError> {
        Reader::open(self.bytes.as_slice()).map_err(|e| ApiError::Internal(format!("asset {}: {e}", self.id)))
    }
}

/// Shared state: the assets, by id.
#[derive(Debug, Default)]
pub struct AppState {
    pub assets: BTreeMap<String, Arc<Asset>>,
}

/// Asset ids: lowercase letters, digits, `.`, `_`, `-`, starting with a letter or digit, at most
/// 64 characters. Nothing else can reach a path or a key.
pub fn validate_id(id: &str) -> Result<(), ApiError> {
    let ok = !id.is_empty()
        && id.len() <= 64
        && id.bytes().enumerate().all(|(i, b)| b.is_ascii_lowercase() || b.is_ascii_digit() || (i > 0 && matches!(b, b'.' | b'_' | b'-')))
        && !id.contains("..");
    if ok { Ok(()) } else { Err(ApiError::BadRequest(format!("invalid asset id {id:?}: use [a-z0-9][a-z0-9._-]{{0,63}}"))) }
}

/// The built-in samples, encoded.
pub fn builtin_assets() -> Result<Vec<Asset>, ApiError> {
    pmcodec_mesh::samples::NAMES
        .iter()
        .map(|&name| {
            let seq = pmcodec_mesh::samples::by_name(name).ok_or_else(|| ApiError::Internal(format!("no sample {name}")))?;
            let bytes = encode(&seq, &EncodeOptions::default(), |_| {}).map_err(|e| ApiError::Internal(format!("encoding {name}: {e}")))?;
            Asset::new(name.to_string(), bytes)
        })
        .collect()
}

/// Every `*.pmc` in a folder, by file stem.
pub fn folder_assets(dir: &Path) -> Result<Vec<Asset>, ApiError> {
    let entries = std::fs::read_dir(dir).map_err(|e| ApiError::Internal(format!("{}: {e}", dir.display())))?;
    let mut out = Vec::new();
    for entry in entries {
        let path = entry.map_err(|e| ApiError::Internal(e.to_string()))?.path();
        if path.extension().is_some_and(|e| e == "pmc") {
            let id = path.file_stem().map(|s| s.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
            let bytes = std::fs::read(&path).map_err(|e| ApiError::Internal(format!("{}: {e}", path.display())))?;
            out.push(Asset::new(id, bytes)?);
        }
    }
    out.sort_by(|a, b| a.id.cmp(&b.id));
    Ok(out)
}

/// Server configuration.
#[derive(Clone, Debug)]
pub struct Config {
    pub assets: Option<std::path::PathBuf>,
    pub listen: std::net::SocketAddr,
    /// Folder of the built viewer, served at `/` when present.
    pub viewer: Option<std::path::PathBuf>,
}

/// Loads the assets and serves until SIGINT/SIGTERM; `ready` is called with the bound address.
pub async fn serve(config: Config, ready: impl FnOnce(std::net::SocketAddr)) -> Result<(), ApiError> {
    let assets = match &config.assets {
        Some(dir) => folder_assets(dir)?,
        None => tokio::task::spawn_blocking(builtin_assets).await.map_err(|e| ApiError::Internal(e.to_string()))??,
    };
    let state = Arc::new(AppState { assets: assets.into_iter().map(|a| (a.id.clone(), Arc::new(a))).collect() });
    let app = router(state, config.viewer.as_deref());
    let listener = tokio::net::TcpListener::bind(config.listen).await.map_err(|e| ApiError::Internal(format!("binding {}: {e}", config.listen)))?;
    let addr = listener.local_addr().map_err(|e| ApiError::Internal(e.to_string()))?;
    ready(addr);
    axum::serve(listener, app)
        .with_graceful_shutdown(async {
            let ctrl_c = tokio::signal::ctrl_c();
            #[cfg(unix)]
            {
                let mut term = match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
                    Ok(t) => t,
                    Err(_) => return,
                };
                tokio::select! { _ = ctrl_c => {}, _ = term.recv() => {} }
            }
            #[cfg(not(unix))]
            let _ = ctrl_c.await;
        })
        .await
        .map_err(|e| ApiError::Internal(e.to_string()))
}
