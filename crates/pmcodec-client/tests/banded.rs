//! A banded file (proto/container.md, "Index") over a real socket: a client at a coarse level
//! reads fewer bytes, through `/stream` and through the index answer's ranges fetched several to
//! a request, and decodes exactly the cut that reading the whole file gives.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_client::Client;
use pmcodec_container::format::{FLAG_BANDS, FLAGS};
use pmcodec_container::{CutTarget, Decoder, Reader};

async fn server() -> (pmcodec_server::RunningServer, Vec<u8>, std::path::PathBuf) {
    let dir = std::env::temp_dir().join(format!("pmcodec-client-banded-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let seq = pmcodec_mesh::samples::twisting_tube(16, 24, 40);
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
async fn a_coarse_client_reads_less_and_decodes_the_same_cut() {
    let (server, bytes, dir) = server().await;
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
