//! Conformance of verifiers: among consistent inter-robot loops, one loop whose measurement is 8 m off is
//! rejected (or retracted), and every consistent loop ends up accepted.

use std::collections::BTreeSet;

use nalgebra::Vector3;
use skid_core::slots::{LoopCandidate, LoopClosure, Verifier};
use skid_core::{Information, KeyframeId, LoopId, Pose};

use crate::backend::ChainGraph;
use crate::scene::{Scene, planar_pose};

/// Robot `robot`'s ground-truth keyframe `index`: two robots driving side by side, 3 m apart.
fn truth(robot: u32, index: u32) -> Pose {
    planar_pose(
        f64::from(index) * 3.0,
        f64::from(robot) * 3.0,
        1.8,
        0.05 * f64::from(index),
    )
}

/// Runs the verifier contract on `verifier`.
pub fn check_verifier(verifier: &mut dyn Verifier) {
    let scene = Scene::new(5, 120.0);
    let mut graph = ChainGraph::default();
    let step_covariance = Information::identity() * 1e-4;
    for robot in 0..2 {
        // Each robot's odometry frame starts at its own first keyframe.
        let origin = truth(robot, 0).inverse();
        for index in 0..12 {
            graph.push(
                KeyframeId::new(robot, index),
                origin * truth(robot, index),
                step_covariance,
            );
        }
    }
    let mut accepted = BTreeSet::new();
    let mut loop_id = 0;
    let outlier = LoopId(100);
    let mut submissions: Vec<(LoopId, KeyframeId, KeyframeId, Pose)> = Vec::new();
    for index in 0..10u32 {
        let (target, source) = (KeyframeId::new(0, index), KeyframeId::new(1, index));
        loop_id += 1;
        submissions.push((
            LoopId(loop_id),
            target,
            source,
            truth(0, index).inverse() * truth(1, index),
        ));
        if index == 3 {
            let (target, source) = (KeyframeId::new(0, 9), KeyframeId::new(1, 2));
            let wrong = truth(0, 9).inverse()
                * truth(1, 2)
                * Pose::new(Vector3::new(8.0, -3.0, 0.0), Vector3::new(0.0, 0.0, 0.3));
            submissions.push((outlier, target, source, wrong));
        }
    }
    for (id, target, source, measured) in submissions {
        let target_cloud = scene.sample(&truth(target.robot.0, target.index), 15_000, 50.0, id.0 * 2);
        let source_cloud = scene.sample(&truth(source.robot.0, source.index), 15_000, 50.0, id.0 * 2 + 1);
        let closure = LoopClosure {
            id,
            target,
            source,
            target_from_source: measured,
            information: Information::identity() * 100.0,
        };
        let candidate = LoopCandidate {
            closure: closure.clone(),
            target_cloud: target_cloud.view(),
            source_cloud: source_cloud.view(),
        };
        let verdict = verifier.submit(&candidate, &graph).expect("submit");
        for id in &verdict.retracted {
            accepted.remove(id);
        }
        for id in &verdict.accepted {
            accepted.insert(*id);
        }
    }
    assert!(
        !accepted.contains(&outlier),
        "the inconsistent loop is rejected: accepted {accepted:?}"
    );
    for id in 1..=10 {
        assert!(
            accepted.contains(&LoopId(id)),
            "consistent loop {id} is accepted: accepted {accepted:?}"
        );
    }
}
