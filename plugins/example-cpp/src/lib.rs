//! The C++17 example plugin `point_to_plane_icp` (in `cpp/`), built by this crate's build script into a
//! shared library that `skid --plugin-lib` loads through the C ABI. The crate itself only says where the
//! library is, for tests and benchmarks.

/// The path of the built plugin library.
pub const LIBRARY_PATH: &str = env!("SKID_EXAMPLE_CPP_LIBRARY");
