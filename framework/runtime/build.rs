//! Records the commit the runtime is built from (`git rev-parse HEAD`, with `-dirty` when the work tree
//! has changes to tracked files) as `SKID_GIT_COMMIT` for the run summary; a build outside a git work tree
//! records none.

use std::path::Path;
use std::process::Command;

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let git = root.join(".git");
    println!("cargo:rerun-if-changed=build.rs");
    if !git.join("HEAD").is_file() {
        // Not a git work tree (a source archive): no commit to record, nothing to watch.
        return;
    }
    // Re-run when HEAD moves, the branch it names gets a new commit or the index changes.
    println!("cargo:rerun-if-changed={}", git.join("HEAD").display());
    if let Ok(head) = std::fs::read_to_string(git.join("HEAD"))
        && let Some(reference) = head.trim().strip_prefix("ref: ")
    {
        println!("cargo:rerun-if-changed={}", git.join(reference).display());
    }
    println!("cargo:rerun-if-changed={}", git.join("index").display());
    let run = |args: &[&str]| {
        Command::new("git")
            .args(args)
            .current_dir(&root)
            .output()
            .ok()
            .filter(|output| output.status.success())
            .map(|output| String::from_utf8_lossy(&output.stdout).trim().to_owned())
    };
    if let Some(commit) = run(&["rev-parse", "HEAD"]).filter(|commit| !commit.is_empty()) {
        let dirty = run(&["status", "--porcelain", "--untracked-files=no"]).is_some_and(|s| !s.is_empty());
        let suffix = if dirty { "-dirty" } else { "" };
        println!("cargo:rustc-env=SKID_GIT_COMMIT={commit}{suffix}");
    }
}
