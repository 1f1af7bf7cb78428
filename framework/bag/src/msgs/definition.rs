//! ROS message definitions as bags carry them (a ROS 1 connection record's `message_definition`, an
//! MCAP schema of encoding `ros1msg` or `ros2msg`): the main type's fields, then each dependency after a
//! line of `=` and `MSG: package/Type`. Parsed into field lists so a message whose type SKiD has no
//! built-in decoder for (a driver's custom point type) is read from its own definition.

use std::collections::HashMap;

use crate::error::DecodeError;
use crate::wire::WireReader;

/// A field's element type.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FieldType {
    /// A primitive (`bool`, `int8` … `float64`, `string`, `time`, `duration`) by its ROS name.
    Primitive(String),
    /// Another message type, fully qualified (`pkg/Type`; `Header` is `std_msgs/Header`).
    Nested(String),
}

/// How many elements a field has.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Arity {
    One,
    Fixed(usize),
    Variable,
}

/// One field of a message definition.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FieldDef {
    pub name: String,
    pub field_type: FieldType,
    pub arity: Arity,
}

/// Every type of a definition text, by `pkg/Type` (the main type under the name given to [`parse`]).
pub type Definitions = HashMap<String, Vec<FieldDef>>;

const PRIMITIVES: [&str; 16] = [
    "bool", "byte", "char", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64",
    "float32", "float64", "string", "time", "duration",
];

/// Parses a concatenated definition whose first section is `main_type` (`pkg/Type`).
pub fn parse(main_type: &str, text: &str) -> Result<Definitions, DecodeError> {
    let mut definitions = Definitions::new();
    let mut current = main_type.to_owned();
    let mut fields = Vec::new();
    for raw_line in text.lines() {
        let line = raw_line.split('#').next().unwrap_or_default().trim();
        if line.starts_with("===") {
            definitions.insert(std::mem::take(&mut current), std::mem::take(&mut fields));
            continue;
        }
        if let Some(name) = line.strip_prefix("MSG:") {
            current = name.trim().replace("/msg/", "/");
            continue;
        }
        if line.is_empty() || line.contains('=') && !line.contains("[<=") {
            // Blank lines, comments and constants (`uint8 FOO=1`) carry no data.
            continue;
        }
        let mut words = line.split_whitespace();
        let (Some(type_text), Some(name)) = (words.next(), words.next()) else {
            return Err(DecodeError::new(format!(
                "definition of {current}: cannot read `{line}`"
            )));
        };
        let package = current.split('/').next().unwrap_or_default();
        fields.push(field(type_text, name, package)?);
    }
    definitions.insert(current, fields);
    Ok(definitions)
}

fn field(type_text: &str, name: &str, package: &str) -> Result<FieldDef, DecodeError> {
    let (base, arity) = match type_text.split_once('[') {
        None => (type_text, Arity::One),
        Some((base, rest)) => {
            let count = rest.trim_end_matches(']').trim_start_matches("<=");
            if count.is_empty() || rest.starts_with("<=") {
                (base, Arity::Variable)
            } else {
                let n = count
                    .parse()
                    .map_err(|_| DecodeError::new(format!("field {name}: bad array size `{type_text}`")))?;
                (base, Arity::Fixed(n))
            }
        }
    };
    let base = base.split("<=").next().unwrap_or(base);
    let field_type = if PRIMITIVES.contains(&base) {
        FieldType::Primitive(base.to_owned())
    } else if base == "Header" {
        FieldType::Nested("std_msgs/Header".to_owned())
    } else if base.contains('/') {
        FieldType::Nested(base.replace("/msg/", "/"))
    } else {
        FieldType::Nested(format!("{package}/{base}"))
    };
    Ok(FieldDef {
        name: name.to_owned(),
        field_type,
        arity,
    })
}

/// A decoded scalar.
#[derive(Clone, Debug, PartialEq)]
pub enum Scalar {
    Number(f64),
    Text(String),
}

/// Reads one primitive of ROS type `name`.
pub fn read_primitive(reader: &mut WireReader<'_>, name: &str) -> Result<Scalar, DecodeError> {
    let number = match name {
        "bool" | "byte" | "char" | "uint8" => f64::from(reader.u8()?),
        "int8" => f64::from(reader.u8()? as i8),
        "int16" | "uint16" => {
            let bytes = reader.take_aligned::<2>()?;
            if name == "int16" {
                f64::from(i16::from_le_bytes(bytes))
            } else {
                f64::from(u16::from_le_bytes(bytes))
            }
        }
        "int32" => f64::from(reader.i32()?),
        "uint32" => f64::from(reader.u32()?),
        "int64" => i64::from_le_bytes(reader.take_aligned::<8>()?) as f64,
        "uint64" => reader.u64()? as f64,
        "float32" => f64::from(reader.f32()?),
        "float64" => reader.f64()?,
        "time" | "duration" => reader.time_nanos()? as f64,
        "string" => return Ok(Scalar::Text(reader.string()?)),
        other => return Err(DecodeError::new(format!("unknown primitive `{other}`"))),
    };
    Ok(Scalar::Number(number))
}

/// Walks one message of `type_name` as `definitions` lay it out, calling `on_scalar(field, value)` for
/// each primitive of the top level (nested messages and arrays of them are walked for their size, their
/// scalars reported under `parent.field`), and `on_sequence(field, count)` before each variable array of
/// messages, which it then leaves to the caller when `on_sequence` returns `true`.
pub fn walk(
    reader: &mut WireReader<'_>,
    definitions: &Definitions,
    type_name: &str,
    visitor: &mut dyn Visitor,
) -> Result<(), DecodeError> {
    if type_name == "std_msgs/Header" {
        let header = reader.header()?;
        visitor.header(header);
        return Ok(());
    }
    let Some(fields) = definitions.get(type_name) else {
        return Err(DecodeError::new(format!(
            "the definition does not describe {type_name}"
        )));
    };
    for field in fields {
        let count = match field.arity {
            Arity::One => None,
            Arity::Fixed(n) => Some(n),
            Arity::Variable => Some(reader.sequence_len(1)?),
        };
        match (&field.field_type, count) {
            (FieldType::Primitive(primitive), None) => {
                visitor.scalar(&field.name, read_primitive(reader, primitive)?)
            }
            (FieldType::Primitive(primitive), Some(n)) => {
                for _ in 0..n {
                    read_primitive(reader, primitive)?;
                }
            }
            (FieldType::Nested(nested), None) => walk(reader, definitions, nested, visitor)?,
            (FieldType::Nested(nested), Some(n)) => {
                if visitor.sequence(&field.name, n) {
                    for _ in 0..n {
                        visitor.element(reader, definitions, nested)?;
                    }
                } else {
                    for _ in 0..n {
                        walk(reader, definitions, nested, &mut Ignore)?;
                    }
                }
            }
        }
    }
    Ok(())
}

/// What [`walk`] reports.
pub trait Visitor {
    fn header(&mut self, _header: crate::wire::Header) {}
    fn scalar(&mut self, _field: &str, _value: Scalar) {}
    /// Whether this visitor reads the elements of this array of messages itself.
    fn sequence(&mut self, _field: &str, _count: usize) -> bool {
        false
    }
    /// Reads one element of an array this visitor took.
    fn element(
        &mut self,
        reader: &mut WireReader<'_>,
        definitions: &Definitions,
        type_name: &str,
    ) -> Result<(), DecodeError> {
        walk(reader, definitions, type_name, &mut Ignore)
    }
}

/// A visitor that only skips.
pub struct Ignore;

impl Visitor for Ignore {}
