//! `import-makehuman`: the MakeHuman base mesh and rig → a skinned `.glb`;
//! `fit`: an anatomy scene fitted to a skinned character.

use sinew_core::Solver;
use sinew_core::character::fit::{FitOptions, FittedAnatomy, RigMap, SkinLayer, fit_anatomy};
use sinew_core::character::makehuman::{self, MakeHumanOptions};
use sinew_core::character::{ClipPlayback, SkinnedCharacter, glb};
use sinew_core::glam::Vec3;
use sinew_core::mesh::ObjObjects;
use sinew_core::scene::Scene;
use std::error::Error;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// What the command line asks for besides the data folder.
#[derive(clap::Args)]
pub struct MakeHumanArgs {
    /// Rig of `rigs/standard/` (its `rig.<RIG>.json` and `weights.<RIG>.json`).
    #[arg(long, default_value = "game_engine")]
    pub rig: String,
    /// Output `.glb`.
    #[arg(long)]
    pub out: PathBuf,
}

/// Converts the MakeHuman data folder `dir` and writes the `.glb`.
pub fn run(dir: &Path, args: &MakeHumanArgs) -> Result<ExitCode, Box<dyn Error>> {
    let options = MakeHumanOptions {
        rig: args.rig.clone(),
        ..MakeHumanOptions::default()
    };
    let character = makehuman::import(dir, &options)?;
    if let Some(parent) = args.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|e| format!("{}: {e}", parent.display()))?;
    }
    glb::write(&character, &args.out)?;
    println!("{}", summary(&character, &args.out));
    Ok(ExitCode::SUCCESS)
}

/// Writes the fitted scene, builds it back and reports its muscle vertices
/// outside the skin at its first frame (the bind pose).
fn write_scene(
    args: &FitArgs,
    out: &Path,
    anatomy: &Scene,
    solver: &Solver,
    character: &SkinnedCharacter,
    fitted_anatomy: &FittedAnatomy,
) -> Result<(), Box<dyn Error>> {
    let FittedAnatomy {
        fit,
        geometry,
        skin,
        ..
    } = fitted_anatomy;
    let clip = match &args.clip {
        Some(name) => Some(
            character
                .clips
                .iter()
                .find(|c| &c.name == name)
                .ok_or_else(|| {
                    let names: Vec<&str> =
                        character.clips.iter().map(|c| c.name.as_str()).collect();
                    format!(
                        "{}: no clip '{name}' (it has: {})",
                        args.character.display(),
                        names.join(", ")
                    )
                })?,
        ),
        None => character
            .clips
            .iter()
            .find(|c| c.name == "walk")
            .or(character.clips.first()),
    };
    let playback = ClipPlayback {
        lead_in: args.lead_in,
        until: args.seconds,
    };
    let mut fitted = fit.scene(anatomy, solver, geometry, character, clip, &playback)?;
    if !args.no_skin {
        fitted.add_skin(character, &SkinLayer::default());
    }
    fitted.save(out)?;
    let built = fitted
        .scene
        .instantiate(out.parent().unwrap_or(Path::new("")))?;
    let anatomy_muscles = built.muscles().iter().filter(|m| !m.is_skin());
    let (outside, all) = anatomy_muscles.fold((0, 0), |(o, a), m| {
        let points = m.surface_positions();
        (o + skin.count_outside(points), a + points.len())
    });
    println!(
        "wrote {} ({} meshes, {} frames, clip {}); built back: muscle vertices outside the skin at rest {outside} of {all} ({:.2} %)",
        out.display(),
        fitted.meshes.len(),
        fitted.scene.frames,
        clip.map_or("none", |c| c.name.as_str()),
        100.0 * outside as f32 / all.max(1) as f32
    );
    Ok(())
}

fn summary(character: &SkinnedCharacter, out: &Path) -> String {
    let (lo, hi) = character
        .positions
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p.y), hi.max(p.y))
        });
    let clips: Vec<String> = character
        .clips
        .iter()
        .map(|c| format!("{} ({:.1} s)", c.name, c.duration()))
        .collect();
    format!(
        "{}: {} skin vertices, {} triangles, {} joints, height {:.3} m, clips: {}",
        out.display(),
        character.positions.len(),
        character.triangles.len(),
        character.joints.len(),
        hi - lo,
        clips.join(", ")
    )
}

/// What `sinew fit` asks for.
#[derive(clap::Args)]
pub struct FitArgs {
    /// Skinned character (`.glb`).
    pub character: PathBuf,
    /// Anatomy scene (with a skeleton), e.g. `assets/scenes/t7.ron`.
    pub scene: String,
    /// Rig map (RON: `RigMap(pairs: [("upperarm_r", "humerus_r"), …])`);
    /// default: the game-engine (Unreal-style) names onto myo-sim's bodies.
    #[arg(long)]
    pub map: Option<PathBuf>,
    /// Also write the skin, the fitted bones and the fitted muscles to this
    /// OBJ file (objects `skin`, `bone:NAME`, `muscle:NAME`), to look at
    /// (`scripts/blender/render_obj.py` draws it).
    #[arg(long)]
    pub obj: Option<PathBuf>,
    /// Leave the fitted muscles and bones where the segments put them
    /// (by default what sticks out of the skin is pulled inside it).
    #[arg(long)]
    pub no_pull: bool,
    /// Write the fitted anatomy as a scene here (`.ron`; its meshes go to
    /// `meshes/` beside it): the character's joints as the skeleton, the
    /// bones following them, the clip as the motion.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// The character's clip the scene plays (default: `walk` when the
    /// character has one, else its first, else none).
    #[arg(long)]
    pub clip: Option<String>,
    /// Seconds from the bind pose to the clip's first pose.
    #[arg(long, default_value_t = 1.0, value_parser = crate::args::non_negative)]
    pub lead_in: f32,
    /// Seconds the scene lasts (the clip loops).
    #[arg(long, default_value_t = 10.0, value_parser = crate::args::positive)]
    pub seconds: f32,
    /// Leave the character's skin out of the scene (by default it is a
    /// simulated layer over the muscles, bound to the joints).
    #[arg(long)]
    pub no_skin: bool,
}

/// Fits the scene's anatomy to the character and reports the segments and
/// the share of muscle and bone vertices outside the skin.
pub fn fit(args: &FitArgs) -> Result<ExitCode, Box<dyn Error>> {
    let read = glb::read(&args.character)?;
    for line in &read.skipped {
        eprintln!("note: {}: {line}", args.character.display());
    }
    let character = read.character;
    let (anatomy, solver) = crate::commands::load_solver(&args.scene)?;
    let map = match &args.map {
        Some(path) => RigMap::load(path)?,
        None => RigMap::game_engine(),
    };
    let options = FitOptions {
        pull: !args.no_pull,
        ..FitOptions::default()
    };
    let fitted = fit_anatomy(&character, &solver, &map, &options)
        .map_err(|e| format!("{}: {e}", args.scene))?;
    let FittedAnatomy {
        fit,
        geometry,
        skin,
        settled,
        pulled,
    } = &fitted;
    for (body, dz) in settled {
        println!(
            "{body}: moved {:+.0} mm front to back to sit inside the skin",
            dz * 1000.0
        );
    }
    println!("segment                      scale   turn (deg)  fitted to");
    for s in &fit.segments {
        let (_, angle) = s.similarity.rotation.to_axis_angle();
        let to = if s.fitted_to_children {
            "children"
        } else {
            "parent (leaf)"
        };
        println!(
            "{:<28} {:>6.3} {:>11.1}  {to}",
            format!("{} → {}", s.joint, s.body),
            s.similarity.scale,
            angle.to_degrees()
        );
    }
    for (what, r) in ["muscle", "bone"].into_iter().zip(pulled.iter().flatten()) {
        println!(
            "pulled inside the skin: {what} vertices outside {} → {}, largest move {:.1} mm, {} triangles folded",
            r.outside_before,
            r.outside_after,
            r.largest_move * 1000.0,
            r.folded
        );
    }
    let outside = |points: &[Vec3]| skin.count_outside(points);
    let mut per_muscle: Vec<(f32, &str, usize, usize)> = geometry
        .muscles
        .iter()
        .zip(solver.muscles())
        .map(|(points, m)| {
            let n = outside(points);
            (
                n as f32 / points.len().max(1) as f32,
                m.name.as_str(),
                n,
                points.len(),
            )
        })
        .collect();
    let (muscle_out, muscle_all) = per_muscle
        .iter()
        .fold((0, 0), |(o, a), m| (o + m.2, a + m.3));
    let (bone_out, bone_all) = geometry
        .bones
        .iter()
        .fold((0, 0), |(o, a), (_, p)| (o + outside(p), a + p.len()));
    let share = |o: usize, a: usize| 100.0 * o as f32 / a.max(1) as f32;
    println!(
        "outside the skin: muscle vertices {muscle_out} of {muscle_all} ({:.2} %), bone vertices {bone_out} of {bone_all} ({:.2} %)",
        share(muscle_out, muscle_all),
        share(bone_out, bone_all)
    );
    let mut per_bone: Vec<(f32, &str, usize, usize)> = geometry
        .bones
        .iter()
        .map(|(b, points)| {
            let n = outside(points);
            let share = n as f32 / points.len().max(1) as f32;
            (share, solver.bones()[*b].name.as_str(), n, points.len())
        })
        .collect();
    for (what, list) in [("muscles", &mut per_muscle), ("bones", &mut per_bone)] {
        list.sort_by(|a, b| b.0.total_cmp(&a.0));
        let worst: Vec<String> = list
            .iter()
            .take(8)
            .filter(|m| m.2 > 0)
            .map(|m| format!("{} {:.0} %", m.1, 100.0 * m.0))
            .collect();
        if !worst.is_empty() {
            println!("{what} most outside: {}", worst.join(", "));
        }
    }
    if let Some(path) = &args.obj {
        let mut obj = ObjObjects::default();
        let mut object = |name: &str, points: &[Vec3], triangles: &[[u32; 3]]| {
            obj.push(
                name,
                points,
                triangles.iter().map(|t| t.as_slice()),
                Some(5),
            );
        };
        object("skin", &character.positions, &character.triangles);
        for (b, points) in &geometry.bones {
            let bone = &solver.bones()[*b];
            let triangles = solver.targets()[bone.target.expect("a bone with a mesh")].triangles();
            object(&format!("bone:{}", bone.name), points, triangles);
        }
        for (points, m) in geometry.muscles.iter().zip(solver.muscles()) {
            object(&format!("muscle:{}", m.name), points, &m.mesh.triangles);
        }
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(|e| format!("{}: {e}", parent.display()))?;
        }
        std::fs::write(path, obj.into_text()).map_err(|e| format!("{}: {e}", path.display()))?;
        println!("wrote {}", path.display());
    }
    if let Some(out) = &args.out {
        write_scene(args, out, &anatomy, &solver, &character, &fitted)?;
    }
    Ok(ExitCode::SUCCESS)
}
