//! The meshes a scene names: files relative to the scene, planes and
//! generators.

use super::{BoneShape, MeshSource};
use crate::error::SceneError;
use crate::mesh::{LoadOptions, SurfaceMesh, load_mesh};
use std::path::{Path, PathBuf};

fn resolve(base_dir: &Path, file: &str) -> PathBuf {
    let p = Path::new(file);
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        base_dir.join(p)
    }
}

pub(super) fn bone_mesh(
    name: &str,
    shape: &BoneShape,
    base_dir: &Path,
) -> Result<SurfaceMesh, SceneError> {
    Ok(match shape {
        BoneShape::Mesh {
            file,
            scale,
            orient_outward,
        } => {
            let mesh = load_mesh(
                &resolve(base_dir, file),
                &LoadOptions {
                    scale: *scale,
                    orient_outward: *orient_outward,
                    ..Default::default()
                },
            )?;
            // A closed bone whose faces point inwards would push muscles
            // into it (Sliding keeps them on the side its normals face).
            let report = mesh.report();
            if report.is_closed_manifold() && report.volume < 0.0 {
                return Err(crate::MeshError::InsideOut {
                    file: mesh.source.clone(),
                    volume: report.volume,
                }
                .into());
            }
            mesh
        }
        BoneShape::Plane {
            center,
            normal,
            size,
        } => {
            let n = normal.try_normalize().ok_or_else(|| SceneError::Invalid {
                context: format!("bone '{name}' plane"),
                reason: "normal has zero length".into(),
            })?;
            if size.is_nan() || *size <= 0.0 {
                return Err(SceneError::Invalid {
                    context: format!("bone '{name}' plane"),
                    reason: format!("size {size} must be > 0"),
                });
            }
            let (u, v) = n.any_orthonormal_pair();
            let h = 0.5 * size;
            let corners = vec![
                *center - h * u - h * v,
                *center + h * u - h * v,
                *center + h * u + h * v,
                *center - h * u + h * v,
            ];
            // Counter-clockwise seen from the normal side.
            let quad = if u.cross(v).dot(n) > 0.0 {
                vec![0, 1, 2, 3]
            } else {
                vec![3, 2, 1, 0]
            };
            SurfaceMesh::new(format!("<plane {name}>"), corners, &[quad])?
        }
        BoneShape::Generated(g) => g.build(name)?,
    })
}

pub(super) fn muscle_mesh(
    name: &str,
    source: &MeshSource,
    base_dir: &Path,
) -> Result<SurfaceMesh, SceneError> {
    Ok(match source {
        MeshSource::File {
            path,
            triangulate,
            scale,
            orient_outward,
            translation,
        } => {
            let mut mesh = load_mesh(
                &resolve(base_dir, path),
                &LoadOptions {
                    triangulate: *triangulate,
                    scale: *scale,
                    orient_outward: *orient_outward,
                    ..Default::default()
                },
            )?;
            for p in &mut mesh.positions {
                *p += *translation;
            }
            mesh
        }
        MeshSource::Generator(g) => g.build(name)?,
    })
}
