//! Assets in memory: the built-in samples, tests, throwaway servers.

use super::{AssetStore, PutMode, StoreError, StoredObject};
use crate::AssetId;
use bytes::Bytes;
use futures_util::future::BoxFuture;
use std::collections::BTreeMap;
use std::sync::Mutex;

/// Assets in a map under a mutex (the `samples` and `memory` stores, tests); lost at exit.
#[derive(Default)]
pub struct MemoryStore {
    inner: Mutex<Inner>,
}

#[derive(Default)]
struct Inner {
    objects: BTreeMap<AssetId, (Bytes, u64)>,
    /// Every put gets a new generation, which is the object's tag.
    generation: u64,
    meta: BTreeMap<AssetId, Bytes>,
}

impl MemoryStore {
    fn lock(&self) -> Result<std::sync::MutexGuard<'_, Inner>, StoreError> {
        // A poisoned lock means a panic while holding it; the map itself is still whole
        // (every update is a single insert or remove), so keep serving.
        Ok(self.inner.lock().unwrap_or_else(|p| p.into_inner()))
    }

    fn object(id: &AssetId, bytes: &Bytes, generation: u64) -> StoredObject {
        StoredObject { id: id.clone(), size: bytes.len() as u64, tag: format!("mem-{generation}") }
    }
}

impl AssetStore for MemoryStore {
    fn describe(&self) -> String {
        "memory".into()
    }

    fn list(&self) -> BoxFuture<'_, Result<Vec<StoredObject>, StoreError>> {
        Box::pin(async move { Ok(self.lock()?.objects.iter().map(|(id, (b, g))| Self::object(id, b, *g)).collect()) })
    }

    fn head<'a>(&'a self, id: &'a AssetId) -> BoxFuture<'a, Result<Option<StoredObject>, StoreError>> {
        Box::pin(async move { Ok(self.lock()?.objects.get(id).map(|(b, g)| Self::object(id, b, *g))) })
    }

    fn get<'a>(&'a self, id: &'a AssetId) -> BoxFuture<'a, Result<Option<(StoredObject, Bytes)>, StoreError>> {
        Box::pin(async move { Ok(self.lock()?.objects.get(id).map(|(b, g)| (Self::object(id, b, *g), b.clone()))) })
    }

    fn put<'a>(&'a self, id: &'a AssetId, bytes: Bytes, mode: PutMode) -> BoxFuture<'a, Result<StoredObject, StoreError>> {
        Box::pin(async move {
            // Check and insert under one lock: no other put can come between.
            let mut inner = self.lock()?;
            if mode == PutMode::Create && inner.objects.contains_key(id) {
                return Err(StoreError::AlreadyExists(id.clone()));
            }
            inner.generation += 1;
            let g = inner.generation;
            let obj = Self::object(id, &bytes, g);
            inner.objects.insert(id.clone(), (bytes, g));
            Ok(obj)
        })
    }

    fn delete<'a>(&'a self, id: &'a AssetId) -> BoxFuture<'a, Result<bool, StoreError>> {
        Box::pin(async move {
            let mut inner = self.lock()?;
            inner.meta.remove(id);
            Ok(inner.objects.remove(id).is_some())
        })
    }

    fn get_meta<'a>(&'a self, id: &'a AssetId) -> BoxFuture<'a, Result<Option<Bytes>, StoreError>> {
        Box::pin(async move { Ok(self.lock()?.meta.get(id).cloned()) })
    }

    fn put_meta<'a>(&'a self, id: &'a AssetId, bytes: Bytes) -> BoxFuture<'a, Result<(), StoreError>> {
        Box::pin(async move {
            self.lock()?.meta.insert(id.clone(), bytes);
            Ok(())
        })
    }

    fn check(&self) -> BoxFuture<'_, Result<(), StoreError>> {
        Box::pin(async { Ok(()) })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn create_keeps_an_existing_asset_and_creates_a_new_one() {
        let store = MemoryStore::default();
        let id = AssetId::parse("a").unwrap();
        let first = store.put(&id, Bytes::from_static(b"first"), PutMode::Create).await.unwrap();
        let r = store.put(&id, Bytes::from_static(b"second"), PutMode::Create).await;
        assert!(matches!(r, Err(StoreError::AlreadyExists(ref x)) if *x == id), "{r:?}");
        let (obj, bytes) = store.get(&id).await.unwrap().unwrap();
        assert_eq!(&bytes[..], b"first");
        assert_eq!(obj, first, "the refused write changed the tag");
        // Overwrite still replaces.
        store.put(&id, Bytes::from_static(b"third"), PutMode::Overwrite).await.unwrap();
        assert_eq!(&store.get(&id).await.unwrap().unwrap().1[..], b"third");
    }
}
