//! PLY ("Polygon File Format", Stanford) point clouds: the `vertex` element with `x`, `y`, `z` and an
//! optional `intensity` (also read from `scalar_intensity` or `reflectance`; 0 when absent).
//!
//! Supported storages: `ascii 1.0`, `binary_little_endian 1.0` and `binary_big_endian 1.0` for reading
//! and writing. Properties of any scalar type are accepted (`char/int8`, `uchar/uint8`, `short/int16`,
//! `ushort/uint16`, `int/int32`, `uint/uint32`, `float/float32`, `double/float64`); other properties of
//! the vertex element and every other element (faces with `property list ...`, edges, materials, ...) are
//! skipped, list properties included, wherever they appear in the file. In ascii files the data is read
//! as a stream of tokens, so an element instance may span lines; errors name the line of the offending
//! token. In binary files errors name the byte offset, and a file that ends early says how many bytes
//! the element needed and how many were left.
//!
//! The writer stores `x y z intensity` as four `float` properties.

mod header;
mod read;
mod write;

pub use header::{PlyElement, PlyFormat, PlyHeader, PlyProperty, PlyScalar};
pub use read::{read_ply, read_ply_header};
pub use write::{ply_bytes, write_ply};

use crate::cloud::CloudReport;

/// A PLY file as read: its header, the vertices kept as points and the report of what was dropped.
#[derive(Clone, Debug, PartialEq)]
pub struct PlyCloud {
    /// The parsed header.
    pub header: PlyHeader,
    /// The vertices, in file order.
    pub points: Vec<skid_msgs::Point>,
    /// Counts of non-finite and zero points.
    pub report: CloudReport,
}
