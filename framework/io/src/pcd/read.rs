//! Reading the data section of a PCD file in any of its three storages, extracting x, y, z and the
//! optional intensity, per-point time and ring fields from fields of any supported type.

use std::path::Path;

use skid_msgs::{Point, RawPoint};

use super::header::{PcdData, PcdFieldKind, PcdHeader, parse_header};
use super::{PcdCloud, lzf};
use crate::cloud::{CloudFilter, CloudReadOptions};
use crate::error::{IoError, Location, read_file};
use crate::text::Tokens;

/// Where one extracted field sits in a point and how to decode it.
#[derive(Clone, Copy, Debug)]
struct Slot {
    /// Byte offset of the field inside a binary point record.
    offset: usize,
    /// Index of the field's first token on an ascii line.
    token: usize,
    kind: PcdFieldKind,
    size: usize,
    /// Bytes of the whole field (size x count), the stride of its column in compressed data.
    bytes: usize,
    /// Factor applied to the decoded value (nanoseconds to seconds for Ouster's `t`).
    scale: f64,
}

/// The slots of the fields the reader extracts.
struct Layout {
    xyz: [Slot; 3],
    intensity: Option<Slot>,
    time: Option<Slot>,
    ring: Option<Slot>,
}

impl Layout {
    fn new(path: &Path, header: &PcdHeader, fields_line: usize) -> Result<Self, IoError> {
        let offsets = header.field_offsets();
        let mut tokens = Vec::with_capacity(header.fields.len());
        let mut token = 0;
        for field in &header.fields {
            tokens.push(token);
            token += field.count;
        }
        let slot = |names: &[&str], scale: f64| {
            names.iter().find_map(|name| header.field_index(name)).map(|i| {
                let field = &header.fields[i];
                Slot {
                    offset: offsets[i],
                    token: tokens[i],
                    kind: field.kind,
                    size: field.size,
                    bytes: field.bytes(),
                    scale,
                }
            })
        };
        let mut xyz = Vec::with_capacity(3);
        for name in ["x", "y", "z"] {
            match slot(&[name], 1.0) {
                Some(s) => xyz.push(s),
                None => {
                    return Err(IoError::at_line(
                        path,
                        fields_line,
                        format!("PCD has no \"{name}\" field"),
                    ));
                }
            }
        }
        let time = slot(&["time"], 1.0).or_else(|| slot(&["t"], 1e-9));
        Ok(Self {
            xyz: [xyz[0], xyz[1], xyz[2]],
            intensity: slot(&["intensity", "reflectance"], 1.0),
            time,
            ring: slot(&["ring"], 1.0),
        })
    }
}

/// Decodes one little-endian element.
fn decode(bytes: &[u8], kind: PcdFieldKind, size: usize) -> f64 {
    let mut b = [0_u8; 8];
    b[..size].copy_from_slice(&bytes[..size]);
    match (kind, size) {
        (PcdFieldKind::Float, 4) => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        (PcdFieldKind::Float, _) => f64::from_le_bytes(b),
        (PcdFieldKind::Unsigned, 1) => f64::from(b[0]),
        (PcdFieldKind::Unsigned, 2) => f64::from(u16::from_le_bytes([b[0], b[1]])),
        (PcdFieldKind::Unsigned, 4) => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        (PcdFieldKind::Unsigned, _) => u64::from_le_bytes(b) as f64,
        (PcdFieldKind::Signed, 1) => f64::from(b[0] as i8),
        (PcdFieldKind::Signed, 2) => f64::from(i16::from_le_bytes([b[0], b[1]])),
        (PcdFieldKind::Signed, 4) => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        (PcdFieldKind::Signed, _) => i64::from_le_bytes(b) as f64,
    }
}

/// Builds the raw point from a value getter.
fn make_point(layout: &Layout, value: impl Fn(&Slot) -> f64) -> RawPoint {
    let get = |slot: &Option<Slot>| slot.as_ref().map(|s| value(s) * s.scale);
    let ring = match get(&layout.ring) {
        Some(r) if r.is_finite() && (0.0..f64::from(u16::MAX)).contains(&r) => r as u16,
        _ => RawPoint::UNKNOWN_RING,
    };
    RawPoint::new(
        value(&layout.xyz[0]) as f32,
        value(&layout.xyz[1]) as f32,
        value(&layout.xyz[2]) as f32,
        get(&layout.intensity).unwrap_or(0.0) as f32,
        get(&layout.time).unwrap_or(0.0) as f32,
        ring,
    )
}

/// Reads a PCD file into raw points (with per-point time and ring when the file has them).
pub fn read_pcd_raw(
    path: impl AsRef<Path>,
    options: CloudReadOptions,
) -> Result<PcdCloud<RawPoint>, IoError> {
    let path = path.as_ref();
    let bytes = read_file(path)?;
    let (header, data_offset, header_lines) = parse_header(path, &bytes)?;
    let layout = Layout::new(path, &header, header_lines)?;
    let mut filter = CloudFilter::new(path, options);
    // The header's count is not trusted for the allocation: a lying POINTS must give an error, not an abort.
    let mut points = Vec::with_capacity(header.points.min(bytes.len()));
    let mut push = |index: usize, point: RawPoint, at: Location| -> Result<(), IoError> {
        if filter.keep(index, &point, at)? {
            points.push(point);
        }
        Ok(())
    };
    let n = header.points;
    let point_bytes = header.point_bytes();
    let mut unread_trailing_bytes = 0;
    let data = &bytes[data_offset..];
    match header.data {
        PcdData::Ascii => read_ascii(path, &header, &layout, data, header_lines, &mut push)?,
        PcdData::Binary => {
            let need = n.saturating_mul(point_bytes);
            if data.len() < need {
                return Err(IoError::truncated(
                    path,
                    data_offset as u64,
                    format!("binary data of {n} points x {point_bytes} bytes"),
                    need as u64,
                    data.len() as u64,
                ));
            }
            // More than one point's worth of data beyond the announced points: the header under-counts.
            let trailing = data.len() - need;
            if trailing >= point_bytes.max(1) {
                unread_trailing_bytes = trailing as u64;
            }
            for i in 0..n {
                let record = &data[i * point_bytes..(i + 1) * point_bytes];
                let point = make_point(&layout, |s| decode(&record[s.offset..], s.kind, s.size));
                push(i, point, Location::Offset((data_offset + i * point_bytes) as u64))?;
            }
        }
        PcdData::BinaryCompressed => {
            let columns = decompress(path, data, data_offset, n, point_bytes)?;
            for i in 0..n {
                let point = make_point(&layout, |s| {
                    decode(&columns[n * s.offset + i * s.bytes..], s.kind, s.size)
                });
                push(i, point, Location::Offset(data_offset as u64))?;
            }
        }
    }
    let mut report = filter.report;
    report.unread_trailing_bytes = unread_trailing_bytes;
    Ok(PcdCloud {
        header,
        points,
        report,
    })
}

/// Reads a PCD file into points (x, y, z and intensity, 0 when the file has no intensity field).
pub fn read_pcd(path: impl AsRef<Path>, options: CloudReadOptions) -> Result<PcdCloud<Point>, IoError> {
    let raw = read_pcd_raw(path, options)?;
    Ok(PcdCloud {
        header: raw.header,
        points: raw.points.iter().map(RawPoint::point).collect(),
        report: raw.report,
    })
}

/// Reads only the header of a PCD file.
pub fn read_pcd_header(path: impl AsRef<Path>) -> Result<PcdHeader, IoError> {
    let path = path.as_ref();
    let bytes = read_file(path)?;
    Ok(parse_header(path, &bytes)?.0)
}

/// Parses `DATA ascii` lines: one point per non-blank line with exactly one token per field element.
fn read_ascii(
    path: &Path,
    header: &PcdHeader,
    layout: &Layout,
    data: &[u8],
    header_lines: usize,
    push: &mut impl FnMut(usize, RawPoint, Location) -> Result<(), IoError>,
) -> Result<(), IoError> {
    let text = String::from_utf8_lossy(data);
    let tokens_per_point: usize = header.fields.iter().map(|f| f.count).sum();
    let mut index = 0;
    let mut last_line = header_lines;
    for (k, content) in text.lines().enumerate() {
        let line = header_lines + k + 1;
        last_line = line;
        if content.trim().is_empty() {
            continue;
        }
        if index == header.points {
            return Err(IoError::at_line(
                path,
                line,
                format!("more data lines than POINTS {}", header.points),
            ));
        }
        let mut tokens = Tokens::new(path, line, content);
        let mut values = Vec::with_capacity(tokens_per_point);
        for _ in 0..tokens_per_point {
            // Any field may be "nan" in PCL output; finiteness is judged by the cloud filter.
            values.push(tokens.next_parsed::<f64>("PCD field value")?);
        }
        tokens.finish()?;
        let point = make_point(layout, |s| values[s.token]);
        push(index, point, Location::Line(line))?;
        index += 1;
    }
    if index < header.points {
        return Err(IoError::at_line(
            path,
            last_line,
            format!(
                "POINTS announces {} points but the ascii data has {index}",
                header.points
            ),
        ));
    }
    Ok(())
}

/// Decompresses the `binary_compressed` block that starts at `data_offset` (8 size bytes, then LZF).
fn decompress(
    path: &Path,
    data: &[u8],
    data_offset: usize,
    n: usize,
    point_bytes: usize,
) -> Result<Vec<u8>, IoError> {
    let Some(sizes) = data.get(..8) else {
        return Err(IoError::truncated(
            path,
            data_offset as u64,
            "compressed and uncompressed sizes (two u32)",
            8,
            data.len() as u64,
        ));
    };
    let compressed = u32::from_le_bytes([sizes[0], sizes[1], sizes[2], sizes[3]]) as usize;
    let uncompressed = u32::from_le_bytes([sizes[4], sizes[5], sizes[6], sizes[7]]) as usize;
    let need = n.saturating_mul(point_bytes);
    if uncompressed != need {
        return Err(IoError::at_offset(
            path,
            (data_offset + 4) as u64,
            format!(
                "uncompressed size {uncompressed} differs from POINTS {n} x {point_bytes} bytes = {need}"
            ),
        ));
    }
    let block_offset = data_offset + 8;
    let Some(block) = data.get(8..8 + compressed) else {
        return Err(IoError::truncated(
            path,
            block_offset as u64,
            "LZF-compressed point data",
            compressed as u64,
            (data.len() - 8) as u64,
        ));
    };
    lzf::decompress(block, need).map_err(|(at, message)| {
        IoError::at_offset(path, (block_offset + at) as u64, format!("LZF data: {message}"))
    })
}
