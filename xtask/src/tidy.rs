//! The house rules, checked on every `.rs` file of the workspace: a `//!` module doc at the top, no file
//! over 800 lines, and no `.unwrap()` in library code (anything outside tests, benches, examples, build
//! scripts and `#[cfg(test)]` modules). Vendored third-party crates (`third_party/`) keep their upstream
//! form and are not checked.

use std::fmt;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

/// Longest file allowed, in lines.
pub const MAX_LINES: usize = 800;

/// One broken rule.
#[derive(Debug, PartialEq, Eq)]
pub struct Violation {
    pub path: PathBuf,
    pub line: usize,
    pub rule: &'static str,
}

impl fmt::Display for Violation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}: {}", self.path.display(), self.line, self.rule)
    }
}

/// Checks every Rust file under `root`, skipping `target/`, `third_party/` and hidden folders.
pub fn check(root: &Path) -> Result<Vec<Violation>> {
    let mut files = Vec::new();
    collect(root, &mut files)?;
    files.sort();
    let mut violations = Vec::new();
    for path in files {
        let text = std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
        let relative = path.strip_prefix(root).unwrap_or(&path).to_owned();
        violations.extend(check_file(&relative, &text));
    }
    Ok(violations)
}

fn collect(dir: &Path, files: &mut Vec<PathBuf>) -> Result<()> {
    for entry in std::fs::read_dir(dir).with_context(|| format!("listing {}", dir.display()))? {
        let path = entry?.path();
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        if path.is_dir() {
            if name != "target" && name != "third_party" && !name.starts_with('.') {
                collect(&path, files)?;
            }
        } else if name.ends_with(".rs") {
            files.push(path);
        }
    }
    Ok(())
}

/// True for files where `unwrap` is allowed: tests, benches, examples, build scripts and xtask itself.
fn is_test_or_tool(path: &Path) -> bool {
    path.components().any(|c| {
        matches!(
            c.as_os_str().to_str(),
            Some("tests" | "benches" | "examples" | "xtask")
        )
    }) || path
        .file_name()
        .is_some_and(|name| name == "build.rs" || name == "tests.rs")
}

/// The rules for one file's text.
pub fn check_file(path: &Path, text: &str) -> Vec<Violation> {
    let mut violations = Vec::new();
    let violation = |line, rule| Violation {
        path: path.to_owned(),
        line,
        rule,
    };
    let first = text.lines().find(|line| !line.trim().is_empty()).unwrap_or("");
    if !first.starts_with("//!") {
        violations.push(violation(
            1,
            "file must start with a `//!` doc saying what it is for",
        ));
    }
    let lines = text.lines().count();
    if lines > MAX_LINES {
        violations.push(violation(
            lines,
            "file is over 800 lines; split it by responsibility",
        ));
    }
    if !is_test_or_tool(path) {
        for (index, line) in text.lines().enumerate() {
            if line.trim_start().starts_with("#[cfg(test)]") {
                break;
            }
            let code = line.split("//").next().unwrap_or("");
            if code.contains(".unwrap()") {
                violations.push(violation(
                    index + 1,
                    "`unwrap()` in library code; return an error instead",
                ));
            }
        }
    }
    violations
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rules_catch_what_they_should() {
        let path = Path::new("framework/x/src/lib.rs");
        assert_eq!(check_file(path, "//! Doc.\nfn f() {}\n"), vec![]);
        let missing_doc = check_file(path, "fn f() {}\n");
        assert_eq!(missing_doc.len(), 1);
        let unwrap = check_file(
            path,
            "//! Doc.\nfn f() { x.unwrap(); }\n#[cfg(test)]\nmod t { fn g() { y.unwrap(); } }\n",
        );
        assert_eq!(unwrap.len(), 1);
        assert_eq!(unwrap[0].line, 2);
        assert!(
            check_file(
                Path::new("framework/x/tests/a.rs"),
                "//! Doc.\nfn f() { x.unwrap(); }\n"
            )
            .is_empty()
        );
        let long = format!("//! Doc.\n{}", "\n".repeat(MAX_LINES + 1));
        assert_eq!(check_file(path, &long).len(), 1);
    }
}
