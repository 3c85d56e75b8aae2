//! The HTTP API against the router (no socket): listing, metadata, LOD on demand, immutable
//! container and chunk URLs with ETag and Range, the playback stream, tokens, JSON errors, and
//! the OpenAPI document's coverage of the mounted routes.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use axum::body::Body;
use axum::http::{Method, Request, StatusCode, header};
use http_body_util::BodyExt;
use pmcodec_container::{CutTarget, Decoder, Reader};
use pmcodec_server::config::Secret;
use pmcodec_server::store::MemoryStore;
use pmcodec_server::{AppState, AssetId, AssetStore, Config, PutMode, StoreError, mounted_routes, router};
use std::sync::Arc;
use tower::ServiceExt;

fn cloth_bytes() -> Vec<u8> {
    let seq = pmcodec_mesh::samples::waving_cloth(16, 12, 6);
    let opts = pmcodec_container::EncodeOptions { keyframe_interval: 4, ..Default::default() };
    pmcodec_container::encode(&seq, &opts, |_| {}).expect("encode the cloth")
}

async fn app_with(config: Config) -> (axum::Router, Vec<u8>) {
    let store: Arc<dyn AssetStore> = Arc::new(MemoryStore::default());
    let bytes = cloth_bytes();
    store.put(&AssetId::parse("cloth").unwrap(), bytes.clone().into(), PutMode::Overwrite).await.unwrap();
    let state = AppState::new(config, store).unwrap();
    state.set_ready(true);
    (router(state), bytes)
}

async fn app() -> (axum::Router, Vec<u8>) {
    app_with(Config::default()).await
}

struct Resp {
    status: StatusCode,
    headers: axum::http::HeaderMap,
    body: Vec<u8>,
}

impl Resp {
    fn json(&self) -> serde_json::Value {
        serde_json::from_slice(&self.body).unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(&self.body)))
    }
    fn header(&self, name: &str) -> &str {
        self.headers.get(name).and_then(|v| v.to_str().ok()).unwrap_or_else(|| panic!("no {name} header"))
    }
}

async fn send(app: &axum::Router, method: Method, uri: &str, headers: &[(&str, &str)], body: Vec<u8>) -> Resp {
    let mut req = Request::builder().method(method).uri(uri);
    for (k, v) in headers {
        req = req.header(*k, *v);
    }
    let resp = app.clone().oneshot(req.body(Body::from(body)).unwrap()).await.unwrap();
    let (parts, body) = resp.into_parts();
    Resp { status: parts.status, headers: parts.headers, body: body.collect().await.unwrap().to_bytes().to_vec() }
}

async fn get(app: &axum::Router, uri: &str, headers: &[(&str, &str)]) -> Resp {
    send(app, Method::GET, uri, headers, Vec::new()).await
}

#[tokio::test]
async fn list_metadata_and_meshes_match_local_decoding() {
    let (app, bytes) = app().await;
    let r = get(&app, "/v1/assets", &[]).await;
    assert_eq!(r.status, StatusCode::OK);
    let list = r.json();
    assert_eq!(list["assets"][0]["id"], "cloth");
    assert_eq!(list["assets"][0]["frames"], 6);
    let info = get(&app, "/v1/assets/cloth", &[]).await.json();
    assert_eq!(info["triangles_per_level"][0], 2 * 15 * 11);
    assert_eq!(info["bytes"], bytes.len());

    let mut local = Decoder::new(Reader::open(bytes.as_slice()).unwrap(), 0).unwrap();
    // Random order: new states (5, 1), a clone stepped forward (3 from 1, 2 from 1), and
    // states reused at their frame with other budgets (3, 5).
    for (frame, budget) in [(5u32, 40u32), (1, 100), (3, 400), (2, 50), (3, 60), (5, 300)] {
        let r = get(&app, &format!("/v1/assets/cloth/mesh?frame={frame}&triangles={budget}&format=bin"), &[]).await;
        assert_eq!(r.status, StatusCode::OK);
        let served = pmcodec_server::decode_bin(&r.body).expect("a compact binary mesh");
        local.seek(frame).unwrap();
        let want = local.mesh(CutTarget::Triangles(budget)).unwrap();
        assert!(served.triangles.len() as u32 <= budget && !served.triangles.is_empty());
        assert_eq!(served.triangles, want.triangles, "frame {frame} budget {budget}");
        assert_eq!(served.positions, want.positions, "frame {frame} budget {budget}");
        assert_eq!(r.header("x-pmc-triangles"), want.triangles.len().to_string());
    }
    let r = get(&app, "/v1/assets/cloth/mesh?frame=2&level=1", &[]).await;
    assert_eq!(r.status, StatusCode::OK);
    assert_eq!(r.header("content-type"), "model/gltf-binary");
    assert!(gltf::Gltf::from_slice(&r.body).is_ok());
    // A revalidation with the mesh's ETag needs no decoding and gets 304.
    let etag = r.header("etag").to_string();
    // The tag names the cut rule and layouts' generation, so a tag from a server whose answers
    // differed (generation 2: priorities from distances to finer nodes) does not validate
    // today's bytes.
    assert!(etag.ends_with("-l1-glb-m3\""), "{etag}");
    let old_tag = etag.replace("-m3\"", "-m2\"");
    assert_eq!(get(&app, "/v1/assets/cloth/mesh?frame=2&level=1", &[("if-none-match", &old_tag)]).await.status, StatusCode::OK);
    let r = get(&app, "/v1/assets/cloth/mesh?frame=2&level=1", &[("if-none-match", &etag)]).await;
    assert_eq!(r.status, StatusCode::NOT_MODIFIED);
    // If-None-Match compares weakly: a cache that weakened the tag still revalidates.
    let r = get(&app, "/v1/assets/cloth/mesh?frame=2&level=1", &[("if-none-match", &format!("\"x\", W/{etag}"))]).await;
    assert_eq!(r.status, StatusCode::NOT_MODIFIED);
}

#[tokio::test]
async fn bad_requests_say_what_is_wrong_in_json() {
    let (app, _) = app().await;
    for (uri, status, needle) in [
        ("/v1/assets/NOPE", StatusCode::BAD_REQUEST, "invalid asset id"),
        ("/v1/assets/..%2f..%2fetc%2fpasswd", StatusCode::BAD_REQUEST, "invalid asset id"),
        ("/v1/assets/.hidden/mesh", StatusCode::BAD_REQUEST, "invalid asset id"),
        ("/v1/assets/missing", StatusCode::NOT_FOUND, "missing"),
        ("/v1/assets/cloth/mesh?frame=99", StatusCode::BAD_REQUEST, "frames 0..=5"),
        ("/v1/assets/cloth/mesh?level=9", StatusCode::BAD_REQUEST, "levels"),
        ("/v1/assets/cloth/mesh?triangles=5&level=1", StatusCode::BAD_REQUEST, "at most one"),
        ("/v1/assets/cloth/mesh?format=fbx", StatusCode::BAD_REQUEST, "format"),
        ("/v1/assets/cloth/mesh?triangles=-3", StatusCode::BAD_REQUEST, "triangles"),
        ("/v1/assets/cloth/mesh?max_error=nan", StatusCode::BAD_REQUEST, "max_error"),
        ("/v1/assets/cloth/mesh?colour=red", StatusCode::BAD_REQUEST, "colour"),
        ("/v1/assets/cloth/stream?level=7", StatusCode::BAD_REQUEST, "levels"),
        ("/v1/assets/cloth/v/0123/file", StatusCode::NOT_FOUND, "current version"),
        ("/v1/jobs/zzz", StatusCode::BAD_REQUEST, "job id"),
        ("/v1/jobs/0123456789abcdef0123456789abcdef", StatusCode::NOT_FOUND, "no job"),
        ("/v1/no-such-route", StatusCode::NOT_FOUND, "no route"),
    ] {
        let r = get(&app, uri, &[]).await;
        assert_eq!(r.status, status, "{uri}: {}", String::from_utf8_lossy(&r.body));
        let detail = r.json()["detail"].as_str().unwrap_or_default().to_string();
        assert!(detail.contains(needle), "{uri}: {detail:?} does not mention {needle:?}");
    }
    let r = send(&app, Method::PUT, "/v1/assets/cloth", &[], Vec::new()).await;
    assert_eq!(r.status, StatusCode::METHOD_NOT_ALLOWED);
    assert!(r.json()["detail"].as_str().unwrap().contains("PUT"));
}

#[tokio::test]
async fn container_and_chunks_are_immutable_with_etags_and_ranges() {
    let (app, whole) = app().await;
    let info = get(&app, "/v1/assets/cloth", &[]).await.json();
    let url = info["file"].as_str().unwrap().to_string();
    let r = get(&app, &url, &[]).await;
    assert_eq!(r.status, StatusCode::OK);
    assert_eq!(r.body, whole);
    assert_eq!(r.header("cache-control"), "public, max-age=31536000, immutable");
    let etag = r.header("etag").to_string();
    assert_eq!(get(&app, &url, &[("if-none-match", &etag)]).await.status, StatusCode::NOT_MODIFIED);

    let r = get(&app, &url, &[("range", "bytes=0-31")]).await;
    assert_eq!(r.status, StatusCode::PARTIAL_CONTENT);
    assert_eq!(r.body, whole[..32]);
    assert_eq!(r.header("content-range"), format!("bytes 0-31/{}", whole.len()));
    let r = get(&app, &url, &[("range", "bytes=-10")]).await;
    assert_eq!((r.status, r.body.as_slice()), (StatusCode::PARTIAL_CONTENT, &whole[whole.len() - 10..]));
    // Past the end: 416 with the length, so a client with a truncated idea of the file learns it.
    let r = get(&app, &url, &[("range", &format!("bytes={}-", whole.len()))]).await;
    assert_eq!(r.status, StatusCode::RANGE_NOT_SATISFIABLE);
    assert_eq!(r.header("content-range"), format!("bytes */{}", whole.len()));
    // A range running past the end is cut to the end.
    let r = get(&app, &url, &[("range", &format!("bytes={}-{}", whole.len() - 4, whole.len() + 100))]).await;
    assert_eq!((r.status, r.body.as_slice()), (StatusCode::PARTIAL_CONTENT, &whole[whole.len() - 4..]));
    // Several ranges: multipart/byteranges with each part in order.
    let r = get(&app, &url, &[("range", "bytes=0-1,10-19")]).await;
    assert_eq!(r.status, StatusCode::PARTIAL_CONTENT);
    assert!(r.header("content-type").starts_with("multipart/byteranges; boundary="));
    let text = String::from_utf8_lossy(&r.body);
    assert!(text.contains(&format!("Content-Range: bytes 0-1/{}", whole.len())), "{text}");
    assert!(text.contains(&format!("Content-Range: bytes 10-19/{}", whole.len())), "{text}");
    // If-Range with a stale validator: the whole representation.
    let r = get(&app, &url, &[("range", "bytes=0-1"), ("if-range", "\"stale\"")]).await;
    assert_eq!((r.status, r.body.len()), (StatusCode::OK, whole.len()));
    let r = get(&app, &url, &[("range", "bytes=0-1"), ("if-range", &etag)]).await;
    assert_eq!(r.status, StatusCode::PARTIAL_CONTENT);
    // The 416 says why in a JSON body.
    let r = get(&app, &url, &[("range", &format!("bytes={}-", whole.len()))]).await;
    assert!(r.json()["detail"].as_str().unwrap().contains("no range overlaps"), "{:?}", r.json());
    // A syntactically invalid range set is ignored (RFC 9110 section 14.1.1), as is another
    // unit: the whole representation.
    for range in ["bytes=zz", "bytes=5-2", "bytes=0-1,9-3", "items=0-1"] {
        let r = get(&app, &url, &[("range", range)]).await;
        assert_eq!((r.status, r.body.len()), (StatusCode::OK, whole.len()), "{range}");
    }

    // The index lists chunks at immutable URLs whose bytes are the file's.
    let index = get(&app, info["index"].as_str().unwrap(), &[]).await.json();
    let chunks = index["chunks"].as_array().unwrap();
    assert!(!chunks.is_empty());
    for c in chunks.iter().take(8) {
        let (off, len) = (c["offset"].as_u64().unwrap() as usize, c["length"].as_u64().unwrap() as usize);
        let r = get(&app, c["url"].as_str().unwrap(), &[]).await;
        assert_eq!(r.status, StatusCode::OK);
        assert_eq!(r.body, whole[off..off + len]);
    }
    let coarse = get(&app, &format!("{}?level=2", info["index"].as_str().unwrap()), &[]).await.json();
    assert!(coarse["chunks"].as_array().unwrap().len() < chunks.len());
    // Bands 2.. and, since the cloth's bands derive their faces (proto/container.md, "Faces"),
    // the triangles and the parent maps and swaps below band 2.
    assert!(
        coarse["chunks"]
            .as_array()
            .unwrap()
            .iter()
            .all(|c| c["band"].as_u64().unwrap() >= 2 || c["kind"] == "triangles" || c["kind"] == "keyframe" || c["kind"] == "delta")
    );
    assert!(coarse["chunks"].as_array().unwrap().iter().all(|c| c["kind"] != "positions" || c["band"].as_u64().unwrap() >= 2));
}

#[tokio::test]
async fn the_stream_is_the_header_then_the_chosen_bands_in_playback_order() {
    let (app, whole) = app().await;
    let r = get(&app, "/v1/assets/cloth/stream?level=1&from=5", &[]).await;
    assert_eq!(r.status, StatusCode::OK);
    // From frame 5 with keyframes every 4 frames, the stream starts at keyframe 4.
    assert_eq!(r.header("x-pmc-from"), "4");
    let reader = Reader::open(whole.as_slice()).unwrap();
    let head = reader.data_start() as usize;
    assert_eq!(r.body[..head], whole[..head]);
    let mut at = head;
    for (_, e) in reader
        .index()
        .chunks
        .iter()
        .enumerate()
        // (A level-1 client of a file whose band 1 derives its faces reads the triangles too,
        // and every client frame 0's Key chunks, which later keyframes' may code changes from.)
        .filter(|(_, e)| {
            reader.reads(e, 1)
                && (e.frame >= 4 || e.kind == pmcodec_container::ChunkKind::Triangles || e.kind == pmcodec_container::ChunkKind::Key)
        })
    {
        let start = head + e.offset as usize;
        let piece = &whole[start..start + e.stored_len as usize];
        assert_eq!(&r.body[at..at + piece.len()], piece);
        at += piece.len();
    }
    assert_eq!(at, r.body.len());
}

#[tokio::test]
async fn writes_need_the_write_token_and_reads_the_read_token_when_set() {
    let mut config = Config::default();
    config.auth.write_token = Some(Secret("w-secret".into()));
    let (app, _) = app_with(config).await;
    let r = send(&app, Method::DELETE, "/v1/assets/cloth", &[], Vec::new()).await;
    assert_eq!(r.status, StatusCode::UNAUTHORIZED);
    assert!(r.headers.contains_key(header::WWW_AUTHENTICATE));
    let r = send(&app, Method::DELETE, "/v1/assets/cloth", &[("authorization", "Bearer wrong")], Vec::new()).await;
    assert!(matches!(r.status, StatusCode::UNAUTHORIZED | StatusCode::FORBIDDEN), "{}", r.status);
    let r = send(&app, Method::POST, "/v1/assets?id=x", &[("content-type", "model/gltf-binary")], b"glTF".to_vec()).await;
    assert_eq!(r.status, StatusCode::UNAUTHORIZED);
    // Reads stay public.
    assert_eq!(get(&app, "/v1/assets/cloth", &[]).await.status, StatusCode::OK);
    let r = send(&app, Method::DELETE, "/v1/assets/cloth", &[("authorization", "Bearer w-secret")], Vec::new()).await;
    assert_eq!(r.status, StatusCode::NO_CONTENT);
    assert_eq!(get(&app, "/v1/assets/cloth", &[]).await.status, StatusCode::NOT_FOUND);

    let mut config = Config::default();
    config.auth.read_token = Some(Secret("r-secret".into()));
    let (app, _) = app_with(config).await;
    assert_eq!(get(&app, "/v1/assets", &[]).await.status, StatusCode::UNAUTHORIZED);
    assert_eq!(get(&app, "/v1/assets", &[("authorization", "Bearer r-secret")]).await.status, StatusCode::OK);
    // Operations endpoints need no token.
    assert_eq!(get(&app, "/healthz", &[]).await.status, StatusCode::OK);
    // Without a write token configured, writes are refused outright.
    let r = send(&app, Method::DELETE, "/v1/assets/cloth", &[("authorization", "Bearer r-secret")], Vec::new()).await;
    assert_eq!(r.status, StatusCode::FORBIDDEN);
}

#[tokio::test]
async fn metrics_count_requests_by_route() {
    let (app, _) = app().await;
    get(&app, "/v1/assets/cloth/mesh?frame=1&triangles=50", &[]).await;
    let r = get(&app, "/metrics", &[]).await;
    assert_eq!(r.status, StatusCode::OK);
    let text = String::from_utf8(r.body).unwrap();
    assert!(text.contains("route=\"/v1/assets/{id}/mesh\""), "{text}");
    assert!(text.contains("pmcodec_ready 1"));
}

/// The `paths:` keys of proto/openapi.yaml with their methods.
fn documented_routes() -> Vec<(String, String)> {
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../proto/openapi.yaml")).unwrap();
    let mut out = Vec::new();
    let mut in_paths = false;
    let mut path = None::<String>;
    for line in doc.lines() {
        if !line.starts_with(' ') && !line.trim().is_empty() {
            in_paths = line.trim_end() == "paths:";
            path = None;
            continue;
        }
        if !in_paths {
            continue;
        }
        if line.starts_with("  /") && !line.starts_with("   ") {
            path = Some(line.trim().trim_end_matches(':').to_string());
        } else if let Some(p) = &path
            && line.starts_with("    ")
            && !line.starts_with("     ")
        {
            let key = line.trim().trim_end_matches(':').to_ascii_uppercase();
            if ["GET", "POST", "PUT", "DELETE", "PATCH", "HEAD"].contains(&key.as_str()) {
                out.push((key, p.clone()));
            }
        }
    }
    out.sort();
    out
}

#[test]
fn openapi_documents_exactly_the_mounted_routes() {
    let mut mounted: Vec<(String, String)> = mounted_routes().into_iter().map(|(m, p)| (m.to_string(), p.to_string())).collect();
    mounted.sort();
    assert_eq!(documented_routes(), mounted);
}

#[tokio::test]
async fn every_mounted_route_answers_with_json_or_data() {
    let (app, _) = app().await;
    for (method, route) in mounted_routes() {
        let uri = route.replace("{id}", "cloth").replace("{version}", "0").replace("{n}", "0");
        let r = send(&app, method.clone(), &uri, &[], Vec::new()).await;
        // An unknown route is our JSON 404 that says "no route"; a mounted one never is.
        let no_route = r.status == StatusCode::NOT_FOUND && String::from_utf8_lossy(&r.body).contains("no route");
        assert!(!no_route, "{method} {route} is not mounted");
    }
}

#[tokio::test]
async fn compressed_json_gets_a_weak_entity_tag_that_still_revalidates() {
    let (app, _) = app().await;
    let info = get(&app, "/v1/assets/cloth", &[]).await.json();
    let index = info["index"].as_str().unwrap().to_string();
    let plain = get(&app, &index, &[]).await;
    assert_eq!(plain.status, StatusCode::OK);
    assert!(plain.headers.get(header::CONTENT_ENCODING).is_none());
    let strong = plain.header("etag").to_string();
    assert!(strong.starts_with('"'), "{strong}");
    let gz = get(&app, &index, &[("accept-encoding", "gzip")]).await;
    assert_eq!(gz.header("content-encoding"), "gzip");
    assert_eq!(gz.header("etag"), format!("W/{strong}"));
    // Revalidating with the weak tag is a 304.
    let again = get(&app, &index, &[("accept-encoding", "gzip"), ("if-none-match", gz.header("etag"))]).await;
    assert_eq!(again.status, StatusCode::NOT_MODIFIED);
}

/// A memory store for tests that counts whole-object reads and, when `blind_head` is set,
/// never sees an asset in `head`: as if another server sharing the store created it just after
/// each existence check, so only a job's final write can notice.
#[derive(Default)]
struct TestStore {
    inner: MemoryStore,
    gets: std::sync::atomic::AtomicUsize,
    blind_head: bool,
}

impl AssetStore for TestStore {
    fn describe(&self) -> String {
        "test memory store".into()
    }
    fn list(&self) -> futures_util::future::BoxFuture<'_, Result<Vec<pmcodec_server::store::StoredObject>, StoreError>> {
        self.inner.list()
    }
    fn head<'a>(
        &'a self,
        id: &'a AssetId,
    ) -> futures_util::future::BoxFuture<'a, Result<Option<pmcodec_server::store::StoredObject>, StoreError>> {
        if self.blind_head { Box::pin(async { Ok(None) }) } else { self.inner.head(id) }
    }
    fn get<'a>(
        &'a self,
        id: &'a AssetId,
    ) -> futures_util::future::BoxFuture<'a, Result<Option<(pmcodec_server::store::StoredObject, bytes::Bytes)>, StoreError>> {
        self.gets.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.inner.get(id)
    }
    fn put<'a>(
        &'a self,
        id: &'a AssetId,
        bytes: bytes::Bytes,
        mode: PutMode,
    ) -> futures_util::future::BoxFuture<'a, Result<pmcodec_server::store::StoredObject, StoreError>> {
        self.inner.put(id, bytes, mode)
    }
    fn delete<'a>(&'a self, id: &'a AssetId) -> futures_util::future::BoxFuture<'a, Result<bool, StoreError>> {
        self.inner.delete(id)
    }
    fn check(&self) -> futures_util::future::BoxFuture<'_, Result<(), StoreError>> {
        self.inner.check()
    }
    fn get_meta<'a>(&'a self, id: &'a AssetId) -> futures_util::future::BoxFuture<'a, Result<Option<bytes::Bytes>, StoreError>> {
        self.inner.get_meta(id)
    }
    fn put_meta<'a>(&'a self, id: &'a AssetId, bytes: bytes::Bytes) -> futures_util::future::BoxFuture<'a, Result<(), StoreError>> {
        self.inner.put_meta(id, bytes)
    }
}

/// A cold server lists assets from the metadata stored beside them, written by the first
/// server that had to read the containers; metadata of other bytes (the asset was replaced)
/// or damaged metadata is passed over and rewritten, never shown.
#[tokio::test]
async fn cold_servers_list_from_stored_metadata() {
    let store = Arc::new(TestStore::default());
    let (a, b) = (AssetId::parse("cloth-a").unwrap(), AssetId::parse("cloth-b").unwrap());
    for id in [&a, &b] {
        store.put(id, cloth_bytes().into(), PutMode::Overwrite).await.unwrap();
    }
    let gets = || store.gets.load(std::sync::atomic::Ordering::Relaxed);
    let cold_listing = || async {
        let state = AppState::new(Config::default(), store.clone()).unwrap();
        state.set_ready(true);
        get(&router(state), "/v1/assets", &[]).await.json()
    };
    let first = cold_listing().await;
    assert_eq!(first["assets"].as_array().map(Vec::len), Some(2));
    assert_eq!(gets(), 2, "the first server reads both containers");
    assert!(store.get_meta(&a).await.unwrap().is_some(), "and leaves their metadata");
    // A second cold server reads no container to list the same assets.
    assert_eq!(cold_listing().await, first);
    assert_eq!(gets(), 2);
    // Replaced bytes: the metadata describes the old object and is not used.
    let other = pmcodec_container::encode(&pmcodec_mesh::samples::twisting_tube(6, 5, 3), &Default::default(), |_| {}).unwrap();
    store.put(&a, other.into(), PutMode::Overwrite).await.unwrap();
    let listed = cold_listing().await;
    assert_eq!(gets(), 3);
    let version =
        |l: &serde_json::Value, id: &str| l["assets"].as_array().unwrap().iter().find(|x| x["id"] == id).unwrap()["version"].clone();
    assert_ne!(version(&listed, "cloth-a"), version(&first, "cloth-a"));
    assert_eq!(version(&listed, "cloth-b"), version(&first, "cloth-b"));
    // Metadata of another schema (another server version's description) is passed over.
    let mut other_schema: serde_json::Value = serde_json::from_slice(&store.get_meta(&b).await.unwrap().unwrap()).unwrap();
    other_schema["schema"] = 99.into();
    other_schema["info"]["frames"] = 12345.into();
    store.put_meta(&b, serde_json::to_vec(&other_schema).unwrap().into()).await.unwrap();
    assert_eq!(cold_listing().await, listed);
    assert_eq!(gets(), 4);
    // Damaged metadata is passed over too (and rewritten).
    store.put_meta(&b, bytes::Bytes::from_static(b"{not json")).await.unwrap();
    assert_eq!(cold_listing().await, listed);
    assert_eq!(gets(), 5);
    assert_eq!(cold_listing().await, listed);
    assert_eq!(gets(), 5);
    // Deleting an asset deletes its metadata.
    store.delete(&b).await.unwrap();
    assert!(store.get_meta(&b).await.unwrap().is_none());
}

#[tokio::test]
async fn an_unreadable_object_is_read_once_until_it_changes() {
    let store = Arc::new(TestStore::default());
    let id = AssetId::parse("broken").unwrap();
    store.put(&id, bytes::Bytes::from_static(b"not a container at all"), PutMode::Overwrite).await.unwrap();
    let state = AppState::new(Config::default(), store.clone()).unwrap();
    state.set_ready(true);
    let app = router(state);
    for _ in 0..3 {
        let r = get(&app, "/v1/assets/broken", &[]).await;
        assert_eq!(r.status, StatusCode::INTERNAL_SERVER_ERROR);
        // Internal errors say no more to clients; the server log names the asset and why.
        assert_eq!(r.json()["error"], "internal");
        // The listing leaves it out and does not fetch it again either.
        assert_eq!(get(&app, "/v1/assets", &[]).await.json()["assets"].as_array().map(Vec::len), Some(0));
    }
    assert_eq!(store.gets.load(std::sync::atomic::Ordering::Relaxed), 1, "the failed bytes were fetched again");
    // New bytes under the same id are read (and now load).
    store.put(&id, cloth_bytes().into(), PutMode::Overwrite).await.unwrap();
    assert_eq!(get(&app, "/v1/assets/broken", &[]).await.status, StatusCode::OK);
    assert_eq!(store.gets.load(std::sync::atomic::Ordering::Relaxed), 2);
}

/// Uploads a one-frame GLB and polls the job until it ends; returns its last status.
async fn upload_and_wait(app: &axum::Router, query: &str) -> serde_json::Value {
    let mesh = pmcodec_mesh::samples::waving_cloth(8, 6, 1).frame_mesh(0).expect("a frame");
    let glb = pmcodec_mesh::write::glb_bytes(&mesh);
    let headers = [("content-type", "model/gltf-binary"), ("authorization", "Bearer w")];
    let r = send(app, Method::POST, &format!("/v1/assets?{query}"), &headers, glb).await;
    assert_eq!(r.status, StatusCode::ACCEPTED, "{}", String::from_utf8_lossy(&r.body));
    let url = r.json()["status_url"].as_str().expect("a status url").to_string();
    // Bounded: the job is one small frame.
    for _ in 0..600 {
        let status = get(app, &url, &[]).await.json();
        if status["state"] == "succeeded" || status["state"] == "failed" {
            return status;
        }
        tokio::time::sleep(std::time::Duration::from_millis(100)).await;
    }
    panic!("the job did not finish within a minute");
}

#[tokio::test]
async fn a_job_without_replace_never_overwrites_an_asset_created_while_it_ran() {
    let store = Arc::new(TestStore { blind_head: true, ..Default::default() });
    let id = AssetId::parse("cloth").unwrap();
    let theirs = cloth_bytes();
    store.inner.put(&id, theirs.clone().into(), PutMode::Overwrite).await.unwrap();
    let mut config = Config::default();
    config.auth.write_token = Some(Secret("w".into()));
    let state = AppState::new(config, store.clone()).unwrap();
    state.set_ready(true);
    let app = router(state);

    // Both existence checks miss the asset; the create-only write finds it and keeps it.
    let status = upload_and_wait(&app, "id=cloth").await;
    assert_eq!(status["state"], "failed", "{status}");
    assert_eq!(status["message"], "asset cloth was created while this job ran; upload again with replace=true to replace it", "{status}");
    assert_eq!(&store.inner.get(&id).await.unwrap().unwrap().1[..], &theirs[..], "the existing asset was overwritten");

    // A new id is created; replace=true replaces.
    let status = upload_and_wait(&app, "id=fresh").await;
    assert_eq!(status["state"], "succeeded", "{status}");
    assert!(store.inner.get(&AssetId::parse("fresh").unwrap()).await.unwrap().is_some());
    let status = upload_and_wait(&app, "id=cloth&replace=true").await;
    assert_eq!(status["state"], "succeeded", "{status}");
    assert_ne!(&store.inner.get(&id).await.unwrap().unwrap().1[..], &theirs[..], "replace=true did not replace");
}

// ---------------------------------------------------------------------------------------------
// Bounds on what a request can take (issue 13): the upload queue, cancelling jobs, frame
// counts and rates, and the smaller ones.

const AUTH: (&str, &str) = ("authorization", "Bearer w");

/// A server with a write token `w` whose upload bodies wait in a folder of their own.
async fn writable_app(configure: impl FnOnce(&mut Config)) -> (axum::Router, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let mut config = Config { upload_dir: Some(dir.path().to_path_buf()), ..Default::default() };
    config.auth.write_token = Some(Secret("w".into()));
    configure(&mut config);
    (app_with(config).await.0, dir)
}

fn files_in(dir: &std::path::Path) -> usize {
    std::fs::read_dir(dir).unwrap().count()
}

/// Frames of a sequence as OBJ files in a multipart body; returns the content type and body.
fn multipart_objs(seq: &pmcodec_mesh::Sequence) -> (String, Vec<u8>) {
    use std::fmt::Write;
    let boundary = "pmcodec-test-boundary";
    let mut body = String::new();
    for (f, frame) in seq.frames.iter().enumerate() {
        write!(body, "--{boundary}\r\nContent-Disposition: form-data; name=\"f\"; filename=\"frame-{f:04}.obj\"\r\n\r\n").unwrap();
        for p in frame {
            writeln!(body, "v {} {} {}", p.x, p.y, p.z).unwrap();
        }
        for t in &seq.triangles {
            writeln!(body, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1).unwrap();
        }
        body.push_str("\r\n");
    }
    write!(body, "--{boundary}--\r\n").unwrap();
    (format!("multipart/form-data; boundary={boundary}"), body.into_bytes())
}

async fn wait_finished(app: &axum::Router, url: &str) -> serde_json::Value {
    for _ in 0..1200 {
        let status = get(app, url, &[]).await.json();
        if ["succeeded", "failed", "cancelled"].contains(&status["state"].as_str().unwrap_or("")) {
            return status;
        }
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
    }
    panic!("the job at {url} did not finish within a minute");
}

#[tokio::test]
async fn a_full_queue_refuses_an_upload_before_reading_its_body() {
    let (app, dir) = writable_app(|c| c.limits.max_pending_jobs = 1).await;
    // The first upload's body arrives slowly: it holds the only place while it is received.
    let (tx, rx) = tokio::sync::mpsc::channel::<Result<bytes::Bytes, std::io::Error>>(4);
    let slow = Body::from_stream(tokio_stream_from(rx));
    let req = Request::post("/v1/assets?id=slow").header("content-type", "application/zip").header(AUTH.0, AUTH.1).body(slow).unwrap();
    let first = tokio::spawn(app.clone().oneshot(req));
    tx.send(Ok(bytes::Bytes::from_static(b"PK\x03\x04"))).await.unwrap();
    // Its body is written to a temporary file as it arrives, not kept in memory.
    for _ in 0..200 {
        if files_in(dir.path()) == 1 {
            break;
        }
        tokio::time::sleep(std::time::Duration::from_millis(10)).await;
    }
    assert_eq!(files_in(dir.path()), 1, "the body being received is spilled to the upload folder");
    // A second upload is refused at once: 503 with Retry-After, its body never stored.
    let r = send(&app, Method::POST, "/v1/assets?id=other", &[("content-type", "application/zip"), AUTH], b"PK\x03\x04more".to_vec()).await;
    assert_eq!(r.status, StatusCode::SERVICE_UNAVAILABLE, "{}", String::from_utf8_lossy(&r.body));
    assert_eq!(r.header("retry-after"), "1");
    assert!(r.json()["detail"].as_str().unwrap().contains("max_pending_jobs"));
    assert_eq!(files_in(dir.path()), 1);
    // The first completes; its job fails on the broken zip, and its file goes with it.
    drop(tx);
    let resp = first.await.unwrap().unwrap();
    assert_eq!(resp.status(), StatusCode::ACCEPTED);
    let status: serde_json::Value = serde_json::from_slice(&resp.into_body().collect().await.unwrap().to_bytes()).unwrap();
    let last = wait_finished(&app, status["status_url"].as_str().unwrap()).await;
    assert_eq!(last["state"], "failed", "{last}");
    assert_eq!(files_in(dir.path()), 0, "the temporary file is removed when the job ends");
    // A refused upload gives its place back: the next one is taken.
    let r = send(&app, Method::POST, "/v1/assets?id=other", &[("content-type", "application/zip"), AUTH], b"PK\x03\x04more".to_vec()).await;
    assert_eq!(r.status, StatusCode::ACCEPTED, "{}", String::from_utf8_lossy(&r.body));
}

/// A stream over an mpsc receiver (tokio-stream is not a dependency).
fn tokio_stream_from<T: Send + 'static>(rx: tokio::sync::mpsc::Receiver<T>) -> impl futures_util::Stream<Item = T> + Send + 'static {
    futures_util::stream::unfold(rx, |mut rx| async move { rx.recv().await.map(|item| (item, rx)) })
}

#[tokio::test]
async fn jobs_can_be_cancelled_queued_or_running_and_store_nothing() {
    let (app, dir) = writable_app(|c| {
        c.limits.encode_concurrency = 1;
        c.store = pmcodec_server::config::StoreConfig::Memory;
    })
    .await;
    // A long job (hundreds of frames) and a short one queued behind it.
    let (ctype, long) = multipart_objs(&pmcodec_mesh::samples::waving_cloth(40, 40, 600));
    let r = send(&app, Method::POST, "/v1/assets?id=long", &[("content-type", &ctype), AUTH], long).await;
    assert_eq!(r.status, StatusCode::ACCEPTED, "{}", String::from_utf8_lossy(&r.body));
    let long_url = r.json()["status_url"].as_str().unwrap().to_string();
    let (ctype, short) = multipart_objs(&pmcodec_mesh::samples::waving_cloth(8, 6, 3));
    let r = send(&app, Method::POST, "/v1/assets?id=short", &[("content-type", &ctype), AUTH], short).await;
    assert_eq!(r.status, StatusCode::ACCEPTED);
    let short_url = r.json()["status_url"].as_str().unwrap().to_string();

    // Wait until the long one encodes: its body has been parsed, so the only temporary file
    // left is the queued job's.
    let mut running = serde_json::Value::Null;
    for _ in 0..2000 {
        running = get(&app, &long_url, &[]).await.json();
        if running["frames_done"].as_u64().unwrap_or(0) >= 1 || running["state"] != "queued" && running["state"] != "running" {
            break;
        }
        tokio::time::sleep(std::time::Duration::from_millis(10)).await;
    }
    assert_eq!(running["state"], "running", "{running}");
    assert_eq!(get(&app, &short_url, &[]).await.json()["state"], "queued");
    assert_eq!(files_in(dir.path()), 1, "the queued job's body waits on disk");

    // Cancelling needs the write token.
    assert_eq!(send(&app, Method::DELETE, &short_url, &[], Vec::new()).await.status, StatusCode::UNAUTHORIZED);
    // The queued job never starts; its file goes.
    let r = send(&app, Method::DELETE, &short_url, &[AUTH], Vec::new()).await;
    assert_eq!(r.status, StatusCode::ACCEPTED, "{}", String::from_utf8_lossy(&r.body));
    assert_eq!(r.json()["cancel_requested"], true);
    let last = wait_finished(&app, &short_url).await;
    assert_eq!(last["state"], "cancelled", "{last}");
    assert_eq!(files_in(dir.path()), 0, "a cancelled job's temporary file is removed");

    // The running one stops between frames and stores nothing.
    let r = send(&app, Method::DELETE, &long_url, &[AUTH], Vec::new()).await;
    assert_eq!(r.status, StatusCode::ACCEPTED);
    let last = wait_finished(&app, &long_url).await;
    assert_eq!(last["state"], "cancelled", "{last}");
    assert!(last["frames_done"].as_u64().unwrap() < 600, "it stopped before the end: {last}");
    assert_eq!(get(&app, "/v1/assets/long", &[]).await.status, StatusCode::NOT_FOUND);
    assert_eq!(get(&app, "/v1/assets/short", &[]).await.status, StatusCode::NOT_FOUND);
    // A finished job cannot be cancelled; an unknown one is not found.
    assert_eq!(send(&app, Method::DELETE, &long_url, &[AUTH], Vec::new()).await.status, StatusCode::CONFLICT);
    let r = send(&app, Method::DELETE, "/v1/jobs/0123456789abcdef0123456789abcdef", &[AUTH], Vec::new()).await;
    assert_eq!(r.status, StatusCode::NOT_FOUND);
    // The asset's place was given back: it can be uploaded again.
    let (ctype, short) = multipart_objs(&pmcodec_mesh::samples::waving_cloth(8, 6, 3));
    let r = send(&app, Method::POST, "/v1/assets?id=long", &[("content-type", &ctype), AUTH], short).await;
    assert_eq!(r.status, StatusCode::ACCEPTED);
    assert_eq!(wait_finished(&app, r.json()["status_url"].as_str().unwrap()).await["state"], "succeeded");
}

#[tokio::test]
async fn frame_rates_and_frame_counts_are_bounded() {
    let (app, dir) = writable_app(|c| c.limits.max_frames = 2).await;
    let glb = pmcodec_mesh::write::glb_bytes(&pmcodec_mesh::samples::waving_cloth(8, 6, 1).frame_mesh(0).unwrap());
    for fps in ["1e-30", "0", "-5", "1000", "241", "NaN", "inf"] {
        let r =
            send(&app, Method::POST, &format!("/v1/assets?id=a&fps={fps}"), &[("content-type", "model/gltf-binary"), AUTH], glb.clone())
                .await;
        assert_eq!(r.status, StatusCode::BAD_REQUEST, "fps={fps}: {}", String::from_utf8_lossy(&r.body));
        assert!(r.json()["detail"].as_str().unwrap().contains("fps"), "fps={fps}");
    }
    // More OBJ files than frames allowed: refused while the body is read.
    let (ctype, three) = multipart_objs(&pmcodec_mesh::samples::waving_cloth(8, 6, 3));
    let r = send(&app, Method::POST, "/v1/assets?id=a", &[("content-type", &ctype), AUTH], three).await;
    assert_eq!(r.status, StatusCode::BAD_REQUEST, "{}", String::from_utf8_lossy(&r.body));
    assert!(r.json()["detail"].as_str().unwrap().contains("max_frames"));
    assert_eq!(files_in(dir.path()), 0, "a refused body leaves no file");
    // Within the bounds, it works.
    let r = send(&app, Method::POST, "/v1/assets?id=a&fps=0.1", &[("content-type", "model/gltf-binary"), AUTH], glb).await;
    assert_eq!(r.status, StatusCode::ACCEPTED, "{}", String::from_utf8_lossy(&r.body));
    assert_eq!(wait_finished(&app, r.json()["status_url"].as_str().unwrap()).await["state"], "succeeded");
}

#[tokio::test]
async fn head_on_a_mesh_does_not_decode() {
    let (app, _) = app().await;
    let decodes = |text: &str| -> u64 {
        let line = text.lines().find(|l| l.starts_with("pmcodec_decode_requests_total")).expect("the decode counter");
        line.split_whitespace().last().unwrap().parse().unwrap()
    };
    let before = decodes(&String::from_utf8(get(&app, "/metrics", &[]).await.body).unwrap());
    let r = send(&app, Method::HEAD, "/v1/assets/cloth/mesh?frame=3&triangles=77", &[], Vec::new()).await;
    assert_eq!(r.status, StatusCode::OK);
    assert_eq!(r.header("content-type"), "model/gltf-binary");
    assert!(r.header("etag").contains("-f3-t77-"));
    assert!(r.body.is_empty());
    let after = decodes(&String::from_utf8(get(&app, "/metrics", &[]).await.body).unwrap());
    assert_eq!(after, before, "HEAD ran a decode");
    // A bad HEAD is still refused.
    assert_eq!(send(&app, Method::HEAD, "/v1/assets/cloth/mesh?frame=99", &[], Vec::new()).await.status, StatusCode::BAD_REQUEST);
    // GET decodes, with the same tag.
    let g = get(&app, "/v1/assets/cloth/mesh?frame=3&triangles=77", &[]).await;
    assert_eq!(g.header("etag"), r.header("etag"));
}

#[tokio::test]
async fn headers_for_browsers_caches_and_long_urls() {
    // Immutable URLs are private when reads need a token.
    let mut config = Config::default();
    config.auth.read_token = Some(Secret("r".into()));
    let (private, _) = app_with(config).await;
    let auth = [("authorization", "Bearer r")];
    let info = get(&private, "/v1/assets/cloth", &auth).await.json();
    for url in [info["file"].as_str().unwrap().to_string(), info["file"].as_str().unwrap().replace("/file", "/chunks/0")] {
        let r = get(&private, &url, &auth).await;
        assert_eq!(r.status, StatusCode::OK);
        assert!(r.header("cache-control").starts_with("private,"), "{url}: {}", r.header("cache-control"));
    }
    let (app, _) = app().await;
    let file = get(&app, "/v1/assets/cloth", &[]).await.json()["file"].as_str().unwrap().to_string();
    assert!(get(&app, &file, &[]).await.header("cache-control").starts_with("public,"));

    // A 64 KB URL is not echoed back in full.
    let long = format!("/v1/{}", "a".repeat(60_000));
    let r = get(&app, &long, &[]).await;
    assert_eq!(r.status, StatusCode::NOT_FOUND);
    assert!(r.body.len() < 2_000, "{} bytes of error body", r.body.len());
    let r = get(&app, &format!("/v1/assets/{}", "b".repeat(60_000)), &[]).await;
    assert_eq!(r.status, StatusCode::BAD_REQUEST);
    assert!(r.body.len() < 2_000, "{} bytes of error body", r.body.len());
    assert_eq!(r.header("x-content-type-options"), "nosniff");

    // The viewer's files: no sniffing, and a policy that allows only this origin's scripts.
    let viewer = tempfile::tempdir().unwrap();
    std::fs::write(viewer.path().join("index.html"), "<!doctype html><title>v</title>").unwrap();
    let (app, _) = app_with(Config { viewer: Some(viewer.path().to_path_buf()), ..Default::default() }).await;
    let r = get(&app, "/index.html", &[]).await;
    assert_eq!(r.status, StatusCode::OK);
    assert_eq!(r.header("x-content-type-options"), "nosniff");
    let csp = r.header("content-security-policy");
    assert!(csp.contains("script-src 'self'") && csp.contains("frame-ancestors 'none'"), "{csp}");
}

#[test]
fn an_empty_token_is_refused_at_start() {
    for (write, read) in [(Some(""), None), (None, Some("  ")), (Some(""), Some("r"))] {
        let mut config = Config::default();
        config.auth.write_token = write.map(|t| Secret(t.into()));
        config.auth.read_token = read.map(|t| Secret(t.into()));
        let e = AppState::new(config, Arc::new(MemoryStore::default())).err().expect("refused");
        assert!(e.to_string().contains("token is empty"), "{e}");
    }
}
