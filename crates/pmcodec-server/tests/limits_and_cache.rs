//! Resources a request can take, against the router (no socket): the input limits of uploads
//! (checked while the meshes are parsed, in the encode job), and the decoder states the LOD
//! workers share (counted through `/metrics`, not timed).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use axum::body::Body;
use axum::http::{Method, Request, StatusCode};
use http_body_util::BodyExt;
use pmcodec_mesh::InputLimits;
use pmcodec_server::config::Secret;
use pmcodec_server::store::MemoryStore;
use pmcodec_server::{AppState, AssetId, AssetStore, Config, PutMode, router};
use std::io::Write;
use std::sync::Arc;
use tower::ServiceExt;

async fn send(app: &axum::Router, method: Method, uri: &str, headers: &[(&str, &str)], body: Vec<u8>) -> (StatusCode, Vec<u8>) {
    let mut req = Request::builder().method(method).uri(uri);
    for (k, v) in headers {
        req = req.header(*k, *v);
    }
    let resp = app.clone().oneshot(req.body(Body::from(body)).expect("request")).await.expect("infallible");
    let status = resp.status();
    (status, resp.into_body().collect().await.expect("body").to_bytes().to_vec())
}

async fn get(app: &axum::Router, uri: &str) -> (StatusCode, Vec<u8>) {
    send(app, Method::GET, uri, &[], Vec::new()).await
}

fn json(body: &[u8]) -> serde_json::Value {
    serde_json::from_slice(body).unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(body)))
}

async fn app_with(config: Config, assets: &[(&str, Vec<u8>)]) -> axum::Router {
    let store: Arc<dyn AssetStore> = Arc::new(MemoryStore::default());
    let state = AppState::new(config, store.clone()).expect("state");
    for (id, bytes) in assets {
        store.put(&AssetId::parse(id).expect("id"), bytes.clone().into(), PutMode::Overwrite).await.expect("put");
    }
    state.set_ready(true);
    router(state)
}

// ------------------------------------------------------------------------------------------------
// Input limits of uploads
// ------------------------------------------------------------------------------------------------

fn zip_of(files: &[(&str, &[u8])]) -> Vec<u8> {
    let mut buf = std::io::Cursor::new(Vec::new());
    let mut z = zip::ZipWriter::new(&mut buf);
    let o = zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
    for (name, data) in files {
        z.start_file(*name, o).expect("zip member");
        z.write_all(data).expect("zip write");
    }
    z.finish().expect("zip");
    buf.into_inner()
}

/// Uploads a zip and polls its job until it ends; returns the job's last status.
async fn upload_zip_and_wait(app: &axum::Router, id: &str, zip: Vec<u8>) -> serde_json::Value {
    let headers = [("content-type", "application/zip"), ("authorization", "Bearer w")];
    let (status, body) = send(app, Method::POST, &format!("/v1/assets?id={id}"), &headers, zip).await;
    assert_eq!(status, StatusCode::ACCEPTED, "{}", String::from_utf8_lossy(&body));
    let url = json(&body)["status_url"].as_str().expect("a status url").to_string();
    // Bounded: a job past a limit ends at the limit.
    for _ in 0..1200 {
        let status = json(&get(app, &url).await.1);
        if status["state"] == "succeeded" || status["state"] == "failed" {
            return status;
        }
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
    }
    panic!("the job did not finish within a minute");
}

fn writer_config() -> Config {
    let mut config = Config::default();
    config.auth.write_token = Some(Secret("w".into()));
    config
}

/// The report's zip (two frames of ten million vertices each, 233 KB) at the default limit:
/// two frames of one vertex more than the default vertex limit fail the job at that vertex,
/// with the limit, file and line in its message, and nothing is stored.
#[tokio::test]
async fn an_obj_zip_past_the_default_vertex_limit_fails_at_that_vertex() {
    let app = app_with(writer_config(), &[]).await;
    let max = InputLimits::default().max_vertices;
    let frame = "v 0 0 0\n".repeat(max + 1).into_bytes();
    let zip = zip_of(&[("f1.obj", &frame), ("f2.obj", &frame)]);
    assert!(zip.len() < 1 << 20, "the zip is small: {} bytes", zip.len());
    drop(frame);
    let status = upload_zip_and_wait(&app, "huge", zip).await;
    assert_eq!(status["state"], "failed", "{status}");
    let message = status["message"].as_str().expect("a message");
    assert!(message.contains(&format!("f1.obj:{}", max + 1)) && message.contains(&format!("max_vertices = {max}")), "{message}");
    assert_eq!(get(&app, "/v1/assets/huge").await.0, StatusCode::NOT_FOUND);
}

#[tokio::test]
async fn configured_input_limits_apply_to_every_kind_of_upload() {
    let mut config = writer_config();
    config.limits.input = InputLimits { max_vertices: 1000, max_triangles: 1000, max_frames: 3, max_positions: 100 };
    let app = app_with(config, &[]).await;
    // 4 vertices and 2 triangles per frame.
    let quad = |dx: f32| format!("v {dx} 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n").into_bytes();
    let frames: Vec<(String, Vec<u8>)> = (0..4).map(|i| (format!("f{i}.obj"), quad(i as f32 * 0.1))).collect();
    let members = |n: usize| frames[..n].iter().map(|(name, data)| (name.as_str(), data.as_slice())).collect::<Vec<_>>();

    let status = upload_zip_and_wait(&app, "four", zip_of(&members(4))).await;
    assert_eq!(status["state"], "failed", "{status}");
    assert!(status["message"].as_str().unwrap().contains("4 frames, past the input limit max_frames = 3"), "{status}");
    let status = upload_zip_and_wait(&app, "three", zip_of(&members(3))).await;
    assert_eq!(status["state"], "succeeded", "{status}");

    // A GLB past the positions limit: one frame (no animation) of more than 100 vertices.
    let mesh = pmcodec_mesh::samples::waving_cloth(12, 12, 1).frame_mesh(0).expect("a frame");
    assert!(mesh.positions.len() > 100);
    let glb = pmcodec_mesh::write::glb_bytes(&mesh);
    let headers = [("content-type", "model/gltf-binary"), ("authorization", "Bearer w")];
    let (code, body) = send(&app, Method::POST, "/v1/assets?id=grid", &headers, glb).await;
    assert_eq!(code, StatusCode::ACCEPTED, "{}", String::from_utf8_lossy(&body));
    let url = json(&body)["status_url"].as_str().expect("a status url").to_string();
    let status = loop {
        let s = json(&get(&app, &url).await.1);
        if s["state"] == "failed" || s["state"] == "succeeded" {
            break s;
        }
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
    };
    assert_eq!(status["state"], "failed", "{status}");
    assert!(status["message"].as_str().unwrap().contains("max_positions = 100"), "{status}");
}

// ------------------------------------------------------------------------------------------------
// The decoder states the workers share
// ------------------------------------------------------------------------------------------------

fn cloth_bytes() -> Vec<u8> {
    let seq = pmcodec_mesh::samples::waving_cloth(16, 12, 6);
    let opts = pmcodec_container::EncodeOptions { keyframe_interval: 4, ..Default::default() };
    pmcodec_container::encode(&seq, &opts, |_| {}).expect("encode the cloth")
}

/// The value of an unlabelled metric.
async fn metric(app: &axum::Router, name: &str) -> u64 {
    let (_, body) = get(app, "/metrics").await;
    let text = String::from_utf8(body).expect("text");
    let line = text.lines().find(|l| l.starts_with(&format!("{name} "))).unwrap_or_else(|| panic!("no {name} in {text}"));
    line[name.len() + 1..].trim().parse().unwrap_or_else(|e| panic!("{line}: {e}"))
}

async fn mesh(app: &axum::Router, asset: &str, frame: u32) -> Vec<u8> {
    let (status, body) = get(app, &format!("/v1/assets/{asset}/mesh?frame={frame}&triangles=150&format=bin")).await;
    assert_eq!(status, StatusCode::OK, "{}", String::from_utf8_lossy(&body));
    body
}

fn cache_config(workers: usize, bytes: u64) -> Config {
    let mut config = Config::default();
    config.cache.decode_workers = workers;
    config.cache.decode_bytes = bytes;
    config
}

/// The weight the server gives one decoder state of the cloth.
async fn state_weight(cloth: &[u8]) -> u64 {
    let app = app_with(cache_config(1, 1 << 30), &[("cloth", cloth.to_vec())]).await;
    mesh(&app, "cloth", 1).await;
    assert_eq!(metric(&app, "pmcodec_decode_states").await, 1);
    metric(&app, "pmcodec_decode_state_bytes").await
}

/// With 16 workers and room for two states in all, a state is larger than one worker's share:
/// it is still kept, and the second request for its frame is served from it.
#[tokio::test]
async fn a_state_larger_than_one_workers_share_is_kept_and_reused() {
    let cloth = cloth_bytes();
    let weight = state_weight(&cloth).await;
    let app = app_with(cache_config(16, 2 * weight), &[("cloth", cloth)]).await;
    let first = mesh(&app, "cloth", 1).await;
    let second = mesh(&app, "cloth", 1).await;
    assert_eq!(first, second);
    assert_eq!(metric(&app, "pmcodec_decode_state_hits_total").await, 1, "the second request reused the state");
    assert_eq!(metric(&app, "pmcodec_decode_state_misses_total").await, 1);
    assert_eq!(metric(&app, "pmcodec_decode_keyframe_starts_total").await, 1);
    // A later frame of the interval steps a clone of the kept state forward.
    mesh(&app, "cloth", 2).await;
    assert_eq!(metric(&app, "pmcodec_decode_keyframe_starts_total").await, 1, "frame 2 started from frame 1's state");
    assert_eq!(metric(&app, "pmcodec_decode_states").await, 2);
    assert!(metric(&app, "pmcodec_decode_state_bytes").await <= 2 * weight);
}

/// A state larger than the whole budget is kept alone in its own slot: the asset is decoded
/// once, not once per request, and the memory held is that one state.
#[tokio::test]
async fn a_state_larger_than_the_whole_budget_is_kept_alone() {
    let cloth = cloth_bytes();
    let weight = state_weight(&cloth).await;
    let app = app_with(cache_config(2, weight / 2), &[("cloth", cloth)]).await;
    let first = mesh(&app, "cloth", 1).await;
    assert_eq!(mesh(&app, "cloth", 1).await, first);
    assert_eq!(metric(&app, "pmcodec_decode_state_hits_total").await, 1);
    mesh(&app, "cloth", 2).await;
    assert_eq!(metric(&app, "pmcodec_decode_keyframe_starts_total").await, 1, "frame 2 started from frame 1's state");
    // The slot holds one state: frame 2's replaced frame 1's.
    assert_eq!(metric(&app, "pmcodec_decode_states").await, 1);
    assert_eq!(metric(&app, "pmcodec_decode_state_bytes").await, weight);
    mesh(&app, "cloth", 2).await;
    assert_eq!(metric(&app, "pmcodec_decode_state_hits_total").await, 2);
}

/// Many concurrent requests for one frame decode it once: the others wait for the state
/// instead of each decoding the same frame from the keyframe.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn concurrent_requests_for_one_frame_decode_it_once() {
    let app = app_with(cache_config(4, 1 << 30), &[("cloth", cloth_bytes())]).await;
    let tasks: Vec<_> = (0..16)
        .map(|_| {
            let app = app.clone();
            tokio::spawn(async move { mesh(&app, "cloth", 3).await })
        })
        .collect();
    let mut bodies = Vec::new();
    for t in tasks {
        bodies.push(t.await.expect("task"));
    }
    assert!(bodies.windows(2).all(|w| w[0] == w[1]));
    assert_eq!(metric(&app, "pmcodec_decode_keyframe_starts_total").await, 1);
    assert_eq!(metric(&app, "pmcodec_decode_state_misses_total").await, 1);
    assert_eq!(metric(&app, "pmcodec_decode_state_hits_total").await, 15);
}
