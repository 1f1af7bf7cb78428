//! The consistent core of a group's loops when pairwise tests may fail by chance: the largest set found
//! by peeling in which every loop is consistent with at least a fraction of the others.
//!
//! PCM's maximum clique (Mangelson et al., ICRA 2018) asks every accepted loop to pass the pairwise test
//! with every other. With real front-end covariances the test statistics of true loops are heavy-tailed:
//! on COSMO-Bench's real 3-robot problems 0.2–3.4 % of the pairs of true loops fail the 99 % χ² test, so
//! each true loop among hundreds fails it with a few others, and the maximum clique leaves 47–147 true
//! loops out per problem (where GNC-TLS in the back-end keeps all but 28–50). A wrong loop, in contrast,
//! fails it with most true loops. Peeling keeps what the clique was after: repeatedly remove the loop
//! consistent with the smallest fraction of the others still in the set (the later one on ties), until
//! every loop left is consistent with at least `min_fraction` of the others. With `min_fraction = 1`
//! the result is a clique, though not always a maximum one: the classic rule keeps the exact search.
//! This is a k-core-like peeling (Seidman, "Network structure and minimum degree", 1983) with a degree
//! relative to the set's size.

use crate::clique::{BitSet, Graph};

/// The members of `graph` (all of its vertices) that peeling at `min_fraction` keeps, in index order.
pub fn consistent_core(graph: &Graph, min_fraction: f64) -> Vec<usize> {
    let n = graph.len();
    let mut alive = BitSet::new(n);
    for v in 0..n {
        alive.insert(v);
    }
    // Consistent partners of each vertex within the set, kept up to date as vertices leave.
    let mut partners: Vec<usize> = (0..n).map(|v| graph.degree(v)).collect();
    let mut remaining = n;
    while remaining > 1 {
        let others = (remaining - 1) as f64;
        let worst = alive
            .iter()
            .min_by(|&a, &b| {
                (partners[a] as f64 / others)
                    .total_cmp(&(partners[b] as f64 / others))
                    .then(b.cmp(&a))
            })
            .filter(|&v| (partners[v] as f64) < min_fraction * others);
        let Some(worst) = worst else {
            break;
        };
        alive.remove(worst);
        remaining -= 1;
        for neighbour in graph.neighbours(worst).iter() {
            if alive.contains(neighbour) {
                partners[neighbour] -= 1;
            }
        }
    }
    alive.iter().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn graph(n: usize, edges: &[(usize, usize)]) -> Graph {
        let mut graph = Graph::new(0);
        for _ in 0..n {
            graph.add_vertex();
        }
        for &(a, b) in edges {
            graph.add_edge(a, b);
        }
        graph
    }

    fn complete_but(n: usize, missing: &[(usize, usize)]) -> Graph {
        let mut edges = Vec::new();
        for a in 0..n {
            for b in a + 1..n {
                if !missing.contains(&(a, b)) {
                    edges.push((a, b));
                }
            }
        }
        graph(n, &edges)
    }

    #[test]
    fn a_few_chance_failures_keep_every_true_loop_while_the_clique_loses_some() {
        // Twenty mutually consistent loops of which three pairs failed the test by chance.
        let chance = complete_but(20, &[(0, 7), (3, 12), (5, 19)]);
        assert_eq!(consistent_core(&chance, 0.9).len(), 20);
        // With every pair required, one loop of each failed pair goes.
        let strict = consistent_core(&chance, 1.0);
        assert_eq!(strict.len(), 17);
        assert!(chance.is_clique(&strict));
    }

    #[test]
    fn a_loop_inconsistent_with_most_others_is_peeled() {
        // Loops 0..10 agree; loop 10 agrees with two of them only, loop 11 with none.
        let mut edges: Vec<(usize, usize)> = Vec::new();
        for a in 0..10 {
            for b in a + 1..10 {
                edges.push((a, b));
            }
        }
        edges.extend([(1, 10), (2, 10)]);
        assert_eq!(
            consistent_core(&graph(12, &edges), 0.9),
            (0..10).collect::<Vec<_>>()
        );
    }

    #[test]
    fn the_larger_of_two_camps_stays() {
        // Six loops agree on one frame, four on another; none agrees across.
        let mut edges = Vec::new();
        for camp in [0..6, 6..10] {
            for a in camp.clone() {
                for b in a + 1..camp.end {
                    edges.push((a, b));
                }
            }
        }
        assert_eq!(
            consistent_core(&graph(10, &edges), 0.9),
            (0..6).collect::<Vec<_>>()
        );
        assert!(consistent_core(&graph(0, &[]), 0.9).is_empty());
        assert_eq!(consistent_core(&graph(1, &[]), 0.9), vec![0]);
    }
}
