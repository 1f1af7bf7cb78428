//! The PCD header: its types, the parser (with line numbers in every error) and the formatter.

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::{Isometry3, Translation3};

use crate::error::IoError;
use crate::geometry::unit_quaternion;
use crate::text::Tokens;

/// How the point data after the header is stored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PcdData {
    /// One point per text line, fields separated by spaces.
    Ascii,
    /// Raw little-endian records, one point after the other (row-major, "array of structures").
    #[default]
    Binary,
    /// LZF-compressed, field-major ("structure of arrays": all x, then all y, ...).
    BinaryCompressed,
}

impl PcdData {
    /// The keyword after `DATA` in the header.
    pub fn keyword(self) -> &'static str {
        match self {
            PcdData::Ascii => "ascii",
            PcdData::Binary => "binary",
            PcdData::BinaryCompressed => "binary_compressed",
        }
    }
}

/// The numeric kind of a field (`TYPE` letter).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PcdFieldKind {
    /// `F`: IEEE float (size 4 or 8).
    Float,
    /// `U`: unsigned integer (size 1, 2, 4 or 8).
    Unsigned,
    /// `I`: signed integer (size 1, 2, 4 or 8).
    Signed,
}

/// One entry of `FIELDS` with its `SIZE`, `TYPE` and `COUNT`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PcdField {
    /// Field name (`x`, `intensity`, `normal_x`, `_` for padding, ...).
    pub name: String,
    /// Bytes per element.
    pub size: usize,
    /// Element type.
    pub kind: PcdFieldKind,
    /// Elements per point (e.g. 33 for an FPFH histogram).
    pub count: usize,
}

impl PcdField {
    /// A single-element field.
    pub fn new(name: &str, kind: PcdFieldKind, size: usize) -> Self {
        Self {
            name: name.to_owned(),
            size,
            kind,
            count: 1,
        }
    }

    /// Bytes the field occupies in one point.
    pub fn bytes(&self) -> usize {
        self.size * self.count
    }

    /// The `TYPE` letter.
    pub fn type_letter(&self) -> char {
        match self.kind {
            PcdFieldKind::Float => 'F',
            PcdFieldKind::Unsigned => 'U',
            PcdFieldKind::Signed => 'I',
        }
    }
}

/// A parsed PCD header.
#[derive(Clone, Debug, PartialEq)]
pub struct PcdHeader {
    /// `VERSION` (e.g. `0.7`); empty when the line is absent.
    pub version: String,
    /// The fields of each point, in storage order.
    pub fields: Vec<PcdField>,
    /// `WIDTH`: points per row (or the point count of an unorganised cloud).
    pub width: usize,
    /// `HEIGHT`: rows (1 for an unorganised cloud).
    pub height: usize,
    /// `VIEWPOINT tx ty tz qw qx qy qz`: the sensor pose in the cloud frame (identity when absent).
    pub viewpoint: Isometry3<f64>,
    /// `POINTS`: must equal `width * height`.
    pub points: usize,
    /// Storage of the data section.
    pub data: PcdData,
}

impl PcdHeader {
    /// Bytes of one point in binary storage.
    pub fn point_bytes(&self) -> usize {
        self.fields.iter().map(PcdField::bytes).sum()
    }

    /// The index of the field called `name`.
    pub fn field_index(&self, name: &str) -> Option<usize> {
        self.fields.iter().position(|f| f.name == name)
    }

    /// Byte offset of each field inside one binary point record.
    pub fn field_offsets(&self) -> Vec<usize> {
        let mut offsets = Vec::with_capacity(self.fields.len());
        let mut offset = 0;
        for field in &self.fields {
            offsets.push(offset);
            offset += field.bytes();
        }
        offsets
    }
}

/// Splits `bytes` into the header and the data: returns the header, the byte offset where the data
/// starts and the number of header lines (the data of an ascii file starts on the next line).
pub(crate) fn parse_header(path: &Path, bytes: &[u8]) -> Result<(PcdHeader, usize, usize), IoError> {
    let mut names: Option<(usize, Vec<String>)> = None;
    let mut sizes: Option<(usize, Vec<usize>)> = None;
    let mut types: Option<(usize, Vec<char>)> = None;
    let mut counts: Option<(usize, Vec<usize>)> = None;
    let (mut version, mut width, mut height) = (String::new(), None, None);
    let (mut viewpoint, mut points) = (Isometry3::identity(), None);
    let mut position = 0;
    let mut line = 0;
    while position < bytes.len() {
        line += 1;
        let end = bytes[position..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |k| position + k);
        let text = String::from_utf8_lossy(&bytes[position..end]).into_owned();
        position = (end + 1).min(bytes.len());
        let text = text.trim();
        if text.is_empty() || text.starts_with('#') {
            continue;
        }
        let mut tokens = Tokens::new(path, line, text);
        let keyword = tokens.next_str("keyword")?;
        let rest: Vec<&str> = text.split_whitespace().skip(1).collect();
        match keyword {
            "VERSION" => version = rest.join(" "),
            "FIELDS" | "COLUMNS" => names = Some((line, rest.iter().map(|s| (*s).to_owned()).collect())),
            "SIZE" => sizes = Some((line, parse_all(&mut tokens, rest.len(), "SIZE")?)),
            "COUNT" => counts = Some((line, parse_all(&mut tokens, rest.len(), "COUNT")?)),
            "TYPE" => {
                let letters = rest.iter().map(|s| s.chars().next().unwrap_or(' ')).collect();
                types = Some((line, letters));
            }
            "WIDTH" => width = Some(single(&mut tokens, "WIDTH")?),
            "HEIGHT" => height = Some(single(&mut tokens, "HEIGHT")?),
            "POINTS" => points = Some((line, single(&mut tokens, "POINTS")?)),
            "VIEWPOINT" => {
                let v = tokens.next_f64s::<7>("VIEWPOINT tx ty tz qw qx qy qz")?;
                let rotation = unit_quaternion(v[4], v[5], v[6], v[3]).map_err(|m| tokens.error(m))?;
                viewpoint = Isometry3::from_parts(Translation3::new(v[0], v[1], v[2]), rotation);
                tokens.finish()?;
            }
            "DATA" => {
                let data = match rest.first().copied() {
                    Some("ascii") => PcdData::Ascii,
                    Some("binary") => PcdData::Binary,
                    Some("binary_compressed") => PcdData::BinaryCompressed,
                    other => {
                        return Err(tokens.error(format!(
                            "unknown DATA kind {other:?} (expected ascii, binary or binary_compressed)"
                        )));
                    }
                };
                let fields = build_fields(path, line, names, sizes, types, counts)?;
                let Some(width) = width else {
                    return Err(IoError::at_line(
                        path,
                        line,
                        "header has no WIDTH line before DATA",
                    ));
                };
                let height = height.unwrap_or(1);
                let expected = width.saturating_mul(height);
                let points = match points {
                    None => expected,
                    Some((points_line, points)) if points != expected => {
                        return Err(IoError::at_line(
                            path,
                            points_line,
                            format!("POINTS {points} disagrees with WIDTH x HEIGHT = {width} x {height}"),
                        ));
                    }
                    Some((_, points)) => points,
                };
                let header = PcdHeader {
                    version,
                    fields,
                    width,
                    height,
                    viewpoint,
                    points,
                    data,
                };
                return Ok((header, position, line));
            }
            other => return Err(tokens.error(format!("unknown PCD header keyword \"{other}\""))),
        }
    }
    Err(IoError::at_line(
        path,
        line,
        "end of file before the DATA line of the PCD header",
    ))
}

/// Parses every remaining token of a header line as an unsigned integer.
fn parse_all(tokens: &mut Tokens<'_>, n: usize, what: &str) -> Result<Vec<usize>, IoError> {
    (0..n).map(|_| tokens.next_parsed::<usize>(what)).collect()
}

/// Parses the single unsigned integer of a header line.
fn single(tokens: &mut Tokens<'_>, what: &str) -> Result<usize, IoError> {
    let value = tokens.next_parsed::<usize>(what)?;
    Ok(value)
}

/// Most values one field may hold per point (PCL's largest histogram features have a few hundred; a
/// larger COUNT is a corrupt header, and an unchecked one sized buffers of petabytes, found by fuzzing).
pub const MAX_FIELD_COUNT: usize = 1 << 16;

/// Combines the FIELDS/SIZE/TYPE/COUNT lines, checking that they agree and that every size fits its type.
fn build_fields(
    path: &Path,
    data_line: usize,
    names: Option<(usize, Vec<String>)>,
    sizes: Option<(usize, Vec<usize>)>,
    types: Option<(usize, Vec<char>)>,
    counts: Option<(usize, Vec<usize>)>,
) -> Result<Vec<PcdField>, IoError> {
    let missing =
        |what: &str| IoError::at_line(path, data_line, format!("header has no {what} line before DATA"));
    let (_, names) = names.ok_or_else(|| missing("FIELDS"))?;
    let (size_line, sizes) = sizes.ok_or_else(|| missing("SIZE"))?;
    let (type_line, types) = types.ok_or_else(|| missing("TYPE"))?;
    let (count_line, counts) = counts.unwrap_or_else(|| (data_line, vec![1; names.len()]));
    for (line, n, what) in [
        (size_line, sizes.len(), "SIZE"),
        (type_line, types.len(), "TYPE"),
        (count_line, counts.len(), "COUNT"),
    ] {
        if n != names.len() {
            return Err(IoError::at_line(
                path,
                line,
                format!("{what} has {n} entries for {} FIELDS", names.len()),
            ));
        }
    }
    let mut fields = Vec::with_capacity(names.len());
    for (i, name) in names.into_iter().enumerate() {
        let (size, letter, count) = (sizes[i], types[i], counts[i]);
        if count == 0 || count > MAX_FIELD_COUNT {
            return Err(IoError::at_line(
                path,
                count_line,
                format!(
                    "field \"{name}\" has COUNT {count}; SKiD reads 1 to {MAX_FIELD_COUNT} values per field"
                ),
            ));
        }
        let kind = match (letter, size) {
            ('F', 4 | 8) => PcdFieldKind::Float,
            ('U', 1 | 2 | 4 | 8) => PcdFieldKind::Unsigned,
            ('I', 1 | 2 | 4 | 8) => PcdFieldKind::Signed,
            _ => {
                return Err(IoError::at_line(
                    path,
                    type_line,
                    format!("field \"{name}\": TYPE {letter} with SIZE {size} is not supported"),
                ));
            }
        };
        fields.push(PcdField {
            name,
            size,
            kind,
            count,
        });
    }
    Ok(fields)
}

/// Formats a header (ending with the `DATA` line and its newline).
pub(crate) fn format_header(header: &PcdHeader) -> String {
    let join = |f: &dyn Fn(&PcdField) -> String| header.fields.iter().map(f).collect::<Vec<_>>().join(" ");
    let t = &header.viewpoint.translation.vector;
    let q = header.viewpoint.rotation.quaternion();
    let mut text = String::from("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n");
    let _ = writeln!(text, "FIELDS {}", join(&|f| f.name.clone()));
    let _ = writeln!(text, "SIZE {}", join(&|f| f.size.to_string()));
    let _ = writeln!(text, "TYPE {}", join(&|f| f.type_letter().to_string()));
    let _ = writeln!(text, "COUNT {}", join(&|f| f.count.to_string()));
    let _ = writeln!(text, "WIDTH {}\nHEIGHT {}", header.width, header.height);
    let _ = writeln!(
        text,
        "VIEWPOINT {} {} {} {} {} {} {}",
        t.x, t.y, t.z, q.w, q.i, q.j, q.k
    );
    let _ = writeln!(text, "POINTS {}\nDATA {}", header.points, header.data.keyword());
    text
}
