//! The server as users meet it: on an ephemeral port, over real sockets, with real data from
//! `../shared/data/`. Uploads become encode jobs whose progress streams as server-sent events;
//! served LODs equal local decoding bit for bit; the Rust client plays a whole sequence; bad
//! uploads, missing tokens, path tricks and cut-off range requests fail cleanly and leave
//! nothing behind; and the S3 backend runs against a real S3-compatible server (s3s-fs).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_client::Client;
use pmcodec_container::{CutTarget, Decoder, Distance, Reader};
use pmcodec_server::config::{S3Config, Secret, StoreConfig};
use pmcodec_server::{Config, RunningServer};
use serde_json::Value;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::time::Duration;

const TOKEN: &str = "test-write-token";

fn data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data").join(rel)
}

/// The first `n` frames of a folder of OBJ files, as (name, bytes) in frame order.
fn obj_frames(dir: &str, n: usize) -> Vec<(String, Vec<u8>)> {
    let mut names: Vec<PathBuf> = std::fs::read_dir(data(dir))
        .unwrap_or_else(|e| panic!("{dir} in ../shared/data: {e}"))
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "obj"))
        .collect();
    names.sort();
    names.truncate(n);
    names.iter().map(|p| (p.file_name().unwrap().to_string_lossy().into_owned(), std::fs::read(p).unwrap())).collect()
}

fn zip_of(files: &[(String, Vec<u8>)]) -> Vec<u8> {
    let mut w = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let opts = zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
    for (name, bytes) in files {
        w.start_file(name.as_str(), opts).unwrap();
        w.write_all(bytes).unwrap();
    }
    w.finish().unwrap().into_inner()
}

async fn local_server(dir: &Path) -> RunningServer {
    let mut config =
        Config { store: StoreConfig::Local { path: dir.to_path_buf() }, listen: "127.0.0.1:0".parse().unwrap(), ..Default::default() };
    config.auth.write_token = Some(Secret(TOKEN.into()));
    pmcodec_server::start(config).await.expect("server starts")
}

/// Uploads a body and follows the job's event stream to its end; returns the events' names and
/// the last status.
async fn upload(http: &reqwest::Client, base: &str, query: &str, content_type: &str, body: Vec<u8>) -> (Vec<String>, Value) {
    let r = http
        .post(format!("{base}/v1/assets?{query}"))
        .bearer_auth(TOKEN)
        .header("content-type", content_type)
        .body(body)
        .send()
        .await
        .unwrap();
    let status = r.status();
    let location = r.headers().get("location").map(|v| v.to_str().unwrap().to_string());
    let job: Value = r.json().await.unwrap();
    assert_eq!(status, 202, "{job}");
    assert_eq!(location.as_deref(), job["status_url"].as_str());
    let events = http.get(format!("{base}{}", job["events_url"].as_str().unwrap())).send().await.unwrap();
    assert_eq!(events.headers()["content-type"], "text/event-stream");
    let text = tokio::time::timeout(Duration::from_secs(300), events.text()).await.expect("the job finishes").unwrap();
    let mut names = Vec::new();
    let mut last = Value::Null;
    for block in text.split("\n\n") {
        let mut event = None;
        for line in block.lines() {
            if let Some(e) = line.strip_prefix("event:") {
                event = Some(e.trim().to_string());
            } else if let Some(d) = line.strip_prefix("data:") {
                last = serde_json::from_str(d.trim()).unwrap();
            }
        }
        names.extend(event);
    }
    (names, last)
}

/// Files in a store folder other than finished containers and their listing metadata
/// (temporary files left behind).
fn leftovers(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !n.ends_with(".pmc") && !n.ends_with(".meta.json"))
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn uploaded_obj_sequence_is_served_bit_for_bit_and_plays_through_the_client() {
    let dir = tempfile::tempdir().unwrap();
    let server = local_server(dir.path()).await;
    let base = server.url();
    let http = reqwest::Client::new();

    let frames = obj_frames("horse-gallop", 10);
    let (events, last) = upload(&http, &base, "id=horse&fps=24", "application/zip", zip_of(&frames)).await;
    assert_eq!(last["state"], "succeeded", "{last}");
    // The first event is the state when the client subscribed (the job may have started).
    assert!(matches!(events.first().map(String::as_str), Some("queued" | "running")), "{events:?}");
    assert!(events.iter().filter(|e| *e == "running").count() >= 2, "progress events while encoding: {events:?}");
    assert_eq!(events.last().map(String::as_str), Some("succeeded"));
    assert!(dir.path().join("horse.pmc").is_file());
    // Its listing metadata is written with it, for cold servers.
    let meta: Value = serde_json::from_slice(&std::fs::read(dir.path().join("horse.meta.json")).unwrap()).unwrap();
    assert_eq!((meta["schema"].as_u64(), meta["info"]["id"].as_str()), (Some(1), Some("horse")), "{meta}");
    assert!(leftovers(dir.path()).is_empty(), "{:?}", leftovers(dir.path()));

    let info: Value = http.get(format!("{base}/v1/assets/horse")).send().await.unwrap().json().await.unwrap();
    assert_eq!(info["frames"], 10);
    assert_eq!(info["vertices"], 8431);
    assert_eq!(info["frame_rate"], 24.0);
    let file = http.get(format!("{base}{}", info["file"].as_str().unwrap())).send().await.unwrap().bytes().await.unwrap().to_vec();
    assert_eq!(file.len() as u64, info["bytes"].as_u64().unwrap());

    // LOD on demand equals decoding the served container here, bit for bit.
    let client = Client::new(&base).unwrap();
    let mut local = Decoder::new(Reader::open(file.as_slice()).unwrap(), 0).unwrap();
    for (frame, target) in [
        (7, CutTarget::Triangles(1600)),
        (2, CutTarget::Triangles(300)),
        (9, CutTarget::Level(2)),
        (0, CutTarget::Level(0)),
        (5, CutTarget::MaxError(Distance::DiagonalFraction(0.01))),
    ] {
        let served = client.mesh("horse", frame, target).await.unwrap();
        local.seek(frame).unwrap();
        assert_eq!(served, local.mesh(target).unwrap(), "frame {frame} {target:?}");
    }

    // A playback session at 10% of the triangles: same meshes as local decoding at its level,
    // and far fewer bytes than the whole file.
    let budget = 16843 / 10;
    let mut session = client.session("horse", budget).await.unwrap();
    let mut local = Decoder::new(Reader::open(file.as_slice()).unwrap(), session.level()).unwrap();
    for f in 0..10 {
        let frame = session.frame(f).await.unwrap();
        local.seek(f).unwrap();
        assert_eq!(frame.mesh, local.mesh(CutTarget::Triangles(budget)).unwrap(), "frame {f}");
    }
    let share = session.bytes_downloaded() as f64 / file.len() as f64;
    assert!(share < 0.5, "a 10% session downloaded {:.0}% of the file", share * 100.0);

    // Replacing needs replace=true; deleting removes the file.
    let r = http
        .post(format!("{base}/v1/assets?id=horse"))
        .bearer_auth(TOKEN)
        .header("content-type", "application/zip")
        .body(zip_of(&frames[..2]))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 409);
    let r = http.delete(format!("{base}/v1/assets/horse")).bearer_auth(TOKEN).send().await.unwrap();
    assert_eq!(r.status(), 204);
    assert!(!dir.path().join("horse.pmc").exists());
    server.stop().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn uploaded_glb_with_a_named_animation_becomes_an_asset() {
    let dir = tempfile::tempdir().unwrap();
    let server = local_server(dir.path()).await;
    let http = reqwest::Client::new();
    let glb = std::fs::read(data("gltf/Fox.glb")).unwrap();
    let (_, last) = upload(&http, &server.url(), "id=fox&fps=10&animation=Walk", "model/gltf-binary", glb.clone()).await;
    assert_eq!(last["state"], "succeeded", "{last}");
    let info: Value = http.get(format!("{}/v1/assets/fox", server.url())).send().await.unwrap().json().await.unwrap();
    assert!(info["frames"].as_u64().unwrap() > 5, "{info}");
    // An animation the file does not have fails the job with its name, and stores nothing.
    let (_, last) = upload(&http, &server.url(), "id=fox2&animation=Moonwalk", "model/gltf-binary", glb).await;
    assert_eq!(last["state"], "failed");
    assert!(last["message"].as_str().unwrap().contains("Moonwalk"), "{last}");
    assert!(!dir.path().join("fox2.pmc").exists());
    assert!(leftovers(dir.path()).is_empty());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn frame_rates_and_long_animations_are_refused_before_sampling() {
    let dir = tempfile::tempdir().unwrap();
    let mut config = Config {
        store: StoreConfig::Local { path: dir.path().to_path_buf() },
        listen: "127.0.0.1:0".parse().unwrap(),
        ..Default::default()
    };
    config.auth.write_token = Some(Secret(TOKEN.into()));
    config.limits.max_frames = 100;
    let server = pmcodec_server::start(config).await.unwrap();
    let http = reqwest::Client::new();
    let glb = std::fs::read(data("gltf/Fox.glb")).unwrap();
    // Out of range (fps=1000 made a 72 KB GLB 20,001 frames; fps=1e-30 a frame time no player
    // can convert): 400 naming the parameter.
    for fps in ["1000", "1e-30", "0"] {
        let r = http
            .post(format!("{}/v1/assets?id=fox&fps={fps}", server.url()))
            .bearer_auth(TOKEN)
            .header("content-type", "model/gltf-binary")
            .body(glb.clone())
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 400, "fps={fps}");
        let body: Value = r.json().await.unwrap();
        assert!(body["detail"].as_str().unwrap().contains("fps"), "{body}");
    }
    // In range, but more frames than the server takes: the job fails naming the limit, before
    // sampling the animation, and stores nothing.
    let (_, last) = upload(&http, &server.url(), "id=fox&fps=240", "model/gltf-binary", glb.clone()).await;
    assert_eq!(last["state"], "failed", "{last}");
    let message = last["message"].as_str().unwrap();
    assert!(message.contains("max_frames") && message.contains("240 frames per second"), "{message}");
    assert_eq!(last["frames_total"], Value::Null, "refused before sampling: {last}");
    assert!(!dir.path().join("fox.pmc").exists());
    assert!(leftovers(dir.path()).is_empty());
    // The same file at a rate within the cap is encoded.
    let (_, last) = upload(&http, &server.url(), "id=fox&fps=2&animation=Walk", "model/gltf-binary", glb).await;
    assert_eq!(last["state"], "succeeded", "{last}");
    server.stop().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_uploads_and_requests_fail_cleanly_and_leave_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let server = local_server(dir.path()).await;
    let base = server.url();
    let http = reqwest::Client::new();
    let post = |query: &str, ctype: &str, body: Vec<u8>, token: Option<&str>| {
        let mut r = http.post(format!("{base}/v1/assets?{query}")).header("content-type", ctype).body(body);
        if let Some(t) = token {
            r = r.bearer_auth(t);
        }
        r.send()
    };
    let frames = obj_frames("horse-gallop", 2);

    // No token, a wrong token.
    let r = post("id=a", "application/zip", zip_of(&frames), None).await.unwrap();
    assert_eq!(r.status(), 401);
    let r = post("id=a", "application/zip", zip_of(&frames), Some("nope")).await.unwrap();
    assert_eq!(r.status(), 401);
    // Refused before its body is read, a large upload still gets the answer (the server
    // drains the body) rather than a connection reset while the client is still writing.
    for _ in 0..10 {
        let r = post("id=a", "application/zip", vec![0u8; 12 << 20], None).await.expect("an answer, not a reset");
        assert_eq!(r.status(), 401);
        let r = post("id=..", "application/zip", vec![0u8; 12 << 20], Some(TOKEN)).await.expect("an answer, not a reset");
        assert_eq!(r.status(), 400);
    }
    // A client that asks `Expect: 100-continue` is answered without sending its body (the
    // drain waits up to 2 s for a body; this answer must come well before that).
    let mut s = std::net::TcpStream::connect(server.addr).unwrap();
    s.set_read_timeout(Some(Duration::from_millis(1500))).unwrap();
    write!(s, "POST /v1/assets?id=a HTTP/1.1\r\nHost: x\r\nContent-Type: application/zip\r\nContent-Length: 100000000\r\nExpect: 100-continue\r\n\r\n").unwrap();
    let mut buf = [0u8; 256];
    let n = s.read(&mut buf).expect("an answer before the body is sent");
    assert!(String::from_utf8_lossy(&buf[..n]).starts_with("HTTP/1.1 401"), "{}", String::from_utf8_lossy(&buf[..n]));
    drop(s);
    // Ids that try to leave the store's folder, or name nothing.
    for id in ["..%2F..%2Fetc%2Fpasswd", "%2Ftmp%2Fx", ".hidden", "A", ""] {
        let r = post(&format!("id={id}"), "application/zip", zip_of(&frames), Some(TOKEN)).await.unwrap();
        assert_eq!(r.status(), 400, "id {id:?}");
        let body: Value = r.json().await.unwrap();
        assert!(body["detail"].as_str().unwrap().contains("id"), "{body}");
    }
    // A body that is not a zip though it says so; a type we do not take.
    let r = post("id=a", "application/zip", b"PK\x03\x04 truncated".to_vec(), Some(TOKEN)).await.unwrap();
    let s = r.status().as_u16();
    let body: Value = r.json().await.unwrap();
    if s == 202 {
        let job = wait_job(&http, &base, &body).await;
        assert_eq!(job["state"], "failed");
    } else {
        assert_eq!(s, 400, "{body}");
    }
    let r = post("id=a", "text/html", b"<html>".to_vec(), Some(TOKEN)).await.unwrap();
    assert_eq!(r.status(), 415);
    // Frames that do not match: the job fails naming the frame, and nothing is stored.
    let mut mixed = frames.clone();
    mixed.push(("horse-gallop-99.obj".into(), std::fs::read(data("cat-poses").join(first_obj("cat-poses"))).unwrap()));
    let (_, last) = upload(&http, &base, "id=mixed", "application/zip", zip_of(&mixed)).await;
    assert_eq!(last["state"], "failed");
    let message = last["message"].as_str().unwrap();
    assert!(message.contains("horse-gallop-99.obj") || message.contains("frame 2"), "{message}");
    // A zip without OBJ files.
    let (_, last) = upload(&http, &base, "id=empty", "application/zip", zip_of(&[("readme.txt".into(), b"hi".to_vec())])).await;
    assert_eq!(last["state"], "failed");
    assert!(last["message"].as_str().unwrap().to_lowercase().contains("obj"), "{last}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "nothing is left in the store");
    // An asset that appears while a job without replace=true encodes (as an upload through
    // another server sharing the store would) is kept, and the job fails saying so. The file
    // is written right after the 202; the job's parse and encode take far longer.
    let r = post("id=dup", "application/zip", zip_of(&obj_frames("horse-gallop", 10)), Some(TOKEN)).await.unwrap();
    assert_eq!(r.status(), 202);
    let job: Value = r.json().await.unwrap();
    std::fs::write(dir.path().join("dup.pmc"), b"another server's asset").unwrap();
    let last = wait_job(&http, &base, &job).await;
    assert_eq!(last["state"], "failed", "{last}");
    assert!(last["message"].as_str().unwrap().contains("replace=true"), "{last}");
    assert_eq!(std::fs::read(dir.path().join("dup.pmc")).unwrap(), b"another server's asset");
    std::fs::remove_file(dir.path().join("dup.pmc")).unwrap();
    let r = http.get(format!("{base}/v1/assets/mixed")).send().await.unwrap();
    assert_eq!(r.status(), 404);
    server.stop().await.unwrap();
}

fn first_obj(dir: &str) -> String {
    obj_frames(dir, 1).remove(0).0
}

async fn wait_job(http: &reqwest::Client, base: &str, job: &Value) -> Value {
    for _ in 0..600 {
        let s: Value = http.get(format!("{base}{}", job["status_url"].as_str().unwrap())).send().await.unwrap().json().await.unwrap();
        if s["state"] == "succeeded" || s["state"] == "failed" {
            return s;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    panic!("job {job} did not finish");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cut_off_and_unsatisfiable_range_requests_leave_the_server_serving() {
    let config = Config { store: StoreConfig::Samples, listen: "127.0.0.1:0".parse().unwrap(), ..Default::default() };
    let server = pmcodec_server::start(config).await.unwrap();
    let base = server.url();
    let http = reqwest::Client::new();
    let info: Value = http.get(format!("{base}/v1/assets/waving-cloth")).send().await.unwrap().json().await.unwrap();
    let file = info["file"].as_str().unwrap().to_string();
    let len = info["bytes"].as_u64().unwrap();
    // Ask for the whole file and hang up after a few bytes, many times over.
    for _ in 0..20 {
        let mut s = std::net::TcpStream::connect(server.addr).unwrap();
        write!(s, "GET {file} HTTP/1.1\r\nHost: x\r\nRange: bytes=0-{}\r\n\r\n", len - 1).unwrap();
        let mut buf = [0u8; 256];
        let n = s.read(&mut buf).unwrap();
        assert!(String::from_utf8_lossy(&buf[..n]).starts_with("HTTP/1.1 206"));
        drop(s);
    }
    for range in [format!("bytes={len}-"), format!("bytes={len}-,-0")] {
        let r = http.get(format!("{base}{file}")).header("range", &range).send().await.unwrap();
        assert_eq!(r.status(), 416, "{range}");
        assert_eq!(r.headers()["content-range"], format!("bytes */{len}").as_str());
    }
    // An invalid range (last before first) is ignored: the whole file.
    let r = http.get(format!("{base}{file}")).header("range", "bytes=5-2").send().await.unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(r.bytes().await.unwrap().len() as u64, len);
    let r = http.get(format!("{base}{file}")).header("range", "bytes=100-199").send().await.unwrap();
    assert_eq!(r.status(), 206);
    assert_eq!(r.bytes().await.unwrap().len(), 100);
    assert_eq!(http.get(format!("{base}/readyz")).send().await.unwrap().status(), 200);
}

/// s3s-fs (an S3-compatible server that checks request signatures), served in this process on
/// a free port over a temporary folder: the s3s and s3s-fs crates are dev-dependencies, built
/// with the tests, so no server is installed first (a `cargo install` of it was 4 of CI's minutes).
struct S3Server {
    port: u16,
    task: tokio::task::JoinHandle<()>,
    _root: tempfile::TempDir,
}

impl Drop for S3Server {
    fn drop(&mut self) {
        self.task.abort();
    }
}

async fn s3s_fs() -> S3Server {
    use hyper_util::rt::{TokioExecutor, TokioIo};
    let root = tempfile::tempdir().unwrap();
    std::fs::create_dir(root.path().join("assets")).unwrap();
    let mut service = s3s::service::S3ServiceBuilder::new(s3s_fs::FileSystem::new(root.path()).unwrap());
    service.set_auth(s3s::auth::SimpleAuth::from_single("AKTEST", "SKTEST"));
    let service = service.build();
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let port = listener.local_addr().unwrap().port();
    let task = tokio::spawn(async move {
        let http = hyper_util::server::conn::auto::Builder::new(TokioExecutor::new());
        while let Ok((socket, _)) = listener.accept().await {
            let conn = http.serve_connection(TokioIo::new(socket), service.clone()).into_owned();
            tokio::spawn(async move {
                let _ = conn.await;
            });
        }
    });
    S3Server { port, task, _root: root }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_servers_share_one_s3_bucket() {
    let s3 = s3s_fs().await;
    let s3_config = S3Config {
        bucket: "assets".into(),
        endpoint: Some(format!("http://127.0.0.1:{}", s3.port)),
        region: Some("us-east-1".into()),
        prefix: "pmc/".into(),
        access_key_id: Some(Secret("AKTEST".into())),
        secret_access_key: Some(Secret("SKTEST".into())),
        allow_http: true,
    };
    let config = || {
        let mut c = Config { store: StoreConfig::S3(s3_config.clone()), listen: "127.0.0.1:0".parse().unwrap(), ..Default::default() };
        c.auth.write_token = Some(Secret(TOKEN.into()));
        c
    };
    let a = pmcodec_server::start(config()).await.unwrap();
    let b = pmcodec_server::start(config()).await.unwrap();
    let http = reqwest::Client::new();
    assert_eq!(http.get(format!("{}/readyz", a.url())).send().await.unwrap().status(), 200);

    let frames = obj_frames("cat-poses", 3);
    let (_, last) = upload(&http, &a.url(), "id=cat", "application/zip", zip_of(&frames)).await;
    assert_eq!(last["state"], "succeeded", "{last}");
    // Server b never saw the upload; it reads the bucket, where server a left the listing
    // metadata with the asset (so a cold server lists it without reading the container).
    let list: Value = http.get(format!("{}/v1/assets", b.url())).send().await.unwrap().json().await.unwrap();
    assert_eq!(list["assets"][0]["id"], "cat", "{list}");
    use pmcodec_server::{AssetId, AssetStore, PutMode, StoreError};
    let store = pmcodec_server::store::S3Store::new(&s3_config).unwrap();
    let cat = AssetId::parse("cat").unwrap();
    let meta: Value = serde_json::from_slice(&store.get_meta(&cat).await.unwrap().expect("cat.meta.json")).unwrap();
    assert_eq!(meta["tag"].as_str(), Some(store.head(&cat).await.unwrap().unwrap().tag.as_str()));
    assert_eq!(meta["info"]["id"], "cat", "{meta}");
    let c = pmcodec_server::start(config()).await.unwrap();
    let list_c: Value = http.get(format!("{}/v1/assets", c.url())).send().await.unwrap().json().await.unwrap();
    assert_eq!(list_c, list);
    let ia: Value = http.get(format!("{}/v1/assets/cat", a.url())).send().await.unwrap().json().await.unwrap();
    let ib: Value = http.get(format!("{}/v1/assets/cat", b.url())).send().await.unwrap().json().await.unwrap();
    assert_eq!(ia["version"], ib["version"]);
    let ma = Client::new(&a.url()).unwrap().mesh("cat", 2, CutTarget::Triangles(500)).await.unwrap();
    let mb = Client::new(&b.url()).unwrap().mesh("cat", 2, CutTarget::Triangles(500)).await.unwrap();
    assert_eq!(ma, mb);
    let r = http.get(format!("{}{}", b.url(), ib["file"].as_str().unwrap())).header("range", "bytes=0-3").send().await.unwrap();
    assert_eq!(r.status(), 206);
    assert_eq!(&r.bytes().await.unwrap()[..], b"\x89PMC".as_slice());

    let r = http.delete(format!("{}/v1/assets/cat", b.url())).bearer_auth(TOKEN).send().await.unwrap();
    assert_eq!(r.status(), 204);
    let list: Value = http.get(format!("{}/v1/assets", a.url())).send().await.unwrap().json().await.unwrap();
    assert_eq!(list["assets"].as_array().unwrap().len(), 0, "{list}");
    assert!(store.get_meta(&cat).await.unwrap().is_none(), "the metadata went with the asset");

    // Create-only writes straight to the bucket: s3s-fs honours `If-None-Match: *`, so a second
    // create of one key is refused and leaves the first object's bytes.
    let dog = AssetId::parse("dog").unwrap();
    store.put(&dog, b"first".to_vec().into(), PutMode::Create).await.unwrap();
    let r = store.put(&dog, b"second".to_vec().into(), PutMode::Create).await;
    assert!(matches!(r, Err(StoreError::AlreadyExists(_))), "{r:?}");
    assert_eq!(&store.get(&dog).await.unwrap().unwrap().1[..], b"first");
}

/// Reads from a raw socket until the server closes it; `true` when it did within `within`
/// (anything it sends first, such as a 408 answer, is read and dropped).
fn closed_by_server(s: &mut std::net::TcpStream, within: Duration) -> bool {
    let deadline = std::time::Instant::now() + within;
    let mut buf = [0u8; 1024];
    loop {
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        if left.is_zero() {
            return false;
        }
        s.set_read_timeout(Some(left)).unwrap();
        match s.read(&mut buf) {
            Ok(0) => return true,
            Ok(_) => continue,
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => return false,
            // A reset is a close too.
            Err(_) => return true,
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn slow_and_idle_connections_are_closed_and_connections_are_capped() {
    let mut config = Config { store: StoreConfig::Memory, listen: "127.0.0.1:0".parse().unwrap(), ..Default::default() };
    config.limits.header_read_timeout_secs = 2;
    config.limits.idle_timeout_secs = 3;
    config.limits.max_connections = 3;
    let server = pmcodec_server::start(config).await.unwrap();
    let addr = server.addr;
    tokio::task::spawn_blocking(move || {
        // A request head trickled a byte at a time (slow loris) is cut off by the header-read
        // timeout, though bytes keep arriving.
        let mut loris = std::net::TcpStream::connect(addr).unwrap();
        let start = std::time::Instant::now();
        let mut cut = false;
        for b in b"GET /healthz HTTP/1.1\r\nHost: x\r\nX-Slow: ".iter().chain([b'a'; 200].iter()) {
            if loris.write_all(&[*b]).is_err() {
                cut = true;
                break;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        assert!(cut || closed_by_server(&mut loris, Duration::from_secs(5)), "a trickled header is cut off");
        assert!(start.elapsed() < Duration::from_secs(15), "cut off after {:?}", start.elapsed());

        // A keep-alive connection left idle after its answer is closed.
        let mut idle = std::net::TcpStream::connect(addr).unwrap();
        write!(idle, "GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
        let mut buf = [0u8; 256];
        let n = idle.read(&mut buf).unwrap();
        assert!(String::from_utf8_lossy(&buf[..n]).starts_with("HTTP/1.1 200"));
        assert!(closed_by_server(&mut idle, Duration::from_secs(10)), "an idle keep-alive connection is closed");

        // Three connections fill the cap; a fourth is not served while they are open, and is
        // once the idle ones are closed.
        let held: Vec<_> = (0..3)
            .map(|_| {
                let mut s = std::net::TcpStream::connect(addr).unwrap();
                write!(s, "GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
                let n = s.read(&mut buf).unwrap();
                assert!(String::from_utf8_lossy(&buf[..n]).starts_with("HTTP/1.1 200"));
                s
            })
            .collect();
        let mut fourth = std::net::TcpStream::connect(addr).unwrap();
        write!(fourth, "GET /healthz HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n").unwrap();
        fourth.set_read_timeout(Some(Duration::from_millis(700))).unwrap();
        assert!(fourth.read(&mut buf).is_err(), "a connection beyond the cap was served");
        fourth.set_read_timeout(Some(Duration::from_secs(15))).unwrap();
        let n = fourth.read(&mut buf).expect("served once the idle connections are closed");
        assert!(String::from_utf8_lossy(&buf[..n]).starts_with("HTTP/1.1 200"), "{}", String::from_utf8_lossy(&buf[..n]));
        drop(held);
    })
    .await
    .unwrap();
    // With many idle sockets open, /healthz still answers (they are closed in time).
    let idle: Vec<_> = (0..8).map(|_| std::net::TcpStream::connect(addr).unwrap()).collect();
    let r = tokio::time::timeout(Duration::from_secs(30), reqwest::get(format!("{}/healthz", server.url())))
        .await
        .expect("healthz answers while idle sockets are open")
        .unwrap();
    assert_eq!(r.status(), 200);
    drop(idle);
    server.stop().await.unwrap();
}
