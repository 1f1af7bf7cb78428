//! Errors of the pose-graph optimiser: every bad-input error names the edge or vertex at fault.

use skid_core::PluginError;

/// Where an edge came from, for error messages: its position in the input and its two vertex ids.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EdgeLabel {
    /// Position of the edge among the input edges (file order for g2o files).
    pub index: usize,
    /// The vertex the measurement is expressed in, as the input names it.
    pub from: String,
    /// The measured vertex, as the input names it.
    pub to: String,
}

impl std::fmt::Display for EdgeLabel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "edge {} ({} -> {})", self.index, self.from, self.to)
    }
}

/// What can go wrong when building or optimising a pose graph.
#[derive(Debug, thiserror::Error)]
pub enum PgoError {
    /// The graph file could not be read or written.
    #[error(transparent)]
    Io(#[from] skid_io::IoError),

    /// An edge cannot be used: unknown vertex, non-finite measurement, information matrix that is not
    /// symmetric positive definite, or an edge from a vertex to itself.
    #[error("{edge}: {reason}")]
    InvalidEdge { edge: EdgeLabel, reason: String },

    /// A vertex pose is not finite.
    #[error("vertex {vertex}: {reason}")]
    InvalidVertex { vertex: String, reason: String },

    /// Part of the graph is connected to no fixed vertex, so its poses are not determined.
    #[error(
        "the graph is disconnected: {count} vertices including {vertex} are not connected to a fixed vertex \
         (connect them, or fix one of them)"
    )]
    Disconnected { vertex: String, count: usize },

    /// The graph has nothing to optimise.
    #[error("the graph is empty: {0}")]
    Empty(String),

    /// The sparse linear algebra failed for a reason other than a damped system that is not positive
    /// definite (which Levenberg-Marquardt handles by raising the damping).
    #[error("linear solver: {0}")]
    Solver(String),

    /// An option is out of range.
    #[error("invalid option: {0}")]
    Option(String),
}

impl From<PgoError> for PluginError {
    fn from(error: PgoError) -> Self {
        match error {
            PgoError::Solver(message) => PluginError::failed("pgo", message),
            other => PluginError::InvalidInput(other.to_string()),
        }
    }
}
