//! The routes: one table (what is mounted, with which limits) and one handler per route, in the
//! order proto/http.md documents them.

use crate::assets::LoadedAsset;
use crate::decode::MeshRequest;
use crate::jobs::valid_job_id;
use crate::meshfmt::MeshFormat;
use crate::middleware::{self, CompressWhenItPays, WriteAccess};
use crate::ranges::{self, IMMUTABLE, Representation};
use crate::upload::{UploadBody, UploadOptions};
use crate::{ApiError, AppState, AssetId};
use axum::body::Body;
use axum::extract::{DefaultBodyLimit, FromRequestParts, Path, Query, Request, State};
use axum::http::request::Parts;
use axum::http::{HeaderMap, HeaderValue, Method, StatusCode, Uri, header};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{MethodRouter, delete, get, post};
use axum::{Json, Router};
use bytes::Bytes;
use pmcodec_container::{CutTarget, Distance};
use pmcodec_mesh::gltf_input::AnimationSelector;
use serde::Deserialize;
use serde::de::DeserializeOwned;
use std::collections::HashMap;
use std::sync::Arc;
use std::time::Duration;

/// How a route is guarded and limited.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Class {
    /// Health, readiness, metrics: no token, short timeout.
    Ops,
    /// Reads under /v1: the read token when configured, the request timeout.
    Read,
    /// Long-lived reads (event streams): the read token, no timeout on the head either.
    LongRead,
    /// Writes: the write token (checked by the handler's `WriteAccess` argument), the upload
    /// body limit and timeout.
    Write,
}

struct Route {
    method: Method,
    path: &'static str,
    class: Class,
    handler: MethodRouter<AppState>,
}

fn table() -> Vec<Route> {
    use Class::*;
    let r = |method: Method, path: &'static str, class: Class, handler: MethodRouter<AppState>| Route { method, path, class, handler };
    vec![
        r(Method::GET, "/healthz", Ops, get(healthz)),
        r(Method::GET, "/readyz", Ops, get(readyz)),
        r(Method::GET, "/metrics", Ops, get(metrics)),
        r(Method::GET, "/v1/assets", Read, get(list_assets)),
        r(Method::POST, "/v1/assets", Write, post(upload)),
        r(Method::GET, "/v1/assets/{id}", Read, get(asset_info)),
        r(Method::DELETE, "/v1/assets/{id}", Write, delete(delete_asset)),
        r(Method::GET, "/v1/assets/{id}/mesh", Read, get(mesh)),
        r(Method::GET, "/v1/assets/{id}/stream", Read, get(stream)),
        r(Method::GET, "/v1/assets/{id}/v/{version}/file", Read, get(file)),
        r(Method::GET, "/v1/assets/{id}/v/{version}/index", Read, get(index)),
        r(Method::GET, "/v1/assets/{id}/v/{version}/chunks/{n}", Read, get(chunk)),
        r(Method::GET, "/v1/assets/{id}/v/{version}/images/{n}", Read, get(image)),
        r(Method::GET, "/v1/jobs/{id}", Read, get(job_status)),
        r(Method::DELETE, "/v1/jobs/{id}", Write, delete(cancel_job)),
        r(Method::GET, "/v1/jobs/{id}/events", LongRead, get(job_events)),
    ]
}

/// Every (method, path template) the router mounts; a test holds this equal to
/// proto/openapi.yaml. (GET routes also answer HEAD, as HTTP requires.)
pub fn mounted_routes() -> Vec<(Method, &'static str)> {
    table().into_iter().map(|r| (r.method, r.path)).collect()
}

/// The whole application: API routes, the viewer's files at `/` when configured, and JSON
/// errors for unknown routes and methods.
pub fn router(app: AppState) -> Router {
    let limits = &app.config.limits;
    let mut api = Router::new();
    for route in table() {
        let h = route.handler;
        let h = match route.class {
            Class::Ops => h.layer(axum::middleware::from_fn_with_state(Duration::from_secs(5), middleware::timeout)),
            Class::Read => h
                .layer(axum::middleware::from_fn_with_state(limits.request_timeout(), middleware::timeout))
                .layer(axum::middleware::from_fn_with_state(app.clone(), middleware::read_auth)),
            Class::LongRead => h.layer(axum::middleware::from_fn_with_state(app.clone(), middleware::read_auth)),
            Class::Write => h
                .layer(DefaultBodyLimit::max(usize::try_from(limits.upload_bytes).unwrap_or(usize::MAX)))
                .layer(axum::middleware::from_fn_with_state(limits.upload_timeout(), middleware::timeout)),
        };
        let h = if route.class == Class::Write {
            h
        } else {
            h.layer(DefaultBodyLimit::max(usize::try_from(limits.body_bytes).unwrap_or(usize::MAX)))
        };
        api = api.route(route.path, h);
    }
    api.method_not_allowed_fallback(method_not_allowed)
        .fallback(fallback)
        .with_state(app.clone())
        .layer(tower_http::compression::CompressionLayer::new().compress_when(CompressWhenItPays))
        .layer(axum::middleware::from_fn(middleware::weaken_etag_when_encoded))
        .layer(middleware::cors(&app.config.cors.allow_origins))
        .layer(axum::middleware::from_fn_with_state(app.clone(), middleware::request_context))
}

// ---------------------------------------------------------------------------------------------
// Extractors whose rejections are JSON errors like every other 4xx.

/// Path parameters by name.
struct Params(HashMap<String, String>);

impl<S: Send + Sync> FromRequestParts<S> for Params {
    type Rejection = ApiError;
    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, ApiError> {
        Path::<HashMap<String, String>>::from_request_parts(parts, state)
            .await
            .map(|Path(p)| Params(p))
            .map_err(|e| ApiError::BadRequest(e.body_text()))
    }
}

impl Params {
    fn get(&self, name: &str) -> Result<&str, ApiError> {
        self.0.get(name).map(String::as_str).ok_or_else(|| ApiError::Internal(format!("route has no {{{name}}}")))
    }
    fn asset_id(&self) -> Result<AssetId, ApiError> {
        AssetId::parse(self.get("id")?)
    }
}

/// A query string; unknown parameters and bad values are 400 with serde's message.
struct Q<T>(T);

impl<T: DeserializeOwned, S: Send + Sync> FromRequestParts<S> for Q<T> {
    type Rejection = ApiError;
    async fn from_request_parts(parts: &mut Parts, _: &S) -> Result<Self, ApiError> {
        Query::<T>::try_from_uri(&parts.uri).map(|Query(q)| Q(q)).map_err(|e| ApiError::BadRequest(e.body_text()))
    }
}

fn header_value(s: &str) -> Result<HeaderValue, ApiError> {
    HeaderValue::from_str(s).map_err(|e| ApiError::Internal(format!("header value {s:?}: {e}")))
}

/// `Cache-Control` of content-addressed URLs: shared caches may keep them forever, unless reads
/// need a token, when only the client's own cache may (a CDN would otherwise hand them to
/// anyone).
fn immutable(app: &AppState) -> &'static str {
    if app.config.auth.read_token.is_some() { IMMUTABLE_PRIVATE } else { IMMUTABLE }
}

const IMMUTABLE_PRIVATE: &str = "private, max-age=31536000, immutable";

/// JSON that may change (metadata by id): validated by ETag, never cached without asking.
fn json_revalidated<T: serde::Serialize>(req: &HeaderMap, etag: &str, value: &T) -> Result<Response, ApiError> {
    let body = serde_json::to_vec(value).map_err(|e| ApiError::Internal(e.to_string()))?;
    ranges::serve(
        req,
        Representation { bytes: body.into(), etag: etag.into(), content_type: "application/json", cache_control: "no-cache" },
        0,
    )
}

// ---------------------------------------------------------------------------------------------
// Operations.

/// `GET /healthz`: the process answers.
async fn healthz() -> &'static str {
    "ok"
}

/// `GET /readyz`: the assets are in place and the store answers.
async fn readyz(State(app): State<AppState>) -> Result<&'static str, ApiError> {
    if !app.is_ready() {
        return Err(ApiError::Busy("not ready: starting (encoding the built-in samples) or shutting down".into()));
    }
    match tokio::time::timeout(Duration::from_secs(3), app.store.check()).await {
        Ok(Ok(())) => Ok("ready"),
        Ok(Err(e)) => {
            tracing::warn!(error = %e, "readiness: the store does not answer");
            Err(ApiError::Busy("not ready: the asset store does not answer".into()))
        }
        Err(_) => Err(ApiError::Busy("not ready: the asset store is slow to answer".into())),
    }
}

/// `GET /metrics`: Prometheus text exposition.
async fn metrics(State(app): State<AppState>) -> Response {
    let (asset_bytes, asset_entries) = app.assets.usage();
    let g = crate::metrics::Gauges {
        ready: app.is_ready(),
        asset_cache_bytes: asset_bytes,
        asset_cache_entries: asset_entries,
        decode: app.decoder.gauges(),
        jobs_pending: app.jobs.pending(),
    };
    ([(header::CONTENT_TYPE, "text/plain; version=0.0.4; charset=utf-8")], app.metrics.render(&g)).into_response()
}

async fn method_not_allowed(method: Method, uri: Uri) -> ApiError {
    ApiError::MethodNotAllowed { method: method.to_string(), path: middleware::clip(uri.path()).into_owned() }
}

/// What the viewer's pages may load: their own scripts (the Vite bundle, no inline script),
/// their inline styles, and the API of this origin; no frames, plugins or foreign origins.
const VIEWER_CSP: &str = "default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; img-src 'self' data: blob:; \
     connect-src 'self' data: blob:; worker-src 'self' blob:; object-src 'none'; base-uri 'self'; form-action 'self'; \
     frame-ancestors 'none'";

/// Unknown paths: JSON 404 under /v1, else the viewer's files when a viewer folder is set.
async fn fallback(State(app): State<AppState>, req: Request) -> Response {
    let path = req.uri().path();
    let api = path == "/v1" || path.starts_with("/v1/");
    match (&app.config.viewer, api) {
        (Some(dir), false) if matches!(*req.method(), Method::GET | Method::HEAD) => {
            use tower::ServiceExt;
            let mut resp = match tower_http::services::ServeDir::new(dir).oneshot(req).await {
                Ok(resp) => resp.into_response(),
                Err(never) => match never {},
            };
            resp.headers_mut().insert(header::CONTENT_SECURITY_POLICY, HeaderValue::from_static(VIEWER_CSP));
            resp
        }
        _ => {
            ApiError::NotFound(format!("no route {} {}; the API is described in proto/openapi.yaml", req.method(), middleware::clip(path)))
                .into_response()
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Assets.

/// Containers a listing loads at once when their metadata is not known yet.
const LIST_LOADS: usize = 4;

/// `GET /v1/assets`
async fn list_assets(State(app): State<AppState>) -> Result<Response, ApiError> {
    use futures_util::StreamExt;
    let objects = app.store.list().await?;
    // Metadata not yet known means fetching and checking the container: a few at a time
    // (a cold server listing a bucket waits for the slowest of each few, not for the sum),
    // in listing order.
    let infos: Vec<_> = futures_util::stream::iter(objects.iter().cloned())
        .map(|obj| {
            let app = app.clone();
            async move {
                let info = app.assets.info(&obj).await;
                (obj, info)
            }
        })
        .buffered(LIST_LOADS)
        .collect()
        .await;
    let mut assets = Vec::with_capacity(objects.len());
    for (obj, info) in infos {
        match info {
            Ok(info) => assets.push(info.summary.clone()),
            // One unreadable object should not hide the others; the log names it.
            Err(e) => tracing::warn!(asset = %obj.id, error = %e, "leaving an unreadable asset out of the listing"),
        }
    }
    let mut resp = Json(serde_json::json!({ "assets": assets })).into_response();
    resp.headers_mut().insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    Ok(resp)
}

/// `GET /v1/assets/{id}`
async fn asset_info(State(app): State<AppState>, p: Params, headers: HeaderMap) -> Result<Response, ApiError> {
    let a = app.assets.get(&p.asset_id()?).await?;
    json_revalidated(&headers, &format!("\"{}-info\"", a.version), &*a.info)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct UploadQuery {
    id: Option<String>,
    fps: Option<f32>,
    animation: Option<String>,
    replace: Option<bool>,
}

/// `POST /v1/assets?id=ID[&fps=F][&animation=A][&replace=true]`: starts an encode job.
async fn upload(
    State(app): State<AppState>,
    access: Result<WriteAccess, ApiError>,
    q: Result<Q<UploadQuery>, ApiError>,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, ApiError> {
    // Refused before the body is read: the body is drained first, so the client gets the
    // answer rather than a reset connection.
    let checked = match (access, q) {
        (Ok(_), Ok(Q(q))) => check_upload(&app, q).await,
        (Err(e), _) | (_, Err(e)) => Err(e),
    };
    let (id, opts) = match checked {
        Ok(checked) => checked,
        Err(e) => {
            if !continue_expected(&headers) {
                crate::upload::drain(body).await;
            }
            return Err(e);
        }
    };
    // A place in the queue before the body is read: a full queue answers at once, and a body
    // being received counts against the queue like a queued job.
    let place = match app.jobs.reserve(&app, id.clone()) {
        Ok(place) => place,
        Err(e) => {
            if !continue_expected(&headers) {
                crate::upload::drain(body).await;
            }
            return Err(e);
        }
    };
    let dir = app.config.upload_dir.clone().unwrap_or_else(std::env::temp_dir);
    let l = &app.config.limits;
    let limits = crate::upload::BodyLimits { bytes: l.upload_bytes, files: l.max_frames as usize, dir: &dir };
    let body = UploadBody::read(&headers, body, &limits).await?;
    let status = app.jobs.submit(&app, place, body, opts)?;
    let location = header_value(&status.status_url)?;
    Ok((StatusCode::ACCEPTED, [(header::LOCATION, location)], Json(status)).into_response())
}

/// A client that asked `Expect: 100-continue` has not sent its body (hyper sends the 100 only
/// once the body is read): it can be answered at once.
fn continue_expected(headers: &HeaderMap) -> bool {
    headers.get(header::EXPECT).is_some_and(|v| v.as_bytes().eq_ignore_ascii_case(b"100-continue"))
}

/// Frame rates an upload may ask for: a glTF animation is sampled at this rate, and the
/// frame time is the reciprocal (`fps=1e-30` made a player's frame time overflow).
const FPS_RANGE: std::ops::RangeInclusive<f32> = 0.1..=240.0;

/// What an upload's query says, checked before its body is read (a large body is not read
/// when the answer is known already).
async fn check_upload(app: &AppState, q: UploadQuery) -> Result<(AssetId, UploadOptions), ApiError> {
    let id = AssetId::parse(q.id.as_deref().ok_or_else(|| ApiError::BadRequest("name the asset: POST /v1/assets?id=<id>".into()))?)?;
    let frame_rate = q.fps.unwrap_or(30.0);
    if !(frame_rate.is_finite() && FPS_RANGE.contains(&frame_rate)) {
        return Err(ApiError::BadRequest(format!(
            "fps {frame_rate}: use a frame rate from {} to {} frames per second",
            FPS_RANGE.start(),
            FPS_RANGE.end()
        )));
    }
    let animation = q.animation.map(|a| a.parse::<usize>().map_or(AnimationSelector::Name(a), AnimationSelector::Index));
    if !q.replace.unwrap_or(false) && app.store.head(&id).await?.is_some() {
        return Err(ApiError::Conflict(format!("asset {id} exists; add replace=true to replace it")));
    }
    if app.jobs.is_pending(&id) {
        return Err(ApiError::Conflict(format!("an encode job for asset {id} is already queued or running")));
    }
    let opts = UploadOptions {
        frame_rate,
        animation,
        unpacked_limit: app.config.limits.unpacked_bytes,
        max_frames: app.config.limits.max_frames,
        replace: q.replace.unwrap_or(false),
        input_limits: app.config.limits.input,
    };
    Ok((id, opts))
}

/// `DELETE /v1/assets/{id}`
async fn delete_asset(State(app): State<AppState>, _: WriteAccess, p: Params) -> Result<StatusCode, ApiError> {
    let id = p.asset_id()?;
    let existed = app.store.delete(&id).await?;
    app.assets.forget(&id);
    if existed { Ok(StatusCode::NO_CONTENT) } else { Err(ApiError::NotFound(format!("no asset {id}"))) }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshQuery {
    frame: Option<u32>,
    triangles: Option<u32>,
    vertices: Option<u32>,
    level: Option<usize>,
    max_error: Option<f64>,
    format: Option<String>,
    /// The compact binary's layout version: 2 (the default) or 3 (with the appearance).
    layout: Option<u32>,
}

impl MeshQuery {
    /// The request, checked against the asset.
    fn resolve(self, a: &LoadedAsset) -> Result<MeshRequest, ApiError> {
        let h = &a.header;
        let frame = self.frame.unwrap_or(0);
        if frame >= h.frame_count {
            return Err(ApiError::BadRequest(format!("frame {frame}: asset {} has frames 0..={}", a.id, h.frame_count - 1)));
        }
        let target = match (self.triangles, self.vertices, self.level, self.max_error) {
            (Some(n), None, None, None) => CutTarget::Triangles(n),
            (None, Some(n), None, None) => CutTarget::Vertices(n),
            (None, None, Some(l), None) if l < h.levels() => CutTarget::Level(l),
            (None, None, Some(l), None) => {
                return Err(ApiError::BadRequest(format!("level {l}: asset {} has levels 0..={}", a.id, h.levels() - 1)));
            }
            (None, None, None, Some(e)) if e.is_finite() && e >= 0.0 => CutTarget::MaxError(Distance::DiagonalFraction(e)),
            (None, None, None, Some(e)) => return Err(ApiError::BadRequest(format!("max_error {e}: use a finite number >= 0"))),
            (None, None, None, None) => CutTarget::Level(0),
            _ => return Err(ApiError::BadRequest("give at most one of triangles, vertices, level, max_error".into())),
        };
        let format = match self.format.as_deref() {
            None => MeshFormat::Glb,
            Some(f) => MeshFormat::parse(f).ok_or_else(|| ApiError::BadRequest(format!("format {f:?}: use glb or bin")))?,
        };
        // Layout 3 is opt-in so that clients reading only layouts 1 and 2 keep working.
        let format = match (format, self.layout) {
            (f, None) => f,
            (MeshFormat::Bin, Some(2)) => MeshFormat::Bin,
            (MeshFormat::Bin, Some(3)) => MeshFormat::Bin3,
            (MeshFormat::Bin, Some(l)) => return Err(ApiError::BadRequest(format!("layout {l}: use 2 or 3"))),
            (_, Some(_)) => return Err(ApiError::BadRequest("layout applies to format=bin only".into())),
        };
        Ok(MeshRequest { frame, target, format })
    }
}

/// Generation of the mesh answers' bytes for a given container and request: raised whenever
/// the cut rule or a body layout changes (2: split-order prefixes and 16-bit indices; 3: split
/// priorities from quadrics), so a strong tag never names two different bodies across server
/// versions.
const MESH_GENERATION: u32 = 3;

/// A strong validator of a mesh response: the output is a function of the container's bytes,
/// the normalised request and [`MESH_GENERATION`].
fn mesh_etag(version: &str, r: &MeshRequest) -> String {
    let t = match r.target {
        CutTarget::Triangles(n) => format!("t{n}"),
        CutTarget::Vertices(n) => format!("v{n}"),
        CutTarget::Level(l) => format!("l{l}"),
        CutTarget::MaxError(Distance::DiagonalFraction(e)) => format!("e{e}"),
        CutTarget::MaxError(Distance::Absolute(d)) => format!("d{d}"),
    };
    format!("\"{version}-f{}-{t}-{}-m{MESH_GENERATION}\"", r.frame, r.format.name())
}

/// `GET /v1/assets/{id}/mesh?frame=F&triangles=N|vertices=N|level=L|max_error=E&format=glb|bin`
/// `HEAD` answers from the request and the asset's metadata (type, ETag, version) without
/// decoding: the counts (`x-pmc-vertices`, `x-pmc-triangles`) come only with `GET`.
async fn mesh(
    State(app): State<AppState>,
    method: Method,
    p: Params,
    Q(q): Q<MeshQuery>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let a = app.assets.get(&p.asset_id()?).await?;
    let req = q.resolve(&a)?;
    let etag = mesh_etag(&a.version, &req);
    let version = header_value(&a.version)?;
    // Answer a revalidation without decoding anything.
    let mut resp = if method == Method::HEAD {
        (StatusCode::OK, [(header::CONTENT_TYPE, req.format.content_type())]).into_response()
    } else if headers.get(header::IF_NONE_MATCH).and_then(|v| v.to_str().ok()).is_some_and(|v| {
        v.split(',').any(|t| {
            // If-None-Match compares weakly (RFC 9110 13.1.2): a W/ prefix does not matter.
            let t = t.trim();
            t == "*" || t.strip_prefix("W/").unwrap_or(t) == etag
        })
    }) {
        StatusCode::NOT_MODIFIED.into_response()
    } else {
        let out = app.decoder.mesh(a, req).await?;
        let mut resp = (StatusCode::OK, [(header::CONTENT_TYPE, req.format.content_type())], out.body).into_response();
        let h = resp.headers_mut();
        h.insert("x-pmc-vertices", HeaderValue::from(out.vertices));
        h.insert("x-pmc-triangles", HeaderValue::from(out.triangles));
        h.insert("server-timing", header_value(&format!("decode;dur={:.3}", out.micros as f64 / 1e3))?);
        resp
    };
    let h = resp.headers_mut();
    h.insert(header::ETAG, header_value(&etag)?);
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    h.insert("x-pmc-version", version);
    Ok(resp)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct StreamQuery {
    /// Finest level the client draws: bands `level..=top` are sent.
    level: Option<usize>,
    /// First frame the client plays: the stream starts at the keyframe at or before it.
    from: Option<u32>,
}

fn check_level(a: &LoadedAsset, level: usize) -> Result<(), ApiError> {
    if level >= a.header.levels() {
        return Err(ApiError::BadRequest(format!("level {level}: asset {} has levels 0..={}", a.id, a.header.levels() - 1)));
    }
    Ok(())
}

/// `GET /v1/assets/{id}/stream?level=L&from=F`: what a client drawing down to level L reads
/// (`pmcodec_container::streams`), one range after the other: the head (preamble, header and
/// index; of a banded index only its table and level L's groups), then the chunks of bands
/// `L..=top` of each frame from the keyframe at or before F, in playback order.
/// `pmcodec_container::streams::stream_source` places them back.
async fn stream(State(app): State<AppState>, p: Params, Q(q): Q<StreamQuery>) -> Result<Response, ApiError> {
    let a = app.assets.get(&p.asset_id()?).await?;
    let level = q.level.unwrap_or(0);
    check_level(&a, level)?;
    let from = q.from.unwrap_or(0);
    if from >= a.header.frame_count {
        return Err(ApiError::BadRequest(format!("from {from}: asset {} has frames 0..={}", a.id, a.header.frame_count - 1)));
    }
    let start = a.header.keyframe_before(from);
    let head = a.head_ranges(level).map_err(ApiError::Internal)?;
    let pieces: Vec<Bytes> = head
        .into_iter()
        .chain(a.frame_ranges(level, start).into_iter().flatten())
        .map(|r| a.bytes.slice(r.start as usize..r.end as usize))
        .collect();
    let mut resp = Body::from_stream(futures_util::stream::iter(pieces.into_iter().map(Ok::<_, std::convert::Infallible>))).into_response();
    let h = resp.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static("application/vnd.pmcodec.stream"));
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    h.insert("x-pmc-version", header_value(&a.version)?);
    h.insert("x-pmc-level", HeaderValue::from(level));
    h.insert("x-pmc-from", HeaderValue::from(start));
    Ok(resp)
}

/// The asset at the version a content-addressed URL names (404 once it has been replaced).
async fn versioned(app: &AppState, p: &Params) -> Result<Arc<LoadedAsset>, ApiError> {
    let a = app.assets.get(&p.asset_id()?).await?;
    let v = p.get("version")?;
    if v != a.version {
        return Err(ApiError::NotFound(format!("asset {} has no version {v:?}; its current version is {}", a.id, a.version)));
    }
    Ok(a)
}

/// `GET /v1/assets/{id}/v/{version}/file`: the container, immutable, with Range.
async fn file(State(app): State<AppState>, p: Params, headers: HeaderMap) -> Result<Response, ApiError> {
    let a = versioned(&app, &p).await?;
    let rep = Representation {
        bytes: a.bytes.clone(),
        etag: format!("\"{}\"", a.version),
        content_type: "application/vnd.pmcodec",
        cache_control: immutable(&app),
    };
    ranges::serve(&headers, rep, app.config.limits.max_ranges)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct IndexQuery {
    level: Option<usize>,
}

/// `GET /v1/assets/{id}/v/{version}/index?level=L`: the chunks a client drawing down to level L
/// needs, with their byte ranges and URLs; per frame one span covering them and the ranges they lie in; and the
/// head ranges (preamble, header and index; of a banded index, its table and level L's groups).
async fn index(State(app): State<AppState>, p: Params, Q(q): Q<IndexQuery>, headers: HeaderMap) -> Result<Response, ApiError> {
    let a = versioned(&app, &p).await?;
    let level = q.level.unwrap_or(0);
    check_level(&a, level)?;
    let base = format!("/v1/assets/{}/v/{}", a.id, a.version);
    let mut chunks = Vec::new();
    // Per frame: the first and last byte of its selected chunks. For level 0 they are
    // contiguous; for level L > 0 the span also covers the faces and corners of bands above L
    // (stored before the main bands, and smaller the coarser the band).
    let mut frames: Vec<Option<(u64, u64)>> = vec![None; a.header.frame_count as usize];
    for (n, e) in a.chunks_for(level, 0) {
        let r = a.chunk_range(e);
        chunks.push(serde_json::json!({
            "n": n, "kind": e.kind.name(), "frame": e.frame, "band": e.band,
            "offset": r.start, "length": e.stored_len, "raw_length": e.raw_len, "crc32": e.crc32,
            "url": format!("{base}/chunks/{n}"),
        }));
        if e.kind != pmcodec_container::ChunkKind::Triangles
            && let Some(slot) = frames.get_mut(e.frame as usize)
        {
            let (s, t) = slot.get_or_insert((r.start, r.end));
            *s = (*s).min(r.start);
            *t = (*t).max(r.end);
        }
    }
    let frames: Vec<_> = frames
        .iter()
        .enumerate()
        .map(|(f, r)| {
            let (s, t) = r.unwrap_or((0, 0));
            serde_json::json!({ "frame": f, "keyframe": a.header.is_keyframe(f as u32), "offset": s, "length": t - s })
        })
        .collect();
    // What the client reads as byte ranges (`pmcodec_container::streams`): its head, and
    // per frame its chunks, adjacent ones merged (a banded index groups the chunks of a band,
    // so a coarse client's chunks of a frame lie in a few ranges, not in one span).
    let pair = |r: &std::ops::Range<u64>| [r.start, r.end - r.start];
    let head: Vec<_> = a.head_ranges(level).map_err(ApiError::Internal)?.iter().map(pair).collect();
    let frames: Vec<_> = frames
        .into_iter()
        .zip(a.frame_ranges(level, 0))
        .map(|(mut f, ranges)| {
            f["ranges"] = ranges.iter().map(pair).collect::<Vec<_>>().into();
            f
        })
        .collect();
    let banded = a
        .bytes
        .get(..pmcodec_container::format::PREAMBLE_LEN)
        .and_then(|b| pmcodec_container::format::Preamble::parse(b).ok())
        .is_some_and(|p| pmcodec_container::streams::is_banded(&p));
    let body = serde_json::json!({
        "id": a.id.as_str(), "version": a.version, "file": format!("{base}/file"), "length": a.bytes.len(),
        "header_length": a.data_start, "level": level, "levels": a.header.levels(), "frames_count": a.header.frame_count,
        "keyframe_interval": a.header.keyframe_interval, "banded": banded, "head": head,
        "chunks": chunks, "frames": frames,
    });
    let bytes = serde_json::to_vec(&body).map_err(|e| ApiError::Internal(e.to_string()))?;
    let rep = Representation {
        bytes: bytes.into(),
        etag: format!("\"{}-index-{level}\"", a.version),
        content_type: "application/json",
        cache_control: immutable(&app),
    };
    ranges::serve(&headers, rep, app.config.limits.max_ranges)
}

/// `GET /v1/assets/{id}/v/{version}/chunks/{n}`: one stored chunk (a zstd frame), immutable.
async fn chunk(State(app): State<AppState>, p: Params, headers: HeaderMap) -> Result<Response, ApiError> {
    let a = versioned(&app, &p).await?;
    let raw = p.get("n")?;
    let n: usize = raw.parse().map_err(|_| ApiError::BadRequest(format!("chunk {raw:?}: use the chunk's number from the index")))?;
    let e = a
        .chunks
        .get(n)
        .ok_or_else(|| ApiError::NotFound(format!("chunk {n}: asset {} has chunks 0..={}", a.id, a.chunks.len().saturating_sub(1))))?;
    let r = a.chunk_range(e);
    let rep = Representation {
        bytes: a.bytes.slice(r.start as usize..r.end as usize),
        etag: format!("\"{}-chunk-{n}\"", a.version),
        content_type: "application/zstd",
        cache_control: immutable(&app),
    };
    ranges::serve(&headers, rep, app.config.limits.max_ranges)
}

/// `GET /v1/assets/{id}/v/{version}/images/{n}`: texture image `n` (PNG or JPEG, as the input
/// had it), immutable.
async fn image(State(app): State<AppState>, p: Params, headers: HeaderMap) -> Result<Response, ApiError> {
    let a = versioned(&app, &p).await?;
    let raw = p.get("n")?;
    let n: u32 =
        raw.parse().map_err(|_| ApiError::BadRequest(format!("image {raw:?}: use the image's number from the asset's textures")))?;
    let (bytes, content_type) = crate::looks::image(&a, n)?;
    let rep = Representation { bytes, etag: format!("\"{}-image-{n}\"", a.version), content_type, cache_control: immutable(&app) };
    ranges::serve(&headers, rep, app.config.limits.max_ranges)
}

// ---------------------------------------------------------------------------------------------
// Jobs.

fn job_id(p: &Params) -> Result<String, ApiError> {
    let id = p.get("id")?;
    if !valid_job_id(id) {
        return Err(ApiError::BadRequest(format!("invalid job id {id:?}: job ids are 32 hex digits")));
    }
    Ok(id.to_string())
}

/// `GET /v1/jobs/{id}`
async fn job_status(State(app): State<AppState>, p: Params) -> Result<Response, ApiError> {
    let id = job_id(&p)?;
    let status = app.jobs.status(&id).ok_or_else(|| ApiError::NotFound(format!("no job {id} on this server")))?;
    let mut resp = Json(status).into_response();
    resp.headers_mut().insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    Ok(resp)
}

/// `DELETE /v1/jobs/{id}`: asks a queued or running job to stop (202 with its status; its
/// events end with `cancelled`). A cancelled job stores nothing.
async fn cancel_job(State(app): State<AppState>, _: WriteAccess, p: Params) -> Result<Response, ApiError> {
    let id = job_id(&p)?;
    let status = app.jobs.cancel(&id)?;
    let mut resp = (StatusCode::ACCEPTED, Json(status)).into_response();
    resp.headers_mut().insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    Ok(resp)
}

/// `GET /v1/jobs/{id}/events`: server-sent events, one per status change (named after the
/// state), ending after `succeeded`, `failed` or `cancelled`.
async fn job_events(State(app): State<AppState>, p: Params) -> Result<Response, ApiError> {
    let id = job_id(&p)?;
    let rx = app.jobs.subscribe(&id).ok_or_else(|| ApiError::NotFound(format!("no job {id} on this server")))?;
    let shutdown = app.shutdown.subscribe();
    // State: the receiver, whether the first event was sent, whether the job has finished.
    let events = futures_util::stream::unfold((rx, shutdown, false, false), |(mut rx, mut shutdown, started, done)| async move {
        if done {
            return None;
        }
        if started {
            tokio::select! {
                changed = rx.changed() => changed.ok()?,
                _ = shutdown.wait_for(|stop| *stop) => return None,
            }
        }
        let status = rx.borrow_and_update().clone();
        let finished = status.state.is_finished();
        let event = Event::default().event(status.state.name()).data(serde_json::to_string(&status).unwrap_or_default());
        Some((Ok::<_, std::convert::Infallible>(event), (rx, shutdown, true, finished)))
    });
    let mut resp = Sse::new(events).keep_alive(KeepAlive::default()).into_response();
    resp.headers_mut().insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    Ok(resp)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::jobs::JobState;

    #[test]
    fn table_has_no_duplicates_and_job_states_name_events() {
        let mut seen = std::collections::HashSet::new();
        for (m, p) in mounted_routes() {
            assert!(seen.insert((m.clone(), p)), "{m} {p} twice");
        }
        assert_eq!(JobState::Failed.name(), "failed");
    }
}
