use super::*;
use glam::Quat;

fn elbow_rig() -> ActivationRig {
    let sensors = [SensorSpec {
        name: "elbow".into(),
        kind: SensorKind::Rotation {
            a: BonePoint {
                bone: "upper".into(),
                point: Vec3::new(0.0, 0.3, 0.0),
            },
            middle: BonePoint {
                bone: "fore".into(),
                point: Vec3::ZERO,
            },
            c: BonePoint {
                bone: "fore".into(),
                point: Vec3::new(0.0, -0.25, 0.0),
            },
        },
    }];
    let names = ["upper", "fore"];
    let mut rig = ActivationRig::new(&sensors, &|n| names.iter().position(|b| *b == n)).unwrap();
    rig.add_stack(
        0,
        "biceps",
        &[ActivationLayer::Add(LayerInput::Sensor(SensorInput {
            sensor: "elbow".into(),
            output: SensorOutput::Value,
            remap: Remap {
                input: (std::f32::consts::PI, std::f32::consts::FRAC_PI_2),
                ..Default::default()
            },
            trigger: TriggerSpec {
                attack: 0.0,
                release: 0.0,
                ..Default::default()
            },
        }))],
    )
    .unwrap();
    rig
}

fn bones(angle: f32) -> [Affine3A; 2] {
    [
        Affine3A::IDENTITY,
        Affine3A::from_quat(Quat::from_rotation_z(angle)),
    ]
}

#[test]
fn rotation_sensor_reads_the_joint_angle_and_drives_activation() {
    let mut rig = elbow_rig();
    let mut got = -1.0;
    rig.update(&bones(0.0), 0.0, 1.0 / 60.0, |_, a| got = a);
    assert!(got.abs() < 1e-5, "straight arm: {got}");
    rig.update(
        &bones(std::f32::consts::FRAC_PI_2),
        0.0,
        1.0 / 60.0,
        |_, a| got = a,
    );
    assert!((got - 1.0).abs() < 1e-4, "right angle: {got}");
    let (_, [theta, velocity, _]) = rig.readings().next().unwrap();
    assert!((theta - std::f32::consts::FRAC_PI_2).abs() < 1e-5);
    // Closing the joint gives a negative angular velocity of −π/2 per frame.
    assert!((velocity + std::f32::consts::FRAC_PI_2 * 60.0).abs() < 1e-2);
}

#[test]
fn attack_and_release_smooth_the_trigger() {
    let mut rig = elbow_rig();
    let trigger = rig.stacks[0].1.trigger_mut(0).expect("a sensor layer");
    trigger.attack = 0.1;
    trigger.release = 0.3;
    let mut a = 0.0;
    rig.update(&bones(std::f32::consts::FRAC_PI_2), 0.0, 0.1, |_, v| a = v);
    // One time constant: 1 − e⁻¹.
    assert!((a - (1.0 - (-1.0f32).exp())).abs() < 1e-4, "{a}");
    let before = a;
    rig.update(&bones(0.0), 0.0, 0.1, |_, v| a = v);
    // Release is slower: a third of a time constant.
    assert!((a - before * (-1.0f32 / 3.0).exp()).abs() < 1e-4, "{a}");
}

#[test]
fn unknown_sensor_or_bone_is_an_error() {
    let names = ["upper"];
    let bad = [SensorSpec {
        name: "s".into(),
        kind: SensorKind::Linear {
            point: BonePoint {
                bone: "femur".into(),
                point: Vec3::ZERO,
            },
        },
    }];
    let e = ActivationRig::new(&bad, &|n| names.iter().position(|b| *b == n)).unwrap_err();
    assert!(e.to_string().contains("femur"), "{e}");
    let mut rig = ActivationRig::new(&[], &|_| None).unwrap();
    let e = rig
        .add_stack(
            0,
            "m",
            &[ActivationLayer::Add(LayerInput::Sensor(SensorInput {
                sensor: "ghost".into(),
                ..Default::default()
            }))],
        )
        .unwrap_err();
    assert!(e.to_string().contains("ghost"), "{e}");
}
