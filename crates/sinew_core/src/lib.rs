//! # `sinew_core`
//!
//! The MSXPBD muscle solver (Romeo et al. 2018, as parallelised in Monteagudo's
//! 2019 thesis): muscles are closed surface meshes plus an internal "medulla",
//! simulated with XPBD. Fibres shorten with activation, the volume grows with
//! it, and muscles hold on to bones and slide over each other through
//! Attach / Sliding / Soft / Hard connections. No Bevy here: the Bevy plug-in
//! and the `sinew` CLI drive this crate.
//!
//! ## Getting started
//!
//! ```
//! use sinew_core::scene::{Scene, builtin};
//!
//! let scene = builtin("T1").expect("built-in scene");
//! let mut solver = scene.instantiate(std::path::Path::new(".")).unwrap();
//! for _ in 0..10 {
//!     solver.step();
//! }
//! assert!(solver.muscles()[0].x.iter().all(|p| p.is_finite()));
//! ```
//!
//! ## Contents
//!
//! | Module | What |
//! |---|---|
//! | [`mesh`] | OBJ/STL loading, welding, validation, volume, primitives |
//! | [`muscle`] | internal structure, fibres, masses, the muscle's own constraints |
//! | [`constraints`] | the constraint kernels (point, distance, sliding, volume) and the XPBD update |
//! | [`closest`] | target surfaces (bones, planes, muscles) and closest-point queries |
//! | [`solver`] | the frame loop, substeps, timers |
//! | [`scene`] | the RON scene format and the reference scenes P1, P2, T1, P3 |
//! | [`animation`] | activation curves and bone tracks |
//! | [`bake`] | simulations written for DCCs: OBJ sequences, `.pc2` point caches, a `.glb` of the rest meshes and the animated skeleton |
//! | [`character`] | skinned characters (MakeHuman import, linear-blend skinning, `.glb`) |
//!
//! ## FAQ
//!
//! - *Why rotation-invariant fibres by default?* Eq. 2.12–2.15 scale world-axis
//!   components; a diagonal fibre would contract differently from the same
//!   muscle aligned with an axis. See [`constraints::FiberMode`].
//! - *Units?* SI: metres, seconds, kilograms. Compliance is `1/k` in m/N.

pub mod analysis;
pub mod animation;
pub mod atomic_file;
pub mod bake;
pub mod character;
pub mod closest;
pub mod constraints;
pub mod error;
mod glb_container;
pub mod import;
mod lanes;
pub mod mesh;
pub mod muscle;
mod prefetch;
mod ron_text;
pub mod scene;
pub mod sensor;
pub mod skeleton;
pub mod solver;

pub use error::{BuildError, ImportError, MeshError, SceneError};
pub use glam;
pub use solver::{
    ColorScope, LayerTimings, RigidMomentum, Solver, SolverMethod, SolverParts, SolverSettings,
    StepTimings, SweepSchedule,
};
