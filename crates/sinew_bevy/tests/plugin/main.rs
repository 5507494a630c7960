//! The plug-in's integration tests, one test binary: each Bevy test binary
//! links all of Bevy (hundreds of MB and tens of seconds per link), so the
//! test files are modules of this one. `no_allocation` stays apart: it
//! installs a counting global allocator.

mod common;

mod character;
mod character_skin;
mod drivers;
mod events;
mod headless;
mod maps;
mod pacing;
mod relations;
mod save;
mod sensors;
