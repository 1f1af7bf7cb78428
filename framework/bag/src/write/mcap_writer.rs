//! Writing one MCAP file (mcap.dev specification) with the official `mcap` crate: zstd-compressed
//! chunks, the ROS 2 profile, `ros2msg` schemas and CDR messages, as rosbag2's MCAP storage writes them.
//! Used bare for a run's record (`run.mcap`) and inside a ROS 2 bag folder by [`super::McapBagWriter`].

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use mcap::records::MessageHeader;

use crate::error::BagError;

/// One topic of a written file and how many messages it got.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WrittenTopic {
    pub name: String,
    pub message_type: String,
    pub count: u64,
}

/// What a finished file holds: its topics and the span of its log times.
#[derive(Clone, Debug)]
pub struct WrittenMcap {
    pub path: PathBuf,
    pub topics: Vec<WrittenTopic>,
    /// The earliest log time, 0 when nothing was written.
    pub start_nanos: u64,
    pub end_nanos: u64,
}

/// Streams CDR messages into one `.mcap` file.
pub struct McapWriter {
    path: PathBuf,
    writer: mcap::Writer<BufWriter<File>>,
    topics: BTreeMap<u16, WrittenTopic>,
    start_nanos: u64,
    end_nanos: u64,
}

fn mcap_error(path: &Path, error: mcap::McapError) -> BagError {
    BagError::io(path, std::io::Error::other(error.to_string()))
}

impl McapWriter {
    /// Creates (or replaces) the file at `path`.
    pub fn create(path: &Path) -> Result<Self, BagError> {
        let file = File::create(path).map_err(|e| BagError::io(path, e))?;
        let options = mcap::WriteOptions::new()
            .profile("ros2")
            .library("skid")
            .compression(Some(mcap::Compression::Zstd));
        let writer = options
            .create(BufWriter::new(file))
            .map_err(|e| mcap_error(path, e))?;
        Ok(Self {
            path: path.to_owned(),
            writer,
            topics: BTreeMap::new(),
            start_nanos: u64::MAX,
            end_nanos: 0,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Declares a topic with its ROS 2 type (`pkg/msg/Type`) and `ros2msg` definition; returns its id.
    pub fn add_topic(&mut self, topic: &str, message_type: &str, definition: &str) -> Result<u16, BagError> {
        let schema = self
            .writer
            .add_schema(message_type, "ros2msg", definition.as_bytes())
            .map_err(|e| mcap_error(&self.path, e))?;
        let channel = self
            .writer
            .add_channel(schema, topic, "cdr", &BTreeMap::new())
            .map_err(|e| mcap_error(&self.path, e))?;
        self.topics.insert(
            channel,
            WrittenTopic {
                name: topic.to_owned(),
                message_type: message_type.to_owned(),
                count: 0,
            },
        );
        Ok(channel)
    }

    /// Appends one CDR message logged at `time_nanos`.
    pub fn write(&mut self, channel: u16, time_nanos: u64, data: &[u8]) -> Result<(), BagError> {
        let Some(topic) = self.topics.get_mut(&channel) else {
            return Err(BagError::unsupported(
                &self.path,
                format!("channel {channel} was never added"),
            ));
        };
        topic.count += 1;
        let header = MessageHeader {
            channel_id: channel,
            sequence: u32::try_from(topic.count).unwrap_or(u32::MAX),
            log_time: time_nanos,
            publish_time: time_nanos,
        };
        self.start_nanos = self.start_nanos.min(time_nanos);
        self.end_nanos = self.end_nanos.max(time_nanos);
        self.writer
            .write_to_known_channel(&header, data)
            .map_err(|e| mcap_error(&self.path, e))
    }

    /// Writes the summary section and closes the file.
    pub fn finish(mut self) -> Result<WrittenMcap, BagError> {
        self.writer.finish().map_err(|e| mcap_error(&self.path, e))?;
        Ok(WrittenMcap {
            path: self.path,
            topics: self.topics.into_values().collect(),
            start_nanos: if self.start_nanos == u64::MAX {
                0
            } else {
                self.start_nanos
            },
            end_nanos: self.end_nanos,
        })
    }
}
