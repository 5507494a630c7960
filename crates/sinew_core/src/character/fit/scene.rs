//! A fitted anatomy as a scene on the character: the character's joints as
//! the skeleton (its clip as the motion), every bone following the joint of
//! its segment with its fitted mesh, the muscles' fitted meshes as their
//! rest shapes.

use super::{AnatomyFit, FittedGeometry};
use crate::character::{CharacterError, ClipPlayback, JointClip, SkinnedCharacter};
use crate::mesh::ObjObjects;
use crate::muscle::HoldFrame;
use crate::scene::{AttachmentSpec, BoneShape, MeshSource, Scene};
use crate::sensor::{BonePoint, SensorKind};
use crate::solver::Solver;
use glam::Vec3;

/// A scene and the mesh files it names ([`AnatomyFit::scene`]).
#[derive(Clone, Debug)]
pub struct FittedScene {
    /// The scene; its mesh paths are relative to the scene file.
    pub scene: Scene,
    /// `(path relative to the scene file, OBJ text)` for every mesh.
    pub meshes: Vec<(String, String)>,
}

impl FittedScene {
    /// Writes the scene to `path` and its meshes beside it (the folders
    /// created); errors name the file or folder.
    pub fn save(&self, path: &std::path::Path) -> Result<(), CharacterError> {
        let io = |file: std::path::PathBuf| {
            move |source: std::io::Error| CharacterError::Io { file, source }
        };
        let dir = path.parent().unwrap_or(std::path::Path::new(""));
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir).map_err(io(dir.to_path_buf()))?;
        }
        for (file, text) in &self.meshes {
            let file = dir.join(file);
            if let Some(folder) = file.parent() {
                std::fs::create_dir_all(folder).map_err(io(folder.to_path_buf()))?;
            }
            crate::atomic_file::write(&file, text).map_err(io(file.clone()))?;
        }
        let text = self.scene.to_ron().map_err(|e| CharacterError::Invalid {
            character: self.scene.name.clone(),
            element: "scene".into(),
            reason: e.to_string(),
        })?;
        crate::atomic_file::write(path, text).map_err(io(path.to_path_buf()))
    }
}

/// How a fitted muscle whose anatomy holds no shape is held under the
/// skin: [`crate::muscle::MuscleParams::hold_release`] and
/// [`crate::muscle::MuscleParams::hold_frame`]. Its shape follows its line
/// of action, as T5's arm does, and the hold lets a contracting muscle go
/// down to a fifth. At full flexion of the MakeHuman's elbows
/// (`--clip elbow_flex`) the skin over the biceps' long and short heads
/// stands 5.62 / 6.67 mm (right) and 5.24 / 8.89 mm (left) out of plain
/// skinning (Colored: 5.58 / 6.56 and 5.20 / 7.14 mm); held at full
/// strength on a blend of its bones 4.89 / 4.65 and 6.32 / 3.33 mm, on
/// the line released to a tenth (T5's) 5.29 / 6.10 and 5.85 / 6.41 mm
/// (Colored: 4.59 mm over the left long head).
pub const HELD_UNDER_SKIN: (f32, HoldFrame) = (0.2, HoldFrame::Line);

impl AnatomyFit {
    /// The scene of `anatomy` (built as `solver`, in metres) fitted to
    /// `character` (`geometry`: this fit's bones and muscles, pulled inside
    /// the skin or not), playing `clip` as `playback` says.
    ///
    /// - skeleton: the character's ([`SkinnedCharacter::skeleton`]);
    /// - bones: each follows the joint of its body's segment (bodies with
    ///   no segment: the character's first joint), its fitted mesh in that
    ///   joint's frame (`meshes/NAME.obj`); tracks are dropped;
    /// - muscles: their fitted surfaces (`meshes/NAME.obj`, same vertex
    ///   order and polygons), attachments as the vertices the anatomy's
    ///   resolved to, holding their shape on their bones
    ///   ([`crate::muscle::MuscleParams::hold_shape`]: a limb turned
    ///   sideways by the clip would otherwise let what no target holds
    ///   sag out of the skin) — where `anatomy` holds none, as
    ///   [`HELD_UNDER_SKIN`] says — everything else as in `anatomy`;
    /// - sensors: their points moved with their bones.
    ///
    /// Errors: an anatomy not in metres (`length_unit` ≠ 1).
    pub fn scene(
        &self,
        anatomy: &Scene,
        solver: &Solver,
        geometry: &FittedGeometry,
        character: &SkinnedCharacter,
        clip: Option<&JointClip>,
        playback: &ClipPlayback,
    ) -> Result<FittedScene, CharacterError> {
        if solver.settings.length_unit != 1.0 {
            return Err(CharacterError::Invalid {
                character: character.name.clone(),
                element: format!("scene {}", anatomy.name),
                reason: format!(
                    "length_unit {} (a fit needs an anatomy in metres)",
                    solver.settings.length_unit
                ),
            });
        }
        let joint_of_bone = |b: usize| {
            let joint = solver.bones()[b]
                .body
                .and_then(|body| self.segment_of.get(body).copied().flatten())
                .and_then(|k| character.joint(&self.segments[k].joint))
                .unwrap_or(0);
            (
                character.joints[joint].name.clone(),
                character.joints[joint].origin,
            )
        };
        let names = solver
            .bones()
            .iter()
            .map(|b| b.name.as_str())
            .chain(solver.muscles().iter().map(|m| m.name.as_str()));
        let files: Vec<String> = crate::bake::file_names(names, "obj")
            .into_iter()
            .map(|f| format!("meshes/{f}"))
            .collect();
        let mut meshes = Vec::new();
        let mut scene = anatomy.clone();
        scene.name = format!("{} on {}", anatomy.name, character.name);
        scene.description = format!(
            "{} fitted to the character {}, playing {}.",
            anatomy.name,
            character.name,
            clip.map_or("its bind pose".to_string(), |c| format!(
                "its clip {}",
                c.name
            ))
        );
        scene.frames = (playback.until / solver.settings.dt).round().max(1.0) as u32;
        scene.skeleton = Some(character.skeleton(clip, playback));
        for (b, spec) in scene.bones.iter_mut().enumerate() {
            let (joint, origin) = joint_of_bone(b);
            spec.body = Some(joint);
            spec.track = Default::default();
            if let Some((_, points)) = geometry.bones.iter().find(|(g, _)| *g == b) {
                let target = solver.bones()[b].target.expect("a fitted bone has a mesh");
                let local: Vec<Vec3> = points.iter().map(|&p| p - origin).collect();
                let mut obj = ObjObjects::default();
                let triangles = solver.targets()[target].triangles();
                obj.push(
                    &spec.name,
                    &local,
                    triangles.iter().map(|t| t.as_slice()),
                    None,
                );
                meshes.push((files[b].clone(), obj.into_text()));
                spec.shape = Some(BoneShape::Mesh {
                    file: files[b].clone(),
                    scale: 1.0,
                    orient_outward: false,
                });
            }
        }
        let bone_count = solver.bones().len();
        for (k, (spec, m)) in scene.muscles.iter_mut().zip(solver.muscles()).enumerate() {
            let mut obj = ObjObjects::default();
            obj.push(&m.name, &geometry.muscles[k], m.mesh.polygons(), None);
            let file = files[bone_count + k].clone();
            meshes.push((file.clone(), obj.into_text()));
            spec.mesh = MeshSource::File {
                path: file,
                triangulate: false,
                scale: 1.0,
                orient_outward: false,
                translation: glam::Vec3::ZERO,
            };
            if !spec.params.hold_shape {
                let (release, frame) = HELD_UNDER_SKIN;
                spec.params.hold_shape = true;
                spec.params.hold_release = release;
                spec.params.hold_frame = frame;
            }
            spec.attachments = m
                .attachments
                .iter()
                .map(|a| AttachmentSpec {
                    bone: a.bone.map(|b| solver.bones()[b].name.clone()),
                    vertex: Some(a.vertex.index() as u32),
                    point: None,
                    radius: 0.0,
                })
                .collect();
        }
        let move_point = |p: &mut BonePoint| {
            let Some(b) = solver.bone_index(&p.bone) else {
                return;
            };
            let bone = &solver.bones()[b];
            let world = bone.transform.transform_point3(p.point);
            let fit = bone
                .body
                .map_or(super::Similarity::IDENTITY, |body| self.body(body));
            p.point = fit.apply(world) - joint_of_bone(b).1;
        };
        for sensor in &mut scene.sensors {
            match &mut sensor.kind {
                SensorKind::Distance { a, b } => [a, b].into_iter().for_each(move_point),
                SensorKind::Rotation { a, middle, c } => {
                    [a, middle, c].into_iter().for_each(move_point)
                }
                SensorKind::Linear { point } => move_point(point),
            }
        }
        Ok(FittedScene { scene, meshes })
    }
}
