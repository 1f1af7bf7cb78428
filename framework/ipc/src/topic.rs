//! The typed topics that stages exchange (design guide §5): each names its header type, its element type
//! and the quality of service every participant must agree on (iceoryx2 refuses to open a service whose
//! types or settings differ, so they live here, in one place).

use std::fmt::Debug;

use iceoryx2::prelude::ZeroCopySend;
use skid_msgs::{DescriptorHeader, KeyframeHeader, LoopMeasurement, Point};

use crate::wire::{FrontEndHeader, GraphUpdateHeader};

/// A publish-subscribe topic: a `#[repr(C)]` header followed by a slice of elements.
pub trait Topic: 'static {
    type Header: Debug + Copy + Default + ZeroCopySend;
    type Item: Debug + Copy + ZeroCopySend;
    /// Last segment of the service name.
    const NAME: &'static str;
    /// Slice length the publisher's memory is sized for first; longer loans grow it (power of two).
    const INITIAL_MAX_LEN: usize;
    /// Samples a late (or restarted) subscriber receives on connecting.
    const HISTORY: usize;
    /// Samples a subscriber holds before the oldest is overwritten.
    const BUFFER: usize;
    /// Whether a full subscriber buffer overwrites its oldest sample (`true`) or makes the publisher
    /// wait until the subscriber has taken one (`false`: back-pressure, nothing is lost).
    const SAFE_OVERFLOW: bool = true;
}

/// Keyframes: deskewed, voxel-downsampled clouds with their pose (2 MB ≈ 131k points).
#[derive(Debug)]
pub struct Keyframes;

impl Topic for Keyframes {
    type Header = KeyframeHeader;
    type Item = Point;
    const NAME: &'static str = "keyframes";
    const INITIAL_MAX_LEN: usize = 1 << 17;
    const HISTORY: usize = 1;
    const BUFFER: usize = 8;
}

/// Global descriptors (f32 values, kind in the header).
#[derive(Debug)]
pub struct Descriptors;

impl Topic for Descriptors {
    type Header = DescriptorHeader;
    type Item = f32;
    const NAME: &'static str = "descriptors";
    const INITIAL_MAX_LEN: usize = 1 << 10;
    const HISTORY: usize = 16;
    const BUFFER: usize = 64;
}

/// Pose-graph updates: odometry edges, accepted and retracted loops.
#[derive(Debug)]
pub struct GraphUpdates;

impl Topic for GraphUpdates {
    type Header = GraphUpdateHeader;
    type Item = LoopMeasurement;
    const NAME: &'static str = "graph";
    const INITIAL_MAX_LEN: usize = 64;
    const HISTORY: usize = 0;
    const BUFFER: usize = 256;
}

/// The front-end stage's output, one sample per scan: the scan's odometry pose and ground truth in the
/// header, the keyframe cloud (empty for scans that are not keyframes) as the slice. Lossless: the
/// front-end waits when the host is behind.
#[derive(Debug)]
pub struct FrontEndScans;

impl Topic for FrontEndScans {
    type Header = FrontEndHeader;
    type Item = Point;
    const NAME: &'static str = "front-end";
    const INITIAL_MAX_LEN: usize = 1 << 17;
    const HISTORY: usize = 0;
    const BUFFER: usize = 8;
    const SAFE_OVERFLOW: bool = false;
}
