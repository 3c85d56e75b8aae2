//! What a client of one level reads (`pmcodec_container::streams`): the head and frame ranges a
//! server sends under `/stream`, placed back at their offsets by `stream_source`, decode every
//! frame from the start frame on exactly as the whole file does, in fewer bytes the coarser the
//! level; and a reader opened for one level serves no other.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use pmcodec_container::format::{FLAG_BANDS, FLAGS, Preamble};
use pmcodec_container::streams::{first_read, frame_ranges, head_ranges, stream_source};
use pmcodec_container::{CutTarget, Decoder, DerivedTopology, EncodeOptions, QuantizationChoice, Reader, encode};

fn file(flags: u16, derived: DerivedTopology) -> Vec<u8> {
    let opts = EncodeOptions {
        build: pmcodec_hierarchy::BuildOptions { min_coarsest: 4, ..EncodeOptions::default().build },
        keyframe_interval: 4,
        quantization: QuantizationChoice::Bits(12),
        derived_topology: derived,
        chunk_flags: flags,
        ..Default::default()
    };
    encode(&pmcodec_mesh::samples::waving_cloth(20, 16, 30), &opts, |_| {}).expect("encode")
}

/// The body a server's `/stream?level=L&from=F` sends: the head ranges, then each frame's.
fn stream(bytes: &[u8], level: usize, from: u32) -> Vec<u8> {
    let full = Reader::open(bytes).unwrap();
    let mut body = Vec::new();
    for r in head_ranges(bytes, level).unwrap() {
        body.extend_from_slice(&bytes[r.start as usize..r.end as usize]);
    }
    for r in frame_ranges(&full.index().chunks, full.header(), full.data_start(), level, from).into_iter().flatten() {
        body.extend_from_slice(&bytes[r.start as usize..r.end as usize]);
    }
    body
}

#[test]
fn a_levels_stream_decodes_as_the_whole_file_in_fewer_bytes() {
    let mut banded = 0;
    for (flags, derived) in
        [(FLAGS | FLAG_BANDS, DerivedTopology::Always), (FLAGS | FLAG_BANDS, DerivedTopology::Never), (FLAGS, DerivedTopology::Never)]
    {
        let bytes = file(flags, derived);
        let pre = Preamble::parse(&bytes[..32]).unwrap();
        assert!(first_read(&pre).end as usize <= bytes.len());
        let full = Reader::open(bytes.as_slice()).unwrap();
        let levels = full.header().levels();
        assert!(levels >= 3, "{levels} levels");
        let mut last = usize::MAX;
        for level in 0..levels {
            for from in [0, 9] {
                let body = stream(&bytes, level, from);
                let source = stream_source(&body, level, from).expect("stream source");
                assert_eq!(source.held(), body.len() as u64);
                let mut mine = Decoder::new(Reader::open_at(&source, level).unwrap(), level).expect("decoder");
                let mut theirs = Decoder::new(full.borrowed(), level).unwrap();
                for f in from..full.header().frame_count {
                    mine.seek(f).unwrap_or_else(|e| panic!("flags {flags} level {level} from {from} frame {f}: {e}"));
                    theirs.seek(f).unwrap();
                    for t in [CutTarget::Level(level), CutTarget::Triangles(60)] {
                        assert_eq!(mine.mesh(t).unwrap(), theirs.mesh(t).unwrap(), "flags {flags} level {level} frame {f}");
                    }
                }
                if from == 0 {
                    // Coarser levels read fewer bytes.
                    assert!(body.len() < last, "flags {flags} level {level}: {} bytes, {last} at the finer level", body.len());
                    last = body.len();
                }
            }
            // Cut off, or with a byte more, the stream is refused.
            let body = stream(&bytes, level, 0);
            assert!(stream_source(&body[..body.len() - 1], level, 0).is_err());
            let mut longer = body.clone();
            longer.push(0);
            assert!(stream_source(&longer, level, 0).is_err());
        }
        if pmcodec_container::streams::is_banded(&pre) {
            banded += 1;
            // A reader opened for a level lacks the faces of the coarser bands: it serves no other level.
            for level in 0..levels {
                for other in (0..levels).filter(|&o| o != level) {
                    assert!(Decoder::new(Reader::open_at(bytes.as_slice(), level).unwrap(), other).is_err(), "{level} for {other}");
                }
            }
        }
    }
    // (The encoder writes the banded index only where it is no longer than the plain one.)
    assert!(banded >= 1, "no input came out banded");
}
