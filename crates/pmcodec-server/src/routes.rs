//! The routes, one handler each, in the order proto/http.md documents them.

use crate::{ApiError, AppState, Asset, validate_id};
use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::{Json, Router};
use pmcodec_container::{Decoder, MeshTarget, summary};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

type Shared = Arc<AppState>;

/// Every route the server mounts (checked against proto/openapi.yaml by a test).
pub const ROUTES: &[&str] = &["/healthz", "/readyz", "/v1/assets", "/v1/assets/{id}", "/v1/assets/{id}/mesh", "/v1/assets/{id}/v/{version}"];

/// The application: API routes, and the viewer's files at `/` when a folder is given.
pub fn router(state: Shared, viewer: Option<&std::path::Path>) -> Router {
    let api = Router::new()
        .route("/healthz", get(|| async { "ok" }))
        .route("/readyz", get(|| async { "ready" }))
        .route("/v1/assets", get(list_assets))
        .route("/v1/assets/{id}", get(asset_info))
        .route("/v1/assets/{id}/mesh", get(mesh))
        .route("/v1/assets/{id}/v/{version}", get(file))
        .with_state(state)
        .layer(axum::middleware::from_fn(log_request))
        .layer(tower_http::cors::CorsLayer::permissive())
        .layer(tower_http::limit::RequestBodyLimitLayer::new(64 * 1024));
    match viewer {
        Some(dir) if dir.is_dir() => api.fallback_service(tower_http::services::ServeDir::new(dir)),
        _ => api,
    }
}

/// One log line per request (method, path and query, range, status, time), the server's
/// request log.
async fn log_request(req: axum::extract::Request, next: axum::middleware::Next) -> Response {
    let (method, uri) = (req.method().clone(), req.uri().clone());
    let range = req.headers().get(header::RANGE).and_then(|v| v.to_str().ok()).map(str::to_string);
    let start = std::time::Instant::now();
    let resp = next.run(req).await;
    tracing::info!(
        target: "pmcodec::request",
        "{method} {uri} range={} status={} {:.1}ms",
        range.as_deref().unwrap_or("-"),
        resp.status().as_u16(),
        start.elapsed().as_secs_f64() * 1e3
    );
    resp
}

fn find(state: &AppState, id: &str) -> Result<Arc<Asset>, ApiError> {
    validate_id(id)?;
    state.assets.get(id).cloned().ok_or_else(|| ApiError::NotFound(format!("no asset {id:?}")))
}

#[derive(Serialize)]
struct AssetSummary {
    id: String,
    frames: u32,
    frame_rate: f32,
    vertices: u32,
    triangles: u32,
    levels: Vec<u32>,
    bytes: usize,
    /// Immutable URL of the container (changes whenever the content does).
    file: String,
}

fn version(a: &Asset) -> String {
    a.etag.trim_matches('"').to_string()
}

fn summarise(a: &Asset) -> Result<AssetSummary, ApiError> {
    let r = a.reader()?;
    let h = r.header();
    Ok(AssetSummary {
        id: a.id.clone(),
        frames: h.frame_count,
        frame_rate: h.frame_rate,
        vertices: h.vertex_count,
        triangles: h.triangle_count,
        levels: h.level_sizes.clone(),
        bytes: a.bytes.len(),
        file: format!("/v1/assets/{}/v/{}.pmc", a.id, version(a)),
    })
}

/// `GET /v1/assets`
async fn list_assets(State(state): State<Shared>) -> Result<Json<serde_json::Value>, ApiError> {
    let assets = state.assets.values().map(|a| summarise(a)).collect::<Result<Vec<_>, _>>()?;
    Ok(Json(serde_json::json!({ "assets": assets })))
}

#[derive(Serialize)]
struct AssetInfo {
    #[serde(flatten)]
    summary: AssetSummary,
    bbox_min: [f32; 3],
    bbox_max: [f32; 3],
    keyframe_interval: u32,
    /// Triangles shown by each whole level in frame 0.
    triangles_per_level: Vec<usize>,
    /// Bytes per frame a client stopping at each level reads.
    bytes_per_frame_to_level: Vec<f64>,
    positions_bits_per_vertex_frame: f64,
}

/// `GET /v1/assets/{id}`
async fn asset_info(State(state): State<Shared>, Path(id): Path<String>) -> Result<Json<AssetInfo>, ApiError> {
    let a = find(&state, &id)?;
    tokio::task::spawn_blocking(move || {
        let r = a.reader()?;
        let s = summary(&r);
        let mut d = Decoder::new(r.borrowed(), 0).map_err(|e| ApiError::Internal(e.to_string()))?;
        d.seek(0).map_err(|e| ApiError::Internal(e.to_string()))?;
        let mut triangles_per_level = Vec::new();
        for l in 0..s.header.levels() {
            let m = d.mesh(MeshTarget::Level(l)).map_err(|e| ApiError::Internal(e.to_string()))?;
            triangles_per_level.push(m.triangles.len());
        }
        Ok(Json(AssetInfo {
            summary: summarise(&a)?,
            bbox_min: s.header.bbox_min,
            bbox_max: s.header.bbox_max,
            keyframe_interval: s.header.keyframe_interval,
            triangles_per_level,
            bytes_per_frame_to_level: s.bytes_per_frame_to_level,
            positions_bits_per_vertex_frame: s.positions_bits_per_vertex_frame,
        }))
    })
    .await
    .map_err(|e| ApiError::Internal(e.to_string()))?
}

#[derive(Deserialize)]
struct MeshQuery {
    frame: Option<u32>,
    triangles: Option<u32>,
    level: Option<usize>,
    max_error: Option<f64>,
    format: Option<String>,
}

/// Magic of the compact binary mesh format (proto/http.md).
pub const MESH_MAGIC: &[u8; 4] = b"PMCM";

/// `GET /v1/assets/{id}/mesh?frame=F&triangles=N|level=L|max_error=E&format=glb|bin`
async fn mesh(State(state): State<Shared>, Path(id): Path<String>, Query(q): Query<MeshQuery>) -> Result<Response, ApiError> {
    let a = find(&state, &id)?;
    let target = match (q.triangles, q.level, q.max_error) {
        (Some(n), None, None) => MeshTarget::Triangles(n),
        (None, Some(l), None) => MeshTarget::Level(l),
        (None, None, Some(e)) if e.is_finite() && e >= 0.0 => MeshTarget::MaxError(e),
        (None, None, Some(e)) => return Err(ApiError::BadRequest(format!("max_error {e} must be a finite number >= 0"))),
        (None, None, None) => MeshTarget::Triangles(u32::MAX),
        _ => return Err(ApiError::BadRequest("give at most one of triangles, level, max_error".into())),
    };
    let format = q.format.unwrap_or_else(|| "glb".into());
    if format != "glb" && format != "bin" {
        return Err(ApiError::BadRequest(format!("format {format:?}: use glb or bin")));
    }
    let frame = q.frame.unwrap_or(0);
    let mesh = tokio::task::spawn_blocking(move || {
        let r = a.reader()?;
        let h = r.header();
        if frame >= h.frame_count {
            return Err(ApiError::BadRequest(format!("frame {frame}: the asset has frames 0..{}", h.frame_count - 1)));
        }
        if let MeshTarget::Level(l) = target
            && l >= h.levels() {
                return Err(ApiError::BadRequest(format!("level {l}: the asset has levels 0..{}", h.levels() - 1)));
            }
        // A level request reads only the bands it needs.
        let min_level = if let MeshTarget::Level(l) = target { l } else { 0 };
        let mut d = Decoder::new(r.borrowed(), min_level).map_err(|e| ApiError::Internal(e.to_string()))?;
        d.seek(frame).map_err(|e| ApiError::Internal(e.to_string()))?;
        d.mesh(target).map_err(|e| ApiError::Internal(e.to_string()))
    })
    .await
    .map_err(|e| ApiError::Internal(e.to_string()))??;
    let (body, mime) = if format == "glb" {
        (pmcodec_mesh::write::glb_bytes(&mesh), "model/gltf-binary")
    } else {
        let mut b = Vec::with_capacity(16 + mesh.positions.len() * 12 + mesh.triangles.len() * 12);
        b.extend_from_slice(MESH_MAGIC);
        b.extend_from_slice(&1u32.to_le_bytes());
        b.extend_from_slice(&(mesh.positions.len() as u32).to_le_bytes());
        b.extend_from_slice(&(mesh.triangles.len() as u32).to_le_bytes());
        for p in &mesh.positions {
            for c in p.to_array() {
                b.extend_from_slice(&c.to_le_bytes());
            }
        }
        for t in &mesh.triangles {
            for i in t {
                b.extend_from_slice(&i.to_le_bytes());
            }
        }
        (b, "application/octet-stream")
    };
    let mut resp = body.into_response();
    resp.headers_mut().insert(header::CONTENT_TYPE, HeaderValue::from_static(mime));
    Ok(resp)
}

/// `GET /v1/assets/{id}/v/{version}.pmc`: the container, immutable, with Range and ETag.
async fn file(State(state): State<Shared>, Path((id, version_pmc)): Path<(String, String)>, headers: HeaderMap) -> Result<Response, ApiError> {
    let a = find(&state, &id)?;
    let wanted = version_pmc.strip_suffix(".pmc").unwrap_or(&version_pmc);
    if wanted != version(&a) {
        return Err(ApiError::NotFound(format!("asset {id} has no version {wanted:?} (current: {})", version(&a))));
    }
    let etag = HeaderValue::from_str(&a.etag).map_err(|e| ApiError::Internal(e.to_string()))?;
    let mut base = HeaderMap::new();
    base.insert(header::ETAG, etag);
    base.insert(header::CACHE_CONTROL, HeaderValue::from_static("public, max-age=31536000, immutable"));
    base.insert(header::ACCEPT_RANGES, HeaderValue::from_static("bytes"));
    base.insert(header::CONTENT_TYPE, HeaderValue::from_static("application/octet-stream"));
    if headers.get(header::IF_NONE_MATCH).and_then(|v| v.to_str().ok()).is_some_and(|v| v.split(',').any(|t| t.trim() == a.etag || t.trim() == "*")) {
        return Ok((StatusCode::NOT_MODIFIED, base).into_response());
    }
    // If-Range with a different validator: the client's partial copy is stale, send it all.
    let range_applies = headers.get(header::IF_RANGE).and_then(|v| v.to_str().ok()).is_none_or(|v| v == a.etag);
    let len = a.bytes.len() as u64;
    match headers.get(header::RANGE).and_then(|v| v.to_str().ok()) {
        Some(spec) if range_applies => match parse_range(spec, len)? {
            Some((start, end)) => {
                let mut h = base;
                h.insert(
                    header::CONTENT_RANGE,
                    HeaderValue::from_str(&format!("bytes {start}-{end}/{len}")).map_err(|e| ApiError::Internal(e.to_string()))?,
                );
                Ok((StatusCode::PARTIAL_CONTENT, h, a.bytes[start as usize..=end as usize].to_vec()).into_response())
            }
            None => Ok((StatusCode::OK, base, a.bytes.clone()).into_response()),
        },
        _ => Ok((StatusCode::OK, base, a.bytes.clone()).into_response()),
    }
}

/// One `bytes=` range (RFC 9110 section 14.1.2) as inclusive `(start, end)`; `None` for a set of
/// several ranges, which this server answers with the whole representation (allowed by
/// section 14.2). Unsatisfiable or malformed ranges are 416.
pub fn parse_range(spec: &str, len: u64) -> Result<Option<(u64, u64)>, ApiError> {
    let bad = || ApiError::RangeNotSatisfiable(format!("range {spec:?} does not fit {len} bytes"));
    let set = spec.strip_prefix("bytes=").ok_or_else(bad)?;
    if set.contains(',') {
        return Ok(None);
    }
    let (a, b) = set.trim().split_once('-').ok_or_else(bad)?;
    let (start, end) = if a.is_empty() {
        let n: u64 = b.parse().map_err(|_| bad())?;
        if n == 0 || len == 0 {
            return Err(bad());
        }
        (len.saturating_sub(n), len - 1)
    } else {
        let s: u64 = a.parse().map_err(|_| bad())?;
        let e: u64 = if b.is_empty() { len.saturating_sub(1) } else { b.parse::<u64>().map_err(|_| bad())?.min(len.saturating_sub(1)) };
        (s, e)
    };
    if start >= len || start > end {
        return Err(bad());
    }
    Ok(Some((start, end)))
}
