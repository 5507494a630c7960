//! Bones of one mesh share one target geometry: a crowd's copies hold each
//! bone once and step as if each had its own.

use super::Solver;
use crate::closest::{TargetSource, TargetSurface};
use crate::scene::Scene;
use glam::Vec3;
use std::path::Path;

/// A crowd holds each bone mesh once: a copy's bone shares copy 0's
/// geometry (one BVH, adjacency and side data), no muscle target is
/// shared, and the copies step bit for bit as with every bone built on its
/// own.
#[test]
fn copies_share_their_bones_geometry_and_step_as_if_they_did_not() {
    let path = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../assets/scenes/t3.ron"
    ));
    let (scene, base) = (Scene::load(path).unwrap(), path.parent().unwrap());
    let crowd = scene.crowd(3, Vec3::new(0.6, 0.0, 0.0), 0.0).unwrap();
    let mut shared = crowd.instantiate(base).unwrap();
    let bones = scene.bones.len();
    let target_of = |s: &Solver, b: usize| s.bones()[b].target;
    let mut meshes = Vec::new();
    for b in 0..bones {
        let Some(first) = target_of(&shared, b) else {
            continue;
        };
        let first = &shared.targets()[first];
        for k in 1..3 {
            let copy = &shared.targets()[target_of(&shared, k * bones + b).unwrap()];
            assert!(
                copy.shares_geometry_with(first),
                "{} and {}",
                copy.name,
                first.name
            );
        }
        meshes.push(first);
    }
    assert!(meshes.len() >= 3, "{} bone meshes", meshes.len());
    for (i, a) in meshes.iter().enumerate() {
        for b in &meshes[i + 1..] {
            assert!(!a.shares_geometry_with(b), "{} and {}", a.name, b.name);
        }
    }
    let shares_with_another = |s: &Solver, i: usize| {
        let t = s.targets();
        (0..t.len()).any(|j| j != i && t[i].shares_geometry_with(&t[j]))
    };
    for (i, t) in shared.targets().iter().enumerate() {
        if t.is_deforming() {
            assert!(!shares_with_another(&shared, i), "muscle {}", t.name);
        }
    }
    // The same crowd with every bone's geometry its own, built from the
    // bone's mesh.
    let mut own = crowd.instantiate(base).unwrap();
    let (bone_meshes, _) = crowd.load_meshes(base).unwrap();
    for (b, mesh) in bone_meshes.iter().enumerate() {
        let (Some(mesh), Some(target)) = (mesh, own.bones[b].target) else {
            continue;
        };
        let t = &mut own.targets[target];
        let mut alone = TargetSurface::new(
            t.name.clone(),
            t.source,
            mesh.positions.clone(),
            mesh.triangles.clone(),
        );
        alone.set_transform(t.transform);
        *t = alone;
    }
    assert!((0..own.targets().len()).all(|i| !shares_with_another(&own, i)));
    for _ in 0..8 {
        shared.step();
        own.step();
    }
    for (a, b) in shared.muscles().iter().zip(own.muscles()) {
        let bits = |x: &[Vec3]| -> Vec<[u32; 3]> {
            x.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
        };
        assert!(bits(&a.x) == bits(&b.x), "{} differs", a.name);
    }
}

/// Through the solver's API too: a bone added with a mesh equal, to the
/// bit, to an earlier bone's shares its geometry; a mesh one position off
/// gets its own, and the bones pose their targets apart.
#[test]
fn a_bone_of_an_equal_mesh_shares_its_geometry() {
    use crate::animation::TransformTrack;
    use crate::mesh::primitives::MeshGenerator;
    use crate::solver::SolverSettings;
    let mesh = MeshGenerator::Ellipsoid {
        center: Vec3::ZERO,
        radii: Vec3::new(0.05, 0.02, 0.025),
        segments: 16,
        stacks: 12,
    }
    .build("bone")
    .unwrap();
    let mut off = mesh.clone();
    off.positions[7].x = f32::from_bits(off.positions[7].x.to_bits() + 1);
    let mut solver = Solver::new(SolverSettings::default()).unwrap();
    let still = TransformTrack::default();
    let mut moved = TransformTrack::default();
    moved.keys.push(crate::animation::TransformKey {
        time: 0.0,
        translation: Vec3::X,
        rotation: glam::Quat::IDENTITY,
    });
    let a = solver.add_bone("a", still.clone(), Some(&mesh));
    let b = solver.add_bone("b", moved, Some(&mesh));
    let c = solver.add_bone("c", still, Some(&off));
    let target = |bone: usize| &solver.targets()[solver.bones()[bone].target.unwrap()];
    assert!(target(b).shares_geometry_with(target(a)));
    assert!(!target(c).shares_geometry_with(target(a)));
    assert_eq!(
        (target(b).name.as_str(), target(b).source),
        ("b", TargetSource::Bone(b))
    );
    let probe = Vec3::new(1.0, 0.1, 0.0);
    let (near_a, near_b) = (target(a).lower_bound(probe), target(b).lower_bound(probe));
    assert!(near_b < 0.1 && near_a > 0.9, "{near_a} {near_b}");
}

/// A clone of a target shares its geometry (a bone given to many
/// characters); a muscle target's clone gets its own copy when one of the
/// two publishes, and the other keeps what it had.
#[test]
fn a_clone_shares_until_one_of_two_muscle_targets_publishes() {
    use crate::mesh::primitives::MeshGenerator;
    let mesh = MeshGenerator::Ellipsoid {
        center: Vec3::ZERO,
        radii: Vec3::new(0.05, 0.02, 0.025),
        segments: 16,
        stacks: 12,
    }
    .build("muscle")
    .unwrap();
    let source = TargetSource::Muscle(0);
    let original = TargetSurface::new("muscle", source, mesh.positions, mesh.triangles);
    let mut copy = original.clone();
    assert!(copy.shares_geometry_with(&original));
    let moved: Vec<Vec3> = (original.positions().iter()).map(|p| *p * 1.1).collect();
    copy.publish(&moved);
    assert!(!copy.shares_geometry_with(&original));
    assert_eq!(copy.positions(), moved.as_slice());
    assert!(original.positions().iter().zip(&moved).all(|(a, b)| a != b));
    let mut staged = moved.iter().map(|p| *p * 1.1).collect::<Vec<_>>();
    let mut again = copy.clone();
    let slack = again.moved_squared(&staged);
    again.publish_staged(&mut staged, slack);
    assert!(!again.shares_geometry_with(&copy));
    assert_eq!(copy.positions(), moved.as_slice());
}
