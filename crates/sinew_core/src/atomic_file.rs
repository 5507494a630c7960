//! Files written whole or not at all: the bytes go to a temporary file
//! beside the target (`<name>.partial`), are flushed to disk, and the
//! temporary file is renamed over the target — an interrupted write leaves
//! the old file (or none) and a `.partial`, never a truncated file that
//! looks complete.

use std::io::Write;
use std::path::{Path, PathBuf};

/// Suffix of a file being written.
pub const PARTIAL_SUFFIX: &str = ".partial";

/// The temporary file `path` is written through.
pub fn partial_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(PARTIAL_SUFFIX);
    path.with_file_name(name)
}

/// Writes `bytes` to `path` atomically (see the module docs). The error is
/// the I/O error of the step that failed; the temporary file is removed.
pub fn write(path: &Path, bytes: impl AsRef<[u8]>) -> std::io::Result<()> {
    let partial = partial_path(path);
    let written = (|| {
        let mut file = std::fs::File::create(&partial)?;
        file.write_all(bytes.as_ref())?;
        file.sync_all()?;
        std::fs::rename(&partial, path)
    })();
    if written.is_err() {
        std::fs::remove_file(&partial).ok();
    }
    written
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replaces_whole_and_leaves_no_partial() {
        let dir = std::env::temp_dir().join(format!("sinew_atomic_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.txt");
        write(&path, "first").unwrap();
        write(&path, "second").unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "second");
        assert!(!partial_path(&path).exists());
        assert_eq!(partial_path(&path), dir.join("a.txt.partial"));
        let missing = dir.join("no_such_folder").join("b.txt");
        assert!(write(&missing, "x").is_err());
        std::fs::remove_dir_all(&dir).ok();
    }
}
