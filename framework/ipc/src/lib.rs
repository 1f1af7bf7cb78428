//! SKiD zero-copy local IPC over iceoryx2: typed keyframe, descriptor and graph-update ports between
//! the stage processes (or threads) of one robot (design guide §5, the `processes` deployment of the
//! SKiD-SLAM pipeline: front-end, place recognition, registration and back-end as separate processes).
//!
//! - [`IpcNode`] ([`ProcessNode`] across processes, [`ThreadNode`] within one): creates ports through one
//!   shared service-builder function, lists dead nodes and cleans up after them ([`IpcNode::maintain`]
//!   about once a second).
//! - [`TopicPublisher`] / [`TopicSubscriber`] for the [`Keyframes`], [`Descriptors`] and [`GraphUpdates`]
//!   topics: a `#[repr(C)]` header and a slice loaned in shared memory, written once, read in place;
//!   every send is followed by an event so subscribers sleep instead of polling; subscribers learn of
//!   publishers that died.

mod error;
mod events;
mod node;
mod port;
mod topic;
#[allow(unsafe_code)] // The `ZeroCopySend` derive only; see the SAFETY note in the module.
mod wire;

pub use error::{IpcError, IpcResult};
pub use node::{CLEANUP_PERIOD, CleanupReport, IpcNode, ProcessNode, ThreadNode};
pub use port::{Loan, PublisherEvents, Received, TopicPublisher, TopicSubscriber};
pub use topic::{Descriptors, FrontEndScans, GraphUpdates, Keyframes, Topic};
pub use wire::{
    FRONT_END_DEGENERATE, FRONT_END_MESSAGE_BYTES, FrontEndHeader, FrontEndStatus, GraphUpdateHeader,
    GraphUpdateKind,
};

/// The iceoryx2 service kinds, for naming `IpcNode<ipc::Service>` and `IpcNode<local::Service>`.
pub use iceoryx2::service::{ipc, local};
