//! Assets as the server serves them: a container's bytes with its content hash, header, index
//! and metadata, kept in an LRU bounded by bytes and revalidated against the store so that
//! servers sharing a bucket see each other's uploads and deletes.

use crate::lru::Lru;
use crate::store::{AssetStore, StoredObject};
use crate::{ApiError, AssetId};
use bytes::Bytes;
use pmcodec_container::{ChunkEntry, CutTarget, Decoder, Header, Reader, summary};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// A loaded, checked container.
#[derive(Debug)]
pub struct LoadedAsset {
    pub id: AssetId,
    /// The store's tag of the object these bytes came from.
    pub tag: String,
    /// Content hash (the first 128 bits of SHA-256, hex): the `{version}` of immutable URLs.
    pub version: String,
    pub bytes: Bytes,
    pub header: Header,
    pub chunks: Vec<ChunkEntry>,
    /// Offset of the chunk area (preamble + header + index), where index offsets start.
    pub data_start: u64,
    pub info: Arc<AssetInfo>,
}

pub use pmcodec_api::{AssetInfo, AssetSummary};

impl LoadedAsset {
    /// Checks and describes a container (CPU work: run it on a blocking thread).
    pub fn new(obj: &StoredObject, bytes: Bytes) -> Result<LoadedAsset, String> {
        let reader = Reader::open(&bytes[..]).map_err(|e| e.to_string())?;
        let version = content_version(&bytes);
        let s = summary(&reader);
        let h = reader.header().clone();
        let id = obj.id.clone();
        let levels = h.levels();

        let mut triangles_per_level = Vec::with_capacity(levels);
        let mut d = Decoder::new(reader.borrowed(), 0).map_err(|e| e.to_string())?;
        d.seek(0).map_err(|e| e.to_string())?;
        for l in 0..levels {
            triangles_per_level.push(d.mesh(CutTarget::Level(l)).map_err(|e| e.to_string())?.triangles.len());
        }
        // Every stored byte of a band; a client stopping at level l reads the key, delta and
        // positions chunks of bands l.. and the faces and corners of band l only.
        let shared: Vec<u64> = (0..levels).map(|l| s.key_bytes[l] + s.delta_bytes[l] + s.positions_bytes[l]).collect();
        let bytes_per_level: Vec<u64> = (0..levels).map(|l| shared[l] + s.faces_bytes[l] + s.corners_bytes[l]).collect();
        let bytes_to_level = (0..levels)
            .map(|l| {
                let bands: u64 = shared[l..].iter().sum::<u64>() + s.faces_bytes[l] + s.corners_bytes[l];
                reader.data_start() + bands + if l == 0 { s.triangles_bytes } else { 0 }
            })
            .collect();
        let base = format!("/v1/assets/{id}");
        let summary_ = AssetSummary {
            id: id.to_string(),
            version: version.clone(),
            frames: h.frame_count,
            frame_rate: h.frame_rate,
            vertices: h.vertex_count,
            triangles: h.triangle_count,
            levels: h.level_sizes.clone(),
            bytes: bytes.len() as u64,
            file: format!("{base}/v/{version}/file"),
        };
        let info = AssetInfo {
            summary: summary_,
            bbox_min: h.bbox_min,
            bbox_max: h.bbox_max,
            keyframe_interval: h.keyframe_interval,
            triangles_per_level,
            bytes_per_level,
            bytes_to_level,
            bytes_per_frame_to_level: s.bytes_per_frame_to_level.clone(),
            positions_bits_per_vertex_frame: s.positions_bits_per_vertex_frame,
            index: format!("{base}/v/{version}/index"),
            stream: format!("{base}/stream"),
            generator: h.generator.clone(),
            appearance: crate::looks::appearance(&reader, &s, &format!("{base}/v/{version}"))?,
        };
        Ok(LoadedAsset {
            tag: obj.tag.clone(),
            version,
            chunks: reader.index().chunks.clone(),
            data_start: reader.data_start(),
            header: h,
            bytes,
            info: Arc::new(info),
            id,
        })
    }

    /// Absolute byte range of a chunk in the file.
    pub fn chunk_range(&self, e: &ChunkEntry) -> std::ops::Range<u64> {
        let start = self.data_start + e.offset;
        start..start + e.stored_len as u64
    }

    /// The chunks a client that draws down to `level` and plays from `from` needs, in frame
    /// order ([`pmcodec_container::streams::chunks_for`], which the clients compute alike).
    pub fn chunks_for(&self, level: usize, from: u32) -> impl Iterator<Item = (usize, &ChunkEntry)> {
        pmcodec_container::streams::chunks_for(&self.chunks, &self.header, level, from)
    }

    /// The byte ranges a client drawing down to `level` reads before any chunk: the preamble,
    /// the header and the index, of a banded index only its table and its level's groups.
    pub fn head_ranges(&self, level: usize) -> Result<Vec<std::ops::Range<u64>>, String> {
        pmcodec_container::streams::head_ranges(&self.bytes, level).map_err(|e| e.to_string())
    }

    /// Per frame, the byte ranges of the chunks a client drawing down to `level` from `from`
    /// reads (those every frame reads counted as frame 0's), adjacent ones merged.
    pub fn frame_ranges(&self, level: usize, from: u32) -> Vec<Vec<std::ops::Range<u64>>> {
        pmcodec_container::streams::frame_ranges(&self.chunks, &self.header, self.data_start, level, from)
    }
}

/// The content hash used in immutable URLs.
pub fn content_version(bytes: &[u8]) -> String {
    use sha2::Digest;
    let digest = sha2::Sha256::digest(bytes);
    digest.iter().take(16).map(|b| format!("{b:02x}")).collect()
}

/// What `<id>.meta.json` holds: the listing metadata of the container whose store tag is `tag`,
/// as this server version describes assets (`schema`: a server that describes them otherwise,
/// with other URLs for instance, passes over metadata of another schema).
#[derive(serde::Serialize, serde::Deserialize)]
struct StoredMeta {
    schema: u32,
    tag: String,
    info: AssetInfo,
}

/// The [`StoredMeta::schema`] this server writes and reads.
const META_SCHEMA: u32 = 1;

struct Cached {
    asset: Arc<LoadedAsset>,
    checked: Instant,
}

/// Loaded assets by id, bounded by bytes, plus the (small) metadata of every asset seen so
/// that listing does not need every container in memory.
pub struct AssetCache {
    store: Arc<dyn AssetStore>,
    lru: Mutex<Lru<AssetId, Cached>>,
    infos: Mutex<HashMap<AssetId, (String, Arc<AssetInfo>)>>,
    /// Objects that did not load (a corrupt file, another format version), by id with the tag
    /// of the bytes that failed and why: until the object changes, requests get that answer
    /// without fetching and parsing it again.
    unreadable: Mutex<HashMap<AssetId, (String, String)>>,
    revalidate: Duration,
    /// Told the version of every asset that leaves the cache because it changed or went away,
    /// so decoder states of it can go too.
    on_stale: Box<dyn Fn(&str) + Send + Sync>,
}

/// Listing metadata is kept for at most this many assets (a few hundred bytes each).
const MAX_INFOS: usize = 100_000;

impl AssetCache {
    pub fn new(store: Arc<dyn AssetStore>, capacity: u64, revalidate: Duration, on_stale: Box<dyn Fn(&str) + Send + Sync>) -> Self {
        AssetCache {
            store,
            lru: Mutex::new(Lru::new(capacity)),
            infos: Mutex::new(HashMap::new()),
            unreadable: Mutex::new(HashMap::new()),
            revalidate,
            on_stale,
        }
    }

    fn lru(&self) -> std::sync::MutexGuard<'_, Lru<AssetId, Cached>> {
        // Every critical section is a single map operation: a panic cannot leave it half done.
        self.lru.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn infos(&self) -> std::sync::MutexGuard<'_, HashMap<AssetId, (String, Arc<AssetInfo>)>> {
        self.infos.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn unreadable(&self) -> std::sync::MutexGuard<'_, HashMap<AssetId, (String, String)>> {
        self.unreadable.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The remembered failure of exactly these bytes (same tag), if they failed before.
    fn known_unreadable(&self, id: &AssetId, tag: &str) -> Option<ApiError> {
        self.unreadable().get(id).filter(|(t, _)| t == tag).map(|(_, why)| ApiError::Internal(why.clone()))
    }

    /// Bytes and entries held.
    pub fn usage(&self) -> (u64, usize) {
        let l = self.lru();
        (l.weight(), l.len())
    }

    /// The current asset with this id, from memory when it was checked against the store
    /// recently, else after asking the store whether it changed.
    pub async fn get(&self, id: &AssetId) -> Result<Arc<LoadedAsset>, ApiError> {
        if let Some(c) = self.lru().get(id)
            && c.checked.elapsed() < self.revalidate
        {
            return Ok(c.asset.clone());
        }
        let Some(obj) = self.store.head(id).await? else {
            self.forget(id);
            return Err(ApiError::NotFound(format!("no asset {id}")));
        };
        if let Some(c) = self.lru().get(id)
            && c.asset.tag == obj.tag
        {
            c.checked = Instant::now();
            return Ok(c.asset.clone());
        }
        if let Some(e) = self.known_unreadable(id, &obj.tag) {
            return Err(e);
        }
        self.load(id).await
    }

    /// Metadata of a listed object: from memory when its tag is unchanged, else from the
    /// metadata stored beside it when that describes this very object (same tag), else by
    /// loading the container, after which the stored metadata is written for the next cold
    /// server.
    pub async fn info(&self, obj: &StoredObject) -> Result<Arc<AssetInfo>, ApiError> {
        if let Some((tag, info)) = self.infos().get(&obj.id)
            && *tag == obj.tag
        {
            return Ok(info.clone());
        }
        if let Some(e) = self.known_unreadable(&obj.id, &obj.tag) {
            return Err(e);
        }
        // The stored metadata is a cache: unreadable, unparsable or stale, it is passed over.
        match self.store.get_meta(&obj.id).await {
            Ok(Some(bytes)) => match serde_json::from_slice::<StoredMeta>(&bytes) {
                Ok(m) if m.schema == META_SCHEMA && m.tag == obj.tag => {
                    let info = Arc::new(m.info);
                    self.remember_info(&obj.id, &obj.tag, &info);
                    return Ok(info);
                }
                Ok(_) => {}
                Err(e) => tracing::warn!(asset = %obj.id, error = %e, "ignoring unreadable stored listing metadata"),
            },
            Ok(None) => {}
            Err(e) => tracing::warn!(asset = %obj.id, error = %e, "reading stored listing metadata failed"),
        }
        self.describe(&obj.id).await
    }

    /// Loads an asset and writes its listing metadata to the store (best effort), for servers
    /// that list it later. An upload's job calls this once it has stored the container.
    pub async fn describe(&self, id: &AssetId) -> Result<Arc<AssetInfo>, ApiError> {
        let asset = self.load(id).await?;
        let meta = StoredMeta { schema: META_SCHEMA, tag: asset.tag.clone(), info: (*asset.info).clone() };
        match serde_json::to_vec(&meta) {
            Ok(bytes) => {
                if let Err(e) = self.store.put_meta(id, bytes.into()).await {
                    tracing::warn!(asset = %id, error = %e, "writing listing metadata failed");
                }
            }
            Err(e) => tracing::warn!(asset = %id, error = %e, "encoding listing metadata failed"),
        }
        Ok(asset.info.clone())
    }

    fn remember_info(&self, id: &AssetId, tag: &str, info: &Arc<AssetInfo>) {
        let mut infos = self.infos();
        if infos.len() >= MAX_INFOS {
            infos.clear();
        }
        infos.insert(id.clone(), (tag.to_string(), info.clone()));
    }

    async fn load(&self, id: &AssetId) -> Result<Arc<LoadedAsset>, ApiError> {
        let Some((obj, bytes)) = self.store.get(id).await? else {
            self.forget(id);
            return Err(ApiError::NotFound(format!("no asset {id}")));
        };
        let weight = bytes.len() as u64;
        let tag = obj.tag.clone();
        let loaded = tokio::task::spawn_blocking(move || LoadedAsset::new(&obj, bytes))
            .await
            .map_err(|e| ApiError::Internal(format!("loading {id}: {e}")))?;
        let asset = match loaded {
            Ok(a) => {
                self.unreadable().remove(id);
                a
            }
            Err(e) => {
                let why = format!("asset {id} in the store is not a readable container: {e}");
                let mut bad = self.unreadable();
                if bad.len() >= MAX_INFOS {
                    bad.clear();
                }
                bad.insert(id.clone(), (tag, why.clone()));
                return Err(ApiError::Internal(why));
            }
        };
        let asset = Arc::new(asset);
        self.remember_info(id, &asset.tag, &asset.info);
        let evicted = self.lru().insert(id.clone(), Cached { asset: asset.clone(), checked: Instant::now() }, weight);
        for old in evicted {
            if old.asset.version != asset.version && old.asset.id == asset.id {
                (self.on_stale)(&old.asset.version);
            }
        }
        Ok(asset)
    }

    /// Drops an asset that changed or went away.
    pub fn forget(&self, id: &AssetId) {
        self.infos().remove(id);
        self.unreadable().remove(id);
        let old = self.lru().remove(id);
        if let Some(old) = old {
            (self.on_stale)(&old.asset.version);
        }
    }
}
