//! What can go wrong reading or writing a session, each naming the file and, where there is one, the
//! entry.

use std::path::PathBuf;

/// A session that cannot be written or read.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// The operating system refused to create, read or write a file.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A cloud or graph file the session names failed to read or write (the error names the file).
    #[error(transparent)]
    File(#[from] skid_io::IoError),
    /// The file is readable but not a session this version understands, or it contradicts the rest of
    /// the session.
    #[error("{}: {message}", path.display())]
    Invalid { path: PathBuf, message: String },
}

impl SessionError {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            source,
        }
    }

    pub(crate) fn invalid(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Self::Invalid {
            path: path.into(),
            message: message.into(),
        }
    }
}
