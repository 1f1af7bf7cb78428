//! The front-end slots' function tables and the values they exchange. A scan (raw points with time
//! offsets and rings, the IMU samples since the previous scan, optional ground truth and LiDAR-to-IMU
//! extrinsic) is lent by the host to an odometry, or by a source to the host until its next call; an
//! odometry writes back its update, with a keyframe cloud it lends to the host until its next call.

use skid_msgs::{ImuSample, Point, RawPoint};

use super::{AbiTransform, CreateFn, DestroyFn, ErrorBuf, Handle, Status};

/// One scan: lent for the duration of a `register` call, or by a source until its next call.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct AbiScan {
    /// The robot the scan belongs to.
    pub robot: u32,
    /// Per-robot scan counter, from 0.
    pub sequence: u32,
    /// Start of the sweep in nanoseconds; point time offsets are relative to it.
    pub stamp_nanos: u64,
    /// Points in the sensor frame. They may hold non-finite coordinates (NaN, infinity): the host passes
    /// a source's points on as they are (the built-in sources drop them, a sensor or a plugin source may
    /// not), so an odometry must skip them.
    pub points: *const RawPoint,
    pub point_count: usize,
    /// IMU samples between the previous scan's stamp and this one's (none without an IMU).
    pub imu: *const ImuSample,
    pub imu_count: usize,
    /// Non-zero when `ground_truth_world_from_sensor` holds the true pose (simulation, datasets).
    pub has_ground_truth: u32,
    /// Non-zero when `imu_from_sensor` holds the LiDAR's pose in the IMU frame.
    pub has_imu_from_sensor: u32,
    pub ground_truth_world_from_sensor: AbiTransform,
    pub imu_from_sensor: AbiTransform,
}

/// What `register` writes: the pose, the motion since the previous scan, and a keyframe when the
/// plugin's keyframe policy fired.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct OdometryResult {
    pub stamp_nanos: u64,
    /// Non-zero when this scan became a keyframe.
    pub is_keyframe: u32,
    /// Explicit padding.
    pub reserved: u32,
    /// Pose of the sensor at the scan stamp in the robot's odometry world frame.
    pub world_from_sensor: AbiTransform,
    /// Motion since the previous scan, `previous_from_current`.
    pub previous_from_current: AbiTransform,
    /// The keyframe's cloud (deskewed, downsampled, sensor frame), lent until the next call on the
    /// instance; empty when `is_keyframe` is zero.
    pub keyframe_points: *const Point,
    pub keyframe_count: usize,
}

/// Registers one scan. Scans arrive in order; a scan the plugin cannot use is an error and leaves its
/// state as it was.
pub type RegisterFn = Option<
    unsafe extern "C" fn(
        handle: Handle,
        scan: *const AbiScan,
        out: *mut OdometryResult,
        error: *mut ErrorBuf,
    ) -> Status,
>;

/// The odometry slot's function table ([`SlotKind::ODOMETRY`](super::SlotKind::ODOMETRY)).
#[repr(C)]
#[derive(Debug)]
pub struct OdometryVTable {
    pub create: CreateFn,
    pub register: RegisterFn,
    pub destroy: DestroyFn,
}

/// Facts about a source the host asks once, after creating it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct SourceInfo {
    /// Non-zero when the scans carry IMU samples.
    pub provides_imu: u32,
    /// Non-zero when `remaining_scans` holds how many scans remain.
    pub knows_remaining: u32,
    pub remaining_scans: u64,
}

/// The next scan of a source: on success `out_has_scan` says whether there was one (zero at the end of
/// the sequence) and `out_scan` describes it, its buffers lent until the next call on the instance.
pub type NextScanFn = Option<
    unsafe extern "C" fn(
        handle: Handle,
        out_scan: *mut AbiScan,
        out_has_scan: *mut u32,
        error: *mut ErrorBuf,
    ) -> Status,
>;

/// Fills a [`SourceInfo`].
pub type SourceInfoFn =
    Option<unsafe extern "C" fn(handle: Handle, out: *mut SourceInfo, error: *mut ErrorBuf) -> Status>;

/// The source slot's function table ([`SlotKind::SOURCE`](super::SlotKind::SOURCE)).
#[repr(C)]
#[derive(Debug)]
pub struct SourceVTable {
    pub create: CreateFn,
    pub info: SourceInfoFn,
    pub next_scan: NextScanFn,
    pub destroy: DestroyFn,
}
