//! Missions: what every robot of a fleet drives, planned together on a world's road graph from a seed,
//! so robots start apart, explore their own part of the world and meet the way field teams meet —
//! crossing at a junction, driving another robot's path the other way, sharing part of a route — or
//! never meet at all. The α/β metric of the SKiD-SLAM paper then measures what the paper measures: how
//! well robots that met are placed in each other's frame.
//!
//! Every mission is deterministic in (world, seed, fleet size, route length). Routes follow junction
//! paths on the graph (shortest paths where a robot travels with a purpose, least-used walks where it
//! explores); [`Mission::SharedRoute`] keeps the older patterns around one base walk ([`plan_route`]).

use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::SimError;
use crate::rng::{Rng, combine};
use crate::route::{
    Route, Steps, centre_line_of, distances_from, path_to, plan_route, reversed, walk, walk_penalised,
};
use crate::world::{RoadGraph, World};

/// The named missions (`[source.sim] mission = "..."`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Mission {
    /// Robots start apart around a central junction, explore their own sector on the way to it, cross
    /// there from different directions, then each drives the next robot's sector the other way: every
    /// pair of robots meets twice, once crossing and once on a reverse traverse.
    ExploreMeet,
    /// Robots start apart, converge on one junction and drive back home: one meeting, at one place.
    Rendezvous,
    /// Every robot drives straight through a central junction along its own axis, the axes spread
    /// around it: each meets the others only where the paths cross, at an angle.
    Crossing,
    /// Robot 0 drives a route, robot 1 the same route backwards (keeping to its own side), and so on
    /// alternately.
    Reverse,
    /// Robot 0 drives a route; the others join its middle from elsewhere, share a stretch of it, then
    /// leave it for roads robot 0 never takes.
    Partial,
    /// `explore_meet` for every robot but the last, which starts at the far end of the world and
    /// explores there: it never meets the others.
    Loner,
    /// Every robot relates to one base walk (leader, reverse, same direction, partial, crossing, far
    /// start; see [`crate::Overlap`]); the robots share one route's roads.
    SharedRoute,
    /// Robots deployed from one base drive one route in the same direction, [`CONVOY_GAP_M`] apart:
    /// each passes where the robot ahead was a short while before, from the first minute to the last.
    /// Their inter-robot loops come at a steady rate, which is what a long mission needs to show whether
    /// the cost of handling them grows with the mission.
    Convoy,
    /// Every robot starts at one junction (`start_junction`, or one `route_seed` picks) and wanders
    /// from it along the roads, each leaving by its own road where there are enough: the trials of a
    /// relocalisation benchmark, which start robots anywhere, facing any way.
    Wander,
}

/// Metres along the route between consecutive robots of a [`Mission::Convoy`].
pub const CONVOY_GAP_M: f64 = 30.0;

impl Mission {
    pub const ALL: [Mission; 9] = [
        Mission::ExploreMeet,
        Mission::Rendezvous,
        Mission::Crossing,
        Mission::Reverse,
        Mission::Partial,
        Mission::Loner,
        Mission::SharedRoute,
        Mission::Convoy,
        Mission::Wander,
    ];

    pub const fn name(self) -> &'static str {
        match self {
            Mission::ExploreMeet => "explore_meet",
            Mission::Rendezvous => "rendezvous",
            Mission::Crossing => "crossing",
            Mission::Reverse => "reverse",
            Mission::Partial => "partial",
            Mission::Loner => "loner",
            Mission::SharedRoute => "shared_route",
            Mission::Convoy => "convoy",
            Mission::Wander => "wander",
        }
    }
}

impl FromStr for Mission {
    type Err = SimError;

    fn from_str(name: &str) -> Result<Self, SimError> {
        Self::ALL
            .into_iter()
            .find(|m| m.name() == name.trim())
            .ok_or_else(|| {
                SimError::invalid(
                    "mission",
                    format!(
                        "unknown mission `{name}`; missions: {}",
                        Self::ALL.map(Mission::name).join(", ")
                    ),
                )
            })
    }
}

/// Length of a list of steps, metres.
fn steps_length_m(graph: &RoadGraph, steps: &[(usize, usize)]) -> f64 {
    steps.iter().map(|&(e, _)| graph.edge_length_m(e)).sum()
}

/// The junction near the middle of the graph where robots meet, preferring junctions where four or more
/// roads meet (every 400 m nearer the middle is worth one road fewer).
fn central_junction(graph: &RoadGraph) -> usize {
    let n = graph.nodes.len() as f64;
    let (cx, cy) = graph
        .nodes
        .iter()
        .fold((0.0, 0.0), |(x, y), p| (x + p[0] / n, y + p[1] / n));
    let adjacency = graph.adjacency();
    let key = |v: usize| {
        let d = (graph.nodes[v][0] - cx).hypot(graph.nodes[v][1] - cy);
        d + 400.0 * 4usize.saturating_sub(adjacency[v].len()) as f64
    };
    (0..graph.nodes.len())
        .min_by(|&a, &b| key(a).total_cmp(&key(b)))
        .unwrap_or(0)
}

/// Bearing of junction `to` seen from junction `from`, radians.
fn bearing(graph: &RoadGraph, from: usize, to: usize) -> f64 {
    let (a, b) = (graph.nodes[from], graph.nodes[to]);
    (b[1] - a[1]).atan2(b[0] - a[0])
}

fn angle_between(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(std::f64::consts::TAU);
    d.min(std::f64::consts::TAU - d)
}

/// `count` junctions about `distance_m` (graph distance) from `centre`, spread around it: the i-th is
/// sought at bearing `first_bearing + 2πi/count`.
fn spread_junctions(
    graph: &RoadGraph,
    centre: usize,
    count: usize,
    distance_m: f64,
    first_bearing: f64,
    taken: &[usize],
) -> Vec<usize> {
    let (dist, _) = distances_from(graph, centre);
    let mut chosen: Vec<usize> = taken.to_vec();
    for i in 0..count {
        let wanted = first_bearing + std::f64::consts::TAU * i as f64 / count.max(1) as f64;
        let best = (0..graph.nodes.len())
            .filter(|&v| v != centre && dist[v].is_finite() && !chosen.contains(&v))
            .min_by(|&a, &b| {
                let cost = |v: usize| {
                    angle_between(bearing(graph, centre, v), wanted) * distance_m
                        + (dist[v] - distance_m).abs()
                };
                cost(a).total_cmp(&cost(b))
            });
        chosen.push(best.unwrap_or(centre));
    }
    chosen.split_off(taken.len())
}

/// A walk of `length_m` from `start` avoiding `avoid` where it can, appended to `steps`.
fn extend_with_walk(
    graph: &RoadGraph,
    rng: &mut Rng,
    steps: &mut Steps,
    start: usize,
    length_m: f64,
    avoid: &[usize],
) {
    if length_m > 1.0 {
        steps.extend(walk(graph, rng, start, length_m, avoid, None));
    }
}

fn end_of(graph: &RoadGraph, steps: &[(usize, usize)], fallback: usize) -> usize {
    steps.last().map_or(fallback, |&(e, from)| graph.other(e, from))
}

fn explore_meet(graph: &RoadGraph, rng: &mut Rng, robots: usize, length_m: f64) -> Vec<(Steps, String)> {
    let centre = central_junction(graph);
    let starts = spread_junctions(
        graph,
        centre,
        robots,
        0.45 * length_m,
        rng.range(0.0, std::f64::consts::TAU),
        &[],
    );
    let approaches: Vec<Steps> = starts
        .iter()
        .map(|&s| reversed(graph, &path_to(graph, centre, s)))
        .collect();
    (0..robots)
        .map(|r| {
            let mut steps = approaches[r].clone();
            if robots > 1 {
                let next = (r + 1) % robots;
                steps.extend(path_to(graph, centre, starts[next]));
            }
            let used = steps_length_m(graph, &steps);
            let end = end_of(graph, &steps, starts[r]);
            let avoid: Vec<usize> = steps.iter().map(|&(e, _)| e).collect();
            extend_with_walk(graph, rng, &mut steps, end, length_m - used, &avoid);
            let role = if robots > 1 {
                format!(
                    "explores its sector towards the meeting junction, crosses the others there, then drives robot {}'s sector the other way",
                    (r + 1) % robots
                )
            } else {
                "explores towards the meeting junction".to_owned()
            };
            (steps, role)
        })
        .collect()
}

fn rendezvous(graph: &RoadGraph, rng: &mut Rng, robots: usize, length_m: f64) -> Vec<(Steps, String)> {
    let centre = central_junction(graph);
    let starts = spread_junctions(
        graph,
        centre,
        robots,
        0.5 * length_m,
        rng.range(0.0, std::f64::consts::TAU),
        &[],
    );
    starts
        .iter()
        .map(|&s| {
            let back = path_to(graph, centre, s);
            let mut steps = reversed(graph, &back);
            steps.extend(back);
            (steps, "drives to the meeting junction and back home".to_owned())
        })
        .collect()
}

/// Bearing of edge `e` leaving junction `node`, from the node to a point about 20 m along the edge.
fn arm_bearing(graph: &RoadGraph, e: usize, node: usize) -> f64 {
    let line = graph.line_from(e, node);
    let (a, mut b) = (line[0], line[line.len() - 1]);
    let mut along = 0.0;
    for w in line.windows(2) {
        along += (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]);
        if along >= 20.0 {
            b = w[1];
            break;
        }
    }
    (b[1] - a[1]).atan2(b[0] - a[0])
}

fn crossing(graph: &RoadGraph, rng: &mut Rng, robots: usize, length_m: f64) -> Vec<(Steps, String)> {
    let centre = central_junction(graph);
    let first = rng.range(0.0, std::f64::consts::PI);
    let arms = graph.adjacency()[centre].clone();
    let (mut used_edges, mut used_arms): (Vec<usize>, Vec<usize>) = (Vec::new(), Vec::new());
    (0..robots)
        .map(|r| {
            // Axes spread over half a turn. Each robot takes the two free roads out of the meeting
            // junction nearest its axis's two directions (roads are shared only when the robots
            // outnumber them) and explores outwards along each, away from the roads taken before.
            let axis = first + std::f64::consts::PI * r as f64 / robots.max(1) as f64;
            let mut arm_towards = |bearing: f64| {
                let free = arms.iter().copied().filter(|e| !used_arms.contains(e));
                let pick = free
                    .min_by(|&a, &b| {
                        angle_between(arm_bearing(graph, a, centre), bearing)
                            .total_cmp(&angle_between(arm_bearing(graph, b, centre), bearing))
                    })
                    .or_else(|| arms.first().copied());
                if let Some(e) = pick {
                    used_arms.push(e);
                }
                pick
            };
            let (entry, exit) = (arm_towards(axis + std::f64::consts::PI), arm_towards(axis));
            let inbound = walk_penalised(graph, rng, centre, 0.5 * length_m, &used_edges, 50.0, entry);
            let mut steps = reversed(graph, &inbound);
            used_edges.extend(steps.iter().map(|&(e, _)| e));
            steps.extend(walk_penalised(
                graph,
                rng,
                centre,
                0.5 * length_m,
                &used_edges,
                50.0,
                exit,
            ));
            used_edges.extend(steps.iter().map(|&(e, _)| e));
            (
                steps,
                format!(
                    "drives through the meeting junction along axis {:.0}°",
                    axis.to_degrees()
                ),
            )
        })
        .collect()
}

/// A convoy of `count` robots (see [`Mission::Convoy`]): one walk from the central junction, long enough
/// for the last robot's route, and each robot's stretch of it, `length_m` long, the leader (robot 0)
/// [`CONVOY_GAP_M`] ahead of robot 1, and so on.
fn convoy(graph: &RoadGraph, rng: &mut Rng, count: usize, length_m: f64) -> Vec<Route> {
    let spread_m = CONVOY_GAP_M * count.saturating_sub(1) as f64;
    let base = walk(
        graph,
        rng,
        central_junction(graph),
        length_m + spread_m,
        &[],
        None,
    );
    let line = centre_line_of(graph, &base);
    (0..count)
        .map(|r| {
            let ahead_m = CONVOY_GAP_M * (count - 1 - r) as f64;
            let role = if r == 0 {
                "leads the convoy".to_owned()
            } else {
                format!(
                    "drives the convoy's route {:.0} m behind the leader",
                    CONVOY_GAP_M * r as f64
                )
            };
            Route {
                robot: r as u32,
                role,
                steps: steps_between(graph, &base, ahead_m, ahead_m + length_m),
                centre_line: cut_line(&line, ahead_m, ahead_m + length_m),
            }
        })
        .collect()
}

/// The steps of `steps` that some of the stretch from `from_m` to `to_m` along them lies on.
fn steps_between(graph: &RoadGraph, steps: &[(usize, usize)], from_m: f64, to_m: f64) -> Steps {
    let mut start_m = 0.0;
    let mut kept = Vec::new();
    for &(edge, from) in steps {
        let end_m = start_m + graph.edge_length_m(edge);
        if end_m > from_m && start_m < to_m {
            kept.push((edge, from));
        }
        start_m = end_m;
    }
    kept
}

/// The part of polyline `line` from `from_m` to `to_m` along it (3-D length), its ends interpolated.
fn cut_line(line: &[[f64; 3]], from_m: f64, to_m: f64) -> Vec<[f64; 3]> {
    let mut out: Vec<[f64; 3]> = Vec::new();
    let mut start_m = 0.0;
    for w in line.windows(2) {
        let length_m = (0..3).map(|k| (w[1][k] - w[0][k]).powi(2)).sum::<f64>().sqrt();
        let end_m = start_m + length_m;
        let at = |m: f64| -> [f64; 3] {
            let t = if length_m > 0.0 {
                ((m - start_m) / length_m).clamp(0.0, 1.0)
            } else {
                0.0
            };
            std::array::from_fn(|k| w[0][k] + (w[1][k] - w[0][k]) * t)
        };
        if end_m >= from_m && start_m <= to_m {
            if out.is_empty() {
                out.push(at(from_m.max(start_m)));
            }
            out.push(at(to_m.min(end_m)));
        }
        start_m = end_m;
    }
    out
}

/// The routes of `mission` for a fleet of `robots` on `world`, each about `length_m` long.
pub fn plan_mission(world: &World, mission: Mission, seed: u64, robots: u32, length_m: f64) -> Vec<Route> {
    let graph = world.graph();
    let count = robots.max(1) as usize;
    let mut rng = Rng::new(combine(combine(seed, 0x3155), u64::from(robots)));
    let planned: Vec<(Steps, String)> = match mission {
        Mission::SharedRoute => {
            return (0..robots.max(1))
                .map(|r| plan_route(world, seed, r, length_m))
                .collect();
        }
        Mission::Convoy => return convoy(graph, &mut rng, count, length_m),
        Mission::Wander => return plan_wander(world, seed, 0, None, robots, length_m),
        Mission::ExploreMeet => explore_meet(graph, &mut rng, count, length_m),
        Mission::Rendezvous => rendezvous(graph, &mut rng, count, length_m),
        Mission::Crossing => crossing(graph, &mut rng, count, length_m),
        Mission::Reverse => {
            let base = plan_route(world, seed, 0, length_m);
            (0..count)
                .map(|r| {
                    if r % 2 == 0 {
                        (base.steps.clone(), "drives the route".to_owned())
                    } else {
                        (
                            reversed(graph, &base.steps),
                            "drives the route backwards".to_owned(),
                        )
                    }
                })
                .collect()
        }
        Mission::Partial => {
            // The shared-route partial pattern (robot 3 of a group) for every robot after the first.
            return (0..robots.max(1))
                .map(|r| {
                    let pattern = if r == 0 { 0 } else { 3 + 6 * (r - 1) };
                    Route {
                        robot: r,
                        ..plan_route(world, seed, pattern, length_m)
                    }
                })
                .collect();
        }
        Mission::Loner => {
            let mut routes = explore_meet(graph, &mut rng, count.saturating_sub(1).max(1), length_m);
            if count > 1 {
                let centre = central_junction(graph);
                let (dist, _) = distances_from(graph, centre);
                let far = (0..graph.nodes.len())
                    .filter(|&v| dist[v].is_finite())
                    .max_by(|&a, &b| dist[a].total_cmp(&dist[b]))
                    .unwrap_or(centre);
                // The loner keeps to junctions farther from the centre than anyone else goes.
                let others: Vec<usize> = routes
                    .iter()
                    .flat_map(|(s, _)| s.iter().map(|&(e, _)| e))
                    .collect();
                let reach = 0.5 * dist[far];
                let out_of_bounds: Vec<usize> = (0..graph.edges.len())
                    .filter(|&e| {
                        let (a, b, _) = &graph.edges[e];
                        dist[*a] < reach || dist[*b] < reach || others.contains(&e)
                    })
                    .collect();
                let steps = walk_penalised(graph, &mut rng, far, length_m, &out_of_bounds, 1e6, None);
                routes.push((steps, "explores the far end of the world alone".to_owned()));
            }
            routes
        }
    };
    planned
        .into_iter()
        .enumerate()
        .map(|(r, (steps, role))| Route {
            robot: r as u32,
            role,
            centre_line: centre_line_of(graph, &steps),
            steps,
        })
        .collect()
}

/// The routes of [`Mission::Wander`]: every robot starts on a road out of `start_junction` (or of a
/// junction `route_seed` picks), somewhere along its first 90 %, and walks `length_m` on from there,
/// robot `r` taking the junction's `r`-th road (in a random order) and then choosing at random;
/// `route_seed` varies the roads and the starting points without changing the world.
pub fn plan_wander(
    world: &World,
    seed: u64,
    route_seed: u64,
    start_junction: Option<usize>,
    robots: u32,
    length_m: f64,
) -> Vec<Route> {
    let graph = world.graph();
    let mut rng = Rng::new(combine(
        combine(combine(seed, 0x3a2d), route_seed),
        u64::from(robots),
    ));
    let start = start_junction
        .filter(|&junction| junction < graph.nodes.len())
        .unwrap_or_else(|| rng.below(graph.nodes.len().max(1)));
    let adjacency = graph.adjacency();
    let mut roads: Vec<usize> = adjacency.get(start).cloned().unwrap_or_default();
    for i in (1..roads.len()).rev() {
        roads.swap(i, rng.below(i + 1));
    }
    (0..robots.max(1))
        .map(|r| {
            let first_edge = (!roads.is_empty()).then(|| roads[r as usize % roads.len()]);
            let steps = walk(graph, &mut rng, start, length_m, &[], first_edge);
            let offset_m = rng.range(
                0.0,
                0.9 * first_edge.map_or(0.0, |edge| graph.edge_length_m(edge)),
            );
            Route {
                robot: r,
                role: format!("wanders from {offset_m:.0} m along a road out of junction {start}"),
                centre_line: trim_start(&centre_line_of(graph, &steps), offset_m),
                steps,
            }
        })
        .collect()
}

/// `line` without its first `offset_m` metres (it starts at the point that far along it).
fn trim_start(line: &[[f64; 3]], offset_m: f64) -> Vec<[f64; 3]> {
    let mut left_m = offset_m;
    for (i, pair) in line.windows(2).enumerate() {
        let length_m = (pair[1][0] - pair[0][0]).hypot(pair[1][1] - pair[0][1]);
        if length_m > left_m {
            let t = left_m / length_m;
            let start = [0, 1, 2].map(|k| pair[0][k] + t * (pair[1][k] - pair[0][k]));
            return std::iter::once(start)
                .chain(line[i + 1..].iter().copied())
                .collect();
        }
        left_m -= length_m;
    }
    line.to_vec()
}
