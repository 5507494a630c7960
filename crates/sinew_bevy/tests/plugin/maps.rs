//! Per-vertex maps painted on a Bevy mesh: sinew's vertex attributes and
//! vertex colours reach the built muscle (welded at UV seams), a painted
//! weight of 0 switches that connection off, and a bad value is refused
//! with a typed error naming the map and the vertex.
#![cfg(feature = "render")]

use crate::common;

use bevy::prelude::*;
use sinew_bevy::mesh_maps::{
    ATTRIBUTE_DAMPING_SCALE, ATTRIBUTE_HARD_WEIGHT, ATTRIBUTE_SLIDING_WEIGHT,
    ATTRIBUTE_TENDON_MASK, ATTRIBUTE_THICKNESS,
};
use sinew_bevy::prelude::*;
use sinew_core::BuildError;
use sinew_core::muscle::Roots;
use std::sync::{Arc, Mutex};

/// The plug-in's app with mesh assets.
fn app() -> App {
    let mut app = common::app();
    app.add_plugins(bevy::asset::AssetPlugin::default())
        .init_asset::<Mesh>();
    app
}

/// A 2 cm ball as a muscle mesh, painted by `paint`, built; its entity.
fn painted_ball(app: &mut App, paint: impl FnOnce(&mut Mesh, usize), colors: bool) -> Entity {
    let mut mesh = Sphere::new(0.02).mesh().ico(3).unwrap();
    let count = mesh.count_vertices();
    paint(&mut mesh, count);
    let handle = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let mut builder =
        MuscleBuilder::new("ball", MuscleSource::Handle(handle)).roots(Roots::LongestAxisTips);
    if colors {
        builder = builder.weights_from_colors();
    }
    app.world_mut().spawn(builder).id()
}

fn built(app: &mut App, muscle: Entity) {
    common::update_until(app, |app| {
        app.world().get::<MuscleState>(muscle).is_some()
            || app.world().get::<BuildFailed>(muscle).is_some()
    });
}

#[test]
fn vertex_attributes_become_the_muscles_maps() {
    let mut app = app();
    let muscle = painted_ball(
        &mut app,
        |mesh, n| {
            mesh.insert_attribute(ATTRIBUTE_HARD_WEIGHT, vec![0.0f32; n]);
            mesh.insert_attribute(ATTRIBUTE_SLIDING_WEIGHT, vec![0.75f32; n]);
            mesh.insert_attribute(ATTRIBUTE_TENDON_MASK, vec![0.25f32; n]);
            mesh.insert_attribute(ATTRIBUTE_DAMPING_SCALE, vec![3.0f32; n]);
            mesh.insert_attribute(ATTRIBUTE_THICKNESS, vec![0.004f32; n]);
        },
        false,
    );
    built(&mut app, muscle);
    let m = &app.world().get::<MuscleState>(muscle).unwrap().muscle;
    let n = m.surface_count;
    assert_eq!(m.maps.hard.as_deref(), Some(&vec![0.0; n][..]));
    assert_eq!(m.maps.sliding.as_deref(), Some(&vec![0.75; n][..]));
    assert_eq!(m.maps.tendon.as_deref(), Some(&vec![0.25; n][..]));
    assert_eq!(m.maps.damping.as_deref(), Some(&vec![3.0; n][..]));
    assert_eq!(m.maps.thickness.as_deref(), Some(&vec![0.004; n][..]));
    assert!(m.maps.soft.is_none(), "not painted: the default weight");
}

#[test]
fn vertex_colours_paint_the_weights_when_asked() {
    let mut app = app();
    let paint = |mesh: &mut Mesh, n| {
        mesh.insert_attribute(Mesh::ATTRIBUTE_COLOR, vec![[1.0f32, 0.0, 0.5, 1.0]; n]);
    };
    let asked = painted_ball(&mut app, paint, true);
    let not_asked = painted_ball(&mut app, paint, false);
    built(&mut app, asked);
    built(&mut app, not_asked);
    let m = &app.world().get::<MuscleState>(asked).unwrap().muscle;
    let n = m.surface_count;
    assert_eq!(m.maps.sliding.as_deref(), Some(&vec![1.0; n][..]));
    assert_eq!(m.maps.soft.as_deref(), Some(&vec![0.0; n][..]));
    assert_eq!(m.maps.hard.as_deref(), Some(&vec![0.5; n][..]));
    let plain = &app.world().get::<MuscleState>(not_asked).unwrap().muscle;
    assert!(plain.maps.sliding.is_none() && plain.maps.hard.is_none());
}

#[test]
fn a_bad_painted_value_is_refused_by_map_and_vertex() {
    let mut app = app();
    let failed = Arc::new(Mutex::new(None));
    let sink = failed.clone();
    app.add_observer(move |f: On<MuscleBuildFailed>| {
        *sink.lock().unwrap() = Some(f.error.clone());
    });
    let muscle = painted_ball(
        &mut app,
        |mesh, n| {
            let mut hard = vec![0.5f32; n];
            hard[0] = -1.0;
            mesh.insert_attribute(ATTRIBUTE_HARD_WEIGHT, hard);
        },
        false,
    );
    built(&mut app, muscle);
    app.update();
    let error = failed.lock().unwrap().clone().expect("refused");
    assert!(
        matches!(
            &*error,
            MuscleBuildError::Build(BuildError::MapValue { map, vertex: 0, value, .. })
                if map == "hard" && *value == -1.0
        ),
        "{error}"
    );
    assert!(app.world().get::<MuscleState>(muscle).is_none());
}
