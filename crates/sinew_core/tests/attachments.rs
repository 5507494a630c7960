//! Attaching by region: a point and a radius hold every surface vertex
//! within the radius (at least the nearest), without vertex indices.

use sinew_core::error::BuildError;
use sinew_core::glam::{Affine3A, Vec3};
use sinew_core::muscle::{AttachmentDesc, Muscle, MuscleDesc, Roots};

fn oval(attachments: Vec<AttachmentDesc>) -> Result<Muscle, BuildError> {
    let mesh = sinew_core::mesh::primitives::thesis_oval(Vec3::ZERO)
        .build("oval")
        .unwrap();
    let desc = MuscleDesc {
        name: "oval".into(),
        mesh,
        roots: Roots::LongestAxisTips,
        attachments,
        targets: Vec::new(),
        params: Default::default(),
        maps: Default::default(),
        binding: None,
    };
    Muscle::build(desc, 1.0, |_| Affine3A::IDENTITY)
}

#[test]
fn a_region_holds_every_vertex_within_its_radius() {
    let probe = oval(Vec::new()).unwrap();
    let surface = probe.surface_positions().to_vec();
    let tip = surface
        .iter()
        .copied()
        .fold(Vec3::splat(f32::MIN), |a, p| if p.x > a.x { p } else { a });
    for radius in [0.0, 0.005, 0.01, 0.02] {
        let within = surface
            .iter()
            .filter(|p| p.distance(tip) <= radius)
            .count()
            .max(1);
        let m = oval(vec![AttachmentDesc {
            point: Some(tip),
            radius,
            ..Default::default()
        }])
        .unwrap();
        println!("radius {radius} m: {} vertices held", m.attachments.len());
        assert_eq!(m.attachments.len(), within, "radius {radius}");
        assert!(
            m.attachments
                .iter()
                .all(|a| surface[a.vertex.index()].distance(tip) <= radius.max(1e-6))
        );
        // Held vertices do not move (world attachment: infinite mass).
        assert!(m.attachments.iter().all(|a| m.w[a.vertex.index()] == 0.0));
    }
    assert!(
        oval(vec![AttachmentDesc {
            point: Some(tip),
            radius: 0.02,
            ..Default::default()
        }])
        .unwrap()
        .attachments
        .len()
            > 3
    );
}

#[test]
fn a_bad_radius_is_refused_by_name() {
    for radius in [f32::NAN, -1.0, f32::INFINITY] {
        let err = oval(vec![AttachmentDesc {
            point: Some(Vec3::ZERO),
            radius,
            ..Default::default()
        }])
        .unwrap_err();
        assert!(
            matches!(&err, BuildError::InvalidParameter { parameter, .. } if parameter == "attachments[0].radius"),
            "{err}"
        );
    }
}

#[test]
fn set_attachments_detaches_and_reattaches_at_run_time() {
    let probe = oval(Vec::new()).unwrap();
    let tip = probe
        .surface_positions()
        .iter()
        .copied()
        .fold(Vec3::splat(f32::MIN), |a, p| if p.x > a.x { p } else { a });
    let tip_region = AttachmentDesc {
        point: Some(tip),
        radius: 0.01,
        ..Default::default()
    };
    let mut m = oval(vec![tip_region]).unwrap();
    let built = m.constraints.attach.clone();
    let held = m.attachments.clone();
    assert!(held.len() > 1);
    let topology = m.topology();
    // The same list again gives the same constraints.
    m.set_attachments(held.clone());
    assert_eq!(m.constraints.attach, built);
    assert!(
        m.topology() != topology,
        "a rebuild invalidates derived plans"
    );
    // Detaching frees every held particle.
    m.set_attachments([]);
    assert!(m.attachments.is_empty() && m.constraints.attach.is_empty());
    assert!(m.constraints.branch_attach.is_empty());
    assert_eq!(m.w, m.free_w, "every particle has its mass back");
    // Re-attaching one vertex where it is now, to a bone posed elsewhere:
    // its place in the bone's frame is the vertex seen from the bone.
    let pose = Affine3A::from_translation(Vec3::new(0.0, 1.0, 0.0));
    let v = held[0].vertex.raw();
    let a = m.attachment_at(Some(0), v, pose);
    assert_eq!(a.vertex_local, m.x[v as usize] - Vec3::new(0.0, 1.0, 0.0));
    m.set_attachments([a]);
    assert_eq!(m.attachments.len(), 1);
    assert_eq!(m.w[v as usize], 0.0, "held rigidly (compliance 0)");
}

#[test]
fn a_region_without_a_finite_point_or_radius_is_refused() {
    let positions = [Vec3::ZERO, Vec3::X];
    for desc in [
        AttachmentDesc::default(),
        AttachmentDesc {
            point: Some(Vec3::NAN),
            ..Default::default()
        },
        AttachmentDesc {
            point: Some(Vec3::ZERO),
            radius: -1.0,
            ..Default::default()
        },
    ] {
        let error = desc.held_vertices(&positions, "m", 3).unwrap_err();
        assert!(error.to_string().contains("attachments[3]"), "{error}");
    }
    let near = AttachmentDesc {
        point: Some(Vec3::new(0.9, 0.0, 0.0)),
        radius: 2.0,
        ..Default::default()
    };
    assert_eq!(near.held_vertices(&positions, "m", 0).unwrap(), vec![1, 0]);
}
