//! Writing ROS 2 bags with MCAP storage: a folder holding `<name>.mcap` (zstd-compressed chunks, ROS 2
//! profile, `ros2msg` schemas, CDR messages, written with the official `mcap` crate) and the
//! `metadata.yaml` (rosbag2 format version 8) that `ros2 bag play` and `rosbags` read first.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use mcap::records::MessageHeader;

use crate::error::BagError;

struct Topic {
    name: String,
    message_type: String,
    count: u64,
}

/// Streams messages into a ROS 2 bag folder.
pub struct McapBagWriter {
    folder: PathBuf,
    file_name: String,
    writer: mcap::Writer<BufWriter<File>>,
    topics: BTreeMap<u16, Topic>,
    start_nanos: u64,
    end_nanos: u64,
}

fn mcap_error(path: &Path, error: mcap::McapError) -> BagError {
    BagError::io(path, std::io::Error::other(error.to_string()))
}

impl McapBagWriter {
    /// Creates `folder` (which must not hold a bag already) and its `.mcap` file.
    pub fn create(folder: &Path) -> Result<Self, BagError> {
        std::fs::create_dir_all(folder).map_err(|e| BagError::io(folder, e))?;
        let name = folder
            .file_name()
            .map_or_else(|| "bag".to_owned(), |n| n.to_string_lossy().into_owned());
        let file_name = format!("{name}.mcap");
        let path = folder.join(&file_name);
        let file = File::create(&path).map_err(|e| BagError::io(&path, e))?;
        let options = mcap::WriteOptions::new()
            .profile("ros2")
            .library("skid")
            .compression(Some(mcap::Compression::Zstd));
        let writer = options
            .create(BufWriter::new(file))
            .map_err(|e| mcap_error(&path, e))?;
        Ok(Self {
            folder: folder.to_owned(),
            file_name,
            writer,
            topics: BTreeMap::new(),
            start_nanos: u64::MAX,
            end_nanos: 0,
        })
    }

    fn path(&self) -> PathBuf {
        self.folder.join(&self.file_name)
    }

    /// Declares a topic with its ROS 2 type (`pkg/msg/Type`) and `ros2msg` definition; returns its id.
    pub fn add_topic(&mut self, topic: &str, message_type: &str, definition: &str) -> Result<u16, BagError> {
        let path = self.path();
        let schema = self
            .writer
            .add_schema(message_type, "ros2msg", definition.as_bytes())
            .map_err(|e| mcap_error(&path, e))?;
        let channel = self
            .writer
            .add_channel(schema, topic, "cdr", &BTreeMap::new())
            .map_err(|e| mcap_error(&path, e))?;
        self.topics.insert(
            channel,
            Topic {
                name: topic.to_owned(),
                message_type: message_type.to_owned(),
                count: 0,
            },
        );
        Ok(channel)
    }

    /// Appends one CDR message received at `time_nanos`.
    pub fn write(&mut self, channel: u16, time_nanos: u64, data: &[u8]) -> Result<(), BagError> {
        let path = self.path();
        let Some(topic) = self.topics.get_mut(&channel) else {
            return Err(BagError::unsupported(
                &path,
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
            .map_err(|e| mcap_error(&path, e))
    }

    /// Closes the MCAP file and writes `metadata.yaml`.
    pub fn finish(mut self) -> Result<PathBuf, BagError> {
        let path = self.path();
        self.writer.finish().map_err(|e| mcap_error(&path, e))?;
        let start = if self.start_nanos == u64::MAX {
            0
        } else {
            self.start_nanos
        };
        let duration = self.end_nanos.saturating_sub(start);
        let total: u64 = self.topics.values().map(|t| t.count).sum();
        let mut yaml =
            String::from("rosbag2_bagfile_information:\n  version: 8\n  storage_identifier: mcap\n");
        let _ = writeln!(yaml, "  duration:\n    nanoseconds: {duration}");
        let _ = writeln!(yaml, "  starting_time:\n    nanoseconds_since_epoch: {start}");
        let _ = writeln!(yaml, "  message_count: {total}\n  topics_with_message_count:");
        for topic in self.topics.values() {
            let _ = writeln!(
                yaml,
                "    - topic_metadata:\n        name: {}\n        type: {}\n        serialization_format: cdr\n        offered_qos_profiles: \"\"\n        type_description_hash: \"\"\n      message_count: {}",
                topic.name, topic.message_type, topic.count
            );
        }
        let _ = writeln!(
            yaml,
            "  compression_format: \"\"\n  compression_mode: \"\"\n  relative_file_paths:\n    - {}",
            self.file_name
        );
        let _ = writeln!(
            yaml,
            "  files:\n    - path: {}\n      starting_time:\n        nanoseconds_since_epoch: {start}\n      duration:\n        nanoseconds: {duration}\n      message_count: {total}\n  custom_data: ~\n  ros_distro: \"\"",
            self.file_name
        );
        let metadata = self.folder.join("metadata.yaml");
        std::fs::write(&metadata, yaml).map_err(|e| BagError::io(&metadata, e))?;
        Ok(self.folder)
    }
}
