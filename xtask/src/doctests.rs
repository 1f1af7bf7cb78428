//! Which crates may skip their documentation tests. `doctest = false` in a crate's `[lib]` saves a rustdoc
//! pass over the crate (one to three seconds each, a minute and a half over the workspace on two cores) and
//! is only right for a crate whose documentation holds no example: this check refuses the flag on a crate
//! whose docs hold one, so that no example goes untested.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use crate::tidy::Violation;

/// Every crate under `root` (outside `target/`, `third_party/`, `fuzz/` and hidden folders) that sets
/// `doctest = false` and has a documentation example rustdoc would run: one violation per crate, at the
/// example's line.
pub fn check(root: &Path) -> Result<Vec<Violation>> {
    let mut manifests = Vec::new();
    collect_manifests(root, &mut manifests)?;
    manifests.sort();
    let mut violations = Vec::new();
    for manifest in manifests {
        let text =
            std::fs::read_to_string(&manifest).with_context(|| format!("reading {}", manifest.display()))?;
        if !text.lines().any(|line| line.trim() == "doctest = false") {
            continue;
        }
        let Some(crate_dir) = manifest.parent() else {
            continue;
        };
        let mut sources = Vec::new();
        collect_sources(&crate_dir.join("src"), &mut sources)?;
        sources.sort();
        for source in sources {
            let code =
                std::fs::read_to_string(&source).with_context(|| format!("reading {}", source.display()))?;
            if let Some(line) = first_tested_example(&code) {
                violations.push(Violation {
                    path: source.strip_prefix(root).unwrap_or(&source).to_owned(),
                    line,
                    rule: "a documentation example in a crate whose Cargo.toml sets `doctest = false`: \
                           remove the flag so the example is tested",
                });
                break;
            }
        }
    }
    Ok(violations)
}

fn collect_manifests(dir: &Path, out: &mut Vec<PathBuf>) -> Result<()> {
    for entry in std::fs::read_dir(dir).with_context(|| format!("listing {}", dir.display()))? {
        let path = entry?.path();
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        if path.is_dir() {
            if !matches!(name.as_str(), "target" | "third_party" | "fuzz") && !name.starts_with('.') {
                collect_manifests(&path, out)?;
            }
        } else if name == "Cargo.toml" {
            out.push(path);
        }
    }
    Ok(())
}

fn collect_sources(dir: &Path, out: &mut Vec<PathBuf>) -> Result<()> {
    if !dir.is_dir() {
        return Ok(());
    }
    for entry in std::fs::read_dir(dir).with_context(|| format!("listing {}", dir.display()))? {
        let path = entry?.path();
        if path.is_dir() {
            collect_sources(&path, out)?;
        } else if path.extension().is_some_and(|ext| ext == "rs") {
            out.push(path);
        }
    }
    Ok(())
}

/// The line (from 1) of the first fenced code block in `///` or `//!` docs that rustdoc compiles: a fence
/// with no info string, or only Rust attributes (`rust`, `no_run`, `should_panic`, `compile_fail`,
/// `editionNNNN`).
pub fn first_tested_example(code: &str) -> Option<usize> {
    let mut inside = false;
    for (index, line) in code.lines().enumerate() {
        let trimmed = line.trim_start();
        let Some(doc) = trimmed
            .strip_prefix("///")
            .or_else(|| trimmed.strip_prefix("//!"))
        else {
            continue;
        };
        let Some(info) = doc.trim().strip_prefix("```") else {
            continue;
        };
        if inside {
            inside = false;
            continue;
        }
        inside = true;
        if is_rust_fence(info) {
            return Some(index + 1);
        }
    }
    None
}

fn is_rust_fence(info: &str) -> bool {
    info.split(',')
        .map(str::trim)
        .filter(|token| !token.is_empty())
        .all(|token| {
            matches!(token, "rust" | "no_run" | "should_panic" | "compile_fail")
                || token.starts_with("edition")
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_examples_rustdoc_runs_and_only_those() {
        assert_eq!(
            first_tested_example("//! Doc.\n//!\n//! ```\n//! f();\n//! ```\n"),
            Some(3)
        );
        assert_eq!(
            first_tested_example("/// ```no_run\n/// f();\n/// ```\n"),
            Some(1)
        );
        assert_eq!(
            first_tested_example("/// ```rust,should_panic\n/// ```\n"),
            Some(1)
        );
        for skipped in ["```text", "```toml", "```ignore", "```sh", "```rust,ignore"] {
            let code = format!("/// {skipped}\n/// x\n/// ```\n");
            assert_eq!(first_tested_example(&code), None, "{skipped}");
        }
        // The closing fence of a skipped block is not the opening of a tested one.
        assert_eq!(
            first_tested_example("/// ```text\n/// x\n/// ```\nfn f() {}\n"),
            None
        );
        assert_eq!(first_tested_example("// ```\nfn f() {}\n"), None);
    }
}
