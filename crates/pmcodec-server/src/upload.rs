//! Upload bodies: a zip of OBJ frames, multipart OBJ files, or a GLB. Reading the body and
//! telling the kinds apart happens in the request (bad bodies get 4xx at once); parsing the
//! meshes happens in the encode job (bad meshes fail the job with the parser's message).
//!
//! A body is written to a temporary file as it arrives, never held in memory: a queued job
//! holds a file, not its bytes, and the file is removed when the job is dropped (it ends,
//! fails or is cancelled).

use crate::ApiError;
use axum::body::Body;
use axum::http::{HeaderMap, header};
use bytes::Bytes;
use pmcodec_mesh::gltf_input::{AnimationSelector, GltfOptions, list_animations_bytes, load_gltf_bytes};
use pmcodec_mesh::obj::{frame_appearance, natural_cmp, parse_obj_appearance, parse_obj_with};
use pmcodec_mesh::{InputLimits, Sequence};
use std::ops::Range;
use std::path::Path;
use tokio::io::AsyncWriteExt;

/// An upload, read into a temporary file and classified but not yet parsed.
pub struct UploadBody {
    kind: Kind,
    /// Removed when dropped.
    file: tempfile::NamedTempFile,
    /// The files of the upload: the whole body, or each multipart part, as byte ranges of
    /// `file`.
    parts: Vec<(String, Range<u64>)>,
    bytes: u64,
}

/// How to turn an upload into a sequence.
#[derive(Clone, Debug)]
pub struct UploadOptions {
    pub frame_rate: f32,
    pub animation: Option<AnimationSelector>,
    /// Largest total of unpacked zip members.
    pub unpacked_limit: u64,
    /// Most frames the sequence may have.
    pub max_frames: u32,
    /// Whether the job may replace an asset of the same id that exists when it stores.
    pub replace: bool,
    /// Vertices, triangles and frames the meshes may hold, checked while they are parsed.
    pub input_limits: InputLimits,
}

/// Where and how much an upload may write.
pub struct BodyLimits<'a> {
    /// Largest body.
    pub bytes: u64,
    /// Most OBJ files (frames) in a multipart body.
    pub files: usize,
    /// The folder of the temporary file.
    pub dir: &'a Path,
}

/// Bytes buffered between the body and its temporary file.
const WRITE_BUFFER: usize = 256 << 10;

impl UploadBody {
    pub fn describe(&self) -> String {
        match self.kind {
            Kind::Zip => format!("zip, {} bytes", self.bytes),
            Kind::Objs => format!("{} OBJ files, {} bytes", self.parts.len(), self.bytes),
            Kind::Glb => format!("GLB, {} bytes", self.bytes),
        }
    }

    /// Reads a request body into a temporary file and classifies it: by content type, and for
    /// bodies sent as plain octets, by their magic number.
    pub async fn read(headers: &HeaderMap, body: Body, limits: &BodyLimits<'_>) -> Result<UploadBody, ApiError> {
        let limit = limits.bytes;
        if let Some(len) = headers.get(header::CONTENT_LENGTH).and_then(|v| v.to_str().ok()).and_then(|v| v.parse::<u64>().ok())
            && len > limit
        {
            return Err(ApiError::PayloadTooLarge { limit });
        }
        let ctype = headers.get(header::CONTENT_TYPE).and_then(|v| v.to_str().ok()).unwrap_or("").to_string();
        let mime = ctype.split(';').next().unwrap_or("").trim().to_ascii_lowercase();
        let declared = match mime.as_str() {
            "multipart/form-data" => None,
            "application/zip" | "application/x-zip-compressed" => Some(Some(Kind::Zip)),
            "model/gltf-binary" => Some(Some(Kind::Glb)),
            "application/octet-stream" | "" => Some(None),
            other => return Err(unsupported(other)),
        };
        let mut spill = Spill::new(limits.dir).await?;
        let upload = match declared {
            None => read_multipart(&ctype, body, limits, &mut spill).await?,
            Some(declared) => {
                let name = match declared {
                    Some(Kind::Zip) => "upload.zip",
                    Some(_) => "upload.glb",
                    None => "the body",
                };
                let range = spill.copy(body_stream(body), limit).await.map_err(|e| e.into_api(limit))?;
                if range.is_empty() {
                    return Err(ApiError::BadRequest("the upload is empty".into()));
                }
                let kind = classify(name, &spill.head, declared)?;
                (kind, vec![(name.to_string(), range)])
            }
        };
        spill.finish(upload.0, upload.1).await
    }

    /// Parses the meshes (CPU work: run on a blocking thread). The error says which file and
    /// line is wrong.
    pub fn into_sequence(self, opts: &UploadOptions) -> Result<Sequence, String> {
        let all = Bytes::from(std::fs::read(self.file.path()).map_err(|e| format!("reading the upload back: {e}"))?);
        let slice = |r: &Range<u64>| all.slice(r.start as usize..r.end as usize);
        let seq = match self.kind {
            Kind::Glb => {
                let b = self.parts.first().map(|(_, r)| slice(r)).unwrap_or_default();
                check_animation_frames(&b, opts)?;
                let o = GltfOptions {
                    animation: opts.animation.clone(),
                    frame_rate: opts.frame_rate,
                    limits: opts.input_limits,
                    ..GltfOptions::default()
                };
                load_gltf_bytes(&b, &o).map_err(|e| format!("GLB: {e}"))?
            }
            Kind::Objs => {
                let files: Vec<_> = self.parts.iter().map(|(n, r)| (n.clone(), slice(r))).collect();
                sequence_from_objs(files, &[], opts.frame_rate, opts.max_frames, &opts.input_limits)?
            }
            Kind::Zip => {
                let b = self.parts.first().map(|(_, r)| slice(r)).unwrap_or_default();
                let (objs, resources) = unzip_objs(b, opts.unpacked_limit, opts.max_frames)?;
                sequence_from_objs(objs, &resources, opts.frame_rate, opts.max_frames, &opts.input_limits)?
            }
        };
        // Whatever the path above, the cap holds for what is encoded.
        if seq.frame_count() > opts.max_frames as usize {
            return Err(too_many_frames(seq.frame_count(), opts.max_frames));
        }
        Ok(seq)
    }
}

fn too_many_frames(n: usize, max: u32) -> String {
    format!("{n} frames: more than this server's limit of {max} frames per asset (limits.max_frames)")
}

/// Refuses an animation that would sample to more frames than allowed before sampling it
/// (a 72 KB GLB at a high frame rate is otherwise tens of thousands of poses to build and
/// encode). A file whose animations cannot be listed is left to the loader to report.
fn check_animation_frames(glb: &[u8], opts: &UploadOptions) -> Result<(), String> {
    let Ok(animations) = list_animations_bytes(glb) else {
        return Ok(());
    };
    let chosen = match &opts.animation {
        None => animations.first(),
        Some(AnimationSelector::Index(i)) => animations.iter().find(|a| a.index == *i),
        Some(AnimationSelector::Name(n)) => animations.iter().find(|a| a.name.as_deref() == Some(n.as_str())),
    };
    let Some(a) = chosen else {
        return Ok(());
    };
    // The loader's own frame count: floor(duration * rate) + 1, in f32.
    let last = (a.duration.max(0.0) * opts.frame_rate).floor();
    if !(last.is_finite() && last < opts.max_frames as f32) {
        let what = a.name.as_deref().map_or_else(|| format!("#{}", a.index), |n| format!("{n:?}"));
        return Err(format!(
            "animation {what} lasts {:.3} s: at {} frames per second that is {} frames, more than this server's limit of {} \
             frames per asset (limits.max_frames); upload with a lower fps",
            a.duration,
            opts.frame_rate,
            if last.is_finite() { format!("{}", last as u64 + 1) } else { "too many".into() },
            opts.max_frames
        ));
    }
    Ok(())
}

#[derive(Clone, Copy, PartialEq, Debug)]
enum Kind {
    Zip,
    Glb,
    Objs,
}

fn unsupported(what: &str) -> ApiError {
    ApiError::UnsupportedMediaType(format!(
        "{what}: upload application/zip (OBJ frames), multipart/form-data with .obj files, or model/gltf-binary"
    ))
}

/// Checks that the first bytes are what the content type or file name says, by magic number.
fn classify(name: &str, head: &[u8], declared: Option<Kind>) -> Result<Kind, ApiError> {
    let sniffed = if head.starts_with(b"PK\x03\x04") {
        Some(Kind::Zip)
    } else if head.starts_with(b"glTF") {
        Some(Kind::Glb)
    } else {
        None
    };
    match (declared, sniffed) {
        (Some(d), Some(s)) if d == s => Ok(s),
        (None, Some(s)) => Ok(s),
        (Some(Kind::Zip), _) => Err(ApiError::BadRequest(format!("{name} is not a zip archive"))),
        (Some(_), _) => Err(ApiError::BadRequest(format!("{name} is not a binary glTF (no glTF magic)"))),
        (None, None) => Err(unsupported(&format!("{name} is neither a zip nor a GLB"))),
    }
}

/// Why copying a body into the temporary file stopped.
enum CopyError {
    TooLarge,
    Body(String),
    Write(std::io::Error),
}

impl CopyError {
    fn into_api(self, limit: u64) -> ApiError {
        match self {
            CopyError::TooLarge => ApiError::PayloadTooLarge { limit },
            CopyError::Body(e) => ApiError::BadRequest(format!("reading the upload: {e}")),
            CopyError::Write(e) => {
                tracing::error!(error = %e, "writing an upload to its temporary file failed");
                ApiError::Internal("the upload could not be written to a temporary file".into())
            }
        }
    }
}

/// The temporary file an upload is written to, with the first bytes of the part being
/// written (for the magic number).
struct Spill {
    file: tempfile::NamedTempFile,
    out: tokio::io::BufWriter<tokio::fs::File>,
    written: u64,
    head: Vec<u8>,
}

fn temp_file_error(e: std::io::Error) -> ApiError {
    tracing::error!(error = %e, "creating a temporary file for an upload failed");
    ApiError::Internal("the upload could not be written to a temporary file".into())
}

impl Spill {
    async fn new(dir: &Path) -> Result<Spill, ApiError> {
        let file = tempfile::Builder::new().prefix("pmcodec-upload-").suffix(".part").tempfile_in(dir).map_err(temp_file_error)?;
        let handle = file.as_file().try_clone().map_err(temp_file_error)?;
        let out = tokio::io::BufWriter::with_capacity(WRITE_BUFFER, tokio::fs::File::from_std(handle));
        Ok(Spill { file, out, written: 0, head: Vec::new() })
    }

    /// Appends a stream of chunks as one part; the total over all parts is at most `limit`.
    async fn copy<S, E>(&mut self, mut chunks: S, limit: u64) -> Result<Range<u64>, CopyError>
    where
        S: futures_util::Stream<Item = Result<Bytes, E>> + Unpin,
        E: std::fmt::Display,
    {
        use futures_util::StreamExt;
        let start = self.written;
        self.head.clear();
        while let Some(chunk) = chunks.next().await {
            let chunk = chunk.map_err(|e| CopyError::Body(e.to_string()))?;
            self.written += chunk.len() as u64;
            if self.written > limit {
                return Err(CopyError::TooLarge);
            }
            if self.head.len() < 4 {
                let take = (4 - self.head.len()).min(chunk.len());
                self.head.extend_from_slice(&chunk[..take]);
            }
            self.out.write_all(&chunk).await.map_err(CopyError::Write)?;
        }
        Ok(start..self.written)
    }

    async fn finish(mut self, kind: Kind, parts: Vec<(String, Range<u64>)>) -> Result<UploadBody, ApiError> {
        self.out.flush().await.map_err(|e| CopyError::Write(e).into_api(0))?;
        Ok(UploadBody { kind, file: self.file, parts, bytes: self.written })
    }
}

fn body_stream(body: Body) -> impl futures_util::Stream<Item = Result<Bytes, axum::Error>> + Unpin {
    body.into_data_stream()
}

async fn read_multipart(
    ctype: &str,
    body: Body,
    limits: &BodyLimits<'_>,
    spill: &mut Spill,
) -> Result<(Kind, Vec<(String, Range<u64>)>), ApiError> {
    use futures_util::StreamExt;
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
    let limit = limits.bytes;
    let boundary = multer::parse_boundary(ctype).map_err(|e| ApiError::BadRequest(format!("multipart: {e}")))?;
    // The body's bytes are counted as they arrive (parts' framing included), so that a body
    // over the limit stops being read at the limit.
    let over = Arc::new(AtomicBool::new(false));
    let seen = Arc::new(AtomicU64::new(0));
    let (over_in, seen_in) = (over.clone(), seen.clone());
    let stream = body.into_data_stream().map(move |chunk| {
        let chunk = chunk.map_err(std::io::Error::other)?;
        if seen_in.fetch_add(chunk.len() as u64, Ordering::Relaxed) + chunk.len() as u64 > limit {
            over_in.store(true, Ordering::Relaxed);
            return Err(std::io::Error::other("the body is over the limit"));
        }
        Ok(chunk)
    });
    let mut mp = multer::Multipart::new(stream, boundary);
    let mp_err = |e: multer::Error, what: &str| {
        if over.load(Ordering::Relaxed) {
            ApiError::PayloadTooLarge { limit }
        } else {
            ApiError::BadRequest(format!("multipart{what}: {e}"))
        }
    };
    let mut objs = Vec::new();
    let mut single: Option<(Kind, (String, Range<u64>))> = None;
    // Bounded: each part consumes body bytes, and the body is bounded.
    while let Some(field) = mp.next_field().await.map_err(|e| mp_err(e, ""))? {
        let Some(name) = field.file_name().map(str::to_string) else {
            // Form fields without a file are not part of the mesh.
            continue;
        };
        let lower = name.to_ascii_lowercase();
        let kind = if lower.ends_with(".obj") {
            Kind::Objs
        } else if lower.ends_with(".zip") {
            Kind::Zip
        } else if lower.ends_with(".glb") {
            Kind::Glb
        } else {
            return Err(unsupported(&format!("part {name:?}")));
        };
        if kind != Kind::Objs && single.is_some() {
            return Err(ApiError::BadRequest("send one .zip or .glb per upload".into()));
        }
        let range = match spill.copy(Box::pin(field), limit).await {
            Ok(r) => r,
            Err(CopyError::Body(_)) if over.load(Ordering::Relaxed) => return Err(ApiError::PayloadTooLarge { limit }),
            Err(CopyError::Body(e)) => return Err(ApiError::BadRequest(format!("multipart part {name}: {e}"))),
            Err(e) => return Err(e.into_api(limit)),
        };
        if kind == Kind::Objs {
            objs.push((name, range));
            if objs.len() > limits.files {
                return Err(ApiError::BadRequest(format!(
                    "more than {} .obj files: more frames than this server takes per asset (limits.max_frames)",
                    limits.files
                )));
            }
        } else {
            classify(&name, &spill.head, Some(kind))?;
            single = Some((kind, (name, range)));
        }
    }
    match (single, objs.is_empty()) {
        (Some(_), false) => Err(ApiError::BadRequest("send either .obj files or one .zip/.glb, not both".into())),
        (Some((kind, part)), true) => Ok((kind, vec![part])),
        (None, false) => Ok((Kind::Objs, objs)),
        (None, true) => Err(ApiError::BadRequest("the multipart upload has no .obj, .zip or .glb file".into())),
    }
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

/// Members of an OBJ upload that are not frames but what the first frame's materials name:
/// material libraries and the images they map.
const RESOURCE_SUFFIXES: [&str; 4] = [".mtl", ".png", ".jpg", ".jpeg"];

/// The `.obj` members of a zip, and its material libraries and images (the first frame's
/// `mtllib` and `map_Kd` files), with a bound on what they all unpack to (zip bombs).
type Members = Vec<(String, Bytes)>;
fn unzip_objs(bytes: Bytes, limit: u64, max_frames: u32) -> Result<(Members, Members), String> {
    use std::io::Read;
    let mut zip = zip::ZipArchive::new(std::io::Cursor::new(bytes)).map_err(|e| format!("zip: {e}"))?;
    let mut out = Vec::new();
    let mut resources = Vec::new();
    let mut total: u64 = 0;
    for i in 0..zip.len() {
        let mut f = zip.by_index(i).map_err(|e| format!("zip member {i}: {e}"))?;
        let name = f.name().map_err(|e| format!("zip member {i}: {e}"))?.to_string();
        let base = name.rsplit('/').next().unwrap_or("");
        let lower = base.to_ascii_lowercase();
        // Folders, resource forks and hidden files are neither frames nor their materials.
        if f.is_dir() || name.contains("__MACOSX/") || base.starts_with('.') {
            continue;
        }
        let resource = RESOURCE_SUFFIXES.iter().any(|s| lower.ends_with(s));
        if !resource && !lower.ends_with(".obj") {
            continue;
        }
        if !resource && out.len() >= max_frames as usize {
            return Err(format!(
                "the zip holds more than {max_frames} .obj files: more frames than this server's limit per asset (limits.max_frames)"
            ));
        }
        let room = limit.saturating_sub(total);
        let mut buf = Vec::new();
        // Read one byte past the room: the declared size in the archive cannot be trusted.
        (&mut f).take(room + 1).read_to_end(&mut buf).map_err(|e| format!("zip member {name}: {e}"))?;
        if buf.len() as u64 > room {
            return Err(format!("the zip unpacks to more than {limit} bytes"));
        }
        total += buf.len() as u64;
        if resource {
            resources.push((name, Bytes::from(buf)));
        } else {
            out.push((name, Bytes::from(buf)));
        }
    }
    Ok((out, resources))
}

/// A zip member's name as a relative path below a folder: `None` for a name that could reach
/// out of it (absolute, `..`, a drive or a backslash), which is then not unpacked.
fn member_path(name: &str) -> Option<std::path::PathBuf> {
    let path = Path::new(name);
    let plain = path.components().all(|c| matches!(c, std::path::Component::Normal(_)));
    (plain && !name.contains('\\') && !name.contains(':')).then(|| path.to_path_buf())
}

/// The first frame's appearance (texture coordinates, normals, materials and their images):
/// its material libraries and images are unpacked into a folder of their own beside where the
/// frame's name puts it, and read from there as the CLI reads them beside an OBJ file. Errors
/// name the member and line, not the folder.
fn upload_appearance(
    first: &pmcodec_mesh::obj::ObjFrame,
    name: &str,
    resources: &[(String, Bytes)],
) -> Result<Option<pmcodec_mesh::Appearance>, String> {
    // A frame that names no material library reads no file: nothing to unpack (most uploads).
    if first.attributes.libraries.is_empty() {
        return frame_appearance(first, Path::new(name), Path::new(name)).map_err(|e| e.to_string());
    }
    let dir = tempfile::tempdir().map_err(|e| format!("unpacking the upload's materials: {e}"))?;
    for (member, bytes) in resources {
        let Some(rel) = member_path(member) else { continue };
        let path = dir.path().join(rel);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(|e| format!("unpacking {member}: {e}"))?;
        }
        std::fs::write(&path, bytes).map_err(|e| format!("unpacking {member}: {e}"))?;
    }
    let frame_path = member_path(name).map_or_else(|| dir.path().join("frame.obj"), |p| dir.path().join(p));
    let prefix = format!("{}/", dir.path().display());
    frame_appearance(first, &frame_path, dir.path()).map_err(|e| e.to_string().replace(&prefix, ""))
}

/// Frames in natural name order, each the same mesh with other positions; the first frame's
/// appearance (`vt`, `vn`, `usemtl` with the libraries and images in `resources`).
fn sequence_from_objs(
    mut files: Vec<(String, Bytes)>,
    resources: &[(String, Bytes)],
    frame_rate: f32,
    max_frames: u32,
    limits: &InputLimits,
) -> Result<Sequence, String> {
    if files.is_empty() {
        return Err("the upload holds no .obj files".into());
    }
    if files.len() > max_frames as usize {
        return Err(too_many_frames(files.len(), max_frames));
    }
    let frames = files.len();
    limits.check_frames(frames, "the upload").map_err(|e| e.to_string())?;
    files.sort_by(|a, b| natural_cmp(&a.0, &b.0));
    let mut seq = Sequence { frame_rate, ..Default::default() };
    for (name, data) in files {
        let text = std::str::from_utf8(&data).map_err(|e| format!("{name}: not UTF-8 text ({e})"))?;
        let first = seq.frames.is_empty();
        let parse = if first { parse_obj_appearance } else { parse_obj_with };
        let frame = parse(text, Path::new(&name), limits, frames).map_err(|e| e.to_string())?;
        if first {
            seq.appearance = upload_appearance(&frame, &name, resources)?;
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
        let seq = sequence_from_objs(files.clone(), &[], 24.0, 3, &InputLimits::default()).unwrap();
        assert_eq!(seq.frame_names, ["f1.obj", "f2.obj", "f10.obj"]);
        assert_eq!(seq.frames[2][0].x, 0.3);
        assert!(sequence_from_objs(files, &[], 24.0, 2, &InputLimits::default()).unwrap_err().contains("limit of 2 frames"));
        let bad = vec![("a.obj".into(), obj(0.0)), ("b.obj".into(), Bytes::from_static(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"))];
        assert!(sequence_from_objs(bad, &[], 24.0, 10, &InputLimits::default()).unwrap_err().contains("b.obj"));
        let broken = vec![("a.obj".into(), Bytes::from_static(b"v 0 0 zero\n"))];
        assert!(sequence_from_objs(broken, &[], 24.0, 10, &InputLimits::default()).unwrap_err().contains("a.obj:1"));
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
        assert!(unzip_objs(bytes.clone(), 50_000, 10).unwrap_err().contains("more than 50000"));
        assert_eq!(unzip_objs(bytes.clone(), 200_000, 10).unwrap().0[0].1.len(), 100_000);
        assert!(unzip_objs(bytes, 200_000, 0).unwrap_err().contains("more than 0"));
    }

    /// A zip of `members` (name, bytes), stored.
    fn zip_of(members: &[(&str, &[u8])]) -> Bytes {
        use std::io::Write;
        let mut buf = std::io::Cursor::new(Vec::new());
        {
            let mut z = zip::ZipWriter::new(&mut buf);
            for (name, bytes) in members {
                z.start_file(*name, zip::write::SimpleFileOptions::default()).unwrap();
                z.write_all(bytes).unwrap();
            }
            z.finish().unwrap();
        }
        Bytes::from(buf.into_inner())
    }

    const TEXTURED: &str = "mtllib looks/quad.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\nusemtl skin\nf 1/1 2/2 3/3\nusemtl plain\nf 2/2 4/4 3/3\n";

    #[test]
    fn zipped_frames_keep_the_first_frames_materials_and_images() {
        let png = pmcodec_mesh::samples::textured_cloth(4, 4, 1, 8).appearance.unwrap().images[0].bytes.clone();
        let mtl = b"newmtl skin\nKd 1 0.5 0.2\nmap_Kd ../maps/skin.png\nnewmtl plain\nKd 0.2 0.2 0.9\n";
        let second = TEXTURED.replace("v 1 1 0", "v 1 1 0.5");
        let bytes = zip_of(&[
            ("seq/f1.obj", TEXTURED.as_bytes()),
            ("seq/f2.obj", second.as_bytes()),
            ("seq/looks/quad.mtl", mtl),
            ("seq/maps/skin.png", &png),
            ("../evil.png", &png),
        ]);
        let (objs, resources) = unzip_objs(bytes, 1 << 20, 10).unwrap();
        assert_eq!(objs.len(), 2);
        assert_eq!(resources.len(), 3, "the library and both images (the one reaching out is not unpacked)");
        let seq = sequence_from_objs(objs, &resources, 24.0, 10, &InputLimits::default()).unwrap();
        let app = seq.appearance.expect("an appearance");
        assert_eq!(app.materials.len(), 2);
        assert_eq!(app.images.len(), 1);
        assert_eq!(app.images[0].bytes, png);
        assert_eq!(app.triangle_material, [0, 1]);
        assert!(app.materials[0].base_color_texture.is_some() && app.materials[1].base_color_texture.is_none());
        assert_eq!(seq.frames.len(), 2);
    }

    #[test]
    fn a_missing_library_or_image_is_named_without_the_unpacking_folder() {
        let mtl = b"newmtl skin\nmap_Kd skin.png\nnewmtl plain\n";
        let bytes = zip_of(&[("f1.obj", TEXTURED.as_bytes()), ("looks/quad.mtl", mtl)]);
        let (objs, resources) = unzip_objs(bytes, 1 << 20, 10).unwrap();
        let e = sequence_from_objs(objs, &resources, 24.0, 10, &InputLimits::default()).unwrap_err();
        assert!(e.contains("looks/quad.mtl") && e.contains("skin.png"), "{e}");
        assert!(!e.contains("/tmp"), "{e}");
        let bytes = zip_of(&[("f1.obj", TEXTURED.as_bytes())]);
        let (objs, resources) = unzip_objs(bytes, 1 << 20, 10).unwrap();
        let e = sequence_from_objs(objs, &resources, 24.0, 10, &InputLimits::default()).unwrap_err();
        assert!(e.contains("quad.mtl"), "{e}");
        // A library naming a file outside the upload is refused, not read.
        for (lib, map) in
            [("../../../../../etc/hostname", "x.png"), ("quad.mtl", "/etc/hostname"), ("quad.mtl", "../../../../etc/hostname")]
        {
            let obj = TEXTURED.replace("looks/quad.mtl", lib);
            let mtl = format!("newmtl skin\nmap_Kd {map}\nnewmtl plain\n");
            let bytes = zip_of(&[("f1.obj", obj.as_bytes()), ("quad.mtl", mtl.as_bytes())]);
            let (objs, resources) = unzip_objs(bytes, 1 << 20, 10).unwrap();
            let e = sequence_from_objs(objs, &resources, 24.0, 10, &InputLimits::default()).unwrap_err();
            assert!(e.contains("outside the upload"), "{lib} {map}: {e}");
        }
        assert!(member_path("../x.png").is_none() && member_path("/etc/x.png").is_none() && member_path("a/b.png").is_some());
    }

    #[test]
    fn magic_numbers_decide_octet_bodies() {
        assert!(matches!(classify("b", b"PK\x03\x04", None), Ok(Kind::Zip)));
        assert!(matches!(classify("b", b"glTF", None), Ok(Kind::Glb)));
        assert!(matches!(classify("b", b"hell", None), Err(ApiError::UnsupportedMediaType(_))));
        assert!(matches!(classify("b", b"glTF", Some(Kind::Zip)), Err(ApiError::BadRequest(_))));
        assert!(matches!(classify("b", b"PK\x03\x04", Some(Kind::Glb)), Err(ApiError::BadRequest(_))));
    }
}
