//! The HTTP API against the router (no socket needed): listing, metadata, LOD on demand,
//! immutable container bytes with ETag and Range, errors, and the OpenAPI document's coverage.

use axum::body::Body;
use axum::http::{Request, StatusCode, header};
use http_body_util::BodyExt;
use pmcodec_server::{AppState, Asset, ROUTES, router};
use std::sync::Arc;
use tower::ServiceExt;

fn app() -> axum::Router {
    let seq = pmcodec_mesh::samples::waving_cloth(16, 12, 6);
    let bytes = pmcodec_container::encode(&seq, &Default::default(), |_| {}).unwrap();
    let asset = Asset::new("cloth".into(), bytes).unwrap();
    let state = AppState { assets: [("cloth".to_string(), Arc::new(asset))].into_iter().collect() };
    router(Arc::new(state), None)
}

async fn get(app: &axum::Router, uri: &str, headers: &[(&str, &str)]) -> (StatusCode, axum::http::HeaderMap, Vec<u8>) {
    let mut req = Request::get(uri);
    for (k, v) in headers {
        req = req.header(*k, *v);
    }
    let resp = app.clone().oneshot(req.body(Body::empty()).unwrap()).await.unwrap();
    let (parts, body) = resp.into_parts();
    (parts.status, parts.headers, body.collect().await.unwrap().to_bytes().to_vec())
}

fn json(b: &[u8]) -> serde_json::Value {
    serde_json::from_slice(b).unwrap()
}

#[tokio::test]
async fn list_metadata_and_meshes() {
    let app = app();
    let (s, _, b) = get(&app, "/v1/assets", &[]).await;
    assert_eq!(s, StatusCode::OK);
    let list = json(&b);
    assert_eq!(list["assets"][0]["id"], "cloth");
    assert_eq!(list["assets"][0]["frames"], 6);
    let (s, _, b) = get(&app, "/v1/assets/cloth", &[]).await;
    assert_eq!(s, StatusCode::OK);
    let info = json(&b);
    assert_eq!(info["triangles_per_level"][0], 2 * 15 * 11);
    for budget in [20u32, 100, 400] {
        let (s, h, b) = get(&app, &format!("/v1/assets/cloth/mesh?frame=5&triangles={budget}&format=bin"), &[]).await;
        assert_eq!(s, StatusCode::OK);
        assert_eq!(h[header::CONTENT_TYPE], "application/octet-stream");
        assert_eq!(&b[..4], b"PMCM");
        let v = u32::from_le_bytes(b[8..12].try_into().unwrap()) as usize;
        let t = u32::from_le_bytes(b[12..16].try_into().unwrap()) as usize;
        assert!(t as u32 <= budget && t > 0, "{t} > {budget}");
        assert_eq!(b.len(), 16 + 12 * v + 12 * t);
    }
    let (s, h, b) = get(&app, "/v1/assets/cloth/mesh?frame=2&level=1", &[]).await;
    assert_eq!(s, StatusCode::OK);
    assert_eq!(h[header::CONTENT_TYPE], "model/gltf-binary");
    assert!(gltf::Gltf::from_slice(&b).is_ok());
}

#[tokio::test]
async fn bad_requests_say_what_is_wrong() {
    let app = app();
    for (uri, status, needle) in [
        ("/v1/assets/NOPE", StatusCode::BAD_REQUEST, "invalid asset id"),
        ("/v1/assets/..%2fetc", StatusCode::BAD_REQUEST, "invalid asset id"),
        ("/v1/assets/missing", StatusCode::NOT_FOUND, "no asset"),
        ("/v1/assets/cloth/mesh?frame=99", StatusCode::BAD_REQUEST, "frames 0..5"),
        ("/v1/assets/cloth/mesh?level=9", StatusCode::BAD_REQUEST, "levels"),
        ("/v1/assets/cloth/mesh?triangles=5&level=1", StatusCode::BAD_REQUEST, "at most one"),
        ("/v1/assets/cloth/mesh?format=fbx", StatusCode::BAD_REQUEST, "format"),
        ("/v1/assets/cloth/mesh?triangles=-3", StatusCode::BAD_REQUEST, ""),
    ] {
        let (s, _, b) = get(&app, uri, &[]).await;
        assert_eq!(s, status, "{uri}");
        if !needle.is_empty() {
            assert!(json(&b)["detail"].as_str().unwrap().contains(needle), "{uri}: {}", String::from_utf8_lossy(&b));
        }
    }
}

#[tokio::test]
async fn container_bytes_are_immutable_with_etag_and_ranges() {
    let app = app();
    let (_, _, b) = get(&app, "/v1/assets", &[]).await;
    let url = json(&b)["assets"][0]["file"].as_str().unwrap().to_string();
    let (s, h, whole) = get(&app, &url, &[]).await;
    assert_eq!(s, StatusCode::OK);
    assert_eq!(h[header::CACHE_CONTROL], "public, max-age=31536000, immutable");
    let etag = h[header::ETAG].to_str().unwrap().to_string();
    assert!(pmcodec_container::Reader::open(whole.as_slice()).is_ok());
    let (s, _, _) = get(&app, &url, &[("if-none-match", &etag)]).await;
    assert_eq!(s, StatusCode::NOT_MODIFIED);
    let (s, h, part) = get(&app, &url, &[("range", "bytes=0-31")]).await;
    assert_eq!(s, StatusCode::PARTIAL_CONTENT);
    assert_eq!(part, whole[..32]);
    assert_eq!(h[header::CONTENT_RANGE], format!("bytes 0-31/{}", whole.len()));
    let (s, _, part) = get(&app, &url, &[("range", "bytes=-10")]).await;
    assert_eq!((s, part.as_slice()), (StatusCode::PARTIAL_CONTENT, &whole[whole.len() - 10..]));
    let (s, _, _) = get(&app, &url, &[("range", &format!("bytes={}-", whole.len()))]).await;
    assert_eq!(s, StatusCode::RANGE_NOT_SATISFIABLE);
    let (s, _, all) = get(&app, &url, &[("range", "bytes=0-1,5-6")]).await;
    assert_eq!((s, all.len()), (StatusCode::OK, whole.len()));
    let (s, _, all) = get(&app, &url, &[("range", "bytes=0-1"), ("if-range", "\"stale\"")]).await;
    assert_eq!((s, all.len()), (StatusCode::OK, whole.len()));
    let (s, _, _) = get(&app, "/v1/assets/cloth/v/00000000-0.pmc", &[]).await;
    assert_eq!(s, StatusCode::NOT_FOUND);
}

#[test]
fn openapi_lists_exactly_the_mounted_routes() {
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../proto/openapi.yaml")).unwrap();
    let documented: Vec<&str> = doc
        .lines()
        .filter(|l| l.starts_with("  /") && l.trim_end().ends_with(':'))
        .map(|l| l.trim().trim_end_matches(':'))
        .collect();
    let mut a = documented.clone();
    a.sort();
    let mut b: Vec<&str> = ROUTES.to_vec();
    b.sort();
    assert_eq!(a, b);
}

#[tokio::test]
async fn every_listed_route_is_mounted() {
    let app = app();
    for route in ROUTES {
        let uri = route.replace("{id}", "cloth").replace("{version}", "x.pmc");
        let (s, _, b) = get(&app, &uri, &[]).await;
        // An unmounted path is the router's bare 404; ours always carry a JSON body.
        assert!(!(s == StatusCode::NOT_FOUND && b.is_empty()), "{route} is not mounted");
    }
    let (s, _, b) = get(&app, "/v1/not-a-route", &[]).await;
    assert!(s == StatusCode::NOT_FOUND && b.is_empty());
}
