//! Routes for fleets of 1–16 robots on a world's road graph, overlapping in the ways that matter for
//! multi-robot place recognition (same direction, reverse direction, partial overlap, crossing at a
//! junction, far-apart starts), and their conversion into smooth trajectories.
//!
//! Robots come in groups of six that share one base walk; robot `r` takes overlap pattern
//! [`Overlap::FOR_ROBOT`]`[r % 6]` relative to group `r / 6`'s base walk. A robot's route depends only
//! on the world, the seed, its index and the route length, never on the fleet size.

use serde::{Deserialize, Serialize};

use crate::rng::{Rng, combine};
use crate::world::{RoadGraph, World};

/// How a robot's route relates to its group's base walk.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Overlap {
    /// Drives the base walk.
    Leader,
    /// Drives the base walk backwards (reverse revisits).
    Reverse,
    /// Joins the base walk 40 % along it and drives it in the same direction, earlier than the leader.
    SameDirection,
    /// Drives the middle of the base walk, then leaves it for roads the leader never takes.
    Partial,
    /// Crosses the base walk at a junction on roads the leader never takes.
    Crossing,
    /// Starts at the junction farthest from the base walk's start and drives towards its middle.
    FarStart,
}

impl Overlap {
    /// The pattern's name, as serialised.
    pub const fn name(self) -> &'static str {
        match self {
            Overlap::Leader => "leader",
            Overlap::Reverse => "reverse",
            Overlap::SameDirection => "same_direction",
            Overlap::Partial => "partial",
            Overlap::Crossing => "crossing",
            Overlap::FarStart => "far_start",
        }
    }

    /// Pattern by robot index within a group of six.
    pub const FOR_ROBOT: [Overlap; 6] = [
        Overlap::Leader,
        Overlap::Reverse,
        Overlap::SameDirection,
        Overlap::Partial,
        Overlap::Crossing,
        Overlap::FarStart,
    ];
}

/// Walked edges as (edge, node it is entered from).
pub type Steps = Vec<(usize, usize)>;

/// A robot's planned route: the junction walk and its centre line.
#[derive(Clone, Debug)]
pub struct Route {
    pub robot: u32,
    /// What the robot does in its fleet's plan, in words (an [`Overlap`] pattern's name, or a
    /// mission's role).
    pub role: String,
    /// Walked edges as (edge, node it is entered from).
    pub steps: Steps,
    /// Centre line (x, y, z_reference), metres.
    pub centre_line: Vec<[f64; 3]>,
}

/// Walks from `start`, choosing at each junction the least-used edge that does not turn back (unless
/// at a dead end), with edges in `avoid` penalised, until `length_m` is reached.
pub(crate) fn walk(
    graph: &RoadGraph,
    rng: &mut Rng,
    start: usize,
    length_m: f64,
    avoid: &[usize],
    first_edge: Option<usize>,
) -> Steps {
    walk_penalised(graph, rng, start, length_m, avoid, 6.0, first_edge)
}

/// [`walk`] with the penalty of an edge in `avoid` given (one earlier visit of an edge costs 10, the
/// random tie-break up to 3): a huge penalty keeps the walk off those edges wherever it has a choice.
pub(crate) fn walk_penalised(
    graph: &RoadGraph,
    rng: &mut Rng,
    start: usize,
    length_m: f64,
    avoid: &[usize],
    avoid_penalty: f64,
    first_edge: Option<usize>,
) -> Steps {
    let adjacency = graph.adjacency();
    let mut visits = vec![0u32; graph.edges.len()];
    let (mut node, mut previous, mut travelled) = (start, usize::MAX, 0.0);
    let mut steps = Vec::new();
    while travelled < length_m {
        let options: Vec<usize> = adjacency[node]
            .iter()
            .copied()
            .filter(|&e| e != previous || adjacency[node].len() == 1)
            .collect();
        let edge = match (steps.is_empty(), first_edge) {
            (true, Some(e)) => e,
            _ => {
                let score = |e: usize, rng: &mut Rng| {
                    f64::from(visits[e]) * 10.0
                        + if avoid.contains(&e) { avoid_penalty } else { 0.0 }
                        + rng.uniform() * 3.0
                };
                let scored: Vec<(f64, usize)> = options.iter().map(|&e| (score(e, rng), e)).collect();
                match scored.into_iter().min_by(|a, b| a.0.total_cmp(&b.0)) {
                    Some((_, e)) => e,
                    None => break,
                }
            }
        };
        visits[edge] += 1;
        steps.push((edge, node));
        travelled += graph.edge_length_m(edge);
        previous = edge;
        node = graph.other(edge, node);
    }
    steps
}

impl Route {
    /// The same route driven from its end back to its start.
    pub fn reversed(&self, graph: &RoadGraph) -> Route {
        Route {
            robot: self.robot,
            role: format!("{} (reversed)", self.role),
            steps: reversed(graph, &self.steps),
            centre_line: self.centre_line.iter().rev().copied().collect(),
        }
    }
}

/// The same steps driven from the last back to the first.
pub(crate) fn reversed(graph: &RoadGraph, steps: &[(usize, usize)]) -> Steps {
    steps
        .iter()
        .rev()
        .map(|&(e, from)| (e, graph.other(e, from)))
        .collect()
}

/// Index of the first step at which `fraction` of the walk's length has been covered.
fn step_at_fraction(graph: &RoadGraph, steps: &[(usize, usize)], fraction: f64) -> usize {
    let total: f64 = steps.iter().map(|&(e, _)| graph.edge_length_m(e)).sum();
    let mut acc = 0.0;
    for (i, &(e, _)) in steps.iter().enumerate() {
        if acc >= fraction * total {
            return i;
        }
        acc += graph.edge_length_m(e);
    }
    steps.len().saturating_sub(1)
}

/// Graph distances (Dijkstra on edge lengths) from `from` to every junction, and the step by which each
/// is reached on a shortest path (`None` for `from` itself and for junctions it cannot reach).
pub(crate) fn distances_from(graph: &RoadGraph, from: usize) -> (Vec<f64>, Vec<Option<(usize, usize)>>) {
    distances_weighted(graph, from, &|e| graph.edge_length_m(e))
}

/// [`distances_from`] with each edge costing `cost(edge)` instead of its length.
fn distances_weighted(
    graph: &RoadGraph,
    from: usize,
    cost: &dyn Fn(usize) -> f64,
) -> (Vec<f64>, Vec<Option<(usize, usize)>>) {
    let adjacency = graph.adjacency();
    let mut dist = vec![f64::INFINITY; graph.nodes.len()];
    let mut via: Vec<Option<(usize, usize)>> = vec![None; graph.nodes.len()];
    let mut done = vec![false; graph.nodes.len()];
    if from >= graph.nodes.len() {
        return (dist, via);
    }
    dist[from] = 0.0;
    loop {
        let current = (0..graph.nodes.len())
            .filter(|&n| !done[n] && dist[n].is_finite())
            .min_by(|&a, &b| dist[a].total_cmp(&dist[b]));
        let Some(n) = current else { break };
        done[n] = true;
        for &e in &adjacency[n] {
            let m = graph.other(e, n);
            let d = dist[n] + cost(e);
            if d < dist[m] {
                dist[m] = d;
                via[m] = Some((e, n));
            }
        }
    }
    (dist, via)
}

/// A shortest path from `from` to `to` as steps (empty when they are the same junction or unconnected).
pub(crate) fn path_to(graph: &RoadGraph, from: usize, to: usize) -> Steps {
    path_avoiding(graph, from, to, &[])
}

/// A shortest path from `from` to `to` on which the edges in `avoid` count five times their length, so
/// it takes other roads where they are not much longer.
pub(crate) fn path_avoiding(graph: &RoadGraph, from: usize, to: usize, avoid: &[usize]) -> Steps {
    let cost = |e: usize| graph.edge_length_m(e) * if avoid.contains(&e) { 5.0 } else { 1.0 };
    let (_, via) = distances_weighted(graph, from, &cost);
    let mut steps = Vec::new();
    let mut n = to;
    while let Some((e, prev)) = via[n] {
        steps.push((e, prev));
        n = prev;
    }
    steps.reverse();
    steps
}

/// The centre line of `steps`: the edges' polylines joined, each junction once.
pub(crate) fn centre_line_of(graph: &RoadGraph, steps: &[(usize, usize)]) -> Vec<[f64; 3]> {
    let mut centre_line: Vec<[f64; 3]> = Vec::new();
    for &(edge, from) in steps {
        let line = graph.line_from(edge, from);
        let skip = usize::from(!centre_line.is_empty());
        centre_line.extend(line.into_iter().skip(skip));
    }
    centre_line
}

fn end_node(graph: &RoadGraph, steps: &[(usize, usize)], fallback: usize) -> usize {
    steps.last().map_or(fallback, |&(e, from)| graph.other(e, from))
}

/// Plans robot `robot`'s route of about `length_m` metres.
pub fn plan_route(world: &World, seed: u64, robot: u32, length_m: f64) -> Route {
    let graph = world.graph();
    let group = u64::from(robot / 6);
    let overlap = Overlap::FOR_ROBOT[(robot % 6) as usize];
    let mut rng = Rng::new(combine(combine(seed, 0x7077e), group));
    let base_start = rng.below(graph.nodes.len());
    let base = walk(graph, &mut rng, base_start, length_m, &[], None);
    let base_edges: Vec<usize> = base.iter().map(|&(e, _)| e).collect();
    let mut own = Rng::new(combine(combine(seed, 0x0e1a), u64::from(robot)));
    let steps = match overlap {
        Overlap::Leader => base.clone(),
        Overlap::Reverse => reversed(graph, &base),
        Overlap::SameDirection => {
            let mut steps = base[step_at_fraction(graph, &base, 0.4)..].to_vec();
            let covered: f64 = steps.iter().map(|&(e, _)| graph.edge_length_m(e)).sum();
            let tail = walk(
                graph,
                &mut own,
                end_node(graph, &steps, base_start),
                length_m - covered,
                &base_edges,
                None,
            );
            steps.extend(tail);
            steps
        }
        Overlap::Partial => {
            let (from, to) = (
                step_at_fraction(graph, &base, 0.5),
                step_at_fraction(graph, &base, 0.75),
            );
            let mut steps = base[from..to.max(from + 1).min(base.len())].to_vec();
            let covered: f64 = steps.iter().map(|&(e, _)| graph.edge_length_m(e)).sum();
            let tail = walk(
                graph,
                &mut own,
                end_node(graph, &steps, base_start),
                length_m - covered,
                &base_edges,
                None,
            );
            steps.extend(tail);
            steps
        }
        Overlap::Crossing => {
            let adjacency = graph.adjacency();
            let crossing = (step_at_fraction(graph, &base, 0.3)..base.len())
                .map(|i| base[i].1)
                .find(|&n| adjacency[n].iter().filter(|e| !base_edges.contains(e)).count() >= 2)
                .unwrap_or(base[base.len() / 2].1);
            let free: Vec<usize> = adjacency[crossing]
                .iter()
                .copied()
                .filter(|e| !base_edges.contains(e))
                .collect();
            let first = walk(
                graph,
                &mut own,
                crossing,
                length_m / 2.0,
                &base_edges,
                free.first().copied(),
            );
            let second = walk(
                graph,
                &mut own,
                crossing,
                length_m / 2.0,
                &base_edges,
                free.get(1).copied(),
            );
            let mut steps = reversed(graph, &first);
            steps.extend(second);
            steps
        }
        Overlap::FarStart => {
            let s = graph.nodes[base_start];
            let far = (0..graph.nodes.len())
                .max_by(|&a, &b| {
                    let d = |n: usize| (graph.nodes[n][0] - s[0]).hypot(graph.nodes[n][1] - s[1]);
                    d(a).total_cmp(&d(b))
                })
                .unwrap_or(base_start);
            let middle = step_at_fraction(graph, &base, 0.5);
            let mut steps = path_to(graph, far, base[middle].1);
            // Follow the base walk for the rest of the length, and for at least 40 % of it even when
            // the approach alone was long.
            let covered: f64 = steps.iter().map(|&(e, _)| graph.edge_length_m(e)).sum();
            let budget = (length_m - covered).max(0.4 * length_m);
            let mut acc = 0.0;
            for &(e, from) in &base[middle..] {
                if acc >= budget {
                    break;
                }
                acc += graph.edge_length_m(e);
                steps.push((e, from));
            }
            steps
        }
    };
    Route {
        robot,
        role: overlap.name().to_owned(),
        centre_line: centre_line_of(graph, &steps),
        steps,
    }
}
