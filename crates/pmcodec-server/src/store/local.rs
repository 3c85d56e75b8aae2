//! A folder of `<id>.pmc` files, the default store.
//!
//! Writes go to a temporary dot-file in the same folder (same file system, so the rename is
//! atomic), are flushed to disk, then renamed over the final name: readers see the old file or
//! the new one, and a crash leaves at worst a dot-file that no id can name and that the next
//! start removes.
//!
//! A create-only write publishes the temporary file with a hard link to the final name instead
//! of a rename: creating the link fails atomically when the name exists (also when another
//! server sharing the folder made it a moment ago), and the existing file is left untouched.
//! The temporary name is then removed. So the folder must be on a file system with hard links
//! (any local Unix file system, NTFS, NFS); where linking is not supported, create-only writes
//! fail with an error rather than fall back to a check that could race.

use super::{AssetStore, PutMode, StoreError, StoredObject};
use crate::AssetId;
use bytes::Bytes;
use futures_util::future::BoxFuture;
use std::path::{Path, PathBuf};

/// A folder of `<id>.pmc` files, written by rename (or hard link for creates) of a flushed temporary dot-file.
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

    fn meta_path(&self, id: &AssetId) -> PathBuf {
        self.root.join(format!("{id}.meta.json"))
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

/// Writes `bytes` to the new file `tmp`, syncs it, and gives it the name `dest`: a rename over
/// whatever is there, or (create-only) a hard link that fails with `AlreadyExists` when `dest`
/// exists. Leaves `tmp` behind for the caller to remove.
fn publish(tmp: &Path, dest: &Path, bytes: &[u8], mode: PutMode) -> std::io::Result<()> {
    use std::io::Write;
    let mut f = std::fs::OpenOptions::new().write(true).create_new(true).open(tmp)?;
    f.write_all(bytes)?;
    f.sync_all()?;
    drop(f);
    match mode {
        PutMode::Overwrite => std::fs::rename(tmp, dest),
        PutMode::Create => std::fs::hard_link(tmp, dest),
    }
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

    fn put<'a>(&'a self, id: &'a AssetId, bytes: Bytes, mode: PutMode) -> BoxFuture<'a, Result<StoredObject, StoreError>> {
        Box::pin(async move {
            let root = self.root.clone();
            let final_path = self.path(id);
            let id = id.clone();
            tokio::task::spawn_blocking(move || -> Result<StoredObject, StoreError> {
                let tmp = root.join(format!("{TMP_PREFIX}{}", uuid::Uuid::new_v4().simple()));
                let published = publish(&tmp, &final_path, &bytes, mode);
                // The temporary name goes on every path: after a rename it no longer exists,
                // after a link or a failure it does.
                if mode == PutMode::Create || published.is_err() {
                    match std::fs::remove_file(&tmp) {
                        Ok(()) => {}
                        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                        // The asset itself is fine; the next start removes the leftover.
                        Err(e) => tracing::warn!(file = %tmp.display(), error = %e, "removing a temporary upload file failed"),
                    }
                }
                match published {
                    Ok(()) => {}
                    Err(e) if mode == PutMode::Create && e.kind() == std::io::ErrorKind::AlreadyExists => {
                        return Err(StoreError::AlreadyExists(id));
                    }
                    Err(e) => return Err(io("writing", &final_path, e)),
                }
                // Make the new name durable (best effort: not every platform can open a folder
                // for syncing).
                if let Ok(d) = std::fs::File::open(&root) {
                    let _ = d.sync_all();
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
            // The metadata first: without its container it would only be a stale cache.
            match tokio::fs::remove_file(self.meta_path(id)).await {
                Ok(()) => {}
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => return Err(io("deleting", &self.meta_path(id), e)),
            }
            match tokio::fs::remove_file(&path).await {
                Ok(()) => Ok(true),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(false),
                Err(e) => Err(io("deleting", &path, e)),
            }
        })
    }

    fn get_meta<'a>(&'a self, id: &'a AssetId) -> BoxFuture<'a, Result<Option<Bytes>, StoreError>> {
        Box::pin(async move {
            let path = self.meta_path(id);
            match tokio::fs::read(&path).await {
                Ok(b) => Ok(Some(Bytes::from(b))),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
                Err(e) => Err(io("reading", &path, e)),
            }
        })
    }

    fn put_meta<'a>(&'a self, id: &'a AssetId, bytes: Bytes) -> BoxFuture<'a, Result<(), StoreError>> {
        Box::pin(async move {
            let (root, dest) = (self.root.clone(), self.meta_path(id));
            tokio::task::spawn_blocking(move || -> Result<(), StoreError> {
                let tmp = root.join(format!("{TMP_PREFIX}{}", uuid::Uuid::new_v4().simple()));
                let published = publish(&tmp, &dest, &bytes, PutMode::Overwrite);
                if published.is_err() {
                    let _ = std::fs::remove_file(&tmp);
                }
                published.map_err(|e| io("writing", &dest, e))
            })
            .await
            .map_err(|e| StoreError::Io(format!("writing: {e}")))?
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

#[cfg(test)]
mod tests {
    use super::*;

    /// An empty store in a fresh temporary folder (kept alive by the returned guard).
    fn temp_store() -> (tempfile::TempDir, LocalStore) {
        let dir = tempfile::tempdir().unwrap();
        let store = LocalStore::open(dir.path()).unwrap();
        (dir, store)
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        v.sort();
        v
    }

    #[tokio::test]
    async fn create_keeps_an_existing_file_and_leaves_no_temporary_files() {
        let (dir, store) = temp_store();
        let id = AssetId::parse("a").unwrap();
        store.put(&id, Bytes::from_static(b"first"), PutMode::Overwrite).await.unwrap();
        let before = store.head(&id).await.unwrap().unwrap();

        let r = store.put(&id, Bytes::from_static(b"second, longer"), PutMode::Create).await;
        assert!(matches!(r, Err(StoreError::AlreadyExists(ref x)) if *x == id), "{r:?}");
        assert_eq!(std::fs::read(dir.path().join("a.pmc")).unwrap(), b"first");
        assert_eq!(store.head(&id).await.unwrap().unwrap(), before, "the refused write touched the file");
        assert_eq!(names(dir.path()), ["a.pmc"]);

        // A new id is created, whole, under its own name only.
        let b = AssetId::parse("b").unwrap();
        let created = store.put(&b, Bytes::from_static(b"bee"), PutMode::Create).await.unwrap();
        assert_eq!(std::fs::read(dir.path().join("b.pmc")).unwrap(), b"bee");
        assert_eq!(created, store.head(&b).await.unwrap().unwrap());
        assert_eq!(created.size, 3);
        assert_eq!(names(dir.path()), ["a.pmc", "b.pmc"]);

        // Overwrite still replaces, and leaves nothing behind either.
        store.put(&id, Bytes::from_static(b"third"), PutMode::Overwrite).await.unwrap();
        assert_eq!(std::fs::read(dir.path().join("a.pmc")).unwrap(), b"third");
        assert_eq!(names(dir.path()), ["a.pmc", "b.pmc"]);
    }

    #[tokio::test]
    async fn metadata_sits_beside_its_asset_and_goes_with_it() {
        let (dir, store) = temp_store();
        let id = AssetId::parse("m").unwrap();
        store.put(&id, Bytes::from_static(b"container"), PutMode::Overwrite).await.unwrap();
        assert_eq!(store.get_meta(&id).await.unwrap(), None);
        store.put_meta(&id, Bytes::from_static(b"{\"a\":1}")).await.unwrap();
        store.put_meta(&id, Bytes::from_static(b"{\"a\":2}")).await.unwrap();
        assert_eq!(store.get_meta(&id).await.unwrap().as_deref(), Some(&b"{\"a\":2}"[..]));
        assert_eq!(names(dir.path()), ["m.meta.json", "m.pmc"], "no temporary file is left");
        // Listings show assets only.
        assert_eq!(store.list().await.unwrap().iter().map(|o| o.id.to_string()).collect::<Vec<_>>(), ["m"]);
        assert!(store.delete(&id).await.unwrap());
        assert!(names(dir.path()).is_empty());
        assert_eq!(store.get_meta(&id).await.unwrap(), None);
    }

    #[tokio::test]
    async fn of_concurrent_creates_exactly_one_wins() {
        let dir = tempfile::tempdir().unwrap();
        let store = std::sync::Arc::new(LocalStore::open(dir.path()).unwrap());
        let id = AssetId::parse("race").unwrap();
        let tasks: Vec<_> = (0..8u8)
            .map(|i| {
                let (store, id) = (store.clone(), id.clone());
                tokio::spawn(async move { store.put(&id, Bytes::from(vec![i; 4096]), PutMode::Create).await.map(|_| i) })
            })
            .collect();
        let mut winners = Vec::new();
        for t in tasks {
            match t.await.unwrap() {
                Ok(i) => winners.push(i),
                Err(StoreError::AlreadyExists(_)) => {}
                Err(e) => panic!("{e}"),
            }
        }
        assert_eq!(winners.len(), 1, "{winners:?}");
        assert_eq!(std::fs::read(dir.path().join("race.pmc")).unwrap(), vec![winners[0]; 4096]);
        assert_eq!(names(dir.path()), ["race.pmc"]);
    }
}
