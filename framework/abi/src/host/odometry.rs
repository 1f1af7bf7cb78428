//! A dynamic odometry plugin seen through skid-core's [`Odometry`] trait, and its registry entry.
//!
//! The host lends the scan by pointer and copies the keyframe cloud the plugin lends back, after
//! checking that it is no larger than the scan and that both poses are rigid motions. Keyframe ids are
//! the host's: the robot and a per-instance counter, as the built-in odometries number them.

use skid_core::slots::{Odometry, OdometryUpdate};
use skid_core::{
    Cloud, Keyframe, KeyframeId, Params, PluginContext, PluginEntry, PluginError, PluginResult, Scan,
};

use super::call::{ErrorSlot, copy_lent};
use super::instance::{Instance, registry_entry};
use super::library::{OdometryFns, PluginSpec};
use crate::ffi::{AbiScan, AbiTransform, OdometryResult};
use crate::transform::{abi_from_pose, pose_from_abi};

/// The registry entry of a loaded odometry plugin.
pub(super) fn entry(plugin: &'static PluginSpec, fns: OdometryFns) -> PluginEntry<dyn Odometry> {
    registry_entry(plugin, fns.create, fns.destroy, move |params, context| {
        DynOdometry::create(plugin, fns, params, context).map(|plugin| Box::new(plugin) as Box<dyn Odometry>)
    })
}

/// An instance of a dynamically loaded odometry plugin. After a panic it refuses further calls.
pub struct DynOdometry {
    instance: Instance,
    fns: OdometryFns,
    keyframes: u32,
}

impl DynOdometry {
    pub(super) fn create(
        plugin: &'static PluginSpec,
        fns: OdometryFns,
        params: &Params,
        context: &PluginContext,
    ) -> PluginResult<Self> {
        let instance = Instance::create(plugin, fns.create, fns.destroy, params, context)?;
        Ok(Self {
            instance,
            fns,
            keyframes: 0,
        })
    }

    fn bad_output(&self, message: String) -> PluginError {
        self.instance.bad_output(format!("register: {message}"))
    }
}

impl Odometry for DynOdometry {
    fn register(&mut self, scan: &Scan) -> PluginResult<OdometryUpdate> {
        let _serial = self.instance.enter()?;
        let lent = AbiScan {
            robot: scan.robot.0,
            sequence: scan.sequence,
            stamp_nanos: scan.stamp_nanos,
            points: scan.points.as_ptr(),
            point_count: scan.points.len(),
            imu: scan.imu.as_ptr(),
            imu_count: scan.imu.len(),
            has_ground_truth: u32::from(scan.ground_truth_world_from_sensor.is_some()),
            has_imu_from_sensor: u32::from(scan.imu_from_sensor.is_some()),
            ground_truth_world_from_sensor: scan
                .ground_truth_world_from_sensor
                .as_ref()
                .map_or(AbiTransform::IDENTITY, abi_from_pose),
            imu_from_sensor: scan
                .imu_from_sensor
                .as_ref()
                .map_or(AbiTransform::IDENTITY, abi_from_pose),
        };
        let mut out = OdometryResult {
            stamp_nanos: scan.stamp_nanos,
            is_keyframe: 0,
            reserved: 0,
            world_from_sensor: AbiTransform::IDENTITY,
            previous_from_current: AbiTransform::IDENTITY,
            keyframe_points: std::ptr::null(),
            keyframe_count: 0,
        };
        let mut error = ErrorSlot::new();
        // SAFETY: a live handle of this plugin; the scan's buffers and the output are host data valid for
        // the call.
        let status = unsafe {
            (self.fns.register)(self.instance.handle.as_ptr(), &lent, &mut out, error.as_mut_ptr())
        };
        error.result(status).map_err(|error| self.instance.fail(error))?;
        let world_from_sensor =
            pose_from_abi(&out.world_from_sensor).map_err(|reason| self.bad_output(reason))?;
        let previous_from_current =
            pose_from_abi(&out.previous_from_current).map_err(|reason| self.bad_output(reason))?;
        let keyframe = if out.is_keyframe != 0 {
            if out.keyframe_count > scan.points.len()
                || (out.keyframe_count > 0 && out.keyframe_points.is_null())
            {
                return Err(self.bad_output(format!(
                    "a keyframe of {} points at {:p} from a scan of {}",
                    out.keyframe_count,
                    out.keyframe_points,
                    scan.points.len()
                )));
            }
            // SAFETY: the plugin lends `keyframe_count` points until its next call; non-null when non-empty
            // and no larger than the scan it was given, both checked above.
            let points = unsafe { copy_lent(out.keyframe_points, out.keyframe_count) };
            let id = KeyframeId::new(scan.robot.0, self.keyframes);
            self.keyframes += 1;
            Some(Keyframe {
                id,
                stamp_nanos: out.stamp_nanos,
                world_from_sensor,
                cloud: Cloud::new(points),
            })
        } else {
            None
        };
        Ok(OdometryUpdate {
            stamp_nanos: out.stamp_nanos,
            world_from_sensor,
            previous_from_current,
            keyframe,
            degenerate: false,
        })
    }
}
