//! The point-cloud file harnesses: PCD (ascii, binary, binary_compressed), PLY (ascii and both binary
//! byte orders) and KITTI `.bin`, each read twice: keeping every point, and dropping non-finite ones.

use skid_io::pcd::read_pcd;
use skid_io::ply::read_ply;
use skid_io::{CloudReadOptions, CloudReport, kitti::read_kitti_bin};
use skid_msgs::Point;

use crate::scratch::with_file;

fn finite(point: &Point) -> bool {
    point.x.is_finite() && point.y.is_finite() && point.z.is_finite()
}

/// What every reader promises about what it returns.
fn check(points: &[Point], report: &CloudReport, options: CloudReadOptions) {
    assert_eq!(
        points.len(),
        report.kept(),
        "points returned differ from the report's count"
    );
    assert!(report.non_finite >= report.dropped_non_finite);
    if options == CloudReadOptions::VALID_ONLY {
        assert!(points.iter().all(finite), "a non-finite point passed VALID_ONLY");
    }
}

const OPTIONS: [CloudReadOptions; 2] = [CloudReadOptions::KEEP_ALL, CloudReadOptions::VALID_ONLY];

pub fn pcd(data: &[u8]) {
    for options in OPTIONS {
        if let Some(Ok(cloud)) = with_file("fuzz.pcd", data, |path| read_pcd(path, options)) {
            check(&cloud.points, &cloud.report, options);
        }
    }
}

pub fn ply(data: &[u8]) {
    for options in OPTIONS {
        if let Some(Ok(cloud)) = with_file("fuzz.ply", data, |path| read_ply(path, options)) {
            check(&cloud.points, &cloud.report, options);
        }
    }
}

pub fn kitti_bin(data: &[u8]) {
    for options in OPTIONS {
        if let Some(Ok(cloud)) = with_file("fuzz.bin", data, |path| read_kitti_bin(path, options)) {
            check(&cloud.points, &cloud.report, options);
        }
    }
}
