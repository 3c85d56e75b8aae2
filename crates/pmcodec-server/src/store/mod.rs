//! Where containers live: a trait and three implementations (a local folder, an S3-compatible
//! bucket, memory). Every implementation stores one object per asset, `<id>.pmc`, and makes a
//! new object visible only when it is complete, so a reader on any server sees the old asset,
//! the new one, or none, never a part. Beside it may sit `<id>.meta.json`, a cache of what a
//! listing shows, tagged with the container it describes.
//!
//! A write either replaces what is there or creates only ([`PutMode`]). A create-only write is
//! a single check-and-write step in the store itself (a hard link that fails on an existing
//! name, an S3 `If-None-Match: *` PUT, an insert under a lock), so that of two servers creating
//! the same asset at once at most one wins and the other gets [`StoreError::AlreadyExists`].

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
    /// The asset.
    pub id: AssetId,
    /// Bytes of the container.
    pub size: u64,
    /// Changes whenever the object is replaced (an S3 ETag, a file's inode and mtime, a
    /// counter), so a server can tell a cached copy is stale without reading the object.
    pub tag: String,
}

/// What [`AssetStore::put`] does when the asset exists.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PutMode {
    /// Replace it.
    Overwrite,
    /// Leave it as it is and fail with [`StoreError::AlreadyExists`]. The existence check and
    /// the write are one atomic step in the store, not a read followed by a write.
    Create,
}

/// Why a store operation failed.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// The asset is not in the store.
    #[error("no asset {0}")]
    NotFound(AssetId),
    /// A [`PutMode::Create`] write found the asset there; nothing was written.
    #[error("asset {0} exists")]
    AlreadyExists(AssetId),
    /// Reading, writing, listing or deleting failed in the store (a file system or S3 error).
    #[error("{0}")]
    Io(String),
    /// The store could not be opened as configured (a missing folder, an empty bucket name).
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
    /// Stores an asset atomically: readers see the whole new object or what was there before.
    /// An existing asset is replaced ([`PutMode::Overwrite`]) or kept, failing the write with
    /// [`StoreError::AlreadyExists`] ([`PutMode::Create`]).
    fn put<'a>(&'a self, id: &'a AssetId, bytes: Bytes, mode: PutMode) -> BoxFuture<'a, Result<StoredObject, StoreError>>;
    /// Removes an asset (and its listing metadata); `false` when there was none.
    fn delete<'a>(&'a self, id: &'a AssetId) -> BoxFuture<'a, Result<bool, StoreError>>;
    /// The listing metadata kept beside an asset (`<id>.meta.json`), if any: what a listing
    /// shows of it and the tag of the container it describes, so that a cold server lists a
    /// bucket without reading every container. It is only ever a cache: a reader checks the
    /// tag against the container's and falls back to the container. Stores without a place
    /// for it keep these defaults (none; writes dropped).
    fn get_meta<'a>(&'a self, _id: &'a AssetId) -> BoxFuture<'a, Result<Option<Bytes>, StoreError>> {
        Box::pin(async { Ok(None) })
    }
    /// Writes (replaces) the listing metadata of an asset, atomically.
    fn put_meta<'a>(&'a self, _id: &'a AssetId, _bytes: Bytes) -> BoxFuture<'a, Result<(), StoreError>> {
        Box::pin(async { Ok(()) })
    }
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
