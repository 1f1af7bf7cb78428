//! Reading the PLY body: every element is walked in file order (so elements before or after `vertex`,
//! and list properties anywhere, are skipped correctly) and the vertex coordinates are kept.

use std::path::Path;
use std::str::{Lines, SplitWhitespace};

use skid_msgs::RawPoint;

use super::PlyCloud;
use super::header::{PlyElement, PlyFormat, PlyHeader, PlyProperty, PlyScalar, parse_header};
use crate::cloud::{CloudFilter, CloudReadOptions};
use crate::error::{IoError, Location, read_file};

/// Largest list length accepted; a larger one means the data is corrupt (or not what the header says).
const MAX_LIST_LEN: f64 = 1e8;

/// A source of property values: ascii tokens or binary bytes.
trait ValueSource {
    /// Called before the instances of `element` are read (binary sources check the size up front).
    fn begin_element(&mut self, element: &PlyElement) -> Result<(), IoError>;
    /// Reads one scalar of type `ty`; `what` describes it for error messages.
    fn scalar(&mut self, ty: PlyScalar, what: &dyn Fn() -> String) -> Result<f64, IoError>;
    /// Where the next value starts.
    fn location(&self) -> Location;
    /// Checks that nothing but whitespace follows the last element.
    fn finish(&mut self) -> Result<(), IoError>;
    /// Binary bytes left after the last element (0 for ascii, where extra lines are an error).
    fn trailing_bytes(&self) -> u64 {
        0
    }
}

/// Binary little- or big-endian data.
struct Binary<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    position: usize,
    big_endian: bool,
}

impl ValueSource for Binary<'_> {
    fn begin_element(&mut self, element: &PlyElement) -> Result<(), IoError> {
        if let Some(size) = element.fixed_size() {
            let need = element.count.saturating_mul(size);
            let left = self.bytes.len() - self.position;
            if left < need {
                return Err(IoError::truncated(
                    self.path,
                    self.position as u64,
                    format!("element \"{}\" ({} x {size} bytes)", element.name, element.count),
                    need as u64,
                    left as u64,
                ));
            }
        }
        Ok(())
    }

    fn scalar(&mut self, ty: PlyScalar, what: &dyn Fn() -> String) -> Result<f64, IoError> {
        let size = ty.size();
        let left = self.bytes.len() - self.position;
        if left < size {
            return Err(IoError::truncated(
                self.path,
                self.position as u64,
                what(),
                size as u64,
                left as u64,
            ));
        }
        let value = ty.decode(&self.bytes[self.position..], self.big_endian);
        self.position += size;
        Ok(value)
    }

    fn location(&self) -> Location {
        Location::Offset(self.position as u64)
    }

    fn finish(&mut self) -> Result<(), IoError> {
        // Trailing bytes after the last element are tolerated (some writers pad or append a newline);
        // more is reported by `trailing_bytes`.
        Ok(())
    }

    fn trailing_bytes(&self) -> u64 {
        (self.bytes.len() - self.position) as u64
    }
}

/// Ascii data read as a stream of whitespace-separated tokens with their line numbers.
struct Ascii<'a> {
    path: &'a Path,
    lines: Lines<'a>,
    tokens: SplitWhitespace<'a>,
    line: usize,
}

impl<'a> Ascii<'a> {
    fn next_token(&mut self, what: &dyn Fn() -> String) -> Result<&'a str, IoError> {
        loop {
            if let Some(token) = self.tokens.next() {
                return Ok(token);
            }
            match self.lines.next() {
                Some(next) => {
                    self.line += 1;
                    self.tokens = next.split_whitespace();
                }
                None => {
                    return Err(IoError::at_line(
                        self.path,
                        self.line,
                        format!("file ends before {}", what()),
                    ));
                }
            }
        }
    }
}

impl ValueSource for Ascii<'_> {
    fn begin_element(&mut self, _element: &PlyElement) -> Result<(), IoError> {
        Ok(())
    }

    fn scalar(&mut self, _ty: PlyScalar, what: &dyn Fn() -> String) -> Result<f64, IoError> {
        let token = self.next_token(what)?;
        token.parse::<f64>().map_err(|_| {
            IoError::at_line(
                self.path,
                self.line,
                format!("{}: cannot parse \"{token}\"", what()),
            )
        })
    }

    fn location(&self) -> Location {
        Location::Line(self.line)
    }

    fn finish(&mut self) -> Result<(), IoError> {
        match self.next_token(&String::new) {
            Ok(token) => Err(IoError::at_line(
                self.path,
                self.line,
                format!("unexpected data \"{token}\" after the last element"),
            )),
            Err(_) => Ok(()),
        }
    }
}

/// Reads only the header of a PLY file.
pub fn read_ply_header(path: impl AsRef<Path>) -> Result<PlyHeader, IoError> {
    let path = path.as_ref();
    Ok(parse_header(path, &read_file(path)?)?.0)
}

/// Reads the `vertex` element of a PLY file as points.
pub fn read_ply(path: impl AsRef<Path>, options: CloudReadOptions) -> Result<PlyCloud, IoError> {
    let path = path.as_ref();
    let bytes = read_file(path)?;
    let (header, data_offset, header_lines) = parse_header(path, &bytes)?;
    let data = &bytes[data_offset..];
    match header.format {
        PlyFormat::Ascii => {
            let text = String::from_utf8_lossy(data);
            let mut source = Ascii {
                path,
                lines: text.lines(),
                tokens: "".split_whitespace(),
                line: header_lines,
            };
            read_body(path, header, header_lines, &mut source, options)
        }
        PlyFormat::BinaryLittleEndian | PlyFormat::BinaryBigEndian => {
            let big_endian = header.format == PlyFormat::BinaryBigEndian;
            let mut source = Binary {
                path,
                bytes: &bytes,
                position: data_offset,
                big_endian,
            };
            read_body(path, header, header_lines, &mut source, options)
        }
    }
}

/// Walks every element instance, keeping the vertex coordinates.
fn read_body(
    path: &Path,
    header: PlyHeader,
    header_lines: usize,
    source: &mut impl ValueSource,
    options: CloudReadOptions,
) -> Result<PlyCloud, IoError> {
    let Some(vertex_index) = header.elements.iter().position(|e| e.name == "vertex") else {
        return Err(IoError::at_line(
            path,
            header_lines,
            "PLY header has no \"vertex\" element",
        ));
    };
    // For each vertex property, which output component (x, y, z, intensity) it feeds.
    let vertex = &header.elements[vertex_index];
    let mut targets: Vec<Option<usize>> = vec![None; vertex.properties.len()];
    for (component, names) in [
        ["x"].as_slice(),
        &["y"],
        &["z"],
        &["intensity", "scalar_intensity", "reflectance"],
    ]
    .iter()
    .enumerate()
    {
        let found = names
            .iter()
            .find_map(|name| vertex.properties.iter().position(|p| p.name() == *name));
        match found.map(|i| (i, &vertex.properties[i])) {
            Some((i, PlyProperty::Scalar { .. })) => targets[i] = Some(component),
            Some((_, PlyProperty::List { name, .. })) => {
                return Err(IoError::at_line(
                    path,
                    header_lines,
                    format!("vertex property \"{name}\" is a list"),
                ));
            }
            None if component < 3 => {
                return Err(IoError::at_line(
                    path,
                    header_lines,
                    format!("vertex element has no \"{}\"", names[0]),
                ));
            }
            None => {}
        }
    }
    let mut filter = CloudFilter::new(path, options);
    // The header's count is not trusted for the allocation (a corrupt count must give an error, not an abort).
    let mut points = Vec::with_capacity(vertex.count.min(1 << 20));
    for (element_index, element) in header.elements.iter().enumerate() {
        source.begin_element(element)?;
        let is_vertex = element_index == vertex_index;
        if element.properties.is_empty() {
            // Instances without properties occupy no data; do not loop over a possibly huge count.
            continue;
        }
        for instance in 0..element.count {
            let at = source.location();
            let mut values = [0.0_f64; 4];
            for (property_index, property) in element.properties.iter().enumerate() {
                let what = || {
                    format!(
                        "element \"{}\" #{instance} property \"{}\"",
                        element.name,
                        property.name()
                    )
                };
                match property {
                    PlyProperty::Scalar { ty, .. } => {
                        let value = source.scalar(*ty, &what)?;
                        if let Some(component) = targets
                            .get(property_index)
                            .copied()
                            .flatten()
                            .filter(|_| is_vertex)
                        {
                            values[component] = value;
                        }
                    }
                    PlyProperty::List { count, item, .. } => {
                        let list_at = source.location();
                        let n = source.scalar(*count, &what)?;
                        if !(0.0..=MAX_LIST_LEN).contains(&n) || n.fract() != 0.0 {
                            return Err(IoError::parse(
                                path,
                                list_at,
                                format!("{}: bad list length {n}", what()),
                            ));
                        }
                        for _ in 0..n as usize {
                            source.scalar(*item, &what)?;
                        }
                    }
                }
            }
            if is_vertex {
                let [x, y, z, intensity] = values.map(|v| v as f32);
                let point = RawPoint::new(x, y, z, intensity, 0.0, RawPoint::UNKNOWN_RING);
                if filter.keep(instance, &point, at)? {
                    points.push(point.point());
                }
            }
        }
    }
    source.finish()?;
    // Padding or a final newline is fine; a whole vertex's worth or more means the count is short.
    let vertex_bytes = header.elements[vertex_index].fixed_size().unwrap_or(1).max(1) as u64;
    let trailing = source.trailing_bytes();
    if trailing >= vertex_bytes && vertex_index + 1 == header.elements.len() {
        filter.report.unread_trailing_bytes = trailing;
    }
    Ok(PlyCloud {
        header,
        points,
        report: filter.report,
    })
}
