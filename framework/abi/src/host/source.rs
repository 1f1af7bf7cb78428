//! A dynamic source plugin seen through skid-core's [`Source`] trait, and its registry entry.
//!
//! The scan a source lends is copied into a host [`Scan`] after checks: a plausible point count (a lying
//! length would otherwise read far past the plugin's buffer), rigid transforms, and sequence numbers
//! that count up from 0.

use skid_core::slots::Source;
use skid_core::{Params, PluginContext, PluginEntry, PluginError, PluginResult, RobotId, Scan};

use super::call::{ErrorSlot, copy_lent};
use super::instance::{Instance, registry_entry};
use super::library::{PluginSpec, SourceFns};
use crate::ffi::{AbiScan, AbiTransform, SourceInfo};
use crate::transform::pose_from_abi;

/// More points than any LiDAR sweep has (a 128-beam sensor gives about 300 000); a larger count is a lie.
const MAX_SCAN_POINTS: usize = 20_000_000;
/// More IMU samples than a scan period can hold at any real rate.
const MAX_SCAN_IMU_SAMPLES: usize = 1_000_000;

/// The registry entry of a loaded source plugin.
pub(super) fn entry(plugin: &'static PluginSpec, fns: SourceFns) -> PluginEntry<dyn Source> {
    registry_entry(plugin, fns.create, fns.destroy, move |params, context| {
        DynSource::create(plugin, fns, params, context).map(|plugin| Box::new(plugin) as Box<dyn Source>)
    })
}

/// An instance of a dynamically loaded source plugin. After a panic it refuses further calls.
pub struct DynSource {
    instance: Instance,
    fns: SourceFns,
    info: SourceInfo,
    robot: RobotId,
    next_sequence: u32,
}

impl DynSource {
    pub(super) fn create(
        plugin: &'static PluginSpec,
        fns: SourceFns,
        params: &Params,
        context: &PluginContext,
    ) -> PluginResult<Self> {
        let mut source = Self {
            instance: Instance::create(plugin, fns.create, fns.destroy, params, context)?,
            fns,
            info: SourceInfo::default(),
            robot: context.robot,
            next_sequence: 0,
        };
        let mut info = SourceInfo::default();
        let mut error = ErrorSlot::new();
        let _serial = plugin.serialise();
        // SAFETY: a live handle of this plugin and a host-owned output.
        let status = unsafe { (fns.info)(source.instance.handle.as_ptr(), &mut info, error.as_mut_ptr()) };
        error
            .result(status)
            .map_err(|error| source.instance.fail(error))?;
        source.info = info;
        Ok(source)
    }

    fn bad_output(&self, message: String) -> PluginError {
        self.instance.bad_output(format!("next_scan: {message}"))
    }

    /// Copies a lent scan after checking it.
    fn copy_scan(&self, lent: &AbiScan) -> PluginResult<Scan> {
        if lent.point_count > MAX_SCAN_POINTS || lent.imu_count > MAX_SCAN_IMU_SAMPLES {
            return Err(self.bad_output(format!(
                "a scan of {} points and {} IMU samples is implausible (at most {MAX_SCAN_POINTS} and \
                 {MAX_SCAN_IMU_SAMPLES}); refusing to read it",
                lent.point_count, lent.imu_count
            )));
        }
        if (lent.point_count > 0 && lent.points.is_null()) || (lent.imu_count > 0 && lent.imu.is_null()) {
            return Err(self.bad_output("a non-empty buffer at a null pointer".to_owned()));
        }
        if lent.robot != self.robot.0 || lent.sequence != self.next_sequence {
            return Err(self.bad_output(format!(
                "scan {} of robot {} where scan {} of robot {} was due",
                lent.sequence, lent.robot, self.next_sequence, self.robot.0
            )));
        }
        let transform = |present: u32, value: &AbiTransform| {
            (present != 0)
                .then(|| pose_from_abi(value))
                .transpose()
                .map_err(|reason| self.bad_output(reason))
        };
        Ok(Scan {
            robot: self.robot,
            sequence: lent.sequence,
            stamp_nanos: lent.stamp_nanos,
            // SAFETY: the plugin lends these buffers until its next call; non-null when non-empty and
            // within the plausible bounds, both checked above.
            points: unsafe { copy_lent(lent.points, lent.point_count) },
            // SAFETY: as above.
            imu: unsafe { copy_lent(lent.imu, lent.imu_count) },
            ground_truth_world_from_sensor: transform(
                lent.has_ground_truth,
                &lent.ground_truth_world_from_sensor,
            )?,
            imu_from_sensor: transform(lent.has_imu_from_sensor, &lent.imu_from_sensor)?,
        })
    }
}

impl Source for DynSource {
    fn next_scan(&mut self) -> PluginResult<Option<Scan>> {
        let _serial = self.instance.enter()?;
        let mut lent = AbiScan {
            robot: 0,
            sequence: 0,
            stamp_nanos: 0,
            points: std::ptr::null(),
            point_count: 0,
            imu: std::ptr::null(),
            imu_count: 0,
            has_ground_truth: 0,
            has_imu_from_sensor: 0,
            ground_truth_world_from_sensor: AbiTransform::IDENTITY,
            imu_from_sensor: AbiTransform::IDENTITY,
        };
        let mut has_scan = 0_u32;
        let mut error = ErrorSlot::new();
        // SAFETY: a live handle of this plugin and host-owned outputs valid for the call.
        let status = unsafe {
            (self.fns.next_scan)(
                self.instance.handle.as_ptr(),
                &mut lent,
                &mut has_scan,
                error.as_mut_ptr(),
            )
        };
        error.result(status).map_err(|error| self.instance.fail(error))?;
        if has_scan == 0 {
            return Ok(None);
        }
        let scan = self.copy_scan(&lent)?;
        self.next_sequence += 1;
        Ok(Some(scan))
    }

    fn provides_imu(&self) -> bool {
        self.info.provides_imu != 0
    }

    fn remaining_hint(&self) -> Option<usize> {
        (self.info.knows_remaining != 0)
            .then(|| usize::try_from(self.info.remaining_scans).unwrap_or(usize::MAX))
    }
}
