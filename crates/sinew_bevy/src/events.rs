//! What the plug-in tells the app: a muscle was built or could not be
//! (with a typed [`MuscleBuildError`]), attached, detached, an attachment
//! could not be made, a muscle's frame blew up and was put back
//! ([`MuscleFaulted`]), the settings were rejected. Each is
//! an entity event for observers (`app.add_observer(|built: On<MuscleBuilt>| …)`)
//! and a message for systems that read them in bulk ([`SinewLog`] keeps the
//! last ones for the panel).

use bevy::prelude::*;
use sinew_core::{BuildError, MeshError};
use std::collections::VecDeque;
use std::sync::Arc;

/// Why a muscle could not be built.
#[derive(Debug, thiserror::Error)]
pub enum MuscleBuildError {
    /// Its mesh file could not be loaded.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// Its Bevy mesh asset is not a closed triangle surface sinew can use.
    #[error("mesh asset of '{muscle}': {reason}")]
    MeshAsset {
        /// The muscle.
        muscle: String,
        /// What is wrong with the asset.
        reason: MeshAssetProblem,
    },
    /// An attachment names an entity that is not there (or not a bone).
    #[error("muscle '{muscle}': attachment bone {bone} does not exist or is not a SinewBone")]
    MissingBone {
        /// The muscle.
        muscle: String,
        /// The entity the attachment names.
        bone: Entity,
    },
    /// An attachment entity ([`crate::relations::AttachmentOf`]) has no
    /// [`crate::relations::AttachmentRegion`]: it does not say which
    /// vertices it holds.
    #[error("muscle '{muscle}': attachment {attachment} has no AttachmentRegion")]
    NoRegion {
        /// The muscle.
        muscle: String,
        /// The attachment entity.
        attachment: Entity,
    },
    /// The core refused the muscle (parameters, maps, mesh topology).
    #[error(transparent)]
    Build(#[from] BuildError),
}

/// What is wrong with a Bevy mesh asset given as a muscle.
#[derive(Debug, thiserror::Error)]
pub enum MeshAssetProblem {
    /// Not a triangle list.
    #[error("not a triangle list")]
    NotTriangles,
    /// No `Float32x3` positions.
    #[error("no Float32x3 positions")]
    NoPositions,
    /// Its surface is broken (degenerate, open, non-manifold).
    #[error(transparent)]
    Surface(#[from] MeshError),
}

/// A muscle entity's build finished: it now has its `MuscleState`.
#[derive(EntityEvent, Message, Clone, Copy, Debug, PartialEq, Eq)]
pub struct MuscleBuilt {
    /// The muscle.
    pub entity: Entity,
}

/// A muscle entity's build failed; the entity keeps a
/// [`crate::build::BuildFailed`] with the same error.
#[derive(EntityEvent, Message, Clone, Debug)]
pub struct MuscleBuildFailed {
    /// The muscle.
    pub entity: Entity,
    /// Why.
    pub error: Arc<MuscleBuildError>,
}

/// An attachment entity now holds its vertices of a muscle (a new one, or
/// one re-targeted to another bone).
#[derive(EntityEvent, Message, Clone, Copy, Debug, PartialEq, Eq)]
pub struct MuscleAttached {
    /// The muscle.
    pub entity: Entity,
    /// The attachment entity.
    pub attachment: Entity,
    /// The bone that holds it (`None`: the world).
    pub bone: Option<Entity>,
}

/// An attachment no longer holds a muscle: it was despawned (or its bone
/// was), or moved to another muscle. The vertices it held are free.
#[derive(EntityEvent, Message, Clone, Copy, Debug, PartialEq, Eq)]
pub struct MuscleDetached {
    /// The muscle.
    pub entity: Entity,
    /// The attachment entity (possibly despawned).
    pub attachment: Entity,
    /// The bone that held it (`None`: the world).
    pub bone: Option<Entity>,
}

/// An attachment entity could not be resolved against its muscle (a
/// vertex out of range, a bad radius, a bone that is not a
/// [`crate::components::SinewBone`]); it holds nothing until it is fixed.
#[derive(EntityEvent, Message, Clone, Debug)]
pub struct AttachmentRejected {
    /// The muscle.
    pub entity: Entity,
    /// The attachment entity.
    pub attachment: Entity,
    /// Why.
    pub error: Arc<MuscleBuildError>,
}

/// A muscle's frame blew up (a NaN or infinite state, or a particle faster
/// than [`sinew_core::SolverSettings::max_speed`]): it was put back to its
/// last good frame while the others ran on. The fault names the particle
/// and the constraint that went bad first.
#[derive(EntityEvent, Message, Clone, Debug)]
pub struct MuscleFaulted {
    /// The muscle.
    pub entity: Entity,
    /// What went wrong (the core's report).
    pub fault: Arc<sinew_core::solver::Fault>,
}

/// The settings were rejected; the simulation keeps the last valid ones.
#[derive(Event, Message, Clone, Debug)]
pub struct SettingsRejected {
    /// Why (the core's validation error, naming the setting).
    pub error: Arc<BuildError>,
}

/// The plug-in's last messages, newest last, for the panel (and anyone
/// who wants a log): at most [`SinewLog::CAPACITY`].
#[derive(Resource, Clone, Debug, Default)]
pub struct SinewLog {
    /// The lines, oldest first.
    pub lines: VecDeque<String>,
}

impl SinewLog {
    /// Lines kept.
    pub const CAPACITY: usize = 32;

    /// Adds a line, dropping the oldest past the capacity.
    pub fn push(&mut self, line: String) {
        if self.lines.len() == Self::CAPACITY {
            self.lines.pop_front();
        }
        self.lines.push_back(line);
    }
}

/// Writes the plug-in's messages of this frame into the [`SinewLog`].
pub(crate) fn log_messages(
    mut log: ResMut<SinewLog>,
    (mut built, mut failed, mut rejected): (
        MessageReader<MuscleBuilt>,
        MessageReader<MuscleBuildFailed>,
        MessageReader<SettingsRejected>,
    ),
    (mut attached, mut detached, mut refused): (
        MessageReader<MuscleAttached>,
        MessageReader<MuscleDetached>,
        MessageReader<AttachmentRejected>,
    ),
    mut faulted: MessageReader<MuscleFaulted>,
    names: Query<&Name>,
) {
    let name = |e: Entity| {
        names
            .get(e)
            .map_or_else(|_| format!("{e}"), |n| n.to_string())
    };
    for m in built.read() {
        log.push(format!("built {}", name(m.entity)));
    }
    for m in failed.read() {
        log.push(format!("build failed ({}): {}", name(m.entity), m.error));
    }
    for m in rejected.read() {
        log.push(format!("settings rejected: {}", m.error));
    }
    let holder = |bone: Option<Entity>| bone.map_or_else(|| "the world".into(), name);
    for m in attached.read() {
        log.push(format!("{} attached to {}", name(m.entity), holder(m.bone)));
    }
    for m in detached.read() {
        log.push(format!(
            "{} detached from {}",
            name(m.entity),
            holder(m.bone)
        ));
    }
    for m in faulted.read() {
        log.push(m.fault.to_string());
    }
    for m in refused.read() {
        log.push(format!(
            "attachment of {} refused: {}",
            name(m.entity),
            m.error
        ));
    }
}
