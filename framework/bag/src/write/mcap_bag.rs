//! Writing ROS 2 bags with MCAP storage: a folder holding `<name>.mcap` (written by [`McapWriter`]) and
//! the `metadata.yaml` (rosbag2 format version 8) that `ros2 bag play` and `rosbags` read first.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::mcap_writer::McapWriter;
use crate::error::BagError;

/// Streams messages into a ROS 2 bag folder.
pub struct McapBagWriter {
    folder: PathBuf,
    file_name: String,
    writer: McapWriter,
}

impl McapBagWriter {
    /// Creates `folder` (which must not hold a bag already) and its `.mcap` file.
    pub fn create(folder: &Path) -> Result<Self, BagError> {
        std::fs::create_dir_all(folder).map_err(|e| BagError::io(folder, e))?;
        let name = folder
            .file_name()
            .map_or_else(|| "bag".to_owned(), |n| n.to_string_lossy().into_owned());
        let file_name = format!("{name}.mcap");
        let writer = McapWriter::create(&folder.join(&file_name))?;
        Ok(Self {
            folder: folder.to_owned(),
            file_name,
            writer,
        })
    }

    /// Declares a topic with its ROS 2 type (`pkg/msg/Type`) and `ros2msg` definition; returns its id.
    pub fn add_topic(&mut self, topic: &str, message_type: &str, definition: &str) -> Result<u16, BagError> {
        self.writer.add_topic(topic, message_type, definition)
    }

    /// Appends one CDR message received at `time_nanos`.
    pub fn write(&mut self, channel: u16, time_nanos: u64, data: &[u8]) -> Result<(), BagError> {
        self.writer.write(channel, time_nanos, data)
    }

    /// Closes the MCAP file and writes `metadata.yaml`.
    pub fn finish(self) -> Result<PathBuf, BagError> {
        let written = self.writer.finish()?;
        let start = written.start_nanos;
        let duration = written.end_nanos.saturating_sub(start);
        let total: u64 = written.topics.iter().map(|t| t.count).sum();
        let mut yaml =
            String::from("rosbag2_bagfile_information:\n  version: 8\n  storage_identifier: mcap\n");
        let _ = writeln!(yaml, "  duration:\n    nanoseconds: {duration}");
        let _ = writeln!(yaml, "  starting_time:\n    nanoseconds_since_epoch: {start}");
        let _ = writeln!(yaml, "  message_count: {total}\n  topics_with_message_count:");
        for topic in &written.topics {
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
