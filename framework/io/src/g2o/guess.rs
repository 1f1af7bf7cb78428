//! The initial guess for vertices a pose-graph file does not list: compose the odometry edges
//! `i -> i + 1` forwards and backwards from the known vertices (see the module documentation of
//! [`crate::g2o`] for the exact rule).

use std::collections::{BTreeSet, HashMap};

use super::{GraphPose, PoseGraph};

/// What [`guess_missing`] did.
#[derive(Debug, Default, PartialEq, Eq)]
pub(crate) struct Guessed {
    /// Ids that received a pose, ascending.
    pub(crate) guessed: Vec<u64>,
    /// Ids still without a pose, ascending.
    pub(crate) unresolved: Vec<u64>,
}

/// Gives a pose to every edge endpoint missing from `graph.vertices` that odometry edges reach.
///
/// `anchor_chain_starts`: place a missing id that has no incoming odometry edge from a posed vertex at
/// the identity (used when the file has no vertex lines at all).
pub(crate) fn guess_missing<P: GraphPose>(graph: &mut PoseGraph<P>, anchor_chain_starts: bool) -> Guessed {
    let mut missing: BTreeSet<u64> = graph.missing_vertices().into_iter().collect();
    if missing.is_empty() {
        return Guessed::default();
    }
    // The first measurement of each odometry step wins (some graphs have parallel edges); a reversed
    // step `i + 1 -> i` (as in TORO's w100) is used inverted when there is no forward one.
    let mut odometry: HashMap<u64, P> = HashMap::new();
    for edge in &graph.edges {
        if edge.from.checked_add(1) == Some(edge.to) {
            odometry.entry(edge.from).or_insert(edge.from_from_to);
        }
    }
    for edge in &graph.edges {
        if edge.to.checked_add(1) == Some(edge.from) {
            odometry
                .entry(edge.to)
                .or_insert_with(|| edge.from_from_to.inverse());
        }
    }
    let mut guessed = Vec::new();
    let mut first_pass = true;
    loop {
        let mut progress = false;
        // Forwards: pose(i) = pose(i - 1) * (i-1 -> i).
        let ascending: Vec<u64> = missing.iter().copied().collect();
        for id in ascending {
            let previous = id.checked_sub(1);
            let chained = previous.and_then(|p| Some(graph.vertices.get(&p)?.compose(odometry.get(&p)?)));
            let pose = match chained {
                Some(pose) => Some(pose),
                None if first_pass && anchor_chain_starts => Some(P::identity()),
                None => None,
            };
            if let Some(pose) = pose {
                graph.vertices.insert(id, pose);
                missing.remove(&id);
                guessed.push(id);
                progress = true;
            }
        }
        // Backwards: pose(i) = pose(i + 1) * (i -> i+1)^-1.
        let descending: Vec<u64> = missing.iter().rev().copied().collect();
        for id in descending {
            let next = id.checked_add(1);
            let chained =
                next.and_then(|n| Some(graph.vertices.get(&n)?.compose(&odometry.get(&id)?.inverse())));
            if let Some(pose) = chained {
                graph.vertices.insert(id, pose);
                missing.remove(&id);
                guessed.push(id);
                progress = true;
            }
        }
        first_pass = false;
        if !progress || missing.is_empty() {
            break;
        }
    }
    guessed.sort_unstable();
    Guessed {
        guessed,
        unresolved: missing.into_iter().collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::g2o::{Edge2, PoseGraph2};
    use nalgebra::{Isometry2, Matrix3, Vector2};

    fn edge(from: u64, to: u64, dx: f64, dtheta: f64) -> Edge2 {
        Edge2 {
            from,
            to,
            from_from_to: Isometry2::new(Vector2::new(dx, 0.0), dtheta),
            information: Matrix3::identity(),
        }
    }

    #[test]
    fn chains_from_the_origin_when_no_vertices() {
        let quarter = std::f64::consts::FRAC_PI_2;
        let mut graph = PoseGraph2 {
            edges: vec![
                edge(0, 1, 1.0, quarter),
                edge(1, 2, 1.0, quarter),
                edge(2, 0, 5.0, 0.0),
            ],
            ..PoseGraph2::default()
        };
        let result = guess_missing(&mut graph, true);
        assert_eq!(result.guessed, vec![0, 1, 2]);
        assert!(result.unresolved.is_empty());
        let p2 = graph.vertices[&2];
        // Origin, 1 m forward and turn left, then 1 m forward (now along +y) and turn left again.
        assert!((p2.translation.vector - Vector2::new(1.0, 1.0)).norm() < 1e-12);
        assert!((p2.rotation.angle() - std::f64::consts::PI).abs() < 1e-12);
    }

    #[test]
    fn chains_both_ways_from_known_vertices_and_reports_the_rest() {
        let mut graph = PoseGraph2 {
            edges: vec![
                edge(3, 4, 1.0, 0.0),
                edge(4, 5, 2.0, 0.0),
                edge(5, 6, 3.0, 0.0),
                edge(5, 100, 1.0, 0.0),
            ],
            ..PoseGraph2::default()
        };
        graph
            .vertices
            .insert(5, Isometry2::new(Vector2::new(10.0, 0.0), 0.0));
        let result = guess_missing(&mut graph, false);
        assert_eq!(result.guessed, vec![3, 4, 6]);
        assert_eq!(result.unresolved, vec![100]);
        assert!((graph.vertices[&6].translation.x - 13.0).abs() < 1e-12);
        assert!((graph.vertices[&4].translation.x - 8.0).abs() < 1e-12);
        assert!((graph.vertices[&3].translation.x - 7.0).abs() < 1e-12);
    }
}
