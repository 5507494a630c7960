//! Baking a simulation for DCCs (Blender, Maya, Houdini, 3ds Max).
//!
//! A [`Bake`] records a [`Solver`] frame after frame into any of three
//! [`BakeFormat`]s, all in one folder:
//!
//! - [`BakeFormat::Obj`]: `frame_0000.obj`, `frame_0001.obj`, … — every
//!   muscle's surface per frame, one OBJ object per muscle, scene units.
//! - [`BakeFormat::Pc2`]: one `.pc2` point cache per muscle
//!   (`<muscle>.pc2`, see [`pc2`]): its surface vertices per frame, sample
//!   `k` = frame `k` (start frame 0, one sample per frame).
//! - [`BakeFormat::Glb`]: `scene.glb` — every muscle's surface at the first
//!   frame (the mesh its `.pc2` deforms, same vertex order; the node's
//!   `extras.sinew_pc2` names the cache), the skeleton's bodies as a node
//!   hierarchy and every bone with its mesh under its body, their poses
//!   animated over the bake (one key per frame, `dt` apart).
//!
//! `.pc2` and `.glb` are in metres and glTF's axes (+Y up), whatever the
//! scene's `length_unit`. A Y-up DCC (Maya, Houdini) reads the caches as they
//! are; Blender imports the `.glb` Z-up and plays a cache with the Mesh Cache
//! modifier set to *Forward* +Z, *Up* −Y (its axes say where Blender's +Y and
//! +Z lie in the file). `scripts/blender/check_bake.py` plays a bake in
//! Blender 3.4 and checks it to 1e-5 m.

pub mod pc2;
mod scene_glb;

use crate::mesh::ObjObjects;
use crate::solver::Solver;
use glam::{Affine3A, Vec3};
use pc2::Pc2Writer;
use scene_glb::{MeshRecord, NodeRecord};
use std::collections::HashSet;
use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;
use thiserror::Error;

/// A bake could not be written or read.
#[derive(Debug, Error)]
pub enum BakeError {
    /// A file or folder could not be created, written or read.
    #[error("{file}: {source}")]
    Io {
        /// Offending file or folder.
        file: PathBuf,
        /// Underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The output folder already holds files of a bake: a new bake would
    /// mix its frames with theirs.
    #[error(
        "{folder}: already holds {count} bake file(s), e.g. {file}; choose an empty folder, replace them (`sinew bake --replace`) or continue an interrupted bake (`--resume`)"
    )]
    Existing {
        /// The output folder.
        folder: PathBuf,
        /// One of the files found.
        file: PathBuf,
        /// How many bake files it holds.
        count: usize,
    },
    /// A file's contents, or what was asked of it, are wrong.
    #[error("{file}: {element}: {reason}")]
    Invalid {
        /// Offending file.
        file: PathBuf,
        /// The element (header, sample, muscle).
        element: String,
        /// What is wrong.
        reason: String,
    },
}

/// What a [`Bake`] writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BakeFormat {
    /// One Wavefront OBJ per frame with every muscle (scene units).
    Obj,
    /// One `.pc2` point cache per muscle (metres).
    Pc2,
    /// `scene.glb`: rest meshes and the animated bones (metres).
    Glb,
}

impl BakeFormat {
    /// Every format, in the order of their names.
    pub const ALL: [Self; 3] = [Self::Obj, Self::Pc2, Self::Glb];

    /// The format's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Obj => "obj",
            Self::Pc2 => "pc2",
            Self::Glb => "glb",
        }
    }
}

impl fmt::Display for BakeFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for BakeFormat {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|f| f.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| format!("unknown bake format '{s}' (obj, pc2, glb)"))
    }
}

/// Name of the bake's `.glb` in its folder.
pub const GLB_FILE: &str = "scene.glb";

/// The OBJ file of frame `frame` in a bake folder.
pub fn obj_file_name(frame: u32) -> String {
    format!("frame_{frame:04}.obj")
}

/// A bake in progress: [`Bake::start`] records the solver's current state as
/// frame 0, [`Bake::record`] each later frame, [`Bake::finish`] completes the
/// files.
#[derive(Debug)]
pub struct Bake {
    out: PathBuf,
    formats: HashSet<BakeFormat>,
    /// Scene units per metre.
    unit: f32,
    dt: f32,
    frame: u32,
    caches: Vec<Pc2Writer>,
    muscles: Vec<MeshRecord>,
    /// The skeleton's bodies and the bones, for the `.glb`.
    nodes: Vec<NodeRecord>,
    /// Per recorded frame, every node's pose in its parent (metres).
    poses: Vec<Vec<Affine3A>>,
    /// Scratch for posing the skeleton.
    skeleton_values: Vec<f32>,
    skeleton_world: Vec<Affine3A>,
    files: Vec<PathBuf>,
    /// Frames `0..resumed` are on disk from an interrupted bake: checked
    /// against the simulation, not written again.
    resumed: u32,
}

/// What [`Bake::start_in`] does with bake files already in its folder.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ExistingFiles {
    /// Refuse to start ([`BakeError::Existing`]). Default.
    #[default]
    Refuse,
    /// Delete them first (only bake files: frame OBJs, `.pc2`, the `.glb`
    /// and `.partial` leftovers; nothing else in the folder is touched).
    Replace,
    /// Continue an interrupted bake: the OBJ frames already written
    /// (`frame_0000.obj` on, without a gap) are kept, and as the simulation
    /// passes them again (sinew is deterministic) each is checked against
    /// the file — a difference means the folder holds another bake, an
    /// error; the caches and the `.glb`, which span the whole run, are
    /// written again.
    Resume,
}

/// Whether `name` is a file a bake writes (or its leftover while writing).
fn is_bake_file(name: &str) -> bool {
    let name = name
        .strip_suffix(crate::atomic_file::PARTIAL_SUFFIX)
        .unwrap_or(name);
    let frame_obj = name
        .strip_prefix("frame_")
        .and_then(|n| n.strip_suffix(".obj"))
        .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()));
    frame_obj || name.ends_with(".pc2") || name == GLB_FILE
}

/// The bake files in `folder` (none when it does not exist).
fn bake_files(folder: &Path) -> Result<Vec<PathBuf>, BakeError> {
    let io = |source| BakeError::Io {
        file: folder.to_path_buf(),
        source,
    };
    let Ok(entries) = std::fs::read_dir(folder) else {
        return Ok(Vec::new());
    };
    let mut files = Vec::new();
    for entry in entries {
        let path = entry.map_err(io)?.path();
        if path.is_file()
            && path
                .file_name()
                .and_then(|n| n.to_str())
                .is_some_and(is_bake_file)
        {
            files.push(path);
        }
    }
    files.sort();
    Ok(files)
}

impl Bake {
    /// Creates `out` (and its parents) and records `solver`'s current state
    /// as frame 0 in `formats`; refuses a folder that already holds bake
    /// files (see [`Bake::start_in`]).
    pub fn start(solver: &Solver, out: &Path, formats: &[BakeFormat]) -> Result<Self, BakeError> {
        Self::start_in(solver, out, formats, ExistingFiles::Refuse)
    }

    /// As [`Bake::start`], with `existing` saying what happens to bake files
    /// already in `out`. Every file is written whole or not at all (OBJ
    /// frames and the `.glb` through [`crate::atomic_file`], `.pc2` caches as
    /// `.partial` until [`Bake::finish`]).
    pub fn start_in(
        solver: &Solver,
        out: &Path,
        formats: &[BakeFormat],
        existing: ExistingFiles,
    ) -> Result<Self, BakeError> {
        let found = bake_files(out)?;
        match (existing, found.first()) {
            (ExistingFiles::Refuse, Some(file)) => {
                return Err(BakeError::Existing {
                    folder: out.to_path_buf(),
                    file: file.clone(),
                    count: found.len(),
                });
            }
            (ExistingFiles::Replace | ExistingFiles::Resume, _) => {
                for file in &found {
                    let name = file.file_name().and_then(|n| n.to_str()).unwrap_or("");
                    if existing == ExistingFiles::Resume && name.ends_with(".obj") {
                        continue;
                    }
                    std::fs::remove_file(file).map_err(|source| BakeError::Io {
                        file: file.clone(),
                        source,
                    })?;
                }
            }
            _ => {}
        }
        std::fs::create_dir_all(out).map_err(|source| BakeError::Io {
            file: out.to_path_buf(),
            source,
        })?;
        let formats: HashSet<BakeFormat> = formats.iter().copied().collect();
        let unit = solver.settings.length_unit;
        let in_metres = |p: &[Vec3]| p.iter().map(|&p| p / unit).collect::<Vec<_>>();
        let cache_names = file_names(solver.muscles().iter().map(|m| m.name.as_str()), "pc2");
        let mut caches = Vec::new();
        let mut muscles = Vec::new();
        for (m, cache) in solver.muscles().iter().zip(cache_names) {
            let positions = in_metres(m.surface_positions());
            let cache = formats.contains(&BakeFormat::Pc2).then_some(cache);
            if let Some(cache) = &cache {
                caches.push(Pc2Writer::create(
                    &out.join(cache),
                    positions.len(),
                    0.0,
                    1.0,
                )?);
            }
            muscles.push(MeshRecord {
                name: m.name.clone(),
                triangles: m.mesh.triangles.clone(),
                positions,
                cache,
            });
        }
        let nodes = scene_glb::nodes(solver, unit);
        let mut bake = Self {
            out: out.to_path_buf(),
            formats,
            unit,
            dt: solver.settings.dt,
            frame: 0,
            caches,
            muscles,
            nodes,
            poses: Vec::new(),
            skeleton_values: Vec::new(),
            skeleton_world: Vec::new(),
            files: Vec::new(),
            resumed: 0,
        };
        if existing == ExistingFiles::Resume && bake.formats.contains(&BakeFormat::Obj) {
            bake.resumed = (0..)
                .take_while(|&k| out.join(obj_file_name(k)).is_file())
                .count() as u32;
        }
        bake.files
            .extend(bake.caches.iter().map(|c| c.path().to_path_buf()));
        bake.record(solver)?;
        Ok(bake)
    }

    /// Records `solver`'s current state as the next frame.
    pub fn record(&mut self, solver: &Solver) -> Result<(), BakeError> {
        let bodies = solver.skeleton().map_or(0, |rig| rig.body_count());
        if solver.muscles().len() != self.muscles.len()
            || solver.bones().len() + bodies != self.nodes.len()
        {
            return Err(BakeError::Invalid {
                file: self.out.clone(),
                element: format!("frame {}", self.frame),
                reason: "the solver's muscles or bones changed during the bake".into(),
            });
        }
        if self.formats.contains(&BakeFormat::Obj) {
            let file = self.out.join(obj_file_name(self.frame));
            let text = obj_text(solver);
            if self.frame < self.resumed {
                let io = |source| BakeError::Io {
                    file: file.clone(),
                    source,
                };
                if std::fs::read(&file).map_err(io)? != text.as_bytes() {
                    return Err(BakeError::Invalid {
                        file,
                        element: format!("frame {}", self.frame),
                        reason: "differs from this scene's frame: the folder holds another bake \
                                 (bake elsewhere, or --replace it)"
                            .into(),
                    });
                }
            } else {
                crate::atomic_file::write(&file, text).map_err(|source| BakeError::Io {
                    file: file.clone(),
                    source,
                })?;
            }
            self.files.push(file);
        }
        for (cache, m) in self.caches.iter_mut().zip(solver.muscles()) {
            let positions: Vec<Vec3> = m
                .surface_positions()
                .iter()
                .map(|&p| p / self.unit)
                .collect();
            cache.write_sample(&positions)?;
        }
        if self.formats.contains(&BakeFormat::Glb) {
            self.poses.push(scene_glb::local_poses(
                solver,
                self.unit,
                &mut self.skeleton_values,
                &mut self.skeleton_world,
            ));
        }
        self.frame += 1;
        Ok(())
    }

    /// Frames recorded so far (frame 0 included).
    pub fn frames(&self) -> u32 {
        self.frame
    }

    /// OBJ frames an interrupted bake had written, kept and checked
    /// ([`ExistingFiles::Resume`]; 0 otherwise).
    pub fn resumed(&self) -> u32 {
        self.resumed
    }

    /// Completes the caches and writes the `.glb`; returns every file written.
    pub fn finish(self) -> Result<Vec<PathBuf>, BakeError> {
        for cache in self.caches {
            cache.finish()?;
        }
        let mut files = self.files;
        if self.formats.contains(&BakeFormat::Glb) {
            let file = self.out.join(GLB_FILE);
            let name = self
                .out
                .file_name()
                .map_or_else(|| "sinew".into(), |n| n.to_string_lossy().into_owned());
            let bytes =
                scene_glb::to_bytes(&name, &self.muscles, &self.nodes, &self.poses, self.dt);
            crate::atomic_file::write(&file, bytes).map_err(|source| BakeError::Io {
                file: file.clone(),
                source,
            })?;
            files.push(file);
        }
        Ok(files)
    }
}

/// Every muscle's surface as OBJ text (one object per muscle).
fn obj_text(solver: &Solver) -> String {
    let mut obj = ObjObjects::default();
    for m in solver.muscles() {
        obj.push(&m.name, m.surface_positions(), m.mesh.polygons(), None);
    }
    obj.into_text()
}

/// Writes every muscle's surface to one OBJ file (one object per muscle).
pub fn write_obj(solver: &Solver, path: &Path) -> Result<(), BakeError> {
    crate::atomic_file::write(path, obj_text(solver)).map_err(|source| BakeError::Io {
        file: path.to_path_buf(),
        source,
    })
}

/// A file name with `extension` per name: characters other than letters,
/// digits, `-`, `_` and `.` become `_`, and a name that repeats an earlier
/// one (ignoring case) gets `_2`, `_3`, … so that no two share a file.
pub(crate) fn file_names<'a>(names: impl Iterator<Item = &'a str>, extension: &str) -> Vec<String> {
    let mut taken = HashSet::new();
    names
        .map(|name| {
            let clean: String = name
                .chars()
                .map(|c| {
                    if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') {
                        c
                    } else {
                        '_'
                    }
                })
                .collect();
            let clean = if clean.is_empty() {
                "muscle".into()
            } else {
                clean
            };
            let mut file = format!("{clean}.{extension}");
            let mut k = 2;
            while !taken.insert(file.to_ascii_lowercase()) {
                file = format!("{clean}_{k}.{extension}");
                k += 1;
            }
            file
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cache_names_are_safe_and_distinct() {
        let names = file_names(["BIClong", "a/b", "a:b", "", "biclong"].into_iter(), "pc2");
        assert_eq!(
            names,
            [
                "BIClong.pc2",
                "a_b.pc2",
                "a_b_2.pc2",
                "muscle.pc2",
                "biclong_2.pc2"
            ]
        );
    }

    #[test]
    fn formats_parse_by_name() {
        assert_eq!("PC2".parse(), Ok(BakeFormat::Pc2));
        assert!(
            "fbx"
                .parse::<BakeFormat>()
                .unwrap_err()
                .contains("obj, pc2, glb")
        );
    }
}
