//! Output folders written all at once: a command writes into `<target>.incomplete/` and renames it to
//! `<target>/` only when everything is written, so a folder under the target's name is always complete
//! and an interrupted command leaves a folder whose name (and `INCOMPLETE` marker file) says so. A
//! previous folder under the target's name stays untouched until the new one is complete, and is then
//! replaced in two renames.

use std::io;
use std::path::{Path, PathBuf};

/// The marker file inside a folder that is still being written (or whose writer was interrupted).
pub const INCOMPLETE_MARKER: &str = "INCOMPLETE";

/// What to do with an existing folder under the target's name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Existing {
    /// Replace it when the new folder is complete.
    Replace,
    /// Refuse to start when it exists and is not empty.
    Refuse,
}

/// Why a staged folder could not be started or completed.
#[derive(Debug, thiserror::Error)]
pub enum StagedError {
    #[error("{} already exists and is not empty; choose another folder or pass --overwrite", path.display())]
    Exists { path: PathBuf },
    #[error("{} exists but is not a folder", path.display())]
    NotAFolder { path: PathBuf },
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
}

fn io_error(path: &Path) -> impl FnOnce(io::Error) -> StagedError + '_ {
    move |source| StagedError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// An output folder being written; [`StagedFolder::commit`] moves it into place.
#[derive(Clone, Debug)]
pub struct StagedFolder {
    target: PathBuf,
    staging: PathBuf,
}

/// `<target>.incomplete`, beside the target.
fn staging_path(target: &Path) -> PathBuf {
    let mut name = target.file_name().unwrap_or(target.as_os_str()).to_os_string();
    name.push(".incomplete");
    target.with_file_name(name)
}

fn is_empty_folder(path: &Path) -> Result<bool, StagedError> {
    Ok(std::fs::read_dir(path).map_err(io_error(path))?.next().is_none())
}

impl StagedFolder {
    /// Names the folders for `target` without touching the disk.
    pub fn new(target: impl Into<PathBuf>) -> Self {
        let target = target.into();
        let staging = staging_path(&target);
        Self { target, staging }
    }

    /// Starts a fresh staging folder (removing one an interrupted earlier writer left) with its
    /// `INCOMPLETE` marker saying `what` is being written. Under [`Existing::Refuse`] a non-empty
    /// target stops here, before anything is written.
    pub fn begin(&self, existing: Existing, what: &str) -> Result<(), StagedError> {
        if self.target.exists() {
            if !self.target.is_dir() {
                return Err(StagedError::NotAFolder {
                    path: self.target.clone(),
                });
            }
            if existing == Existing::Refuse && !is_empty_folder(&self.target)? {
                return Err(StagedError::Exists {
                    path: self.target.clone(),
                });
            }
        }
        if self.staging.exists() {
            std::fs::remove_dir_all(&self.staging).map_err(io_error(&self.staging))?;
        }
        std::fs::create_dir_all(&self.staging).map_err(io_error(&self.staging))?;
        let marker = self.staging.join(INCOMPLETE_MARKER);
        let note = format!(
            "{what} did not finish (process {} was stopped or failed before the end).\n\
             A complete result is renamed to {} when it finishes.\n",
            std::process::id(),
            self.target.display()
        );
        std::fs::write(&marker, note).map_err(io_error(&marker))
    }

    /// The folder to write into until [`StagedFolder::commit`].
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// The folder's name once complete.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Removes the marker and moves the folder to the target's name, replacing an existing folder
    /// there; returns the target.
    pub fn commit(&self) -> Result<PathBuf, StagedError> {
        let marker = self.staging.join(INCOMPLETE_MARKER);
        std::fs::remove_file(&marker).map_err(io_error(&marker))?;
        if self.target.exists() {
            // Move the old folder aside first, so the target's name never holds a mix of both.
            let mut old_name = self.target.file_name().unwrap_or_default().to_os_string();
            old_name.push(format!(".replaced-{}", std::process::id()));
            let old = self.target.with_file_name(old_name);
            std::fs::rename(&self.target, &old).map_err(io_error(&self.target))?;
            std::fs::rename(&self.staging, &self.target).map_err(io_error(&self.staging))?;
            std::fs::remove_dir_all(&old).map_err(io_error(&old))?;
        } else {
            std::fs::rename(&self.staging, &self.target).map_err(io_error(&self.staging))?;
        }
        Ok(self.target.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_committed_folder_replaces_the_old_one_whole() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("run");
        std::fs::create_dir_all(target.join("robot2")).unwrap();
        std::fs::write(target.join("metrics.json"), "old").unwrap();
        let staged = StagedFolder::new(&target);
        staged.begin(Existing::Replace, "the run").unwrap();
        std::fs::write(staged.path().join("metrics.json"), "new").unwrap();
        // Until the commit the old folder is intact.
        assert_eq!(
            std::fs::read_to_string(target.join("metrics.json")).unwrap(),
            "old"
        );
        assert_eq!(staged.commit().unwrap(), target);
        assert_eq!(
            std::fs::read_to_string(target.join("metrics.json")).unwrap(),
            "new"
        );
        assert!(
            !target.join("robot2").exists(),
            "stale files of the old folder survived"
        );
        assert!(!target.join(INCOMPLETE_MARKER).exists());
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("run")]);
    }

    #[test]
    fn an_uncommitted_folder_is_marked_and_refusal_keeps_a_non_empty_target() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("export");
        let staged = StagedFolder::new(&target);
        staged.begin(Existing::Refuse, "the export").unwrap();
        assert!(staged.path().ends_with("export.incomplete"));
        let note = std::fs::read_to_string(staged.path().join(INCOMPLETE_MARKER)).unwrap();
        assert!(note.contains("did not finish"), "{note}");
        std::fs::create_dir_all(&target).unwrap();
        std::fs::write(target.join("keep.txt"), "mine").unwrap();
        let error = StagedFolder::new(&target)
            .begin(Existing::Refuse, "the export")
            .unwrap_err();
        assert!(error.to_string().contains("--overwrite"), "{error}");
        assert_eq!(std::fs::read_to_string(target.join("keep.txt")).unwrap(), "mine");
    }
}
