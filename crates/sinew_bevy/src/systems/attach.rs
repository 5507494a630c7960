//! Attachments at run time: each muscle's core attachments follow its
//! attachment entities ([`crate::relations`]) — new ones attach the muscle
//! where it is, despawned ones detach it, re-targeted ones are held by
//! their new bone from where they are.

use super::StepContext;
use crate::components::*;
use crate::events::{AttachmentRejected, MuscleAttached, MuscleBuildError, MuscleDetached};
use crate::relations::{
    AttachedTo, AttachmentRegion, Attachments, HeldVertices, PlacedAttachments,
};
use crate::settings::SinewTimings;
use bevy::prelude::*;
use sinew_core::glam::Affine3A;
use sinew_core::muscle::AttachmentDesc;
use sinew_core::solver::Stopwatch;
use std::sync::Arc;

/// An attachment entity as [`sync_attachments`] reads it.
type AttachmentItem = (
    Option<&'static AttachedTo>,
    Option<&'static AttachmentRegion>,
    &'static mut HeldVertices,
);

/// Brings every muscle's core attachments in line with its attachment
/// entities: resolves new, edited and re-targeted ones against the muscle
/// as it is at the start of the step (the bones at their start-of-step
/// pose), and rebuilds the muscle's attachments when the set changed,
/// keeping each one's place in the list (so that an unchanged set gives
/// the same bits). Sends [`MuscleAttached`], [`MuscleDetached`] and
/// [`AttachmentRejected`].
pub(crate) fn sync_attachments(
    ctx: Res<StepContext>,
    mut timings: ResMut<SinewTimings>,
    mut muscles: Query<(Entity, &mut MuscleState, Option<&Attachments>)>,
    mut attachments: Query<AttachmentItem>,
    bones: Query<&BonePose, With<SinewBone>>,
    mut commands: Commands,
    mut now: Local<Vec<(Entity, Option<Entity>)>>,
) {
    let mut clock = Stopwatch::new(ctx.settings.timers);
    for (muscle, mut state, list) in &mut muscles {
        let state = &mut *state;
        let list = list.map_or(&[][..], |l| l.collection().as_slice());
        now.clear();
        let mut changed = false;
        for (index, &entity) in list.iter().enumerate() {
            let Ok((to, region, mut held)) = attachments.get_mut(entity) else {
                continue;
            };
            let bone = to.map(|t| t.0);
            if !held.is_resolved_for(region, bone) {
                changed = true;
                let pose = match bone.map(|b| bones.get(b)) {
                    None => Ok(Affine3A::IDENTITY),
                    Some(Ok(pose)) => Ok(pose.previous),
                    Some(Err(_)) => Err(MuscleBuildError::MissingBone {
                        muscle: state.muscle.name.clone(),
                        bone: bone.expect("a bone"),
                    }),
                };
                let resolved = pose.and_then(|pose| match region {
                    Some(region) => Ok(resolve(state, region, pose, index)?),
                    None => Err(MuscleBuildError::NoRegion {
                        muscle: state.muscle.name.clone(),
                        attachment: entity,
                    }),
                });
                held.resolved_for = Some((region.cloned(), bone));
                match resolved {
                    Ok(resolved) => {
                        held.attachments = resolved;
                        let attached = MuscleAttached {
                            entity: muscle,
                            attachment: entity,
                            bone,
                        };
                        commands.write_message(attached);
                        commands.trigger(attached);
                    }
                    Err(error) => {
                        warn!(
                            "sinew: an attachment of '{}' was refused: {error}",
                            state.muscle.name
                        );
                        held.attachments.clear();
                        let refused = AttachmentRejected {
                            entity: muscle,
                            attachment: entity,
                            error: Arc::new(error),
                        };
                        commands.write_message(refused.clone());
                        commands.trigger(refused);
                    }
                }
            }
            now.push((entity, bone));
        }
        if !changed && *now == state.attached {
            continue;
        }
        for &(gone, bone) in &state.attached {
            if !now.iter().any(|&(e, _)| e == gone) {
                let detached = MuscleDetached {
                    entity: muscle,
                    attachment: gone,
                    bone,
                };
                commands.write_message(detached);
                commands.trigger(detached);
            }
        }
        // Every held vertex, in its place in the muscle's list, with the
        // core bone index of its attachment.
        let mut all: PlacedAttachments = Vec::new();
        for (k, &(entity, bone)) in now.iter().enumerate() {
            if let Ok((_, _, held)) = attachments.get(entity) {
                all.extend(held.attachments.iter().map(|&(order, mut a)| {
                    a.bone = bone.map(|_| k);
                    (order, a)
                }));
            }
        }
        all.sort_by_key(|&(order, _)| order);
        state
            .muscle
            .set_attachments(all.into_iter().map(|(_, a)| a));
        state.attached.clone_from(&now);
        state.bone_poses.clear();
    }
    clock.lap(&mut timings.step.read_inputs);
}

/// The core attachments `region` makes on `state`'s muscle as it is now,
/// held by a bone at `pose`, each with a new place in the muscle's list.
fn resolve(
    state: &mut MuscleState,
    region: &AttachmentRegion,
    pose: Affine3A,
    index: usize,
) -> Result<PlacedAttachments, sinew_core::BuildError> {
    let m = &state.muscle;
    let vertices = match region {
        AttachmentRegion::Vertices(vertices) => {
            let n = m.surface_count;
            if let Some(&vertex) = vertices.iter().find(|&&v| v as usize >= n) {
                return Err(sinew_core::BuildError::AttachmentVertexOutOfRange {
                    muscle: m.name.clone(),
                    attachment: index,
                    vertex,
                    count: n,
                });
            }
            vertices.clone()
        }
        AttachmentRegion::Near { point, radius } => AttachmentDesc {
            bone: None,
            vertex: None,
            point: Some(*point),
            radius: *radius,
        }
        .held_vertices(m.surface_positions(), &m.name, index)?,
    };
    let made = vertices
        .into_iter()
        .map(|v| {
            let order = state.next_attachment;
            state.next_attachment += 1;
            // The bone index is set when the muscle's list is rebuilt.
            (order, state.muscle.attachment_at(Some(0), v, pose))
        })
        .collect();
    Ok(made)
}
