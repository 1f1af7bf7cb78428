//! Turning a `sensor_msgs/PointCloud2`'s point bytes into SKiD's [`RawPoint`]s, one pass per role.
//!
//! A cloud's field types are only known at run time, and a per-point branch on each field's type and
//! byte order costs more than the reading itself (a 64-beam cloud has ~130 000 points). So the
//! conversion is done in passes: the positions first, then intensity, ring and time, each pass compiled
//! for its field's concrete type and the cloud's byte order, with no branch inside the loop. The passes
//! run over blocks of points small enough to stay in cache between passes, so the cloud is still read
//! from memory once. Points with a non-finite coordinate are removed at the end, and only when there are
//! any.

use skid_msgs::RawPoint;

use super::{ABSOLUTE_TIME_THRESHOLD_S, CloudLayout, DecodedPoints, FieldSlot, PointCloud2, datatype};

/// A numeric `PointField` type, read from a point's bytes in either byte order.
trait FieldValue: Copy {
    /// Reads the value at the start of `bytes`, which hold at least its size (the cloud's sizes were
    /// checked when it was decoded).
    fn read<const BIG_ENDIAN: bool>(bytes: &[u8]) -> Self;
    fn to_f64(self) -> f64;
    fn to_f32(self) -> f32;
}

macro_rules! field_value {
    ($($ty:ty),*) => {$(
        impl FieldValue for $ty {
            #[inline(always)]
            fn read<const BIG_ENDIAN: bool>(bytes: &[u8]) -> Self {
                let mut raw = [0u8; size_of::<$ty>()];
                raw.copy_from_slice(&bytes[..size_of::<$ty>()]);
                if BIG_ENDIAN {
                    <$ty>::from_be_bytes(raw)
                } else {
                    <$ty>::from_le_bytes(raw)
                }
            }

            #[inline(always)]
            fn to_f64(self) -> f64 {
                self as f64
            }

            #[inline(always)]
            fn to_f32(self) -> f32 {
                self as f32
            }
        }
    )*};
}

field_value!(i8, u8, i16, u16, i32, u32, f32, f64);

/// Runs `$body` with `$value` naming the Rust type of the `PointField` datatype `$datatype` (a slot's
/// datatype is one of the eight known ones; layout detection skips fields of any other).
macro_rules! with_value_type {
    ($datatype:expr, $value:ident => $body:expr) => {
        match $datatype {
            datatype::INT8 => {
                type $value = i8;
                $body
            }
            datatype::UINT8 => {
                type $value = u8;
                $body
            }
            datatype::INT16 => {
                type $value = i16;
                $body
            }
            datatype::UINT16 => {
                type $value = u16;
                $body
            }
            datatype::INT32 => {
                type $value = i32;
                $body
            }
            datatype::UINT32 => {
                type $value = u32;
                $body
            }
            datatype::FLOAT32 => {
                type $value = f32;
                $body
            }
            _ => {
                type $value = f64;
                $body
            }
        }
    };
}

/// Converts a cloud's points with `layout`: positions, intensity, ring and the time offset from the
/// header stamp in seconds.
pub fn raw_points(cloud: &PointCloud2<'_>, layout: &CloudLayout) -> DecodedPoints {
    if cloud.is_bigendian {
        convert::<true>(cloud, layout)
    } else {
        convert::<false>(cloud, layout)
    }
}

/// Points converted per block: the block's bytes and its points (32 KiB each at 32 bytes a point) stay
/// in the first-level cache through all the passes.
const BLOCK_POINTS: usize = 1024;

fn convert<const BIG_ENDIAN: bool>(cloud: &PointCloud2<'_>, layout: &CloudLayout) -> DecodedPoints {
    let step = cloud.point_step as usize;
    if step == 0 {
        return DecodedPoints::default();
    }
    let row_bytes = cloud.width as usize * step;
    let stamp_s = cloud.header.stamp_nanos as f64 * 1e-9;
    let mut points = Vec::with_capacity(cloud.point_count());
    let mut non_finite = 0;
    for row in cloud.data.chunks_exact(cloud.row_step.max(1) as usize) {
        for block in row[..row_bytes].chunks(step * BLOCK_POINTS) {
            let start = points.len();
            push_positions::<BIG_ENDIAN>(block, step, layout, &mut points);
            non_finite += points[start..].iter().filter(|point| !is_finite(point)).count();
            fill_roles::<BIG_ENDIAN>(block, step, layout, stamp_s, &mut points[start..]);
        }
    }
    if non_finite > 0 {
        points.retain(is_finite);
    }
    DecodedPoints {
        dropped_non_finite: non_finite,
        points,
    }
}

fn is_finite(point: &RawPoint) -> bool {
    point.x.is_finite() && point.y.is_finite() && point.z.is_finite()
}

/// The first pass: one point per point in `block`, with its position and no intensity, ring or time.
fn push_positions<const BIG_ENDIAN: bool>(
    block: &[u8],
    step: usize,
    layout: &CloudLayout,
    points: &mut Vec<RawPoint>,
) {
    let (x, y, z) = (layout.x.offset, layout.y.offset, layout.z.offset);
    let at = |point: [f32; 3]| RawPoint::new(point[0], point[1], point[2], 0.0, 0.0, RawPoint::UNKNOWN_RING);
    if layout.x.datatype == layout.y.datatype && layout.y.datatype == layout.z.datatype {
        with_value_type!(layout.x.datatype, Value => {
            points.extend(block.chunks_exact(step).map(|bytes| {
                at([
                    Value::read::<BIG_ENDIAN>(&bytes[x..]).to_f32(),
                    Value::read::<BIG_ENDIAN>(&bytes[y..]).to_f32(),
                    Value::read::<BIG_ENDIAN>(&bytes[z..]).to_f32(),
                ])
            }))
        });
    } else {
        // Coordinates of different types: rare enough to read each through a branch on its type.
        let read = |slot: &FieldSlot, bytes: &[u8]| {
            with_value_type!(slot.datatype, Value => {
                Value::read::<BIG_ENDIAN>(&bytes[slot.offset..]).to_f32()
            })
        };
        points.extend(block.chunks_exact(step).map(|bytes| {
            at([
                read(&layout.x, bytes),
                read(&layout.y, bytes),
                read(&layout.z, bytes),
            ])
        }));
    }
}

/// The later passes over one block: intensity, ring and the time offset, each when the cloud has it.
fn fill_roles<const BIG_ENDIAN: bool>(
    block: &[u8],
    step: usize,
    layout: &CloudLayout,
    stamp_s: f64,
    points: &mut [RawPoint],
) {
    if let Some((_, slot)) = &layout.intensity {
        with_value_type!(slot.datatype, Value => {
            fill::<BIG_ENDIAN, Value>(block, step, slot, points, |point, value| {
                point.intensity = value.to_f32();
            })
        });
    }
    if let Some((_, slot)) = &layout.ring {
        let highest_ring = f64::from(RawPoint::UNKNOWN_RING - 1);
        with_value_type!(slot.datatype, Value => {
            fill::<BIG_ENDIAN, Value>(block, step, slot, points, |point, value| {
                point.ring = value.to_f64().clamp(0.0, highest_ring) as u16;
            })
        });
    }
    if let Some((_, slot)) = &layout.time {
        // Integer times are nanoseconds, floating-point times seconds.
        let seconds_per_unit = if slot.is_float() { 1.0 } else { 1e-9 };
        with_value_type!(slot.datatype, Value => {
            fill::<BIG_ENDIAN, Value>(block, step, slot, points, |point, value| {
                let seconds = value.to_f64() * seconds_per_unit;
                let offset_s = if seconds.abs() > ABSOLUTE_TIME_THRESHOLD_S {
                    seconds - stamp_s
                } else {
                    seconds
                };
                point.time_offset_s = offset_s as f32;
            })
        });
    }
}

/// One later pass: `apply` given each point and its value of the field in `slot`, read as `Value`.
#[inline(always)]
fn fill<const BIG_ENDIAN: bool, Value: FieldValue>(
    block: &[u8],
    step: usize,
    slot: &FieldSlot,
    points: &mut [RawPoint],
    mut apply: impl FnMut(&mut RawPoint, Value),
) {
    let offset = slot.offset;
    for (point, bytes) in points.iter_mut().zip(block.chunks_exact(step)) {
        apply(point, Value::read::<BIG_ENDIAN>(&bytes[offset..]));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::point_cloud2::PointField;
    use crate::wire::Header;

    fn field(name: &str, offset: u32, datatype: u8) -> PointField {
        PointField {
            name: name.to_owned(),
            offset,
            datatype,
            count: 1,
        }
    }

    /// An organised big-endian cloud whose rows are longer than a block and padded past their points,
    /// with x in float64, y and z in float32, a u8 ring, u16 intensity and absolute f64 times.
    #[test]
    fn organised_padded_mixed_type_big_endian_rows_convert_point_by_point() {
        let (width, height, step, row_padding) = (BLOCK_POINTS + 37, 3usize, 32usize, 5usize);
        let row_step = width * step + row_padding;
        let stamp_nanos = 1_700_000_000_000_000_000u64;
        let mut data = vec![0xAAu8; row_step * height];
        let value = |row: usize, column: usize| (row * width + column) as f64;
        for row in 0..height {
            for column in 0..width {
                let point = &mut data[row * row_step + column * step..][..step];
                let index = value(row, column);
                let x = if column % 500 == 7 { f64::NAN } else { index * 0.5 };
                point[0..8].copy_from_slice(&x.to_be_bytes());
                point[8..12].copy_from_slice(&(-(index as f32)).to_be_bytes());
                point[12..16].copy_from_slice(&(index as f32 * 2.0).to_be_bytes());
                point[16] = (column % 128) as u8;
                point[17..19].copy_from_slice(&((index as u32 % 60_000) as u16).to_be_bytes());
                let time_s = stamp_nanos as f64 * 1e-9 + column as f64 * 1e-5;
                point[20..28].copy_from_slice(&time_s.to_be_bytes());
            }
        }
        let fields = vec![
            field("x", 0, datatype::FLOAT64),
            field("y", 8, datatype::FLOAT32),
            field("z", 12, datatype::FLOAT32),
            field("ring", 16, datatype::UINT8),
            field("intensity", 17, datatype::UINT16),
            field("timestamp", 20, datatype::FLOAT64),
        ];
        let cloud = PointCloud2 {
            header: Header {
                stamp_nanos,
                frame_id: "lidar".to_owned(),
            },
            height: height as u32,
            width: width as u32,
            fields,
            is_bigendian: true,
            point_step: step as u32,
            row_step: row_step as u32,
            data: &data,
            is_dense: false,
        };
        let layout = CloudLayout::detect(&cloud.fields).expect("layout");
        let decoded = raw_points(&cloud, &layout);

        let holes_per_row = (0..width).filter(|column| column % 500 == 7).count();
        assert_eq!(decoded.dropped_non_finite, holes_per_row * height);
        let mut expected = Vec::new();
        for row in 0..height {
            for column in (0..width).filter(|column| column % 500 != 7) {
                let index = value(row, column);
                expected.push((row, column, index));
            }
        }
        assert_eq!(decoded.points.len(), expected.len());
        for (point, (_, column, index)) in decoded.points.iter().zip(expected) {
            assert_eq!(point.x, (index * 0.5) as f32);
            assert_eq!(point.y, -(index as f32));
            assert_eq!(point.z, index as f32 * 2.0);
            assert_eq!(point.ring, (column % 128) as u16);
            assert_eq!(point.intensity, f32::from((index as u32 % 60_000) as u16));
            // Absolute times become offsets from the stamp (f64 seconds near 1.7e9 keep ~0.2 µs).
            assert!((f64::from(point.time_offset_s) - column as f64 * 1e-5).abs() < 1e-6);
        }
    }

    #[test]
    fn a_zero_point_step_or_width_gives_no_points() {
        let fields = vec![
            field("x", 0, datatype::FLOAT32),
            field("y", 4, datatype::FLOAT32),
            field("z", 8, datatype::FLOAT32),
        ];
        let cloud = PointCloud2 {
            header: Header::default(),
            height: 1,
            width: 0,
            fields,
            is_bigendian: false,
            point_step: 12,
            row_step: 0,
            data: &[],
            is_dense: true,
        };
        let layout = CloudLayout::detect(&cloud.fields).expect("layout");
        assert!(raw_points(&cloud, &layout).points.is_empty());
        let no_step = PointCloud2 {
            point_step: 0,
            ..cloud
        };
        assert!(raw_points(&no_step, &layout).points.is_empty());
    }
}
