//! Opening any bag by what it is: a ROS 1 `.bag` file, a bare `.mcap` file, a `.db3` file, or a ROS 2 bag
//! folder (`metadata.yaml` with one or more `.mcap` or `.db3` files, read in name order, which is the
//! order `rosbag2` splits them in). The kind is decided from each file's magic bytes, not its name.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::connection::{Connection, MessageReader, RawMessage};
use crate::error::BagError;
use crate::{mcap_file, ros1, sqlite};

/// The storage of one bag file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Storage {
    Ros1,
    Mcap,
    Sqlite3,
}

impl Storage {
    /// A short name for messages and `skid bag info`.
    pub fn name(self) -> &'static str {
        match self {
            Storage::Ros1 => "ROS 1 bag v2.0",
            Storage::Mcap => "MCAP",
            Storage::Sqlite3 => "sqlite3",
        }
    }
}

/// Finds a file's storage from its first bytes.
pub fn detect_storage(path: &Path) -> Result<Storage, BagError> {
    let mut file = std::fs::File::open(path).map_err(|e| BagError::io(path, e))?;
    let mut start = [0u8; 16];
    let mut filled = 0;
    while filled < start.len() {
        let read = file
            .read(&mut start[filled..])
            .map_err(|e| BagError::io(path, e))?;
        if read == 0 {
            break;
        }
        filled += read;
    }
    let start = &start[..filled];
    if start.starts_with(ros1::MAGIC) {
        Ok(Storage::Ros1)
    } else if start.starts_with(mcap_file::MAGIC) {
        Ok(Storage::Mcap)
    } else if start.starts_with(sqlite::MAGIC) {
        Ok(Storage::Sqlite3)
    } else {
        Err(BagError::unsupported(
            path,
            "not a ROS 1 bag, MCAP file or sqlite3 database (unknown first bytes)",
        ))
    }
}

/// The files of a bag path: the file itself, or a folder's `.mcap`/`.db3`/`.bag` files in name order.
pub fn bag_files(path: &Path) -> Result<Vec<PathBuf>, BagError> {
    if !path.is_dir() {
        if !path.exists() {
            return Err(BagError::io(
                path,
                std::io::Error::from(std::io::ErrorKind::NotFound),
            ));
        }
        return Ok(vec![path.to_owned()]);
    }
    let entries = std::fs::read_dir(path).map_err(|e| BagError::io(path, e))?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|entry| entry.ok().map(|e| e.path()))
        .filter(|file| {
            file.extension()
                .is_some_and(|ext| ext == "mcap" || ext == "db3" || ext == "bag")
        })
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(BagError::unsupported(
            path,
            "the folder holds no .mcap, .db3 or .bag file (a ROS 2 bag folder has metadata.yaml and its storage files)",
        ));
    }
    Ok(files)
}

/// The connection of `topic` in `reader` (named `label` in errors); when the reader knows every topic
/// up front and `topic` is not among them, an error that lists those that are.
pub fn require_topic(
    reader: &dyn MessageReader,
    label: &Path,
    topic: &str,
) -> Result<Option<Arc<Connection>>, BagError> {
    let connections = reader.connections();
    if let Some(connection) = connections.iter().find(|c| c.topic == topic) {
        return Ok(Some(Arc::clone(connection)));
    }
    if reader.connections_complete() {
        return Err(BagError::NoSuchTopic {
            path: label.to_owned(),
            topic: topic.to_owned(),
            available: connections.iter().map(|c| c.topic.clone()).collect(),
        });
    }
    Ok(None)
}

fn open_file(path: &Path) -> Result<Box<dyn MessageReader>, BagError> {
    Ok(match detect_storage(path)? {
        Storage::Ros1 => Box::new(ros1::Ros1Reader::open(path)?),
        Storage::Mcap => Box::new(mcap_file::McapReader::open(path)?),
        Storage::Sqlite3 => Box::new(sqlite::SqliteReader::open(path)?),
    })
}

/// A bag of one or more files, read one after the other.
pub struct Bag {
    path: PathBuf,
    files: Vec<PathBuf>,
    current: Box<dyn MessageReader>,
    next_file: usize,
    selected: Option<Vec<String>>,
    /// Connections of files already read, kept for [`Bag::connections`].
    seen: Vec<Arc<Connection>>,
}

impl Bag {
    /// Opens a bag file or folder; the first file is opened (and its index or summary read) now.
    pub fn open(path: &Path) -> Result<Self, BagError> {
        let files = bag_files(path)?;
        let current = open_file(&files[0])?;
        Ok(Self {
            path: path.to_owned(),
            files,
            current,
            next_file: 1,
            selected: None,
            seen: Vec::new(),
        })
    }

    /// The path the bag was opened from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The storage files, in reading order.
    pub fn files(&self) -> &[PathBuf] {
        &self.files
    }

    /// The connection of `topic`; when the bag lists its topics up front and `topic` is not among
    /// them, an error that lists those that are.
    pub fn require_topic(&self, topic: &str) -> Result<Option<Arc<Connection>>, BagError> {
        require_topic(self, &self.path, topic)
    }
}

impl MessageReader for Bag {
    /// The connections known so far, one per topic (the first file's index or summary up front).
    fn connections(&self) -> Vec<Arc<Connection>> {
        let mut all = self.seen.clone();
        for connection in self.current.connections() {
            if !all.iter().any(|known| known.topic == connection.topic) {
                all.push(connection);
            }
        }
        all
    }

    /// Whether the connections already list every topic of the current file.
    fn connections_complete(&self) -> bool {
        self.current.connections_complete()
    }

    /// Restricts `next_message` to these topics.
    fn select_topics(&mut self, topics: &[String]) {
        self.current.select_topics(topics);
        self.selected = Some(topics.to_vec());
    }

    /// The next message of a selected topic, in file order, or `None` at the end of the last file.
    fn next_message(&mut self) -> Result<Option<RawMessage>, BagError> {
        loop {
            if let Some(message) = self.current.next_message()? {
                return Ok(Some(message));
            }
            let Some(file) = self.files.get(self.next_file) else {
                return Ok(None);
            };
            for connection in self.current.connections() {
                if !self.seen.iter().any(|known| known.topic == connection.topic) {
                    self.seen.push(connection);
                }
            }
            self.current = open_file(file)?;
            if let Some(topics) = &self.selected {
                self.current.select_topics(topics);
            }
            self.next_file += 1;
        }
    }
}
