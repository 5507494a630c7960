//! Importing anatomy: MuJoCo MJCF models (bones, joints, muscle paths) become
//! sinew scenes with swept muscle meshes.
//!
//! - [`mjcf`] reads the model (with includes, defaults, composition and
//!   mirroring).
//! - [`builder`] sweeps a fusiform muscle along each tendon path.
//! - [`import_model`] assembles a [`Scene`]: one bone per body following the
//!   skeleton, bone meshes for the bones muscles touch, one muscle per chosen
//!   actuator with its roots, attachments, fibres and neighbour targets.
//! - [`ImportRecipe`] is the RON file that makes a whole reference scene
//!   (model, composition, muscles, motion, sensors, drives) reproducible with
//!   one command: `sinew import-mjcf recipe.ron`.

pub mod builder;
mod clearance;
pub mod mjcf;
mod options;
mod recipe;
mod wrap;

pub use options::{BoneMeshes, ImportOptions, TargetOverride, UserMuscleMesh};
pub use recipe::{AttachModel, ImportRecipe, MuscleDrive};

use crate::animation::Curve;
use crate::closest::{TargetSource, TargetSurface};
use crate::error::ImportError;
use crate::mesh::{LoadOptions, SurfaceMesh, load_mesh};
use crate::muscle::{MuscleParams, Roots, VertexMaps};
use crate::scene::{AttachmentSpec, BoneShape, BoneSpec, MeshSource, MuscleSpec, Scene};
use crate::sensor::{ActivationLayer, SensorSpec};
use crate::skeleton::{BodySpec, JointMotion, Skeleton, SkeletonRig};
use crate::solver::SolverSettings;
use builder::{SweepOptions, push_out_of_bones, sweep_path_clear_of};
use glam::{Affine3A, Quat, Vec3};
use mjcf::MjcfModel;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Rotation taking MuJoCo's Z-up world to Y-up: (x, y, z) → (x, z, −y).
pub fn z_up_to_y_up() -> Quat {
    Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2)
}

/// A bone's triangles in its body frame.
struct BoneGeometry {
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
}

/// Loads and places the mesh geoms of every body (body frame), welded, with
/// degenerate faces dropped.
fn bone_geometry(model: &MjcfModel) -> Result<Vec<Option<BoneGeometry>>, ImportError> {
    let mut out: Vec<Option<BoneGeometry>> = (0..model.bodies.len()).map(|_| None).collect();
    for g in &model.geoms {
        let Some(body) = g.body else { continue };
        let asset = model
            .mesh(&g.mesh)
            .ok_or_else(|| ImportError::UnknownName {
                context: format!("geom '{}' of body '{}'", g.name, model.bodies[body].name),
                kind: "mesh asset",
                name: g.mesh.clone(),
            })?;
        // Real bone scans have slivers; a target only needs triangles.
        let options = LoadOptions {
            drop_degenerate_faces: true,
            ..Default::default()
        };
        let mesh = load_mesh(&asset.file, &options)?;
        let flip = asset.scale.x * asset.scale.y * asset.scale.z < 0.0;
        let place = Affine3A::from_rotation_translation(g.quat, g.pos);
        let geometry = out[body].get_or_insert_with(|| BoneGeometry {
            positions: Vec::new(),
            triangles: Vec::new(),
        });
        let base = geometry.positions.len() as u32;
        geometry.positions.extend(
            mesh.positions
                .iter()
                .map(|&p| place.transform_point3(p * asset.scale)),
        );
        geometry.triangles.extend(mesh.triangles.iter().map(|t| {
            let t = if flip { [t[0], t[2], t[1]] } else { *t };
            t.map(|i| i + base)
        }));
    }
    Ok(out)
}

/// Result of [`import_model`].
#[derive(Debug)]
pub struct Imported {
    /// The scene (mesh paths relative to the scene file's directory).
    pub scene: Scene,
    /// Files written.
    pub files: Vec<PathBuf>,
    /// Notes for the user (skipped wraps, pushed-out vertices …).
    pub notes: Vec<String>,
}

struct BuiltMuscle {
    name: String,
    mesh: SurfaceMesh,
    fibers: Vec<Vec3>,
    tips: [u32; 2],
    ends: [Vec<u32>; 2],
    bodies: [Option<usize>; 2],
    centers: Vec<Vec3>,
}

/// Turns `model` into a scene. Meshes are written under
/// `scene_dir/mesh_dir`; the scene refers to them relative to `scene_dir`.
pub fn import_model(
    model: &MjcfModel,
    options: &ImportOptions,
    scene_dir: &Path,
    mesh_dir: &Path,
) -> Result<Imported, ImportError> {
    let mut notes = Vec::new();
    // Skeleton, in Y-up when asked.
    let root = if options.y_up {
        z_up_to_y_up()
    } else {
        Quat::IDENTITY
    };
    let bodies: Vec<BodySpec> = model
        .bodies
        .iter()
        .map(|b| BodySpec {
            name: b.name.clone(),
            parent: b.parent.map(|p| model.bodies[p].name.clone()),
            translation: if b.parent.is_none() {
                root * b.pos
            } else {
                b.pos
            },
            rotation: if b.parent.is_none() {
                root * b.quat
            } else {
                b.quat
            },
            joints: b.joints.clone(),
        })
        .collect();
    let skeleton = Skeleton {
        bodies,
        motion: Vec::new(),
        couplings: model.couplings.clone(),
    };
    let rig: SkeletonRig = skeleton.compile()?;
    // Reference pose: every joint at 0, coupled joints at their polynomials.
    let (mut values, mut world) = (Vec::new(), Vec::new());
    rig.pose_at(0.0, &mut values, &mut world);
    let world_root = Affine3A::from_quat(root);
    let frame_of = |body: Option<usize>| body.map_or(world_root, |b| world[b]);

    // Bones in the world (reference pose) for push-out and target choice.
    let geometry = bone_geometry(model)?;
    let bone_targets: Vec<Option<TargetSurface>> = geometry
        .iter()
        .enumerate()
        .map(|(b, g)| {
            g.as_ref().map(|g| {
                let mut t = TargetSurface::new(
                    model.bodies[b].name.clone(),
                    TargetSource::Bone(b),
                    g.positions.clone(),
                    g.triangles.clone(),
                );
                t.set_transform(world[b]);
                t
            })
        })
        .collect();
    let bone_boxes: Vec<Option<Bounds>> = geometry
        .iter()
        .zip(&world)
        .map(|(g, pose)| {
            g.as_ref().map(|g| {
                let placed: Vec<Vec3> = g
                    .positions
                    .iter()
                    .map(|&p| pose.transform_point3(p))
                    .collect();
                crate::mesh::bounds_of(&placed)
            })
        })
        .collect();
    // Bone targets whose world box overlaps `bounds`.
    let bones_near = |bounds: Bounds| -> Vec<&TargetSurface> {
        bone_targets
            .iter()
            .zip(&bone_boxes)
            .filter_map(|(t, b)| overlap(bounds, (*b)?).then_some(t.as_ref()?))
            .collect()
    };

    // Muscles.
    let chosen: Vec<usize> = if options.muscles.is_empty() {
        (0..model.actuators.len()).collect()
    } else {
        options
            .muscles
            .iter()
            .map(|name| {
                model
                    .actuators
                    .iter()
                    .position(|a| &a.name == name)
                    .ok_or_else(|| ImportError::UnknownName {
                        context: format!("import of {}", model.file.display()),
                        kind: "muscle (actuator)",
                        name: name.clone(),
                    })
            })
            .collect::<Result<_, _>>()?
    };
    // Per-muscle overrides name muscles being imported.
    let overridden = options
        .radii
        .iter()
        .map(|(m, _)| ("radii", m))
        .chain(options.held_rings.iter().map(|(m, ..)| ("held_rings", m)));
    for (field, name) in overridden {
        if !chosen.iter().any(|&a| model.actuators[a].name == *name) {
            return Err(ImportError::UnknownName {
                context: format!(
                    "import option `{field}` (import of {})",
                    model.file.display()
                ),
                kind: "muscle being imported",
                name: name.clone(),
            });
        }
    }
    let mut built: Vec<BuiltMuscle> = Vec::with_capacity(chosen.len());
    for &a in &chosen {
        let actuator = &model.actuators[a];
        let tendon = &model.tendons[actuator.tendon];
        let sites = model.tendon_sites(actuator.tendon)?;
        let points = wrap::tendon_path(model, tendon, &sites, &frame_of, options.wrap_paths)?;
        let wraps = tendon.wraps.len();
        if wraps > 0 && !options.wrap_paths {
            notes.push(format!(
                "{}: {wraps} wrapping geom(s) ignored (wrap_paths is off); the path runs through its {} sites",
                actuator.name,
                sites.len()
            ));
        }
        let name = actuator.name.clone();
        let bodies = [
            sites.first().and_then(|s| s.body),
            sites.last().and_then(|s| s.body),
        ];
        let mut m = if let Some(user) = options.user_meshes.iter().find(|u| u.muscle == name) {
            user_muscle(&name, Path::new(&user.file), &points, bodies, options)?
        } else {
            let mut sweep = options.sweep.clone();
            if let Some((_, r)) = options.radii.iter().find(|(m, _)| *m == name) {
                sweep.radius = Some(*r);
            }
            // Bones near the path: its rings are moved aside out of them,
            // thinned down to the tendon's radius where they must be.
            let belly = sweep.belly_radius(actuator.force);
            let reach = Vec3::splat(belly);
            let (plo, phi) = crate::mesh::bounds_of(&points);
            let near = bones_near((plo - reach, phi + reach));
            let tendon_radius = belly * sweep.tendon_ratio;
            let margin = options.push_out_margin;
            let clear = |c: Vec3, n: Vec3, r: f32, previous: Vec3| {
                clearance::clear_ring(c, n, r, tendon_radius, previous, margin, &near)
            };
            let s = sweep_path_clear_of(&name, &points, actuator.force, &sweep, &clear)?;
            let half = s.rings.len() as u32 / 2;
            let [origin, insertion] = options.rings_held_by(&name).map(|k| k.min(half) as usize);
            let first: Vec<u32> = s.rings[..origin].iter().flatten().copied().collect();
            let last: Vec<u32> = s.rings[s.rings.len() - insertion..]
                .iter()
                .flatten()
                .copied()
                .collect();
            BuiltMuscle {
                name: name.clone(),
                mesh: s.mesh,
                fibers: s.fibers,
                tips: [s.first_tip, s.last_tip],
                ends: [first, last],
                bodies,
                centers: s.centers,
            }
        };
        // Push the surface out of nearby bones (tips and held rings too: they
        // are attached where they end up).
        let near = bones_near(crate::mesh::bounds_of(&m.mesh.positions));
        let mut positions = m.mesh.positions.clone();
        let moved = push_out_of_bones(&mut positions, &m.centers, &near, options.push_out_margin);
        if moved > 0 {
            notes.push(format!("{name}: {moved} vertices pushed out of bones"));
            m.mesh = SurfaceMesh::new(
                m.mesh.source.clone(),
                positions,
                &m.mesh.polygons().map(<[u32]>::to_vec).collect::<Vec<_>>(),
            )?;
        }
        let crossed = m.mesh.self_crossings(&m.mesh.positions);
        if crossed > 0 {
            notes.push(format!(
                "{name}: its surface crosses itself at rest ({crossed} triangle pairs): its edges' rest lengths are a crumpled surface's (a thinner belly, `radii`, crosses less)"
            ));
        }
        built.push(m);
    }

    // Targets by neighbourhood.
    let boxes: Vec<Bounds> = built
        .iter()
        .map(|m| crate::mesh::bounds_of(&m.mesh.positions))
        .collect();
    let reach = options.neighbour_distance;
    let mut targets: Vec<Vec<String>> = Vec::with_capacity(built.len());
    let mut used_bones = vec![false; model.bodies.len()];
    for (i, m) in built.iter().enumerate() {
        if let Some(o) = options.targets.iter().find(|o| o.muscle == m.name) {
            targets.push(o.targets.clone());
            continue;
        }
        let grown = (
            boxes[i].0 - Vec3::splat(reach),
            boxes[i].1 + Vec3::splat(reach),
        );
        let mut muscles: Vec<(f32, usize)> = Vec::new();
        for (j, o) in built.iter().enumerate() {
            if j == i || !overlap(grown, boxes[j]) {
                continue;
            }
            let d = m
                .mesh
                .positions
                .iter()
                .flat_map(|p| o.mesh.positions.iter().map(move |q| p.distance_squared(*q)))
                .fold(f32::INFINITY, f32::min)
                .sqrt();
            if d <= reach {
                muscles.push((d, j));
            }
        }
        muscles.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut bones: Vec<(f32, usize)> = Vec::new();
        for (b, t) in bone_targets.iter().enumerate() {
            let (Some(t), Some(bounds)) = (t, bone_boxes[b]) else {
                continue;
            };
            if !overlap(grown, bounds) {
                continue;
            }
            let d = m
                .mesh
                .positions
                .iter()
                .filter_map(|&p| t.closest_within(p, None, reach))
                .map(|h| h.distance)
                .fold(f32::INFINITY, f32::min);
            if d <= reach {
                bones.push((d, b));
            }
        }
        bones.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut list: Vec<String> = bones
            .iter()
            .take(options.bone_targets)
            .map(|&(_, b)| {
                used_bones[b] = true;
                model.bodies[b].name.clone()
            })
            .collect();
        list.extend(
            muscles
                .iter()
                .take(options.muscle_targets)
                .map(|&(_, j)| built[j].name.clone()),
        );
        targets.push(list);
    }
    for m in &built {
        for b in m.bodies.iter().flatten() {
            used_bones[*b] = true;
        }
    }
    for t in targets.iter().flatten() {
        if let Some(b) = model.body_index(t) {
            used_bones[b] = true;
        }
    }

    // Files.
    let out_dir = scene_dir.join(mesh_dir);
    std::fs::create_dir_all(&out_dir).map_err(|source| ImportError::Io {
        file: out_dir.clone(),
        source,
    })?;
    let mut files = Vec::new();
    let mut bones = Vec::with_capacity(model.bodies.len());
    for (b, body) in model.bodies.iter().enumerate() {
        let wanted = options.bone_meshes == BoneMeshes::All || used_bones[b];
        let shape = match (&geometry[b], wanted) {
            (Some(g), true) => {
                let rel = mesh_dir.join(format!("{}.obj", body.name));
                let triangles = g.triangles.iter().map(<[u32; 3]>::as_slice);
                write_obj(&scene_dir.join(&rel), &g.positions, triangles)?;
                files.push(scene_dir.join(&rel));
                Some(BoneShape::Mesh {
                    file: path_string(&rel),
                    scale: 1.0,
                    orient_outward: false,
                })
            }
            _ => None,
        };
        bones.push(BoneSpec {
            name: body.name.clone(),
            shape,
            body: Some(body.name.clone()),
            ..Default::default()
        });
    }
    let mut muscles = Vec::with_capacity(built.len());
    for (m, targets) in built.into_iter().zip(targets) {
        let rel = mesh_dir.join(format!("{}.obj", m.name));
        write_obj(&scene_dir.join(&rel), &m.mesh.positions, m.mesh.polygons())?;
        files.push(scene_dir.join(&rel));
        let mut attachments = Vec::new();
        for (end, body) in m.bodies.iter().enumerate() {
            let bone = body.map(|b| model.bodies[b].name.clone());
            for &v in std::iter::once(&m.tips[end]).chain(&m.ends[end]) {
                attachments.push(AttachmentSpec {
                    bone: bone.clone(),
                    vertex: Some(v),
                    ..Default::default()
                });
            }
        }
        muscles.push(MuscleSpec {
            name: m.name,
            mesh: MeshSource::File {
                path: path_string(&rel),
                triangulate: false,
                scale: 1.0,
                orient_outward: false,
                translation: glam::Vec3::ZERO,
            },
            roots: Roots::Vertices(m.tips.to_vec()),
            attachments,
            targets,
            params: options.params.clone(),
            maps: VertexMaps {
                fibers: Some(m.fibers),
                ..Default::default()
            },
            ..Default::default()
        });
    }
    Ok(Imported {
        scene: Scene {
            name: model
                .file
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default(),
            frames: 600,
            bones,
            muscles,
            skeleton: Some(skeleton),
            ..Default::default()
        },
        files,
        notes,
    })
}

/// An axis-aligned box: `(min, max)`.
type Bounds = (Vec3, Vec3);

/// Whether two boxes overlap (touching counts).
fn overlap(a: Bounds, b: Bounds) -> bool {
    (a.0.cmple(b.1) & a.1.cmpge(b.0)).all()
}

/// The vertices within `rings` edges of `tip` on `mesh`, `tip` left out,
/// nearest first (a user mesh's held rings: its rings are the tip's
/// neighbours, theirs, …).
fn rings_around(mesh: &SurfaceMesh, tip: u32, rings: u32) -> Vec<u32> {
    let reached = mesh.breadth_first(&[tip]).into_iter().skip(1);
    let within = reached.take_while(|&(_, hops)| hops <= rings);
    within.map(|(v, _)| v).collect()
}

/// A user-supplied muscle mesh: roots at the vertices nearest the path's
/// ends, those plus the rings around them that the options hold
/// ([`ImportOptions::rings_held_by`]), fibres along the path.
fn user_muscle(
    name: &str,
    file: &Path,
    points: &[Vec3],
    bodies: [Option<usize>; 2],
    options: &ImportOptions,
) -> Result<BuiltMuscle, ImportError> {
    let mesh = load_mesh(file, &LoadOptions::default())?;
    mesh.check_closed_manifold()?;
    if points.len() < 2 {
        return Err(ImportError::Path {
            muscle: name.to_string(),
            reason: format!("path has {} point(s); need at least 2", points.len()),
        });
    }
    let tip = |p: Vec3| crate::muscle::nearest_vertex(&mesh.positions, p);
    let tips = [tip(points[0]), tip(points[points.len() - 1])];
    let held = options.rings_held_by(name);
    let ends = [0, 1].map(|e| rings_around(&mesh, tips[e], held[e]));
    // Direction of, and nearest point on, the path segment nearest to each vertex.
    let (fibers, centers) = mesh
        .positions
        .iter()
        .map(|&p| {
            points
                .windows(2)
                .map(|w| {
                    let d = w[1] - w[0];
                    let t = ((p - w[0]).dot(d) / d.length_squared().max(1e-12)).clamp(0.0, 1.0);
                    let q = w[0] + d * t;
                    (q.distance_squared(p), d.normalize_or_zero(), q)
                })
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .map_or((Vec3::X, p), |(_, d, q)| (d, q))
        })
        .unzip();
    Ok(BuiltMuscle {
        name: name.to_string(),
        mesh,
        fibers,
        tips,
        ends,
        bodies,
        centers,
    })
}

fn path_string(p: &Path) -> String {
    p.to_string_lossy().replace('\\', "/")
}

/// Writes positions and polygons as a Wavefront OBJ (6 decimals: µm).
pub fn write_obj<'a>(
    path: &Path,
    positions: &[Vec3],
    polygons: impl IntoIterator<Item = &'a [u32]>,
) -> Result<(), ImportError> {
    let mut text = String::from("# written by sinew\n");
    crate::mesh::append_obj(&mut text, positions, polygons, 1, Some(6));
    crate::atomic_file::write(path, text).map_err(|source| ImportError::Io {
        file: path.to_path_buf(),
        source,
    })
}
