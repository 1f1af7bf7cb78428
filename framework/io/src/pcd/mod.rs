//! PCL's PCD point-cloud files (format v0.7; v0.6 files without `VERSION`/`VIEWPOINT` read too).
//!
//! The header lists the fields of each point (`FIELDS`, with `SIZE` bytes, `TYPE` F/U/I and `COUNT`
//! elements each), the cloud shape (`WIDTH`, `HEIGHT`; `POINTS` must equal their product), the sensor
//! `VIEWPOINT` (`tx ty tz qw qx qy qz`) and the data storage (`DATA ascii|binary|binary_compressed`).
//! `binary` stores point records one after the other; `binary_compressed` stores two little-endian `u32`
//! (compressed size, uncompressed size) and then an LZF block (see [`lzf`]) that expands to the fields
//! **column by column**: all points' `x`, then all `y`, and so on, in `FIELDS` order.
//!
//! The readers accept fields of any type and size (F4, F8, U1..U8, I1..I8) and extract:
//! `x`, `y`, `z` (required), `intensity` (or `reflectance`; 0 when absent), and for
//! [`read_pcd_raw`] the per-point `time` (seconds, as the Velodyne ROS driver writes it) or `t`
//! (nanoseconds, as Ouster writes it) and `ring`. Every other field (normals, curvature, `_` padding,
//! histograms with `COUNT > 1`, ...) is skipped. Organised clouds with NaN or `(0, 0, 0)` "no return"
//! points are handled through [`crate::CloudReadOptions`], and the counts are in the
//! returned [`crate::CloudReport`].
//!
//! The writer stores `x y z intensity` as four F4 fields in any of the three storages.

mod header;
pub mod lzf;
mod read;
mod write;

pub use header::{PcdData, PcdField, PcdFieldKind, PcdHeader};
pub use read::{read_pcd, read_pcd_header, read_pcd_raw};
pub use write::{PcdWriteOptions, pcd_bytes, write_pcd};

use crate::cloud::CloudReport;

/// A PCD file as read: its header, the points kept and the report of what was dropped.
#[derive(Clone, Debug, PartialEq)]
pub struct PcdCloud<P> {
    /// The parsed header (`width`/`height` describe the file, also when points were dropped).
    pub header: PcdHeader,
    /// The points, in file order (row-major for an organised cloud).
    pub points: Vec<P>,
    /// Counts of non-finite and zero points.
    pub report: CloudReport,
}
