//! The peer-visibility check: a loop that puts two robots a few metres apart at one moment says that
//! each stood in the other's view, so each one's scan of that moment must show the other's body.
//!
//! Robots are solid. An inter-robot loop between keyframes recorded at (nearly) one time places the
//! source robot's sensor in the target keyframe's frame at that time; when that is within the
//! LiDAR's reach, the target scan's rays towards the source robot should end on its body, not pass on
//! through where it would stand and return from the ground or a wall beyond it. Two robots that start
//! on two identical junctions of a grid see the same place, and their loops, consistent with one
//! another, put them side by side; neither scan holds the other robot, and that refutes the frame. The
//! free-space check ([`crate::free_space`]) cannot: it compares the two scans with each other, and
//! they agree. Mutual observation is the inter-robot cue of Kim et al.'s multi-robot SLAM with
//! robots that detect one another (IROS 2010) and of UWB-ranging fleets; here it is used only to
//! refute, from the scans already at hand.
//!
//! ## Definition
//!
//! The peer's **core** is a box fixed in its sensor frame (`core_centre_m`, `core_half_extents_m`; by
//! default 0.3 × 0.3 × 0.1 m centred 0.3 m under the sensor), small enough to lie inside any carrier's
//! body: a rover's chassis, a quadruped, the person carrying a handheld unit, a multirotor. Where the
//! peer was at the target keyframe's stamp is interpolated between the peer's two keyframes around that
//! stamp (at most `within_s` from it), through the peer's odometry from the loop's source keyframe.
//! Each point of the target cloud is a ray from the sensor; a ray whose line crosses the core either
//! ends before the core's far side plus the margin (`margin_m` + `margin_fraction` · range:
//! **blocked**, by the body or by something in front of it) or beyond it (**through**). The loop is
//! refused when at least `min_rays` rays cross the core and more than `max_through_fraction` of them
//! pass through. A body in the scan lets no ray through its core (the core is inside it), so a few rays
//! through are evidence enough; a keyframe's cloud, thinned to 0.25 m voxels, leaves only a handful of
//! rays in the core's direction at 5–15 m, so the default asks for 3; the check runs both ways (the target robot in the source scan too) and only where the
//! core is `min_range_m` to `max_range_m` from the sensor. Keyframes recorded farther apart in time
//! than `within_s` say nothing about where the other robot was, and are not checked.
//!
//! The same rays also **confirm**: the peer is **sighted** when at least `min_rays` rays towards a box
//! of `sighting_half_extents_m` around the core (by default 0.8 × 0.5 × 0.2 m, inside a ground rover's
//! or a quadruped's body) end on it, within `margin_m` of its faces, and at most
//! `max_sighted_through_fraction` of those reaching it pass through. A ray that ends farther before the
//! box is occluded and says nothing. Sighted loops are positive evidence of a frame where the places
//! alone cannot be told apart ([`crate::repeated`]).
//!
//! The check assumes the robots' stamps share one clock (the fleet's, as everywhere else in SKiD) and
//! that a robot's scans are not cropped around other robots.

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};
use skid_core::slots::{GraphView, LoopClosure};
use skid_core::{KeyframeId, ParamError, Point, Pose};

/// Parameters of the peer-visibility check: `[verifier.pcm.peer_seen]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct PeerSeenConfig {
    pub enabled: bool,
    /// Keyframes of two robots recorded within this many seconds of each other count as one moment.
    pub within_s: f64,
    /// Centre of the peer's body core in its sensor frame (x forward, z up), metres.
    pub core_centre_m: [f64; 3],
    /// Half extents of the core, metres.
    pub core_half_extents_m: [f64; 3],
    /// The core is looked for only this far from the sensor and farther (metres) ...
    pub min_range_m: f64,
    /// ... and up to this far.
    pub max_range_m: f64,
    /// A ray passes through the core when it returns farther than the core's far side by this many
    /// metres plus `margin_fraction` of its range.
    pub margin_m: f64,
    pub margin_fraction: f64,
    /// Fewest rays crossing the core for the check to judge.
    pub min_rays: usize,
    /// Largest fraction of those rays passing through the core that is accepted.
    pub max_through_fraction: f64,
    /// Half extents of the box around the core whose rays confirm a sighting, metres.
    pub sighting_half_extents_m: [f64; 3],
    /// Largest fraction of the rays reaching the sighting box that may pass through it in a sighting.
    pub max_sighted_through_fraction: f64,
}

impl Default for PeerSeenConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            within_s: 1.0,
            core_centre_m: [0.0, 0.0, -0.30],
            core_half_extents_m: [0.15, 0.15, 0.05],
            min_range_m: 1.5,
            max_range_m: 30.0,
            margin_m: 0.3,
            margin_fraction: 0.02,
            min_rays: 3,
            max_through_fraction: 0.8,
            sighting_half_extents_m: [0.4, 0.25, 0.1],
            max_sighted_through_fraction: 0.2,
        }
    }
}

/// What the check counted in one scan: the rays crossing the peer's core.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayCount {
    pub through: usize,
    pub blocked: usize,
}

/// What the rays of the two scans say about where an inter-robot loop puts each robot at one moment.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Sighting {
    /// Not one moment, out of range, too few rays, or the check off: nothing either way.
    Unjudged,
    /// A scan shows the other robot's body where the loop puts it.
    Seen,
    /// A scan shows the place where the loop puts the other robot empty; the reason says how.
    Unseen(String),
}

impl PeerSeenConfig {
    /// Checks that every value is usable; the error is at the offending key.
    pub fn validate(&self) -> Result<(), ParamError> {
        let positive = |value: f64| value.is_finite() && value > 0.0;
        let checks: [(bool, &str, String); 9] = [
            (
                positive(self.within_s),
                "within_s",
                format!("must be positive, got {}", self.within_s),
            ),
            (
                self.core_half_extents_m.iter().all(|&h| positive(h)),
                "core_half_extents_m",
                format!("must all be positive, got {:?}", self.core_half_extents_m),
            ),
            (
                self.core_centre_m.iter().all(|c| c.is_finite()),
                "core_centre_m",
                format!("must be finite, got {:?}", self.core_centre_m),
            ),
            (
                self.min_range_m.is_finite() && self.min_range_m >= 0.0,
                "min_range_m",
                format!("must be at least 0, got {}", self.min_range_m),
            ),
            (
                positive(self.max_range_m) && self.max_range_m > self.min_range_m,
                "max_range_m",
                format!("must exceed min_range_m, got {}", self.max_range_m),
            ),
            (
                self.margin_m.is_finite()
                    && self.margin_m >= 0.0
                    && self.margin_fraction.is_finite()
                    && self.margin_fraction >= 0.0,
                "margin_m",
                format!(
                    "margin_m and margin_fraction must be at least 0, got {} and {}",
                    self.margin_m, self.margin_fraction
                ),
            ),
            (
                (0.0..=1.0).contains(&self.max_through_fraction),
                "max_through_fraction",
                format!("must be in [0, 1], got {}", self.max_through_fraction),
            ),
            (
                self.sighting_half_extents_m.iter().all(|&h| positive(h)),
                "sighting_half_extents_m",
                format!("must all be positive, got {:?}", self.sighting_half_extents_m),
            ),
            (
                (0.0..=1.0).contains(&self.max_sighted_through_fraction),
                "max_sighted_through_fraction",
                format!("must be in [0, 1], got {}", self.max_sighted_through_fraction),
            ),
        ];
        match checks.into_iter().find(|(ok, _, _)| !ok) {
            Some((_, key, message)) => Err(ParamError::at(key, message)),
            None if self.min_rays == 0 => Err(ParamError::at("min_rays", "must be at least 1")),
            None => Ok(()),
        }
    }

    /// `Some(reason)` when `closure`, an inter-robot loop, puts one robot in the other's view at one
    /// moment and that robot's scan (`target` or `source`, in its sensor frame) shows it absent.
    pub fn refusal(
        &self,
        closure: &LoopClosure,
        clouds: (&[Point], &[Point]),
        graph: &dyn GraphView,
    ) -> Option<String> {
        match self.judge(closure, clouds, graph, false) {
            Sighting::Unseen(reason) => Some(reason),
            Sighting::Seen | Sighting::Unjudged => None,
        }
    }

    /// What the two scans say about the loop: the other robot absent from either where the loop puts
    /// it refutes the loop; else, when `confirm` asks for it, its body on either confirms it (a second
    /// pass over the rays, which a caller that reads no sightings does without).
    pub fn judge(
        &self,
        closure: &LoopClosure,
        (target, source): (&[Point], &[Point]),
        graph: &dyn GraphView,
        confirm: bool,
    ) -> Sighting {
        let (target_id, source_id) = (closure.target, closure.source);
        if !self.enabled || target_id.robot == source_id.robot {
            return Sighting::Unjudged;
        }
        let ways = [
            (target_id, source_id, target, closure.target_from_source),
            (source_id, target_id, source, closure.target_from_source.inverse()),
        ];
        let mut seen = false;
        for (seer, seen_id, cloud, seer_from_seen) in ways {
            let Some(seen_sensor) = self.peer_at_stamp(seer, seen_id, &seer_from_seen, graph) else {
                continue;
            };
            let distance_m = seen_sensor.translation.vector.norm();
            if !(self.min_range_m..=self.max_range_m).contains(&distance_m) {
                continue;
            }
            let count = self.count(cloud, &seen_sensor);
            let crossing = count.through + count.blocked;
            if crossing >= self.min_rays && count.through as f64 > self.max_through_fraction * crossing as f64
            {
                return Sighting::Unseen(format!(
                    "peer unseen: the loop puts robot {} {distance_m:.1} m from {seer}'s sensor at that moment, but {} of the {crossing} rays towards it passed through (> {:.0} %)",
                    seen_id.robot,
                    count.through,
                    100.0 * self.max_through_fraction
                ));
            }
            seen = seen || (confirm && self.sighted(cloud, &seen_sensor));
        }
        match seen {
            true => Sighting::Seen,
            false => Sighting::Unjudged,
        }
    }

    /// Whether the rays of `cloud` towards the sighting box of a robot whose sensor is at
    /// `seen_sensor` end on it: at least `min_rays` of them, and at most `max_sighted_through_fraction`
    /// of those reaching it passing through.
    fn sighted(&self, cloud: &[Point], seen_sensor: &Pose) -> bool {
        let (mut on, mut through) = (0usize, 0usize);
        let half = Vector3::from(self.sighting_half_extents_m);
        for (range_m, near_m, far_m) in self.crossings(cloud, seen_sensor, &half) {
            if range_m > far_m + self.margin_m + self.margin_fraction * range_m {
                through += 1;
            } else if range_m >= near_m - self.margin_m - self.margin_fraction * range_m {
                on += 1;
            }
        }
        on >= self.min_rays && through as f64 <= self.max_sighted_through_fraction * (on + through) as f64
    }

    /// The seen robot's sensor pose in the seer keyframe's frame at the seer's stamp, from the loop's
    /// `seer_from_seen` and the seen robot's odometry; `None` when the stamps are unknown or the seen
    /// robot has no keyframe within `within_s` on either side of that stamp.
    fn peer_at_stamp(
        &self,
        seer: KeyframeId,
        seen: KeyframeId,
        seer_from_seen: &Pose,
        graph: &dyn GraphView,
    ) -> Option<Pose> {
        let at_nanos = graph.keyframe_stamp_nanos(seer)?;
        let within_nanos = (self.within_s * 1e9) as u64;
        let stamp = |index: u32| {
            graph.keyframe_stamp_nanos(KeyframeId {
                robot: seen.robot,
                index,
            })
        };
        let seen_stamp = stamp(seen.index)?;
        if seen_stamp.abs_diff(at_nanos) > 8 * within_nanos {
            return None;
        }
        // The seen robot's keyframes just before and just after the stamp, searched from the loop's.
        let mut before = seen.index;
        let mut before_stamp = seen_stamp;
        while before_stamp > at_nanos {
            before = before.checked_sub(1)?;
            before_stamp = stamp(before)?;
        }
        let mut after = before;
        let mut after_stamp = before_stamp;
        while after_stamp < at_nanos {
            after = after.checked_add(1)?;
            after_stamp = stamp(after)?;
        }
        let pose_of = |index: u32| -> Option<Pose> {
            if index == seen.index {
                return Some(Pose::identity());
            }
            let id = KeyframeId {
                robot: seen.robot,
                index,
            };
            graph
                .odometry_between(seen, id)
                .map(|relative| relative.target_from_source)
        };
        let (from, to) = (pose_of(before)?, pose_of(after)?);
        if at_nanos - before_stamp > within_nanos || after_stamp - at_nanos > within_nanos {
            return None;
        }
        let span = after_stamp - before_stamp;
        let fraction = if span == 0 {
            0.0
        } else {
            (at_nanos - before_stamp) as f64 / span as f64
        };
        let between = from.inverse() * to;
        let moved = Pose::from_parts(
            nalgebra::Translation3::from(between.translation.vector * fraction),
            nalgebra::UnitQuaternion::identity().slerp(&between.rotation, fraction),
        );
        Some(seer_from_seen * from * moved)
    }

    /// The rays of `cloud` (points in their sensor's frame) that cross the core of a robot whose sensor
    /// is at `seen_sensor`, split into those that pass through it and those that end before its far
    /// side.
    pub fn count(&self, cloud: &[Point], seen_sensor: &Pose) -> RayCount {
        let mut count = RayCount::default();
        let half = Vector3::from(self.core_half_extents_m);
        for (range_m, _, far_m) in self.crossings(cloud, seen_sensor, &half) {
            if range_m > far_m + self.margin_m + self.margin_fraction * range_m {
                count.through += 1;
            } else {
                count.blocked += 1;
            }
        }
        count
    }

    /// Each ray of `cloud` whose line crosses the box of `half` extents centred on the core of a robot
    /// whose sensor is at `seen_sensor`: its range and where it enters and leaves the box, metres.
    fn crossings<'a>(
        &'a self,
        cloud: &'a [Point],
        seen_sensor: &Pose,
        half: &'a Vector3<f64>,
    ) -> impl Iterator<Item = (f64, f64, f64)> + 'a {
        let [cx, cy, cz] = self.core_centre_m;
        let centre = seen_sensor * Point3::new(cx, cy, cz);
        let box_from_sensor = seen_sensor.rotation.inverse();
        let origin = box_from_sensor * (Point3::origin() - centre);
        cloud.iter().filter_map(move |point| {
            let p = Vector3::new(f64::from(point.x), f64::from(point.y), f64::from(point.z));
            let range_m = p.norm();
            if !range_m.is_finite() || range_m < self.min_range_m {
                return None;
            }
            let direction = box_from_sensor * (p / range_m);
            let (near_m, far_m) = crossing(&origin, &direction, half)?;
            Some((range_m, near_m, far_m))
        })
    }
}

/// Where the ray from `origin` along `direction` enters and leaves the box `[-half, half]`, if it
/// crosses it ahead.
fn crossing(origin: &Vector3<f64>, direction: &Vector3<f64>, half: &Vector3<f64>) -> Option<(f64, f64)> {
    let (mut near, mut far) = (0.0f64, f64::INFINITY);
    for axis in 0..3 {
        let (o, d, h) = (origin[axis], direction[axis], half[axis]);
        if d.abs() < 1e-12 {
            if o.abs() > h {
                return None;
            }
            continue;
        }
        let (a, b) = ((-h - o) / d, (h - o) / d);
        near = near.max(a.min(b));
        far = far.min(a.max(b));
    }
    (near <= far).then_some((near, far))
}

#[cfg(test)]
mod tests;
