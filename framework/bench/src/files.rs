//! Finding the data files a benchmark reads: every file with one extension under a folder of the shared
//! data, at any depth.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

/// Every file under `root` (at any depth) whose extension is `extension`, in path order.
pub fn files_with_extension(root: &Path, extension: &str) -> Result<Vec<PathBuf>> {
    let mut found = Vec::new();
    let mut folders = vec![root.to_path_buf()];
    while let Some(folder) = folders.pop() {
        for entry in std::fs::read_dir(&folder).with_context(|| format!("listing {}", folder.display()))? {
            let path = entry?.path();
            if path.is_dir() {
                folders.push(path);
            } else if path.extension().is_some_and(|ext| ext == extension) {
                found.push(path);
            }
        }
    }
    found.sort();
    Ok(found)
}
