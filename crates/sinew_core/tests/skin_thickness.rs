//! `VertexMaps::thickness`: the fat under a skin. A skin shell 1 cm above
//! a bone ball, in contact with it and bound to a second bone that sinks
//! 8 mm (its skinned position comes down to 2 mm above the ball): without
//! a map its top stays at its rest gap, with 4 mm of fat it is pressed down
//! to 4 mm and no closer, with 1 mm it goes where its binding puts it —
//! every method.

use sinew_core::animation::{TransformKey, TransformTrack};
use sinew_core::constraints::SlidingMode;
use sinew_core::glam::{Quat, Vec3};
use sinew_core::mesh::primitives::MeshGenerator;
use sinew_core::muscle::{MuscleDesc, MuscleParams, Roots, SkinBindingDesc, TargetRef, VertexMaps};
use sinew_core::{Solver, SolverMethod, SolverSettings};

const BONE_RADIUS: f32 = 0.04;
const SKIN_RADIUS: f32 = 0.05;

fn ball(radius: f32, name: &str) -> sinew_core::mesh::SurfaceMesh {
    MeshGenerator::Ellipsoid {
        center: Vec3::ZERO,
        radii: Vec3::splat(radius),
        segments: 24,
        stacks: 16,
    }
    .build(name)
    .unwrap()
}

/// The shell over the ball after 2 s, its binding's bone 8 mm lower than
/// at rest; `thickness` paints every vertex.
fn settled(thickness: Option<f32>, method: SolverMethod) -> Solver {
    let settings = SolverSettings {
        method,
        threads: 2,
        gravity: Vec3::new(0.0, -9.81, 0.0),
        ..Default::default()
    };
    let mut solver = Solver::new(settings).unwrap();
    let key = |time: f32, y: f32| TransformKey {
        time,
        translation: Vec3::new(0.0, y, 0.0),
        rotation: Quat::IDENTITY,
    };
    let track = |keys| TransformTrack {
        keys,
        ..Default::default()
    };
    let bone = solver.add_bone(
        "bone",
        track(vec![key(0.0, 0.0)]),
        Some(&ball(BONE_RADIUS, "bone")),
    );
    let sinking = solver.add_bone(
        "sinking",
        track(vec![key(0.0, 0.0), key(0.5, 0.0), key(1.0, -0.008)]),
        None,
    );
    let skin = ball(SKIN_RADIUS, "skin");
    let n = skin.vertex_count();
    let mut params = MuscleParams::surface_layer(1.1, 0.02);
    params.sliding_mode = SlidingMode::Contact;
    // A soft membrane: the sinking binding pulls the whole shell down, and
    // a shell that resists shear (its quads' corner areas at the default
    // 1e-7 m³/N) hands that pull to the few vertices in contact on top,
    // which then give 1–3 mm; this test is about the fat under them.
    params.compliance.area = 1e-3;
    solver
        .add_muscle(MuscleDesc {
            name: "skin".into(),
            mesh: skin,
            roots: Roots::Vertices(Vec::new()),
            attachments: Vec::new(),
            targets: vec![TargetRef::Bone(bone)],
            params,
            maps: VertexMaps {
                thickness: thickness.map(|t| vec![t; n]),
                ..Default::default()
            },
            binding: Some(SkinBindingDesc {
                influences: vec![vec![(sinking, 1.0)]; n],
                strength: Vec::new(),
                holds_shape: false,
            }),
        })
        .unwrap();
    while solver.time() < 2.0 {
        solver.step();
    }
    solver
}

/// The skin's top vertex's height above the bone, and the smallest
/// distance of any skin vertex from the bone's centre minus its radius.
fn gaps(solver: &Solver) -> (f32, f32) {
    let m = &solver.muscles()[0];
    let skin = &m.x[..m.surface_count];
    let top = skin.iter().map(|p| p.y).fold(f32::MIN, f32::max) - BONE_RADIUS;
    let closest = skin.iter().map(|p| p.length()).fold(f32::MAX, f32::min) - BONE_RADIUS;
    (top, closest)
}

#[test]
fn the_skin_is_pressed_down_to_its_thickness_and_no_further() {
    for method in SolverMethod::EVERY {
        let (free_top, free_min) = gaps(&settled(None, method));
        let (fat_top, fat_min) = gaps(&settled(Some(0.004), method));
        let (thin_top, _) = gaps(&settled(Some(0.001), method));
        eprintln!(
            "{method:?}: top of the skin over the bone {:.2} mm without a map, {:.2} mm with 4 mm \
             of fat (closest {:.2} / {:.2} mm), {:.2} mm with 1 mm",
            free_top * 1e3,
            fat_top * 1e3,
            free_min * 1e3,
            fat_min * 1e3,
            thin_top * 1e3
        );
        // Contact (1e-3 m/N) against the binding (5e-2) pulling 8 mm down.
        assert!(
            free_top > 0.008,
            "{method:?}: without a map the top keeps its rest gap: {free_top}"
        );
        assert!(
            (fat_top - 0.004).abs() < 5e-4,
            "{method:?}: with 4 mm of fat it is pressed down to it: {fat_top}"
        );
        assert!(fat_min > 0.003, "{method:?}: never closer: {fat_min}");
        assert!(
            (thin_top - 0.002).abs() < 5e-4,
            "{method:?}: with 1 mm of fat it goes where its binding puts it: {thin_top}"
        );
    }
}

#[test]
fn a_bad_thickness_is_refused_by_name() {
    let mut solver = Solver::new(SolverSettings::default()).unwrap();
    let skin = ball(SKIN_RADIUS, "skin");
    let n = skin.vertex_count();
    let mut values = vec![0.004; n];
    values[7] = -1.0;
    let desc = |maps| MuscleDesc {
        name: "skin".into(),
        mesh: skin.clone(),
        roots: Roots::Vertices(Vec::new()),
        attachments: Vec::new(),
        targets: Vec::new(),
        params: MuscleParams::surface_layer(1.1, 0.02),
        maps,
        binding: None,
    };
    let negative = solver.add_muscle(desc(VertexMaps {
        thickness: Some(values),
        ..Default::default()
    }));
    let message = negative.unwrap_err().to_string();
    assert!(
        message.contains("thickness") && message.contains('7'),
        "{message}"
    );
    let short = solver.add_muscle(desc(VertexMaps {
        thickness: Some(vec![0.004; 3]),
        ..Default::default()
    }));
    assert!(short.unwrap_err().to_string().contains("thickness"));
}
