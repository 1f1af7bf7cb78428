//! SKiD back-end: SE(3)/SE(2) pose-graph optimisation (Levenberg-Marquardt on faer sparse Cholesky).

pub mod chordal;
pub mod error;
pub mod g2o_file;
pub mod gnc;
pub mod group;
pub mod linear;
pub mod lm;
pub mod problem;
pub mod robust;
pub mod se2;
pub mod se3;

pub use error::{EdgeLabel, PgoError};
pub use g2o_file::{
    Initialization, PgoOptions, PgoReport, RobustMode, optimize_g2o_file, optimize_pose_graph, write_g2o,
};
