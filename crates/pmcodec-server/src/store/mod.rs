//! Where containers live: a trait and three implementations (a local folder, an S3-compatible
//! bucket, memory). Every implementation stores one object per asset, `<id>.pmc`, and makes a
//! new object visible only when it is complete, so a reader on any server sees the old asset,
//! the new one, or none, never a part.

mod local;
mod memory;
mod s3;

pub use local::LocalStore;
pub use memory::MemoryStore;
pub use s3::S3Store;

use crate::AssetId;
use bytes::Bytes;
use futures_util::future::BoxFuture;

/// One stored asset as a listing sees it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StoredObject {
    pub id: AssetId,
    pub size: u64,
    /// Changes whenever the object is replaced (an S3 ETag, a file's inode and mtime, a
    /// counter), so a server can tell a cached copy is stale without reading the object.
    pub tag: String,
}

#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("no asset {0}")]
    NotFound(AssetId),
    #[error("{0}")]
    Io(String),
    #[error("{0}")]
    Config(String),
}

/// An asset store. Methods return boxed futures so that the server can hold any store as
/// `Arc<dyn AssetStore>` chosen at run time by configuration.
pub trait AssetStore: Send + Sync + 'static {
    /// A short description for logs: "local folder /srv/assets", "s3 bucket x".
    fn describe(&self) -> String;
    /// Every asset, in id order.
    fn list(&self) -> BoxFuture<'_, Result<Vec<StoredObject>, StoreError>>;
    /// Size and tag of one asset, `None` when there is none.
    fn head<'a>(&'a self, id: &'a AssetId) -> BoxFuture<'a, Result<Option<StoredObject>, StoreError>>;
    /// The whole container with the size and tag of exactly those bytes.
    fn get<'a>(&'a self, id: &'a AssetId) -> BoxFuture<'a, Result<Option<(StoredObject, Bytes)>, StoreError>>;
    /// Stores (or replaces) an asset atomically.
    fn put<'a>(&'a self, id: &'a AssetId, bytes: Bytes) -> BoxFuture<'a, Result<StoredObject, StoreError>>;
    /// Removes an asset; `false` when there was none.
    fn delete<'a>(&'a self, id: &'a AssetId) -> BoxFuture<'a, Result<bool, StoreError>>;
    /// Whether the store answers at all (readiness).
    fn check(&self) -> BoxFuture<'_, Result<(), StoreError>>;
}

/// Builds the store a configuration names. `Samples` gives an empty memory store: the caller
/// fills it.
pub fn from_config(config: &crate::config::StoreConfig) -> Result<std::sync::Arc<dyn AssetStore>, StoreError> {
    use crate::config::StoreConfig;
    Ok(match config {
        StoreConfig::Samples | StoreConfig::Memory => std::sync::Arc::new(MemoryStore::default()),
        StoreConfig::Local { path } => std::sync::Arc::new(LocalStore::open(path)?),
        StoreConfig::S3(s3) => std::sync::Arc::new(S3Store::new(s3)?),
    })
}
