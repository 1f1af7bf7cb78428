//! The robot's own track: every scan's odometry pose, its keyframes with their clouds, and what the
//! source delivered. It is what the host knows without any peer, and what the trajectories and the map
//! are rebuilt from at the end of a run.

use std::collections::BTreeMap;
use std::sync::Arc;

use skid_core::slots::DescriptorBuf;
use skid_core::{Keyframe, Pose};

use crate::warn_limit::WarnLimiter;

/// One scan's odometry, remembered so the optimised trajectory can be rebuilt for every scan.
#[derive(Clone, Copy, Debug)]
pub struct ScanRecord {
    pub stamp_nanos: u64,
    pub world_from_sensor: Pose,
    /// The keyframe at or before this scan.
    pub keyframe: Option<u32>,
    pub ground_truth: Option<Pose>,
}

/// The scans and keyframes of one robot, in the order the odometry produced them.
#[derive(Debug, Default)]
pub(crate) struct OwnTrack {
    keyframes: BTreeMap<u32, Arc<Keyframe>>,
    /// The descriptor of each described keyframe, kept for the session the run leaves.
    descriptors: BTreeMap<u32, DescriptorBuf>,
    scans: Vec<ScanRecord>,
    points_read: usize,
    /// Scans read from the source, including those the odometry skipped.
    scans_read: usize,
    /// Scans the odometry refused (too few points, a stamp going backwards, …), counted and warned
    /// about at a limited rate.
    skipped_scans: WarnLimiter,
    /// Registered scans the odometry found degenerate (a direction of the motion left to its prior).
    degenerate_scans: u64,
}

impl OwnTrack {
    /// Counts one scan read from the source, with its point count.
    pub(crate) fn count_read(&mut self, points: usize) {
        self.points_read += points;
        self.scans_read += 1;
    }

    /// Counts one scan the odometry skipped; returns its number when the warning is due.
    pub(crate) fn count_skipped(&mut self) -> Option<u64> {
        self.skipped_scans.occurrence()
    }

    /// Counts one registered scan the odometry found degenerate.
    pub(crate) fn count_degenerate(&mut self) {
        self.degenerate_scans += 1;
    }

    /// Records one registered scan.
    pub(crate) fn push_scan(&mut self, scan: ScanRecord) {
        self.scans.push(scan);
    }

    /// Records one keyframe.
    pub(crate) fn push_keyframe(&mut self, keyframe: Arc<Keyframe>) {
        self.keyframes.insert(keyframe.id.index, keyframe);
    }

    /// Records the descriptor of keyframe `index`.
    pub(crate) fn push_descriptor(&mut self, index: u32, descriptor: DescriptorBuf) {
        self.descriptors.insert(index, descriptor);
    }

    pub(crate) fn descriptors(&self) -> &BTreeMap<u32, DescriptorBuf> {
        &self.descriptors
    }

    pub(crate) fn keyframes(&self) -> &BTreeMap<u32, Arc<Keyframe>> {
        &self.keyframes
    }

    pub(crate) fn keyframe(&self, index: u32) -> Option<&Arc<Keyframe>> {
        self.keyframes.get(&index)
    }

    pub(crate) fn scans(&self) -> &[ScanRecord] {
        &self.scans
    }

    /// The keyframe a new scan belongs to when it is not one itself: the newest one.
    pub(crate) fn current_keyframe(&self) -> Option<u32> {
        self.scans.last().and_then(|scan| scan.keyframe)
    }

    /// The newest registered scan's stamp.
    pub(crate) fn newest_stamp_nanos(&self) -> Option<u64> {
        self.scans.last().map(|scan| scan.stamp_nanos)
    }

    pub(crate) fn points_read(&self) -> usize {
        self.points_read
    }

    pub(crate) fn scans_read(&self) -> usize {
        self.scans_read
    }

    pub(crate) fn scans_skipped(&self) -> u64 {
        self.skipped_scans.count()
    }

    pub(crate) fn degenerate_scans(&self) -> u64 {
        self.degenerate_scans
    }
}
