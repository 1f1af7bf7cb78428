//! The house rules hold for the whole workspace (the same check as `cargo xtask tidy`).

#![allow(clippy::unwrap_used, clippy::expect_used)] // Test helpers fail loudly by design.

#[test]
fn workspace_is_tidy() {
    let violations = xtask::tidy::check(&xtask::workspace_root()).unwrap();
    let report: Vec<String> = violations.iter().map(ToString::to_string).collect();
    assert!(report.is_empty(), "tidy violations:\n{}", report.join("\n"));
}

#[test]
fn checked_crates_have_no_import_loops() {
    for crate_dir in xtask::imports::CHECKED_CRATES {
        let graph = xtask::imports::import_graph(&xtask::workspace_root().join(crate_dir)).unwrap();
        let loops = xtask::imports::loops(&graph);
        assert!(loops.is_empty(), "{crate_dir}: import loops {loops:?}");
    }
}

#[test]
fn no_crate_that_skips_its_doc_tests_has_a_documentation_example() {
    let violations = xtask::doctests::check(&xtask::workspace_root()).unwrap();
    let report: Vec<String> = violations.iter().map(ToString::to_string).collect();
    assert!(report.is_empty(), "{}", report.join("\n"));
}
