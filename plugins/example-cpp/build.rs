//! Builds `cpp/point_to_plane_icp.cpp` into a shared library with the system C++ compiler (found by
//! the `cc` crate, so `CXX` and `CXXFLAGS` apply) against skid-abi's generated C header, and tells the
//! crate where it is. No CMake: a C++ plugin needs only a compiler and `skid_plugin.h`.

use std::path::PathBuf;
use std::process::Command;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR")?);
    let out = PathBuf::from(std::env::var("OUT_DIR")?);
    let include = manifest.join("../../framework/abi/include");
    let sources = manifest.join("cpp");
    let library = out.join(format!(
        "{}skid_point_to_plane_icp{}",
        std::env::consts::DLL_PREFIX,
        std::env::consts::DLL_SUFFIX
    ));
    let compiler = cc::Build::new().cpp(true).get_compiler();
    let mut command: Command = compiler.to_command();
    command
        .args([
            "-std=c++17",
            "-O2",
            "-fPIC",
            "-shared",
            "-fvisibility=hidden",
            "-Wall",
            "-Wextra",
        ])
        .arg("-I")
        .arg(&include)
        .arg("-I")
        .arg(&sources)
        .arg("-o")
        .arg(&library)
        .arg(sources.join("point_to_plane_icp.cpp"));
    let status = command
        .status()
        .unwrap_or_else(|error| panic!("running the C++ compiler {command:?}: {error}"));
    assert!(
        status.success(),
        "the C++ compiler failed ({status}): {command:?}"
    );
    for watched in [
        "cpp/point_to_plane_icp.cpp",
        "cpp/kdtree.hpp",
        "cpp/linalg.hpp",
        "../../framework/abi/include/skid_plugin.h",
    ] {
        println!("cargo:rerun-if-changed={watched}");
    }
    println!("cargo:rustc-env=SKID_EXAMPLE_CPP_LIBRARY={}", library.display());
    Ok(())
}
