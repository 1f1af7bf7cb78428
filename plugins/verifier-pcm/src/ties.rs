//! How far a keyframe lies, along its robot's estimated route, from the nearest keyframe of the same
//! robot that an inter-robot loop in the graph ties to another robot.
//!
//! A frame through a third robot ([`skid_core::slots::GraphView::frames_through_others`]) is one rigid
//! transform, fixed where the robots' loops are. Away from those places the robots' odometry drifts
//! apart, and the frame's error at a loop's place grows with the route travelled from the nearest tie
//! on either robot: on COSMO-Bench's real problems (LOAM odometry) two robots' true loops 1.1 km of
//! route from their nearest ties sit 6–10 m from the frame through the third robot, 0.5–0.9 % of that
//! route, where real LiDAR(-inertial) odometry drifts 0.3–1 % of the path. The cycle test
//! ([`crate::earned`]) allows for that drift before it calls a set contradicted.

use std::collections::BTreeMap;

use skid_core::slots::GraphView;
use skid_core::{KeyframeId, RobotId};

/// One robot's route: the path length travelled up to each keyframe, and the path lengths at its tied
/// keyframes, ascending.
#[derive(Debug, Default)]
struct Route {
    travelled_m: BTreeMap<u32, f64>,
    tied_m: Vec<f64>,
}

/// The routes of the robots a cycle test asks about, with their ties.
#[derive(Debug, Default)]
pub(crate) struct Ties {
    routes: BTreeMap<RobotId, Route>,
}

impl Ties {
    /// Measures the routes of `robots` along the graph's estimate (keyframes without an estimate are
    /// skipped) and finds their keyframes that inter-robot loops in the graph join.
    pub(crate) fn of(graph: &dyn GraphView, robots: &[RobotId]) -> Self {
        let mut routes: BTreeMap<RobotId, Route> =
            robots.iter().map(|&robot| (robot, Route::default())).collect();
        let mut chains: BTreeMap<RobotId, Vec<KeyframeId>> = BTreeMap::new();
        for id in graph.keyframes() {
            if routes.contains_key(&id.robot) {
                chains.entry(id.robot).or_default().push(id);
            }
        }
        for (robot, mut chain) in chains {
            chain.sort_by_key(|id| id.index);
            let Some(route) = routes.get_mut(&robot) else {
                continue;
            };
            let mut travelled_m = 0.0;
            let mut last: Option<nalgebra::Vector3<f64>> = None;
            for id in chain {
                let Some(pose) = graph.pose(id) else {
                    continue;
                };
                if let Some(last) = last {
                    travelled_m += (pose.translation.vector - last).norm();
                }
                last = Some(pose.translation.vector);
                route.travelled_m.insert(id.index, travelled_m);
            }
        }
        for closure in graph.loops() {
            if closure.target.robot == closure.source.robot {
                continue;
            }
            for end in [closure.target, closure.source] {
                if let Some(route) = routes.get_mut(&end.robot)
                    && let Some(&at_m) = route.travelled_m.get(&end.index)
                {
                    route.tied_m.push(at_m);
                }
            }
        }
        for route in routes.values_mut() {
            route.tied_m.sort_by(f64::total_cmp);
        }
        Self { routes }
    }

    /// The path length from `id` to the nearest tied keyframe of its robot; `None` when `id` has no
    /// estimate or its robot no tie.
    pub(crate) fn distance_m(&self, id: KeyframeId) -> Option<f64> {
        let route = self.routes.get(&id.robot)?;
        let here_m = *route.travelled_m.get(&id.index)?;
        let after = route.tied_m.partition_point(|&tied_m| tied_m < here_m);
        let next = route.tied_m.get(after).map(|tied_m| tied_m - here_m);
        let previous = after
            .checked_sub(1)
            .and_then(|before| route.tied_m.get(before))
            .map(|tied_m| here_m - tied_m);
        match (previous, next) {
            (Some(x), Some(y)) => Some(x.min(y)),
            (x, y) => x.or(y),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skid_core::slots::LoopClosure;
    use skid_core::{Information, LoopId, Pose};
    use skid_testkit::backend::ChainGraph;

    /// Two straight routes along x, 10 m between keyframes 0–19, and the loops given.
    fn straight(loops: &[(KeyframeId, KeyframeId)]) -> ChainGraph {
        let mut graph = ChainGraph::default();
        for robot in 0..2 {
            for index in 0..20 {
                let pose = Pose::translation(10.0 * f64::from(index), f64::from(robot), 0.0);
                graph.push(KeyframeId::new(robot, index), pose, Information::identity());
            }
        }
        for &(target, source) in loops {
            graph.add_loop(LoopClosure {
                id: LoopId(0),
                target,
                source,
                target_from_source: Pose::identity(),
                information: Information::identity(),
            });
        }
        graph
    }

    #[test]
    fn the_distance_is_along_the_route_to_the_nearest_inter_robot_tie() {
        let kf = KeyframeId::new;
        let graph = straight(&[
            (kf(0, 3), kf(1, 15)),
            (kf(0, 12), kf(1, 2)),
            // An intra-robot loop ties nothing.
            (kf(0, 18), kf(0, 1)),
        ]);
        let ties = Ties::of(&graph, &[RobotId(0), RobotId(1)]);
        let near = |distance: Option<f64>, expected: f64| {
            assert!(
                distance.is_some_and(|d| (d - expected).abs() < 1e-9),
                "{distance:?} vs {expected}"
            );
        };
        near(ties.distance_m(kf(0, 3)), 0.0);
        near(ties.distance_m(kf(0, 0)), 30.0);
        near(ties.distance_m(kf(0, 7)), 40.0);
        near(ties.distance_m(kf(0, 19)), 70.0);
        near(ties.distance_m(kf(1, 9)), 60.0);
        assert_eq!(ties.distance_m(kf(0, 25)), None, "no estimate");
        let untied = straight(&[]);
        assert_eq!(Ties::of(&untied, &[RobotId(0)]).distance_m(kf(0, 3)), None);
        assert_eq!(ties.distance_m(kf(2, 3)), None, "a robot not asked about");
    }
}
