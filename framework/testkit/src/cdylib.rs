//! Where a plugin library is for a test that loads it: a crate that names a cdylib plugin package as a
//! dev-dependency gets it built by `cargo test` into the folder its test binaries run from
//! (`<target>/<profile>/deps/`), with the test build's own profile and features. No test runs cargo.

use std::path::PathBuf;

/// The path of the shared library of `package` (a dev-dependency of the calling crate) beside the
/// running test binary. Panics, naming the fix, when it is not there.
pub fn dev_dependency_library(package: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("the test binary's path");
    let deps = exe.parent().expect("the folder of the test binary");
    let path = deps.join(format!(
        "{}{}{}",
        std::env::consts::DLL_PREFIX,
        package.replace('-', "_"),
        std::env::consts::DLL_SUFFIX
    ));
    assert!(
        path.is_file(),
        "{} is missing: {package} must be a dev-dependency of the crate whose test loads it",
        path.display()
    );
    path
}
