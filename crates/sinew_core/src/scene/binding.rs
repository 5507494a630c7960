//! A skin binding in a scene file, resolved by bone name.

use crate::error::SceneError;
use crate::muscle::SkinBindingDesc;
use serde::{Deserialize, Serialize};

/// A skin binding in a scene: per surface vertex, up to four bones (named
/// through `bones`) and weights, as a glTF skin's `JOINTS_0`/`WEIGHTS_0`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SkinBindingSpec {
    /// The bones the influences index, by name.
    pub bones: Vec<String>,
    /// Per surface vertex: `(index into bones, weight)` pairs, at most
    /// four, weights ≥ 0 summing to 1; an empty list leaves it unbound.
    pub influences: Vec<Vec<(u16, f32)>>,
    /// Per surface vertex, the binding's strength (its compliance is
    /// divided by it; 0 unbinds). Empty: 1 everywhere. Unitless, ≥ 0.
    pub strength: Vec<f32>,
}

impl SkinBindingSpec {
    /// The binding with its bones resolved by `bone_index(k, name)` (the
    /// `k`-th named bone); errors name the muscle, the vertex and the bone.
    pub fn resolve(
        &self,
        muscle: &str,
        bone_index: impl Fn(usize, &str) -> Result<usize, SceneError>,
    ) -> Result<SkinBindingDesc, SceneError> {
        let bones = self
            .bones
            .iter()
            .enumerate()
            .map(|(k, b)| bone_index(k, b))
            .collect::<Result<Vec<_>, _>>()?;
        let influences = self
            .influences
            .iter()
            .enumerate()
            .map(|(v, list)| {
                list.iter()
                    .map(|&(k, w)| {
                        let bone = bones.get(k as usize).ok_or_else(|| SceneError::Invalid {
                            context: format!("muscle '{muscle}' binding vertex {v}"),
                            reason: format!("bone {k} of {} named", bones.len()),
                        })?;
                        Ok((*bone, w))
                    })
                    .collect::<Result<Vec<_>, SceneError>>()
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(SkinBindingDesc {
            influences,
            strength: self.strength.clone(),
            holds_shape: false,
        })
    }
}
