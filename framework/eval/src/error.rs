//! Errors of the evaluation metrics: every bad input (empty, mismatched, non-finite, degenerate) gets a
//! variant with enough context to fix the input, never a panic or a NaN result.

use std::path::PathBuf;

/// What went wrong while evaluating.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// A metric got fewer items than it needs.
    #[error("{what}: need at least {needed}, got {got}")]
    TooFew {
        what: &'static str,
        needed: usize,
        got: usize,
    },

    /// Two inputs that must pair up element by element have different lengths.
    #[error("{what}: lengths differ ({left} vs {right})")]
    LengthMismatch {
        what: &'static str,
        left: usize,
        right: usize,
    },

    /// An input value is NaN or infinite.
    #[error("{what}: non-finite value at index {index}")]
    NonFinite { what: &'static str, index: usize },

    /// The point sets cannot define a unique alignment (all points collinear or coincident).
    #[error("degenerate point set for Umeyama alignment: {reason}")]
    Degenerate { reason: String },

    /// No timestamp of one trajectory lies within the allowed difference of the other's.
    #[error(
        "no matching timestamps between the trajectories (max difference {max_diff_s} s, offset {offset_s} s)"
    )]
    NoAssociation { max_diff_s: f64, offset_s: f64 },

    /// An option has a value the metric cannot use.
    #[error("invalid option {name}: {reason}")]
    InvalidOption { name: &'static str, reason: String },

    /// The PR curve has no ground-truth positive, so recall is undefined.
    #[error("PR curve: no ground-truth positive among {candidates} candidates, recall is undefined")]
    NoPositives { candidates: usize },

    /// A candidate is marked as a true match while its query is marked as having none.
    #[error("PR curve: candidate {index} is a true match but its query is marked as having no match")]
    InconsistentLabels { index: usize },

    /// A trajectory file could not be read.
    #[error(transparent)]
    Io(#[from] skid_io::IoError),

    /// A trajectory file's format could not be recognised.
    #[error("{path}: cannot tell the trajectory format: {reason}")]
    UnknownFormat { path: PathBuf, reason: String },

    /// Drawing or writing a plot failed.
    #[error("plot {path}: {reason}")]
    Plot { path: PathBuf, reason: String },
}
