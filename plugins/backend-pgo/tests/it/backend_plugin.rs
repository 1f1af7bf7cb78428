//! The `pgo` back-end on a two-robot scene: peer alignment, the distributed subgraph, retraction.

use nalgebra::Vector3;
use skid_backend_pgo::{PgoBackend, PgoConfig};
use skid_core::slots::{Backend, LoopClosure, OdometryMeasurement, OptimizeBudget};
use skid_core::{Information, KeyframeId, LoopId, PluginContext, Pose, RobotId};

/// Ground truth: robot 0 drives along x, robot 1 along a parallel line 4 m away, turning slowly.
fn truth(id: KeyframeId) -> Pose {
    let k = f64::from(id.index);
    let r = f64::from(id.robot.0);
    Pose::new(
        Vector3::new(2.0 * k, 4.0 * r + 0.1 * k * r, 0.05 * k),
        Vector3::new(0.0, 0.01 * k, 0.03 * k * (1.0 + r)),
    )
}

/// A backend for robot 0 holding both robots' chains, each in its own odometry frame, with drift.
fn two_robot_backend(config: PgoConfig) -> PgoBackend {
    let context = PluginContext {
        robot: RobotId(0),
        fleet_size: 2,
        ..PluginContext::default()
    };
    let mut backend = PgoBackend::new(config, &context).unwrap();
    let drift = Pose::new(Vector3::new(0.01, 0.005, 0.0), Vector3::new(0.0, 0.0, 0.004));
    for robot in 0..2 {
        let mut estimate = Pose::identity();
        for index in 0..20 {
            let id = KeyframeId::new(robot, index);
            if index > 0 {
                let previous = KeyframeId::new(robot, index - 1);
                let measured = truth(previous).inverse() * truth(id) * drift;
                estimate *= measured;
                backend.add_keyframe(id, estimate).unwrap();
                let odometry = OdometryMeasurement {
                    target: previous,
                    source: id,
                    target_from_source: measured,
                    information: Information::identity() * 400.0,
                };
                backend.add_odometry(odometry).unwrap();
            } else {
                backend.add_keyframe(id, estimate).unwrap();
            }
        }
    }
    backend
}

fn inter_loop(id: u64, a: u32, b: u32) -> LoopClosure {
    let (target, source) = (KeyframeId::new(0, a), KeyframeId::new(1, b));
    LoopClosure {
        id: LoopId(id),
        target,
        source,
        target_from_source: truth(target).inverse() * truth(source),
        information: Information::identity() * 1e4,
    }
}

/// Largest error of the relative pose of robot 0's keyframe `a` and robot 1's keyframe `b`.
fn pair_error_m(backend: &PgoBackend, pairs: &[(u32, u32)]) -> f64 {
    let graph = backend.graph();
    pairs
        .iter()
        .map(|&(a, b)| {
            let (ta, tb) = (KeyframeId::new(0, a), KeyframeId::new(1, b));
            let estimated = graph.pose(ta).unwrap().inverse() * graph.pose(tb).unwrap();
            let expected = truth(ta).inverse() * truth(tb);
            (estimated.inverse() * expected).translation.vector.norm()
        })
        .fold(0.0, f64::max)
}

#[test]
fn peers_are_aligned_and_joined_by_their_odometry() {
    let mut backend = two_robot_backend(PgoConfig::default());
    backend.add_loop(inter_loop(1, 3, 2)).unwrap();
    backend.add_loop(inter_loop(2, 15, 16)).unwrap();
    let report = backend.optimize(OptimizeBudget::default()).unwrap();
    assert!(
        report.converged && report.final_cost <= report.initial_cost,
        "{report:?}"
    );
    // The touched peer keyframes sit where the loops put them relative to their partners (the odometry
    // drift of both robots between the loops leaves a few centimetres), and the untouched ones follow
    // by odometry.
    let touched = pair_error_m(&backend, &[(3, 2), (15, 16)]);
    assert!(touched < 0.1, "touched: {touched} m");
    let untouched = pair_error_m(&backend, &[(3, 3), (15, 17), (0, 0)]);
    assert!(untouched < 0.2, "untouched: {untouched} m");

    // A third loop in the middle, then its retraction restores the two-loop solution.
    let before: Vec<Pose> = (0..20)
        .map(|k| backend.graph().pose(KeyframeId::new(1, k)).unwrap())
        .collect();
    backend.add_loop(inter_loop(3, 9, 9)).unwrap();
    backend.optimize(OptimizeBudget::default()).unwrap();
    assert!(pair_error_m(&backend, &[(9, 9)]) < 0.05);
    backend.remove_loop(LoopId(3)).unwrap();
    backend.optimize(OptimizeBudget::default()).unwrap();
    for (k, pose) in before.iter().enumerate() {
        let now = backend.graph().pose(KeyframeId::new(1, k as u32)).unwrap();
        assert!(
            (pose.inverse() * now).translation.vector.norm() < 1e-4,
            "keyframe {k} moved after the retraction"
        );
    }
    assert_eq!(backend.graph().loops().len(), 2);
}

#[test]
fn centralised_and_distributed_agree_on_the_robots_own_poses() {
    let mut distributed = two_robot_backend(PgoConfig::default());
    let mut centralised = two_robot_backend(PgoConfig {
        distributed: false,
        ..PgoConfig::default()
    });
    for backend in [&mut distributed, &mut centralised] {
        for (id, a, b) in [(1, 3, 2), (2, 15, 16), (3, 9, 9)] {
            backend.add_loop(inter_loop(id, a, b)).unwrap();
        }
        backend.optimize(OptimizeBudget::default()).unwrap();
    }
    // Joining the touched peer keyframes by their composed odometry (covariance to first order) is
    // equivalent for a chain up to second-order terms: the optimum moves by about a millimetre, against
    // corrections of tens of centimetres.
    for k in 0..20 {
        let id = KeyframeId::new(0, k);
        let (a, b) = (
            distributed.graph().pose(id).unwrap(),
            centralised.graph().pose(id).unwrap(),
        );
        let difference = (a.inverse() * b).translation.vector.norm();
        assert!(difference < 5e-3, "keyframe {k}: {difference} m");
    }
}

#[test]
fn bad_input_is_refused() {
    let mut backend = two_robot_backend(PgoConfig::default());
    let mut wrong = inter_loop(1, 3, 2);
    wrong.information[(0, 0)] = -5.0;
    let error = backend.add_loop(wrong).unwrap_err().to_string();
    assert!(error.contains("positive definite"), "{error}");
    let mut nan = inter_loop(2, 3, 2);
    nan.target_from_source.translation.vector.x = f64::NAN;
    assert!(backend.add_loop(nan).is_err());
    let unknown = LoopClosure {
        source: KeyframeId::new(5, 1),
        ..inter_loop(3, 1, 1)
    };
    assert!(
        backend
            .add_loop(unknown)
            .unwrap_err()
            .to_string()
            .contains("unknown")
    );
    backend.add_loop(inter_loop(4, 3, 2)).unwrap();
    assert!(
        backend.add_loop(inter_loop(4, 5, 5)).is_err(),
        "duplicate loop id"
    );
    let backwards = OdometryMeasurement {
        target: KeyframeId::new(0, 5),
        source: KeyframeId::new(0, 4),
        target_from_source: Pose::identity(),
        information: Information::identity(),
    };
    assert!(backend.add_odometry(backwards).is_err());
    assert!(
        backend
            .add_keyframe(
                KeyframeId::new(2, 0),
                Pose::new(Vector3::new(f64::INFINITY, 0.0, 0.0), Vector3::zeros())
            )
            .is_err()
    );
    assert!(backend.optimize(OptimizeBudget::default()).unwrap().converged);
}

/// Robot 0's and robot 1's poses of `backend`, in keyframe order.
fn all_poses(backend: &PgoBackend) -> Vec<Pose> {
    (0..2)
        .flat_map(|robot| (0..20).map(move |k| KeyframeId::new(robot, k)))
        .map(|id| backend.graph().pose(id).unwrap())
        .collect()
}

/// A loop between robot 0's keyframe `a` and robot 1's `b` that is `offset_m` off along y.
fn wrong_loop(id: u64, a: u32, b: u32, offset_m: f64) -> LoopClosure {
    let mut closure = inter_loop(id, a, b);
    closure.target_from_source = Pose::translation(0.0, offset_m, 0.0) * closure.target_from_source;
    closure
}

/// Ten true loops, then three true and two wrong ones.
fn first_and_second_loops() -> (Vec<LoopClosure>, Vec<LoopClosure>) {
    let first: Vec<LoopClosure> = (0..10)
        .map(|k| inter_loop(k, 2 * (k as u32 % 9) + 1, 2 * (k as u32 % 9)))
        .collect();
    let second: Vec<LoopClosure> = [
        inter_loop(20, 4, 5),
        inter_loop(21, 12, 12),
        inter_loop(22, 18, 17),
    ]
    .into_iter()
    .chain([wrong_loop(23, 10, 10, 3.0), wrong_loop(24, 6, 7, -2.5)])
    .collect();
    (first, second)
}

/// Solves `first`, then `second` on top of it; returns the backend and the second solve's report.
fn solved_in_two_steps(
    config: PgoConfig,
    first: &[LoopClosure],
    second: &[LoopClosure],
) -> (PgoBackend, skid_core::slots::OptimizeReport) {
    let mut backend = two_robot_backend(config);
    for closure in first {
        backend.add_loop(closure.clone()).unwrap();
    }
    assert!(backend.optimize(OptimizeBudget::default()).unwrap().converged);
    for closure in second {
        backend.add_loop(closure.clone()).unwrap();
    }
    let report = backend.optimize(OptimizeBudget::default()).unwrap();
    (backend, report)
}

/// Solves every one of `loops` at once, from the odometry; returns the backend and its report.
fn solved_at_once<'a>(
    config: PgoConfig,
    loops: impl IntoIterator<Item = &'a LoopClosure>,
) -> (PgoBackend, skid_core::slots::OptimizeReport) {
    let mut backend = two_robot_backend(config);
    for closure in loops {
        backend.add_loop(closure.clone()).unwrap();
    }
    let report = backend.optimize(OptimizeBudget::default()).unwrap();
    (backend, report)
}

/// Asserts that every pose of `backend` is within a millimetre of `full`'s (`what` names the run).
fn assert_ends_where(backend: &PgoBackend, full: &PgoBackend, what: &str) {
    for (k, (a, b)) in all_poses(backend).iter().zip(all_poses(full)).enumerate() {
        let difference = (a.inverse() * b).translation.vector.norm();
        assert!(
            difference < 1e-3,
            "{what}pose {k}: {difference} m from the full run"
        );
    }
}

#[test]
fn gnc_warm_started_from_the_last_solution_ends_where_a_full_run_does() {
    // The warm path alone: no full run when it rejects a new loop.
    let gnc = || PgoConfig {
        robust: skid_backend_pgo::g2o_file::RobustMode::Gnc,
        full_run_on_rejected_new_loop: false,
        ..PgoConfig::default()
    };
    let (first, second) = first_and_second_loops();
    let mut incremental = two_robot_backend(gnc());
    for closure in &first {
        incremental.add_loop(closure.clone()).unwrap();
    }
    let first_report = incremental.optimize(OptimizeBudget::default()).unwrap();
    assert!(first_report.converged, "{first_report:?}");

    // Nothing new: no solve, and nothing moves.
    let settled = all_poses(&incremental);
    let idle = incremental.optimize(OptimizeBudget::default()).unwrap();
    assert_eq!(idle.iterations, 0, "{idle:?}");
    assert_eq!(all_poses(&incremental), settled);

    // Five new loops, two of them wrong: the warm start rejects those and agrees with a full run from
    // the odometry on every loop at once.
    for closure in &second {
        incremental.add_loop(closure.clone()).unwrap();
    }
    let warm = incremental.optimize(OptimizeBudget::default()).unwrap();
    assert!(warm.converged, "{warm:?}");
    let (full, full_report) = solved_at_once(gnc(), first.iter().chain(&second));
    assert_ends_where(&incremental, &full, "");
    assert!(pair_error_m(&incremental, &[(10, 10), (6, 7), (12, 12)]) < 0.1);
    assert!(
        warm.iterations < full_report.iterations,
        "the warm start does less work than a full run on the same loops: {} against {}",
        warm.iterations,
        full_report.iterations
    );
}

#[test]
fn a_warm_run_that_rejects_a_new_loop_is_settled_again_by_a_full_run() {
    let gnc = |full_run_on_rejected_new_loop| PgoConfig {
        robust: skid_backend_pgo::g2o_file::RobustMode::Gnc,
        full_run_on_rejected_new_loop,
        ..PgoConfig::default()
    };
    let (first, second) = first_and_second_loops();
    let (warm, warm_report) = solved_in_two_steps(gnc(false), &first, &second);
    let (settled, settled_report) = solved_in_two_steps(gnc(true), &first, &second);
    let (full, full_report) = solved_at_once(gnc(true), first.iter().chain(&second));
    // The two wrong loops are rejected by the warm run, so the labels were settled by a full run: the
    // same work as a full run from scratch, where the warm run alone did less.
    assert_eq!(settled.rejected_loops(), vec![LoopId(23), LoopId(24)]);
    assert_eq!(warm.rejected_loops(), vec![LoopId(23), LoopId(24)]);
    assert!(warm_report.iterations < full_report.iterations);
    assert!(
        settled_report.iterations >= full_report.iterations,
        "{settled_report:?}"
    );
    assert_ends_where(&settled, &full, "");
    // With only true new loops, the warm run rejects none and no full run follows.
    let (_, true_only) = solved_in_two_steps(gnc(true), &first, &second[..3]);
    assert!(true_only.iterations < full_report.iterations, "{true_only:?}");
}

#[test]
fn a_warm_run_over_the_new_loops_region_ends_where_a_full_run_does() {
    let gnc = |warm_region_hops| PgoConfig {
        robust: skid_backend_pgo::g2o_file::RobustMode::Gnc,
        warm_region_hops,
        ..PgoConfig::default()
    };
    let first: Vec<LoopClosure> = (0..10)
        .map(|k| inter_loop(k, 2 * (k as u32 % 9) + 1, 2 * (k as u32 % 9)))
        .collect();
    // Three true loops far apart along the chains: each region holds a few keyframes around its ends.
    let second = [
        inter_loop(20, 4, 5),
        inter_loop(21, 12, 12),
        inter_loop(22, 18, 17),
    ];
    let (full, full_report) = solved_at_once(gnc(0), first.iter().chain(&second));
    assert!(full_report.converged);
    for hops in [0, 1, 4] {
        let (incremental, warm) = solved_in_two_steps(gnc(hops), &first, &second);
        assert!(warm.converged, "{hops} hops: {warm:?}");
        assert_ends_where(&incremental, &full, &format!("{hops} hops, "));
    }
}
