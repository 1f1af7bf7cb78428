//! Reading the two serializations ROS messages travel in, with one cursor:
//!
//! - **ROS 1** (the `ros::serialization` wire format, as ROS 1 bags store messages): little-endian,
//!   packed without alignment, strings and variable arrays prefixed by a `uint32` length, the header
//!   with a `seq` field and `time` as two `uint32`.
//! - **CDR** (OMG XCDR1 as ROS 2 middlewares and bags store messages): a 4-byte encapsulation header
//!   whose second byte selects the byte order (`0x00` big, `0x01` little), every primitive aligned to its
//!   own size counted from the end of that header, strings with a `uint32` length that includes the
//!   terminating NUL, and `builtin_interfaces/Time` as `int32 sec, uint32 nanosec` without `seq`.
//!
//! Every length read from the data is checked against the bytes that remain before anything is
//! allocated, so a lying length field is an error and never a large allocation.

use crate::error::DecodeError;

/// How a message's bytes are serialized.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    Ros1,
    Cdr,
}

/// A `std_msgs/Header`: the stamp in nanoseconds since the Unix epoch and the frame.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Header {
    pub stamp_nanos: u64,
    pub frame_id: String,
}

/// A cursor over one serialized message.
#[derive(Clone, Debug)]
pub struct WireReader<'a> {
    data: &'a [u8],
    position: usize,
    encoding: Encoding,
    big_endian: bool,
}

impl<'a> WireReader<'a> {
    /// A reader over a whole message; for CDR the encapsulation header is read and checked here.
    pub fn new(message: &'a [u8], encoding: Encoding) -> Result<Self, DecodeError> {
        match encoding {
            Encoding::Ros1 => Ok(Self {
                data: message,
                position: 0,
                encoding,
                big_endian: false,
            }),
            Encoding::Cdr => {
                let Some((header, body)) = message.split_first_chunk::<4>() else {
                    return Err(DecodeError::new(format!(
                        "{} bytes, shorter than the 4-byte CDR encapsulation header",
                        message.len()
                    )));
                };
                let big_endian = match header[1] {
                    0x00 | 0x02 => true,
                    0x01 | 0x03 => false,
                    other => {
                        return Err(DecodeError::new(format!(
                            "unknown CDR encapsulation kind 0x{:02x}{other:02x}",
                            header[0]
                        )));
                    }
                };
                Ok(Self {
                    data: body,
                    position: 0,
                    encoding,
                    big_endian,
                })
            }
        }
    }

    /// The serialization being read.
    pub fn encoding(&self) -> Encoding {
        self.encoding
    }

    /// Bytes not read yet.
    pub fn remaining(&self) -> usize {
        self.data.len() - self.position
    }

    /// Whether multi-byte values are big-endian (CDR only; ROS 1 is always little-endian).
    pub fn is_big_endian(&self) -> bool {
        self.big_endian
    }

    fn align(&mut self, size: usize) -> Result<(), DecodeError> {
        if self.encoding == Encoding::Cdr && size > 1 {
            let padding = (size - self.position % size) % size;
            self.take(padding)?;
        }
        Ok(())
    }

    /// The next `count` raw bytes.
    pub fn take(&mut self, count: usize) -> Result<&'a [u8], DecodeError> {
        if count > self.remaining() {
            return Err(DecodeError::new(format!(
                "needs {count} bytes at offset {}, only {} left",
                self.position,
                self.remaining()
            )));
        }
        let bytes = &self.data[self.position..self.position + count];
        self.position += count;
        Ok(bytes)
    }

    /// The next `N` bytes of an `N`-byte primitive, aligned (CDR) and in little-endian order.
    pub fn take_aligned<const N: usize>(&mut self) -> Result<[u8; N], DecodeError> {
        self.align(N)?;
        let mut bytes = [0u8; N];
        bytes.copy_from_slice(self.take(N)?);
        if self.big_endian {
            bytes.reverse();
        }
        Ok(bytes)
    }

    pub fn u8(&mut self) -> Result<u8, DecodeError> {
        Ok(self.take(1)?[0])
    }

    pub fn bool(&mut self) -> Result<bool, DecodeError> {
        Ok(self.u8()? != 0)
    }

    pub fn u32(&mut self) -> Result<u32, DecodeError> {
        Ok(u32::from_le_bytes(self.take_aligned()?))
    }

    pub fn i32(&mut self) -> Result<i32, DecodeError> {
        Ok(i32::from_le_bytes(self.take_aligned()?))
    }

    pub fn u64(&mut self) -> Result<u64, DecodeError> {
        Ok(u64::from_le_bytes(self.take_aligned()?))
    }

    pub fn f32(&mut self) -> Result<f32, DecodeError> {
        Ok(f32::from_le_bytes(self.take_aligned()?))
    }

    pub fn f64(&mut self) -> Result<f64, DecodeError> {
        Ok(f64::from_le_bytes(self.take_aligned()?))
    }

    /// `N` consecutive `float64` (a fixed-size array or a geometry message of doubles).
    pub fn f64_array<const N: usize>(&mut self) -> Result<[f64; N], DecodeError> {
        let mut values = [0.0; N];
        for value in &mut values {
            *value = self.f64()?;
        }
        Ok(values)
    }

    /// The length of a variable-size array whose elements take at least `min_element_bytes` each,
    /// refused when the remaining bytes cannot hold that many.
    pub fn sequence_len(&mut self, min_element_bytes: usize) -> Result<usize, DecodeError> {
        let count = self.u32()? as usize;
        if count.saturating_mul(min_element_bytes.max(1)) > self.remaining() {
            return Err(DecodeError::new(format!(
                "an array announces {count} elements of at least {min_element_bytes} bytes, only {} bytes left",
                self.remaining()
            )));
        }
        Ok(count)
    }

    /// A `uint8[]`, borrowed.
    pub fn byte_sequence(&mut self) -> Result<&'a [u8], DecodeError> {
        let count = self.sequence_len(1)?;
        self.take(count)
    }

    /// A `string`, checked to be UTF-8.
    pub fn string(&mut self) -> Result<String, DecodeError> {
        let mut bytes = self.byte_sequence()?;
        if self.encoding == Encoding::Cdr {
            // CDR counts the terminating NUL; an empty CDR string is length 1, but tolerate 0.
            if let Some((&0, rest)) = bytes.split_last() {
                bytes = rest;
            }
        }
        String::from_utf8(bytes.to_vec()).map_err(|_| DecodeError::new("a string is not UTF-8"))
    }

    /// A `time` (ROS 1) or `builtin_interfaces/Time` (ROS 2) in nanoseconds since the epoch.
    pub fn time_nanos(&mut self) -> Result<u64, DecodeError> {
        let seconds = match self.encoding {
            Encoding::Ros1 => i64::from(self.u32()?),
            Encoding::Cdr => i64::from(self.i32()?),
        };
        let nanos = self.u32()?;
        if seconds < 0 || nanos >= 1_000_000_000 {
            return Err(DecodeError::new(format!(
                "time {seconds} s {nanos} ns is not a valid stamp"
            )));
        }
        Ok(seconds as u64 * 1_000_000_000 + u64::from(nanos))
    }

    /// A `std_msgs/Header` (ROS 1 with its `seq`, which is dropped).
    pub fn header(&mut self) -> Result<Header, DecodeError> {
        if self.encoding == Encoding::Ros1 {
            self.u32()?;
        }
        let stamp_nanos = self.time_nanos()?;
        let frame_id = self.string()?;
        Ok(Header {
            stamp_nanos,
            frame_id,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cdr_aligns_from_the_end_of_the_encapsulation_header() {
        // Little-endian CDR: a u8, then a f64 that must start at offset 8 of the body.
        let mut message = vec![0x00, 0x01, 0x00, 0x00, 7];
        message.extend_from_slice(&[0; 7]);
        message.extend_from_slice(&2.5f64.to_le_bytes());
        let mut reader = WireReader::new(&message, Encoding::Cdr).unwrap();
        assert_eq!(reader.u8().unwrap(), 7);
        assert_eq!(reader.f64().unwrap(), 2.5);
        assert_eq!(reader.remaining(), 0);
    }

    #[test]
    fn big_endian_cdr_strings_and_times() {
        let mut message = vec![0x00, 0x00, 0x00, 0x00];
        message.extend_from_slice(&12i32.to_be_bytes());
        message.extend_from_slice(&5u32.to_be_bytes());
        message.extend_from_slice(&4u32.to_be_bytes());
        message.extend_from_slice(b"map\0");
        let mut reader = WireReader::new(&message, Encoding::Cdr).unwrap();
        let header = reader.header().unwrap();
        assert_eq!(header.stamp_nanos, 12_000_000_005);
        assert_eq!(header.frame_id, "map");
    }

    #[test]
    fn lying_lengths_are_refused_before_allocating() {
        let mut message = Vec::new();
        message.extend_from_slice(&u32::MAX.to_le_bytes());
        message.extend_from_slice(b"abc");
        let mut reader = WireReader::new(&message, Encoding::Ros1).unwrap();
        let error = reader.string().unwrap_err();
        assert!(error.0.contains("4294967295"), "{error}");
        let error = WireReader::new(&[0x00, 0x07, 0, 0], Encoding::Cdr).unwrap_err();
        assert!(error.0.contains("encapsulation"), "{error}");
    }
}
