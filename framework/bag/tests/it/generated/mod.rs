//! Bag fixtures written by `tests/fixtures/make_bags.py` with the independent `rosbags` and `mcap`
//! Python packages: the script runs once per test binary into a temporary folder.
//!
//! The Python interpreter is `$SKID_PYTHON` (`cargo xtask ci` creates a venv with the packages and sets
//! it), else `python3`; without the packages the tests fail with the command that installs them.

#![allow(dead_code)] // Each test binary uses a different part of it.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// The folder holding the generated fixtures (created on first use).
pub fn fixtures() -> &'static Path {
    static FOLDER: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    let (_, path) = FOLDER.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("bags");
        // Found from whichever crate includes this module: the nearest ancestor holding the script.
        let script = Path::new(env!("CARGO_MANIFEST_DIR"))
            .ancestors()
            .map(|dir| dir.join("framework/bag/tests/fixtures/make_bags.py"))
            .find(|script| script.is_file())
            .expect("framework/bag/tests/fixtures/make_bags.py in an ancestor of the crate");
        let python = std::env::var("SKID_PYTHON").unwrap_or_else(|_| "python3".to_owned());
        let output = Command::new(&python)
            .arg(&script)
            .arg(&out)
            .output()
            .unwrap_or_else(|e| panic!("cannot run {python}: {e}; set SKID_PYTHON to a Python 3 with rosbags, mcap and numpy"));
        assert!(
            output.status.success(),
            "{python} {} failed (needs `pip install rosbags==0.11.9 mcap numpy`, or SKID_PYTHON set to a venv that has them; `cargo xtask ci` makes one):\n{}",
            script.display(),
            String::from_utf8_lossy(&output.stderr)
        );
        (dir, out)
    });
    path
}

/// The expected rows (x, y, z, intensity, time offset s, ring) of cloud `index` of `kind`.
pub fn expected_rows(kind: &str, index: usize) -> Vec<[f32; 6]> {
    let bytes = std::fs::read(fixtures().join("expected").join(format!("{kind}_{index}.f32"))).unwrap();
    bytes
        .chunks_exact(24)
        .map(|row| {
            let mut values = [0f32; 6];
            for (value, raw) in values.iter_mut().zip(row.chunks_exact(4)) {
                *value = f32::from_le_bytes(raw.try_into().unwrap());
            }
            values
        })
        .collect()
}

pub const KINDS: [&str; 5] = ["velodyne", "ouster", "hesai", "livox", "plain64be"];
pub const CLOUDS: usize = 3;
pub const IMU_PER_CLOUD: usize = 20;
/// Every bag the script writes with the full message set.
pub const COMPLETE_BAGS: [&str; 8] = [
    "none.bag",
    "bz2.bag",
    "lz4.bag",
    "unindexed.bag",
    "ros2_mcap",
    "ros2_sqlite3",
    "zstd.mcap",
    "lz4.mcap",
];
