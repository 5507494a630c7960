//! `sinew`: headless tools for MSXPBD scenes — info, validate, bake, bench.

mod args;
mod bench;
mod character;
mod check;
mod commands;
mod import;
mod reference_kernel;
mod render;
mod soak;
mod suite;

use clap::{Parser, Subcommand};
use sinew_core::bake::{BakeFormat, ExistingFiles};
use std::path::PathBuf;
use std::process::ExitCode;

/// Headless tools for sinew muscle scenes. A SCENE is a `.ron` file or the
/// name of a built-in reference scene (P1, P2, T1, P3).
#[derive(Parser)]
#[command(name = "sinew", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Constraint table by type (the thesis' Tables 5.1–5.4) and internal-structure figures.
    Info {
        /// Scene file or built-in name.
        scene: String,
    },
    /// Report problems in a scene or a mesh (OBJ/STL) without simulating.
    Validate {
        /// Scene file, built-in name, or mesh file.
        input: String,
    },
    /// Simulate and write the result for DCCs: OBJ per frame, `.pc2` point
    /// caches per muscle, and/or a `.glb` of the rest meshes and animated bones.
    Bake {
        /// Scene file or built-in name.
        scene: String,
        /// Frames to simulate (default: the scene's).
        #[arg(long)]
        frames: Option<u32>,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        /// Formats, comma-separated: obj (one file per frame, scene units),
        /// pc2 (one point cache per muscle, metres), glb (rest meshes and
        /// the animated bones, metres).
        #[arg(long, value_delimiter = ',', default_value = "obj")]
        format: Vec<BakeFormat>,
        /// Delete an earlier bake's files in the output folder first (by
        /// default a folder holding bake files is refused, so two bakes
        /// never mix).
        #[arg(long, conflicts_with = "resume")]
        replace: bool,
        /// Continue an interrupted bake in the output folder: its OBJ frames
        /// are kept (each checked as the simulation passes it again), the
        /// rest is written.
        #[arg(long)]
        resume: bool,
    },
    /// Per-block ms/frame (median of runs), active constraints and ns per
    /// active constraint-iteration next to a coloured reference sweep.
    Bench(bench::BenchArgs),
    /// The benchmark suite: P1–P4 and T7, every method, 1 to all threads,
    /// next to the thesis' tables; writes suite.json and PNG plots.
    Suite(suite::SuiteArgs),
    /// Import a MuJoCo MJCF model (or run an import recipe `.ron`): bones,
    /// joints and one swept muscle per tendon actuator, as a scene.
    ImportMjcf {
        /// MJCF model (.xml) or import recipe (.ron).
        input: PathBuf,
        #[command(flatten)]
        args: import::ImportArgs,
    },
    /// Simulate and judge: finiteness, attachment error, muscle–bone
    /// penetration, volume, edge strain, flipped triangles and, once the
    /// motion has stopped, rest (velocity, jiggle, deviation from the rest
    /// shape). Exits non-zero when a figure is out of its range.
    Check(check::CheckArgs),
    /// A long run at rest (`--still`) or looping its motion: stays finite,
    /// drifts less than a share of the scene's size, keeps its memory flat.
    /// Exits non-zero when a figure fails.
    Soak(soak::SoakArgs),
    /// Convert the MakeHuman base mesh and rig (a folder holding `3dobjs/`
    /// and `rigs/`, e.g. fetched by `scripts/fetch_makehuman.sh`) into a
    /// skinned glTF character (`.glb`) with an elbow-flexion clip.
    ImportMakehuman {
        /// MakeHuman data folder.
        dir: PathBuf,
        #[command(flatten)]
        args: character::MakeHumanArgs,
    },
    /// Fit an anatomy scene to a skinned character (per-segment similarity
    /// from matched joint centres) and report how much of it is outside the skin.
    Fit(character::FitArgs),
    /// Simulate to a frame and draw bones and muscles into a PNG (software
    /// rasteriser: no GPU or window needed).
    Render {
        /// Scene file or built-in name.
        scene: String,
        /// Frame to draw (frames simulated first).
        #[arg(long, default_value_t = 0)]
        frame: u32,
        /// Camera direction.
        #[arg(long, value_enum, default_value = "front")]
        view: render::View,
        /// Image width in pixels (1–16384).
        #[arg(long, default_value_t = 900, value_parser = clap::value_parser!(u32).range(1..=16384))]
        width: u32,
        /// Image height in pixels (1–16384).
        #[arg(long, default_value_t = 900, value_parser = clap::value_parser!(u32).range(1..=16384))]
        height: u32,
        /// Leave the bones out.
        #[arg(long)]
        no_bones: bool,
        /// How a skin is drawn (scenes with a simulated skin).
        #[arg(long, value_enum, default_value = "simulated")]
        skin: render::SkinDraw,
        /// Frame this muscle, skin or bone (by name) instead of every muscle.
        #[arg(long)]
        focus: Option<String>,
        /// Output PNG.
        #[arg(long)]
        out: PathBuf,
    },
    /// Write a built-in scene as RON.
    Scene {
        /// Built-in name.
        name: String,
        /// Output file.
        #[arg(long)]
        out: PathBuf,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Info { scene } => commands::info(&scene),
        Command::Validate { input } => commands::validate(&input),
        Command::Bake {
            scene,
            frames,
            out,
            format,
            replace,
            resume,
        } => {
            let existing = match (replace, resume) {
                (true, _) => ExistingFiles::Replace,
                (_, true) => ExistingFiles::Resume,
                _ => ExistingFiles::Refuse,
            };
            commands::bake(&scene, frames, &out, &format, existing)
        }
        Command::Bench(args) => bench::run(&args),
        Command::Scene { name, out } => commands::write_builtin(&name, &out),
        Command::Render {
            scene,
            frame,
            view,
            width,
            height,
            no_bones,
            skin,
            focus,
            out,
        } => render::run(
            &scene,
            frame,
            &render::RenderOptions {
                view,
                size: (width, height),
                bones: !no_bones,
                skin,
                focus,
            },
            &out,
        ),
        Command::Check(args) => check::run(&args),
        Command::Soak(args) => soak::run(&args),
        Command::ImportMakehuman { dir, args } => character::run(&dir, &args),
        Command::Fit(args) => character::fit(&args),
        Command::ImportMjcf { input, args } => import::run(&input, &args),
        Command::Suite(args) => suite::run(&args),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
