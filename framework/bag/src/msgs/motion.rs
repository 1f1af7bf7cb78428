//! Motion messages: `sensor_msgs/Imu`, and poses from `nav_msgs/Odometry`, `geometry_msgs/PoseStamped`
//! and `tf2_msgs/TFMessage` (`geometry_msgs/TransformStamped[]`), each decoded from either serialization
//! (the fields and their order are the same in ROS 1 and ROS 2).

use skid_msgs::{ImuSample, PoseWire};

use crate::error::DecodeError;
use crate::wire::{Header, WireReader};

/// A pose or transform with its stamp: `frame_id` is the parent, `child_frame_id` the frame it places.
#[derive(Clone, Debug, PartialEq)]
pub struct StampedPose {
    pub stamp_nanos: u64,
    pub frame_id: String,
    pub child_frame_id: String,
    pub translation_m: [f64; 3],
    /// Unit quaternion `x, y, z, w` as ROS orders it.
    pub rotation_xyzw: [f64; 4],
}

impl StampedPose {
    /// The pose alone, in SKiD's wire form (the same order as ROS's).
    pub fn wire(&self) -> PoseWire {
        PoseWire {
            translation_m: self.translation_m,
            rotation_xyzw: self.rotation_xyzw,
        }
    }
}

fn pose(reader: &mut WireReader<'_>) -> Result<([f64; 3], [f64; 4]), DecodeError> {
    Ok((reader.f64_array::<3>()?, reader.f64_array::<4>()?))
}

/// `sensor_msgs/Imu` as an [`ImuSample`] at its header stamp.
pub fn decode_imu(reader: &mut WireReader<'_>) -> Result<ImuSample, DecodeError> {
    let header = reader.header()?;
    let _orientation = reader.f64_array::<4>()?;
    let _orientation_covariance = reader.f64_array::<9>()?;
    let gyro_radps = reader.f64_array::<3>()?;
    let _gyro_covariance = reader.f64_array::<9>()?;
    let accel_mps2 = reader.f64_array::<3>()?;
    if !gyro_radps.iter().chain(&accel_mps2).all(|v| v.is_finite()) {
        return Err(DecodeError::new("IMU sample is not finite"));
    }
    Ok(ImuSample {
        stamp_nanos: header.stamp_nanos,
        accel_mps2,
        gyro_radps,
    })
}

/// `nav_msgs/Odometry`: the pose of `child_frame_id` in `header.frame_id`.
pub fn decode_odometry(reader: &mut WireReader<'_>) -> Result<StampedPose, DecodeError> {
    let Header {
        stamp_nanos,
        frame_id,
    } = reader.header()?;
    let child_frame_id = reader.string()?;
    let (translation_m, rotation_xyzw) = pose(reader)?;
    Ok(StampedPose {
        stamp_nanos,
        frame_id,
        child_frame_id,
        translation_m,
        rotation_xyzw,
    })
}

/// `geometry_msgs/PoseStamped`; the child frame is left empty (the message does not name it).
pub fn decode_pose_stamped(reader: &mut WireReader<'_>) -> Result<StampedPose, DecodeError> {
    let Header {
        stamp_nanos,
        frame_id,
    } = reader.header()?;
    let (translation_m, rotation_xyzw) = pose(reader)?;
    Ok(StampedPose {
        stamp_nanos,
        frame_id,
        child_frame_id: String::new(),
        translation_m,
        rotation_xyzw,
    })
}

/// `tf2_msgs/TFMessage`: every transform it carries.
pub fn decode_tf_message(reader: &mut WireReader<'_>) -> Result<Vec<StampedPose>, DecodeError> {
    // A TransformStamped takes at least a header (12 bytes), a child frame (4) and 7 doubles.
    let count = reader.sequence_len(72)?;
    let mut transforms = Vec::with_capacity(count);
    for _ in 0..count {
        let Header {
            stamp_nanos,
            frame_id,
        } = reader.header()?;
        let child_frame_id = reader.string()?;
        let (translation_m, rotation_xyzw) = pose(reader)?;
        transforms.push(StampedPose {
            stamp_nanos,
            frame_id,
            child_frame_id,
            translation_m,
            rotation_xyzw,
        });
    }
    Ok(transforms)
}

/// `nav_msgs/Path`: its poses, each with its own stamp and the path's frame.
pub fn decode_path(reader: &mut WireReader<'_>) -> Result<Vec<StampedPose>, DecodeError> {
    reader.header()?;
    // A PoseStamped takes at least a header (12 bytes) and 7 doubles.
    let count = reader.sequence_len(68)?;
    let mut poses = Vec::with_capacity(count);
    for _ in 0..count {
        poses.push(decode_pose_stamped(reader)?);
    }
    Ok(poses)
}
