//! MCAP files (mcap.dev specification), the default storage of ROS 2 bags since Iron and what Foxglove
//! records, streamed with the official `mcap` crate's sans-I/O linear reader: the file is fed in pieces,
//! chunks (uncompressed, zstd or lz4) are decompressed one at a time, so memory stays at one chunk.
//!
//! The summary section at the end of the file (found through the footer) lists every schema and channel,
//! so topics are known before the first message; a file without a summary learns its channels as they
//! appear. Messages are ROS 2 CDR (`message_encoding = "cdr"`) or ROS 1 (`"ros1"`); the schema name is the
//! message type. A file cut short (a recorder that crashed) is read up to the cut, with a warning naming
//! the byte offset.

use std::collections::{HashMap, HashSet};
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use mcap::records::Record;
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};

use crate::connection::{BufferPool, Connection, MessageReader, RawMessage};
use crate::error::BagError;
use crate::mcap_records::parse_known;
use crate::wire::Encoding;

/// The magic bytes at both ends of an MCAP file.
pub const MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// No record may announce more than this (chunks included, compressed or not).
const MAX_RECORD_BYTES: usize = 1 << 30;
/// A summary section larger than this is not read up front (topics are then learnt while streaming).
const MAX_SUMMARY_BYTES: u64 = 256 << 20;
/// Footer record (opcode, length, two offsets, CRC) plus the closing magic.
const FOOTER_AND_MAGIC_BYTES: u64 = 1 + 8 + 8 + 8 + 4 + 8;

/// A schema as declared: its name and definition.
#[derive(Clone, Debug)]
struct Schema {
    name: String,
    definition: String,
}

/// What the schema and channel records declared so far.
#[derive(Default)]
struct Declarations {
    schemas: HashMap<u16, Schema>,
    channels: HashMap<u16, (String, Result<Arc<Connection>, String>)>,
}

impl Declarations {
    /// Takes a schema or channel record; returns `true` when the record was one of them.
    fn declare(&mut self, record: &Record<'_>) -> bool {
        match record {
            Record::Schema { header, data } => {
                self.schemas.insert(
                    header.id,
                    Schema {
                        name: header.name.clone(),
                        definition: String::from_utf8_lossy(data).into_owned(),
                    },
                );
                true
            }
            Record::Channel(channel) => {
                let connection = self.connection(channel);
                self.channels
                    .entry(channel.id)
                    .or_insert((channel.topic.clone(), connection));
                true
            }
            _ => false,
        }
    }

    fn connection(&self, channel: &mcap::records::Channel) -> Result<Arc<Connection>, String> {
        let encoding = match channel.message_encoding.as_str() {
            "cdr" => Encoding::Cdr,
            "ros1" => Encoding::Ros1,
            other => {
                return Err(format!(
                    "topic {} has message encoding `{other}`; SKiD reads cdr and ros1",
                    channel.topic
                ));
            }
        };
        let Some(schema) = self.schemas.get(&channel.schema_id) else {
            return Err(format!(
                "topic {} refers to schema {}, which the file does not declare, so its message type is unknown",
                channel.topic, channel.schema_id
            ));
        };
        Ok(Arc::new(Connection::new(
            &channel.topic,
            &schema.name,
            schema.definition.clone(),
            encoding,
        )))
    }
}

/// Streams the messages of one MCAP file.
pub struct McapReader {
    path: PathBuf,
    file: File,
    bytes_read: u64,
    reader: LinearReader,
    declarations: Declarations,
    summary_complete: bool,
    selected: Option<HashSet<String>>,
    buffers: BufferPool,
    finished: bool,
}

impl McapReader {
    /// Opens the file, checks its magic and reads the summary's schemas and channels when it has one.
    pub fn open(path: &Path) -> Result<Self, BagError> {
        let mut file = File::open(path).map_err(|e| BagError::io(path, e))?;
        let file_len = file.metadata().map_err(|e| BagError::io(path, e))?.len();
        let mut magic = [0u8; 8];
        if file.read_exact(&mut magic).is_err() || magic != MAGIC {
            return Err(BagError::unsupported(path, "not an MCAP file (no MCAP magic)"));
        }
        let mut declarations = Declarations::default();
        let summary_complete = read_summary(path, &mut file, file_len, &mut declarations)?;
        file.seek(SeekFrom::Start(0)).map_err(|e| BagError::io(path, e))?;
        let options = LinearReaderOptions::default()
            // No record is longer than the file that holds it (a lying length would otherwise reserve
            // up to the limit before the read comes up short).
            .with_record_length_limit(MAX_RECORD_BYTES.min(usize::try_from(file_len).unwrap_or(usize::MAX)))
            .with_skip_end_magic(true);
        Ok(Self {
            path: path.to_owned(),
            file,
            bytes_read: 0,
            reader: LinearReader::new_with_options(options),
            declarations,
            summary_complete,
            selected: None,
            buffers: BufferPool::default(),
            finished: false,
        })
    }
}

/// Reads the summary section's records through the footer; `Ok(false)` when there is none.
fn read_summary(
    path: &Path,
    file: &mut File,
    file_len: u64,
    declarations: &mut Declarations,
) -> Result<bool, BagError> {
    if file_len < 8 + FOOTER_AND_MAGIC_BYTES {
        return Ok(false);
    }
    let footer_offset = file_len - FOOTER_AND_MAGIC_BYTES;
    let mut footer = [0u8; FOOTER_AND_MAGIC_BYTES as usize];
    file.seek(SeekFrom::Start(footer_offset))
        .map_err(|e| BagError::io(path, e))?;
    file.read_exact(&mut footer).map_err(|e| BagError::io(path, e))?;
    let summary_start = u64::from_le_bytes(footer[9..17].try_into().unwrap_or_default());
    if footer[0] != 0x02 || &footer[29..] != MAGIC || summary_start == 0 {
        return Ok(false);
    }
    if summary_start < 8 || summary_start > footer_offset || footer_offset - summary_start > MAX_SUMMARY_BYTES
    {
        return Err(BagError::malformed(
            path,
            footer_offset,
            format!("the footer puts the summary at byte {summary_start}, outside the file's data"),
        ));
    }
    let mut summary = vec![0u8; (footer_offset - summary_start) as usize];
    file.seek(SeekFrom::Start(summary_start))
        .map_err(|e| BagError::io(path, e))?;
    file.read_exact(&mut summary).map_err(|e| BagError::io(path, e))?;
    let mut rest = summary.as_slice();
    while let Some((&opcode, tail)) = rest.split_first() {
        let offset = summary_start + (summary.len() - rest.len()) as u64;
        let length = tail
            .get(..8)
            .and_then(|b| b.try_into().ok())
            .map(u64::from_le_bytes)
            .filter(|&length| length <= (tail.len() - 8) as u64)
            .ok_or_else(|| {
                BagError::malformed(path, offset, "a summary record runs past the summary section")
            })?;
        let body = &tail[8..8 + length as usize];
        let record = parse_known(opcode, body)
            .map_err(|e| BagError::malformed(path, offset, format!("summary record 0x{opcode:02x}: {e}")))?;
        if let Some(record) = record {
            declarations.declare(&record);
        }
        rest = &tail[8 + length as usize..];
    }
    Ok(true)
}

impl MessageReader for McapReader {
    fn connections(&self) -> Vec<Arc<Connection>> {
        let mut channels: Vec<_> = self.declarations.channels.iter().collect();
        channels.sort_by_key(|(id, _)| **id);
        channels
            .into_iter()
            .filter_map(|(_, (_, connection))| connection.as_ref().ok().cloned())
            .collect()
    }

    fn connections_complete(&self) -> bool {
        self.summary_complete
    }

    fn select_topics(&mut self, topics: &[String]) {
        self.selected = Some(topics.iter().cloned().collect());
    }

    fn next_message(&mut self) -> Result<Option<RawMessage>, BagError> {
        let Self {
            path,
            file,
            bytes_read,
            reader,
            declarations,
            selected,
            buffers,
            finished,
            ..
        } = self;
        while !*finished {
            let malformed = |message: String| BagError::malformed(path, *bytes_read, message);
            // The `mcap` crate's reader (0.26) subtracts a record's length from what is left of its
            // chunk without checking it fits, which panics in builds with overflow checks (found by
            // fuzzing); such a file is malformed, not a reason to stop the process.
            let linear: &mut LinearReader = reader;
            let next = std::panic::catch_unwind(std::panic::AssertUnwindSafe(move || {
                let linear = linear;
                linear.next_event()
            }));
            let Ok(next) = next else {
                *finished = true;
                return Err(malformed(
                    "a record runs past the end of its chunk (the MCAP reader gave up here)".to_owned(),
                ));
            };
            let event = match next {
                None => {
                    *finished = true;
                    break;
                }
                Some(Err(mcap::McapError::UnexpectedEof)) => {
                    // A recorder that stopped while writing leaves the file cut inside a record: what
                    // came before it is read, as the reference readers do, and the cut is reported.
                    *finished = true;
                    tracing::warn!(
                        path = %path.display(),
                        byte_offset = *bytes_read,
                        "the MCAP file ends in the middle of a record (cut short while it was written?); \
                         the messages before the cut are read, the rest is lost"
                    );
                    break;
                }
                Some(event) => event.map_err(|e| malformed(format!("near this offset: {e}")))?,
            };
            match event {
                LinearReadEvent::ReadRequest(wanted) => {
                    let buffer = reader.insert(wanted);
                    let read = file.read(buffer).map_err(|e| BagError::io(path, e))?;
                    reader.notify_read(read);
                    *bytes_read += read as u64;
                }
                LinearReadEvent::Record { data, opcode } => {
                    let record = parse_known(opcode, data)
                        .map_err(|e| malformed(format!("record 0x{opcode:02x}: {e}")))?;
                    let Some(record) = record else {
                        continue;
                    };
                    if declarations.declare(&record) {
                        continue;
                    }
                    let Record::Message { header, data } = record else {
                        continue;
                    };
                    let connection = match declarations.channels.get(&header.channel_id) {
                        Some((topic, _))
                            if selected.as_ref().is_some_and(|topics| !topics.contains(topic)) =>
                        {
                            continue;
                        }
                        Some((_, Ok(connection))) => connection,
                        Some((_, Err(problem))) => {
                            return Err(malformed(problem.clone()));
                        }
                        None => {
                            return Err(malformed(format!(
                                "a message on channel {} comes before (or without) its channel record",
                                header.channel_id
                            )));
                        }
                    };
                    return Ok(Some(RawMessage {
                        connection: Arc::clone(connection),
                        log_time_nanos: header.log_time,
                        data: buffers.copy_of(&data),
                    }));
                }
            }
        }
        Ok(None)
    }
}
