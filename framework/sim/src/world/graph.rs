//! The drivable network of a world: junctions joined by centre-line polylines (streets, traverse lanes,
//! tunnels). Routes are walks on this graph, so robots share stretches in the ways that matter.

use crate::rng::Rng;

/// Junctions and the polylines between them; points are (x, y, z_reference) in metres, where
/// `z_reference` lies a little above the ground (surface worlds) or on the tunnel axis (caves).
#[derive(Clone, Debug, Default)]
pub struct RoadGraph {
    pub nodes: Vec<[f64; 3]>,
    /// Edges as (from node, to node, centre line from `from` to `to`, both ends included).
    pub edges: Vec<(usize, usize, Vec<[f64; 3]>)>,
}

impl RoadGraph {
    /// Edge indices at each node.
    pub fn adjacency(&self) -> Vec<Vec<usize>> {
        let mut adjacency = vec![Vec::new(); self.nodes.len()];
        for (e, (a, b, _)) in self.edges.iter().enumerate() {
            adjacency[*a].push(e);
            adjacency[*b].push(e);
        }
        adjacency
    }

    /// The node at the other end of edge `e` from `node`.
    pub fn other(&self, e: usize, node: usize) -> usize {
        let (a, b, _) = &self.edges[e];
        if *a == node { *b } else { *a }
    }

    /// Edge `e`'s centre line walked away from `node`.
    pub fn line_from(&self, e: usize, node: usize) -> Vec<[f64; 3]> {
        let (a, _, line) = &self.edges[e];
        if *a == node {
            line.clone()
        } else {
            line.iter().rev().copied().collect()
        }
    }

    /// Length of edge `e` in metres.
    pub fn edge_length_m(&self, e: usize) -> f64 {
        polyline_length_m(&self.edges[e].2)
    }

    /// True when every node can reach every other.
    pub fn is_connected(&self) -> bool {
        if self.nodes.is_empty() {
            return true;
        }
        let adjacency = self.adjacency();
        let mut seen = vec![false; self.nodes.len()];
        let mut stack = vec![0];
        seen[0] = true;
        while let Some(n) = stack.pop() {
            for &e in &adjacency[n] {
                let m = self.other(e, n);
                if !seen[m] {
                    seen[m] = true;
                    stack.push(m);
                }
            }
        }
        seen.into_iter().all(|s| s)
    }

    /// Removes about `fraction` of the edges at random while keeping the graph connected and every
    /// node of degree at least 2 (no dead ends), so the network has irregular blocks and loops.
    pub fn prune(&mut self, rng: &mut Rng, fraction: f64) {
        let target = (self.edges.len() as f64 * fraction) as usize;
        let mut removed = 0;
        let mut attempts = 0;
        while removed < target && attempts < self.edges.len() * 4 {
            attempts += 1;
            let e = rng.below(self.edges.len());
            let (a, b, _) = self.edges[e];
            let adjacency = self.adjacency();
            if adjacency[a].len() <= 2 || adjacency[b].len() <= 2 {
                continue;
            }
            let edge = self.edges.remove(e);
            if self.is_connected() {
                removed += 1;
            } else {
                self.edges.insert(e, edge);
            }
        }
    }

    /// Shortest distance in the x/y plane from (x, y) to any centre line.
    pub fn distance_xy_m(&self, x: f64, y: f64) -> f64 {
        self.edges
            .iter()
            .flat_map(|(_, _, line)| line.windows(2))
            .map(|w| segment_distance_xy(x, y, w[0], w[1]))
            .fold(f64::INFINITY, f64::min)
    }
}

/// Length of a polyline.
pub fn polyline_length_m(line: &[[f64; 3]]) -> f64 {
    line.windows(2).map(|w| distance(w[0], w[1])).sum()
}

/// Euclidean distance between two points.
pub fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Distance in the x/y plane from (x, y) to the segment a–b.
pub fn segment_distance_xy(x: f64, y: f64, a: [f64; 3], b: [f64; 3]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((x - a[0]) * dx + (y - a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((x - a[0] - t * dx).powi(2) + (y - a[1] - t * dy).powi(2)).sqrt()
}

/// A jittered `nx` × `ny` grid of nodes with spacing `spacing_m` centred on the origin, joined to their
/// four neighbours by straight edges (two-point centre lines).
pub fn jittered_grid(
    rng: &mut Rng,
    nx: usize,
    ny: usize,
    spacing_m: f64,
    jitter_m: f64,
    z: impl Fn(f64, f64) -> f64,
) -> RoadGraph {
    let mut graph = RoadGraph::default();
    for j in 0..ny {
        for i in 0..nx {
            let x = (i as f64 - (nx - 1) as f64 / 2.0) * spacing_m + rng.range(-jitter_m, jitter_m);
            let y = (j as f64 - (ny - 1) as f64 / 2.0) * spacing_m + rng.range(-jitter_m, jitter_m);
            graph.nodes.push([x, y, z(x, y)]);
        }
    }
    for j in 0..ny {
        for i in 0..nx {
            let n = j * nx + i;
            if i + 1 < nx {
                graph
                    .edges
                    .push((n, n + 1, vec![graph.nodes[n], graph.nodes[n + 1]]));
            }
            if j + 1 < ny {
                graph
                    .edges
                    .push((n, n + nx, vec![graph.nodes[n], graph.nodes[n + nx]]));
            }
        }
    }
    graph
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pruning_keeps_connectivity_and_degree() {
        let mut rng = Rng::new(5);
        let mut graph = jittered_grid(&mut rng, 5, 5, 100.0, 10.0, |_, _| 0.0);
        let before = graph.edges.len();
        graph.prune(&mut rng, 0.3);
        assert!(graph.edges.len() < before);
        assert!(graph.is_connected());
        assert!(graph.adjacency().iter().all(|a| a.len() >= 2));
        assert!(graph.distance_xy_m(graph.nodes[0][0], graph.nodes[0][1]) < 1e-9);
    }
}
