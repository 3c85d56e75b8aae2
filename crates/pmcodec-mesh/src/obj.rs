//! OBJ sequences: one OBJ file per frame, all with the same vertices and faces.
//!
//! Only `v` and `f` records carry meaning here; `vn`, `vt`, groups, materials and smoothing
//! groups are accepted and ignored (the hierarchy is built on positions alone). Polygons are
//! triangulated as fans, which is exact for the convex quads and n-gons that deforming-mesh
//! exporters write.

use crate::{MeshError, Sequence};
use glam::Vec3;
use std::path::{Path, PathBuf};

/// One parsed OBJ file.
#[derive(Clone, Debug, Default)]
pub struct ObjFrame {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}

/// Parses the text of one OBJ file. `path` is only used to name the file in errors.
pub fn parse_obj(text: &str, path: &Path) -> Result<ObjFrame, MeshError> {
    let mut out = ObjFrame::default();
    let mut polygon: Vec<u32> = Vec::with_capacity(8);
    let err = |line: usize, message: String| MeshError::Parse { path: path.to_path_buf(), line, message };
    for (lineno, raw) in text.lines().enumerate() {
        let line = raw.trim();
        let lineno = lineno + 1;
        let mut words = line.split_ascii_whitespace();
        match words.next() {
            Some("v") => {
                let mut p = [0f32; 3];
                for (axis, slot) in p.iter_mut().enumerate() {
                    let word = words.next().ok_or_else(|| err(lineno, format!("vertex has {axis} coordinates, expected 3")))?;
                    *slot = word.parse().map_err(|_| err(lineno, format!("vertex coordinate {word:?} is not a number")))?;
                }
                // An optional fourth (w) or vertex colours may follow: ignored.
                out.positions.push(Vec3::from_array(p));
            }
            Some("f") => {
                polygon.clear();
                for word in words {
                    // `v`, `v/vt`, `v//vn` or `v/vt/vn`: only the position index matters.
                    let index = word.split('/').next().unwrap_or(word);
                    let i: i64 = index.parse().map_err(|_| err(lineno, format!("face index {word:?} is not an integer")))?;
                    // OBJ indices are 1-based; negative ones count back from the latest vertex.
                    let resolved = match i {
                        0 => return Err(err(lineno, "face index 0 (OBJ indices start at 1)".into())),
                        i if i > 0 => i - 1,
                        i => out.positions.len() as i64 + i,
                    };
                    if resolved < 0 || resolved >= u32::MAX as i64 {
                        return Err(err(lineno, format!("face index {i} is out of range")));
                    }
                    polygon.push(resolved as u32);
                }
                if polygon.len() < 3 {
                    return Err(err(lineno, format!("face has {} corners, expected at least 3", polygon.len())));
                }
                for k in 1..polygon.len() - 1 {
                    out.triangles.push([polygon[0], polygon[k], polygon[k + 1]]);
                }
            }
            _ => {}
        }
    }
    let n = out.positions.len();
    if let Some((t, &i)) = out.triangles.iter().enumerate().find_map(|(t, tri)| tri.iter().find(|&&i| i as usize >= n).map(|i| (t, i))) {
        return Err(MeshError::Parse {
            path: path.to_path_buf(),
            line: 0,
            message: format!("face {t} uses vertex {} but the file has {n} vertices", i + 1),
        });
    }
    Ok(out)
}

/// Reads one OBJ file.
pub fn read_obj(path: &Path) -> Result<ObjFrame, MeshError> {
    let text = std::fs::read_to_string(path).map_err(|error| MeshError::Io { path: path.to_path_buf(), error })?;
    parse_obj(&text, path)
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
    let paths = frame_paths(input)?;
    load_obj_files(&paths, frame_rate)
}

/// Loads the given files, in the given order, as the frames of one sequence.
pub fn load_obj_files(paths: &[PathBuf], frame_rate: f32) -> Result<Sequence, MeshError> {
    let mut seq = Sequence { frame_rate, ..Default::default() };
    for path in paths {
        let frame = read_obj(path)?;
        let label = || path.display().to_string();
        if seq.frames.is_empty() {
            seq.triangles = frame.triangles;
        } else {
            if frame.positions.len() != seq.frames[0].len() {
                return Err(MeshError::FrameMismatch {
                    frame: label(),
                    detail: format!("{} vertices where frame 0 has {}", frame.positions.len(), seq.frames[0].len()),
                });
            }
            if frame.triangles.len() != seq.triangles.len() {
                return Err(MeshError::FrameMismatch {
                    frame: label(),
                    detail: format!("{} triangles where frame 0 has {}", frame.triangles.len(), seq.triangles.len()),
                });
            }
            if let Some(t) = frame.triangles.iter().zip(&seq.triangles).position(|(a, b)| a != b) {
                return Err(MeshError::FrameMismatch {
                    frame: label(),
                    detail: format!(
                        "face {t} is {:?} where frame 0 has {:?} (0-based vertex indices)",
                        frame.triangles[t], seq.triangles[t]
                    ),
                });
            }
        }
        seq.frames.push(frame.positions);
        seq.frame_names.push(path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default());
    }
    seq.validate()?;
    Ok(seq)
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
        let e = parse_obj("v 0 0 0\nf 1 2 3\n", Path::new("bad.obj")).unwrap_err().to_string();
        assert!(e.contains("face 0 uses vertex 2"), "{e}");
        let e = parse_obj("v 0 0 0\nf 1 0 1\n", Path::new("bad.obj")).unwrap_err().to_string();
        assert!(e.contains("index 0"), "{e}");
    }
}
