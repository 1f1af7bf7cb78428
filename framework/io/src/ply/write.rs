//! Writing PLY files with one `vertex` element of four `float` properties `x y z intensity`.

use std::path::Path;

use skid_msgs::Point;

use super::header::{PlyElement, PlyFormat, PlyHeader, PlyProperty, PlyScalar, format_header};
use crate::error::{IoError, write_file};

/// The bytes of a PLY file holding `points` in the given storage.
pub fn ply_bytes(points: &[Point], format: PlyFormat) -> Vec<u8> {
    let properties = ["x", "y", "z", "intensity"]
        .map(|name| PlyProperty::Scalar {
            name: name.to_owned(),
            ty: PlyScalar::F32,
        })
        .to_vec();
    let header = PlyHeader {
        format,
        elements: vec![PlyElement {
            name: "vertex".to_owned(),
            count: points.len(),
            properties,
        }],
        comments: vec!["written by skid-io".to_owned()],
    };
    let mut bytes = format_header(&header).into_bytes();
    for p in points {
        let values = [p.x, p.y, p.z, p.intensity];
        match format {
            PlyFormat::Ascii => {
                let line: Vec<String> = values.iter().map(|v| format!("{v}")).collect();
                bytes.extend_from_slice(line.join(" ").as_bytes());
                bytes.push(b'\n');
            }
            PlyFormat::BinaryLittleEndian => values
                .iter()
                .for_each(|v| bytes.extend_from_slice(&v.to_le_bytes())),
            PlyFormat::BinaryBigEndian => values
                .iter()
                .for_each(|v| bytes.extend_from_slice(&v.to_be_bytes())),
        }
    }
    bytes
}

/// Writes `points` as a PLY file. Non-finite values are written as they are (`NaN`, `inf` in ascii).
pub fn write_ply(path: impl AsRef<Path>, points: &[Point], format: PlyFormat) -> Result<(), IoError> {
    write_file(path.as_ref(), &ply_bytes(points, format))
}
