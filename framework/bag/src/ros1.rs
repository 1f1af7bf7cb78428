//! ROS 1 bag format 2.0 (the `rosbag` format specification, wiki.ros.org/Bags/Format/2.0), streamed.
//!
//! A bag is the magic line `#ROSBAG V2.0\n` followed by records, each a `uint32` header length, a header
//! of `uint32`-length-prefixed `name=value` fields (`op` says the record kind), a `uint32` data length
//! and the data. Messages (`op=0x02`) and the connection records (`op=0x07`) that announce their topics
//! live inside chunk records (`op=0x05`), compressed with `none`, `bz2` or `lz4` (the LZ4 frame format);
//! after the chunks, at the bag header's `index_pos`, every connection is repeated and chunk-info
//! records summarise the chunks.
//!
//! The reader goes through the file once, front to back, decompressing one chunk at a time, so memory
//! stays at one chunk whatever the bag's size. An indexed bag's connections are read from its index
//! first, so the topics are known before any message; a bag without an index (`index_pos = 0`, a
//! recorder that crashed) is read the same way with a warning, its connections learnt as they appear,
//! and a record cut short at its end ends the bag with a warning instead of an error.

use std::collections::{HashMap, HashSet};
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::chunk_codec::{decompress_into, resize_for};
use crate::connection::{Connection, MessageBytes, MessageReader, RawMessage};
use crate::error::BagError;
use crate::wire::Encoding;

/// The first bytes of every ROS 1 bag this reader understands.
pub const MAGIC: &[u8] = b"#ROSBAG V2.0\n";

/// Record headers are a handful of short fields; a larger one is corrupt.
const MAX_HEADER_BYTES: u32 = 1 << 20;
/// No record (chunk or message) is allowed to announce more than this.
const MAX_DATA_BYTES: u32 = 1 << 30;

mod op {
    pub const MESSAGE_DATA: u8 = 0x02;
    pub const BAG_HEADER: u8 = 0x03;
    pub const CHUNK: u8 = 0x05;
    pub const CONNECTION: u8 = 0x07;
}

/// The `name=value` fields of a record header or connection header.
struct Fields<'a>(Vec<(&'a str, &'a [u8])>);

impl<'a> Fields<'a> {
    fn parse(bytes: &'a [u8]) -> Result<Self, String> {
        let mut fields = Vec::new();
        let mut rest = bytes;
        while !rest.is_empty() {
            let Some((length, tail)) = rest.split_first_chunk::<4>() else {
                return Err("a header field length is cut short".to_owned());
            };
            let length = u32::from_le_bytes(*length) as usize;
            if length > tail.len() {
                return Err(format!(
                    "a header field announces {length} bytes, {} left",
                    tail.len()
                ));
            }
            let (field, tail) = tail.split_at(length);
            let Some(equals) = field.iter().position(|&b| b == b'=') else {
                return Err("a header field has no `=`".to_owned());
            };
            let name = std::str::from_utf8(&field[..equals])
                .map_err(|_| "a header field name is not UTF-8".to_owned())?;
            fields.push((name, &field[equals + 1..]));
            rest = tail;
        }
        Ok(Self(fields))
    }

    fn bytes(&self, name: &str) -> Result<&'a [u8], String> {
        self.0
            .iter()
            .find(|(field, _)| *field == name)
            .map(|(_, value)| *value)
            .ok_or_else(|| format!("the record has no `{name}` field"))
    }

    fn text(&self, name: &str) -> Result<&'a str, String> {
        std::str::from_utf8(self.bytes(name)?).map_err(|_| format!("field `{name}` is not UTF-8"))
    }

    fn u8(&self, name: &str) -> Result<u8, String> {
        match self.bytes(name)? {
            [value] => Ok(*value),
            other => Err(format!("field `{name}` has {} bytes, 1 expected", other.len())),
        }
    }

    fn u32(&self, name: &str) -> Result<u32, String> {
        let bytes: [u8; 4] = self
            .bytes(name)?
            .try_into()
            .map_err(|_| format!("field `{name}` is not 4 bytes"))?;
        Ok(u32::from_le_bytes(bytes))
    }

    fn u64(&self, name: &str) -> Result<u64, String> {
        let bytes: [u8; 8] = self
            .bytes(name)?
            .try_into()
            .map_err(|_| format!("field `{name}` is not 8 bytes"))?;
        Ok(u64::from_le_bytes(bytes))
    }

    /// A ROS 1 `time` field: `uint32` seconds then `uint32` nanoseconds.
    fn time_nanos(&self, name: &str) -> Result<u64, String> {
        let packed = self.u64(name)?;
        let seconds = packed & 0xffff_ffff;
        let nanos = packed >> 32;
        Ok(seconds * 1_000_000_000 + nanos)
    }
}

/// A decompressed chunk being read.
struct OpenChunk {
    data: Arc<Vec<u8>>,
    position: usize,
    file_offset: u64,
}

/// Streams the messages of a ROS 1 bag.
pub struct Ros1Reader {
    path: PathBuf,
    file: BufReader<File>,
    file_len: u64,
    offset: u64,
    /// Where the index starts (the end of the chunks), or the file's end when the bag has no index.
    data_end: u64,
    indexed: bool,
    connections: HashMap<u32, Arc<Connection>>,
    selected: Option<HashSet<String>>,
    chunk: Option<OpenChunk>,
    /// The last chunk's buffer, reused for the next chunk once no message of it is alive.
    spare_chunk: Option<Arc<Vec<u8>>>,
    /// The compressed bytes of the chunk being opened (reused).
    compressed: Vec<u8>,
    finished: bool,
}

impl Ros1Reader {
    /// Opens a bag, checks its magic and bag header, and reads its index's connections when it has one.
    pub fn open(path: &Path) -> Result<Self, BagError> {
        let file = File::open(path).map_err(|e| BagError::io(path, e))?;
        let file_len = file.metadata().map_err(|e| BagError::io(path, e))?.len();
        let mut reader = Self {
            path: path.to_owned(),
            file: BufReader::with_capacity(1 << 20, file),
            file_len,
            offset: 0,
            data_end: file_len,
            indexed: false,
            connections: HashMap::new(),
            selected: None,
            chunk: None,
            spare_chunk: None,
            compressed: Vec::new(),
            finished: false,
        };
        let mut magic = [0u8; 13];
        reader.read_exact(&mut magic, "the magic line")?;
        if magic != MAGIC {
            return Err(BagError::unsupported(
                path,
                "not a ROS 1 bag v2.0 (no `#ROSBAG V2.0` magic line)",
            ));
        }
        let header_offset = reader.offset;
        let Some((header, data_len)) = reader.read_record_header()? else {
            return Err(BagError::malformed(
                path,
                header_offset,
                "the bag ends before its bag header record",
            ));
        };
        let fields = Fields::parse(&header).map_err(|m| BagError::malformed(path, header_offset, m))?;
        if fields.u8("op") != Ok(op::BAG_HEADER) {
            return Err(BagError::malformed(
                path,
                header_offset,
                "the first record is not a bag header",
            ));
        }
        let index_pos = fields
            .u64("index_pos")
            .map_err(|m| BagError::malformed(path, header_offset, m))?;
        let connection_count = fields
            .u32("conn_count")
            .map_err(|m| BagError::malformed(path, header_offset, m))?;
        reader.skip(data_len)?;
        let chunks_start = reader.offset;
        if index_pos >= chunks_start && index_pos < file_len {
            reader.data_end = index_pos;
            reader.indexed = true;
            reader.read_index_connections(index_pos, connection_count)?;
            reader.seek(chunks_start)?;
        } else {
            tracing::warn!(
                "{}: the bag has no index (index_pos {index_pos}); reading it sequentially, as a recorder that stopped abruptly leaves it",
                path.display()
            );
        }
        Ok(reader)
    }

    /// Whether the bag carries an index.
    pub fn is_indexed(&self) -> bool {
        self.indexed
    }

    fn read_exact(&mut self, buffer: &mut [u8], what: &str) -> Result<(), BagError> {
        self.file.read_exact(buffer).map_err(|error| {
            if error.kind() == std::io::ErrorKind::UnexpectedEof {
                BagError::malformed(&self.path, self.offset, format!("the file ends inside {what}"))
            } else {
                BagError::io(&self.path, error)
            }
        })?;
        self.offset += buffer.len() as u64;
        Ok(())
    }

    fn seek(&mut self, offset: u64) -> Result<(), BagError> {
        self.file
            .seek(SeekFrom::Start(offset))
            .map_err(|e| BagError::io(&self.path, e))?;
        self.offset = offset;
        Ok(())
    }

    fn skip(&mut self, bytes: u32) -> Result<(), BagError> {
        if self.offset + u64::from(bytes) > self.file_len {
            return Err(BagError::malformed(
                &self.path,
                self.offset,
                format!(
                    "a record announces {bytes} data bytes, the file has {} left",
                    self.file_len - self.offset
                ),
            ));
        }
        self.file
            .seek_relative(i64::from(bytes))
            .map_err(|e| BagError::io(&self.path, e))?;
        self.offset += u64::from(bytes);
        Ok(())
    }

    fn read_length(&mut self, limit: u32, what: &str) -> Result<u32, BagError> {
        let mut bytes = [0u8; 4];
        self.read_exact(&mut bytes, what)?;
        let length = u32::from_le_bytes(bytes);
        let left = self.file_len - self.offset;
        if length > limit || u64::from(length) > left {
            return Err(BagError::malformed(
                &self.path,
                self.offset - 4,
                format!("{what} announces {length} bytes; {left} left in the file (limit {limit})"),
            ));
        }
        Ok(length)
    }

    /// The next record's header bytes and data length, leaving the file at the data; `None` at the end.
    fn read_record_header(&mut self) -> Result<Option<(Vec<u8>, u32)>, BagError> {
        if self.offset >= self.data_end {
            return Ok(None);
        }
        let header_len = self.read_length(MAX_HEADER_BYTES, "a record header length")?;
        let mut header = vec![0u8; header_len as usize];
        self.read_exact(&mut header, "a record header")?;
        let data_len = self.read_length(MAX_DATA_BYTES, "a record's data length")?;
        Ok(Some((header, data_len)))
    }

    fn read_data(&mut self, data_len: u32) -> Result<Vec<u8>, BagError> {
        let mut data = vec![0u8; data_len as usize];
        self.read_exact(&mut data, "a record's data")?;
        Ok(data)
    }

    fn read_index_connections(&mut self, index_pos: u64, count: u32) -> Result<(), BagError> {
        self.seek(index_pos)?;
        let data_end = std::mem::replace(&mut self.data_end, self.file_len);
        for _ in 0..count {
            let record_offset = self.offset;
            let Some((header, data_len)) = self.read_record_header()? else {
                break;
            };
            let data = self.read_data(data_len)?;
            let fields =
                Fields::parse(&header).map_err(|m| BagError::malformed(&self.path, record_offset, m))?;
            if fields.u8("op") == Ok(op::CONNECTION) {
                let connection = Record::Connection(connection_from(&fields, &data));
                self.handle_record(connection, record_offset)?;
            }
        }
        self.data_end = data_end;
        Ok(())
    }

    fn open_chunk(&mut self, fields: &Fields<'_>, data_len: u32, offset: u64) -> Result<(), BagError> {
        let path = self.path.clone();
        let malformed = |m: String| BagError::malformed(&path, offset, format!("chunk: {m}"));
        let compression = fields.text("compression").map_err(malformed)?.to_owned();
        let size = fields.u32("size").map_err(malformed)?;
        if size > MAX_DATA_BYTES {
            return Err(malformed(format!(
                "announces {size} uncompressed bytes (limit {MAX_DATA_BYTES})"
            )));
        }
        let mut buffer = self
            .spare_chunk
            .take()
            .and_then(|spare| Arc::try_unwrap(spare).ok())
            .unwrap_or_default();
        if compression == "none" {
            if size != data_len {
                return Err(malformed(format!(
                    "an uncompressed chunk of {data_len} bytes says it holds {size}"
                )));
            }
            resize_for(&mut buffer, size as usize);
            self.read_exact(&mut buffer, "a chunk")?;
        } else {
            let mut compressed = std::mem::take(&mut self.compressed);
            resize_for(&mut compressed, data_len as usize);
            let read = self.read_exact(&mut compressed, "a chunk");
            let decompressed = read.and_then(|()| {
                decompress_into(&compression, &compressed, size as usize, &mut buffer).map_err(malformed)
            });
            self.compressed = compressed;
            decompressed?;
        }
        self.chunk = Some(OpenChunk {
            data: Arc::new(buffer),
            position: 0,
            file_offset: offset,
        });
        Ok(())
    }

    /// The next selected message inside the open chunk; `None` (and the chunk closed) when it is exhausted.
    fn next_in_chunk(&mut self) -> Result<Option<RawMessage>, BagError> {
        while let Some(mut chunk) = self.chunk.take() {
            if chunk.position >= chunk.data.len() {
                self.spare_chunk = Some(chunk.data);
                break;
            }
            let offset = chunk.file_offset;
            let at = chunk.position;
            let (header, data) = split_record(&chunk.data[at..]).map_err(|m| {
                BagError::malformed(&self.path, offset, format!("inside the chunk at byte {at}: {m}"))
            })?;
            let record_len = 8 + header.len() + data.len();
            let fields = Fields::parse(header).map_err(|m| BagError::malformed(&self.path, offset, m))?;
            let record = match fields.u8("op") {
                Ok(op::CONNECTION) => Record::Connection(connection_from(&fields, data)),
                Ok(op::MESSAGE_DATA) => Record::Message(message_from(&fields).map(|(id, time)| {
                    let wanted = self.connections.get(&id).is_none_or(|c| self.is_selected(c));
                    let start = at + 8 + header.len();
                    (
                        id,
                        time,
                        wanted.then(|| MessageBytes::shared(&chunk.data, start..start + data.len())),
                    )
                })),
                _ => Record::Other,
            };
            chunk.position += record_len;
            self.chunk = Some(chunk);
            if let Some(message) = self.handle_record(record, offset)? {
                return Ok(Some(message));
            }
        }
        Ok(None)
    }

    fn is_selected(&self, connection: &Connection) -> bool {
        self.selected
            .as_ref()
            .is_none_or(|topics| topics.contains(&connection.topic))
    }

    /// Registers a connection or returns a selected message.
    fn handle_record(&mut self, record: Record, offset: u64) -> Result<Option<RawMessage>, BagError> {
        let malformed = |m: String| BagError::malformed(&self.path, offset, m);
        match record {
            Record::Connection(connection) => {
                let (id, connection) = connection.map_err(malformed)?;
                self.connections.entry(id).or_insert_with(|| Arc::new(connection));
                Ok(None)
            }
            Record::Message(message) => {
                let (id, log_time_nanos, data) = message.map_err(malformed)?;
                let Some(connection) = self.connections.get(&id) else {
                    return Err(malformed(format!(
                        "message record: connection {id} was never announced"
                    )));
                };
                Ok(data.map(|data| RawMessage {
                    connection: Arc::clone(connection),
                    log_time_nanos,
                    data,
                }))
            }
            Record::Other => Ok(None),
        }
    }

    /// Reads one record at the top level of the file: opens a chunk, registers a connection, returns a
    /// message, or skips anything else. `Err(None)`-like end is `Ok(TopLevel::End)`.
    fn next_top_level(&mut self) -> Result<TopLevel, BagError> {
        let record_offset = self.offset;
        let (header, data_len) = match self.read_record_header() {
            Ok(Some(record)) => record,
            Ok(None) => return Ok(TopLevel::End),
            Err(error) => return self.end_of_unindexed(error),
        };
        let fields = Fields::parse(&header).map_err(|m| BagError::malformed(&self.path, record_offset, m))?;
        let result = match fields.u8("op") {
            Ok(op::CHUNK) => self.open_chunk(&fields, data_len, record_offset).map(|()| None),
            Ok(op::CONNECTION) => self.read_data(data_len).and_then(|data| {
                self.handle_record(Record::Connection(connection_from(&fields, &data)), record_offset)
            }),
            Ok(op::MESSAGE_DATA) => self.read_data(data_len).and_then(|data| {
                let message = message_from(&fields).map(|(id, time)| (id, time, Some(data.into())));
                self.handle_record(Record::Message(message), record_offset)
            }),
            _ => self.skip(data_len).map(|()| None),
        };
        match result {
            Ok(Some(message)) => Ok(TopLevel::Message(message)),
            Ok(None) => Ok(TopLevel::Other),
            Err(error) => self.end_of_unindexed(error),
        }
    }

    /// In a bag without an index, a broken record ends the bag (the recorder stopped while writing it);
    /// in an indexed bag it is an error.
    fn end_of_unindexed(&self, error: BagError) -> Result<TopLevel, BagError> {
        if self.indexed {
            return Err(error);
        }
        tracing::warn!("{error}; the unindexed bag ends here");
        Ok(TopLevel::End)
    }
}

/// A record decoded enough to act on.
enum Record {
    Connection(Result<(u32, Connection), String>),
    /// Connection id, receive time, and the data when the topic is selected.
    Message(Result<(u32, u64, Option<MessageBytes>), String>),
    Other,
}

/// What one top-level record gave.
enum TopLevel {
    End,
    Message(RawMessage),
    Other,
}

fn connection_from(fields: &Fields<'_>, data: &[u8]) -> Result<(u32, Connection), String> {
    let context = |m: String| format!("connection record: {m}");
    let id = fields.u32("conn").map_err(context)?;
    let topic = fields.text("topic").map_err(context)?;
    let details = Fields::parse(data).map_err(context)?;
    let message_type = details.text("type").map_err(context)?;
    let definition = details.text("message_definition").unwrap_or_default().to_owned();
    Ok((
        id,
        Connection::new(topic, message_type, definition, Encoding::Ros1),
    ))
}

fn message_from(fields: &Fields<'_>) -> Result<(u32, u64), String> {
    let context = |m: String| format!("message record: {m}");
    Ok((
        fields.u32("conn").map_err(context)?,
        fields.time_nanos("time").map_err(context)?,
    ))
}

/// Splits one record (header length, header, data length, data) off the front of `bytes`.
fn split_record(bytes: &[u8]) -> Result<(&[u8], &[u8]), String> {
    let take_length = |bytes: &[u8]| -> Result<usize, String> {
        let length: [u8; 4] = bytes
            .get(..4)
            .and_then(|b| b.try_into().ok())
            .ok_or("a record length is cut short")?;
        Ok(u32::from_le_bytes(length) as usize)
    };
    let header_len = take_length(bytes)?;
    let header = bytes
        .get(4..4 + header_len)
        .ok_or_else(|| format!("a record header of {header_len} bytes runs past the end"))?;
    let rest = &bytes[4 + header_len..];
    let data_len = take_length(rest)?;
    let data = rest
        .get(4..4 + data_len)
        .ok_or_else(|| format!("record data of {data_len} bytes runs past the end"))?;
    Ok((header, data))
}

impl MessageReader for Ros1Reader {
    fn connections(&self) -> Vec<Arc<Connection>> {
        let mut connections: Vec<_> = self.connections.iter().collect();
        connections.sort_by_key(|(id, _)| **id);
        connections.into_iter().map(|(_, c)| Arc::clone(c)).collect()
    }

    fn connections_complete(&self) -> bool {
        self.indexed
    }

    fn select_topics(&mut self, topics: &[String]) {
        self.selected = Some(topics.iter().cloned().collect());
    }

    fn next_message(&mut self) -> Result<Option<RawMessage>, BagError> {
        while !self.finished {
            if self.chunk.is_some() {
                if let Some(message) = self.next_in_chunk()? {
                    return Ok(Some(message));
                }
                continue;
            }
            match self.next_top_level()? {
                TopLevel::Message(message) => return Ok(Some(message)),
                TopLevel::Other => {}
                TopLevel::End => self.finished = true,
            }
        }
        Ok(None)
    }
}
