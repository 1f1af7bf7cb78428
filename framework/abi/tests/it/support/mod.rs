//! Test support: finds the plugin cdylibs cargo built beside this test binary, reads KITTI scans, and
//! captures host `tracing` events.

pub mod capture;

use std::path::{Path, PathBuf};

use skid_core::Point;

/// The workspace root (two levels above this crate).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The path of `package`'s plugin library, a dev-dependency of this crate
/// ([`skid_testkit::cdylib::dev_dependency_library`]). Installs the global event capture first, so it
/// sees every plugin event.
pub fn library(package: &str) -> PathBuf {
    capture::global();
    skid_testkit::cdylib::dev_dependency_library(package)
}

/// The folder of the test data: `SKID_DATA_DIR`, or `<workspace>/../shared/data`.
pub fn data_dir() -> PathBuf {
    std::env::var_os("SKID_DATA_DIR").map_or_else(|| workspace_root().join("../shared/data"), PathBuf::from)
}

/// Reads KITTI Velodyne scan `frame` of sequence 00 (16-byte little-endian records x, y, z, reflectance).
pub fn kitti_scan(frame: u32) -> Vec<Point> {
    let path = data_dir().join(format!("kitti_00_lidar_frames_0000_0015/velodyne/{frame:06}.bin"));
    let bytes = std::fs::read(&path).unwrap_or_else(|error| {
        panic!(
            "cannot read the KITTI scan {} ({error}); set SKID_DATA_DIR to the folder holding \
             kitti_00_lidar_frames_0000_0015 (default <workspace>/../shared/data)",
            path.display()
        )
    });
    assert_eq!(
        bytes.len() % 16,
        0,
        "{} is not a whole number of 16-byte points",
        path.display()
    );
    let float = |chunk: &[u8]| f32::from_le_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]);
    bytes
        .chunks_exact(16)
        .map(|record| {
            Point::with_intensity(
                float(&record[0..4]),
                float(&record[4..8]),
                float(&record[8..12]),
                float(&record[12..16]),
            )
        })
        .collect()
}

/// The points turned by `yaw_rad` about the sensor's vertical axis.
pub fn yawed(points: &[Point], yaw_rad: f32) -> Vec<Point> {
    let (sin, cos) = yaw_rad.sin_cos();
    points
        .iter()
        .map(|p| Point::with_intensity(cos * p.x - sin * p.y, sin * p.x + cos * p.y, p.z, p.intensity))
        .collect()
}
