//! The plugin slots: one object-safe, `Send` trait per pipeline stage, and the data each returns.
//!
//! Conventions shared by every slot: methods take `&mut self`; a plugin spawns no hidden threads (it
//! sizes any rayon pool from [`PluginContext::threads`](crate::PluginContext)); bad input is an
//! `Err(PluginError::InvalidInput)`, never a panic; construction goes through the
//! [`Registry`](crate::Registry) from the plugin's own `deny_unknown_fields` parameters.

mod backend;
mod descriptor;
mod frontend;
mod registration;
mod rejection;
mod transport;

pub use backend::{
    Backend, GraphView, LoopCandidate, LoopClosure, OdometryMeasurement, OptimizeBudget, OptimizeReport,
    RelativePose, Verdict, Verifier,
};
pub use descriptor::{Descriptor, DescriptorBuf, DescriptorIndex, PlaceCandidate};
pub use frontend::{Odometry, OdometryUpdate, Source};
pub use registration::{CoarseAlignment, CoarseRegistration, FineAlignment, FineRegistration, PreparedCloud};
pub use rejection::RejectionKind;
pub use transport::{Datagram, Destination, NetworkTotals, PeerInfo, SimulatedNetwork, Transport};
