//! Test support: builds the plugin cdylibs with the same cargo, target folder and profile as this test
//! binary, reads KITTI scans, and captures host `tracing` events.

pub mod capture;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use skid_core::Point;

/// The workspace root (two levels above this crate).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The cdylib packages the tests load.
const PACKAGES: [&str; 4] = [
    "skid-example-cdylib",
    "skid-fixture-abi-wrong-version",
    "skid-fixture-abi-no-entry",
    "skid-fixture-abi-panics",
];

/// Where the built libraries land: this test binary's profile folder.
struct Built {
    profile_dir: PathBuf,
}

/// Builds every plugin package once per test process and returns the path of `package`'s library.
/// Installs the global event capture first, so it sees every plugin event.
pub fn library(package: &str) -> PathBuf {
    static BUILT: OnceLock<Built> = OnceLock::new();
    capture::global();
    let built = BUILT.get_or_init(build_all);
    let file = format!(
        "{}{}{}",
        std::env::consts::DLL_PREFIX,
        package.replace('-', "_"),
        std::env::consts::DLL_SUFFIX
    );
    built.profile_dir.join(file)
}

/// Runs `cargo build -p …` for every plugin package into this binary's target folder and profile.
fn build_all() -> Built {
    // This binary is `<target>/[<triple>/]<profile folder>/deps/<name>-<hash>`.
    let exe = std::env::current_exe().expect("the test binary's path");
    let profile_dir = exe
        .parent()
        .and_then(Path::parent)
        .expect("a profile folder above deps/")
        .to_owned();
    let profile = match profile_dir.file_name().and_then(|name| name.to_str()) {
        Some("debug") => "dev".to_owned(),
        Some(other) => other.to_owned(),
        None => panic!("cannot tell the profile from {}", profile_dir.display()),
    };
    let mut target_dir = profile_dir.parent().expect("a target folder").to_owned();
    let mut triple = None;
    if !target_dir.join("CACHEDIR.TAG").exists()
        && let Some(parent) = target_dir
            .parent()
            .filter(|parent| parent.join("CACHEDIR.TAG").exists())
    {
        triple = target_dir.file_name().map(|name| name.to_owned());
        target_dir = parent.to_owned();
    }
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| env!("CARGO").into());
    let mut command = Command::new(cargo);
    command
        .current_dir(workspace_root())
        .arg("build")
        .arg("--profile")
        .arg(&profile)
        .arg("--target-dir")
        .arg(&target_dir);
    if let Some(triple) = triple {
        command.arg("--target").arg(triple);
    }
    for package in PACKAGES {
        command.args(["-p", package]);
    }
    let output = command.output().expect("running cargo");
    assert!(
        output.status.success(),
        "building the plugin cdylibs failed ({:?}):\n{}",
        command,
        String::from_utf8_lossy(&output.stderr)
    );
    Built { profile_dir }
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
