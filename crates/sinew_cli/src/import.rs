//! `import-mjcf`: MJCF model or import recipe → scene + meshes.

use crate::commands::write_stdout;
use sinew_core::Solver;
use sinew_core::import::builder::SweepOptions;
use sinew_core::import::mjcf::MjcfModel;
use sinew_core::import::{ImportOptions, ImportRecipe, Imported, import_model};
use sinew_core::muscle::ConstraintCounts;
use sinew_core::solver::coloring::ColorGroups;
use std::error::Error;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

type Result<T> = std::result::Result<T, Box<dyn Error>>;

/// What the command line asks for besides the input.
#[derive(clap::Args)]
pub struct ImportArgs {
    /// Attach another model at a site of this one: FILE@SITE (repeatable;
    /// an empty SITE is the world origin).
    #[arg(long)]
    pub attach: Vec<String>,
    /// Attach a mirrored (right → left) copy: FILE@SITE (repeatable).
    #[arg(long)]
    pub attach_mirrored: Vec<String>,
    /// Muscles (actuator names) to import, comma separated; default all.
    #[arg(long, value_delimiter = ',')]
    pub muscles: Vec<String>,
    /// Approximate vertex count per muscle (32–100000).
    #[arg(long, value_parser = clap::value_parser!(u32).range(32..=100_000))]
    pub resolution: Option<u32>,
    /// Belly radius of every muscle (m) instead of the one from its force.
    #[arg(long, value_parser = crate::args::positive)]
    pub radius: Option<f32>,
    /// Output scene file (meshes go to `<stem>_meshes/` beside it).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

fn split_attach(arg: &str) -> Result<(PathBuf, String)> {
    let (file, site) = arg
        .rsplit_once('@')
        .ok_or_else(|| format!("--attach '{arg}': expected FILE@SITE"))?;
    Ok((PathBuf::from(file), site.to_string()))
}

/// Runs the import and prints what it made.
pub fn run(input: &Path, args: &ImportArgs) -> Result<ExitCode> {
    let start = Instant::now();
    let (imported, scene_path, solver) = if input.extension().is_some_and(|e| e == "ron") {
        if !args.attach.is_empty() || !args.muscles.is_empty() || args.out.is_some() {
            return Err(
                "a recipe names its own model, muscles and output; pass only the recipe".into(),
            );
        }
        ImportRecipe::load(input)?.run(input)?
    } else {
        let out = args
            .out
            .clone()
            .ok_or("--out <scene.ron> is required when importing an MJCF model")?;
        let mut model = MjcfModel::load(input)?;
        for (arg, mirror) in args
            .attach
            .iter()
            .map(|a| (a, false))
            .chain(args.attach_mirrored.iter().map(|a| (a, true)))
        {
            let (file, site) = split_attach(arg)?;
            model.attach(&MjcfModel::load(&file)?, &site, mirror)?;
        }
        let mut options = ImportOptions {
            muscles: args.muscles.clone(),
            ..Default::default()
        };
        if let Some(v) = args.resolution {
            options.sweep = SweepOptions::with_resolution(v);
        }
        options.sweep.radius = args.radius;
        let scene_dir = out.parent().unwrap_or(Path::new(".")).to_path_buf();
        let stem = out
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "scene".into());
        let mesh_dir = PathBuf::from(format!("{stem}_meshes"));
        let mut imported = import_model(&model, &options, &scene_dir, &mesh_dir)?;
        let solver = imported.scene.instantiate(&scene_dir)?;
        imported.scene.save(&out)?;
        imported.files.push(out.clone());
        (imported, out, solver)
    };
    let built = start.elapsed().as_secs_f64();
    // Colour groups of every muscle, as a parallel solver would need them.
    let groups: usize = solver
        .muscles()
        .iter()
        .map(|m| ColorGroups::greedy(m, &solver.settings.projection_order).len())
        .sum();
    let seconds = start.elapsed().as_secs_f64();
    write_stdout(&report(
        &imported,
        &scene_path,
        &solver,
        built,
        groups,
        seconds,
    )?)?;
    Ok(ExitCode::SUCCESS)
}

fn report(
    imported: &Imported,
    scene_path: &Path,
    solver: &Solver,
    built: f64,
    groups: usize,
    seconds: f64,
) -> Result<String> {
    let scene = &imported.scene;
    let mut total = ConstraintCounts::default();
    for m in solver.muscles() {
        total += m.counts();
    }
    let vertices: usize = solver.muscles().iter().map(|m| m.surface_count).sum();
    let mut out = String::new();
    writeln!(
        out,
        "{}: {} bones ({} with meshes), {} muscles, {} surface vertices, {} constraints",
        scene_path.display(),
        scene.bones.len(),
        scene.bones.iter().filter(|b| b.shape.is_some()).count(),
        scene.muscles.len(),
        vertices,
        total.total()
    )?;
    writeln!(
        out,
        "{} files written; build {seconds:.2} s: read, compose, sweep, push-out, targets, write and constraints {built:.2} s; colouring {:.2} s ({groups} colour groups)",
        imported.files.len(),
        seconds - built
    )?;
    for n in &imported.notes {
        writeln!(out, "  note: {n}")?;
    }
    Ok(out)
}
