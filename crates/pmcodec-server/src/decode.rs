//! LOD on demand: decode worker threads, each owning an LRU of decoder states.
//!
//! A decoder state is a [`Decoder`] positioned at one frame of one asset, at one finest level.
//! A request for frame f uses the state at f when there is one (then only the cut and the
//! encoding cost anything); otherwise it clones the nearest state at a frame before f in the same
//! keyframe interval and steps the clone forward, or starts from the keyframe. The new state is
//! kept too, so once an asset is warm, random frames cost no replay at all; the LRU bounds the
//! memory. Every request for one frame goes to the same worker (the one holding its state);
//! frames spread over the workers, so a cold frame finds earlier states of its interval on its
//! own worker about 1/workers of the time.
//!
//! The container's `Decoder` owns its `Reader`, which counts bytes in a `Cell`, so a state is
//! `Send` but not `Sync`. Each state lives on one worker thread for its whole life (requests are
//! routed to the worker that owns their state by hashing its key), which needs no locks on the
//! decode path.

use crate::ApiError;
use crate::assets::LoadedAsset;
use crate::lru::Lru;
use crate::meshfmt::{MeshFormat, encode_mesh};
use bytes::Bytes;
use pmcodec_container::{ByteSource, ContainerError, Decoder, MeshTarget, Reader};
use pmcodec_mesh::TriMesh;
use std::hash::{Hash, Hasher};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError};
use std::time::Instant;

/// A container's bytes as a byte source that owns them (a cheap, shared handle).
#[derive(Clone)]
pub struct AssetSource(pub Bytes);

impl ByteSource for AssetSource {
    fn len(&self) -> Result<u64, ContainerError> {
        Ok(self.0.len() as u64)
    }
    fn read_at(&self, offset: u64, len: usize) -> Result<Vec<u8>, ContainerError> {
        self.0[..].read_at(offset, len)
    }
}

/// A decoder state: a decoder over its own handle on the asset's bytes.
type DecoderCell = Decoder<AssetSource>;

/// One mesh request.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshRequest {
    pub frame: u32,
    pub target: MeshTarget,
    pub format: MeshFormat,
}

/// An encoded mesh.
#[derive(Debug)]
pub struct MeshOutput {
    pub body: Vec<u8>,
    pub vertices: usize,
    pub triangles: usize,
    /// Time spent in the worker (decode, cut, encode).
    pub micros: u64,
}

enum Msg {
    Decode(Box<Job>),
    /// Drop every state of this asset version (it was replaced or deleted).
    Purge(String),
}

struct Job {
    asset: Arc<LoadedAsset>,
    req: MeshRequest,
    min_level: usize,
    reply: tokio::sync::oneshot::Sender<Result<MeshOutput, ApiError>>,
}

/// Counters the metrics endpoint reads.
#[derive(Default)]
pub struct DecodeStats {
    pub state_bytes: Vec<AtomicU64>,
    pub states: Vec<AtomicU64>,
    pub hits: AtomicU64,
    pub misses: AtomicU64,
    pub requests: AtomicU64,
}

pub struct DecodePool {
    workers: Vec<SyncSender<Msg>>,
    pub stats: Arc<DecodeStats>,
}

/// (asset version, finest level, frame).
type Key = (String, usize, u32);

impl DecodePool {
    /// `workers` threads (0: one per core), each with `capacity / workers` bytes of states and
    /// a queue of `queue` requests.
    pub fn new(workers: usize, capacity: u64, queue: usize) -> Result<DecodePool, std::io::Error> {
        let n = if workers == 0 { std::thread::available_parallelism().map_or(2, |n| n.get()) } else { workers };
        let stats = Arc::new(DecodeStats {
            state_bytes: (0..n).map(|_| AtomicU64::new(0)).collect(),
            states: (0..n).map(|_| AtomicU64::new(0)).collect(),
            ..Default::default()
        });
        let per_worker = capacity / n as u64;
        let mut senders = Vec::with_capacity(n);
        for w in 0..n {
            let (tx, rx) = std::sync::mpsc::sync_channel(queue.max(1));
            let stats = stats.clone();
            std::thread::Builder::new().name(format!("pmc-decode-{w}")).spawn(move || worker(w, rx, per_worker, &stats))?;
            senders.push(tx);
        }
        Ok(DecodePool { workers: senders, stats })
    }

    fn worker_for(&self, key: &Key) -> &SyncSender<Msg> {
        let mut h = std::collections::hash_map::DefaultHasher::new();
        key.hash(&mut h);
        &self.workers[(h.finish() % self.workers.len() as u64) as usize]
    }

    /// Decodes `req.frame` of an asset and cuts and encodes it. Frame, level and target must
    /// have been checked against the header (the caller answers 400 for those).
    pub async fn mesh(&self, asset: Arc<LoadedAsset>, req: MeshRequest) -> Result<MeshOutput, ApiError> {
        // A whole-level request reads only the bands it needs; budgets and error bounds may
        // refine anywhere, so they decode every band.
        let min_level = match req.target {
            MeshTarget::Level(l) => l,
            _ => 0,
        };
        // Routed by frame: the worker that holds the frame's state gets it, and a hot asset's
        // frames spread evenly over the workers (routing by keyframe interval left a worker
        // idle when an asset has fewer intervals than there are workers).
        let key = (asset.version.clone(), min_level, req.frame);
        let (tx, rx) = tokio::sync::oneshot::channel();
        self.stats.requests.fetch_add(1, Ordering::Relaxed);
        match self.worker_for(&key).try_send(Msg::Decode(Box::new(Job { asset, req, min_level, reply: tx }))) {
            Ok(()) => {}
            Err(TrySendError::Full(_)) => return Err(ApiError::Busy("every decoder is busy; retry shortly".into())),
            Err(TrySendError::Disconnected(_)) => return Err(ApiError::Internal("the decode workers have stopped".into())),
        }
        rx.await.map_err(|_| ApiError::Internal("a decode worker dropped the request".into()))?
    }

    /// Forgets every state of an asset version, on every worker.
    pub fn purge(&self, version: &str) {
        for w in &self.workers {
            // A full queue drops the purge: the LRU evicts those states in time anyway.
            let _ = w.try_send(Msg::Purge(version.to_string()));
        }
    }

    pub fn workers(&self) -> usize {
        self.workers.len()
    }
}

/// A rough size of a decoder state: per node its parent, positions (current and previous,
/// dequantized), split priority, split rank, parent-and-rank pair and bookkeeping; per triangle its corners,
/// incidence, degeneration node and place in the split order; plus the reader's index.
fn state_weight(asset: &LoadedAsset) -> u64 {
    let h = &asset.header;
    116 * h.node_count() + 76 * h.triangle_count as u64 + 32 * asset.chunks.len() as u64 + 4096
}

fn worker(w: usize, rx: Receiver<Msg>, capacity: u64, stats: &DecodeStats) {
    let mut cache: Lru<Key, DecoderCell> = Lru::new(capacity);
    // The cut's buffers, reused by every request on this worker (only the encoded body is
    // allocated per request).
    let mut scratch = TriMesh::default();
    // Ends when every sender is gone, i.e. when the server state is dropped.
    while let Ok(msg) = rx.recv() {
        match msg {
            Msg::Purge(version) => drop(cache.retain(|k| k.0 != version)),
            Msg::Decode(job) => {
                // The client went away while the request waited: skip the work.
                if job.reply.is_closed() {
                    continue;
                }
                let key = (job.asset.version.clone(), job.min_level, job.req.frame);
                let result =
                    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| run(&mut cache, &key, &job, stats, &mut scratch))) {
                        Ok(r) => r,
                        Err(_) => {
                            // The state in use may be half-updated: drop it. (A new state enters
                            // the cache only after it decoded.)
                            drop(cache.remove(&key));
                            Err(ApiError::Internal(format!("decoder panicked on {} frame {}", job.asset.id, job.req.frame)))
                        }
                    };
                let _ = job.reply.send(result);
            }
        }
        stats.state_bytes[w].store(cache.weight(), Ordering::Relaxed);
        stats.states[w].store(cache.len() as u64, Ordering::Relaxed);
    }
}

fn run(cache: &mut Lru<Key, DecoderCell>, key: &Key, job: &Job, stats: &DecodeStats, mesh: &mut TriMesh) -> Result<MeshOutput, ApiError> {
    let t0 = Instant::now();
    let asset = &job.asset;
    let fail = |e: ContainerError| ApiError::Internal(format!("asset {} frame {}: {e}", asset.id, job.req.frame));
    if let Some(state) = cache.get(key) {
        stats.hits.fetch_add(1, Ordering::Relaxed);
        // Already at the frame; a cut leaves the state at this frame.
        match state.mesh_into(job.req.target, mesh) {
            Ok(()) => {}
            Err(e) => {
                // A failed cut may leave the state anywhere: it goes.
                drop(cache.remove(key));
                return Err(fail(e));
            }
        }
    } else {
        stats.misses.fetch_add(1, Ordering::Relaxed);
        let (version, level, frame) = key.clone();
        let keyframe = asset.header.keyframe_before(frame);
        // The nearest earlier state of this keyframe interval, cloned (it stays for others).
        let start = (keyframe..frame).rev().find_map(|g| cache.get(&(version.clone(), level, g)).map(|d| d.clone()));
        let mut state = match start {
            Some(d) => d,
            None => Decoder::new(Reader::open(AssetSource(asset.bytes.clone())).map_err(fail)?, level).map_err(fail)?,
        };
        state.seek(frame).map_err(fail)?;
        state.mesh_into(job.req.target, mesh).map_err(fail)?;
        // Only a state that decoded without error is kept.
        for evicted in cache.insert(key.clone(), state, state_weight(asset)) {
            drop(evicted);
        }
    }
    let body = encode_mesh(mesh, job.req.format);
    Ok(MeshOutput { body, vertices: mesh.positions.len(), triangles: mesh.triangles.len(), micros: t0.elapsed().as_micros() as u64 })
}
