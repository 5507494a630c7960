//! What ordering distance constraints in runs that share no particle gives
//! a Gauss–Seidel pass (`DistanceBatch::arrange_in_runs`, ARCHITECTURE.md
//! "Distance constraints in runs"): two solvers of one scene, one in runs
//! and one in creation (mesh) order, stepped side by side in one process,
//! frame by frame and alternating which goes first, so that a machine
//! whose speed drifts slows both alike. Prints the median step and projection times of
//! each and their ratio.
//!
//! ```sh
//! cargo run --release -p sinew_cli --example gauss_seidel_order -- assets/scenes/t7.ron 2 120 120
//! ```
//! Arguments: scene (file or built-in name), threads, first timed frame,
//! timed frames.

use sinew_core::scene::{BUILTIN_SCENES, Scene, builtin};
use sinew_core::solver::Solver;
use std::error::Error;
use std::path::Path;
use std::time::Instant;

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [scene, threads, from, frames] = args.as_slice() else {
        return Err("usage: gauss_seidel_order SCENE THREADS FROM FRAMES".into());
    };
    let (threads, from, frames): (u32, u32, u32) =
        (threads.parse()?, from.parse()?, frames.parse()?);
    if frames == 0 {
        return Err("FRAMES must be at least 1".into());
    }
    // As the CLI reads a scene argument (`load_scene`): a `.ron` or an
    // existing path is a file, anything else a built-in name.
    let path = Path::new(scene);
    let (mut spec, base) = if path.extension().is_some_and(|e| e == "ron") || path.exists() {
        let base = path.parent().unwrap_or(Path::new(".")).to_path_buf();
        (Scene::load(path)?, base)
    } else {
        let spec = builtin(scene).ok_or_else(|| {
            format!(
                "'{scene}' is neither a scene file nor a built-in scene ({})",
                BUILTIN_SCENES.join(", ")
            )
        })?;
        (spec, Path::new(".").to_path_buf())
    };
    spec.settings.threads = threads;
    let mut in_runs = spec.instantiate(&base)?;
    let mut in_mesh_order = spec.instantiate(&base)?;
    for i in 0..in_mesh_order.muscles().len() {
        let k = &mut in_mesh_order.muscle_mut(i).constraints;
        for batch in [&mut k.fiber, &mut k.internal, &mut k.branch] {
            batch.in_creation_order();
        }
    }
    for _ in 0..from {
        in_runs.step();
        in_mesh_order.step();
    }
    // (step ms, project ms) per frame, for each solver.
    let mut times: [Vec<(f64, f64)>; 2] = [Vec::new(), Vec::new()];
    for frame in 0..frames as usize {
        for k in [frame % 2, 1 - frame % 2] {
            let solver: &mut Solver = if k == 0 {
                &mut in_runs
            } else {
                &mut in_mesh_order
            };
            let start = Instant::now();
            solver.step();
            let step = start.elapsed().as_secs_f64() * 1e3;
            let project = solver.timings().project.as_secs_f64() * 1e3;
            times[k].push((step, project));
        }
    }
    let median = |k: usize, column: usize| {
        let mut v: Vec<f64> = times[k].iter().map(|t| [t.0, t.1][column]).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (s0, s1, p0, p1) = (median(0, 0), median(1, 0), median(0, 1), median(1, 1));
    println!(
        "{scene}, {threads} thread(s), frames {from}..{}: step {s0:.3} ms in runs, {s1:.3} ms in mesh order (× {:.3}); projection {p0:.3} / {p1:.3} ms (× {:.3})",
        from + frames,
        s0 / s1,
        p0 / p1
    );
    Ok(())
}
