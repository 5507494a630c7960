//! The main example: a walking human with the 144 muscles and the bones of
//! the full body (scene T7) under a simulated skin. The character is a
//! skinned glTF (MakeHuman, `assets/characters/makehuman.glb`) played by
//! `bevy_animation`; its joints carry the fitted bones, the muscles slide
//! and bulge on them, and its skin is a simulated layer held to the
//! skinned position and kept above the muscles. The panel toggles skin,
//! plain skinning, muscles, bones and x-ray, and tunes the skin.
//!
//! `cargo run --release --example character`
//!
//! The first run fits T7 to the character (what `sinew fit
//! assets/characters/makehuman.glb assets/scenes/t7.ron --out
//! assets/fitted/t7_makehuman/t7_makehuman.ron` does) and keeps the fitted
//! scene under `assets/fitted/` (not in git; fitted again when the
//! character, T7 or the program is newer). Drag to orbit, scroll to zoom. Set
//! `SINEW_SCREENSHOT=out.png` to save a screenshot at simulation frame
//! `SINEW_SCREENSHOT_FRAME` and exit (CI does, under Xvfb);
//! `SINEW_XRAY=1` starts see-through.

use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use sinew::bevy::prelude::*;
use sinew::core::character::fit::{FitOptions, RigMap, SkinLayer, fit_anatomy};
use sinew::core::character::{ClipPlayback, glb};
use sinew::core::scene::Scene;
use std::error::Error;
use std::path::{Path, PathBuf};

/// The character, under `assets/`.
const CHARACTER: &str = "characters/makehuman.glb";
/// The anatomy fitted to it, under `assets/`.
const ANATOMY: &str = "scenes/t7.ron";
/// Where the fitted scene is kept, under `assets/`.
const FITTED: &str = "fitted/t7_makehuman/t7_makehuman.ron";

fn main() -> AppExit {
    if let Err(e) = fit_once(&asset_root()) {
        eprintln!("character: could not fit {ANATOMY} to {CHARACTER}: {e}");
        return AppExit::error();
    }
    App::new()
        .add_plugins(DefaultPlugins.set(WindowPlugin {
            primary_window: Some(Window {
                title: "sinew — character".into(),
                resolution: (1280, 720).into(),
                ..default()
            }),
            ..default()
        }))
        // The walk and the simulation in step: real time at 60 Hz, slow
        // motion where the machine cannot keep up.
        .add_plugins((
            SinewPlugin::default().pacing(SimulationPacing {
                mode: PacingMode::Lockstep,
                ..default()
            }),
            SinewUiPlugin,
        ))
        .insert_resource(ClearColor(Color::srgb(0.11, 0.12, 0.14)))
        .insert_resource(GlobalAmbientLight {
            brightness: 300.0,
            ..default()
        })
        .insert_resource(SinewView {
            xray: std::env::var("SINEW_XRAY").is_ok_and(|v| !v.is_empty() && v != "0"),
            ..default()
        })
        .add_systems(Startup, setup)
        .add_systems(Update, spawn_character)
        .run()
}

/// The folder Bevy reads assets from (`BEVY_ASSET_ROOT`, else this crate's).
fn asset_root() -> PathBuf {
    let root = std::env::var_os("BEVY_ASSET_ROOT")
        .map_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")), PathBuf::from);
    root.join("assets")
}

/// Fits the anatomy to the character and writes the fitted scene with its
/// skin, unless a fitted scene newer than the character, the anatomy and
/// this program is there.
fn fit_once(assets: &Path) -> Result<(), Box<dyn Error>> {
    let (character, anatomy, fitted) = (
        assets.join(CHARACTER),
        assets.join(ANATOMY),
        assets.join(FITTED),
    );
    // Fitted again when the character, the anatomy or this program (which
    // holds the fit's code) is newer than the fitted scene.
    let modified = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    let program = std::env::current_exe()?;
    if let Some(written) = modified(&fitted)
        && [&character, &anatomy, &program]
            .iter()
            .all(|input| modified(input).is_some_and(|t| t <= written))
    {
        return Ok(());
    }
    println!("fitting {ANATOMY} to {CHARACTER} (once; kept in assets/{FITTED})…");
    let character = glb::read(&character)?.character;
    let scene = Scene::load(&anatomy)?;
    let solver = scene.instantiate(anatomy.parent().unwrap_or(Path::new("")))?;
    let fit = fit_anatomy(
        &character,
        &solver,
        &RigMap::game_engine(),
        &FitOptions::default(),
    )?;
    let walk = character.clips.iter().find(|c| c.name == "walk");
    let mut out = fit.fit.scene(
        &scene,
        &solver,
        &fit.geometry,
        &character,
        walk,
        &ClipPlayback::default(),
    )?;
    out.add_skin(&character, &SkinLayer::default());
    out.save(&fitted)?;
    Ok(())
}

/// The character's glTF, loaded once (all its assets from one read:
/// asking for several of a file's assets before it is loaded may read it
/// several times, and each later read respawns the character).
#[derive(Resource)]
struct Character(Handle<Gltf>);

fn setup(mut commands: Commands, assets: Res<AssetServer>) {
    commands.insert_resource(Character(assets.load(CHARACTER)));
    commands.spawn((
        Camera3d::default(),
        OrbitCamera {
            focus: Vec3::new(-0.15, 0.88, 0.0),
            yaw: 0.45,
            pitch: -0.05,
            distance: 2.55,
            ..default()
        },
    ));
    for (illuminance, from) in [
        (8000.0, Vec3::new(1.0, 2.0, 2.0)),
        (2500.0, Vec3::new(-1.5, 1.0, -1.0)),
    ] {
        commands.spawn((
            DirectionalLight {
                illuminance,
                ..default()
            },
            Transform::from_translation(from).looking_at(Vec3::new(0.0, 1.0, 0.0), Vec3::Y),
        ));
    }
}

/// Once the glTF is loaded: spawns the character and, on it, the fitted
/// anatomy with its skin.
fn spawn_character(
    mut commands: Commands,
    character: Res<Character>,
    gltfs: Res<Assets<Gltf>>,
    assets: Res<AssetServer>,
    mut spawned: Local<bool>,
) -> Result {
    let Some(gltf) = gltfs.get(&character.0).filter(|_| !*spawned) else {
        return Ok(());
    };
    let scene = gltf
        .default_scene
        .clone()
        .or_else(|| gltf.scenes.first().cloned())
        .ok_or("the character's glTF has no scene")?;
    let root = commands.spawn(WorldAssetRoot(scene)).id();
    commands
        .spawn((
            SinewSceneRoot::Asset(assets.load(FITTED)),
            OnCharacter(root),
        ))
        .observe(walk);
    *spawned = true;
    Ok(())
}

/// Plays the character's walk once the anatomy is on it, blended in over
/// a second from the bind pose the muscles were fitted in.
fn walk(
    placed: On<Add, PlacedOnCharacter>,
    scenes: Query<&OnCharacter>,
    character: Res<Character>,
    gltfs: Res<Assets<Gltf>>,
    mut gltf: GltfCharacters,
) -> Result {
    let clip = gltfs
        .get(&character.0)
        .and_then(|g| g.named_animations.get("walk"))
        .ok_or("the character has no clip named walk")?
        .clone();
    let root = scenes.get(placed.entity)?.0;
    gltf.play_looped_from_rest(root, clip, 1.0)?;
    Ok(())
}
