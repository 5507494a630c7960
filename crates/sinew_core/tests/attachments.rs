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
