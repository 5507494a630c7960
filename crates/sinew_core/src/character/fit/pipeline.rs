//! The whole fit in one call: segments, settling in the skin, the fitted
//! geometry pulled inside it ([`fit_anatomy`]).

use super::{AnatomyFit, FittedGeometry, PullInside, PullReport, RigMap, SkinVolume};
use crate::character::{CharacterError, SkinnedCharacter};
use crate::solver::Solver;

/// What [`fit_anatomy`] does besides the segments.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitOptions {
    /// How far the free segments (the map's `free`) may move front to back
    /// to sit in the skin ([`AnatomyFit::settle_in_skin`]). Units: m.
    /// Default: 0.15.
    pub settle_reach: f32,
    /// Pull what sticks out of the skin inside it
    /// ([`FittedGeometry::pull_inside`]); `false` leaves the bones and
    /// muscles where the segments put them. Default: `true`.
    pub pull: bool,
    /// How the muscles are pulled inside. Default: [`PullInside::default`].
    pub muscles: PullInside,
    /// How the bones are pulled inside. Default: [`PullInside::default`]
    /// with a 1 mm margin.
    pub bones: PullInside,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            settle_reach: 0.15,
            pull: true,
            muscles: PullInside::default(),
            bones: PullInside {
                margin: 0.001,
                ..PullInside::default()
            },
        }
    }
}

/// An anatomy fitted to a character ([`fit_anatomy`]).
#[derive(Clone, Debug)]
pub struct FittedAnatomy {
    /// The segments' similarities.
    pub fit: AnatomyFit,
    /// The bones and muscles where the fit puts them.
    pub geometry: FittedGeometry,
    /// The character's skin at its bind pose, as a volume.
    pub skin: SkinVolume,
    /// Each settled segment's front-to-back move (m).
    pub settled: Vec<(String, f32)>,
    /// What the pull did to the muscles and to the bones (`None`: no pull).
    pub pulled: Option<[PullReport; 2]>,
}

/// Fits the anatomy of `solver` (a scene with a skeleton, in metres, built
/// at rest) to `character` through `map`: the segments' similarities
/// ([`AnatomyFit::new`]), the free segments settled in the skin, the bones
/// and muscles moved, then pulled inside the skin if `options` says so.
/// Errors: the solver has no skeleton, or what [`AnatomyFit::new`] refuses.
pub fn fit_anatomy(
    character: &SkinnedCharacter,
    solver: &Solver,
    map: &RigMap,
    options: &FitOptions,
) -> Result<FittedAnatomy, CharacterError> {
    let rig = solver.skeleton().ok_or_else(|| CharacterError::Invalid {
        character: character.name.clone(),
        element: "anatomy".into(),
        reason: "the scene has no skeleton to fit".into(),
    })?;
    let unit = solver.settings.length_unit;
    let mut rest = Vec::new();
    rig.pose(&vec![0.0; rig.value_count()], &mut rest);
    for pose in &mut rest {
        pose.translation /= unit;
    }
    let mut fit = AnatomyFit::new(character, rig, &rest, map)?;
    let skin = SkinVolume::new(character);
    let settled = fit.settle_in_skin(solver, &skin, &map.free, options.settle_reach);
    let mut geometry = fit.geometry(solver);
    let pulled = options
        .pull
        .then(|| geometry.pull_inside(solver, &skin, &options.muscles, &options.bones));
    Ok(FittedAnatomy {
        fit,
        geometry,
        skin,
        settled,
        pulled,
    })
}
