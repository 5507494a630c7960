//! Building muscles from meshes off the main thread.
//!
//! Spawn an entity with a [`MuscleBuilder`]; the plug-in builds the muscle
//! (internal structure, fibres, constraints) on Bevy's async compute pool
//! and, when it is done, inserts [`MuscleState`], [`MuscleSnapshot`] and
//! (if absent) [`Muscle`], and spawns its attachment and connection
//! entities ([`crate::relations`]). The frame never waits for a build. A build that fails leaves a [`BuildFailed`]
//! with the reason and logs it.

use crate::components::*;
use crate::events::{MuscleBuildError, MuscleBuildFailed, MuscleBuilt};
use crate::relations::{spawn_attachments, spawn_connections};
use bevy::prelude::*;
use bevy::tasks::{AsyncComputeTaskPool, Task, futures::check_ready};
use bevy::transform::helper::TransformHelper;
use sinew_core::closest::{TargetSource, TargetSurface};
use sinew_core::glam::Affine3A;
use sinew_core::mesh::primitives::MeshGenerator;
use sinew_core::mesh::{LoadOptions, SurfaceMesh};
use sinew_core::muscle::{
    AttachmentDesc, Muscle as CoreMuscle, MuscleDesc, MuscleParams, Roots, TargetRef, VertexMaps,
};
use std::path::PathBuf;
use std::sync::Arc;

/// Where a muscle's surface comes from.
#[derive(Clone, Debug)]
pub enum MuscleSource {
    /// An OBJ or STL file on disk, loaded with these options.
    File(PathBuf, LoadOptions),
    /// A mesh already in memory.
    Mesh(SurfaceMesh),
    /// A generated mesh (ellipsoid, box, spindle…), built with the muscle.
    Generated(MeshGenerator),
    /// A Bevy mesh asset (triangle list; split vertices are welded). The
    /// build starts once the asset is loaded.
    #[cfg(feature = "render")]
    Handle(Handle<Mesh>),
}

impl MuscleSource {
    /// An OBJ or STL file loaded with the default options (welded, in the
    /// file's units).
    pub fn file(path: impl Into<PathBuf>) -> Self {
        Self::File(path.into(), LoadOptions::default())
    }

    /// A spindle from `start` to `end` with a belly of `belly_radius` (scene
    /// units) tapering to tendons of a quarter of it: 12 vertices around,
    /// 16 rings (≈ 200 vertices), quads along and across its axis.
    pub fn fusiform(start: Vec3, end: Vec3, belly_radius: f32) -> Self {
        Self::Generated(MeshGenerator::Fusiform {
            start,
            end,
            belly_radius,
            tendon_radius: 0.25 * belly_radius,
            around: 12,
            rings: 16,
        })
    }
}

/// Where a muscle is held: a vertex (or the vertex nearest `point`) fixed to
/// a bone (`None`: to the world).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MuscleAttachment {
    /// The bone entity, or `None` for the world.
    pub bone: Option<Entity>,
    /// The vertex index.
    pub vertex: Option<u32>,
    /// Or the vertex nearest this world point.
    pub point: Option<Vec3>,
    /// With `point`: every vertex within this distance of it (a region).
    /// Units: scene units. `0`: the nearest only.
    pub radius: f32,
}

impl MuscleAttachment {
    /// Vertex `vertex` held by `bone`.
    pub fn vertex(bone: Entity, vertex: u32) -> Self {
        Self {
            bone: Some(bone),
            vertex: Some(vertex),
            point: None,
            radius: 0.0,
        }
    }

    /// The vertex nearest `point` held by `bone`.
    pub fn nearest(bone: Entity, point: Vec3) -> Self {
        Self {
            bone: Some(bone),
            vertex: None,
            point: Some(point),
            radius: 0.0,
        }
    }

    /// Every vertex within `radius` of `point` (at least the nearest) held
    /// by `bone`: a tendon's end without vertex indices.
    pub fn region(bone: Entity, point: Vec3, radius: f32) -> Self {
        Self {
            bone: Some(bone),
            vertex: None,
            point: Some(point),
            radius,
        }
    }
}

/// A muscle to build: its mesh, root selection, attachments, targets and
/// parameters. Replaced by the built state when done.
#[derive(Component, Clone, Debug)]
pub struct MuscleBuilder {
    /// Name (messages, sensors, the panel).
    pub name: String,
    /// The surface mesh (world coordinates).
    pub source: MuscleSource,
    /// The vertices the internal structure grows from.
    pub roots: Roots,
    /// Where it is held.
    pub attachments: Vec<MuscleAttachment>,
    /// Bones (with a [`BoneTarget`]) and muscles it slides on.
    pub targets: Vec<Entity>,
    /// Build-time and initial parameters.
    pub params: MuscleParams,
    /// The bone whose frame the mesh and the attachment points are given
    /// in (`None`: the world). See [`MuscleBuilder::placed_on`].
    pub frame: Option<Entity>,
    /// Per-vertex maps (one value per surface vertex, after welding). A
    /// [`MuscleSource::Handle`] mesh adds those its vertex attributes
    /// carry ([`crate::mesh_maps`]); a map given here wins.
    pub maps: VertexMaps,
    /// Where a mesh asset's maps come from besides sinew's attributes.
    #[cfg(feature = "render")]
    pub maps_from: crate::mesh_maps::MapsFromMesh,
}

impl MuscleBuilder {
    /// A muscle called `name` from `source`, default parameters, roots at
    /// its attachments.
    pub fn new(name: impl Into<String>, source: MuscleSource) -> Self {
        Self {
            name: name.into(),
            source,
            roots: Roots::Attachments,
            attachments: Vec::new(),
            targets: Vec::new(),
            frame: None,
            params: MuscleParams::default(),
            maps: VertexMaps::default(),
            #[cfg(feature = "render")]
            maps_from: Default::default(),
        }
    }

    /// Roots of the internal structure.
    pub fn roots(mut self, roots: Roots) -> Self {
        self.roots = roots;
        self
    }

    /// Adds an attachment.
    pub fn attach(mut self, attachment: MuscleAttachment) -> Self {
        self.attachments.push(attachment);
        self
    }

    /// Adds a target (a bone with a [`BoneTarget`] or another muscle).
    pub fn target(mut self, target: Entity) -> Self {
        self.targets.push(target);
        self
    }

    /// The mesh and every attachment point are in `bone`'s frame (scene
    /// units): the muscle is built where that bone is when the build starts,
    /// whatever pose an animation has it in — e.g. a muscle authored on a
    /// glTF character's joint at its bind pose.
    pub fn placed_on(mut self, bone: Entity) -> Self {
        self.frame = Some(bone);
        self
    }

    /// Sets the parameters.
    pub fn params(mut self, params: MuscleParams) -> Self {
        self.params = params;
        self
    }

    /// Sets the per-vertex maps.
    pub fn maps(mut self, maps: VertexMaps) -> Self {
        self.maps = maps;
        self
    }

    /// Reads a mesh asset's Sliding / Soft / Hard weights from its vertex
    /// colours (red, green, blue).
    #[cfg(feature = "render")]
    pub fn weights_from_colors(mut self) -> Self {
        self.maps_from.colors = true;
        self
    }
}

/// A build that failed, with the reason (also logged, and sent as
/// [`MuscleBuildFailed`]).
#[derive(Component, Clone, Debug)]
pub struct BuildFailed(pub Arc<MuscleBuildError>);

/// A muscle built from a [`MuscleBuilder`] as it was built: what
/// [`crate::ResetSimulation`] puts back (scene muscles are respawned with
/// their scene instead).
#[derive(Component, Clone, Debug)]
pub(crate) struct MuscleAtBuild(pub(crate) CoreMuscle);

/// A muscle surface made on the build task (file reading and generation
/// stay off the main thread).
enum Deferred {
    File(PathBuf, LoadOptions),
    Generated(MeshGenerator),
}

/// A build in flight.
#[derive(Component)]
pub(crate) struct BuildTask {
    task: Task<Result<CoreMuscle, MuscleBuildError>>,
    bones: Vec<Entity>,
    targets: Vec<Entity>,
}

/// Starts the builds of new [`MuscleBuilder`]s whose inputs are ready.
pub(crate) fn start_builds(
    mut commands: Commands,
    builders: Query<(Entity, &MuscleBuilder), Without<BuildTask>>,
    bones: Query<(&BonePose, &GlobalTransform)>,
    hierarchy: TransformHelper,
    settings: Res<crate::settings::SinewSettings>,
    #[cfg(feature = "render")] meshes: Option<Res<Assets<Mesh>>>,
) {
    for (entity, builder) in &builders {
        let mut maps = builder.maps.clone();
        let mesh = match &builder.source {
            MuscleSource::File(path, options) => Err(Deferred::File(path.clone(), options.clone())),
            MuscleSource::Generated(generator) => Err(Deferred::Generated(generator.clone())),
            MuscleSource::Mesh(mesh) => Ok(mesh.clone()),
            #[cfg(feature = "render")]
            MuscleSource::Handle(handle) => match meshes.as_ref().and_then(|m| m.get(handle)) {
                Some(mesh) => {
                    match crate::mesh_maps::surface_and_maps(&builder.name, mesh, builder.maps_from)
                    {
                        Ok((mesh, painted)) => {
                            maps = maps.or(painted);
                            Ok(mesh)
                        }
                        Err(reason) => {
                            let muscle = builder.name.clone();
                            let error = MuscleBuildError::MeshAsset { muscle, reason };
                            fail(&mut commands, entity, error);
                            continue;
                        }
                    }
                }
                None => continue, // not loaded yet
            },
        };
        // A bone's pose now (`None`: not a bone). A bone the simulation has
        // not read yet may be new this frame, its `GlobalTransform` not yet
        // propagated (e.g. a joint of a glTF scene spawned this frame): its
        // pose comes from its and its ancestors' `Transform`s.
        let pose_of = |b: Entity| match bones.get(b) {
            Ok((pose, _)) if pose.initialized => Some(pose.current),
            Ok((_, global)) => Some(
                hierarchy
                    .compute_global_transform(b)
                    .map_or(global.affine(), |g| g.affine()),
            ),
            Err(_) => None,
        };
        let mut missing = None;
        // The frame the mesh and attachment points are given in.
        let frame = match builder.frame {
            Some(b) => pose_of(b).unwrap_or_else(|| {
                missing = Some(b);
                Affine3A::IDENTITY
            }),
            None => Affine3A::IDENTITY,
        };
        // Attachment bones by local index, with their poses now.
        let mut bone_entities: Vec<Entity> = Vec::new();
        let mut poses: Vec<Affine3A> = Vec::new();
        let mut attachments = Vec::new();
        for a in &builder.attachments {
            let bone = a
                .bone
                .map(|b| match bone_entities.iter().position(|&e| e == b) {
                    Some(i) => i,
                    None => {
                        poses.push(pose_of(b).unwrap_or_else(|| {
                            missing = Some(b);
                            Affine3A::IDENTITY
                        }));
                        bone_entities.push(b);
                        bone_entities.len() - 1
                    }
                });
            attachments.push(AttachmentDesc {
                bone,
                vertex: a.vertex,
                point: a.point.map(|p| frame.transform_point3(p)),
                radius: a.radius,
            });
        }
        if let Some(bone) = missing {
            let muscle = builder.name.clone();
            fail(
                &mut commands,
                entity,
                MuscleBuildError::MissingBone { muscle, bone },
            );
            continue;
        }
        let name = builder.name.clone();
        let roots = builder.roots.clone();
        let params = builder.params.clone();
        let length_unit = settings.length_unit;
        let task = AsyncComputeTaskPool::get().spawn(async move {
            let mut mesh = match mesh {
                Ok(mesh) => mesh,
                Err(Deferred::File(path, options)) => SurfaceMesh::load(&path, &options)?,
                Err(Deferred::Generated(generator)) => generator.build(&name)?,
            };
            if frame != Affine3A::IDENTITY {
                for p in &mut mesh.positions {
                    *p = frame.transform_point3(*p);
                }
            }
            let desc = MuscleDesc {
                name,
                mesh,
                roots,
                attachments,
                // Targets are the driver's business (connection entities).
                targets: Vec::<TargetRef>::new(),
                params,
                maps,
                // Muscles are not skin-bound; a skin layer is built apart.
                binding: None,
            };
            Ok(CoreMuscle::build(desc, length_unit, |b| poses[b])?)
        });
        commands
            .entity(entity)
            .remove::<MuscleBuilder>()
            .insert(BuildTask {
                task,
                bones: bone_entities,
                targets: builder.targets.clone(),
            });
    }
}

/// Marks `entity`'s build failed: [`BuildFailed`] on it, logged, sent as
/// [`MuscleBuildFailed`] (message and entity event).
fn fail(commands: &mut Commands, entity: Entity, error: MuscleBuildError) {
    error!("sinew: a muscle could not be built: {error}");
    let error = Arc::new(error);
    commands
        .entity(entity)
        .remove::<MuscleBuilder>()
        .insert(BuildFailed(error.clone()));
    let failed = MuscleBuildFailed { entity, error };
    commands.write_message(failed.clone());
    commands.trigger(failed);
}

/// Inserts the built state of finished builds.
pub(crate) fn finish_builds(
    mut commands: Commands,
    mut tasks: Query<(Entity, &mut BuildTask, Option<&Muscle>)>,
) {
    for (entity, mut build, muscle) in &mut tasks {
        let Some(result) = check_ready(&mut build.task) else {
            continue;
        };
        commands.entity(entity).remove::<BuildTask>();
        match result {
            Ok(built) => {
                let mut e = commands.entity(entity);
                let live = muscle
                    .cloned()
                    .unwrap_or_else(|| Muscle::from_params(&built.params));
                e.insert((live, muscle_snapshot(&built), MuscleAtBuild(built.clone())));
                let bones = std::mem::take(&mut build.bones);
                spawn_attachments(&mut commands, entity, &built, |b| bones[b]);
                spawn_connections(&mut commands, entity, build.targets.drain(..));
                commands.entity(entity).insert(MuscleState::new(built));
                commands.write_message(MuscleBuilt { entity });
                commands.trigger(MuscleBuilt { entity });
            }
            Err(error) => fail(&mut commands, entity, error),
        }
    }
}

/// The snapshot other muscles see `m` through.
pub fn muscle_snapshot(m: &CoreMuscle) -> MuscleSnapshot {
    let mut surface = TargetSurface::new(
        m.name.clone(),
        TargetSource::Muscle(0),
        m.surface_positions().to_vec(),
        m.mesh.triangles.clone(),
    );
    surface.set_transform(Affine3A::IDENTITY);
    MuscleSnapshot {
        surface,
        targeted: false,
    }
}
