//! Everything a scene file can get wrong that the RON parser cannot see:
//! names, ranges, finiteness and the order of keys. [`Scene::load`] and
//! [`Scene::instantiate`] run it, so a bad value is refused by name before
//! anything is simulated.

use super::{AttachmentSpec, BoneShape, MeshSource, Scene};
use crate::error::SceneError;

impl Scene {
    /// Checks the scene without loading meshes: unique names, solver
    /// settings and muscle parameters in range, bone tracks, activation
    /// curves (values in `[0, 1]`) and joint motions with finite, sorted,
    /// unrepeated keys, attachment points and mesh scales finite. The error
    /// names the element (bone, muscle, key) and the reason.
    pub fn validate(&self) -> Result<(), SceneError> {
        self.check_names()?;
        self.settings.validate()?;
        let invalid = |context: String, reason: String| SceneError::Invalid { context, reason };
        for b in &self.bones {
            b.track
                .validate()
                .map_err(|reason| invalid(format!("bone '{}' track", b.name), reason))?;
            if let Some(BoneShape::Mesh { scale, .. }) = &b.shape {
                check_scale(*scale).map_err(|r| invalid(format!("bone '{}' mesh", b.name), r))?;
            }
        }
        for m in &self.muscles {
            m.params.validate(&m.name)?;
            if let Some(curve) = &m.activation {
                curve
                    .validate(0.0..=1.0)
                    .map_err(|reason| invalid(format!("muscle '{}' activation", m.name), reason))?;
            }
            if let MeshSource::File {
                scale, translation, ..
            } = &m.mesh
            {
                check_scale(*scale).map_err(|r| invalid(format!("muscle '{}' mesh", m.name), r))?;
                if !translation.is_finite() {
                    return Err(invalid(
                        format!("muscle '{}' mesh", m.name),
                        format!("translation {translation} is not finite"),
                    ));
                }
            }
            for (i, a) in m.attachments.iter().enumerate() {
                check_attachment(a).map_err(|reason| {
                    invalid(format!("muscle '{}' attachment {i}", m.name), reason)
                })?;
            }
        }
        if let Some(skeleton) = &self.skeleton {
            for (i, motion) in skeleton.motion.iter().enumerate() {
                motion
                    .curve
                    .validate(f32::MIN..=f32::MAX)
                    .map_err(|reason| {
                        invalid(
                            format!("skeleton motion {i} (joint '{}')", motion.joint),
                            reason,
                        )
                    })?;
            }
        }
        Ok(())
    }

    pub(super) fn check_names(&self) -> Result<(), SceneError> {
        let mut seen = std::collections::HashSet::new();
        for name in self
            .bones
            .iter()
            .map(|b| &b.name)
            .chain(self.muscles.iter().map(|m| &m.name))
        {
            if !seen.insert(name) {
                return Err(SceneError::DuplicateName(name.clone()));
            }
        }
        Ok(())
    }
}

fn check_scale(scale: f32) -> Result<(), String> {
    if scale.is_finite() && scale > 0.0 {
        Ok(())
    } else {
        Err(format!("scale {scale}, expected a finite value > 0"))
    }
}

fn check_attachment(a: &AttachmentSpec) -> Result<(), String> {
    if let Some(point) = a.point
        && !point.is_finite()
    {
        return Err(format!("point {point}, expected finite coordinates"));
    }
    if !(a.radius.is_finite() && a.radius >= 0.0) {
        return Err(format!("radius {}, expected a finite value ≥ 0", a.radius));
    }
    Ok(())
}
