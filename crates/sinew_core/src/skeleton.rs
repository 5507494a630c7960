//! A kinematic skeleton: a tree of rigid bodies connected by hinge, slide and
//! ball joints, posed every frame (and at every substep) from keyframed joint
//! values. Bones of a scene follow the world frames of their bodies.
//!
//! The joint model is MuJoCo's: a body sits at `translation`/`rotation` in its
//! parent's frame, then its joints act in order, each about (or along) an axis
//! through `anchor`, both in the body's own frame. A hinge turns by its value
//! (radians), a slide moves by its value (metres), a ball turns by a rotation
//! vector (three values, radians).

use crate::animation::Curve;
use crate::error::SceneError;
use glam::{Affine3A, Quat, Vec3};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;

/// Kind of a joint.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum JointKind {
    /// One rotational degree of freedom about `axis`. Value in radians.
    #[default]
    Hinge,
    /// One translational degree of freedom along `axis`. Value in metres.
    Slide,
    /// Three rotational degrees of freedom: a rotation vector (radians).
    Ball,
}

impl JointKind {
    /// Number of scalar values the joint takes.
    pub fn dofs(self) -> usize {
        match self {
            Self::Hinge | Self::Slide => 1,
            Self::Ball => 3,
        }
    }
}

/// A joint of a body.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct JointSpec {
    /// Unique name.
    pub name: String,
    /// Hinge, slide or ball.
    pub kind: JointKind,
    /// Point the joint acts about, in the body frame. Units: m.
    pub anchor: Vec3,
    /// Axis in the body frame (hinge and slide).
    pub axis: Vec3,
    /// Allowed range of the value, if limited; keyframes are clamped to it.
    pub range: Option<(f32, f32)>,
}

/// A rigid body of the skeleton.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BodySpec {
    /// Unique name.
    pub name: String,
    /// Parent body; `None` for a root (placed in the world frame).
    pub parent: Option<String>,
    /// Position in the parent frame. Units: m.
    pub translation: Vec3,
    /// Orientation in the parent frame.
    pub rotation: Quat,
    /// Joints, applied in order.
    pub joints: Vec<JointSpec>,
}

/// Keyframes of one joint value over time.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct JointMotion {
    /// Joint name.
    pub joint: String,
    /// Which value of the joint (0 for hinge and slide; 0–2 for a ball's
    /// rotation-vector components).
    pub component: u8,
    /// Value over time (radians or metres).
    pub curve: Curve,
}

/// A joint whose value follows another's through a polynomial (MuJoCo's
/// joint equality): `value = Σ cₖ · driverᵏ` for k = 0..4, or `c₀` alone
/// without a driver. Knees use it to slide and roll the tibia and move the
/// patella with the flexion angle.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct JointCoupling {
    /// The coupled joint (hinge or slide).
    pub joint: String,
    /// The joint it follows; `None` holds it at `polynomial[0]`.
    pub driver: Option<String>,
    /// Coefficients `c₀ … c₄`.
    pub polynomial: [f32; 5],
}

/// Bodies, joints and their animation, as stored in a scene.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Skeleton {
    /// Bodies; a parent must come before its children.
    pub bodies: Vec<BodySpec>,
    /// Keyframed joint values; joints without motion stay at 0.
    pub motion: Vec<JointMotion>,
    /// Joints computed from other joints, applied in order after the motion.
    pub couplings: Vec<JointCoupling>,
}

#[derive(Clone, Debug)]
struct RigJoint {
    kind: JointKind,
    anchor: Vec3,
    axis: Vec3,
    /// Index of the first value in the value vector.
    offset: usize,
}

/// A keyframed joint value: value index, curve and the joint's range.
#[derive(Clone, Debug)]
struct RigMotion {
    value: usize,
    curve: Curve,
    range: Option<(f32, f32)>,
}

#[derive(Clone, Debug)]
struct RigBody {
    parent: Option<usize>,
    local: Affine3A,
    joints: Vec<RigJoint>,
}

/// A compiled [`Skeleton`]: index-based, ready to pose every substep.
#[derive(Clone, Debug)]
pub struct SkeletonRig {
    names: Vec<String>,
    bodies: Vec<RigBody>,
    joint_names: HashMap<String, usize>,
    /// Value offset of each joint by name index.
    joint_offsets: Vec<(usize, JointKind)>,
    value_count: usize,
    /// Keyframed values.
    motion: Vec<RigMotion>,
    /// `(value index, driver value index, coefficients)`.
    couplings: Vec<(usize, Option<usize>, [f32; 5])>,
}

impl Skeleton {
    /// Checks names, parents, axes and motion, and compiles the rig.
    pub fn compile(&self) -> Result<SkeletonRig, SceneError> {
        let invalid = |context: String, reason: String| SceneError::Invalid { context, reason };
        let mut index = HashMap::new();
        let mut bodies = Vec::with_capacity(self.bodies.len());
        let mut names = Vec::with_capacity(self.bodies.len());
        let mut joint_names = HashMap::new();
        let mut joint_offsets = Vec::new();
        let mut value_count = 0;
        for (bi, b) in self.bodies.iter().enumerate() {
            let context = || format!("skeleton body {bi} '{}'", b.name);
            // The parent is looked up before the body is listed, so a body
            // cannot be its own parent and the hierarchy has no cycle.
            let parent = match &b.parent {
                None => None,
                Some(p) => Some(*index.get(p).ok_or_else(|| {
                    invalid(
                        context(),
                        format!("parent '{p}' is not a body listed before it"),
                    )
                })?),
            };
            if index.insert(b.name.clone(), bi).is_some() {
                return Err(SceneError::DuplicateName(b.name.clone()));
            }
            if !b.translation.is_finite() || !b.rotation.is_finite() {
                return Err(invalid(
                    context(),
                    "non-finite translation or rotation".into(),
                ));
            }
            let rotation = normalized(b.rotation)
                .ok_or_else(|| invalid(context(), "rotation has zero length".into()))?;
            let mut joints = Vec::with_capacity(b.joints.len());
            for j in &b.joints {
                let jcontext = || format!("skeleton body '{}' joint '{}'", b.name, j.name);
                let axis = if j.kind == JointKind::Ball {
                    Vec3::X
                } else {
                    j.axis
                        .try_normalize()
                        .ok_or_else(|| invalid(jcontext(), "axis has zero length".into()))?
                };
                if !j.anchor.is_finite() {
                    return Err(invalid(jcontext(), "non-finite anchor".into()));
                }
                if let Some((lo, hi)) = j.range
                    && (lo.is_nan() || hi.is_nan() || lo > hi)
                {
                    return Err(invalid(jcontext(), format!("range ({lo}, {hi}) is empty")));
                }
                if joint_names
                    .insert(j.name.clone(), joint_offsets.len())
                    .is_some()
                {
                    return Err(SceneError::DuplicateName(j.name.clone()));
                }
                joint_offsets.push((value_count, j.kind));
                joints.push(RigJoint {
                    kind: j.kind,
                    anchor: j.anchor,
                    axis,
                    offset: value_count,
                });
                value_count += j.kind.dofs();
            }
            names.push(b.name.clone());
            bodies.push(RigBody {
                parent,
                local: Affine3A::from_rotation_translation(rotation, b.translation),
                joints,
            });
        }
        let mut motion = Vec::with_capacity(self.motion.len());
        for (i, m) in self.motion.iter().enumerate() {
            let context = || format!("skeleton motion {i} (joint '{}')", m.joint);
            let &j = joint_names
                .get(&m.joint)
                .ok_or_else(|| SceneError::UnknownReference {
                    context: context(),
                    kind: "joint",
                    name: m.joint.clone(),
                })?;
            let (offset, kind) = joint_offsets[j];
            if m.component as usize >= kind.dofs() {
                return Err(invalid(
                    context(),
                    format!(
                        "component {} but a {kind:?} joint has {}",
                        m.component,
                        kind.dofs()
                    ),
                ));
            }
            if m.curve
                .keys
                .iter()
                .any(|(t, v)| !t.is_finite() || !v.is_finite())
            {
                return Err(invalid(context(), "non-finite key".into()));
            }
            let range = self
                .bodies
                .iter()
                .flat_map(|b| &b.joints)
                .nth(j)
                .and_then(|j| j.range);
            motion.push(RigMotion {
                value: offset + m.component as usize,
                curve: m.curve.clone(),
                range,
            });
        }
        let mut couplings = Vec::with_capacity(self.couplings.len());
        for (i, c) in self.couplings.iter().enumerate() {
            let context = || format!("skeleton coupling {i} (joint '{}')", c.joint);
            let value = |name: &str| -> Result<usize, SceneError> {
                let &j = joint_names
                    .get(name)
                    .ok_or_else(|| SceneError::UnknownReference {
                        context: context(),
                        kind: "joint",
                        name: name.to_string(),
                    })?;
                let (offset, kind) = joint_offsets[j];
                if kind == JointKind::Ball {
                    return Err(invalid(context(), format!("'{name}' is a ball joint")));
                }
                Ok(offset)
            };
            if c.polynomial.iter().any(|v| !v.is_finite()) {
                return Err(invalid(context(), "non-finite coefficient".into()));
            }
            couplings.push((
                value(&c.joint)?,
                c.driver.as_deref().map(value).transpose()?,
                c.polynomial,
            ));
        }
        Ok(SkeletonRig {
            names,
            bodies,
            joint_names,
            joint_offsets,
            value_count,
            motion,
            couplings,
        })
    }
}

impl SkeletonRig {
    /// Number of bodies.
    pub fn body_count(&self) -> usize {
        self.bodies.len()
    }

    /// Index of a body by name.
    pub fn body_index(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }

    /// Body names in order.
    pub fn body_names(&self) -> &[String] {
        &self.names
    }

    /// A body's parent (a body listed before it), `None` for a root.
    pub fn parent(&self, body: usize) -> Option<usize> {
        self.bodies[body].parent
    }

    /// Number of joint values (hinge/slide 1, ball 3).
    pub fn value_count(&self) -> usize {
        self.value_count
    }

    /// Offset of a joint's first value, by joint name.
    pub fn joint_value_offset(&self, joint: &str) -> Option<usize> {
        self.joint_names
            .get(joint)
            .map(|&j| self.joint_offsets[j].0)
    }

    /// Joint values at `time` from the keyframed motion, clamped to each
    /// joint's range (0 for joints without motion, as in the model's
    /// reference pose).
    pub fn values_at(&self, time: f32, values: &mut Vec<f32>) {
        values.clear();
        values.resize(self.value_count, 0.0);
        for m in &self.motion {
            let v = m.curve.sample(time);
            values[m.value] = m.range.map_or(v, |(lo, hi)| v.clamp(lo, hi));
        }
        for &(joint, driver, c) in &self.couplings {
            let x = driver.map_or(0.0, |d| values[d]);
            values[joint] = c[0] + x * (c[1] + x * (c[2] + x * (c[3] + x * c[4])));
        }
    }

    /// World transforms of every body for the given joint values.
    pub fn pose(&self, values: &[f32], world: &mut Vec<Affine3A>) {
        world.clear();
        for b in &self.bodies {
            let mut t = match b.parent {
                Some(p) => world[p] * b.local,
                None => b.local,
            };
            for j in &b.joints {
                let motion = match j.kind {
                    JointKind::Hinge => {
                        let q = values.get(j.offset).copied().unwrap_or(0.0);
                        about(j.anchor, Quat::from_axis_angle(j.axis, q))
                    }
                    JointKind::Slide => {
                        let q = values.get(j.offset).copied().unwrap_or(0.0);
                        Affine3A::from_translation(j.axis * q)
                    }
                    JointKind::Ball => {
                        let v = Vec3::from_slice(
                            values.get(j.offset..j.offset + 3).unwrap_or(&[0.0; 3]),
                        );
                        about(j.anchor, Quat::from_scaled_axis(v))
                    }
                };
                t *= motion;
            }
            world.push(t);
        }
    }

    /// World transforms of every body at `time`.
    pub fn pose_at(&self, time: f32, values: &mut Vec<f32>, world: &mut Vec<Affine3A>) {
        self.values_at(time, values);
        self.pose(values, world);
    }
}

/// A rotation about a point.
fn about(anchor: Vec3, rotation: Quat) -> Affine3A {
    Affine3A::from_translation(anchor)
        * Affine3A::from_quat(rotation)
        * Affine3A::from_translation(-anchor)
}

/// `q` scaled to unit length, or `None` when its length is zero or not finite.
fn normalized(q: Quat) -> Option<Quat> {
    let len = q.length();
    (len > 1e-12 && len.is_finite()).then(|| q / len)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn arm() -> Skeleton {
        Skeleton {
            bodies: vec![
                BodySpec {
                    name: "upper".into(),
                    rotation: Quat::IDENTITY,
                    ..Default::default()
                },
                BodySpec {
                    name: "fore".into(),
                    parent: Some("upper".into()),
                    translation: Vec3::new(0.0, -0.3, 0.0),
                    rotation: Quat::IDENTITY,
                    joints: vec![JointSpec {
                        name: "elbow".into(),
                        kind: JointKind::Hinge,
                        anchor: Vec3::ZERO,
                        axis: Vec3::Z,
                        range: Some((0.0, 2.5)),
                    }],
                },
            ],
            motion: vec![JointMotion {
                joint: "elbow".into(),
                component: 0,
                curve: Curve {
                    keys: vec![(0.0, 0.0), (1.0, std::f32::consts::FRAC_PI_2)],
                    ..Default::default()
                },
            }],
            couplings: Vec::new(),
        }
    }

    #[test]
    fn hinge_turns_the_child_about_its_anchor() {
        let rig = arm().compile().unwrap();
        let (mut values, mut world) = (Vec::new(), Vec::new());
        rig.pose_at(1.0, &mut values, &mut world);
        // The forearm's point 0.25 m down its own -Y swings to +X (90° about Z).
        let tip = world[1].transform_point3(Vec3::new(0.0, -0.25, 0.0));
        assert!((tip - Vec3::new(0.25, -0.3, 0.0)).length() < 1e-5, "{tip}");
        // The elbow itself does not move.
        assert!(
            world[1]
                .translation
                .abs_diff_eq(Vec3::new(0.0, -0.3, 0.0).into(), 1e-6)
        );
    }

    #[test]
    fn keyframed_values_are_clamped_to_the_range() {
        let mut s = arm();
        s.motion[0].curve.keys[1].1 = 10.0;
        let rig = s.compile().unwrap();
        let mut values = Vec::new();
        rig.values_at(1.0, &mut values);
        assert_eq!(values, vec![2.5]);
    }

    #[test]
    fn couplings_follow_their_driver() {
        let mut s = arm();
        s.bodies[1].joints.push(JointSpec {
            name: "slide".into(),
            kind: JointKind::Slide,
            axis: Vec3::X,
            ..Default::default()
        });
        s.couplings.push(JointCoupling {
            joint: "slide".into(),
            driver: Some("elbow".into()),
            polynomial: [0.01, 0.5, 0.0, 0.0, 0.0],
        });
        let rig = s.compile().unwrap();
        let mut values = Vec::new();
        rig.values_at(1.0, &mut values);
        let q = std::f32::consts::FRAC_PI_2;
        assert!((values[1] - (0.01 + 0.5 * q)).abs() < 1e-6, "{values:?}");
    }

    #[test]
    fn bad_skeletons_are_rejected() {
        let mut s = arm();
        s.bodies[1].parent = Some("nope".into());
        assert!(s.compile().unwrap_err().to_string().contains("nope"));
        let mut s = arm();
        s.motion[0].joint = "knee".into();
        assert!(s.compile().unwrap_err().to_string().contains("knee"));
        let mut s = arm();
        s.bodies[1].joints[0].axis = Vec3::ZERO;
        assert!(s.compile().unwrap_err().to_string().contains("axis"));
    }
}
