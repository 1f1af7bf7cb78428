//! `sensor_msgs/PointCloud2` (identical in ROS 1 and ROS 2): decoding the message without copying its
//! point data, finding which field is what from its `fields`, and turning the points into SKiD's
//! [`RawPoint`]s with per-point time offsets.
//!
//! The layout is found from the field names real drivers publish (their `PointXYZIRT`-like types):
//!
//! | role | names tried, first found wins |
//! |---|---|
//! | position | `x`, `y`, `z` (required; any numeric type, `float32` or `float64` in practice) |
//! | intensity | `intensity`, `reflectivity`, `i` |
//! | ring | `ring` (Velodyne u16, Ouster u8/u16), `line` (Livox), `channel`, `laser_id` |
//! | time | `time` (Velodyne f32 s since sweep start), `t` (Ouster u32 ns), `timestamp` (Hesai f64 absolute s), `offset_time` (Livox u32 ns), `time_offset` |
//!
//! A time field is read in seconds when its type is floating point and in nanoseconds when it is an
//! integer. A value larger than 10⁶ s is absolute (since the epoch) and becomes an offset from the
//! message's header stamp; smaller values are offsets already. Points with a non-finite coordinate (the
//! holes of organised clouds) are dropped and counted.

use skid_msgs::RawPoint;

use crate::error::DecodeError;
use crate::wire::{Header, WireReader};

mod convert;

pub use convert::raw_points;

/// `sensor_msgs/PointField` datatypes.
pub mod datatype {
    pub const INT8: u8 = 1;
    pub const UINT8: u8 = 2;
    pub const INT16: u8 = 3;
    pub const UINT16: u8 = 4;
    pub const INT32: u8 = 5;
    pub const UINT32: u8 = 6;
    pub const FLOAT32: u8 = 7;
    pub const FLOAT64: u8 = 8;
}

/// The size in bytes of a `PointField` datatype, `None` for an unknown one.
pub fn datatype_size(datatype: u8) -> Option<usize> {
    match datatype {
        datatype::INT8 | datatype::UINT8 => Some(1),
        datatype::INT16 | datatype::UINT16 => Some(2),
        datatype::INT32 | datatype::UINT32 | datatype::FLOAT32 => Some(4),
        datatype::FLOAT64 => Some(8),
        _ => None,
    }
}

fn datatype_name(datatype: u8) -> &'static str {
    match datatype {
        datatype::INT8 => "int8",
        datatype::UINT8 => "uint8",
        datatype::INT16 => "int16",
        datatype::UINT16 => "uint16",
        datatype::INT32 => "int32",
        datatype::UINT32 => "uint32",
        datatype::FLOAT32 => "float32",
        datatype::FLOAT64 => "float64",
        _ => "unknown",
    }
}

/// One `sensor_msgs/PointField`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PointField {
    pub name: String,
    pub offset: u32,
    pub datatype: u8,
    pub count: u32,
}

/// A decoded `sensor_msgs/PointCloud2` whose point data borrows from the message bytes.
#[derive(Clone, Debug)]
pub struct PointCloud2<'a> {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub fields: Vec<PointField>,
    pub is_bigendian: bool,
    pub point_step: u32,
    pub row_step: u32,
    pub data: &'a [u8],
    pub is_dense: bool,
}

impl<'a> PointCloud2<'a> {
    /// Decodes the message; the point data is checked against `height`, `row_step` and `point_step`.
    pub fn decode(reader: &mut WireReader<'a>) -> Result<Self, DecodeError> {
        let header = reader.header()?;
        let height = reader.u32()?;
        let width = reader.u32()?;
        // A PointField takes at least a length-prefixed name, an offset, a datatype and a count.
        let field_count = reader.sequence_len(13)?;
        let mut fields = Vec::with_capacity(field_count);
        for _ in 0..field_count {
            let name = reader.string()?;
            let offset = reader.u32()?;
            let datatype = reader.u8()?;
            let count = reader.u32()?;
            fields.push(PointField {
                name,
                offset,
                datatype,
                count,
            });
        }
        let is_bigendian = reader.bool()?;
        let point_step = reader.u32()?;
        let row_step = reader.u32()?;
        let data = reader.byte_sequence()?;
        let is_dense = reader.bool()?;
        let cloud = Self {
            header,
            height,
            width,
            fields,
            is_bigendian,
            point_step,
            row_step,
            data,
            is_dense,
        };
        cloud.check_sizes()?;
        Ok(cloud)
    }

    /// The number of points announced, `height · width`.
    pub fn point_count(&self) -> usize {
        self.height as usize * self.width as usize
    }

    fn check_sizes(&self) -> Result<(), DecodeError> {
        let row_bytes = u64::from(self.width) * u64::from(self.point_step);
        if u64::from(self.row_step) < row_bytes {
            return Err(DecodeError::new(format!(
                "row_step {} is smaller than width {} x point_step {}",
                self.row_step, self.width, self.point_step
            )));
        }
        let expected = u64::from(self.row_step) * u64::from(self.height);
        if expected != self.data.len() as u64 {
            return Err(DecodeError::new(format!(
                "data holds {} bytes but height {} x row_step {} is {expected}",
                self.data.len(),
                self.height,
                self.row_step
            )));
        }
        for field in &self.fields {
            let size = datatype_size(field.datatype).unwrap_or(0) as u64;
            let end = u64::from(field.offset) + size * u64::from(field.count.max(1));
            if end > u64::from(self.point_step) {
                return Err(DecodeError::new(format!(
                    "field {} ends at byte {end}, past point_step {}",
                    field.name, self.point_step
                )));
            }
        }
        Ok(())
    }
}

/// Where one role's value sits in a point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FieldSlot {
    pub offset: usize,
    pub datatype: u8,
}

impl FieldSlot {
    pub(crate) fn is_float(&self) -> bool {
        matches!(self.datatype, datatype::FLOAT32 | datatype::FLOAT64)
    }
}

/// Which field holds what, found from a cloud's `fields`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CloudLayout {
    pub x: FieldSlot,
    pub y: FieldSlot,
    pub z: FieldSlot,
    /// The intensity field and its name.
    pub intensity: Option<(String, FieldSlot)>,
    pub ring: Option<(String, FieldSlot)>,
    pub time: Option<(String, FieldSlot)>,
}

const INTENSITY_NAMES: [&str; 3] = ["intensity", "reflectivity", "i"];
const RING_NAMES: [&str; 4] = ["ring", "line", "channel", "laser_id"];
const TIME_NAMES: [&str; 5] = ["time", "t", "timestamp", "offset_time", "time_offset"];

/// Time values above this many seconds are absolute (since the epoch), not offsets within a sweep.
pub(crate) const ABSOLUTE_TIME_THRESHOLD_S: f64 = 1e6;

impl CloudLayout {
    /// Finds the roles in `fields`; a cloud without `x`, `y` and `z` is an error.
    pub fn detect(fields: &[PointField]) -> Result<Self, DecodeError> {
        let find = |name: &str| -> Option<FieldSlot> {
            fields
                .iter()
                .find(|field| field.name == name && datatype_size(field.datatype).is_some())
                .map(|field| FieldSlot {
                    offset: field.offset as usize,
                    datatype: field.datatype,
                })
        };
        let first_of = |names: &[&str]| -> Option<(String, FieldSlot)> {
            names
                .iter()
                .find_map(|name| find(name).map(|slot| ((*name).to_owned(), slot)))
        };
        let coordinate = |name: &str| {
            find(name).ok_or_else(|| {
                let present: Vec<&str> = fields.iter().map(|f| f.name.as_str()).collect();
                DecodeError::new(format!(
                    "no numeric field `{name}`; the cloud's fields are [{}]",
                    present.join(", ")
                ))
            })
        };
        Ok(Self {
            x: coordinate("x")?,
            y: coordinate("y")?,
            z: coordinate("z")?,
            intensity: first_of(&INTENSITY_NAMES),
            ring: first_of(&RING_NAMES),
            time: first_of(&TIME_NAMES),
        })
    }

    /// A one-line description for `skid bag info`: which field is time, ring and intensity.
    pub fn describe(&self) -> String {
        let role = |slot: &Option<(String, FieldSlot)>| match slot {
            Some((name, slot)) => format!("{name} ({})", datatype_name(slot.datatype)),
            None => "none".to_owned(),
        };
        let time_unit = match &self.time {
            Some((_, slot)) if slot.is_float() => ", time in s",
            Some(_) => ", time in ns",
            None => "",
        };
        format!(
            "xyz {}, intensity {}, ring {}, time {}{time_unit}",
            datatype_name(self.x.datatype),
            role(&self.intensity),
            role(&self.ring),
            role(&self.time)
        )
    }
}

/// The points of one cloud as SKiD reads them.
#[derive(Clone, Debug, Default)]
pub struct DecodedPoints {
    pub points: Vec<RawPoint>,
    /// Points dropped because a coordinate was NaN or infinite.
    pub dropped_non_finite: usize,
}
