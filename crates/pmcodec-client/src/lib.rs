//! A client for the pmcodec HTTP API (proto/http.md): list assets, fetch a LOD on demand, and
//! play an asset as a [`Session`] that streams the container with range requests, reading only
//! the bands its triangle budget needs and prefetching frames ahead of the playhead, and hands
//! out ready-to-draw vertex and index buffers per frame.
//!
//! A server's answers are bounded: a range answer may hold the ranges asked and their
//! multipart framing, any other at most [`DEFAULT_ANSWER_LIMIT`] bytes
//! ([`Client::with_answer_limit`]), an error answer's first 64 KiB are kept as its detail; a
//! server that sends more gets an error, checked against its declared length before reading
//! and against the bytes as they arrive.
#![warn(missing_docs)]

mod multirange;
pub use multirange::MAX_RANGES_PER_REQUEST;

use pmcodec_container::format::{FLAG_BANDS, PREAMBLE_LEN, Preamble};
use pmcodec_container::{ByteSource, ChunkEntry, ChunkKind, ContainerError, CutTarget, Decoder, Distance, Reader};
use pmcodec_mesh::{Appearance, TriMesh};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::ops::Range;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// What can go wrong talking to a server.
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    /// The request failed (connection, TLS, body).
    #[error("HTTP: {0}")]
    Http(#[from] reqwest::Error),
    /// The server answered with an error status.
    #[error("{url}: HTTP {status}: {detail}")]
    Status {
        /// The URL asked for.
        url: String,
        /// The HTTP status.
        status: u16,
        /// The body of the answer (the API's JSON error, see proto/http.md).
        detail: String,
    },
    /// The bytes served are not a container this decoder reads.
    #[error("container: {0}")]
    Container(#[from] ContainerError),
    /// The server's answer, or the request asked of this client, breaks the protocol.
    #[error("{0}")]
    Protocol(String),
}

pub use pmcodec_api::{AssetInfo, AssetSummary};

/// Most bytes one answer may hold (a whole file, a `/stream` answer, a mesh, a JSON document)
/// unless [`Client::with_answer_limit`] says otherwise; a range answer may hold only the
/// ranges asked and their multipart framing. A server that sends more (a wrong length, an
/// endless body) gets an error before the client holds it.
pub const DEFAULT_ANSWER_LIMIT: u64 = 1 << 30;

/// Most bytes of an error answer kept as [`ClientError::Status`]'s detail.
const ERROR_DETAIL_LIMIT: u64 = 64 << 10;

/// Bytes a `multipart/byteranges` answer may spend per part on its boundary and headers, and
/// once on its preamble and closing boundary, beyond the ranges' own bytes.
const MULTIPART_FRAMING: u64 = 512;

/// A connection to one server.
#[derive(Clone, Debug)]
pub struct Client {
    http: reqwest::Client,
    base: String,
    /// Bearer token for servers that guard reads.
    token: Option<String>,
    /// Most bytes one answer may hold ([`DEFAULT_ANSWER_LIMIT`]).
    answer_limit: u64,
}

/// Reads an answer's body, refusing one of more than `limit` bytes: by its declared length
/// before reading anything, and as its bytes arrive (a chunked answer declares none).
async fn read_body(mut resp: reqwest::Response, limit: u64) -> Result<Vec<u8>, ClientError> {
    let url = resp.url().to_string();
    let over = |n: u64| ClientError::Protocol(format!("{url}: an answer of {n} bytes or more, over the {limit} this request allows"));
    if let Some(n) = resp.content_length().filter(|&n| n > limit) {
        return Err(over(n));
    }
    let mut out = Vec::new();
    while let Some(chunk) = resp.chunk().await? {
        let n = out.len() as u64 + chunk.len() as u64;
        if n > limit {
            return Err(over(n));
        }
        out.extend_from_slice(&chunk);
    }
    Ok(out)
}

/// The first `limit` bytes of an error answer, as text (the rest is not read).
async fn error_detail(mut resp: reqwest::Response) -> String {
    let mut out = Vec::new();
    while let Ok(Some(chunk)) = resp.chunk().await {
        let room = (ERROR_DETAIL_LIMIT as usize).saturating_sub(out.len());
        out.extend_from_slice(&chunk[..chunk.len().min(room)]);
        if room <= chunk.len() {
            break;
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

impl Client {
    /// `base` is the server's root, e.g. `http://127.0.0.1:8080`.
    pub fn new(base: &str) -> Result<Self, ClientError> {
        let http = reqwest::Client::builder().timeout(Duration::from_secs(60)).build()?;
        Ok(Client { http, base: base.trim_end_matches('/').to_string(), token: None, answer_limit: DEFAULT_ANSWER_LIMIT })
    }

    /// Sets the most bytes one answer may hold ([`DEFAULT_ANSWER_LIMIT`] unless set).
    pub fn with_answer_limit(mut self, bytes: u64) -> Self {
        self.answer_limit = bytes;
        self
    }

    /// `path`'s answer as a JSON document of at most the answer limit.
    async fn json<T: serde::de::DeserializeOwned>(&self, path: &str) -> Result<T, ClientError> {
        let body = read_body(self.get(path, None).await?, self.answer_limit).await?;
        serde_json::from_slice(&body).map_err(|e| ClientError::Protocol(format!("{}{path}: {e}", self.base)))
    }

    /// Sends `Authorization: Bearer <token>` with every request (servers with a read token).
    pub fn with_token(mut self, token: impl Into<String>) -> Self {
        self.token = Some(token.into());
        self
    }

    async fn get(&self, path: &str, range: Option<(u64, u64)>) -> Result<reqwest::Response, ClientError> {
        let url = format!("{}{path}", self.base);
        let mut req = self.http.get(&url);
        if let Some(t) = &self.token {
            req = req.bearer_auth(t);
        }
        if let Some((start, end)) = range {
            req = req.header("Range", format!("bytes={start}-{end}"));
        }
        let resp = req.send().await?;
        if !resp.status().is_success() {
            let status = resp.status().as_u16();
            let detail = error_detail(resp).await;
            return Err(ClientError::Status { url, status, detail });
        }
        Ok(resp)
    }

    /// The server's assets (`GET /v1/assets`).
    pub async fn assets(&self) -> Result<Vec<AssetSummary>, ClientError> {
        #[derive(Deserialize)]
        struct List {
            assets: Vec<AssetSummary>,
        }
        Ok(self.json::<List>("/v1/assets").await?.assets)
    }

    /// One asset's description (`GET /v1/assets/{id}`).
    pub async fn asset(&self, id: &str) -> Result<AssetInfo, ClientError> {
        self.json(&format!("/v1/assets/{id}")).await
    }

    /// LOD on demand: frame `frame` cut by the server (compact binary format).
    pub async fn mesh(&self, id: &str, frame: u32, target: CutTarget) -> Result<TriMesh, ClientError> {
        let q = Self::cut_query(target)?;
        let bytes =
            read_body(self.get(&format!("/v1/assets/{id}/mesh?frame={frame}&{q}&format=bin"), None).await?, self.answer_limit).await?;
        parse_bin_mesh(&bytes)
    }

    /// LOD on demand with the appearance (`format=bin&layout=3`): the cut's normals and, for an
    /// asset with an appearance, texture coordinates, colours and each triangle's material (an
    /// index into [`AssetInfo::appearance`]'s materials; the textures are at their own URLs).
    /// Triangles come grouped by material.
    pub async fn textured_mesh(&self, id: &str, frame: u32, target: CutTarget) -> Result<(TriMesh, Appearance), ClientError> {
        let q = Self::cut_query(target)?;
        let bytes =
            read_body(self.get(&format!("/v1/assets/{id}/mesh?frame={frame}&{q}&format=bin&layout=3"), None).await?, self.answer_limit)
                .await?;
        parse_bin_textured(&bytes)
    }

    fn cut_query(target: CutTarget) -> Result<String, ClientError> {
        Ok(match target {
            CutTarget::Triangles(n) => format!("triangles={n}"),
            CutTarget::Level(l) => format!("level={l}"),
            CutTarget::MaxError(Distance::DiagonalFraction(e)) => format!("max_error={e}"),
            CutTarget::MaxError(Distance::Absolute(_)) => {
                return Err(ClientError::Protocol("the server takes max_error as a fraction of the diagonal".into()));
            }
            CutTarget::Vertices(_) => return Err(ClientError::Protocol("the server cuts by triangles, level or error".into())),
        })
    }

    /// What a client drawing down to `level` reads of asset `id` at `version` (`GET
    /// /v1/assets/{id}/v/{version}/index?level=L`): whether its index is banded, its head
    /// ranges and per frame the ranges of its chunks.
    pub async fn index(&self, id: &str, version: &str, level: usize) -> Result<IndexAnswer, ClientError> {
        self.json(&format!("/v1/assets/{id}/v/{version}/index?level={level}")).await
    }

    /// The bytes of each of `ranges` of the file at `path` (end exclusive), up to
    /// [`MAX_RANGES_PER_REQUEST`] ranges a request, adjacent and overlapping ones merged
    /// first; with the data bytes downloaded (multipart framing not counted, as the response's
    /// own headers are not; a server may answer with the whole file, which counts whole).
    pub async fn range(&self, path: &str, ranges: &[Range<u64>]) -> Result<(Vec<Vec<u8>>, u64), ClientError> {
        let mut merged: Vec<Range<u64>> = ranges.iter().filter(|r| !r.is_empty()).cloned().collect();
        merged.sort_by_key(|r| r.start);
        let mut spans: Vec<Range<u64>> = Vec::new();
        for r in merged {
            match spans.last_mut() {
                Some(last) if r.start <= last.end => last.end = last.end.max(r.end),
                _ => spans.push(r),
            }
        }
        let mut held: Vec<(Range<u64>, Vec<u8>)> = Vec::with_capacity(spans.len());
        let mut downloaded = 0;
        for batch in spans.chunks(MAX_RANGES_PER_REQUEST) {
            let url = format!("{}{path}", self.base);
            let mut req = self.http.get(&url).header("Range", multirange::range_header(batch));
            if let Some(t) = &self.token {
                req = req.bearer_auth(t);
            }
            let resp = req.send().await?;
            let status = resp.status().as_u16();
            if !resp.status().is_success() {
                let detail = error_detail(resp).await;
                return Err(ClientError::Status { url, status, detail });
            }
            let header = |n: reqwest::header::HeaderName| resp.headers().get(n).and_then(|v| v.to_str().ok()).map(str::to_string);
            let (ct, cr) = (header(reqwest::header::CONTENT_TYPE), header(reqwest::header::CONTENT_RANGE));
            // A range answer holds the ranges and their framing; a whole-file one (200) the file.
            let asked: u64 = batch.iter().map(|r| r.end - r.start).sum();
            let limit = if status == 200 { self.answer_limit } else { asked + MULTIPART_FRAMING * (batch.len() as u64 + 1) };
            let body = read_body(resp, limit).await?;
            // Data bytes, as a single range counts them: a multipart answer's part headers
            // are framing like the response's own headers (a whole-file answer counts whole).
            downloaded += if status == 200 { body.len() as u64 } else { batch.iter().map(|r| r.end - r.start).sum() };
            let parts = multirange::split_answer(batch, status, ct.as_deref(), cr.as_deref(), &body)?;
            held.extend(batch.iter().cloned().zip(parts));
        }
        let out = ranges
            .iter()
            .map(|want| {
                held.iter()
                    .find(|(r, _)| r.start <= want.start && want.end <= r.end)
                    .map(|(r, b)| b[(want.start - r.start) as usize..(want.end - r.start) as usize].to_vec())
                    .unwrap_or_default()
            })
            .collect();
        Ok((out, downloaded))
    }

    /// What a client drawing down to `level` and playing from frame `from` reads, in one
    /// answer (`GET /v1/assets/{id}/stream?level=L&from=F`), placed back at its offsets
    /// ([`stream_source`]); with the bytes downloaded.
    pub async fn stream(&self, id: &str, level: usize, from: u32) -> Result<(pmcodec_container::streams::Sparse, u64), ClientError> {
        let resp = self.get(&format!("/v1/assets/{id}/stream?level={level}&from={from}"), None).await?;
        let start = resp
            .headers()
            .get("x-pmc-from")
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| ClientError::Protocol("a stream without x-pmc-from".into()))?;
        let body = read_body(resp, self.answer_limit).await?;
        Ok((stream_source(&body, level, start)?, body.len() as u64))
    }

    /// Opens a playback session at a triangle budget.
    pub async fn session(&self, id: &str, triangles: u32) -> Result<Session, ClientError> {
        Session::open(self.clone(), self.asset(id).await?, triangles).await
    }
}

/// The byte source a `/stream?level=L&from=F` answer holds: its head and chunk ranges placed
/// back at their offsets, so that a [`Reader::open_at`] and a [`Decoder`] of level L read the
/// file from it, and fail on anything else. `from` is the keyframe the server started at (its
/// `x-pmc-from`).
pub fn stream_source(body: &[u8], level: usize, from: u32) -> Result<pmcodec_container::streams::Sparse, ClientError> {
    Ok(pmcodec_container::streams::stream_source(body, level, from)?)
}

/// One byte range of an [`IndexAnswer`]: `[offset, length]`.
pub type ByteSpan = [u64; 2];

/// What `GET /v1/assets/{id}/v/{version}/index?level=L` says of the bytes a client of level L
/// reads (the chunks' own entries are left out).
#[derive(Clone, Debug, Deserialize)]
pub struct IndexAnswer {
    /// The level asked for.
    pub level: usize,
    /// Levels of the file.
    pub levels: usize,
    /// Length of the file.
    pub length: u64,
    /// Whether the file's index is banded, so that the head is read in part.
    pub banded: bool,
    /// The preamble, header and index bytes the client reads.
    pub head: Vec<ByteSpan>,
    /// Per frame, the ranges its chunks lie in.
    pub frames: Vec<FrameRanges>,
}

/// One frame of an [`IndexAnswer`].
#[derive(Clone, Debug, Deserialize)]
pub struct FrameRanges {
    /// The frame.
    pub frame: u32,
    /// Whether it is a keyframe.
    pub keyframe: bool,
    /// The ranges its chunks lie in, adjacent ones merged.
    pub ranges: Vec<ByteSpan>,
}

/// Parses the compact binary mesh of proto/http.md.
pub fn parse_bin_mesh(b: &[u8]) -> Result<TriMesh, ClientError> {
    pmcodec_mesh::binmesh::decode_bin(b).map_err(|e| ClientError::Protocol(e.to_string()))
}

/// Parses the compact binary mesh of proto/http.md with its appearance (layout 3; layouts 1
/// and 2 give an empty appearance).
pub fn parse_bin_textured(b: &[u8]) -> Result<(TriMesh, Appearance), ClientError> {
    pmcodec_mesh::binmesh::decode_bin_appearance(b).map_err(|e| ClientError::Protocol(e.to_string()))
}

/// The byte ranges fetched so far: a [`ByteSource`] that serves what was prefetched and
/// reports anything else as missing (the session fetches before it decodes).
#[derive(Debug, Default)]
pub struct Prefetched {
    len: u64,
    ranges: Mutex<BTreeMap<u64, Vec<u8>>>,
}

impl Prefetched {
    fn has(&self, offset: u64, len: u64) -> bool {
        let ranges = self.ranges.lock().unwrap_or_else(|e| e.into_inner());
        ranges.range(..=offset).next_back().is_some_and(|(&s, b)| s + b.len() as u64 >= offset + len)
    }

    fn insert(&self, offset: u64, bytes: Vec<u8>) {
        self.ranges.lock().unwrap_or_else(|e| e.into_inner()).insert(offset, bytes);
    }
}

impl ByteSource for Prefetched {
    fn len(&self) -> Result<u64, ContainerError> {
        Ok(self.len)
    }
    fn read_at(&self, offset: u64, len: usize) -> Result<Vec<u8>, ContainerError> {
        let ranges = self.ranges.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((&s, b)) = ranges.range(..=offset).next_back() {
            let (i, end) = ((offset - s) as usize, (offset - s) as usize + len);
            if end <= b.len() {
                return Ok(b[i..end].to_vec());
            }
        }
        Err(ContainerError::Io(format!("bytes {offset}..{} were not fetched", offset + len as u64)))
    }
}

/// A shared handle on the fetched bytes: the session fetches into it, the decoder reads it.
#[derive(Clone, Debug, Default)]
pub struct SharedBytes(Arc<Prefetched>);

impl ByteSource for SharedBytes {
    fn len(&self) -> Result<u64, ContainerError> {
        self.0.len()
    }
    fn read_at(&self, offset: u64, len: usize) -> Result<Vec<u8>, ContainerError> {
        self.0.read_at(offset, len)
    }
}

/// Fetches what a client of `level` reads of the head ([`pmcodec_container::streams::head_ranges`]:
/// of a banded index the groups of its level) and `source` lacks, in one request; returns the
/// bytes downloaded. The reader checks what they hold.
async fn fetch_head(client: &Client, file: &str, source: &SharedBytes, level: usize) -> Result<u64, ClientError> {
    let first =
        source.read_at(0, pmcodec_container::streams::first_read(&Preamble::parse(&source.read_at(0, PREAMBLE_LEN)?)?).end as usize)?;
    let wanted: Vec<Range<u64>> =
        pmcodec_container::streams::head_ranges(&first, level)?.into_iter().filter(|r| !source.0.has(r.start, r.end - r.start)).collect();
    fetch_into(client, file, source, &wanted).await
}

/// Fetches `ranges` into `source` (a few requests of several ranges); returns the bytes downloaded.
async fn fetch_into(client: &Client, file: &str, source: &SharedBytes, ranges: &[Range<u64>]) -> Result<u64, ClientError> {
    if ranges.is_empty() {
        return Ok(0);
    }
    let (parts, downloaded) = client.range(file, ranges).await?;
    for (r, bytes) in ranges.iter().zip(parts) {
        if bytes.len() as u64 != r.end - r.start {
            return Err(ClientError::Protocol(format!("range {}-{} returned {} bytes", r.start, r.end - 1, bytes.len())));
        }
        source.0.insert(r.start, bytes);
    }
    Ok(downloaded)
}

/// One frame, ready to draw.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Its index in the sequence.
    pub frame: u32,
    /// The frame cut to the session's budget.
    pub mesh: TriMesh,
    /// Bytes downloaded by the session so far.
    pub bytes_downloaded: u64,
    /// Time to apply the frame's deltas and cut it (network excluded).
    pub decode_time: Duration,
}

/// Streaming playback of one asset at a triangle budget.
pub struct Session {
    client: Client,
    /// The asset played.
    pub info: AssetInfo,
    source: SharedBytes,
    decoder: Decoder<SharedBytes>,
    budget: u32,
    /// Frames fetched ahead of the one being decoded.
    pub ahead: u32,
    bytes_downloaded: u64,
    /// A finer level [`Session::set_budget`] asked for, opened (its index groups fetched) by
    /// the next [`Session::frame`].
    pending: Option<usize>,
}

/// A level whose whole mesh falls short of the budget by at most this share still serves it:
/// levels are anchored at round shares of the input's vertices (25%, 10%), whose meshes come
/// out a few triangles short of the same share of its triangles, and the next finer band is
/// about 2.5 times larger.
pub const LEVEL_SLACK: f64 = 0.02;

/// The coarsest level whose whole mesh has at least `budget` triangles, less [`LEVEL_SLACK`].
fn level_for(info: &AssetInfo, budget: u32) -> usize {
    let need = budget as f64 * (1.0 - LEVEL_SLACK);
    info.triangles_per_level.iter().rposition(|&t| t as f64 >= need).unwrap_or(0)
}

impl Session {
    async fn open(client: Client, info: AssetInfo, budget: u32) -> Result<Self, ClientError> {
        let source = SharedBytes(Arc::new(Prefetched { len: info.summary.bytes, ..Default::default() }));
        let mut downloaded = 0;
        // Preamble, then header and index (their lengths are in the preamble).
        // At most the file (a server may answer a range with the whole of it).
        let limit = info.summary.bytes.min(client.answer_limit);
        let pre = read_body(client.get(&info.summary.file, Some((0, PREAMBLE_LEN as u64 - 1))).await?, limit).await?;
        // Magic and version are checked before the lengths are trusted.
        let p = Preamble::parse(&pre)?;
        let tables = PREAMBLE_LEN as u64 + p.header_len as u64 + p.index_len as u64;
        if tables > info.summary.bytes {
            return Err(ClientError::Protocol("header and index beyond the file".into()));
        }
        // A banded index (proto/container.md, "Index"): the header and the index's table
        // first, then only the groups of entries this session's level reads.
        let banded = p.version >= 7 && p.flags & FLAG_BANDS != 0;
        let head_end = if banded { PREAMBLE_LEN as u64 + p.header_len as u64 + p.table_len as u64 } else { tables };
        let head = read_body(client.get(&info.summary.file, Some((0, head_end - 1))).await?, limit).await?;
        if head.len() as u64 != head_end {
            return Err(ClientError::Protocol(format!("range 0-{} returned {} bytes", head_end - 1, head.len())));
        }
        downloaded += (pre.len() + head.len()) as u64;
        source.0.insert(0, head);
        let level = level_for(&info, budget);
        if banded {
            downloaded += fetch_head(&client, &info.summary.file, &source, level).await?;
        }
        let reader = Reader::open_at(source.clone(), level)?;
        let decoder = Decoder::new(reader, level)?;
        Ok(Session { client, info, source, decoder, budget, ahead: 4, bytes_downloaded: downloaded, pending: None })
    }

    /// The triangle budget each frame is cut to.
    pub fn budget(&self) -> u32 {
        self.budget
    }

    /// Finest level this session reads.
    pub fn level(&self) -> usize {
        self.pending.unwrap_or(self.decoder.min_level())
    }

    /// Bytes downloaded by the session so far.
    pub fn bytes_downloaded(&self) -> u64 {
        self.bytes_downloaded
    }

    /// Changes the budget while playing; a budget that needs finer bands restarts the decoder
    /// at that level (it re-reads the current frame's keyframe and the finer bands) when the
    /// next frame is asked for, which first fetches those bands' index groups (a banded index).
    pub fn set_budget(&mut self, triangles: u32) -> Result<(), ClientError> {
        self.budget = triangles;
        let need = level_for(&self.info, triangles);
        if need < self.level() {
            self.pending = Some(need);
        }
        Ok(())
    }

    /// Opens the level [`Session::set_budget`] asked for.
    async fn open_pending(&mut self) -> Result<(), ClientError> {
        let Some(level) = self.pending else { return Ok(()) };
        self.bytes_downloaded += fetch_head(&self.client, &self.info.summary.file, &self.source, level).await?;
        self.decoder = Decoder::new(Reader::open_at(self.source.clone(), level)?, level)?;
        self.pending = None;
        Ok(())
    }

    /// Downloads what frames `frame..=frame + ahead` need and is not here yet, adjacent chunks
    /// in one range request.
    async fn fetch(&mut self, frame: u32) -> Result<(), ClientError> {
        let h = self.decoder.reader().header();
        let last = (frame + self.ahead).min(h.frame_count - 1);
        let mut wanted: Vec<ChunkEntry> = self.decoder.chunks_for(frame);
        let level = self.decoder.min_level();
        wanted.extend(self.decoder.reader().index().chunks.iter().filter(|e| {
            e.frame > frame
                && e.frame <= last
                && self.decoder.reader().reads(e, level)
                && matches!(
                    e.kind,
                    ChunkKind::Delta | ChunkKind::Positions | ChunkKind::Corners | ChunkKind::Pose | ChunkKind::Palette | ChunkKind::Joints
                )
        }));
        let start = self.decoder.reader().data_start();
        let mut spans: Vec<Range<u64>> = Vec::new();
        let mut chunks: Vec<Range<u64>> = wanted
            .iter()
            .map(|e| start + e.offset..start + e.offset + e.stored_len as u64)
            .filter(|r| !r.is_empty() && !self.source.0.has(r.start, r.end - r.start))
            .collect();
        chunks.sort_unstable_by_key(|r| r.start);
        for r in chunks {
            match spans.last_mut() {
                Some(last) if r.start <= last.end => last.end = last.end.max(r.end),
                _ => spans.push(r),
            }
        }
        // Several ranges a request: a banded file keeps a band's chunks together, so a frame's
        // chunks lie in a few ranges per band, not one span.
        self.bytes_downloaded += fetch_into(&self.client, &self.info.summary.file, &self.source, &spans).await?;
        Ok(())
    }

    /// Frame `frame` at the current budget.
    pub async fn frame(&mut self, frame: u32) -> Result<Frame, ClientError> {
        self.open_pending().await?;
        self.fetch(frame).await?;
        let t = Instant::now();
        self.decoder.seek(frame)?;
        let mesh = self.decoder.mesh(CutTarget::Triangles(self.budget))?;
        Ok(Frame { frame, mesh, bytes_downloaded: self.bytes_downloaded, decode_time: t.elapsed() })
    }
}
