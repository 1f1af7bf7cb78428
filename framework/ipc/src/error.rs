//! Errors of the IPC layer, each naming the service or port and iceoryx2's reason.

/// What can go wrong creating or using a port.
#[derive(Debug, thiserror::Error)]
pub enum IpcError {
    #[error("invalid name {name:?}: {reason}")]
    Name { name: String, reason: String },
    #[error("creating the iceoryx2 node {name:?}: {reason}")]
    Node { name: String, reason: String },
    #[error("opening service {service:?}: {reason}")]
    Service { service: String, reason: String },
    #[error("creating a {port} on {service:?}: {reason}")]
    Port {
        port: &'static str,
        service: String,
        reason: String,
    },
    #[error("{operation} on {service:?}: {reason}")]
    Io {
        operation: &'static str,
        service: String,
        reason: String,
    },
}

/// Shorthand for results of this crate.
pub type IpcResult<T> = Result<T, IpcError>;
