//! The PLY header: element and property types, the parser (with line numbers in every error) and the
//! formatter.

use std::fmt::Write as _;
use std::path::Path;

use crate::error::IoError;

/// How the element data after `end_header` is stored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PlyFormat {
    /// Whitespace-separated decimal text.
    Ascii,
    /// Packed little-endian binary.
    #[default]
    BinaryLittleEndian,
    /// Packed big-endian binary.
    BinaryBigEndian,
}

impl PlyFormat {
    /// The keyword after `format` in the header.
    pub fn keyword(self) -> &'static str {
        match self {
            PlyFormat::Ascii => "ascii",
            PlyFormat::BinaryLittleEndian => "binary_little_endian",
            PlyFormat::BinaryBigEndian => "binary_big_endian",
        }
    }
}

/// A scalar property type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlyScalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl PlyScalar {
    /// Parses a type name (both the classic `uchar` and the sized `uint8` spellings).
    pub fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => PlyScalar::I8,
            "uchar" | "uint8" => PlyScalar::U8,
            "short" | "int16" => PlyScalar::I16,
            "ushort" | "uint16" => PlyScalar::U16,
            "int" | "int32" => PlyScalar::I32,
            "uint" | "uint32" => PlyScalar::U32,
            "float" | "float32" => PlyScalar::F32,
            "double" | "float64" => PlyScalar::F64,
            _ => return None,
        })
    }

    /// Bytes of one value.
    pub fn size(self) -> usize {
        match self {
            PlyScalar::I8 | PlyScalar::U8 => 1,
            PlyScalar::I16 | PlyScalar::U16 => 2,
            PlyScalar::I32 | PlyScalar::U32 | PlyScalar::F32 => 4,
            PlyScalar::F64 => 8,
        }
    }

    /// The classic type name.
    pub fn name(self) -> &'static str {
        match self {
            PlyScalar::I8 => "char",
            PlyScalar::U8 => "uchar",
            PlyScalar::I16 => "short",
            PlyScalar::U16 => "ushort",
            PlyScalar::I32 => "int",
            PlyScalar::U32 => "uint",
            PlyScalar::F32 => "float",
            PlyScalar::F64 => "double",
        }
    }

    /// Decodes one value from the first `size()` bytes of `bytes`.
    pub(crate) fn decode(self, bytes: &[u8], big_endian: bool) -> f64 {
        let mut b = [0_u8; 8];
        let n = self.size();
        b[..n].copy_from_slice(&bytes[..n]);
        if big_endian {
            b[..n].reverse();
        }
        match self {
            PlyScalar::I8 => f64::from(b[0] as i8),
            PlyScalar::U8 => f64::from(b[0]),
            PlyScalar::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
            PlyScalar::U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
            PlyScalar::I32 => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            PlyScalar::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            PlyScalar::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            PlyScalar::F64 => f64::from_le_bytes(b),
        }
    }
}

/// One property of an element.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PlyProperty {
    /// `property TYPE NAME`.
    Scalar {
        /// Property name.
        name: String,
        /// Value type.
        ty: PlyScalar,
    },
    /// `property list COUNT_TYPE ITEM_TYPE NAME`: a length followed by that many items.
    List {
        /// Property name.
        name: String,
        /// Type of the length prefix (an integer type).
        count: PlyScalar,
        /// Type of each item.
        item: PlyScalar,
    },
}

impl PlyProperty {
    /// The property name.
    pub fn name(&self) -> &str {
        match self {
            PlyProperty::Scalar { name, .. } | PlyProperty::List { name, .. } => name,
        }
    }
}

/// One `element NAME COUNT` with its properties.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PlyElement {
    /// Element name (`vertex`, `face`, ...).
    pub name: String,
    /// Number of instances.
    pub count: usize,
    /// Properties in storage order.
    pub properties: Vec<PlyProperty>,
}

impl PlyElement {
    /// Bytes per instance in binary storage, when no property is a list.
    pub fn fixed_size(&self) -> Option<usize> {
        self.properties
            .iter()
            .map(|p| match p {
                PlyProperty::Scalar { ty, .. } => Some(ty.size()),
                PlyProperty::List { .. } => None,
            })
            .sum()
    }
}

/// A parsed PLY header.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PlyHeader {
    /// Data storage.
    pub format: PlyFormat,
    /// Elements in file order.
    pub elements: Vec<PlyElement>,
    /// `comment` and `obj_info` lines, without the keyword.
    pub comments: Vec<String>,
}

/// Parses the header; returns it, the byte offset of the data and the number of header lines.
pub(crate) fn parse_header(path: &Path, bytes: &[u8]) -> Result<(PlyHeader, usize, usize), IoError> {
    let mut header = PlyHeader::default();
    let mut format = None;
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
        let words: Vec<&str> = text.split_whitespace().collect();
        let error = |message: String| IoError::at_line(path, line, message);
        if line == 1 {
            if words.first() != Some(&"ply") {
                return Err(error("not a PLY file: the first line must be \"ply\"".to_owned()));
            }
            continue;
        }
        match words.as_slice() {
            [] => {}
            ["comment" | "obj_info", ..] => {
                let rest = text.trim().split_once(char::is_whitespace).map_or("", |(_, r)| r);
                header.comments.push(rest.trim().to_owned());
            }
            ["format", kind, version] => {
                if *version != "1.0" {
                    return Err(error(format!("unsupported PLY version \"{version}\"")));
                }
                format = Some(match *kind {
                    "ascii" => PlyFormat::Ascii,
                    "binary_little_endian" => PlyFormat::BinaryLittleEndian,
                    "binary_big_endian" => PlyFormat::BinaryBigEndian,
                    other => return Err(error(format!("unknown PLY format \"{other}\""))),
                });
            }
            ["element", name, count] => {
                let count = count
                    .parse()
                    .map_err(|_| error(format!("bad element count \"{count}\"")))?;
                header.elements.push(PlyElement {
                    name: (*name).to_owned(),
                    count,
                    properties: Vec::new(),
                });
            }
            ["property", "list", count, item, name] => {
                let (Some(count), Some(item)) = (PlyScalar::parse(count), PlyScalar::parse(item)) else {
                    return Err(error(format!("unknown type in list property \"{name}\"")));
                };
                if matches!(count, PlyScalar::F32 | PlyScalar::F64) {
                    return Err(error(format!(
                        "list property \"{name}\" has a floating-point length type"
                    )));
                }
                let property = PlyProperty::List {
                    name: (*name).to_owned(),
                    count,
                    item,
                };
                current(&mut header, path, line)?.properties.push(property);
            }
            ["property", ty, name] => {
                let ty =
                    PlyScalar::parse(ty).ok_or_else(|| error(format!("unknown property type \"{ty}\"")))?;
                let property = PlyProperty::Scalar {
                    name: (*name).to_owned(),
                    ty,
                };
                current(&mut header, path, line)?.properties.push(property);
            }
            ["end_header"] => {
                header.format =
                    format.ok_or_else(|| error("no \"format\" line before end_header".to_owned()))?;
                return Ok((header, position, line));
            }
            _ => return Err(error(format!("unrecognised PLY header line \"{}\"", text.trim()))),
        }
    }
    Err(IoError::at_line(path, line, "end of file before \"end_header\""))
}

/// The element the next `property` line belongs to.
fn current<'h>(header: &'h mut PlyHeader, path: &Path, line: usize) -> Result<&'h mut PlyElement, IoError> {
    header
        .elements
        .last_mut()
        .ok_or_else(|| IoError::at_line(path, line, "property before any element"))
}

/// Formats a header, ending with `end_header` and its newline.
pub(crate) fn format_header(header: &PlyHeader) -> String {
    let mut text = format!("ply\nformat {} 1.0\n", header.format.keyword());
    for comment in &header.comments {
        let _ = writeln!(text, "comment {comment}");
    }
    for element in &header.elements {
        let _ = writeln!(text, "element {} {}", element.name, element.count);
        for property in &element.properties {
            let _ = match property {
                PlyProperty::Scalar { name, ty } => writeln!(text, "property {} {name}", ty.name()),
                PlyProperty::List { name, count, item } => {
                    writeln!(text, "property list {} {} {name}", count.name(), item.name())
                }
            };
        }
    }
    text.push_str("end_header\n");
    text
}
