//! [`ImportRecipe`]: the RON file that makes a whole reference scene
//! reproducible with one command (`sinew import-mjcf recipe.ron`).

use super::*;

/// A model attached to the main one at a site.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AttachModel {
    /// MJCF file, relative to the recipe.
    pub model: String,
    /// Site of the main model the child's root bodies hang from.
    pub site: String,
    /// Reflect the child (right → left).
    pub mirror: bool,
}

/// The same activation stack for several muscles.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MuscleDrive {
    /// Muscle names.
    pub muscles: Vec<String>,
    /// Layers (see [`crate::sensor`]).
    pub layers: Vec<ActivationLayer>,
}

/// Everything that makes a reference scene from an MJCF model, in one RON file:
/// `sinew import-mjcf recipe.ron` regenerates the scene and its meshes.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImportRecipe {
    /// Scene name.
    pub name: String,
    /// Scene description.
    pub description: String,
    /// Frames a bake or benchmark runs.
    pub frames: u32,
    /// Main MJCF file, relative to the recipe.
    pub model: String,
    /// Models attached to it (composition, mirroring).
    pub attach: Vec<AttachModel>,
    /// Import options.
    pub options: ImportOptions,
    /// Solver settings of the scene.
    pub settings: SolverSettings,
    /// Joint animation.
    pub motion: Vec<JointMotion>,
    /// Sensors.
    pub sensors: Vec<SensorSpec>,
    /// Activation stacks.
    pub drives: Vec<MuscleDrive>,
    /// Constant activation curves `(muscle, curve)` for muscles not driven.
    pub activation: Vec<(String, Curve)>,
    /// Extra bones (e.g. a ground plane), with the muscles that target them.
    pub extra_bones: Vec<(BoneSpec, Vec<String>)>,
    /// Output scene file, relative to the recipe.
    pub scene: String,
    /// Output mesh directory, relative to the scene file.
    pub meshes: String,
}

impl ImportRecipe {
    /// Reads a recipe.
    pub fn load(path: &Path) -> Result<Self, ImportError> {
        let text = std::fs::read_to_string(path).map_err(|source| ImportError::Io {
            file: path.to_path_buf(),
            source,
        })?;
        Ok(crate::ron_text::parse(&text, path)?)
    }

    /// Imports, builds and writes the scene; returns it with its path and
    /// the solver it was checked with (instantiated once, before writing).
    pub fn run(
        &self,
        recipe_path: &Path,
    ) -> Result<(Imported, PathBuf, crate::Solver), ImportError> {
        let base = recipe_path.parent().unwrap_or(Path::new("."));
        let mut model = MjcfModel::load(&base.join(&self.model))?;
        for a in &self.attach {
            let child = MjcfModel::load(&base.join(&a.model))?;
            model.attach(&child, &a.site, a.mirror)?;
        }
        let scene_path = base.join(&self.scene);
        let scene_dir = scene_path.parent().unwrap_or(Path::new(".")).to_path_buf();
        let mut options = self.options.clone();
        for u in &mut options.user_meshes {
            u.file = path_string(&base.join(&u.file));
        }
        let mut imported = import_model(&model, &options, &scene_dir, Path::new(&self.meshes))?;
        let scene = &mut imported.scene;
        scene.name = self.name.clone();
        scene.description = self.description.clone();
        scene.frames = self.frames;
        scene.settings = self.settings.clone();
        if let Some(sk) = &mut scene.skeleton {
            sk.motion = self.motion.clone();
        }
        scene.sensors = self.sensors.clone();
        let muscle = |name: &str, scene: &mut Scene| -> Result<usize, ImportError> {
            scene
                .muscles
                .iter()
                .position(|m| m.name == name)
                .ok_or_else(|| ImportError::UnknownName {
                    context: format!("recipe {}", recipe_path.display()),
                    kind: "muscle",
                    name: name.to_string(),
                })
        };
        for d in &self.drives {
            for name in &d.muscles {
                let i = muscle(name, scene)?;
                scene.muscles[i].drive = d.layers.clone();
            }
        }
        for (name, curve) in &self.activation {
            let i = muscle(name, scene)?;
            scene.muscles[i].activation = Some(curve.clone());
        }
        for (bone, users) in &self.extra_bones {
            scene.bones.push(bone.clone());
            for name in users {
                let i = muscle(name, scene)?;
                scene.muscles[i].targets.push(bone.name.clone());
            }
        }
        // Check it loads before writing it.
        let solver = scene.instantiate(&scene_dir)?;
        scene.save(&scene_path)?;
        imported.files.push(scene_path.clone());
        Ok((imported, scene_path, solver))
    }
}
