//! Writing ROS 1 bags (format 2.0, wiki.ros.org/Bags/Format/2.0), indexed as `rosbag record` leaves them
//! so `rosbag`, `rosbags` and other readers open them: the bag header record padded to 4096 bytes and
//! rewritten on close, chunks (uncompressed or LZ4 frames) each followed by its index-data records, and
//! at the end every connection and one chunk-info record per chunk.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use crate::error::BagError;
use crate::ros1::MAGIC;

/// A chunk is closed once it holds this many bytes (`rosbag record`'s default).
const CHUNK_THRESHOLD_BYTES: usize = 768 * 1024;
/// The bag header record is padded to this size so it can be rewritten in place.
const BAG_HEADER_RECORD_BYTES: usize = 4096;

/// How chunks are stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ros1Compression {
    None,
    Lz4,
}

struct ConnectionInfo {
    topic: String,
    /// The connection header (`topic`, `type`, `md5sum`, `message_definition`) as record fields.
    details: Vec<u8>,
}

#[derive(Default)]
struct ChunkIndex {
    start_nanos: u64,
    end_nanos: u64,
    /// Per connection: (time, offset in the chunk) of each message.
    entries: BTreeMap<u32, Vec<(u64, u32)>>,
}

/// Streams messages into a ROS 1 bag.
pub struct Ros1Writer {
    path: PathBuf,
    file: BufWriter<File>,
    position: u64,
    compression: Ros1Compression,
    connections: Vec<ConnectionInfo>,
    chunk: Vec<u8>,
    chunk_index: ChunkIndex,
    /// Connections already announced inside the current chunk.
    announced: Vec<bool>,
    /// (chunk position, index) of every closed chunk.
    chunk_infos: Vec<(u64, ChunkIndex)>,
}

fn field(name: &str, value: &[u8]) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(4 + name.len() + 1 + value.len());
    bytes.extend_from_slice(
        &u32::try_from(name.len() + 1 + value.len())
            .unwrap_or(u32::MAX)
            .to_le_bytes(),
    );
    bytes.extend_from_slice(name.as_bytes());
    bytes.push(b'=');
    bytes.extend_from_slice(value);
    bytes
}

fn record(header_fields: &[Vec<u8>], data: &[u8]) -> Vec<u8> {
    let header: Vec<u8> = header_fields.concat();
    let mut bytes = Vec::with_capacity(8 + header.len() + data.len());
    bytes.extend_from_slice(&u32::try_from(header.len()).unwrap_or(u32::MAX).to_le_bytes());
    bytes.extend_from_slice(&header);
    bytes.extend_from_slice(&u32::try_from(data.len()).unwrap_or(u32::MAX).to_le_bytes());
    bytes.extend_from_slice(data);
    bytes
}

/// A ROS 1 `time` packed as the bag stores it: seconds, then nanoseconds, as two little-endian u32.
fn packed_time(nanos: u64) -> [u8; 8] {
    let seconds = u32::try_from(nanos / 1_000_000_000).unwrap_or(u32::MAX);
    let rest = (nanos % 1_000_000_000) as u32;
    let mut bytes = [0u8; 8];
    bytes[..4].copy_from_slice(&seconds.to_le_bytes());
    bytes[4..].copy_from_slice(&rest.to_le_bytes());
    bytes
}

impl Ros1Writer {
    /// Creates the bag (replacing a file there).
    pub fn create(path: &Path, compression: Ros1Compression) -> Result<Self, BagError> {
        let file = File::create(path).map_err(|e| BagError::io(path, e))?;
        let mut writer = Self {
            path: path.to_owned(),
            file: BufWriter::new(file),
            position: 0,
            compression,
            connections: Vec::new(),
            chunk: Vec::new(),
            chunk_index: ChunkIndex::default(),
            announced: Vec::new(),
            chunk_infos: Vec::new(),
        };
        writer.write_bytes(MAGIC)?;
        let header = writer.bag_header(0)?;
        writer.write_bytes(&header)?;
        Ok(writer)
    }

    fn bag_header(&self, index_pos: u64) -> Result<Vec<u8>, BagError> {
        let fields = [
            field("op", &[0x03]),
            field("index_pos", &index_pos.to_le_bytes()),
            field(
                "conn_count",
                &u32::try_from(self.connections.len())
                    .unwrap_or(u32::MAX)
                    .to_le_bytes(),
            ),
            field(
                "chunk_count",
                &u32::try_from(self.chunk_infos.len())
                    .unwrap_or(u32::MAX)
                    .to_le_bytes(),
            ),
        ];
        let header_len: usize = fields.iter().map(Vec::len).sum();
        let padding = BAG_HEADER_RECORD_BYTES.saturating_sub(8 + header_len);
        Ok(record(&fields, &vec![b' '; padding]))
    }

    fn write_bytes(&mut self, bytes: &[u8]) -> Result<(), BagError> {
        self.file
            .write_all(bytes)
            .map_err(|e| BagError::io(&self.path, e))?;
        self.position += bytes.len() as u64;
        Ok(())
    }

    /// Declares a topic; returns its connection id.
    pub fn add_connection(&mut self, topic: &str, message_type: &str, md5sum: &str, definition: &str) -> u32 {
        let details = [
            field("topic", topic.as_bytes()),
            field("type", message_type.as_bytes()),
            field("md5sum", md5sum.as_bytes()),
            field("message_definition", definition.as_bytes()),
        ]
        .concat();
        self.connections.push(ConnectionInfo {
            topic: topic.to_owned(),
            details,
        });
        self.announced.push(false);
        u32::try_from(self.connections.len() - 1).unwrap_or(u32::MAX)
    }

    fn connection_record(&self, id: u32) -> Vec<u8> {
        let connection = &self.connections[id as usize];
        record(
            &[
                field("op", &[0x07]),
                field("conn", &id.to_le_bytes()),
                field("topic", connection.topic.as_bytes()),
            ],
            &connection.details,
        )
    }

    /// Appends one serialized message received at `time_nanos`.
    pub fn write(&mut self, connection: u32, time_nanos: u64, data: &[u8]) -> Result<(), BagError> {
        if connection as usize >= self.connections.len() {
            return Err(BagError::unsupported(
                &self.path,
                format!("connection {connection} was never added"),
            ));
        }
        if !self.announced[connection as usize] {
            let announcement = self.connection_record(connection);
            self.chunk.extend_from_slice(&announcement);
            self.announced[connection as usize] = true;
        }
        let offset = u32::try_from(self.chunk.len()).unwrap_or(u32::MAX);
        let message = record(
            &[
                field("op", &[0x02]),
                field("conn", &connection.to_le_bytes()),
                field("time", &packed_time(time_nanos)),
            ],
            data,
        );
        self.chunk.extend_from_slice(&message);
        let index = &mut self.chunk_index;
        if index.entries.is_empty() {
            index.start_nanos = time_nanos;
            index.end_nanos = time_nanos;
        }
        index.start_nanos = index.start_nanos.min(time_nanos);
        index.end_nanos = index.end_nanos.max(time_nanos);
        index
            .entries
            .entry(connection)
            .or_default()
            .push((time_nanos, offset));
        if self.chunk.len() >= CHUNK_THRESHOLD_BYTES {
            self.flush_chunk()?;
        }
        Ok(())
    }

    fn flush_chunk(&mut self) -> Result<(), BagError> {
        if self.chunk_index.entries.is_empty() {
            return Ok(());
        }
        let chunk_pos = self.position;
        let size = u32::try_from(self.chunk.len()).unwrap_or(u32::MAX).to_le_bytes();
        let (compression, data): (&[u8], Vec<u8>) = match self.compression {
            Ros1Compression::None => (b"none", std::mem::take(&mut self.chunk)),
            Ros1Compression::Lz4 => {
                let mut encoder =
                    lz4_flex::frame::FrameEncoder::new(Vec::with_capacity(self.chunk.len() / 2));
                encoder
                    .write_all(&self.chunk)
                    .map_err(|e| BagError::io(&self.path, e))?;
                let compressed = encoder
                    .finish()
                    .map_err(|e| BagError::io(&self.path, std::io::Error::other(e)))?;
                self.chunk.clear();
                (b"lz4", compressed)
            }
        };
        let chunk = record(
            &[
                field("op", &[0x05]),
                field("compression", compression),
                field("size", &size),
            ],
            &data,
        );
        self.write_bytes(&chunk)?;
        let index = std::mem::take(&mut self.chunk_index);
        for (connection, entries) in &index.entries {
            let mut data = Vec::with_capacity(entries.len() * 12);
            for (time, offset) in entries {
                data.extend_from_slice(&packed_time(*time));
                data.extend_from_slice(&offset.to_le_bytes());
            }
            let count = u32::try_from(entries.len()).unwrap_or(u32::MAX);
            let index_record = record(
                &[
                    field("op", &[0x04]),
                    field("ver", &1u32.to_le_bytes()),
                    field("conn", &connection.to_le_bytes()),
                    field("count", &count.to_le_bytes()),
                ],
                &data,
            );
            self.write_bytes(&index_record)?;
        }
        self.chunk_infos.push((chunk_pos, index));
        self.announced.iter_mut().for_each(|announced| *announced = false);
        Ok(())
    }

    /// Writes the last chunk, the index and the final bag header.
    pub fn finish(mut self) -> Result<PathBuf, BagError> {
        self.flush_chunk()?;
        let index_pos = self.position;
        for id in 0..self.connections.len() {
            let connection = self.connection_record(u32::try_from(id).unwrap_or(u32::MAX));
            self.write_bytes(&connection)?;
        }
        let infos = std::mem::take(&mut self.chunk_infos);
        for (chunk_pos, index) in &infos {
            let mut data = Vec::new();
            for (connection, entries) in &index.entries {
                data.extend_from_slice(&connection.to_le_bytes());
                data.extend_from_slice(&u32::try_from(entries.len()).unwrap_or(u32::MAX).to_le_bytes());
            }
            let count = u32::try_from(index.entries.len()).unwrap_or(u32::MAX);
            let info = record(
                &[
                    field("op", &[0x06]),
                    field("ver", &1u32.to_le_bytes()),
                    field("chunk_pos", &chunk_pos.to_le_bytes()),
                    field("start_time", &packed_time(index.start_nanos)),
                    field("end_time", &packed_time(index.end_nanos)),
                    field("count", &count.to_le_bytes()),
                ],
                &data,
            );
            self.write_bytes(&info)?;
        }
        self.chunk_infos = infos;
        let header = self.bag_header(index_pos)?;
        self.file
            .seek(SeekFrom::Start(MAGIC.len() as u64))
            .and_then(|_| self.file.write_all(&header))
            .and_then(|()| self.file.flush())
            .map_err(|e| BagError::io(&self.path, e))?;
        Ok(self.path)
    }
}
