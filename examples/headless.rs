//! Runs a scene headless (`MinimalPlugins`, no window) for N frames through
//! the Bevy plug-in and prints the per-block timings. With `--compare` it
//! also runs the plain `sinew_core` driver on the same scene and reports both
//! medians and the ECS overhead.
//!
//! `cargo run --release --example headless -- assets/scenes/t5.ron 120 --compare`

use bevy::prelude::*;
use sinew::bevy::prelude::*;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let compare = args.iter().any(|a| a == "--compare");
    let mut positional = args.iter().filter(|a| !a.starts_with("--"));
    let path = positional
        .next()
        .map_or("assets/scenes/p3.ron", |p| p.as_str());
    let frames: usize = positional.next().map_or(Ok(120), |f| f.parse())?;
    let scene = SinewScene::load(Path::new(path))?;

    let mut plain_ms = Vec::new();
    if compare {
        let mut solver = scene.scene.instantiate(Path::new(path).parent().unwrap())?;
        for _ in 0..frames {
            let start = Instant::now();
            solver.step();
            plain_ms.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }

    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        bevy::transform::TransformPlugin,
        SinewPlugin::default(),
    ));
    app.world_mut()
        .spawn(SinewSceneRoot::Built(Arc::new(scene)));
    let mut ecs_ms = Vec::new();
    let mut solver_ms = Vec::new();
    for _ in 0..frames {
        let start = Instant::now();
        app.update();
        ecs_ms.push(start.elapsed().as_secs_f64() * 1e3);
        solver_ms.push(app.world().resource::<SinewTimings>().total.as_secs_f64() * 1e3);
    }
    let timings = app.world().resource::<SinewTimings>();
    println!("{path}: {frames} frames; last frame per block:");
    for (name, d) in timings.blocks() {
        println!("  {name:<15} {:8.3} ms", d.as_secs_f64() * 1e3);
    }
    // The first update also spawns the scene: leave it out.
    let ecs = median(ecs_ms[1..].to_vec());
    println!(
        "Bevy driver: median app.update {ecs:.3} ms, blocks {:.3} ms",
        median(solver_ms[1..].to_vec())
    );
    if compare {
        let plain = median(plain_ms);
        println!(
            "plain driver: median step {plain:.3} ms; ECS overhead {:+.1} %",
            (ecs / plain - 1.0) * 100.0
        );
    }
    Ok(())
}
