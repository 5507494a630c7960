//! Runs a scene headless (`MinimalPlugins`, no window) for N frames through
//! the Bevy plug-in and prints the per-block timings. With `--compare` the
//! plain `sinew_core` driver steps the same scene in lockstep (same frames,
//! same machine state), and both medians and the ECS overhead are reported,
//! with the part of it that is Bevy's own frame: an app with the same
//! plugins but no sinew, updated in the same lockstep.
//!
//! `--threads N` runs both drivers on N worker threads (default: the
//! scene's). `--instances N` spawns a crowd: N copies of the scene's body
//! side by side, 1 m apart, each started 0.25 s after the one before
//! (`Scene::crowd`), in one plug-in.
//!
//! `cargo run --release --example headless -- assets/scenes/t5.ron 120 --compare --threads 2`

use bevy::prelude::*;
use sinew::bevy::prelude::*;
use sinew::core::StepTimings;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

fn print_blocks(title: &str, blocks: impl IntoIterator<Item = (&'static str, Duration)>) {
    println!("{title}, last frame per block:");
    for (name, d) in blocks {
        println!("  {name:<15} {:8.3} ms", ms(d));
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let compare = args.iter().any(|a| a == "--compare");
    let count = |flag: &str| -> Result<Option<u32>, Box<dyn std::error::Error>> {
        match args.iter().position(|a| a == flag) {
            Some(i) => Ok(Some(
                args.get(i + 1)
                    .ok_or(format!("{flag} needs a count"))?
                    .parse::<u32>()
                    .map_err(|e| format!("{flag}: {e}"))?,
            )),
            None => Ok(None),
        }
    };
    let threads = count("--threads")?;
    let instances = count("--instances")?.unwrap_or(1);
    let mut positional = args
        .iter()
        .enumerate()
        .filter(|&(i, a)| {
            !a.starts_with("--")
                && (i == 0 || !matches!(args[i - 1].as_str(), "--threads" | "--instances"))
        })
        .map(|(_, a)| a);
    let path = positional
        .next()
        .map_or("assets/scenes/p3.ron", |p| p.as_str());
    let frames: usize = positional.next().map_or(Ok(120), |f| f.parse())?;
    if frames < 2 {
        return Err("run at least 2 frames (the first is left out of the medians)".into());
    }
    let mut scene = if instances > 1 {
        // Read once, built once: the crowd, not the scene and then the crowd.
        let file = Path::new(path);
        let single = sinew::core::scene::Scene::load(file)?;
        let spacing = sinew::core::glam::Vec3::X * single.settings.length_unit;
        let crowd = single.crowd(instances, spacing, 0.25)?;
        let base = file.parent().unwrap_or(Path::new("."));
        SinewScene::build(crowd, base).map_err(|e| e.in_file(file))?
    } else {
        SinewScene::load(Path::new(path))?
    };
    if let Some(threads) = threads {
        scene.scene.settings.threads = threads;
        scene.parts.settings.threads = threads;
    }
    let mut plain = if compare {
        Some(scene.scene.instantiate(Path::new(path).parent().unwrap())?)
    } else {
        None
    };

    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        bevy::transform::TransformPlugin,
        SinewPlugin::default().every_update(),
    ));
    let mut empty = compare.then(|| {
        let mut app = App::new();
        app.add_plugins((MinimalPlugins, bevy::transform::TransformPlugin));
        app
    });
    app.world_mut()
        .spawn(SinewSceneRoot::Built(Arc::new(scene)));
    let (mut ecs_ms, mut blocks_ms, mut plain_ms) = (Vec::new(), Vec::new(), Vec::new());
    let mut empty_ms = Vec::new();
    for _ in 0..frames {
        if let Some(empty) = &mut empty {
            let start = Instant::now();
            empty.update();
            empty_ms.push(ms(start.elapsed()));
        }
        if let Some(solver) = &mut plain {
            let start = Instant::now();
            solver.step();
            plain_ms.push(ms(start.elapsed()));
        }
        let start = Instant::now();
        app.update();
        ecs_ms.push(ms(start.elapsed()));
        blocks_ms.push(ms(app.world().resource::<SinewTimings>().total));
    }
    println!("{path} ×{instances}: {frames} frames");
    if let Some(solver) = &plain {
        let t = solver.timings();
        print_blocks(
            "plain driver",
            StepTimings::NAMES.into_iter().zip(t.as_array()),
        );
    }
    print_blocks(
        "Bevy driver",
        app.world().resource::<SinewTimings>().blocks(),
    );
    // The first frame links the targets (and, in the app, spawns the
    // scene): leave it out of both.
    let ecs = median(ecs_ms[1..].to_vec());
    println!(
        "Bevy driver: median app.update {ecs:.3} ms (blocks {:.3} ms)",
        median(blocks_ms[1..].to_vec())
    );
    if plain.is_some() {
        let base = median(plain_ms[1..].to_vec());
        let bevy_frame = median(empty_ms[1..].to_vec());
        println!(
            "plain driver: median step {base:.3} ms; ECS overhead {:+.1} %",
            (ecs / base - 1.0) * 100.0
        );
        println!(
            "of which Bevy's own frame (same plugins, no sinew): {bevy_frame:.3} ms ({:.1} %)",
            bevy_frame / base * 100.0
        );
    }
    Ok(())
}
