//! Activates the T1 oval muscle (0 → 1 → 0) and prints its length along the
//! fibres and its volume, relative to rest, every 10 frames.
//!
//! Run with `cargo run --release --example oval`.

use sinew::core::glam::Vec3;
use sinew::core::muscle::longest_axis;
use sinew::core::scene::builtin;

fn extent(points: &[Vec3], axis: Vec3) -> f32 {
    let (lo, hi) = points
        .iter()
        .map(|p| p.dot(axis))
        .fold((f32::MAX, f32::MIN), |(lo, hi), d| (lo.min(d), hi.max(d)));
    hi - lo
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let scene = builtin("T1").expect("T1 is built in");
    let mut solver = scene.instantiate(std::path::Path::new("."))?;
    let axis = longest_axis(&solver.muscles()[0].rest);
    let rest_len = extent(solver.muscles()[0].surface_positions(), axis);
    let rest_vol = solver.muscles()[0].rest_volume();
    println!("frame  activation  length/rest  volume/rest");
    for frame in 1..=160 {
        solver.step();
        let m = &solver.muscles()[0];
        if frame % 10 == 0 {
            println!(
                "{frame:>5}  {:>10.3}  {:>11.3}  {:>11.3}",
                m.params.activation,
                extent(m.surface_positions(), axis) / rest_len,
                m.volume() / rest_vol
            );
        }
    }
    Ok(())
}
