//! Where the shared test and benchmark data lives: `SKID_DATA_DIR` when set, else `shared/data` next to
//! the workspace (the workspace root is fixed at compile time from this crate's manifest directory).
//!
//! Tests that need real data call [`data_path`], which fails (rather than letting the test skip) with an
//! error naming `SKID_DATA_DIR` when the data is not there.

use std::path::{Path, PathBuf};

use crate::error::IoError;

/// The environment variable that overrides the data directory.
pub const DATA_DIR_VAR: &str = "SKID_DATA_DIR";

/// The workspace root, computed at compile time as `framework/io/../..`.
pub fn workspace_root() -> PathBuf {
    let manifest_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    match manifest_dir.parent().and_then(Path::parent) {
        Some(root) => root.to_path_buf(),
        None => manifest_dir.join("..").join(".."),
    }
}

/// The shared data directory: `$SKID_DATA_DIR` if set and non-empty, else `<workspace root>/../shared/data`.
pub fn data_dir() -> PathBuf {
    match std::env::var_os(DATA_DIR_VAR) {
        Some(dir) if !dir.is_empty() => PathBuf::from(dir),
        _ => {
            let root = workspace_root();
            match root.parent() {
                Some(parent) => parent.join("shared").join("data"),
                None => root.join("..").join("shared").join("data"),
            }
        }
    }
}

/// `relative` inside [`data_dir`], or [`IoError::DataMissing`] (whose message names `SKID_DATA_DIR`)
/// when that path does not exist.
pub fn data_path(relative: impl AsRef<Path>) -> Result<PathBuf, IoError> {
    let path = data_dir().join(relative);
    if path.exists() {
        Ok(path)
    } else {
        Err(IoError::DataMissing { path })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_next_to_the_workspace() {
        let root = workspace_root();
        assert!(root.join("Cargo.toml").exists(), "{}", root.display());
        if std::env::var_os(DATA_DIR_VAR).is_none() {
            assert!(data_dir().ends_with("shared/data"));
        }
        let err = data_path("surely/not/here.bin").unwrap_err().to_string();
        assert!(err.contains("SKID_DATA_DIR"), "{err}");
    }
}
