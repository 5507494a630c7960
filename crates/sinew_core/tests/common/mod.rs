//! What several integration tests build alike.

use sinew_core::glam::Vec3;
use sinew_core::mesh::primitives::MeshGenerator;
use sinew_core::muscle::MuscleParams;
use sinew_core::scene::{MeshSource, MuscleSpec, Scene, builtin};

/// P1's oval (held at both ends, 6 × 2.5 × 2.5 cm) under a closed skin 4 mm
/// above it, an ellipsoid of `segments` × `stacks` (a surface layer of
/// 2.2 kg/m², in contact within 1 cm), as P1's second body.
pub fn oval_with_skin(segments: u32, stacks: u32) -> Scene {
    let mut scene = builtin("P1").expect("built-in scene");
    scene.muscles.push(MuscleSpec {
        name: "skin".into(),
        mesh: MeshSource::Generator(MeshGenerator::Ellipsoid {
            center: Vec3::ZERO,
            radii: Vec3::new(0.064, 0.029, 0.029),
            segments,
            stacks,
        }),
        targets: vec!["oval".into()],
        params: MuscleParams::surface_layer(2.2, 0.01),
        ..Default::default()
    });
    scene
}
