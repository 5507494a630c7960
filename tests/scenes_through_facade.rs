//! The committed RON scenes load and run through the `sinew` facade crate.

use std::path::Path;

#[test]
fn committed_scenes_run_through_the_facade() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    for file in ["p1.ron", "p2.ron", "t1.ron", "p3.ron"] {
        let path = dir.join(file);
        let scene = sinew::core::scene::Scene::load(&path).unwrap();
        let mut solver = scene.instantiate(&dir).unwrap();
        for _ in 0..5 {
            solver.step();
        }
        for m in solver.muscles() {
            assert!(
                m.x.iter().all(|p| p.is_finite()),
                "{file}: {} not finite",
                m.name
            );
        }
    }
}
