//! OBJ sequences: one OBJ file per frame, all with the same vertices and faces.
//!
//! Every frame's `v` and `f` records give the positions and the (shared) faces. The first
//! frame's `vt`, `vn`, `mtllib` and `usemtl` records, when present, also give the sequence's
//! [`crate::Appearance`] (see `obj::appearance`): texture coordinates, normals and materials are
//! the same in every frame, so later frames' are not read. Groups and smoothing groups are
//! ignored. Polygons are triangulated as fans, which is exact for the convex quads and n-gons
//! that deforming-mesh exporters write.

mod appearance;
mod mtl;

use crate::{InputLimits, MeshError, Sequence};
use glam::Vec3;
use std::path::{Path, PathBuf};

/// "No index": a corner without `vt` or `vn`, a face before any `usemtl`.
pub const NONE: u32 = u32::MAX;

/// One parsed OBJ file.
#[derive(Clone, Debug, Default)]
pub struct ObjFrame {
    /// Vertex positions (`v` lines), in file order.
    pub positions: Vec<Vec3>,
    /// Triangles (`f` lines, polygons fan-triangulated), 0-based indices into `positions`.
    pub triangles: Vec<[u32; 3]>,
    /// Appearance records, read only when asked for ([`parse_obj_appearance`],
    /// [`read_obj_appearance_with`]); empty otherwise.
    pub attributes: ObjAttributes,
}

/// The raw appearance records of one OBJ file, as written (resolved into wedges by
/// `appearance::build`).
#[derive(Clone, Debug, Default)]
pub struct ObjAttributes {
    /// `vt` records (u, v; a third coordinate is ignored).
    pub texcoords: Vec<[f32; 2]>,
    /// `vn` records.
    pub normals: Vec<[f32; 3]>,
    /// Per triangle, per corner: (`vt` index, `vn` index), 0-based, [`NONE`] when absent.
    pub corners: Vec<[[u32; 2]; 3]>,
    /// Per triangle: index into `material_names` of the `usemtl` in force, or [`NONE`].
    pub triangle_material: Vec<u32>,
    /// Names given to `usemtl`, in order of first use, with the line of that use.
    pub material_names: Vec<(String, usize)>,
    /// `mtllib` file names, as written, with their line.
    pub libraries: Vec<(String, usize)>,
}

/// Parses the text of one OBJ file, a sequence of one frame under the default
/// [`InputLimits`]. `path` is only used to name the file in errors.
pub fn parse_obj(text: &str, path: &Path) -> Result<ObjFrame, MeshError> {
    parse_obj_with(text, path, &InputLimits::default(), 1)
}

/// Parses the text of one OBJ file, one of `frames` frames of a sequence: the parser stops at
/// the first vertex or triangle past `limits` (the vertex limit shared out over the frames),
/// before it takes the memory, and the error names the file and line.
pub fn parse_obj_with(text: &str, path: &Path, limits: &InputLimits, frames: usize) -> Result<ObjFrame, MeshError> {
    parse_text(text, path, limits, frames, false)
}

/// [`parse_obj_with`], also reading the appearance records (`vt`, `vn`, `mtllib`, `usemtl`)
/// into [`ObjFrame::attributes`] and checking their indices.
pub fn parse_obj_appearance(text: &str, path: &Path, limits: &InputLimits, frames: usize) -> Result<ObjFrame, MeshError> {
    parse_text(text, path, limits, frames, true)
}

/// The appearance of a frame parsed with [`parse_obj_appearance`], as if the file were at `path`:
/// its `mtllib` libraries and their `map_Kd` images are read relative to `path`'s folder (a
/// server unpacks an upload's materials and images there), and only below `root`: a library
/// or image named outside it is refused unread. `None` when the frame has neither texture
/// coordinates, normals nor materials.
pub fn frame_appearance(frame: &ObjFrame, path: &Path, root: &Path) -> Result<Option<crate::Appearance>, MeshError> {
    appearance::build_within(frame, path, Some(root))
}

fn parse_text(text: &str, path: &Path, limits: &InputLimits, frames: usize, attributes: bool) -> Result<ObjFrame, MeshError> {
    let mut parser = ObjParser::new(path, limits, frames, attributes);
    for (i, line) in text.lines().enumerate() {
        parser.line(i + 1, line)?;
    }
    parser.finish()
}

/// Reads one OBJ file as a sequence of one frame under the default [`InputLimits`].
pub fn read_obj(path: &Path) -> Result<ObjFrame, MeshError> {
    read_obj_with(path, &InputLimits::default(), 1)
}

/// Longest line [`read_obj_with`] reads: a file without line breaks must not be read whole.
const MAX_LINE: u64 = 16 << 20;

/// [`parse_obj_with`] over a file, read a line at a time (the text is never all in memory).
pub fn read_obj_with(path: &Path, limits: &InputLimits, frames: usize) -> Result<ObjFrame, MeshError> {
    read_file(path, limits, frames, false)
}

/// [`read_obj_with`], also reading the appearance records, as [`parse_obj_appearance`].
pub fn read_obj_appearance_with(path: &Path, limits: &InputLimits, frames: usize) -> Result<ObjFrame, MeshError> {
    read_file(path, limits, frames, true)
}

fn read_file(path: &Path, limits: &InputLimits, frames: usize, attributes: bool) -> Result<ObjFrame, MeshError> {
    use std::io::{BufRead, Read};
    let io = |error| MeshError::Io { path: path.to_path_buf(), error };
    let mut reader = std::io::BufReader::new(std::fs::File::open(path).map_err(io)?);
    let mut parser = ObjParser::new(path, limits, frames, attributes);
    let mut line = String::new();
    for lineno in 1.. {
        line.clear();
        match (&mut reader).take(MAX_LINE).read_line(&mut line) {
            Ok(0) => break,
            Ok(n) if n as u64 == MAX_LINE && !line.ends_with('\n') => {
                return Err(parser.error(lineno, format!("line longer than {MAX_LINE} bytes")));
            }
            Ok(_) => parser.line(lineno, &line)?,
            Err(e) if e.kind() == std::io::ErrorKind::InvalidData => {
                return Err(parser.error(lineno, "not UTF-8 text".into()));
            }
            Err(e) => return Err(io(e)),
        }
    }
    parser.finish()
}

/// The state of one file's parse: what has been read, the caps, and where the largest face
/// index was seen (an index past the last vertex is only known to be wrong at the end, since
/// OBJ lets faces name vertices defined after them).
struct ObjParser<'a> {
    path: &'a Path,
    limits: &'a InputLimits,
    frames: usize,
    vertex_cap: usize,
    out: ObjFrame,
    polygon: Vec<u32>,
    /// Largest 0-based position index any face used, and the first line that used it.
    max_index: Option<(u32, usize)>,
    /// Whether appearance records are read (the first frame of a sequence).
    attributes: bool,
    /// Per polygon corner: (`vt`, `vn`) indices, parallel to `polygon`.
    polygon_attrs: Vec<[u32; 2]>,
    /// Largest `vt` and `vn` indices used, with their line (checked at the end, as positions).
    max_attr: [Option<(u32, usize)>; 2],
    /// The `usemtl` in force.
    material: u32,
}

impl<'a> ObjParser<'a> {
    fn new(path: &'a Path, limits: &'a InputLimits, frames: usize, attributes: bool) -> Self {
        let vertex_cap = limits.vertices_per_frame(frames);
        ObjParser {
            path,
            limits,
            frames,
            vertex_cap,
            out: ObjFrame::default(),
            polygon: Vec::with_capacity(8),
            max_index: None,
            attributes,
            polygon_attrs: Vec::with_capacity(8),
            max_attr: [None; 2],
            material: NONE,
        }
    }

    fn error(&self, line: usize, message: String) -> MeshError {
        MeshError::Parse { path: self.path.to_path_buf(), line, message }
    }

    fn at(&self, line: usize) -> String {
        format!("{}:{line}", self.path.display())
    }

    fn line(&mut self, lineno: usize, raw: &str) -> Result<(), MeshError> {
        let mut words = raw.split_ascii_whitespace();
        match words.next() {
            Some("v") => {
                if self.out.positions.len() >= self.vertex_cap {
                    return Err(self.limits.too_many_vertices(self.frames, self.vertex_cap, &self.at(lineno)));
                }
                let mut p = [0f32; 3];
                for (axis, slot) in p.iter_mut().enumerate() {
                    let word = words.next().ok_or_else(|| self.error(lineno, format!("vertex has {axis} coordinates, expected 3")))?;
                    *slot = word.parse().map_err(|_| self.error(lineno, format!("vertex coordinate {word:?} is not a number")))?;
                }
                // An optional fourth (w) or vertex colours may follow: ignored.
                self.out.positions.push(Vec3::from_array(p));
            }
            Some("f") => {
                self.polygon.clear();
                self.polygon_attrs.clear();
                for word in words {
                    // `v`, `v/vt`, `v//vn` or `v/vt/vn`. The first '/' found bytewise: a str
                    // pattern search per corner was a twentieth of parsing a frame.
                    let (index, attrs_part) = match word.bytes().position(|b| b == b'/') {
                        Some(s) => (&word[..s], Some(&word[s + 1..])),
                        None => (word, None),
                    };
                    let resolved = self.resolve(lineno, index, word, self.out.positions.len())?;
                    if self.max_index.is_none_or(|(m, _)| resolved > m) {
                        self.max_index = Some((resolved, lineno));
                    }
                    self.polygon.push(resolved);
                    if self.attributes {
                        let mut attrs = [NONE; 2];
                        let counts = [self.out.attributes.texcoords.len(), self.out.attributes.normals.len()];
                        for (k, part) in attrs_part.into_iter().flat_map(|p| p.split('/')).take(2).enumerate() {
                            if !part.is_empty() {
                                let a = self.resolve(lineno, part, word, counts[k])?;
                                if self.max_attr[k].is_none_or(|(m, _)| a > m) {
                                    self.max_attr[k] = Some((a, lineno));
                                }
                                attrs[k] = a;
                            }
                        }
                        self.polygon_attrs.push(attrs);
                    }
                }
                let corners = self.polygon.len();
                if corners < 3 {
                    return Err(self.error(lineno, format!("face has {corners} corners, expected at least 3")));
                }
                if self.out.triangles.len() + (corners - 2) > self.limits.max_triangles {
                    return Err(self.limits.too_many_triangles(&self.at(lineno)));
                }
                let p = &self.polygon;
                self.out.triangles.extend((1..corners - 1).map(|k| [p[0], p[k], p[k + 1]]));
                if self.attributes {
                    let a = &self.polygon_attrs;
                    self.out.attributes.corners.extend((1..corners - 1).map(|k| [a[0], a[k], a[k + 1]]));
                    self.out.attributes.triangle_material.extend((1..corners - 1).map(|_| self.material));
                }
            }
            Some(record @ ("vt" | "vn")) if self.attributes => self.attribute_record(lineno, record, words)?,
            Some("usemtl") if self.attributes => {
                let name = words.collect::<Vec<_>>().join(" ");
                let names = &mut self.out.attributes.material_names;
                self.material = match names.iter().position(|(n, _)| *n == name) {
                    Some(m) => m as u32,
                    None => {
                        names.push((name, lineno));
                        names.len() as u32 - 1
                    }
                };
            }
            Some("mtllib") if self.attributes => {
                // Several libraries may follow on one line; names with spaces are not supported.
                self.out.attributes.libraries.extend(words.map(|w| (w.to_string(), lineno)));
            }
            _ => {}
        }
        Ok(())
    }

    /// A 1-based (or negative, counting back from the latest record) OBJ index into a list of
    /// `count` records, 0-based; whether it is below the final count is checked at the end.
    fn resolve(&self, lineno: usize, index: &str, word: &str, count: usize) -> Result<u32, MeshError> {
        // Plain decimal digits (what exporters write) directly; anything else (a sign, a stray
        // character) through i64's parser, which also words the error.
        let i: i64 = match plain_digits(index) {
            Some(i) => i,
            None => index.parse().map_err(|_| self.error(lineno, format!("face index {word:?} is not an integer")))?,
        };
        let resolved = match i {
            0 => return Err(self.error(lineno, "face index 0 (OBJ indices start at 1)".into())),
            i if i > 0 => i - 1,
            i => count as i64 + i,
        };
        if resolved < 0 || resolved >= u32::MAX as i64 {
            return Err(self.error(lineno, format!("face index {i} is out of range")));
        }
        Ok(resolved as u32)
    }

    /// A `vt` or `vn` record: finite numbers only (a NaN texture coordinate would poison every
    /// coarser node's).
    fn attribute_record<'w>(&mut self, lineno: usize, record: &str, mut words: impl Iterator<Item = &'w str>) -> Result<(), MeshError> {
        let (n, count) = if record == "vt" { (2, self.out.attributes.texcoords.len()) } else { (3, self.out.attributes.normals.len()) };
        if count >= self.vertex_cap.saturating_mul(4) {
            return Err(
                self.error(lineno, format!("more than {} {record} records (four per vertex allowed)", self.vertex_cap.saturating_mul(4)))
            );
        }
        let mut x = [0f32; 3];
        for (axis, slot) in x.iter_mut().enumerate().take(n) {
            // `vt u` alone is legal OBJ (v defaults to 0).
            let Some(word) = words.next() else {
                if record == "vt" && axis == 1 {
                    break;
                }
                return Err(self.error(lineno, format!("{record} has {axis} coordinates, expected {n}")));
            };
            let value: f32 = word.parse().map_err(|_| self.error(lineno, format!("{record} coordinate {word:?} is not a number")))?;
            if !value.is_finite() {
                return Err(self.error(lineno, format!("{record} coordinate {word:?} is not a finite number")));
            }
            *slot = value;
        }
        if record == "vt" {
            self.out.attributes.texcoords.push([x[0], x[1]]);
        } else {
            self.out.attributes.normals.push(x);
        }
        Ok(())
    }

    fn finish(self) -> Result<ObjFrame, MeshError> {
        let n = self.out.positions.len();
        if let Some((i, line)) = self.max_index.filter(|&(i, _)| i as usize >= n) {
            return Err(self.error(line, format!("face uses vertex {} but the file has {n} vertices", i + 1)));
        }
        let counts = [self.out.attributes.texcoords.len(), self.out.attributes.normals.len()];
        for (k, what) in ["texture coordinate (vt)", "normal (vn)"].into_iter().enumerate() {
            if let Some((i, line)) = self.max_attr[k].filter(|&(i, _)| i as usize >= counts[k]) {
                return Err(self.error(line, format!("face uses {what} {} but the file has {}", i + 1, counts[k])));
            }
        }
        Ok(self.out)
    }
}

/// `s` as a number when it is 1 to 18 ASCII digits (below i64's limit whatever they are), the
/// value `str::parse::<i64>` gives it; `None` otherwise.
fn plain_digits(s: &str) -> Option<i64> {
    let b = s.as_bytes();
    if b.is_empty() || b.len() > 18 || !b.iter().all(u8::is_ascii_digit) {
        return None;
    }
    Some(b.iter().fold(0i64, |v, &d| v * 10 + (d - b'0') as i64))
}

/// Resolves the frames of a sequence: a folder (every `.obj` in it), a glob whose last component
/// holds `*` or `?` (`frames/horse-*.obj`), or a single file. Frames come in natural sort order
/// (`f2` before `f10`).
pub fn frame_paths(input: &Path) -> Result<Vec<PathBuf>, MeshError> {
    let text = input.to_string_lossy();
    let name = input.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let mut paths = if name.contains(['*', '?']) {
        let dir = match input.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        if dir.to_string_lossy().contains(['*', '?']) {
            return Err(MeshError::NoInput(format!("{text}: wildcards are only supported in the file name")));
        }
        list_dir(&dir)?.into_iter().filter(|p| p.file_name().is_some_and(|n| wildcard_match(&name, &n.to_string_lossy()))).collect()
    } else if input.is_dir() {
        list_dir(input)?.into_iter().filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj"))).collect()
    } else if input.is_file() {
        vec![input.to_path_buf()]
    } else {
        return Err(MeshError::NoInput(format!("{text} is neither a file, a folder nor a glob")));
    };
    paths.sort_by(|a, b| natural_cmp(&a.to_string_lossy(), &b.to_string_lossy()));
    if paths.is_empty() {
        return Err(MeshError::NoInput(format!("{text} matches no OBJ file")));
    }
    Ok(paths)
}

fn list_dir(dir: &Path) -> Result<Vec<PathBuf>, MeshError> {
    let io = |error| MeshError::Io { path: dir.to_path_buf(), error };
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        if path.is_file() {
            out.push(path);
        }
    }
    Ok(out)
}

/// `*` matches any run of characters, `?` any one character.
pub fn wildcard_match(pattern: &str, name: &str) -> bool {
    let p: Vec<char> = pattern.chars().collect();
    let s: Vec<char> = name.chars().collect();
    // Classic greedy match with backtracking to the last star: linear for typical patterns.
    let (mut pi, mut si) = (0, 0);
    let mut star: Option<(usize, usize)> = None;
    while si < s.len() {
        if pi < p.len() && (p[pi] == '?' || p[pi] == s[si]) {
            pi += 1;
            si += 1;
        } else if pi < p.len() && p[pi] == '*' {
            star = Some((pi, si));
            pi += 1;
        } else if let Some((sp, ss)) = star {
            pi = sp + 1;
            si = ss + 1;
            star = Some((sp, ss + 1));
        } else {
            return false;
        }
    }
    p[pi..].iter().all(|&c| c == '*')
}

/// Natural order: runs of digits compare by value, everything else by character.
pub fn natural_cmp(a: &str, b: &str) -> std::cmp::Ordering {
    use std::cmp::Ordering;
    let (a, b) = (a.as_bytes(), b.as_bytes());
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        if a[i].is_ascii_digit() && b[j].is_ascii_digit() {
            let si = i;
            while i < a.len() && a[i].is_ascii_digit() {
                i += 1;
            }
            let sj = j;
            while j < b.len() && b[j].is_ascii_digit() {
                j += 1;
            }
            // Compare by value without overflow: strip leading zeros, then length, then digits.
            let da = trim_zeros(&a[si..i]);
            let db = trim_zeros(&b[sj..j]);
            let ord = da.len().cmp(&db.len()).then_with(|| da.cmp(db));
            if ord != Ordering::Equal {
                return ord;
            }
        } else {
            let ord = a[i].cmp(&b[j]);
            if ord != Ordering::Equal {
                return ord;
            }
            i += 1;
            j += 1;
        }
    }
    (a.len() - i).cmp(&(b.len() - j))
}

fn trim_zeros(d: &[u8]) -> &[u8] {
    let k = d.iter().position(|&c| c != b'0').unwrap_or(d.len());
    &d[k..]
}

/// Loads an OBJ sequence (folder, glob or single file) as a [`Sequence`]. Every frame must have
/// frame 0's vertex count and faces; the error names the first differing frame and face.
pub fn load_obj_sequence(input: &Path, frame_rate: f32) -> Result<Sequence, MeshError> {
    load_obj_sequence_with(input, frame_rate, &InputLimits::default())
}

/// [`load_obj_sequence`] under the given limits.
pub fn load_obj_sequence_with(input: &Path, frame_rate: f32, limits: &InputLimits) -> Result<Sequence, MeshError> {
    let paths = frame_paths(input)?;
    limits.check_frames(paths.len(), &input.display().to_string())?;
    load_obj_files_with(&paths, frame_rate, limits)
}

/// Loads the given files, in the given order, as the frames of one sequence; the first
/// file's texture coordinates, normals and materials (with their libraries and textures) give
/// its appearance.
pub fn load_obj_files(paths: &[PathBuf], frame_rate: f32) -> Result<Sequence, MeshError> {
    load_obj_files_with(paths, frame_rate, &InputLimits::default())
}

/// [`load_obj_files`] under the given limits: the frame count is checked before any file is
/// read, and each file's vertices and triangles while it is read.
pub fn load_obj_files_with(paths: &[PathBuf], frame_rate: f32, limits: &InputLimits) -> Result<Sequence, MeshError> {
    use rayon::prelude::*;
    let (mut seq, rest) = open_obj_files(paths, frame_rate, limits)?;
    // The files after the first are read in parallel (each on its own), then taken in order:
    // the first bad one's error is the one a reading in order would give.
    let frames: Vec<Result<Vec<Vec3>, MeshError>> = rest.paths.par_iter().rev().map(|p| rest.read(p)).collect();
    seq.frames.reserve(frames.len());
    for frame in frames {
        seq.frames.push(frame?);
    }
    seq.validate()?;
    Ok(seq)
}

/// The first of the given files as a one-frame [`Sequence`] (its triangles, appearance, and
/// every file's name in `frame_names`), and a reader of the frames after it, each checked to
/// have frame 0's vertex count and faces: so that a sequence can be encoded while its later
/// frames are still being read. Nothing past the first file is read until asked for.
pub fn open_obj_files(paths: &[PathBuf], frame_rate: f32, limits: &InputLimits) -> Result<(Sequence, ObjFrames), MeshError> {
    let mut seq = Sequence { frame_rate, ..Default::default() };
    let Some(first) = paths.first() else {
        return Ok((seq, ObjFrames { paths: Vec::new(), limits: *limits, frames: 0, triangles: Vec::new(), vertex_count: 0 }));
    };
    limits.check_frames(paths.len(), &format!("{} and the {} files after it", first.display(), paths.len() - 1))?;
    let frame = read_file(first, limits, paths.len(), true)?;
    seq.appearance = appearance::build(&frame, first)?;
    seq.triangles = frame.triangles;
    let vertex_count = frame.positions.len();
    seq.frames.push(frame.positions);
    seq.frame_names = paths.iter().map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default()).collect();
    let rest = ObjFrames {
        paths: paths[1..].iter().rev().cloned().collect(),
        limits: *limits,
        frames: paths.len(),
        triangles: seq.triangles.clone(),
        vertex_count,
    };
    Ok((seq, rest))
}

/// The frames after the first of an OBJ sequence (see [`open_obj_files`]), read one file per
/// `next`.
#[derive(Debug)]
pub struct ObjFrames {
    /// Files still to read, last first.
    paths: Vec<PathBuf>,
    limits: InputLimits,
    /// Frames in the whole sequence (what the limits are checked against).
    frames: usize,
    triangles: Vec<[u32; 3]>,
    vertex_count: usize,
}

impl ObjFrames {
    fn read(&self, path: &Path) -> Result<Vec<Vec3>, MeshError> {
        let frame = read_file(path, &self.limits, self.frames, false)?;
        let label = || path.display().to_string();
        if frame.positions.len() != self.vertex_count {
            return Err(MeshError::FrameMismatch {
                frame: label(),
                detail: format!("{} vertices where frame 0 has {}", frame.positions.len(), self.vertex_count),
            });
        }
        if frame.triangles.len() != self.triangles.len() {
            return Err(MeshError::FrameMismatch {
                frame: label(),
                detail: format!("{} triangles where frame 0 has {}", frame.triangles.len(), self.triangles.len()),
            });
        }
        if let Some(t) = frame.triangles.iter().zip(&self.triangles).position(|(a, b)| a != b) {
            return Err(MeshError::FrameMismatch {
                frame: label(),
                detail: format!("face {t} is {:?} where frame 0 has {:?} (0-based vertex indices)", frame.triangles[t], self.triangles[t]),
            });
        }
        Ok(frame.positions)
    }
}

impl Iterator for ObjFrames {
    type Item = Result<Vec<Vec3>, MeshError>;

    fn next(&mut self) -> Option<Self::Item> {
        let path = self.paths.pop()?;
        let frame = self.read(&path);
        if frame.is_err() {
            // Nothing after a bad file is read.
            self.paths.clear();
        }
        Some(frame)
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        (self.paths.len(), Some(self.paths.len()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn natural_order() {
        let mut v = vec!["f10.obj", "f2.obj", "f1.obj", "f01.obj", "g.obj", "f002.obj"];
        v.sort_by(|a, b| natural_cmp(a, b));
        assert_eq!(v, ["f1.obj", "f01.obj", "f2.obj", "f002.obj", "f10.obj", "g.obj"]);
    }

    #[test]
    fn plain_digits_agree_with_i64_parse() {
        let mut words: Vec<String> =
            ["0", "1", "007", "-3", "+4", "", "1a", " 1", "999999999999999999", "9999999999999999999", "١"].map(String::from).to_vec();
        // Varied lengths and digits, from a fixed linear congruential sequence.
        let mut x = 12345u64;
        for _ in 0..500 {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let len = 1 + (x >> 60) as usize;
            words.push((0..len).map(|i| char::from(b'0' + ((x >> (i * 3)) % 10) as u8)).collect());
        }
        for w in &words {
            match plain_digits(w) {
                Some(v) => assert_eq!(Ok(v), w.parse::<i64>(), "{w:?}"),
                // Only what is not 1 to 18 plain digits is left to the parser.
                None => assert!(w.is_empty() || w.len() > 18 || !w.bytes().all(|b| b.is_ascii_digit()), "{w:?}"),
            }
        }
    }

    #[test]
    fn wildcards() {
        assert!(wildcard_match("horse-*.obj", "horse-01.obj"));
        assert!(wildcard_match("h?rse*", "horse-01.obj"));
        assert!(!wildcard_match("horse-*.obj", "horse-01.objx"));
        assert!(wildcard_match("*a*b*", "xxaxxbxx"));
        assert!(!wildcard_match("*a*b", "xxaxxbxxc"));
    }

    #[test]
    fn parses_polygons_negative_indices_and_ignores_attributes() {
        let text = "# c\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\nf 1/1/1 2/1/1 3/1/1 4/1/1\nf -4 -2 -1\n";
        let m = parse_obj(text, Path::new("t.obj")).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 2, 3]]);
    }

    #[test]
    fn errors_name_line() {
        let e = parse_obj("v 0 0 0\nv 1 x 0\n", Path::new("bad.obj")).unwrap_err().to_string();
        assert!(e.contains("bad.obj:2") && e.contains("\"x\""), "{e}");
        // Found only at the end of the file (faces may name later vertices), but the error
        // still names the line of the face.
        let e = parse_obj("v 0 0 0\nv 1 0 0\nf 1 2 5\nv 1 1 0\nf 1 2 3\n# end\n", Path::new("bad.obj")).unwrap_err().to_string();
        assert!(e.contains("bad.obj:3:") && e.contains("vertex 5 but the file has 3 vertices"), "{e}");
        let e = parse_obj("v 0 0 0\nf 1 0 1\n", Path::new("bad.obj")).unwrap_err().to_string();
        assert!(e.contains("index 0"), "{e}");
    }
}
