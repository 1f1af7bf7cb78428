//! The file a path-based reader is pointed at: the fuzz input written to a per-thread scratch file (in
//! `/dev/shm` when it exists, so the fuzzer's thousands of runs a second stay in memory).

use std::cell::RefCell;
use std::path::{Path, PathBuf};

thread_local! {
    static SCRATCH_FOLDER: RefCell<Option<PathBuf>> = const { RefCell::new(None) };
}

fn scratch_folder() -> PathBuf {
    SCRATCH_FOLDER.with(|cell| {
        cell.borrow_mut()
            .get_or_insert_with(|| {
                let base = Path::new("/dev/shm");
                let base = if base.is_dir() {
                    base.to_owned()
                } else {
                    std::env::temp_dir()
                };
                let thread = format!("{:?}", std::thread::current().id());
                let digits: String = thread.chars().filter(char::is_ascii_digit).collect();
                base.join(format!("skid-fuzz-{}-{digits}", std::process::id()))
            })
            .clone()
    })
}

/// Writes `data` to this thread's scratch file named `file_name` and runs `read` on its path. A scratch
/// file that cannot be written is a broken machine, not a finding: the input is skipped.
pub fn with_file<R>(file_name: &str, data: &[u8], read: impl FnOnce(&Path) -> R) -> Option<R> {
    let folder = scratch_folder();
    std::fs::create_dir_all(&folder).ok()?;
    let path = folder.join(file_name);
    std::fs::write(&path, data).ok()?;
    Some(read(&path))
}

/// Writes `files` (name relative to the folder, bytes) into this thread's scratch session folder, emptied
/// first, and runs `read` on the folder. A folder that cannot be written is skipped, as in [`with_file`].
pub fn with_folder<R>(files: &[(&str, &[u8])], read: impl FnOnce(&Path) -> R) -> Option<R> {
    let folder = scratch_folder().join("folder");
    let _ = std::fs::remove_dir_all(&folder);
    for (name, data) in files {
        let path = folder.join(name);
        std::fs::create_dir_all(path.parent()?).ok()?;
        std::fs::write(&path, data).ok()?;
    }
    Some(read(&folder))
}
