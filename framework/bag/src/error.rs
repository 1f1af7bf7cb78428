//! The error type of this crate, [`BagError`]: every variant names the file, and where it can the byte
//! offset, topic and message index, so its `Display` text can be shown to a user as is.

use std::path::{Path, PathBuf};

/// Everything that can go wrong while reading a bag or decoding one of its messages.
#[derive(Debug, thiserror::Error)]
pub enum BagError {
    /// The operating system refused to open or read the file.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },

    /// The container (bag records, MCAP records, sqlite tables) is malformed at a byte offset.
    #[error("{}: byte offset {offset}: {message}", path.display())]
    Malformed {
        path: PathBuf,
        offset: u64,
        message: String,
    },

    /// The file is not a bag this crate reads (unknown magic, storage or compression).
    #[error("{}: {message}", path.display())]
    Unsupported { path: PathBuf, message: String },

    /// A message could not be decoded as the type its connection announces.
    #[error("{}: topic {topic}, message {index}: {message}", path.display())]
    Message {
        path: PathBuf,
        topic: String,
        index: u64,
        message: String,
    },

    /// A requested topic is not in the bag.
    #[error("{}: no topic {topic}; the bag has: {}", path.display(), available.join(", "))]
    NoSuchTopic {
        path: PathBuf,
        topic: String,
        available: Vec<String>,
    },
}

impl BagError {
    pub(crate) fn io(path: &Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.to_owned(),
            source,
        }
    }

    pub(crate) fn malformed(path: &Path, offset: u64, message: impl Into<String>) -> Self {
        Self::Malformed {
            path: path.to_owned(),
            offset,
            message: message.into(),
        }
    }

    pub(crate) fn unsupported(path: &Path, message: impl Into<String>) -> Self {
        Self::Unsupported {
            path: path.to_owned(),
            message: message.into(),
        }
    }
}

/// A problem inside one serialized message, before the bag's context (file, topic, index) is attached.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct DecodeError(pub String);

impl DecodeError {
    pub(crate) fn new(message: impl Into<String>) -> Self {
        Self(message.into())
    }
}
