//! Configuration errors: each says where the value came from, which key, and what was expected.

use std::path::PathBuf;

/// A configuration that cannot be loaded or does not validate.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// A file that was asked for explicitly does not exist or cannot be read.
    #[error("{}: cannot read configuration file: {reason}", path.display())]
    MissingFile { path: PathBuf, reason: String },

    /// A profile overlay that does not exist.
    #[error("unknown profile `{name}` (no file {}); available profiles: {}", path.display(), available.join(", "))]
    UnknownProfile {
        name: String,
        path: PathBuf,
        available: Vec<String>,
    },

    /// A `--set` argument that is not `key=value`.
    #[error("--set `{argument}`: expected `section.key=value`")]
    BadSetArgument { argument: String },

    /// A file that is not valid TOML.
    #[error("{}: {message}", path.display())]
    Syntax { path: PathBuf, message: String },

    /// A key with a bad value, an unknown key, or an unknown plugin.
    #[error("{origin}: key `{key}`: {message}")]
    Invalid {
        /// The file, environment variable or `--set` argument that supplied the value.
        origin: String,
        /// Full dotted key path from the top of the configuration.
        key: String,
        /// What is wrong and what was expected.
        message: String,
    },
}
