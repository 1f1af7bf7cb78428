//! Library half of xtask, so the tidy rules also run as a test (`cargo test -p xtask`).

pub mod bench;
pub mod doctests;
pub mod header;
pub mod imports;
pub mod python;
pub mod results;
pub mod tidy;

use std::path::PathBuf;

/// The workspace root (the folder above `xtask/`).
pub fn workspace_root() -> PathBuf {
    let manifest = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    manifest.parent().map(PathBuf::from).unwrap_or(manifest)
}
