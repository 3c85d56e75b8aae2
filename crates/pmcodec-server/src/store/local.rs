//! A folder of `<id>.pmc` files, the default store.
//!
//! Writes go to a temporary dot-file in the same folder (same file system, so the rename is
//! atomic), are flushed to disk, then renamed over the final name: readers see the old file or
//! the new one, and a crash leaves at worst a dot-file that no id can name and that the next
//! start removes.

use super::{AssetStore, StoreError, StoredObject};
use crate::AssetId;
use bytes::Bytes;
use futures_util::future::BoxFuture;
use std::path::{Path, PathBuf};

pub struct LocalStore {
    root: PathBuf,
}

const TMP_PREFIX: &str = ".pmc-upload-";

impl LocalStore {
    /// Opens an existing folder (a missing one is an error: a typo should not start an empty
    /// server) and removes temporary files a crashed write left.
    pub fn open(root: &Path) -> Result<LocalStore, StoreError> {
        if !root.is_dir() {
            return Err(StoreError::Config(format!("assets folder {} does not exist or is not a folder", root.display())));
        }
        if let Ok(entries) = std::fs::read_dir(root) {
            for e in entries.flatten() {
                if e.file_name().to_string_lossy().starts_with(TMP_PREFIX) {
                    let _ = std::fs::remove_file(e.path());
                }
            }
        }
        Ok(LocalStore { root: root.to_path_buf() })
    }

    fn path(&self, id: &AssetId) -> PathBuf {
        self.root.join(id.file_name())
    }
}

fn io(what: &str, path: &Path, e: std::io::Error) -> StoreError {
    StoreError::Io(format!("{what} {}: {e}", path.display()))
}

/// A tag that changes when the file is replaced: a rename brings a new inode, and an in-place
/// edit by hand changes the modification time or the size.
fn tag_of(meta: &std::fs::Metadata) -> String {
    let mtime = meta.modified().ok().and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok()).map_or(0, |d| d.as_nanos());
    #[cfg(unix)]
    let ino = std::os::unix::fs::MetadataExt::ino(meta);
    #[cfg(not(unix))]
    let ino = 0u64;
    format!("{ino:x}-{mtime:x}-{:x}", meta.len())
}

impl AssetStore for LocalStore {
    fn describe(&self) -> String {
        format!("local folder {}", self.root.display())
    }

    fn list(&self) -> BoxFuture<'_, Result<Vec<StoredObject>, StoreError>> {
        Box::pin(async move {
            let mut dir = tokio::fs::read_dir(&self.root).await.map_err(|e| io("listing", &self.root, e))?;
            let mut out = Vec::new();
            // Bounded by the folder's size: next_entry returns None at its end.
            while let Some(entry) = dir.next_entry().await.map_err(|e| io("listing", &self.root, e))? {
                let name = entry.file_name();
                let name = name.to_string_lossy();
                if !name.ends_with(".pmc") || name.starts_with('.') {
                    continue;
                }
                let Some(id) = AssetId::from_file_name(&name) else {
                    tracing::warn!(file = %name, "skipping a .pmc whose name is not a valid asset id");
                    continue;
                };
                match entry.metadata().await {
                    Ok(meta) if meta.is_file() => out.push(StoredObject { id, size: meta.len(), tag: tag_of(&meta) }),
                    Ok(_) => {}
                    // Deleted between listing and stat: not an asset any more.
                    Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                    Err(e) => return Err(io("reading", &entry.path(), e)),
                }
            }
            out.sort_by(|a, b| a.id.cmp(&b.id));
            Ok(out)
        })
    }

    fn head<'a>(&'a self, id: &'a AssetId) -> BoxFuture<'a, Result<Option<StoredObject>, StoreError>> {
        Box::pin(async move {
            let path = self.path(id);
            match tokio::fs::metadata(&path).await {
                Ok(meta) if meta.is_file() => Ok(Some(StoredObject { id: id.clone(), size: meta.len(), tag: tag_of(&meta) })),
                Ok(_) => Ok(None),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
                Err(e) => Err(io("reading", &path, e)),
            }
        })
    }

    fn get<'a>(&'a self, id: &'a AssetId) -> BoxFuture<'a, Result<Option<(StoredObject, Bytes)>, StoreError>> {
        Box::pin(async move {
            let path = self.path(id);
            // Size and tag come from the opened file, so they describe exactly the bytes read
            // even if a writer renames a new file over the name meanwhile.
            let result = tokio::task::spawn_blocking(move || -> std::io::Result<(std::fs::Metadata, Vec<u8>)> {
                use std::io::Read;
                let mut f = std::fs::File::open(&path)?;
                let meta = f.metadata()?;
                let mut buf = Vec::with_capacity(meta.len() as usize);
                f.read_to_end(&mut buf)?;
                Ok((meta, buf))
            })
            .await
            .map_err(|e| StoreError::Io(format!("reading {id}: {e}")))?;
            match result {
                Ok((meta, buf)) => {
                    Ok(Some((StoredObject { id: id.clone(), size: buf.len() as u64, tag: tag_of(&meta) }, Bytes::from(buf))))
                }
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
                Err(e) => Err(io("reading", &self.path(id), e)),
            }
        })
    }

    fn put<'a>(&'a self, id: &'a AssetId, bytes: Bytes) -> BoxFuture<'a, Result<StoredObject, StoreError>> {
        Box::pin(async move {
            let root = self.root.clone();
            let final_path = self.path(id);
            let id = id.clone();
            tokio::task::spawn_blocking(move || -> Result<StoredObject, StoreError> {
                use std::io::Write;
                let tmp = root.join(format!("{TMP_PREFIX}{}", uuid::Uuid::new_v4().simple()));
                let write = || -> std::io::Result<()> {
                    let mut f = std::fs::File::create(&tmp)?;
                    f.write_all(&bytes)?;
                    f.sync_all()?;
                    std::fs::rename(&tmp, &final_path)?;
                    // Make the rename itself durable (best effort: not every platform can
                    // open a folder for syncing).
                    if let Ok(d) = std::fs::File::open(&root) {
                        let _ = d.sync_all();
                    }
                    Ok(())
                };
                if let Err(e) = write() {
                    let _ = std::fs::remove_file(&tmp);
                    return Err(io("writing", &final_path, e));
                }
                let meta = std::fs::metadata(&final_path).map_err(|e| io("reading", &final_path, e))?;
                Ok(StoredObject { id, size: meta.len(), tag: tag_of(&meta) })
            })
            .await
            .map_err(|e| StoreError::Io(format!("writing: {e}")))?
        })
    }

    fn delete<'a>(&'a self, id: &'a AssetId) -> BoxFuture<'a, Result<bool, StoreError>> {
        Box::pin(async move {
            let path = self.path(id);
            match tokio::fs::remove_file(&path).await {
                Ok(()) => Ok(true),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(false),
                Err(e) => Err(io("deleting", &path, e)),
            }
        })
    }

    fn check(&self) -> BoxFuture<'_, Result<(), StoreError>> {
        Box::pin(async move {
            match tokio::fs::metadata(&self.root).await {
                Ok(m) if m.is_dir() => Ok(()),
                Ok(_) => Err(StoreError::Io(format!("{} is not a folder", self.root.display()))),
                Err(e) => Err(io("reading", &self.root, e)),
            }
        })
    }
}
