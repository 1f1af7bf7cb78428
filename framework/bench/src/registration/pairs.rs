//! Simulated scan pairs for the registration tables, built the way robots meet in the field (the
//! SKiD-SLAM paper's Table II and its yaw figure): along one route through a `skid-sim` world, a target
//! scan every `anchor_spacing_m` and, per pair kind, a source scan
//! - `same_direction`: further along the route, driving the same way;
//! - `reverse`: from a second robot driving the route the other way (a real reverse traverse: it keeps
//!   to its own side of the route, so its viewpoint differs; a scan turned by 180° would be the same
//!   problem as `same_direction` for rotation-invariant features);
//! - `random_yaw`: further along, the sensor turned by a random yaw about its own axis (the paper's
//!   "pose discrepancy" between robots driving in different directions);
//! - `partial`: far enough along that the scans only partly overlap.
//!
//! Scans are taken at rest (as deskewed keyframes are) with the simulator's default noise.

use anyhow::{Result, bail};
use nalgebra::{UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use skid_core::{Cloud, Pose};
use skid_sim::motion::{MotionSpec, trajectory};
use skid_sim::{ScanNoise, Sensor, Trajectory, World, WorldKind, plan_route, simulate_sweep};

/// How the source scan of a pair relates to its target.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PairKind {
    SameDirection,
    Reverse,
    RandomYaw,
    Partial,
}

impl PairKind {
    pub const ALL: [PairKind; 4] = [
        PairKind::SameDirection,
        PairKind::Reverse,
        PairKind::RandomYaw,
        PairKind::Partial,
    ];

    /// A short label for tables.
    pub fn label(self) -> &'static str {
        match self {
            PairKind::SameDirection => "same direction",
            PairKind::Reverse => "reverse traverse",
            PairKind::RandomYaw => "random yaw",
            PairKind::Partial => "partial overlap",
        }
    }
}

/// Distances along the route between a pair's scans, per kind.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PairGeometry {
    pub same_direction_m: f64,
    pub reverse_m: f64,
    pub random_yaw_m: f64,
    pub partial_m: f64,
    /// Route distance between consecutive targets.
    pub anchor_spacing_m: f64,
}

impl Default for PairGeometry {
    fn default() -> Self {
        Self {
            same_direction_m: 10.0,
            reverse_m: 10.0,
            random_yaw_m: 6.0,
            partial_m: 25.0,
            anchor_spacing_m: 45.0,
        }
    }
}

impl PairGeometry {
    fn gap_m(&self, kind: PairKind) -> f64 {
        match kind {
            PairKind::SameDirection => self.same_direction_m,
            PairKind::Reverse => self.reverse_m,
            PairKind::RandomYaw => self.random_yaw_m,
            PairKind::Partial => self.partial_m,
        }
    }
}

/// A simulated scan pair: target, source and the true `target_from_source`.
pub struct SimPair {
    pub kind: PairKind,
    /// Which target (anchor) along the route the pair belongs to.
    pub anchor: usize,
    pub target: Cloud,
    pub source: Cloud,
    pub truth: Pose,
}

/// Poses along `path` at least a metre apart, so an index difference is a distance along the route.
fn poses_every_metre(path: &Trajectory) -> Vec<Pose> {
    let mut along: Vec<Pose> = Vec::new();
    let mut t = path.start_s();
    while t <= path.end_s() {
        let pose = path.pose_at(t);
        if along
            .last()
            .is_none_or(|last| (pose.translation.vector - last.translation.vector).norm() >= 1.0)
        {
            along.push(pose);
        }
        t += 0.02;
    }
    along
}

/// The pose of `path` nearest `place` horizontally.
fn nearest_pose(path: &[Pose], place: &Pose) -> Option<Pose> {
    let horizontal = |pose: &Pose| {
        let d = pose.translation.vector - place.translation.vector;
        d.x.hypot(d.y)
    };
    path.iter()
        .min_by(|a, b| horizontal(a).total_cmp(&horizontal(b)))
        .copied()
}

/// A fixed pseudo-random number in [0, 1) for `index` and `salt`.
pub fn unit_hash(index: usize, salt: u64) -> f64 {
    let h = (index as u64 + 1).wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ salt.wrapping_mul(0xbf58_476d_1ce4_e5b9);
    let h = (h ^ (h >> 31)).wrapping_mul(0x94d0_49bb_1331_11eb);
    (h >> 11) as f64 / (1u64 << 53) as f64
}

/// A route through a world with poses every metre in both directions, from which scan pairs are cut.
pub struct RouteSampler {
    world: std::sync::Arc<World>,
    sensor: Sensor,
    seed: u64,
    /// Poses every metre driving the route forwards ...
    forward: Vec<Pose>,
    /// ... and driving it backwards (keeping to the other side).
    backward: Vec<Pose>,
}

impl RouteSampler {
    /// Robot 0's route of about `route_m` in the world of `kind` and `seed`, seen by `sensor`.
    pub fn new(kind: WorldKind, sensor: &str, route_m: f64, seed: u64) -> Result<Self> {
        let world = World::shared(kind, seed);
        let sensor = Sensor::by_name(sensor)?;
        let route = plan_route(&world, seed, 0, route_m.clamp(50.0, 5000.0));
        let spec = MotionSpec {
            keep_right_m: MotionSpec::default_keep_right_m(kind),
            ..MotionSpec::default()
        };
        let forward = poses_every_metre(&trajectory(&world, &route, &spec));
        let backward = poses_every_metre(&trajectory(&world, &route.reversed(world.graph()), &spec));
        Ok(Self {
            world,
            sensor,
            seed,
            forward,
            backward,
        })
    }

    /// The pose `index` metres along the route, driving forwards.
    pub fn target_pose(&self, index: usize) -> Option<Pose> {
        self.forward.get(index).copied()
    }

    /// The pose of a pair's source `gap_m` further along from `index`, as `kind` places it; for
    /// `RandomYaw` the sensor is turned by `yaw_rad` about its own axis.
    pub fn source_pose(&self, kind: PairKind, index: usize, gap_m: f64, yaw_rad: f64) -> Option<Pose> {
        let ahead = *self.forward.get(index + gap_m.round() as usize)?;
        match kind {
            PairKind::SameDirection | PairKind::Partial => Some(ahead),
            PairKind::Reverse => nearest_pose(&self.backward, &ahead),
            PairKind::RandomYaw => Some(ahead * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_rad)),
        }
    }

    /// A scan taken at rest at `pose`, its noise drawn from `key`.
    pub fn scan(&self, pose: Pose, key: u64) -> Cloud {
        let points = simulate_sweep(
            &self.world,
            &self.sensor,
            &move |_| pose,
            0.0,
            &ScanNoise::default(),
            key,
            true,
        );
        Cloud::new(points.iter().map(|p| p.point()).collect())
    }

    pub fn seed(&self) -> u64 {
        self.seed
    }
}

/// `per_kind` pairs of each of `kinds` from the world of `kind` and `seed`, seen by `sensor`.
pub fn sim_pairs(
    kind: WorldKind,
    sensor: &str,
    per_kind: usize,
    seed: u64,
    kinds: &[PairKind],
    geometry: &PairGeometry,
) -> Result<Vec<SimPair>> {
    if kinds.is_empty() || per_kind == 0 {
        bail!("no pairs asked for: give at least one pair kind and one pair per kind");
    }
    let longest_gap_m = kinds.iter().map(|k| geometry.gap_m(*k)).fold(0.0, f64::max);
    let route_m = geometry.anchor_spacing_m * per_kind as f64 + longest_gap_m + 60.0;
    let sampler = RouteSampler::new(kind, sensor, route_m, seed)?;
    let mut pairs = Vec::new();
    for anchor in 0..per_kind {
        let target_index = 20 + (geometry.anchor_spacing_m as usize) * anchor;
        let Some(target_pose) = sampler.target_pose(target_index) else {
            break;
        };
        let target_key = seed ^ ((anchor as u64) << 8);
        let target = sampler.scan(target_pose, target_key);
        for (k, &pair_kind) in kinds.iter().enumerate() {
            let yaw = std::f64::consts::TAU * unit_hash(anchor, seed ^ 0x7a3);
            let Some(source_pose) =
                sampler.source_pose(pair_kind, target_index, geometry.gap_m(pair_kind), yaw)
            else {
                continue;
            };
            pairs.push(SimPair {
                kind: pair_kind,
                anchor,
                source: sampler.scan(source_pose, target_key ^ (0xabcd + k as u64)),
                target: target.clone(),
                truth: target_pose.inverse() * source_pose,
            });
        }
    }
    Ok(pairs)
}
