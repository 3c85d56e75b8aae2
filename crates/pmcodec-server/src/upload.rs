//! Upload bodies: a zip of OBJ frames, multipart OBJ files, or a GLB. Reading the body and
//! telling the kinds apart happens in the request (bad bodies get 4xx at once); parsing the
//! meshes happens in the encode job (bad meshes fail the job with the parser's message).

use crate::ApiError;
use axum::body::Body;
use axum::http::{HeaderMap, header};
use bytes::Bytes;
use pmcodec_mesh::gltf_input::{AnimationSelector, GltfOptions, load_gltf_bytes};
use pmcodec_mesh::obj::{natural_cmp, parse_obj_with};
use pmcodec_mesh::{InputLimits, Sequence};
use std::path::Path;

/// An upload, read and classified but not yet parsed.
pub enum UploadBody {
    /// A zip archive holding one `.obj` per frame.
    Zip(Bytes),
    /// OBJ files by name (multipart parts).
    Objs(Vec<(String, Bytes)>),
    /// A binary glTF with an animation (or a single pose).
    Glb(Bytes),
}

/// How to turn an upload into a sequence.
#[derive(Clone, Debug)]
pub struct UploadOptions {
    pub frame_rate: f32,
    pub animation: Option<AnimationSelector>,
    /// Largest total of unpacked zip members.
    pub unpacked_limit: u64,
    /// Whether the job may replace an asset of the same id that exists when it stores.
    pub replace: bool,
    /// Vertices, triangles and frames the meshes may hold, checked while they are parsed.
    pub input_limits: InputLimits,
}

/// Parts of a multipart upload beyond this are refused (frames of one sequence).
const MAX_PARTS: usize = 100_000;

impl UploadBody {
    pub fn describe(&self) -> String {
        match self {
            UploadBody::Zip(b) => format!("zip, {} bytes", b.len()),
            UploadBody::Objs(f) => format!("{} OBJ files, {} bytes", f.len(), f.iter().map(|(_, b)| b.len()).sum::<usize>()),
            UploadBody::Glb(b) => format!("GLB, {} bytes", b.len()),
        }
    }

    /// Reads and classifies a request body: by content type, and for bodies sent as plain
    /// octets, by their magic number.
    pub async fn read(headers: &HeaderMap, body: Body, limit: u64) -> Result<UploadBody, ApiError> {
        if let Some(len) = headers.get(header::CONTENT_LENGTH).and_then(|v| v.to_str().ok()).and_then(|v| v.parse::<u64>().ok())
            && len > limit
        {
            return Err(ApiError::PayloadTooLarge { limit });
        }
        let ctype = headers.get(header::CONTENT_TYPE).and_then(|v| v.to_str().ok()).unwrap_or("").to_string();
        let mime = ctype.split(';').next().unwrap_or("").trim().to_ascii_lowercase();
        let bytes = read_limited(body, limit).await?;
        if bytes.is_empty() {
            return Err(ApiError::BadRequest("the upload is empty".into()));
        }
        match mime.as_str() {
            "multipart/form-data" => read_multipart(&ctype, bytes).await,
            "application/zip" | "application/x-zip-compressed" => classify("upload.zip", bytes, Some(Kind::Zip)),
            "model/gltf-binary" => classify("upload.glb", bytes, Some(Kind::Glb)),
            "application/octet-stream" | "" => classify("the body", bytes, None),
            other => Err(unsupported(other)),
        }
    }

    /// Parses the meshes (CPU work: run on a blocking thread). The error says which file and
    /// line is wrong.
    pub fn into_sequence(self, opts: &UploadOptions) -> Result<Sequence, String> {
        match self {
            UploadBody::Glb(b) => {
                let o = GltfOptions {
                    animation: opts.animation.clone(),
                    frame_rate: opts.frame_rate,
                    limits: opts.input_limits,
                    ..GltfOptions::default()
                };
                load_gltf_bytes(&b, &o).map_err(|e| format!("GLB: {e}"))
            }
            UploadBody::Objs(files) => sequence_from_objs(files, opts.frame_rate, &opts.input_limits),
            UploadBody::Zip(b) => sequence_from_objs(unzip_objs(b, opts.unpacked_limit)?, opts.frame_rate, &opts.input_limits),
        }
    }
}

#[derive(Clone, Copy, PartialEq)]
enum Kind {
    Zip,
    Glb,
}

fn unsupported(what: &str) -> ApiError {
    ApiError::UnsupportedMediaType(format!(
        "{what}: upload application/zip (OBJ frames), multipart/form-data with .obj files, or model/gltf-binary"
    ))
}

/// Checks that the bytes are what the content type or file name says, by magic number.
fn classify(name: &str, bytes: Bytes, declared: Option<Kind>) -> Result<UploadBody, ApiError> {
    let sniffed = if bytes.starts_with(b"PK\x03\x04") {
        Some(Kind::Zip)
    } else if bytes.starts_with(b"glTF") {
        Some(Kind::Glb)
    } else {
        None
    };
    match (declared, sniffed) {
        (Some(d), Some(s)) if d == s => {}
        (None, Some(_)) => {}
        (Some(Kind::Zip), _) => return Err(ApiError::BadRequest(format!("{name} is not a zip archive"))),
        (Some(Kind::Glb), _) => return Err(ApiError::BadRequest(format!("{name} is not a binary glTF (no glTF magic)"))),
        (None, None) => return Err(unsupported(&format!("{name} is neither a zip nor a GLB"))),
    }
    Ok(match sniffed {
        Some(Kind::Zip) => UploadBody::Zip(bytes),
        _ => UploadBody::Glb(bytes),
    })
}

/// Bytes of an upload refused before it was read that are still read (and dropped) before the
/// answer goes out, and for how long at most.
const DRAIN_BYTES: usize = 16 << 20;
const DRAIN_TIME: std::time::Duration = std::time::Duration::from_secs(2);

/// Reads and drops a refused upload's body, up to [`DRAIN_BYTES`] or [`DRAIN_TIME`]. An
/// HTTP/1.1 client writes its whole body before it reads the answer; a server that answers and
/// closes with the body unread resets the connection, and the client sees a broken pipe instead
/// of the 401 or 400 that says what is wrong (RFC 9112 section 9.6). A longer body still gets
/// the reset: reading it all would let anyone without a token make the server take any size.
pub async fn drain(body: Body) {
    use http_body_util::BodyExt;
    let mut body = http_body_util::Limited::new(body, DRAIN_BYTES);
    let _ = tokio::time::timeout(DRAIN_TIME, async move { while let Some(Ok(_)) = body.frame().await {} }).await;
}

async fn read_limited(body: Body, limit: u64) -> Result<Bytes, ApiError> {
    use http_body_util::BodyExt;
    let limited = http_body_util::Limited::new(body, usize::try_from(limit).unwrap_or(usize::MAX));
    match limited.collect().await {
        Ok(c) => Ok(c.to_bytes()),
        Err(e) if e.is::<http_body_util::LengthLimitError>() => Err(ApiError::PayloadTooLarge { limit }),
        Err(e) => Err(ApiError::BadRequest(format!("reading the upload: {e}"))),
    }
}

async fn read_multipart(ctype: &str, bytes: Bytes) -> Result<UploadBody, ApiError> {
    let boundary = multer::parse_boundary(ctype).map_err(|e| ApiError::BadRequest(format!("multipart: {e}")))?;
    let stream = futures_util::stream::once(async move { Ok::<Bytes, std::convert::Infallible>(bytes) });
    let mut mp = multer::Multipart::new(stream, boundary);
    let mut objs = Vec::new();
    let mut single = None;
    // Bounded: each part consumes body bytes, and the body is bounded.
    while let Some(field) = mp.next_field().await.map_err(|e| ApiError::BadRequest(format!("multipart: {e}")))? {
        let Some(name) = field.file_name().map(str::to_string) else {
            // Form fields without a file are not part of the mesh.
            continue;
        };
        let data = field.bytes().await.map_err(|e| ApiError::BadRequest(format!("multipart part {name}: {e}")))?;
        let lower = name.to_ascii_lowercase();
        if lower.ends_with(".obj") {
            objs.push((name, data));
            if objs.len() > MAX_PARTS {
                return Err(ApiError::BadRequest(format!("more than {MAX_PARTS} files")));
            }
        } else if lower.ends_with(".zip") || lower.ends_with(".glb") {
            if single.is_some() {
                return Err(ApiError::BadRequest("send one .zip or .glb per upload".into()));
            }
            let kind = if lower.ends_with(".zip") { Kind::Zip } else { Kind::Glb };
            single = Some(classify(&name, data, Some(kind))?);
        } else {
            return Err(unsupported(&format!("part {name:?}")));
        }
    }
    match (single, objs.is_empty()) {
        (Some(_), false) => Err(ApiError::BadRequest("send either .obj files or one .zip/.glb, not both".into())),
        (Some(s), true) => Ok(s),
        (None, false) => Ok(UploadBody::Objs(objs)),
        (None, true) => Err(ApiError::BadRequest("the multipart upload has no .obj, .zip or .glb file".into())),
    }
}

/// The `.obj` members of a zip, with a bound on what they unpack to (zip bombs).
fn unzip_objs(bytes: Bytes, limit: u64) -> Result<Vec<(String, Bytes)>, String> {
    use std::io::Read;
    let mut zip = zip::ZipArchive::new(std::io::Cursor::new(bytes)).map_err(|e| format!("zip: {e}"))?;
    let mut out = Vec::new();
    let mut total: u64 = 0;
    for i in 0..zip.len() {
        let mut f = zip.by_index(i).map_err(|e| format!("zip member {i}: {e}"))?;
        let name = f.name().map_err(|e| format!("zip member {i}: {e}"))?.to_string();
        let base = name.rsplit('/').next().unwrap_or("");
        // Folders, resource forks and hidden files are not frames.
        if f.is_dir() || name.contains("__MACOSX/") || base.starts_with('.') || !base.to_ascii_lowercase().ends_with(".obj") {
            continue;
        }
        let room = limit.saturating_sub(total);
        let mut buf = Vec::new();
        // Read one byte past the room: the declared size in the archive cannot be trusted.
        (&mut f).take(room + 1).read_to_end(&mut buf).map_err(|e| format!("zip member {name}: {e}"))?;
        if buf.len() as u64 > room {
            return Err(format!("the zip unpacks to more than {limit} bytes"));
        }
        total += buf.len() as u64;
        out.push((name, Bytes::from(buf)));
    }
    Ok(out)
}

/// Frames in natural name order, each the same mesh with other positions.
fn sequence_from_objs(mut files: Vec<(String, Bytes)>, frame_rate: f32, limits: &InputLimits) -> Result<Sequence, String> {
    if files.is_empty() {
        return Err("the upload holds no .obj files".into());
    }
    let frames = files.len();
    limits.check_frames(frames, "the upload").map_err(|e| e.to_string())?;
    files.sort_by(|a, b| natural_cmp(&a.0, &b.0));
    let mut seq = Sequence { frame_rate, ..Default::default() };
    for (name, data) in files {
        let text = std::str::from_utf8(&data).map_err(|e| format!("{name}: not UTF-8 text ({e})"))?;
        let frame = parse_obj_with(text, Path::new(&name), limits, frames).map_err(|e| e.to_string())?;
        if seq.frames.is_empty() {
            seq.triangles = frame.triangles;
        } else {
            if frame.positions.len() != seq.frames[0].len() {
                return Err(format!("{name}: {} vertices where the first frame has {}", frame.positions.len(), seq.frames[0].len()));
            }
            if frame.triangles != seq.triangles {
                let t = frame
                    .triangles
                    .iter()
                    .zip(&seq.triangles)
                    .position(|(a, b)| a != b)
                    .unwrap_or(seq.triangles.len().min(frame.triangles.len()));
                return Err(format!("{name}: face {t} differs from the first frame's (every frame must have the same faces)"));
            }
        }
        seq.frames.push(frame.positions);
        seq.frame_names.push(name);
    }
    seq.validate().map_err(|e| e.to_string())?;
    Ok(seq)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obj(dx: f32) -> Bytes {
        Bytes::from(format!("v {dx} 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n"))
    }

    #[test]
    fn frames_sort_naturally_and_must_match() {
        let files = vec![("f10.obj".into(), obj(0.3)), ("f2.obj".into(), obj(0.2)), ("f1.obj".into(), obj(0.1))];
        let seq = sequence_from_objs(files, 24.0, &InputLimits::default()).unwrap();
        assert_eq!(seq.frame_names, ["f1.obj", "f2.obj", "f10.obj"]);
        assert_eq!(seq.frames[2][0].x, 0.3);
        let bad = vec![("a.obj".into(), obj(0.0)), ("b.obj".into(), Bytes::from_static(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"))];
        assert!(sequence_from_objs(bad, 24.0, &InputLimits::default()).unwrap_err().contains("b.obj"));
        let broken = vec![("a.obj".into(), Bytes::from_static(b"v 0 0 zero\n"))];
        assert!(sequence_from_objs(broken, 24.0, &InputLimits::default()).unwrap_err().contains("a.obj:1"));
    }

    #[test]
    fn zip_bombs_are_bounded() {
        use std::io::Write;
        let mut buf = std::io::Cursor::new(Vec::new());
        {
            let mut z = zip::ZipWriter::new(&mut buf);
            let o = zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
            z.start_file("big.obj", o).unwrap();
            z.write_all(&vec![b'#'; 100_000]).unwrap();
            z.finish().unwrap();
        }
        let bytes = Bytes::from(buf.into_inner());
        assert!(bytes.len() < 10_000);
        assert!(unzip_objs(bytes.clone(), 50_000).unwrap_err().contains("more than 50000"));
        assert_eq!(unzip_objs(bytes, 200_000).unwrap()[0].1.len(), 100_000);
    }

    #[test]
    fn magic_numbers_decide_octet_bodies() {
        assert!(matches!(classify("b", Bytes::from_static(b"PK\x03\x04rest"), None), Ok(UploadBody::Zip(_))));
        assert!(matches!(classify("b", Bytes::from_static(b"glTFrest"), None), Ok(UploadBody::Glb(_))));
        assert!(matches!(classify("b", Bytes::from_static(b"hello"), None), Err(ApiError::UnsupportedMediaType(_))));
        assert!(matches!(classify("b", Bytes::from_static(b"glTF"), Some(Kind::Zip)), Err(ApiError::BadRequest(_))));
    }
}
