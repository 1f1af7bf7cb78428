//! Reading a point cloud of any supported format, chosen by the file extension: `.bin` (KITTI),
//! `.pcd` and `.ply`. Commands that take "a point-cloud file" use this.

use std::path::Path;

use skid_msgs::Point;

use crate::{Cloud, CloudReadOptions, IoError, kitti, pcd, ply};

/// The extensions [`read_cloud`] understands.
pub const CLOUD_EXTENSIONS: [&str; 3] = ["bin", "pcd", "ply"];

/// Reads the points of a `.bin`, `.pcd` or `.ply` file; any other extension is an error naming the
/// supported ones.
pub fn read_cloud(path: impl AsRef<Path>, options: CloudReadOptions) -> Result<Cloud<Point>, IoError> {
    let path = path.as_ref();
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    match extension.as_str() {
        "bin" => kitti::read_kitti_bin(path, options),
        "pcd" => pcd::read_pcd(path, options).map(|c| Cloud {
            points: c.points,
            report: c.report,
        }),
        "ply" => ply::read_ply(path, options).map(|c| Cloud {
            points: c.points,
            report: c.report,
        }),
        _ => Err(IoError::invalid(
            path,
            format!(
                "unknown point-cloud format; expected one of .{}",
                CLOUD_EXTENSIONS.join(", .")
            ),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dispatches_on_extension_and_refuses_others() {
        let dir = tempfile::tempdir().unwrap();
        let points = vec![
            Point::with_intensity(1.0, 2.0, 3.0, 0.5),
            Point::with_intensity(-1.0, 0.0, 2.0, 0.25),
        ];
        for name in ["a.bin", "a.pcd", "a.PLY"] {
            let path = dir.path().join(name);
            match name {
                "a.bin" => kitti::write_kitti_bin(&path, &points).unwrap(),
                "a.pcd" => pcd::write_pcd(&path, &points, &pcd::PcdWriteOptions::default()).unwrap(),
                _ => ply::write_ply(&path, &points, ply::PlyFormat::BinaryLittleEndian).unwrap(),
            }
            assert_eq!(
                read_cloud(&path, CloudReadOptions::default()).unwrap().points,
                points,
                "{name}"
            );
        }
        let error = read_cloud(dir.path().join("a.xyz"), CloudReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(error.contains("a.xyz") && error.contains(".pcd"), "{error}");
    }
}
