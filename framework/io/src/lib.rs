//! SKiD file I/O: readers and writers for the point-cloud, trajectory and pose-graph files the framework
//! consumes and produces.
//!
//! | module | formats |
//! |---|---|
//! | [`kitti`] | KITTI Velodyne `.bin` scans, `calib.txt`, `times.txt` |
//! | [`pcd`] | PCL PCD v0.7 with `DATA ascii`, `binary` and `binary_compressed` (LZF) |
//! | [`ply`] | PLY `ascii`, `binary_little_endian`, `binary_big_endian` |
//! | [`trajectory`] | TUM (`stamp tx ty tz qx qy qz qw`) and KITTI (3x4 per line) trajectories |
//! | [`g2o`] | g2o 2D/3D pose graphs (`VERTEX_SE2`, `EDGE_SE2`, `VERTEX_SE3:QUAT`, `EDGE_SE3:QUAT`, `FIX`) |
//! | [`toro`] | TORO 2D/3D pose graphs (`VERTEX2`, `EDGE2`, `VERTEX3`, `EDGE3`, `EQUIV`) |
//! | [`jrl`] | JSON Robot Log collaborative SLAM problems (COSMO-Bench): Pose3 priors and between factors, per-robot ground truth and initialisation, outlier labels |
//! | [`mod@data_dir`] | where the shared test data lives (`SKID_DATA_DIR`) |
//! | [`staged`] | output folders written whole (`<name>.incomplete/`, renamed when complete) |
//!
//! Every function returns `Result<_, IoError>`; a malformed file gives an error whose `Display` names the
//! file and the line (text) or byte offset (binary), and a truncated file says how many bytes were
//! expected and found. Point readers never pass NaN/Inf points through silently: see
//! [`CloudReadOptions`].

mod any;
mod cloud;
pub mod data_dir;
mod error;
pub mod g2o;
pub mod geometry;
pub mod jrl;
pub mod kitti;
pub mod pcd;
pub mod ply;
pub mod scan_pair;
pub mod staged;
mod text;
pub mod toro;
pub mod trajectory;

pub use any::{CLOUD_EXTENSIONS, read_cloud};
pub use cloud::{Cloud, CloudReadOptions, CloudReport, NonFinitePolicy};
pub use data_dir::{DATA_DIR_VAR, data_dir, data_path};
pub use error::{IoError, Location};
