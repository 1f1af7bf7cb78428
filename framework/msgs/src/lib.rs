//! SKiD wire types: the `#[repr(C)]` data that crosses process boundaries (iceoryx2 shared memory) and
//! plugin boundaries (the C ABI of `skid-abi`).
//!
//! Every type here has a fixed layout, no pointers and no padding that could leak uninitialised memory,
//! so it can be written once into shared memory and read in place by another process. Each type carries
//! a versioned type name ([`WireType::TYPE_NAME`]); readers and writers must agree on it, and
//! [`LAYOUT_FINGERPRINT`] summarises the names, sizes and alignments of all of them so that a plugin built
//! against other wire types is refused before any of its data is read.
//!
//! With the `ipc` feature every type also implements iceoryx2's `ZeroCopySend`.

#![allow(unsafe_code)] // Only for the `ZeroCopySend` derive under the `ipc` feature.

mod fingerprint;
mod headers;
mod measurements;
mod points;

pub use fingerprint::{LAYOUT_FINGERPRINT, layout_fingerprint};
pub use headers::{CloudHeader, DescriptorHeader, KeyframeHeader, PoseWire};
pub use measurements::{Information6, LoopMeasurement, OdometryEdge};
pub use points::{ImuSample, Point, RawPoint};

/// A type that travels on the wire under a versioned, stable name such as `skid/Point@1`.
///
/// Bump the version suffix whenever the layout or the meaning of a field changes.
pub trait WireType: Copy + 'static {
    /// The versioned type name, `skid/<Name>@<version>`.
    const TYPE_NAME: &'static str;
}

/// Declares the iceoryx2 derive and type name on a wire type when the `ipc` feature is on.
macro_rules! wire_type {
    ($ty:ident, $name:literal) => {
        impl $crate::WireType for $ty {
            const TYPE_NAME: &'static str = $name;
        }
    };
}
pub(crate) use wire_type;
