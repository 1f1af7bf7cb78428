//! Writing PCD files with the fields `x y z intensity` (F4 each) in ascii, binary or binary_compressed.

use std::path::Path;

use nalgebra::Isometry3;
use skid_msgs::Point;

use super::header::{PcdData, PcdField, PcdFieldKind, PcdHeader, format_header};
use super::lzf;
use crate::error::{IoError, write_file};

/// How [`write_pcd`] stores a cloud.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PcdWriteOptions {
    /// The data storage.
    pub data: PcdData,
    /// `(width, height)` of an organised cloud; `None` writes `WIDTH = points, HEIGHT = 1`.
    pub organised: Option<(usize, usize)>,
    /// The `VIEWPOINT` (sensor pose in the cloud frame).
    pub viewpoint: Isometry3<f64>,
}

impl Default for PcdWriteOptions {
    fn default() -> Self {
        Self {
            data: PcdData::Binary,
            organised: None,
            viewpoint: Isometry3::identity(),
        }
    }
}

impl PcdWriteOptions {
    /// Unorganised cloud, identity viewpoint, in the given storage.
    pub fn new(data: PcdData) -> Self {
        Self {
            data,
            ..Self::default()
        }
    }
}

/// The bytes of a PCD file holding `points`. Fails when `organised` does not match the point count.
pub fn pcd_bytes(points: &[Point], options: &PcdWriteOptions, path: &Path) -> Result<Vec<u8>, IoError> {
    let (width, height) = options.organised.unwrap_or((points.len(), 1));
    if width.checked_mul(height) != Some(points.len()) {
        return Err(IoError::invalid(
            path,
            format!(
                "organised size {width} x {height} does not match {} points",
                points.len()
            ),
        ));
    }
    let fields = ["x", "y", "z", "intensity"]
        .map(|name| PcdField::new(name, PcdFieldKind::Float, 4))
        .to_vec();
    let header = PcdHeader {
        version: "0.7".to_owned(),
        fields,
        width,
        height,
        viewpoint: options.viewpoint,
        points: points.len(),
        data: options.data,
    };
    let mut bytes = format_header(&header).into_bytes();
    let values = |p: &Point| [p.x, p.y, p.z, p.intensity];
    match options.data {
        PcdData::Ascii => {
            for p in points {
                let line: Vec<String> = values(p).iter().map(|v| format_ascii(*v)).collect();
                bytes.extend_from_slice(line.join(" ").as_bytes());
                bytes.push(b'\n');
            }
        }
        PcdData::Binary => {
            bytes.reserve(points.len() * 16);
            for p in points {
                for v in values(p) {
                    bytes.extend_from_slice(&v.to_le_bytes());
                }
            }
        }
        PcdData::BinaryCompressed => {
            let mut columns = Vec::with_capacity(points.len() * 16);
            for k in 0..4 {
                for p in points {
                    columns.extend_from_slice(&values(p)[k].to_le_bytes());
                }
            }
            let packed = lzf::compress(&columns);
            let too_big =
                |n: usize| u32::try_from(n).map_err(|_| IoError::invalid(path, "cloud too large for PCD"));
            bytes.extend_from_slice(&too_big(packed.len())?.to_le_bytes());
            bytes.extend_from_slice(&too_big(columns.len())?.to_le_bytes());
            bytes.extend_from_slice(&packed);
        }
    }
    Ok(bytes)
}

/// Writes `points` as a PCD file.
pub fn write_pcd(path: impl AsRef<Path>, points: &[Point], options: &PcdWriteOptions) -> Result<(), IoError> {
    let path = path.as_ref();
    write_file(path, &pcd_bytes(points, options, path)?)
}

/// Shortest exact decimal form of an `f32`, with PCL's spelling of non-finite values.
fn format_ascii(v: f32) -> String {
    if v.is_nan() {
        "nan".to_owned()
    } else if v.is_infinite() {
        if v > 0.0 {
            "inf".to_owned()
        } else {
            "-inf".to_owned()
        }
    } else {
        format!("{v}")
    }
}
