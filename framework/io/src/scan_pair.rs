//! The real HDL-32E scan pair of the data set `lidar_scan_pair_fast_gicp` (fast_gicp's and small_gicp's
//! registration unit-test pair; its PROVENANCE.md describes the scans and the references): the two
//! scans and a reference `target_from_source`, read in one place for every test and benchmark that
//! registers them.
//!
//! The scans are organised, with (0, 0, 0) for "no return", so they are read with
//! [`CloudReadOptions::VALID_ONLY`]. A reference file holds a row-major 4x4 `T_target_source`, which maps
//! source points into the target frame: our `target_from_source`.

use std::path::Path;

use nalgebra::Isometry3;
use skid_msgs::Point;

use crate::cloud::CloudReadOptions;
use crate::data_dir::data_path;
use crate::error::IoError;
use crate::geometry::isometry_from_4x4;
use crate::text::read_text;

/// The data set's folder inside the data directory.
pub const SCAN_PAIR_FOLDER: &str = "lidar_scan_pair_fast_gicp";

/// fast_gicp's reference `T_target_source`.
pub const FAST_GICP_REFERENCE: &str = "relative_fast_gicp.txt";

/// small_gicp's reference `T_target_source`.
pub const SMALL_GICP_REFERENCE: &str = "T_target_source_small_gicp.txt";

/// The pair's valid points and fast_gicp's reference alignment.
#[derive(Clone, Debug)]
pub struct ScanPair {
    pub target: Vec<Point>,
    pub source: Vec<Point>,
    /// fast_gicp's reference, which maps source points into the target frame.
    pub target_from_source: Isometry3<f64>,
}

/// Reads the pair from the data directory (its valid points only) with fast_gicp's reference.
pub fn read_scan_pair() -> Result<ScanPair, IoError> {
    let folder = data_path(SCAN_PAIR_FOLDER)?;
    let read = |name: &str| crate::pcd::read_pcd(folder.join(name), CloudReadOptions::VALID_ONLY);
    Ok(ScanPair {
        target: read("251370668.pcd")?.points,
        source: read("251371071.pcd")?.points,
        target_from_source: read_pose_matrix(&folder.join(FAST_GICP_REFERENCE))?,
    })
}

/// Reads a reference file of the pair's folder by name (one of the `*_REFERENCE` constants or another
/// 4x4 matrix stored beside them).
pub fn read_scan_pair_reference(name: &str) -> Result<Isometry3<f64>, IoError> {
    read_pose_matrix(&data_path(SCAN_PAIR_FOLDER)?.join(name))
}

/// Reads a text file of 16 numbers, a row-major 4x4 homogeneous transform whose last row is
/// `0 0 0 1`; the rotation is re-orthonormalised as every reader here does.
pub fn read_pose_matrix(path: &Path) -> Result<Isometry3<f64>, IoError> {
    let text = read_text(path)?;
    let mut values = Vec::with_capacity(16);
    for token in text.split_whitespace() {
        let value: f64 = token
            .parse()
            .map_err(|_| IoError::at_line(path, 1, format!("cannot parse \"{token}\" as a number")))?;
        values.push(value);
    }
    if values.len() != 16 {
        return Err(IoError::at_line(
            path,
            1,
            format!("a 4x4 matrix needs 16 numbers, found {}", values.len()),
        ));
    }
    let mut matrix = [0.0; 16];
    matrix.copy_from_slice(&values);
    isometry_from_4x4(&matrix).map_err(|message| IoError::at_line(path, 1, message))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pair_reads_its_valid_points_and_a_small_forward_motion() {
        let pair = read_scan_pair().unwrap();
        assert_eq!(
            (pair.target.len(), pair.source.len()),
            (69_088 - 5_032, 69_792 - 5_107)
        );
        let forward_m = pair.target_from_source.translation.vector.x;
        assert!((0.4..0.6).contains(&forward_m), "{forward_m}");
    }

    #[test]
    fn a_matrix_file_that_lies_is_refused_naming_the_file() {
        let dir = std::env::temp_dir().join(format!("skid-pose-matrix-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let short = dir.join("short.txt");
        std::fs::write(&short, "1 0 0 0\n0 1 0 0\n0 0 1 0\n").unwrap();
        let message = read_pose_matrix(&short).unwrap_err().to_string();
        assert!(
            message.contains("short.txt") && message.contains("found 12"),
            "{message}"
        );
        let projective = dir.join("projective.txt");
        std::fs::write(&projective, "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 1 1\n").unwrap();
        let message = read_pose_matrix(&projective).unwrap_err().to_string();
        assert!(message.contains("last row"), "{message}");
        let word = dir.join("word.txt");
        std::fs::write(&word, "1 0 0 x\n").unwrap();
        assert!(read_pose_matrix(&word).unwrap_err().to_string().contains("\"x\""));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
