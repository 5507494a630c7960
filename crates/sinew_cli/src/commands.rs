//! `info`, `validate`, `bake` and `scene`.

use sinew_core::bake::{Bake, BakeFormat, ExistingFiles};
use sinew_core::mesh::{LoadOptions, load_mesh};
use sinew_core::muscle::{ConstraintCounts, ConstraintKind};
use sinew_core::scene::{BUILTIN_SCENES, Scene, builtin};
use sinew_core::solver::coloring::{ColorGroups, ColorPlan, PlanKind};
use sinew_core::{SceneError, Solver};
use std::error::Error;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// A command's result: any error, printed by `main`.
pub type Result<T> = std::result::Result<T, Box<dyn Error>>;

/// Loads a scene file or a built-in; returns it with its base directory.
pub fn load_scene(arg: &str) -> Result<(Scene, PathBuf)> {
    let path = Path::new(arg);
    if path.extension().is_some_and(|e| e == "ron") || path.exists() {
        let scene = Scene::load(path)?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        return Ok((scene, base));
    }
    builtin(arg)
        .map(|s| (s, PathBuf::from(".")))
        .ok_or_else(|| {
            format!(
                "'{arg}' is neither a scene file nor a built-in scene ({})",
                BUILTIN_SCENES.join(", ")
            )
            .into()
        })
}

/// Loads and instantiates a scene.
pub fn load_solver(arg: &str) -> Result<(Scene, Solver)> {
    let (scene, base) = load_scene(arg)?;
    let solver = scene.instantiate(&base)?;
    Ok((scene, solver))
}

/// The constraint table, one column per muscle plus the total.
pub fn constraint_table(solver: &Solver) -> String {
    let muscles = solver.muscles();
    let mut out = String::new();
    let _ = write!(out, "{:<10}", "Type");
    for m in muscles {
        let _ = write!(out, "{:>12}", truncate(&m.name, 11));
    }
    let _ = writeln!(out, "{:>10}", "TOTAL");
    let mut total = ConstraintCounts::default();
    for m in muscles {
        total += m.counts();
    }
    for kind in ConstraintKind::TABLE_ORDER {
        let _ = write!(out, "{:<10}", kind.label());
        for m in muscles {
            let _ = write!(out, "{:>12}", m.counts().get(kind));
        }
        let _ = writeln!(out, "{:>10}", total.get(kind));
    }
    let _ = write!(out, "{:<10}", "TOTAL");
    for m in muscles {
        let _ = write!(out, "{:>12}", m.counts().total());
    }
    let _ = writeln!(out, "{:>10}", total.total());
    out
}

/// `s` cut to its first `n` characters.
pub fn truncate(s: &str, n: usize) -> String {
    s.chars().take(n).collect()
}

pub fn info(arg: &str) -> Result<ExitCode> {
    let (scene, solver) = load_solver(arg)?;
    // Built whole and written once, so a reader that stops early (`| head`,
    // `grep -q`) ends the output instead of a panicking `println!`.
    let mut out = String::new();
    writeln!(out, "scene {}: {}", scene.name, scene.description)?;
    writeln!(
        out,
        "{} bones, {} muscles, {} iterations, {} substeps, dt {:.5} s\n",
        solver.bones().len(),
        solver.muscles().len(),
        solver.settings.iterations,
        solver.settings.substeps,
        solver.settings.dt
    )?;
    out.push_str(&constraint_table(&solver));
    writeln!(out)?;
    writeln!(
        out,
        "{:<12}{:>9}{:>9}{:>8}{:>9}{:>9}{:>7}{:>13}",
        "muscle", "vertices", "internal", "branch", "bifurc.", "roots", "links", "volume (cm³)"
    )?;
    for m in solver.muscles() {
        let s = &m.structure;
        let max_links = (0..s.points.len())
            .map(|p| s.vertex_point.iter().filter(|&&q| q as usize == p).count())
            .max()
            .unwrap_or(0);
        writeln!(
            out,
            "{:<12}{:>9}{:>9}{:>8}{:>9}{:>9}{:>7}{:>13.2}",
            truncate(&m.name, 11),
            m.surface_count,
            s.points.len(),
            s.branches.len(),
            s.bifurcations,
            m.roots.len(),
            max_links,
            m.rest_volume() * 1e6
        )?;
    }
    writeln!(
        out,
        "\n(links = most surface vertices tied to one internal point)"
    )?;
    writeln!(
        out,
        "\nColour groups (Volume apart): the thesis' greedy first-fit per constraint \
         (sizes shown), the clustered colouring of the global scope, and Hybrid's \
         Gauss–Seidel groups (≥ 32) with its Jacobi tail:"
    )?;
    writeln!(
        out,
        "{:<12}{:>8}{:>9}{:>9}{:>8}{:>11}{:>8}{:>6}  sizes",
        "muscle", "groups", "largest", "smallest", "size 1", "clustered", "hybrid", "tail"
    )?;
    let order = &solver.settings.projection_order;
    for m in solver.muscles() {
        let colors = ColorGroups::greedy(m, order);
        let clustered = ColorPlan::build(m, order, PlanKind::Clustered);
        let hybrid = ColorPlan::build(m, order, PlanKind::Hybrid { min_group: 32 });
        let sizes = colors.sizes();
        let shown: Vec<String> = sizes.iter().take(16).map(usize::to_string).collect();
        let more = if sizes.len() > 16 { " …" } else { "" };
        writeln!(
            out,
            "{:<12}{:>8}{:>9}{:>9}{:>8}{:>11}{:>8}{:>6}  {}{more}",
            truncate(&m.name, 11),
            colors.len(),
            sizes.iter().max().unwrap_or(&0),
            sizes.iter().min().unwrap_or(&0),
            sizes.iter().filter(|&&n| n == 1).count(),
            clustered.color_count(),
            hybrid.color_count(),
            hybrid.tail().len(),
            shown.join(" ")
        )?;
    }
    write_stdout(&out)?;
    Ok(ExitCode::SUCCESS)
}

/// Writes `text` to standard output; a closed pipe is not an error.
pub fn write_stdout(text: &str) -> std::io::Result<()> {
    use std::io::Write as _;
    match std::io::stdout().lock().write_all(text.as_bytes()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        other => other,
    }
}

pub fn validate(arg: &str) -> Result<ExitCode> {
    let path = Path::new(arg);
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if matches!(ext.as_deref(), Some("obj" | "stl")) {
        let mesh = load_mesh(path, &LoadOptions::default())?;
        let r = mesh.report();
        println!(
            "{}: {} vertices, {} polygons, {} edges, volume {:.6e} m³",
            path.display(),
            r.vertices,
            r.polygons,
            r.edges,
            r.volume
        );
        let mut problems = 0;
        for (a, b) in r.open_edges.iter().take(10) {
            println!("  open edge ({a}, {b})");
        }
        problems += r.open_edges.len();
        for (a, b, n) in r.non_manifold_edges.iter().take(10) {
            println!("  non-manifold edge ({a}, {b}) shared by {n} faces");
        }
        problems += r.non_manifold_edges.len();
        for (a, b) in r.inconsistent_edges.iter().take(10) {
            println!("  inconsistent orientation at edge ({a}, {b})");
        }
        problems += r.inconsistent_edges.len();
        if r.is_closed_manifold() && r.volume < 0.0 {
            println!("  faces point inwards (negative volume)");
            problems += 1;
        }
        return Ok(report_problems(problems));
    }
    let (scene, base) = load_scene(arg)?;
    let (_, muscle_meshes) = scene.load_meshes(&base)?;
    let mut problems = 0;
    for (spec, mesh) in scene.muscles.iter().zip(&muscle_meshes) {
        let r = mesh.report();
        let status = match r.into_result(&mesh.source) {
            Ok(()) if r.volume > 0.0 => "ok".to_string(),
            Ok(()) => {
                problems += 1;
                "faces point inwards".to_string()
            }
            Err(e) => {
                problems += 1;
                e.to_string()
            }
        };
        println!(
            "muscle {:<12} {:>6} vertices {:>6} edges  {status}",
            spec.name, r.vertices, r.edges
        );
    }
    match scene.instantiate(&base) {
        Ok(solver) => println!(
            "built {} muscles, {} constraints",
            solver.muscles().len(),
            solver
                .muscles()
                .iter()
                .map(|m| m.counts().total())
                .sum::<usize>()
        ),
        Err(e) => {
            problems += 1;
            println!("build failed: {e}");
        }
    }
    Ok(report_problems(problems))
}

fn report_problems(problems: usize) -> ExitCode {
    if problems == 0 {
        println!("no problems found");
        ExitCode::SUCCESS
    } else {
        println!("{problems} problem(s) found");
        ExitCode::FAILURE
    }
}

/// Simulates `frames` frames (default: the scene's) and writes them to `out`
/// in `formats` (see [`sinew_core::bake`]).
pub fn bake(
    arg: &str,
    frames: Option<u32>,
    out: &Path,
    formats: &[BakeFormat],
    existing: ExistingFiles,
) -> Result<ExitCode> {
    let (scene, mut solver) = load_solver(arg)?;
    let frames = frames.unwrap_or(scene.frames.max(1));
    let bar = indicatif::ProgressBar::new(frames as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} frames  {eta} left")
            .expect("valid template"),
    );
    let mut bake = Bake::start_in(&solver, out, formats, existing)?;
    for _ in 1..=frames {
        solver.step();
        bake.record(&solver)?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    for w in solver.take_warnings() {
        eprintln!("warning: {w}");
    }
    let recorded = bake.frames();
    if bake.resumed() > 0 {
        println!(
            "resumed: {} frames on disk checked against the simulation and kept",
            bake.resumed()
        );
    }
    let files = bake.finish()?;
    let names: Vec<String> = formats.iter().map(|f| f.to_string()).collect();
    println!(
        "wrote {recorded} frames ({}) to {}: {} files",
        names.join(", "),
        out.display(),
        files.len()
    );
    Ok(ExitCode::SUCCESS)
}

pub fn write_builtin(name: &str, out: &Path) -> Result<ExitCode> {
    let scene = builtin(name).ok_or_else(|| -> Box<dyn Error> {
        format!("no built-in scene '{name}' ({})", BUILTIN_SCENES.join(", ")).into()
    })?;
    scene
        .save(out)
        .map_err(|e: SceneError| -> Box<dyn Error> { e.into() })?;
    println!("wrote {}", out.display());
    Ok(ExitCode::SUCCESS)
}
