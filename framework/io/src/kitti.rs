//! KITTI odometry files: Velodyne scans (`velodyne/NNNNNN.bin`), the sequence calibration
//! (`calib.txt`) and the frame timestamps (`times.txt`).
//!
//! * A scan is a headerless array of little-endian `f32` records `[x y z reflectance]`, 16 bytes per
//!   point, in metres in the Velodyne frame (x forward, y left, z up); reflectance is in `[0, 1]`. A file
//!   whose length is not a multiple of 16 is truncated: the error names the offset of the partial record.
//! * `calib.txt` has lines `KEY: v1 v2 ...`; `P0`..`P3` are 3x4 camera projection matrices and `Tr` (or
//!   `Tr_velo_to_cam` in the raw-data layout) is the row-major 3x4 transform taking Velodyne coordinates
//!   to camera-0 coordinates, i.e. `cam0_from_velodyne`. Its rotation is re-orthonormalised (see
//!   [`crate::geometry::nearest_rotation`]): the stored 13-digit values are orthonormal to ~1e-9 only.
//! * `times.txt` has one timestamp in seconds per line (KITTI prints them with `%e`).
//!
//! For KITTI ground-truth pose files (`poses/NN.txt`) see [`crate::trajectory::read_kitti_poses`].

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::{Isometry3, Matrix3x4};
use skid_msgs::{Point, RawPoint};

use crate::cloud::{Cloud, CloudFilter, CloudReadOptions};
use crate::error::{IoError, Location, read_file, write_file};
use crate::geometry::isometry_from_3x4;
use crate::text::{Tokens, fmt_f64, numbered_lines, read_text};

/// Bytes per point in a KITTI `.bin` scan (four little-endian `f32`).
pub const KITTI_POINT_BYTES: usize = 16;

/// Reads a KITTI Velodyne `.bin` scan. Reflectance goes to [`Point::intensity`].
pub fn read_kitti_bin(path: impl AsRef<Path>, options: CloudReadOptions) -> Result<Cloud, IoError> {
    let path = path.as_ref();
    let bytes = read_file(path)?;
    let whole = bytes.len() / KITTI_POINT_BYTES;
    let rest = bytes.len() % KITTI_POINT_BYTES;
    if rest != 0 {
        let offset = (whole * KITTI_POINT_BYTES) as u64;
        return Err(IoError::truncated(
            path,
            offset,
            format!(
                "point {whole} (file length {} is not a multiple of 16)",
                bytes.len()
            ),
            KITTI_POINT_BYTES as u64,
            rest as u64,
        ));
    }
    let mut filter = CloudFilter::new(path, options);
    let mut points = Vec::with_capacity(whole);
    for (index, record) in bytes.chunks_exact(KITTI_POINT_BYTES).enumerate() {
        let f = |k: usize| f32::from_le_bytes([record[k], record[k + 1], record[k + 2], record[k + 3]]);
        let raw = RawPoint::new(f(0), f(4), f(8), f(12), 0.0, RawPoint::UNKNOWN_RING);
        let at = Location::Offset((index * KITTI_POINT_BYTES) as u64);
        if filter.keep(index, &raw, at)? {
            points.push(raw.point());
        }
    }
    Ok(Cloud {
        points,
        report: filter.report,
    })
}

/// The bytes of a KITTI `.bin` scan holding `points` (intensity is written as reflectance).
pub fn kitti_bin_bytes(points: &[Point]) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(points.len() * KITTI_POINT_BYTES);
    for p in points {
        for v in [p.x, p.y, p.z, p.intensity] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    bytes
}

/// Writes `points` as a KITTI `.bin` scan (bit-exact: reading it back gives the same `f32`s).
pub fn write_kitti_bin(path: impl AsRef<Path>, points: &[Point]) -> Result<(), IoError> {
    write_file(path.as_ref(), &kitti_bin_bytes(points))
}

/// The contents of a KITTI `calib.txt`.
#[derive(Clone, Debug, PartialEq)]
pub struct KittiCalib {
    /// Camera projection matrices by name (`P0`..`P3`, or `P_rect_NN` in the raw-data layout).
    pub projections: BTreeMap<String, Matrix3x4<f64>>,
    /// The `Tr` line: maps a point in the Velodyne frame to the camera-0 frame.
    pub cam0_from_velodyne: Isometry3<f64>,
    /// Every line as read, by key, for entries this type does not interpret (e.g. `R0_rect`).
    pub entries: BTreeMap<String, Vec<f64>>,
}

/// Reads a KITTI `calib.txt`. The `Tr` (or `Tr_velo_to_cam`) entry is required; `P*` entries with 12
/// numbers become projection matrices. Blank lines are ignored.
pub fn read_kitti_calib(path: impl AsRef<Path>) -> Result<KittiCalib, IoError> {
    let path = path.as_ref();
    let text = read_text(path)?;
    let mut projections = BTreeMap::new();
    let mut entries = BTreeMap::new();
    let mut tr = None;
    for (line, content) in numbered_lines(&text) {
        let content = content.trim();
        if content.is_empty() || content.starts_with('#') {
            continue;
        }
        let Some((key, values)) = content.split_once(':') else {
            return Err(IoError::at_line(
                path,
                line,
                format!("expected \"KEY: numbers\", found \"{content}\""),
            ));
        };
        let key = key.trim().to_owned();
        let mut tokens = Tokens::new(path, line, values);
        let mut numbers = Vec::new();
        while let Ok(token) = tokens.next_str("") {
            let value: f64 = token.parse().map_err(|_| {
                IoError::at_line(path, line, format!("{key}: cannot parse \"{token}\" as a number"))
            })?;
            numbers.push(value);
        }
        let twelve = |numbers: &[f64]| -> Result<[f64; 12], IoError> {
            <[f64; 12]>::try_from(numbers).map_err(|_| {
                IoError::at_line(
                    path,
                    line,
                    format!("{key} needs 12 numbers, found {}", numbers.len()),
                )
            })
        };
        if key == "Tr" || key == "Tr_velo_to_cam" {
            let values = twelve(&numbers)?;
            let pose = isometry_from_3x4(&values)
                .map_err(|m| IoError::at_line(path, line, format!("{key}: {m}")))?;
            tr = Some(pose);
        } else if key.starts_with('P') && numbers.len() == 12 {
            projections.insert(key.clone(), Matrix3x4::from_row_slice(&numbers));
        }
        entries.insert(key, numbers);
    }
    let cam0_from_velodyne =
        tr.ok_or_else(|| IoError::invalid(path, "no \"Tr:\" line (Velodyne to camera 0)"))?;
    Ok(KittiCalib {
        projections,
        cam0_from_velodyne,
        entries,
    })
}

/// Reads a KITTI `times.txt`: one timestamp in seconds per line (blank lines are ignored).
pub fn read_kitti_times(path: impl AsRef<Path>) -> Result<Vec<f64>, IoError> {
    let path = path.as_ref();
    let text = read_text(path)?;
    let mut times = Vec::new();
    for (line, content) in numbered_lines(&text) {
        if content.trim().is_empty() {
            continue;
        }
        let mut tokens = Tokens::new(path, line, content);
        times.push(tokens.next_f64("time in seconds")?);
        tokens.finish()?;
    }
    Ok(times)
}

/// Writes a KITTI `times.txt` (shortest exact decimal form, one value per line).
pub fn write_kitti_times(path: impl AsRef<Path>, times_s: &[f64]) -> Result<(), IoError> {
    let mut text = String::with_capacity(times_s.len() * 14);
    for t in times_s {
        text.push_str(&fmt_f64(*t));
        text.push('\n');
    }
    write_file(path.as_ref(), text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bin_round_trip_and_truncation() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("scan.bin");
        let points = [
            Point::with_intensity(1.0, -2.5, 0.25, 0.37),
            Point::with_intensity(f32::MAX, 0.0, -0.0, 0.0),
        ];
        write_kitti_bin(&path, &points).unwrap();
        let cloud = read_kitti_bin(&path, CloudReadOptions::default()).unwrap();
        assert_eq!(cloud.points, points);
        let mut bytes = kitti_bin_bytes(&points);
        bytes.truncate(20);
        std::fs::write(&path, &bytes).unwrap();
        let err = read_kitti_bin(&path, CloudReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("byte offset 16") && err.contains("needs 16 bytes, found 4"),
            "{err}"
        );
    }
}
