//! The house rules hold for the whole workspace (the same check as `cargo xtask tidy`).

#![allow(clippy::unwrap_used, clippy::expect_used)] // Test helpers fail loudly by design.

#[test]
fn workspace_is_tidy() {
    let violations = xtask::tidy::check(&xtask::workspace_root()).unwrap();
    let report: Vec<String> = violations.iter().map(ToString::to_string).collect();
    assert!(report.is_empty(), "tidy violations:\n{}", report.join("\n"));
}

#[test]
fn no_crate_has_import_loops() {
    let root = xtask::workspace_root();
    let crates = xtask::imports::workspace_crates(&root).unwrap();
    assert!(crates.len() >= 30, "{crates:?}");
    for crate_dir in crates {
        let loops = xtask::imports::crate_loops(&crate_dir).unwrap();
        assert!(
            loops.is_empty(),
            "{}: import loops {loops:?}",
            crate_dir.display()
        );
    }
}

#[test]
fn no_crate_that_skips_its_doc_tests_has_a_documentation_example() {
    let violations = xtask::doctests::check(&xtask::workspace_root()).unwrap();
    let report: Vec<String> = violations.iter().map(ToString::to_string).collect();
    assert!(report.is_empty(), "{}", report.join("\n"));
}
