//! The single error type of this crate, [`IoError`], and [`Location`], the place in a file an error
//! points at (a line for text formats, a byte offset for binary ones).
//!
//! Every variant carries the path of the file concerned, so the `Display` text of any error can be shown
//! to a user as is: it always names the file and, for malformed content, the line or byte offset.

use std::fmt;
use std::path::{Path, PathBuf};

/// Where in a file a problem was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Location {
    /// A 1-based line number in a text file (or in the text header of a binary file).
    Line(usize),
    /// A 0-based byte offset from the start of a binary file.
    Offset(u64),
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(line) => write!(f, "line {line}"),
            Location::Offset(offset) => write!(f, "byte offset {offset}"),
        }
    }
}

/// Everything that can go wrong while reading or writing a file.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The operating system refused to open, read or write the file.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file that could not be accessed.
        path: PathBuf,
        /// The underlying operating-system error.
        #[source]
        source: std::io::Error,
    },

    /// The content is malformed at a known place (bad number, wrong field count, unknown keyword, ...).
    #[error("{}: {at}: {message}", path.display())]
    Parse {
        /// The file being read.
        path: PathBuf,
        /// The line or byte offset of the problem.
        at: Location,
        /// What is wrong, in a full sentence.
        message: String,
    },

    /// The file ends before the data its layout or header announces.
    #[error(
        "{}: truncated at byte offset {offset}: {what} needs {expected} bytes, found {found}",
        path.display()
    )]
    Truncated {
        /// The file being read.
        path: PathBuf,
        /// The byte offset at which the missing data should start.
        offset: u64,
        /// What was being read (e.g. "point data of 69088 points").
        what: String,
        /// How many bytes were expected from `offset` on.
        expected: u64,
        /// How many bytes were actually present from `offset` on.
        found: u64,
    },

    /// The content is well-formed line by line but inconsistent as a whole (e.g. two files that should
    /// have the same number of rows do not), or a value cannot be written in the requested format.
    #[error("{}: {message}", path.display())]
    Invalid {
        /// The file being read or written.
        path: PathBuf,
        /// What is wrong, in a full sentence.
        message: String,
    },

    /// The test and benchmark data directory (see [`crate::data_dir()`]) or a file in it is absent.
    #[error(
        "{}: data not found; set the SKID_DATA_DIR environment variable to the shared data directory \
         (default <workspace>/../shared/data)",
        path.display()
    )]
    DataMissing {
        /// The path that was looked for.
        path: PathBuf,
    },
}

impl IoError {
    /// An operating-system error on `path`.
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        IoError::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    /// A malformed-content error at `at` in `path`.
    pub fn parse(path: &Path, at: Location, message: impl Into<String>) -> Self {
        IoError::Parse {
            path: path.to_path_buf(),
            at,
            message: message.into(),
        }
    }

    /// A malformed-content error at 1-based `line` of `path`.
    pub fn at_line(path: &Path, line: usize, message: impl Into<String>) -> Self {
        Self::parse(path, Location::Line(line), message)
    }

    /// A malformed-content error at byte `offset` of `path`.
    pub fn at_offset(path: &Path, offset: u64, message: impl Into<String>) -> Self {
        Self::parse(path, Location::Offset(offset), message)
    }

    /// A whole-file inconsistency in `path`.
    pub fn invalid(path: &Path, message: impl Into<String>) -> Self {
        IoError::Invalid {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }

    /// A truncation error: `what` needed `expected` bytes from `offset` but only `found` were there.
    pub fn truncated(path: &Path, offset: u64, what: impl Into<String>, expected: u64, found: u64) -> Self {
        IoError::Truncated {
            path: path.to_path_buf(),
            offset,
            what: what.into(),
            expected,
            found,
        }
    }

    /// The file the error is about.
    pub fn path(&self) -> &Path {
        match self {
            IoError::Io { path, .. }
            | IoError::Parse { path, .. }
            | IoError::Truncated { path, .. }
            | IoError::Invalid { path, .. }
            | IoError::DataMissing { path } => path,
        }
    }

    /// The line or byte offset the error points at, when it points at one.
    pub fn location(&self) -> Option<Location> {
        match self {
            IoError::Parse { at, .. } => Some(*at),
            IoError::Truncated { offset, .. } => Some(Location::Offset(*offset)),
            _ => None,
        }
    }
}

/// Reads a whole file into memory, mapping the failure to [`IoError::Io`] with the path.
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>, IoError> {
    std::fs::read(path).map_err(|e| IoError::io(path, e))
}

/// Writes `bytes` to `path` (creating or truncating it), mapping the failure to [`IoError::Io`].
pub(crate) fn write_file(path: &Path, bytes: &[u8]) -> Result<(), IoError> {
    std::fs::write(path, bytes).map_err(|e| IoError::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_names_file_and_place() {
        let e = IoError::at_line(Path::new("/tmp/a.g2o"), 7, "bad number \"x\"");
        assert_eq!(e.to_string(), "/tmp/a.g2o: line 7: bad number \"x\"");
        let e = IoError::truncated(Path::new("b.bin"), 32, "point data", 16, 3);
        assert_eq!(
            e.to_string(),
            "b.bin: truncated at byte offset 32: point data needs 16 bytes, found 3"
        );
        assert_eq!(e.location(), Some(Location::Offset(32)));
    }
}
