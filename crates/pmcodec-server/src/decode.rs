//! LOD on demand: decode worker threads over one shared queue and one shared cache of decoder
//! states.
//!
//! A decoder state is a [`Decoder`] positioned at one frame of one asset, at one finest level.
//! A request for frame f uses the state at f when there is one (then only the cut and the
//! encoding cost anything); otherwise it clones the nearest state at a frame before f in the same
//! keyframe interval and steps the clone forward, or starts from the keyframe. The new state is
//! kept too, so once an asset is warm, random frames cost no replay at all.
//!
//! **One budget.** Every worker reads and fills the same LRU, bounded by the configured bytes as
//! a whole: a state is never refused for being larger than one worker's share (with a share per
//! worker, a 152,000-vertex asset on 16 workers was decoded from its keyframe on every request).
//! A state larger than the whole budget is kept in a slot of its own, one for the pool, so the
//! largest asset in use is still decoded once rather than once per request; the memory bound is
//! the budget plus that one state.
//!
//! **Fair turns.** Requests wait in one queue per asset version, and a free worker takes the
//! next request from the asset whose turn it is (round robin over assets with waiting requests),
//! so a request for a small asset waits for at most one request of each other asset, not for a
//! slow asset's whole backlog. One asset takes at most three quarters of the workers (all of two
//! or three), so with four or more workers others find a free one even when its requests take
//! seconds each. A request for a frame a worker is decoding right now waits until
//! that state is in the cache (it is then a hit) instead of decoding the same frame twice.
//!
//! The container's `Decoder` owns its `Reader`, which counts bytes in a `Cell`, so a state is
//! `Send` but not `Sync`: each cached state sits behind its own mutex, which only the worker
//! using it holds (the queue never hands out two requests for one state at once; a worker that
//! wants to clone a state in use takes another or starts from the keyframe).

use crate::ApiError;
use crate::assets::LoadedAsset;
use crate::lru::Lru;
use crate::meshfmt::{MeshFormat, encode_bin_v3, encode_mesh};
use bytes::Bytes;
use pmcodec_container::{ByteSource, ContainerError, CutTarget, Decoder, Reader};
use pmcodec_mesh::TriMesh;
use std::collections::{HashMap, HashSet, VecDeque};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
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

/// A decoder state: a decoder over its own handle on the asset's bytes, behind the mutex that
/// lets whichever worker uses it move it (see the module documentation).
type StateCell = Arc<Mutex<Decoder<AssetSource>>>;

/// One mesh request.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshRequest {
    pub frame: u32,
    pub target: CutTarget,
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

/// (asset version, finest level, frame): what a decoder state is positioned at.
type Key = (String, usize, u32);

struct Job {
    asset: Arc<LoadedAsset>,
    req: MeshRequest,
    reply: tokio::sync::oneshot::Sender<Result<MeshOutput, ApiError>>,
}

/// Requests waiting, one first-in-first-out line per asset version, served in turns: the asset
/// at the front gives its oldest request whose state is not in use and goes to the back. A
/// request thus waits for at most one request of every other asset with requests waiting, however
/// many one of them has queued (Nagle's fair queueing, *On packet switches with infinite storage*,
/// 1987, with assets for hosts).
struct Turns<T> {
    lines: HashMap<String, VecDeque<(Key, T)>>,
    /// Versions with waiting requests, the one whose turn it is first.
    order: VecDeque<String>,
    len: usize,
}

impl<T> Turns<T> {
    fn new() -> Self {
        Turns { lines: HashMap::new(), order: VecDeque::new(), len: 0 }
    }

    fn push(&mut self, key: Key, item: T) {
        let line = self.lines.entry(key.0.clone()).or_default();
        if line.is_empty() {
            self.order.push_back(key.0.clone());
        }
        line.push_back((key, item));
        self.len += 1;
    }

    /// The next request to serve, skipping requests for a key in `busy` and assets for which
    /// `full` is true.
    fn pop(&mut self, busy: &HashSet<Key>, full: impl Fn(&str) -> bool) -> Option<(Key, T)> {
        // Each pass looks at one asset's line; every asset gets one look.
        for _ in 0..self.order.len() {
            let version = self.order.pop_front()?;
            let Some(line) = self.lines.get_mut(&version) else { continue };
            let found = if full(&version) { None } else { line.iter().position(|(k, _)| !busy.contains(k)).and_then(|i| line.remove(i)) };
            if line.is_empty() {
                self.lines.remove(&version);
            } else {
                self.order.push_back(version);
            }
            if let Some(item) = found {
                self.len -= 1;
                return Some(item);
            }
        }
        None
    }
}

/// Counters the metrics endpoint reads.
#[derive(Default)]
struct DecodeStats {
    hits: AtomicU64,
    misses: AtomicU64,
    keyframe_starts: AtomicU64,
    requests: AtomicU64,
}

/// What the metrics endpoint shows of the pool.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DecodeGauges {
    /// Estimated bytes of the kept states (the oversized one included).
    pub state_bytes: u64,
    pub states: u64,
    pub hits: u64,
    pub misses: u64,
    /// Misses that found no earlier state to step forward and decoded from the keyframe.
    pub keyframe_starts: u64,
    pub requests: u64,
    /// Requests waiting for a worker.
    pub queued: u64,
    pub workers: usize,
}

/// Everything the workers share, behind one mutex held only for queue and cache bookkeeping
/// (never while decoding).
struct Inner {
    waiting: Turns<Job>,
    /// Keys a worker is serving now.
    busy: HashSet<Key>,
    /// Workers serving each asset version now, and the most one version may have: a quarter of
    /// the workers (none of two or three) stay free for other assets even when one asset's
    /// requests take seconds each.
    running: HashMap<String, usize>,
    per_asset: usize,
    cache: Lru<Key, StateCell>,
    /// The one kept state heavier than the whole cache, with its key and weight.
    oversized: Option<(Key, StateCell, u64)>,
    /// Purges so far: a state decoded while a purge happened is not kept (its version may be
    /// gone; a version is content-addressed, so serving it was still right).
    purges: u64,
    queue_limit: usize,
    stopping: bool,
}

impl Inner {
    fn state(&mut self, key: &Key) -> Option<StateCell> {
        if let Some(cell) = self.cache.get(key) {
            return Some(cell.clone());
        }
        self.oversized.as_ref().filter(|(k, ..)| k == key).map(|(_, cell, _)| cell.clone())
    }

    fn keep(&mut self, key: Key, state: Decoder<AssetSource>, weight: u64) -> Vec<StateCell> {
        let cell = Arc::new(Mutex::new(state));
        if weight > self.cache.capacity() {
            return self.oversized.replace((key, cell, weight)).map(|(_, c, _)| c).into_iter().collect();
        }
        self.cache.insert(key, cell, weight)
    }

    fn remove(&mut self, key: &Key) -> Option<StateCell> {
        self.cache.remove(key).or_else(|| self.oversized.take_if(|(k, ..)| k == key).map(|(_, c, _)| c))
    }

    fn purge(&mut self, version: &str) -> Vec<StateCell> {
        self.purges += 1;
        let mut gone = self.cache.retain(|k| k.0 != version);
        gone.extend(self.oversized.take_if(|(k, ..)| k.0 == version).map(|(_, c, _)| c));
        gone
    }
}

struct Shared {
    inner: Mutex<Inner>,
    /// Signalled when a request is queued or a key stops being busy.
    work: Condvar,
    stats: DecodeStats,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, Inner> {
        // Nothing panics while holding this lock but the map operations themselves; their
        // state stays consistent, so a poisoned lock is used as it is.
        self.inner.lock().unwrap_or_else(|p| p.into_inner())
    }
}

pub struct DecodePool {
    shared: Arc<Shared>,
    workers: usize,
}

impl DecodePool {
    /// `workers` threads (0: one per core) sharing `capacity` bytes of states and a queue of
    /// `queue` requests per worker.
    pub fn new(workers: usize, capacity: u64, queue: usize) -> Result<DecodePool, std::io::Error> {
        let n = if workers == 0 { std::thread::available_parallelism().map_or(2, |n| n.get()) } else { workers };
        let shared = Arc::new(Shared {
            inner: Mutex::new(Inner {
                waiting: Turns::new(),
                busy: HashSet::new(),
                running: HashMap::new(),
                per_asset: n - n / 4,
                cache: Lru::new(capacity),
                oversized: None,
                purges: 0,
                queue_limit: queue.max(1).saturating_mul(n),
                stopping: false,
            }),
            work: Condvar::new(),
            stats: DecodeStats::default(),
        });
        let pool = DecodePool { shared, workers: n };
        for w in 0..n {
            let shared = pool.shared.clone();
            // On an error, dropping the pool stops the workers already started.
            std::thread::Builder::new().name(format!("pmc-decode-{w}")).spawn(move || worker(&shared))?;
        }
        Ok(pool)
    }

    /// Decodes `req.frame` of an asset and cuts and encodes it. Frame, level and target must
    /// have been checked against the header (the caller answers 400 for those).
    pub async fn mesh(&self, asset: Arc<LoadedAsset>, req: MeshRequest) -> Result<MeshOutput, ApiError> {
        // A whole-level request reads only the bands it needs; budgets and error bounds may
        // refine anywhere, so they decode every band.
        let min_level = match req.target {
            CutTarget::Level(l) => l,
            _ => 0,
        };
        let key = (asset.version.clone(), min_level, req.frame);
        let (tx, rx) = tokio::sync::oneshot::channel();
        self.shared.stats.requests.fetch_add(1, Ordering::Relaxed);
        {
            let mut inner = self.shared.lock();
            if inner.stopping {
                return Err(ApiError::Internal("the decode workers have stopped".into()));
            }
            if inner.waiting.len >= inner.queue_limit {
                return Err(ApiError::Busy("every decoder is busy; retry shortly".into()));
            }
            inner.waiting.push(key, Job { asset, req, reply: tx });
        }
        self.shared.work.notify_one();
        rx.await.map_err(|_| ApiError::Internal("a decode worker dropped the request".into()))?
    }

    /// Forgets every state of an asset version.
    pub fn purge(&self, version: &str) {
        let gone = self.shared.lock().purge(version);
        drop(gone);
    }

    pub fn gauges(&self) -> DecodeGauges {
        let s = &self.shared.stats;
        let inner = self.shared.lock();
        let oversized = inner.oversized.as_ref().map_or(0, |o| o.2);
        DecodeGauges {
            state_bytes: inner.cache.weight() + oversized,
            states: (inner.cache.len() + usize::from(oversized > 0)) as u64,
            hits: s.hits.load(Ordering::Relaxed),
            misses: s.misses.load(Ordering::Relaxed),
            keyframe_starts: s.keyframe_starts.load(Ordering::Relaxed),
            requests: s.requests.load(Ordering::Relaxed),
            queued: inner.waiting.len as u64,
            workers: self.workers,
        }
    }
}

impl Drop for DecodePool {
    fn drop(&mut self) {
        self.shared.lock().stopping = true;
        self.shared.work.notify_all();
    }
}

/// A rough size of a decoder state: per node its parent, positions (current and previous,
/// dequantized), split priority, split rank, parent-and-rank pair and bookkeeping; per triangle its corners,
/// incidence, degeneration node and place in the split order; plus the reader's index.
fn state_weight(asset: &LoadedAsset) -> u64 {
    let h = &asset.header;
    116 * h.node_count() + 76 * h.triangle_count as u64 + 32 * asset.chunks.len() as u64 + 4096
}

fn worker(shared: &Shared) {
    // The cut's buffers, reused by every request on this worker (only the encoded body is
    // allocated per request).
    let mut scratch = TriMesh::default();
    loop {
        let (key, job) = {
            let mut inner = shared.lock();
            loop {
                if inner.stopping {
                    return;
                }
                let Inner { waiting, busy, running, per_asset, .. } = &mut *inner;
                if let Some(next) = waiting.pop(busy, |v| running.get(v).is_some_and(|&r| r >= *per_asset)) {
                    busy.insert(next.0.clone());
                    *running.entry(next.0.0.clone()).or_default() += 1;
                    break next;
                }
                inner = shared.work.wait(inner).unwrap_or_else(|p| p.into_inner());
            }
        };
        // The client went away while the request waited: skip the work.
        let result = (!job.reply.is_closed()).then(|| {
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| run(shared, &key, &job, &mut scratch))).unwrap_or_else(|_| {
                // The state in use may be half-updated: drop it. (A new state is kept only
                // after it decoded.)
                drop(shared.lock().remove(&key));
                Err(ApiError::Internal(format!("decoder panicked on {} frame {}", job.asset.id, job.req.frame)))
            })
        });
        {
            let mut inner = shared.lock();
            inner.busy.remove(&key);
            if let Some(r) = inner.running.get_mut(&key.0) {
                *r -= 1;
                if *r == 0 {
                    inner.running.remove(&key.0);
                }
            }
        }
        // A request for this key or asset may have waited for it; another worker may take it.
        shared.work.notify_one();
        if let Some(result) = result {
            let _ = job.reply.send(result);
        }
    }
}

fn run(shared: &Shared, key: &Key, job: &Job, mesh: &mut TriMesh) -> Result<MeshOutput, ApiError> {
    let t0 = Instant::now();
    let asset = &job.asset;
    let stats = &shared.stats;
    let fail = |e: ContainerError| ApiError::Internal(format!("asset {} frame {}: {e}", asset.id, job.req.frame));
    let (version, level, frame) = key.clone();
    let keyframe = asset.header.keyframe_before(frame);
    let (cached, earlier, purges) = {
        let mut inner = shared.lock();
        let cached = inner.state(key);
        // The earlier states of this keyframe interval, nearest first.
        let earlier: Vec<StateCell> = if cached.is_some() {
            Vec::new()
        } else {
            (keyframe..frame).rev().filter_map(|g| inner.state(&(version.clone(), level, g))).collect()
        };
        (cached, earlier, inner.purges)
    };
    // A GLB or a layout 3 binary of an asset with an appearance carries it (UVs, normals,
    // colours, materials; the GLB the textures too); everything else is the bare mesh.
    let textured = matches!(job.req.format, MeshFormat::Glb | MeshFormat::Bin3) && asset.header.appearance.is_some();
    let mut body: Option<Vec<u8>> = None;
    let mut cut = |state: &mut Decoder<AssetSource>, mesh: &mut TriMesh| -> Result<(), ContainerError> {
        if textured {
            let (m, app) = state.textured_mesh(job.req.target)?;
            body = Some(if job.req.format == MeshFormat::Bin3 {
                encode_bin_v3(&m, &app).map_err(|e| ContainerError::Options(e.to_string()))?
            } else {
                pmcodec_container::appearance::export::textured_glb(&m, &app)?
            });
            *mesh = m;
            Ok(())
        } else {
            state.mesh_into(job.req.target, mesh)
        }
    };
    let output = |mesh: &TriMesh, body: Option<Vec<u8>>| MeshOutput {
        body: body.unwrap_or_else(|| encode_mesh(mesh, job.req.format)),
        vertices: mesh.positions.len(),
        triangles: mesh.triangles.len(),
        micros: t0.elapsed().as_micros() as u64,
    };
    if let Some(cell) = cached {
        // No other worker serves this key now (the queue sees to it); one cloning it holds the
        // lock for the clone's time at most. A poisoned state is dropped and decoded anew.
        if let Ok(mut state) = cell.lock() {
            stats.hits.fetch_add(1, Ordering::Relaxed);
            // Already at the frame; a cut leaves the state at this frame.
            let result = cut(&mut state, mesh);
            drop(state);
            if let Err(e) = result {
                // A failed cut may leave the state anywhere: it goes.
                drop(shared.lock().remove(key));
                return Err(fail(e));
            }
            return Ok(output(mesh, body));
        }
        drop(shared.lock().remove(key));
    }
    stats.misses.fetch_add(1, Ordering::Relaxed);
    // The nearest earlier state that no other worker is stepping now, cloned (it stays for
    // others).
    let start = earlier.iter().find_map(|cell| cell.try_lock().ok().map(|d| d.clone()));
    let mut state = match start {
        Some(d) => d,
        None => {
            stats.keyframe_starts.fetch_add(1, Ordering::Relaxed);
            Decoder::new(Reader::open(AssetSource(asset.bytes.clone())).map_err(fail)?, level).map_err(fail)?
        }
    };
    state.seek(frame).map_err(fail)?;
    cut(&mut state, mesh).map_err(fail)?;
    let out = output(mesh, body);
    // Only a state that decoded without error is kept, and evicted states are freed outside the
    // lock.
    let evicted = {
        let mut inner = shared.lock();
        if inner.purges == purges { inner.keep(key.clone(), state, state_weight(asset)) } else { Vec::new() }
    };
    drop(evicted);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(asset: &str, frame: u32) -> Key {
        (asset.to_string(), 0, frame)
    }

    #[test]
    fn a_request_waits_for_one_request_per_other_asset_not_for_a_backlog() {
        let mut t = Turns::new();
        // A slow asset's backlog of six, then one request for another asset, then two more.
        for f in 0..6 {
            t.push(key("slow", f), f);
        }
        t.push(key("small", 0), 100);
        t.push(key("other", 0), 200);
        t.push(key("small", 1), 101);
        let none = HashSet::new();
        let order: Vec<u32> = std::iter::from_fn(|| t.pop(&none, |_| false).map(|(_, v)| v)).collect();
        assert_eq!(order, [0, 100, 200, 1, 101, 2, 3, 4, 5]);
        assert_eq!(t.len, 0);
        assert!(t.lines.is_empty() && t.order.is_empty());
    }

    #[test]
    fn a_request_for_a_busy_state_waits_and_the_rest_go_on() {
        let mut t = Turns::new();
        t.push(key("a", 3), 1);
        t.push(key("a", 3), 2);
        t.push(key("a", 4), 3);
        t.push(key("b", 0), 4);
        let busy: HashSet<Key> = [key("a", 3)].into();
        assert_eq!(t.pop(&busy, |_| false).map(|(_, v)| v), Some(3));
        assert_eq!(t.pop(&busy, |_| false).map(|(_, v)| v), Some(4));
        // Only requests for the busy key are left: none is handed out.
        assert_eq!(t.pop(&busy, |_| false).map(|(_, v)| v), None);
        assert_eq!(t.len, 2);
        let none = HashSet::new();
        assert_eq!(t.pop(&none, |_| false).map(|(_, v)| v), Some(1));
        assert_eq!(t.pop(&none, |_| false).map(|(_, v)| v), Some(2));
        assert_eq!(t.pop(&none, |_| false).map(|(_, v)| v), None);
    }

    #[test]
    fn an_asset_at_its_worker_limit_waits_and_others_go_on() {
        let mut t = Turns::new();
        t.push(key("slow", 0), 1);
        t.push(key("slow", 1), 2);
        t.push(key("small", 0), 3);
        let none = HashSet::new();
        let slow_full = |v: &str| v == "slow";
        assert_eq!(t.pop(&none, slow_full).map(|(_, v)| v), Some(3));
        assert_eq!(t.pop(&none, slow_full).map(|(_, v)| v), None);
        assert_eq!(t.pop(&none, |_| false).map(|(_, v)| v), Some(1));
    }

    #[test]
    fn a_quarter_of_the_workers_stay_free_for_other_assets() {
        let per_asset = |n: usize| DecodePool::new(n, 1 << 20, 1).map(|p| p.shared.lock().per_asset).expect("pool");
        assert_eq!((per_asset(1), per_asset(2), per_asset(3), per_asset(4), per_asset(16)), (1, 2, 3, 3, 12));
    }
}
