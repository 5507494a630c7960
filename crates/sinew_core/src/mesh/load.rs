//! OBJ (`tobj`) and STL (`stl_io`) loading into [`SurfaceMesh`].

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
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self {
            weld_tolerance: Some(1e-6),
            triangulate: false,
            scale: 1.0,
        }
    }
}

/// Loads `.obj` or `.stl` (ASCII or binary), welds duplicated positions and
/// validates indices, finiteness and degenerate faces. Topology (closed,
/// manifold, orientation) is *not* required here; see
/// [`SurfaceMesh::check_closed_manifold`].
pub fn load_mesh(path: &Path, options: &LoadOptions) -> Result<SurfaceMesh, MeshError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let (positions, polygons) = match ext.as_deref() {
        Some("obj") => read_obj(path)?,
        Some("stl") => read_stl(path)?,
        _ => {
            return Err(MeshError::UnsupportedFormat {
                file: path.to_path_buf(),
            });
        }
    };
    from_raw(path, positions, polygons, options)
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
    for (face, poly) in polygons.iter().enumerate() {
        if let Some(&index) = poly.iter().find(|&&i| i as usize >= positions.len()) {
            return Err(MeshError::IndexOutOfRange {
                file: path.to_path_buf(),
                face,
                index: index as usize,
                count: positions.len(),
            });
        }
    }
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
    let mesh = SurfaceMesh::new(path, positions, &polygons)?;
    Ok(if options.triangulate {
        mesh.triangulated()
    } else {
        mesh
    })
}

type Raw = (Vec<Vec3>, Vec<Vec<u32>>);

fn read_obj(path: &Path) -> Result<Raw, MeshError> {
    let text = std::fs::read_to_string(path).map_err(|source| MeshError::Io {
        file: path.to_path_buf(),
        source,
    })?;
    let opts = tobj::LoadOptions {
        single_index: false,
        triangulate: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _) = tobj::load_obj_buf(&mut text.as_bytes(), &opts, |_| {
        Ok((Vec::new(), Default::default()))
    })
    .map_err(|e| MeshError::Parse {
        file: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    let mut positions = Vec::new();
    let mut polygons = Vec::new();
    for model in models {
        let m = model.mesh;
        let base = positions.len() as u32;
        positions.extend(
            m.positions
                .chunks_exact(3)
                .map(|c| Vec3::new(c[0], c[1], c[2])),
        );
        let mut start = 0usize;
        let arities: Vec<u32> = if m.face_arities.is_empty() {
            vec![3; m.indices.len() / 3]
        } else {
            m.face_arities.clone()
        };
        for arity in arities {
            let end = start + arity as usize;
            polygons.push(m.indices[start..end].iter().map(|&i| i + base).collect());
            start = end;
        }
    }
    Ok((positions, polygons))
}

fn read_stl(path: &Path) -> Result<Raw, MeshError> {
    let file = std::fs::File::open(path).map_err(|source| MeshError::Io {
        file: path.to_path_buf(),
        source,
    })?;
    let mut reader = std::io::BufReader::new(file);
    let parse_err = |e: std::io::Error| MeshError::Parse {
        file: path.to_path_buf(),
        reason: e.to_string(),
    };
    let triangles = stl_io::create_stl_reader(&mut reader).map_err(parse_err)?;
    let mut positions = Vec::new();
    let mut polygons = Vec::new();
    for tri in triangles {
        let tri = tri.map_err(parse_err)?;
        let base = positions.len() as u32;
        positions.extend(tri.vertices.iter().map(|v| Vec3::from_array(v.0)));
        polygons.push(vec![base, base + 1, base + 2]);
    }
    // STL stores every triangle separately: welding is what makes it a surface.
    Ok((positions, polygons))
}
