//! Appearance through the HTTP API: the metadata names materials and textures with their byte
//! sizes and URLs, textures are served at immutable URLs with ETags, and `format=glb` answers
//! carry UVs, normals, colours, materials and the texture.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use axum::body::Body;
use axum::http::{Request, StatusCode};
use http_body_util::BodyExt;
use pmcodec_server::store::MemoryStore;
use pmcodec_server::{AppState, AssetId, AssetStore, Config, PutMode, router};
use std::sync::Arc;
use tower::ServiceExt;

async fn get(app: &axum::Router, uri: &str, headers: &[(&str, &str)]) -> (StatusCode, axum::http::HeaderMap, Vec<u8>) {
    let mut req = Request::builder().uri(uri);
    for (k, v) in headers {
        req = req.header(*k, *v);
    }
    let resp = app.clone().oneshot(req.body(Body::empty()).unwrap()).await.unwrap();
    let (parts, body) = resp.into_parts();
    (parts.status, parts.headers, body.collect().await.unwrap().to_bytes().to_vec())
}

#[tokio::test]
async fn textured_assets_describe_and_serve_their_appearance() {
    let seq = pmcodec_mesh::samples::textured_cloth(16, 10, 4, 16);
    let png = seq.appearance.as_ref().unwrap().images[0].bytes.clone();
    let bytes = pmcodec_container::encode(&seq, &Default::default(), |_| {}).unwrap();
    let store: Arc<dyn AssetStore> = Arc::new(MemoryStore::default());
    store.put(&AssetId::parse("textured").unwrap(), bytes.into(), PutMode::Overwrite).await.unwrap();
    let state = AppState::new(Config::default(), store).unwrap();
    state.set_ready(true);
    let app = router(state);

    let (status, _, body) = get(&app, "/v1/assets/textured", &[]).await;
    assert_eq!(status, StatusCode::OK);
    let info: serde_json::Value = serde_json::from_slice(&body).unwrap();
    let a = &info["appearance"];
    assert_eq!(a["materials"].as_array().unwrap().len(), 2);
    assert_eq!(a["materials"][0]["name"], "checker");
    assert_eq!(a["materials"][0]["base_color_texture"], 0);
    assert_eq!(a["materials"][1]["alpha_mode"], "BLEND");
    assert_eq!(a["textures"][0]["mime_type"], "image/png");
    assert_eq!(a["textures"][0]["bytes"], png.len());
    assert_eq!(a["attribute_bytes_per_level"].as_array().unwrap().len(), info["levels"].as_array().unwrap().len());

    // The texture at its immutable URL: the PNG's bytes, an ETag that revalidates, immutable.
    let url = a["textures"][0]["url"].as_str().unwrap().to_string();
    let (status, headers, body) = get(&app, &url, &[]).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(body, png);
    assert_eq!(headers["content-type"], "image/png");
    assert!(headers["cache-control"].to_str().unwrap().contains("immutable"));
    let etag = headers["etag"].to_str().unwrap().to_string();
    assert!(etag.ends_with("-image-0\""), "{etag}");
    let (status, _, _) = get(&app, &url, &[("if-none-match", &etag)]).await;
    assert_eq!(status, StatusCode::NOT_MODIFIED);
    let (status, _, body) = get(&app, &url, &[("range", "bytes=0-7")]).await;
    assert_eq!((status, body.as_slice()), (StatusCode::PARTIAL_CONTENT, &b"\x89PNG\r\n\x1a\n"[..]));
    let (status, _, _) = get(&app, &url.replace("/images/0", "/images/1"), &[]).await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    let (status, _, _) = get(&app, &url.replace("/images/0", "/images/x"), &[]).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);

    // A GLB answer carries the appearance, the texture embedded.
    let (status, _, body) = get(&app, "/v1/assets/textured/mesh?frame=1&triangles=120", &[]).await;
    assert_eq!(status, StatusCode::OK);
    let (doc, buffers, images) = gltf::import_slice(&body).expect("a GLB the gltf crate imports");
    assert_eq!(doc.materials().count(), 2);
    assert_eq!(images.len(), 1);
    let mut triangles = 0;
    for p in doc.meshes().next().unwrap().primitives() {
        let r = p.reader(|b| Some(&buffers[b.index()]));
        let n = r.read_positions().unwrap().count();
        assert_eq!(r.read_tex_coords(0).unwrap().into_f32().count(), n);
        assert_eq!(r.read_normals().unwrap().count(), n);
        triangles += r.read_indices().unwrap().into_u32().count() / 3;
    }
    assert!(triangles > 0 && triangles <= 120, "{triangles}");
}

#[tokio::test]
async fn a_stream_from_a_later_frame_carries_the_appearance_of_frame_0() {
    let seq = pmcodec_mesh::samples::textured_cloth(16, 10, 8, 16);
    let opts = pmcodec_container::EncodeOptions { keyframe_interval: 4, ..Default::default() };
    let bytes = pmcodec_container::encode(&seq, &opts, |_| {}).unwrap();
    let reader = pmcodec_container::Reader::open(bytes.as_slice()).unwrap();
    let head = reader.data_start() as usize;
    let piece = |kind: pmcodec_container::ChunkKind, frame: u32| -> Vec<Vec<u8>> {
        reader
            .index()
            .chunks
            .iter()
            .filter(|e| e.kind == kind && e.frame == frame)
            .map(|e| bytes[head + e.offset as usize..head + e.offset as usize + e.stored_len as usize].to_vec())
            .collect()
    };
    let store: Arc<dyn AssetStore> = Arc::new(MemoryStore::default());
    store.put(&AssetId::parse("textured").unwrap(), bytes.clone().into(), PutMode::Overwrite).await.unwrap();
    let state = AppState::new(Config::default(), store).unwrap();
    state.set_ready(true);
    let app = router(state);
    let (status, headers, body) = get(&app, "/v1/assets/textured/stream?from=7", &[]).await;
    assert_eq!(status, StatusCode::OK);
    assert_ne!(headers["x-pmc-from"], "0", "the stream starts at a later keyframe");
    let has = |p: &[u8]| body.windows(p.len()).any(|w| w == p);
    use pmcodec_container::ChunkKind;
    for kind in [ChunkKind::Charts, ChunkKind::Materials, ChunkKind::Attributes, ChunkKind::Key] {
        let pieces = piece(kind, 0);
        assert!(!pieces.is_empty(), "{kind:?}: the file has frame-0 chunks of this kind");
        for p in pieces {
            assert!(has(&p), "{kind:?} of frame 0 is missing from the stream");
        }
    }
}

#[tokio::test]
async fn binary_layout_3_carries_the_appearance_on_request() {
    let seq = pmcodec_mesh::samples::textured_cloth(16, 10, 4, 16);
    let bytes = pmcodec_container::encode(&seq, &Default::default(), |_| {}).unwrap();
    let bare = pmcodec_container::encode(&pmcodec_mesh::samples::twisting_tube(12, 10, 3), &Default::default(), |_| {}).unwrap();
    let store: Arc<dyn AssetStore> = Arc::new(MemoryStore::default());
    store.put(&AssetId::parse("textured").unwrap(), bytes.clone().into(), PutMode::Overwrite).await.unwrap();
    store.put(&AssetId::parse("bare").unwrap(), bare.into(), PutMode::Overwrite).await.unwrap();
    let state = AppState::new(Config::default(), store).unwrap();
    state.set_ready(true);
    let app = router(state);

    // Without `layout` the answer stays layout 2, which older clients read.
    let (status, _, body) = get(&app, "/v1/assets/textured/mesh?frame=2&triangles=120&format=bin", &[]).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(&body[4..8], &2u32.to_le_bytes());

    let (status, headers, body) = get(&app, "/v1/assets/textured/mesh?frame=2&triangles=120&format=bin&layout=3", &[]).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(headers["content-type"], "application/vnd.pmcodec.mesh");
    assert!(headers["etag"].to_str().unwrap().contains("-bin3-"), "{:?}", headers["etag"]);
    let (mesh, got) = pmcodec_server::decode_bin_appearance(&body).unwrap();
    assert!(!mesh.triangles.is_empty() && mesh.triangles.len() <= 120);
    // The same cut the decoder draws locally: same vertices and attributes in the same order,
    // the same triangles with the same materials (grouped by material in the body).
    let reader = pmcodec_container::Reader::open(bytes.as_slice()).unwrap();
    let mut d = pmcodec_container::Decoder::new(reader.borrowed(), 0).unwrap();
    d.seek(2).unwrap();
    let (want_mesh, want) = d.textured_mesh(pmcodec_container::CutTarget::Triangles(120)).unwrap();
    assert_eq!(mesh.positions, want_mesh.positions);
    assert_eq!((&got.uv0, &got.normals), (&want.uv0, &want.normals));
    assert_eq!(got.colors.len(), want.colors.len());
    let sorted = |m: &[u32], t: &[[u32; 3]]| {
        let mut v: Vec<(u32, [u32; 3])> = m.iter().copied().zip(t.iter().copied()).collect();
        v.sort();
        v
    };
    assert_eq!(sorted(&got.triangle_material, &mesh.triangles), sorted(&want.triangle_material, &want_mesh.triangles));
    assert!(got.triangle_material.windows(2).all(|w| w[0] <= w[1]), "triangles grouped by material");
    assert_eq!(got.triangle_material.iter().max(), Some(&1), "both materials of the cloth are shown");

    // A bare asset's layout 3 carries unit normals and nothing else.
    let (status, _, body) = get(&app, "/v1/assets/bare/mesh?frame=1&level=0&format=bin&layout=3", &[]).await;
    assert_eq!(status, StatusCode::OK);
    let (mesh, got) = pmcodec_server::decode_bin_appearance(&body).unwrap();
    assert_eq!(got.normals.len(), mesh.positions.len());
    assert!(got.normals.iter().all(|n| ((n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() - 1.0).abs() < 1e-5));
    assert!(got.uv0.is_empty() && got.triangle_material.is_empty());

    for bad in ["format=bin&layout=4", "format=glb&layout=3", "layout=3", "format=bin&layout=x"] {
        let (status, _, _) = get(&app, &format!("/v1/assets/textured/mesh?frame=0&{bad}"), &[]).await;
        assert_eq!(status, StatusCode::BAD_REQUEST, "{bad}");
    }
}
