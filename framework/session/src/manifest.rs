//! The JSON files of a session (`session.json`, `robot<i>/keyframes.json`) as serde types, and poses as
//! they are written there.

use nalgebra::{Quaternion, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};
use skid_core::Pose;

/// A pose in JSON: translation in metres and a unit quaternion, x y z w.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseRecord {
    pub translation_m: [f64; 3],
    pub rotation_xyzw: [f64; 4],
}

impl PoseRecord {
    /// The record of `pose`.
    pub fn from_pose(pose: &Pose) -> Self {
        let t = pose.translation.vector;
        let q = pose.rotation.quaternion();
        Self {
            translation_m: [t.x, t.y, t.z],
            rotation_xyzw: [q.i, q.j, q.k, q.w],
        }
    }

    /// The pose, or why the record is not one (a non-finite number, a zero quaternion).
    pub(crate) fn to_pose(self) -> Result<Pose, String> {
        let numbers = self.translation_m.iter().chain(&self.rotation_xyzw);
        if numbers.clone().any(|v| !v.is_finite()) {
            return Err("a pose holds a number that is not finite".into());
        }
        let [x, y, z, w] = self.rotation_xyzw;
        let quaternion = Quaternion::new(w, x, y, z);
        if quaternion.norm() < 1e-9 {
            return Err("a pose's rotation quaternion is zero".into());
        }
        let [tx, ty, tz] = self.translation_m;
        Ok(Pose::from_parts(
            Translation3::new(tx, ty, tz),
            UnitQuaternion::from_quaternion(quaternion),
        ))
    }
}

/// The descriptor entry of the manifest.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct DescriptorRecord {
    pub kind: String,
    pub params: serde_json::Value,
    pub length: usize,
}

/// One robot in the manifest.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RobotRecord {
    pub robot: u32,
    /// Where the robot's map frame sits in the session's map frame; absent when never placed.
    pub map_from_robot: Option<PoseRecord>,
    pub keyframes: usize,
}

/// `session.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Manifest {
    pub format: String,
    pub version: u32,
    pub skid_version: String,
    pub name: String,
    /// The frame every robot is placed in.
    pub map_frame: String,
    pub descriptor: Option<DescriptorRecord>,
    pub robots: Vec<RobotRecord>,
    /// The effective configuration, as TOML text.
    pub config: String,
}

/// The first fields of `session.json`, read before the rest so that another format or a newer version
/// is named as such rather than as a missing field.
#[derive(Clone, Debug, Deserialize)]
pub(crate) struct ManifestHead {
    pub format: Option<String>,
    pub version: Option<u32>,
}

/// One entry of `robot<i>/keyframes.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct KeyframeRecord {
    pub index: u32,
    pub stamp_nanos: u64,
    pub map_from_sensor: PoseRecord,
    pub odometry_from_sensor: PoseRecord,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ground_truth: Option<PoseRecord>,
    pub points: usize,
}
