//! Serializing messages in the two encodings [`crate::wire`] reads: ROS 1 (packed little-endian) and
//! little-endian CDR (encapsulation header `00 01 00 00`, primitives aligned to their size from the
//! end of that header, strings with their NUL counted).

use crate::wire::Encoding;

/// Builds one serialized message.
#[derive(Clone, Debug)]
pub struct WireWriter {
    bytes: Vec<u8>,
    encoding: Encoding,
    /// Where the aligned body starts (after the CDR encapsulation header).
    origin: usize,
}

impl WireWriter {
    /// An empty message in `encoding`, with room for `capacity` bytes.
    pub fn new(encoding: Encoding, capacity: usize) -> Self {
        let mut bytes = Vec::with_capacity(capacity + 4);
        if encoding == Encoding::Cdr {
            bytes.extend_from_slice(&[0x00, 0x01, 0x00, 0x00]);
        }
        let origin = bytes.len();
        Self {
            bytes,
            encoding,
            origin,
        }
    }

    /// The finished message.
    pub fn into_bytes(self) -> Vec<u8> {
        self.bytes
    }

    fn align(&mut self, size: usize) {
        if self.encoding == Encoding::Cdr {
            while !(self.bytes.len() - self.origin).is_multiple_of(size) {
                self.bytes.push(0);
            }
        }
    }

    pub fn u8(&mut self, value: u8) {
        self.bytes.push(value);
    }

    pub fn bool(&mut self, value: bool) {
        self.bytes.push(u8::from(value));
    }

    pub fn u32(&mut self, value: u32) {
        self.align(4);
        self.bytes.extend_from_slice(&value.to_le_bytes());
    }

    pub fn i32(&mut self, value: i32) {
        self.align(4);
        self.bytes.extend_from_slice(&value.to_le_bytes());
    }

    pub fn f32(&mut self, value: f32) {
        self.align(4);
        self.bytes.extend_from_slice(&value.to_le_bytes());
    }

    pub fn f64(&mut self, value: f64) {
        self.align(8);
        self.bytes.extend_from_slice(&value.to_le_bytes());
    }

    pub fn f64s(&mut self, values: &[f64]) {
        for value in values {
            self.f64(*value);
        }
    }

    /// A `uint8[]`: length, then the bytes.
    pub fn byte_sequence(&mut self, bytes: &[u8]) {
        self.u32(u32::try_from(bytes.len()).unwrap_or(u32::MAX));
        self.bytes.extend_from_slice(bytes);
    }

    /// The length prefix of a variable array.
    pub fn sequence_len(&mut self, count: usize) {
        self.u32(u32::try_from(count).unwrap_or(u32::MAX));
    }

    pub fn string(&mut self, text: &str) {
        match self.encoding {
            Encoding::Ros1 => self.byte_sequence(text.as_bytes()),
            Encoding::Cdr => {
                self.u32(u32::try_from(text.len() + 1).unwrap_or(u32::MAX));
                self.bytes.extend_from_slice(text.as_bytes());
                self.bytes.push(0);
            }
        }
    }

    /// A stamp in nanoseconds since the epoch as `time` / `builtin_interfaces/Time`.
    pub fn time_nanos(&mut self, stamp_nanos: u64) {
        let seconds = stamp_nanos / 1_000_000_000;
        let nanos = (stamp_nanos % 1_000_000_000) as u32;
        match self.encoding {
            Encoding::Ros1 => self.u32(u32::try_from(seconds).unwrap_or(u32::MAX)),
            Encoding::Cdr => self.i32(i32::try_from(seconds).unwrap_or(i32::MAX)),
        }
        self.u32(nanos);
    }

    /// A `std_msgs/Header` (ROS 1 with `seq`).
    pub fn header(&mut self, seq: u32, stamp_nanos: u64, frame_id: &str) {
        if self.encoding == Encoding::Ros1 {
            self.u32(seq);
        }
        self.time_nanos(stamp_nanos);
        self.string(frame_id);
    }
}
