//! OBJ (our own order-preserving reader) and STL (binary: ours; ASCII: `stl_io`) loading into
//! [`SurfaceMesh`].

use super::{SurfaceMesh, bounds_of, weld_positions};
use crate::error::MeshError;
use glam::Vec3;
use std::path::Path;

/// How a mesh file is turned into a [`SurfaceMesh`].
#[derive(Clone, Debug, PartialEq)]
pub struct LoadOptions {
    /// Weld vertices closer than this fraction of the bounding-box diagonal.
    /// `None` keeps the file's vertices as they are. Default: `Some(1e-6)`.
    pub weld_tolerance: Option<f32>,
    /// Split every polygon into triangles (their diagonals become edges and so
    /// Fiber constraints). Default: `false` (quads stay quads, as in the thesis).
    pub triangulate: bool,
    /// Multiply every position by this factor (e.g. `0.01` for centimetre files
    /// in a metre scene). Default: `1.0`.
    pub scale: f32,
    /// Drop faces that are degenerate after welding (repeated corners or zero
    /// area) instead of failing. For targets such as scanned bones, which
    /// only need triangles; a muscle's faces must all be sound. Default: `false`.
    pub drop_degenerate_faces: bool,
    /// Reverse every polygon when the faces point inwards (a closed mesh
    /// with a negative signed volume), as some exporters write them.
    /// Default: `false` (a muscle whose faces point inwards is refused by
    /// [`crate::muscle::Muscle::build`], naming this option).
    pub orient_outward: bool,
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self {
            weld_tolerance: Some(1e-6),
            triangulate: false,
            scale: 1.0,
            drop_degenerate_faces: false,
            orient_outward: false,
        }
    }
}

/// Loads `.obj` or `.stl` (ASCII or binary), welds duplicated positions and
/// validates indices, finiteness and degenerate faces. Topology (closed,
/// manifold, orientation) is *not* required here; see
/// [`SurfaceMesh::check_closed_manifold`].
pub fn load_mesh(path: &Path, options: &LoadOptions) -> Result<SurfaceMesh, MeshError> {
    let (positions, polygons) = read_raw(path)?;
    from_raw(path, positions, polygons, options)
}

/// The positions and polygons of an OBJ or STL file, as stored (no welding,
/// no validation beyond the syntax).
fn read_raw(path: &Path) -> Result<Raw, MeshError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("obj") => read_obj(path).map(|(positions, polygons, _)| (positions, polygons)),
        Some("stl") => read_stl(path),
        _ => Err(MeshError::UnsupportedFormat {
            file: path.to_path_buf(),
        }),
    }
}

/// Builds a mesh from raw positions and polygons with the load options applied.
pub(crate) fn from_raw(
    path: &Path,
    mut positions: Vec<Vec3>,
    mut polygons: Vec<Vec<u32>>,
    options: &LoadOptions,
) -> Result<SurfaceMesh, MeshError> {
    // Validate before welding so errors name the file's own indices.
    for (vertex, p) in positions.iter().enumerate() {
        if !p.is_finite() {
            return Err(MeshError::NonFinite {
                file: path.to_path_buf(),
                vertex,
                value: p.to_array(),
            });
        }
    }
    check_indices(path, &polygons, positions.len())?;
    if options.scale != 1.0 {
        for p in &mut positions {
            *p *= options.scale;
        }
    }
    if let Some(rel) = options.weld_tolerance {
        let (lo, hi) = bounds_of(&positions);
        let (welded, remap) = weld_positions(&positions, rel * (hi - lo).length());
        positions = welded;
        for poly in &mut polygons {
            for i in poly.iter_mut() {
                *i = remap[*i as usize];
            }
        }
    }
    if options.drop_degenerate_faces {
        let min_area = super::min_polygon_area(&positions);
        polygons.retain(|poly| !super::is_degenerate(&positions, poly, min_area));
    }
    if options.orient_outward {
        polygons = super::primitives::oriented_outward(&positions, polygons);
    }
    let mesh = SurfaceMesh::new(path, positions, &polygons)?;
    Ok(if options.triangulate {
        mesh.triangulated()
    } else {
        mesh
    })
}

/// Every polygon corner must name one of the `count` vertices (the error
/// names the face in file order).
fn check_indices(path: &Path, polygons: &[Vec<u32>], count: usize) -> Result<(), MeshError> {
    for (face, poly) in polygons.iter().enumerate() {
        if let Some(&index) = poly.iter().find(|&&i| i as usize >= count) {
            return Err(MeshError::IndexOutOfRange {
                file: path.to_path_buf(),
                face,
                index: index as usize,
                count,
            });
        }
    }
    Ok(())
}

/// Positions and polygons as read from a file.
type Raw = (Vec<Vec3>, Vec<Vec<u32>>);

/// An OBJ's vertices in the file's order and its faces by group (`g NAME`):
/// a character's skin apart from its helper geometry, whose vertex indices
/// still match the file's (skin weights and joint markers refer to them).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ObjGroups {
    /// Every vertex, as stored.
    pub positions: Vec<Vec3>,
    /// Each group's name and polygons (0-based indices into `positions`), in
    /// the order the groups first appear; faces before any `g` are in
    /// `"default"`, a face under `g a b` is in both groups.
    pub groups: Vec<(String, Vec<Vec<u32>>)>,
}

impl ObjGroups {
    /// Reads an OBJ's vertices and grouped faces (syntax and indices checked,
    /// no welding).
    pub fn read(path: &Path) -> Result<Self, MeshError> {
        let (positions, polygons, labels) = read_obj(path)?;
        check_indices(path, &polygons, positions.len())?;
        let mut groups: Vec<(String, Vec<Vec<u32>>)> = Vec::new();
        for (polygon, names) in polygons.into_iter().zip(labels) {
            for name in names.split_whitespace() {
                match groups.iter_mut().find(|(n, _)| n == name) {
                    Some((_, faces)) => faces.push(polygon.clone()),
                    None => groups.push((name.to_string(), vec![polygon.clone()])),
                }
            }
        }
        Ok(Self { positions, groups })
    }

    /// The polygons of group `name`, or `MeshError::MissingGroup` naming `file`.
    pub fn group(&self, file: &Path, name: &str) -> Result<&[Vec<u32>], MeshError> {
        self.groups
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, faces)| faces.as_slice())
            .ok_or_else(|| MeshError::MissingGroup {
                file: file.to_path_buf(),
                group: name.to_string(),
            })
    }
}

/// Reads the vertices and faces of a Wavefront OBJ, keeping the file's vertex
/// order (scenes refer to vertices by index: roots, attachments, maps).
/// `v x y z [w]` and `f` with `v`, `v/vt`, `v//vn` or `v/vt/vn` corners,
/// 1-based or negative (relative) indices; other statements are ignored.
/// Each polygon comes with the names of the `g` statement above it.
fn read_obj(path: &Path) -> Result<ObjText, MeshError> {
    let text = std::fs::read_to_string(path).map_err(|source| MeshError::Io {
        file: path.to_path_buf(),
        source,
    })?;
    let parse = |line: usize, reason: String| MeshError::Parse {
        file: path.to_path_buf(),
        reason: format!("line {line}: {reason}"),
    };
    let mut positions = Vec::new();
    let mut polygons = Vec::new();
    // The `g` statements' names, and each polygon's entry in that list.
    let mut labels = vec!["default".to_string()];
    let mut polygon_labels = Vec::new();
    for (n, raw) in text.lines().enumerate() {
        let line = n + 1;
        let content = raw.split('#').next().unwrap_or("");
        let mut words = content.split_whitespace();
        match words.next() {
            Some("v") => {
                let mut c = [0.0f32; 3];
                for (k, slot) in c.iter_mut().enumerate() {
                    let word = words.next().ok_or_else(|| {
                        parse(line, format!("vertex has {k} coordinates, needs 3"))
                    })?;
                    *slot = word
                        .parse()
                        .map_err(|_| parse(line, format!("'{word}' is not a number")))?;
                }
                positions.push(Vec3::from_array(c));
            }
            Some("g") => {
                let names = words.collect::<Vec<_>>().join(" ");
                labels.push(if names.is_empty() {
                    "default".into()
                } else {
                    names
                });
            }
            Some("f") => {
                let mut face = Vec::new();
                for word in words {
                    let index = word.split('/').next().unwrap_or("");
                    let i: i64 = index
                        .parse()
                        .map_err(|_| parse(line, format!("'{word}' is not a vertex index")))?;
                    let resolved = match i {
                        0 => {
                            return Err(parse(
                                line,
                                "vertex index 0 (OBJ indices start at 1)".into(),
                            ));
                        }
                        i if i > 0 => i - 1,
                        i => positions.len() as i64 + i,
                    };
                    if resolved < 0 {
                        return Err(parse(
                            line,
                            format!("relative index {i} points before the first vertex"),
                        ));
                    }
                    face.push(
                        u32::try_from(resolved)
                            .map_err(|_| parse(line, format!("index {i} is too large")))?,
                    );
                }
                if face.len() < 3 {
                    return Err(parse(
                        line,
                        format!("face has {} vertices, needs 3", face.len()),
                    ));
                }
                polygons.push(face);
                polygon_labels.push(labels.len() - 1);
            }
            _ => {}
        }
    }
    let labels = polygon_labels
        .into_iter()
        .map(|k| labels[k].clone())
        .collect();
    Ok((positions, polygons, labels))
}

/// An OBJ's positions, polygons, and the group names above each polygon.
type ObjText = (Vec<Vec3>, Vec<Vec<u32>>, Vec<String>);

/// Bytes of a binary STL's header (80) and triangle count (4).
const STL_HEADER: usize = 84;
/// Bytes per binary STL triangle: normal and three corners (12 `f32`) and a
/// `u16` attribute.
const STL_TRIANGLE: usize = 50;

/// A binary STL when its size matches the triangle count in its header, an
/// ASCII STL when it starts with `solid`; a binary file whose header count
/// disagrees with its size (triangles that would be dropped or read past the
/// end) is an error.
fn read_stl(path: &Path) -> Result<Raw, MeshError> {
    let bytes = std::fs::read(path).map_err(|source| MeshError::Io {
        file: path.to_path_buf(),
        source,
    })?;
    let parse_err = |reason: String| MeshError::Parse {
        file: path.to_path_buf(),
        reason,
    };
    let counted = bytes
        .get(80..STL_HEADER)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]) as usize);
    let mut positions = Vec::new();
    let mut polygons = Vec::new();
    let mut push = |corners: [[f32; 3]; 3]| {
        let base = positions.len() as u32;
        positions.extend(corners.map(Vec3::from_array));
        polygons.push(vec![base, base + 1, base + 2]);
    };
    match counted {
        Some(count) if STL_HEADER + count * STL_TRIANGLE == bytes.len() => {
            for record in bytes[STL_HEADER..].chunks_exact(STL_TRIANGLE) {
                let float = |k: usize| {
                    let at = 12 + 4 * k;
                    f32::from_le_bytes([record[at], record[at + 1], record[at + 2], record[at + 3]])
                };
                push([0, 1, 2].map(|c| [0, 1, 2].map(|a| float(3 * c + a))));
            }
        }
        _ if bytes.trim_ascii_start().starts_with(b"solid") => {
            let mut reader = std::io::Cursor::new(&bytes);
            let triangles = stl_io::create_stl_reader(&mut reader)
                .map_err(|e| parse_err(format!("ASCII STL: {e}")))?;
            for tri in triangles {
                let tri = tri.map_err(|e| parse_err(format!("ASCII STL: {e}")))?;
                push(tri.vertices.map(|v| v.0));
            }
        }
        Some(count) => {
            let held = (bytes.len() - STL_HEADER) as f64 / STL_TRIANGLE as f64;
            return Err(parse_err(format!(
                "binary STL header counts {count} triangles but the file's {} bytes hold {held} \
                 ({STL_HEADER} + {STL_TRIANGLE} per triangle): truncated or corrupt",
                bytes.len()
            )));
        }
        None => {
            return Err(parse_err(format!(
                "{} bytes: too short for a binary STL and not an ASCII one (no `solid`)",
                bytes.len()
            )));
        }
    }
    // STL stores every triangle separately: welding is what makes it a surface.
    Ok((positions, polygons))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A binary STL of `triangles`, with `header` (a binary header may
    /// start with `solid`, as some exporters write) and the triangle count
    /// `count` in it.
    fn binary_stl(header: &[u8], count: u32, triangles: &[[[f32; 3]; 3]]) -> Vec<u8> {
        let mut bytes = header.to_vec();
        bytes.resize(80, b' ');
        bytes.extend(count.to_le_bytes());
        for t in triangles {
            bytes.extend(
                [0f32; 3]
                    .iter()
                    .chain(t.iter().flatten())
                    .flat_map(|x| x.to_le_bytes()),
            );
            bytes.extend([0u8; 2]);
        }
        bytes
    }

    /// Binary STLs read as `stl_io` reads them, even with a header that
    /// starts with `solid`; a header count that disagrees with the size is
    /// an error naming both.
    #[test]
    fn binary_stl_is_read_whole_or_refused() {
        let triangles = [
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.5]],
        ];
        let path = std::env::temp_dir().join(format!("sinew_stl_{}.stl", std::process::id()));
        for header in [b"binary".as_slice(), b"solid but binary"] {
            std::fs::write(&path, binary_stl(header, 2, &triangles)).unwrap();
            let (positions, polygons) = read_stl(&path).unwrap();
            let mut reader = std::io::Cursor::new(binary_stl(b"binary", 2, &triangles));
            let theirs: Vec<Vec3> = stl_io::create_stl_reader(&mut reader)
                .unwrap()
                .flat_map(|t| t.unwrap().vertices.map(|v| Vec3::from_array(v.0)))
                .collect();
            assert_eq!(positions, theirs);
            assert_eq!(polygons, [vec![0, 1, 2], vec![3, 4, 5]]);
        }
        for count in [1, 3, 1_000_000] {
            std::fs::write(&path, binary_stl(b"binary", count, &triangles)).unwrap();
            let e = read_stl(&path).unwrap_err().to_string();
            assert!(e.contains(&format!("counts {count} triangles")), "{e}");
            assert!(e.contains("184 bytes hold 2"), "{e}");
        }
        std::fs::write(&path, b"short").unwrap();
        assert!(
            read_stl(&path)
                .unwrap_err()
                .to_string()
                .contains("too short")
        );
        std::fs::remove_file(&path).ok();
    }

    #[test]
    fn obj_keeps_the_file_vertex_order() {
        // Faces list vertex 4 first: a reader that renumbers by first use
        // would move it to index 0 and break index-based roots/attachments.
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 4 3 2\nf 1 2 3\nf 1 4 2\nf 1 3 4\n";
        let path = std::env::temp_dir().join(format!("sinew_order_{}.obj", std::process::id()));
        std::fs::write(&path, text).unwrap();
        let mesh = load_mesh(&path, &LoadOptions::default()).unwrap();
        assert_eq!(mesh.positions[0], Vec3::ZERO);
        assert_eq!(mesh.positions[3], Vec3::Z);
        assert_eq!(mesh.polygons().next().unwrap(), &[3, 2, 1]);
        // Negative (relative) indices and v/vt/vn corners.
        std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3/1/1 -2//1 -1/2\n").unwrap();
        let mesh = load_mesh(&path, &LoadOptions::default()).unwrap();
        assert_eq!(mesh.polygons().next().unwrap(), &[0, 1, 2]);
        std::fs::write(&path, "v 0 0 0\nv 1 0 x\nf 1 2 3\n").unwrap();
        let e = load_mesh(&path, &LoadOptions::default()).unwrap_err();
        assert!(e.to_string().contains("line 2"), "{e}");
        std::fs::remove_file(&path).ok();
    }
}
