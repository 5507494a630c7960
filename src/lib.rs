//! # sinew
//!
//! Real-time muscle simulation (MSXPBD) in Rust. This facade re-exports the
//! workspace crates:
//!
//! | Crate | Re-exported as | What |
//! |---|---|---|
//! | `sinew_core` | [`core`] | the solver, meshes, scenes — no Bevy |
//! | `sinew_bevy` | [`bevy`] (feature `bevy`, default) | the Bevy plug-in, panel and gizmos |
//!
//! ```
//! let scene = sinew::core::scene::builtin("P1").unwrap();
//! let mut solver = scene.instantiate(std::path::Path::new(".")).unwrap();
//! solver.step();
//! ```

pub use sinew_core as core;

#[cfg(feature = "bevy")]
pub use sinew_bevy as bevy;
