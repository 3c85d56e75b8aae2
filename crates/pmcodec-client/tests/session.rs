//! The client against a real server on loopback: listing, LOD on demand, a playback session
//! that reads only its bands and yields the same meshes as decoding the whole file, and a
//! banded file (proto/container.md, "Index") read by a coarse client through `/stream` and
//! through the index answer's ranges fetched several to a request.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_client::{Client, parse_bin_mesh};
use pmcodec_container::format::{FLAG_BANDS, FLAGS};
use pmcodec_container::{CutTarget, Decoder, Reader};

async fn server(tag: &str) -> (pmcodec_server::RunningServer, Vec<u8>, std::path::PathBuf) {
    let dir = std::env::temp_dir().join(format!("pmcodec-client-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let seq = pmcodec_mesh::samples::twisting_tube(16, 24, 40);
    // With the banded index, which a session reads in part.
    let opts = pmcodec_container::EncodeOptions { keyframe_interval: 8, chunk_flags: FLAGS | FLAG_BANDS, ..Default::default() };
    let bytes = pmcodec_container::encode(&seq, &opts, |_| {}).unwrap();
    std::fs::write(dir.join("tube.pmc"), &bytes).unwrap();
    let config = pmcodec_server::Config {
        store: pmcodec_server::config::StoreConfig::Local { path: dir.clone() },
        listen: "127.0.0.1:0".parse().unwrap(),
        ..Default::default()
    };
    (pmcodec_server::start(config).await.unwrap(), bytes, dir)
}

#[tokio::test]
async fn playback_matches_local_decoding() {
    let (server, bytes, dir) = server("session").await;
    let client = Client::new(&server.url()).unwrap();
    let assets = client.assets().await.unwrap();
    assert_eq!(assets.len(), 1);
    assert_eq!(assets[0].id, "tube");
    let lod = client.mesh("tube", 3, CutTarget::Triangles(200)).await.unwrap();
    assert!(!lod.triangles.is_empty() && lod.triangles.len() <= 200);
    assert!(client.mesh("nope", 0, CutTarget::Level(0)).await.is_err());

    // A session at a small budget reads only coarse bands.
    let mut session = client.session("tube", 150).await.unwrap();
    assert!(session.level() > 0, "a 150-triangle budget should not need level 0");
    let reader = Reader::open(bytes.as_slice()).unwrap();
    // Of the banded index (proto/container.md, "Index") it fetched the table and its groups only.
    assert_ne!(reader.flags() & FLAG_BANDS, 0);
    assert!(
        session.bytes_downloaded() < 32 + reader.data_start(),
        "{} bytes to open, of {}",
        session.bytes_downloaded(),
        reader.data_start()
    );
    let mut local = Decoder::new(reader.borrowed(), session.level()).unwrap();
    for f in 0..20 {
        let frame = session.frame(f).await.unwrap();
        local.seek(f).unwrap();
        assert_eq!(frame.mesh, local.mesh(CutTarget::Triangles(150)).unwrap(), "frame {f}");
        assert!(frame.mesh.triangles.len() <= 150);
    }
    assert!(session.bytes_downloaded() * 2 < bytes.len() as u64, "{} of {}", session.bytes_downloaded(), bytes.len());
    // Raising the budget while playing switches to finer bands.
    let coarse_level = session.level();
    session.set_budget(2000).unwrap();
    assert!(session.level() < coarse_level);
    let frame = session.frame(5).await.unwrap();
    assert!(frame.mesh.triangles.len() > 150 && frame.mesh.triangles.len() <= 2000);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn binary_meshes_are_checked() {
    assert!(parse_bin_mesh(b"nope").is_err());
    let mut b = b"PMCM".to_vec();
    b.extend_from_slice(&1u32.to_le_bytes());
    b.extend_from_slice(&1u32.to_le_bytes());
    b.extend_from_slice(&1u32.to_le_bytes());
    b.extend_from_slice(&[0; 12]);
    b.extend_from_slice(&[0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0]);
    assert!(parse_bin_mesh(&b).unwrap_err().to_string().contains("index out of range"));
}

#[tokio::test]
async fn textured_meshes_come_with_their_appearance() {
    let dir = std::env::temp_dir().join(format!("pmcodec-client-textured-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let seq = pmcodec_mesh::samples::textured_cloth(14, 9, 3, 16);
    let bytes = pmcodec_container::encode(&seq, &Default::default(), |_| {}).unwrap();
    std::fs::write(dir.join("cloth.pmc"), &bytes).unwrap();
    let config = pmcodec_server::Config {
        store: pmcodec_server::config::StoreConfig::Local { path: dir.clone() },
        listen: "127.0.0.1:0".parse().unwrap(),
        ..Default::default()
    };
    let server = pmcodec_server::start(config).await.unwrap();
    let client = Client::new(&server.url()).unwrap();
    let info = client.asset("cloth").await.unwrap();
    let materials = info.appearance.as_ref().unwrap().materials.len();
    let (mesh, app) = client.textured_mesh("cloth", 1, CutTarget::Triangles(90)).await.unwrap();
    assert!(!mesh.triangles.is_empty() && mesh.triangles.len() <= 90);
    assert_eq!(app.uv0.len(), mesh.positions.len());
    assert_eq!(app.colors.len(), mesh.positions.len());
    assert_eq!(app.normals.len(), mesh.positions.len());
    assert_eq!(app.triangle_material.len(), mesh.triangles.len());
    assert!(app.triangle_material.iter().all(|&m| (m as usize) < materials));
    // What the container's own decoder draws for the same cut.
    let reader = Reader::open(bytes.as_slice()).unwrap();
    let mut local = Decoder::new(reader.borrowed(), 0).unwrap();
    local.seek(1).unwrap();
    let (want_mesh, want) = local.textured_mesh(CutTarget::Triangles(90)).unwrap();
    assert_eq!((&mesh.positions, &app.uv0, &app.normals, &app.colors), (&want_mesh.positions, &want.uv0, &want.normals, &want.colors));
    // The plain call still gets layout 2's bare mesh.
    let bare = client.mesh("cloth", 1, CutTarget::Triangles(90)).await.unwrap();
    assert_eq!(bare.triangles.len(), mesh.triangles.len());
    std::fs::remove_dir_all(&dir).ok();
}

#[tokio::test]
async fn a_coarse_client_reads_less_and_decodes_the_same_cut() {
    let (server, bytes, dir) = server("banded").await;
    let client = Client::new(&server.url()).unwrap();
    let full = Reader::open(bytes.as_slice()).unwrap();
    assert_ne!(full.flags() & FLAG_BANDS, 0, "the tube should come out banded");
    let levels = full.header().levels();
    let info = client.asset("tube").await.unwrap();
    let coarse = levels - 2;
    let frames = full.header().frame_count;

    // Through /stream: fewer bytes at a coarser level, and the same meshes.
    let (_, all) = client.stream("tube", 0, 0).await.unwrap();
    let (source, part) = client.stream("tube", coarse, 0).await.unwrap();
    assert!(part < all && all <= bytes.len() as u64, "level {coarse}: {part} bytes, level 0: {all}, file {}", bytes.len());
    let mut mine = Decoder::new(Reader::open_at(&source, coarse).unwrap(), coarse).unwrap();
    let mut theirs = Decoder::new(full.borrowed(), coarse).unwrap();
    for f in 0..frames {
        mine.seek(f).unwrap();
        theirs.seek(f).unwrap();
        for t in [CutTarget::Level(coarse), CutTarget::Triangles(100)] {
            assert_eq!(mine.mesh(t).unwrap(), theirs.mesh(t).unwrap(), "frame {f}");
        }
    }
    // From a later frame, the stream starts at its keyframe.
    let (source, later) = client.stream("tube", coarse, 19).await.unwrap();
    assert!(later < part);
    let mut mine = Decoder::new(Reader::open_at(&source, coarse).unwrap(), coarse).unwrap();
    mine.seek(16).unwrap();
    theirs.seek(16).unwrap();
    assert_eq!(mine.mesh(CutTarget::Level(coarse)).unwrap(), theirs.mesh(CutTarget::Level(coarse)).unwrap());
    assert!(client.stream("tube", levels, 0).await.is_err());

    // Through the index answer: its head and frame ranges, several ranges a request, are the
    // file's bytes, and as many as the stream's.
    let index = client.index("tube", &info.summary.version, coarse).await.unwrap();
    assert!(index.banded && index.level == coarse && index.levels == levels && index.length == bytes.len() as u64);
    let ranges: Vec<_> = index.head.iter().chain(index.frames.iter().flat_map(|f| &f.ranges)).map(|&[o, l]| o..o + l).collect();
    assert!(ranges.len() > pmcodec_client::MAX_RANGES_PER_REQUEST, "{} ranges: one request would do", ranges.len());
    let head: u64 = index.head.iter().map(|r| r[1]).sum();
    assert!(head < full.data_start(), "head of {head} bytes, the whole one {}", full.data_start());
    let (got, downloaded) = client.range(&info.summary.file, &ranges).await.unwrap();
    for (r, b) in ranges.iter().zip(&got) {
        assert_eq!(b.as_slice(), &bytes[r.start as usize..r.end as usize], "{r:?}");
    }
    assert_eq!(got.iter().map(|b| b.len() as u64).sum::<u64>(), part);
    // Multipart framing costs a little, never the whole file.
    assert!(downloaded >= part && downloaded < bytes.len() as u64, "{downloaded} bytes downloaded for {part}");

    // A session at a budget that level serves reads fewer bytes than the file and matches.
    let budget = info.triangles_per_level[coarse] as u32;
    let mut session = client.session("tube", budget).await.unwrap();
    assert_eq!(session.level(), coarse);
    for f in 0..frames {
        let frame = session.frame(f).await.unwrap();
        theirs.seek(f).unwrap();
        assert_eq!(frame.mesh, theirs.mesh(CutTarget::Triangles(budget)).unwrap(), "frame {f}");
    }
    assert!(session.bytes_downloaded() < all, "session {} bytes, full stream {all}", session.bytes_downloaded());
    server.stop().await.unwrap();
    std::fs::remove_dir_all(dir).ok();
}

/// A server on loopback that answers every request with `head` and then `body_chunks` chunks
/// of 64 KiB (as many as it can write before the client hangs up); returns its URL.
async fn hostile_server(head: &'static str, body_chunks: usize) -> String {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let url = format!("http://{}", listener.local_addr().unwrap());
    tokio::spawn(async move {
        while let Ok((mut sock, _)) = listener.accept().await {
            tokio::spawn(async move {
                let mut req = [0u8; 4096];
                let _ = sock.read(&mut req).await;
                if sock.write_all(head.as_bytes()).await.is_err() {
                    return;
                }
                let chunk = vec![b'x'; 1 << 16];
                for _ in 0..body_chunks {
                    // Chunked transfer coding when the head says so, else raw bytes.
                    let framed = if head.contains("chunked") {
                        [format!("{:x}\r\n", chunk.len()).into_bytes(), chunk.clone(), b"\r\n".to_vec()].concat()
                    } else {
                        chunk.clone()
                    };
                    if sock.write_all(&framed).await.is_err() {
                        return;
                    }
                }
            });
        }
    });
    url
}

/// Answers larger than the client allows are refused, whether the server declares their
/// length (refused before reading) or streams without one (refused once past the limit), and
/// a range answer may not exceed what was asked.
#[tokio::test]
async fn answers_over_the_limit_are_refused() {
    let limit = 1 << 20;
    // An endless chunked body: refused after the limit, long before the 64 MiB it would send.
    let url = hostile_server("HTTP/1.1 200 OK\r\nContent-Type: application/octet-stream\r\nTransfer-Encoding: chunked\r\n\r\n", 1024).await;
    let client = Client::new(&url).unwrap().with_answer_limit(limit);
    let t = std::time::Instant::now();
    let e = client.mesh("a", 0, CutTarget::Triangles(10)).await.unwrap_err().to_string();
    assert!(e.contains("over the 1048576 this request allows"), "{e}");
    assert!(t.elapsed().as_secs() < 20, "{:?}", t.elapsed());
    let e = client.assets().await.unwrap_err().to_string();
    assert!(e.contains("over the 1048576"), "{e}");
    // A declared length over the limit: refused from the head.
    let url = hostile_server("HTTP/1.1 200 OK\r\nContent-Length: 1000000000000\r\n\r\n", 1).await;
    let client = Client::new(&url).unwrap().with_answer_limit(limit);
    let e = client.mesh("a", 0, CutTarget::Level(0)).await.unwrap_err().to_string();
    assert!(e.contains("1000000000000 bytes"), "{e}");
    // A 206 to ten bytes that goes on: refused past the ranges and their framing.
    let url = hostile_server("HTTP/1.1 206 Partial Content\r\nContent-Range: bytes 0-9/100\r\nTransfer-Encoding: chunked\r\n\r\n", 4).await;
    let client = Client::new(&url).unwrap();
    let e = client.range("/f", std::slice::from_ref(&(0..10))).await.unwrap_err().to_string();
    assert!(e.contains("over the"), "{e}");
    // An error answer's endless body: its first bytes kept as the detail, the rest not read.
    let url = hostile_server("HTTP/1.1 500 Internal Server Error\r\nTransfer-Encoding: chunked\r\n\r\n", 1024).await;
    match Client::new(&url).unwrap().asset("a").await.unwrap_err() {
        pmcodec_client::ClientError::Status { status, detail, .. } => {
            assert!(status == 500 && detail.len() <= 64 << 10 && detail.starts_with("xxx"))
        }
        e => panic!("{e}"),
    }
}
