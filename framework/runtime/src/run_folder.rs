//! Where a run writes: `<output_dir>/<name>.incomplete/` while it runs (plugins, the front-end processes'
//! stage files and the outputs all go there), renamed to `<output_dir>/<name>/` when every output is
//! written. A rerun under the same name takes the old run's place only then and whole (no stale
//! `robot2/` from an earlier, larger fleet), and the old run is kept aside as `<name>.previous/` (one
//! generation: an older `.previous` goes), with a warning; an interrupted run leaves only the
//! `.incomplete` folder with its `INCOMPLETE` marker. A non-empty folder under the run's name that is not
//! a SKiD run (it has no `config.toml`) is never replaced.

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use skid_config::ResolvedConfig;
use skid_io::staged::{Existing, StagedError, StagedFolder};

use crate::error::RuntimeError;

/// The folder inside the run's staging folder holding the configuration the front-end processes read.
pub(crate) const STAGES_FOLDER: &str = "stages";

/// The run folders this process has started and not yet committed or abandoned (a folder left by an
/// interrupted earlier run is started afresh).
static STARTED: Mutex<Option<HashSet<PathBuf>>> = Mutex::new(None);

fn started(folder: &StagedFolder) -> bool {
    STARTED
        .lock()
        .is_ok_and(|set| set.as_ref().is_some_and(|set| set.contains(folder.target())))
}

fn set_started(folder: &StagedFolder, started: bool) {
    if let Ok(mut set) = STARTED.lock() {
        let set = set.get_or_insert_with(HashSet::new);
        if started {
            set.insert(folder.target().to_path_buf());
        } else {
            set.remove(folder.target());
        }
    }
}

/// The run's folder: staged under `<name>.incomplete` until [`commit`].
pub(crate) fn run_folder(config: &ResolvedConfig) -> StagedFolder {
    StagedFolder::new(config.run.output_dir.join(&config.run.name))
}

fn staged_error(folder: &StagedFolder, error: StagedError) -> RuntimeError {
    RuntimeError::Output {
        path: folder.target().to_path_buf(),
        message: error.to_string(),
    }
}

/// Starts the run's staging folder unless it is already started; refuses to replace a folder that is
/// not a run.
pub(crate) fn begin(config: &ResolvedConfig) -> Result<StagedFolder, RuntimeError> {
    let folder = run_folder(config);
    if started(&folder) {
        return Ok(folder);
    }
    let target = folder.target();
    if target.is_dir() && !target.join("config.toml").exists() && !is_empty(target) {
        return Err(RuntimeError::Output {
            path: target.to_path_buf(),
            message: "the folder exists and is not a SKiD run (no config.toml), so the run will not replace \
                      it; choose another run.name or run.output_dir"
                .into(),
        });
    }
    folder
        .begin(Existing::Replace, &format!("run `{}`", config.run.name))
        .map_err(|e| staged_error(&folder, e))?;
    set_started(&folder, true);
    Ok(folder)
}

fn is_empty(folder: &Path) -> bool {
    std::fs::read_dir(folder).is_ok_and(|mut entries| entries.next().is_none())
}

/// Moves the finished run into place (after dropping the front-end processes' stage files).
pub(crate) fn commit(folder: &StagedFolder) -> Result<PathBuf, RuntimeError> {
    let stages = folder.path().join(STAGES_FOLDER);
    if stages.exists() {
        std::fs::remove_dir_all(&stages).map_err(|e| crate::error::output_error(&stages, e))?;
    }
    set_started(folder, false);
    keep_previous_aside(folder.target())?;
    folder.commit().map_err(|e| staged_error(folder, e))
}

/// Moves a completed run at `target` to `<target>.previous`, replacing an older one there.
fn keep_previous_aside(target: &Path) -> Result<(), RuntimeError> {
    if !target.join("config.toml").is_file() {
        return Ok(());
    }
    let mut name = target.file_name().map(|n| n.to_os_string()).unwrap_or_default();
    name.push(".previous");
    let previous = target.with_file_name(name);
    if previous.exists() {
        std::fs::remove_dir_all(&previous).map_err(|e| crate::error::output_error(&previous, e))?;
    }
    std::fs::rename(target, &previous).map_err(|e| crate::error::output_error(target, e))?;
    tracing::warn!(
        run = %target.display(),
        previous = %previous.display(),
        "a run of the same name was there: it is kept as the previous run (one generation)"
    );
    Ok(())
}

/// After a run failed or was stopped: drops the front-end processes' stage files and records `reason`
/// in the `INCOMPLETE` marker of `<name>.incomplete/`, which stays for inspection. Returns that folder
/// when the run had started one.
pub fn abandon_run(config: &ResolvedConfig, reason: &str) -> Option<PathBuf> {
    let folder = run_folder(config);
    if !started(&folder) {
        return None;
    }
    set_started(&folder, false);
    let _ = std::fs::remove_dir_all(folder.path().join(STAGES_FOLDER));
    let marker = folder.path().join(skid_io::staged::INCOMPLETE_MARKER);
    let note = std::fs::read_to_string(&marker).unwrap_or_default();
    if let Err(error) = std::fs::write(&marker, format!("{note}Reason: {reason}\n")) {
        tracing::warn!(path = %marker.display(), %error, "could not record why the run stopped");
    }
    Some(folder.path().to_path_buf())
}
