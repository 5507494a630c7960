//! What can go wrong reading, converting or writing a character.

use crate::error::MeshError;
use std::path::PathBuf;
use thiserror::Error;

/// A character could not be read, converted or written.
#[derive(Debug, Error)]
pub enum CharacterError {
    /// A file could not be read or written.
    #[error("{file}: {source}")]
    Io {
        /// Offending file.
        file: PathBuf,
        /// Underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A JSON file is broken or lacks what the converter needs.
    #[error("{file}: {element}: {reason}")]
    Json {
        /// Offending file.
        file: PathBuf,
        /// The JSON element (a joint, a key).
        element: String,
        /// What is wrong.
        reason: String,
    },
    /// The skin mesh could not be read.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// The character breaks an invariant (see `SkinnedCharacter::validate`).
    #[error("character {character}: {element}: {reason}")]
    Invalid {
        /// The character's name.
        character: String,
        /// The element (vertex, triangle, joint, clip).
        element: String,
        /// What is wrong.
        reason: String,
    },
}
