//! Conformance of back-ends (a drifting square closed by one loop) and [`ChainGraph`], a plain
//! [`GraphView`] over per-robot odometry chains that verifier suites run against.

use nalgebra::Vector3;
use skid_core::slots::{Backend, GraphView, LoopClosure, OdometryMeasurement, OptimizeBudget, RelativePose};
use skid_core::{Information, KeyframeId, LoopId, Pose};
use skid_geometry::OdometryChains;

use crate::pose_error;
use crate::scene::planar_pose;

/// A plain [`GraphView`]: per-robot odometry chains (from `skid-geometry`) and a list of loops.
#[derive(Clone, Debug, Default)]
pub struct ChainGraph {
    chains: OdometryChains,
    loops: Vec<LoopClosure>,
}

impl ChainGraph {
    /// Appends keyframe `id` at `world_from_sensor`, with the covariance of the step from the previous one.
    pub fn push(&mut self, id: KeyframeId, world_from_sensor: Pose, step_covariance: Information) {
        self.chains.insert(id, world_from_sensor, step_covariance);
    }

    /// Records an accepted loop.
    pub fn add_loop(&mut self, closure: LoopClosure) {
        self.loops.push(closure);
    }
}

impl GraphView for ChainGraph {
    fn pose(&self, id: KeyframeId) -> Option<Pose> {
        self.chains.pose(id)
    }

    fn odometry_between(&self, target: KeyframeId, source: KeyframeId) -> Option<RelativePose> {
        self.chains.between(target, source)
    }

    fn keyframes(&self) -> Vec<KeyframeId> {
        self.chains.keyframes()
    }

    fn loops(&self) -> Vec<LoopClosure> {
        self.loops.clone()
    }
}

/// Ground truth of the square: 40 keyframes, 10 per 10 m side, ending where it began.
pub fn square_truth(index: u32) -> Pose {
    let side = index / 10;
    let along = f64::from(index % 10);
    let (x, y, yaw) = match side {
        0 => (along, 0.0, 0.0),
        1 => (10.0, along, 90.0),
        2 => (10.0 - along, 10.0, 180.0),
        _ => (0.0, 10.0 - along, 270.0),
    };
    planar_pose(x, y, 0.0, f64::to_radians(yaw))
}

/// Runs the back-end contract on `backend`.
pub fn check_backend(backend: &mut dyn Backend) {
    let odometry_information = Information::identity() * 100.0;
    let drift = Pose::new(
        Vector3::new(0.02, 0.0, 0.0),
        Vector3::new(0.0, 0.0, 0.5f64.to_radians()),
    );
    let mut estimate = Pose::identity();
    let count = 40;
    for index in 0..count {
        let id = KeyframeId::new(0, index);
        if index > 0 {
            let truth_step = square_truth(index - 1).inverse() * square_truth(index);
            let measured = truth_step * drift;
            estimate *= measured;
            backend.add_keyframe(id, estimate).expect("add keyframe");
            let measurement = OdometryMeasurement {
                target: KeyframeId::new(0, index - 1),
                source: id,
                target_from_source: measured,
                information: odometry_information,
            };
            backend.add_odometry(measurement).expect("add odometry");
        } else {
            backend.add_keyframe(id, estimate).expect("add keyframe");
        }
    }
    assert!(
        backend
            .add_keyframe(KeyframeId::new(0, 0), Pose::identity())
            .is_err(),
        "a keyframe cannot be added twice"
    );
    let dangling = OdometryMeasurement {
        target: KeyframeId::new(0, 100),
        source: KeyframeId::new(0, 101),
        target_from_source: Pose::identity(),
        information: odometry_information,
    };
    assert!(
        backend.add_odometry(dangling).is_err(),
        "odometry between unknown keyframes is an error"
    );

    let last = KeyframeId::new(0, count - 1);
    backend
        .optimize(OptimizeBudget::default())
        .expect("optimise the chain");
    let before = backend.graph().pose(last).expect("last pose");
    let (drift_error_m, _) = pose_error(&square_truth(count - 1), &before);

    let closure = LoopClosure {
        id: LoopId(1),
        target: KeyframeId::new(0, 0),
        source: last,
        target_from_source: square_truth(0).inverse() * square_truth(count - 1),
        information: Information::identity() * 1000.0,
    };
    backend.add_loop(closure).expect("add loop");
    let report = backend
        .optimize(OptimizeBudget::default())
        .expect("optimise with the loop");
    assert!(
        report.final_cost.is_finite() && report.final_cost <= report.initial_cost + 1e-9,
        "cost does not increase"
    );
    let after = backend.graph().pose(last).expect("last pose");
    let (closed_error_m, _) = pose_error(&square_truth(count - 1), &after);
    assert!(
        closed_error_m < drift_error_m * 0.25,
        "the loop pulls the end in: {drift_error_m:.3} m -> {closed_error_m:.3} m"
    );
    assert_eq!(backend.graph().loops().len(), 1);

    backend.remove_loop(LoopId(1)).expect("remove loop");
    assert!(
        backend.remove_loop(LoopId(1)).is_err(),
        "removing an unknown loop is an error"
    );
    backend
        .optimize(OptimizeBudget::default())
        .expect("optimise without the loop");
    let restored = backend.graph().pose(last).expect("last pose");
    let (restored_difference_m, _) = pose_error(&before, &restored);
    assert!(
        restored_difference_m < 1e-3,
        "removing the loop restores the odometry solution ({restored_difference_m} m)"
    );

    // Priors at both ends of the square, where the ground truth puts them, pull the drifted chain in as
    // the loop did; a prior on a keyframe the graph lacks is refused.
    let tight = Information::identity() * 1e4;
    assert!(
        backend
            .add_prior(KeyframeId::new(0, 500), Pose::identity(), tight)
            .is_err(),
        "a prior on an unknown keyframe is an error"
    );
    for index in [0, count - 1] {
        backend
            .add_prior(KeyframeId::new(0, index), square_truth(index), tight)
            .expect("add prior");
    }
    backend
        .optimize(OptimizeBudget::default())
        .expect("optimise with the priors");
    let anchored = backend.graph().pose(last).expect("last pose");
    let (anchored_error_m, _) = pose_error(&square_truth(count - 1), &anchored);
    assert!(
        anchored_error_m < 0.05 && anchored_error_m < drift_error_m * 0.25,
        "the priors hold the end where it is: {drift_error_m:.3} m -> {anchored_error_m:.3} m"
    );
}
