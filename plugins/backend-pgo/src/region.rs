//! The part of a pose graph that new loop closures touch (issue #18): the poses within a few factors of
//! a new loop's ends. A warm GNC run ([`crate::gnc_warm::gnc_tls_warm`]) graduates the new loops with only
//! these poses free, so the many small steps of its graduated path cost in proportion to this region,
//! not to the graph; the whole graph then takes the loops' final labels in one refinement.
//!
//! The region grows by breadth-first search over the factors that carry weight (odometry, loops labelled
//! inlier, the new loops): an outlier loop carries no information in the solve, so it does not join the
//! parts of the graph it links.

use crate::group::PoseGroup;
use crate::problem::Problem;

/// Which poses lie within `hops` weighted factors of an end of a factor marked in `seeds`. Factors
/// count as weighted when `weights` gives them more than 0 or they are seeds.
pub fn region_around<G: PoseGroup<D>, const D: usize>(
    problem: &Problem<G, D>,
    seeds: &[bool],
    weights: &[f64],
    hops: usize,
) -> Vec<bool> {
    let pose_count = problem.poses.len();
    let mut neighbours: Vec<Vec<usize>> = vec![Vec::new(); pose_count];
    let mut inside = vec![false; pose_count];
    let mut frontier = Vec::new();
    for (k, factor) in problem.factors.iter().enumerate() {
        let seed = seeds.get(k).copied().unwrap_or(false);
        if seed || weights.get(k).is_some_and(|w| *w > 0.0) {
            neighbours[factor.i].push(factor.j);
            neighbours[factor.j].push(factor.i);
        }
        if seed {
            for end in [factor.i, factor.j] {
                if !inside[end] {
                    inside[end] = true;
                    frontier.push(end);
                }
            }
        }
    }
    for _ in 0..hops {
        let mut next = Vec::new();
        for pose in frontier {
            for &neighbour in &neighbours[pose] {
                if !inside[neighbour] {
                    inside[neighbour] = true;
                    next.push(neighbour);
                }
            }
        }
        if next.is_empty() {
            break;
        }
        frontier = next;
    }
    inside
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problem::{RawEdge, Unanchored};
    use nalgebra::{Isometry2, Matrix3, Vector2};

    /// A chain of `n` poses 1 m apart, with one loop from pose `a` to pose `b` at the end of the factors.
    fn chain_with_loop(n: usize, a: usize, b: usize) -> Problem<Isometry2<f64>, 3> {
        let step = Isometry2::new(Vector2::new(1.0, 0.0), 0.0);
        let mut edges: Vec<RawEdge<Isometry2<f64>, 3>> = (0..n - 1)
            .map(|k| RawEdge {
                i: k,
                j: k + 1,
                measured: step,
                information: Matrix3::identity(),
                robust: false,
            })
            .collect();
        edges.push(RawEdge {
            i: a,
            j: b,
            measured: Isometry2::new(Vector2::new((b - a) as f64, 0.0), 0.0),
            information: Matrix3::identity(),
            robust: true,
        });
        let poses = (0..n)
            .map(|k| Isometry2::new(Vector2::new(k as f64, 0.0), 0.0))
            .collect();
        let mut fixed = vec![false; n];
        fixed[0] = true;
        Problem::new(poses, fixed, &edges, Unanchored::Error, &|k| k.to_string()).expect("a valid graph")
    }

    #[test]
    fn the_region_holds_the_poses_within_the_hops_of_the_new_loops_ends() {
        let problem = chain_with_loop(30, 5, 20);
        let loop_factor = problem.factors.len() - 1;
        let mut seeds = vec![false; problem.factors.len()];
        seeds[loop_factor] = true;
        let weights = vec![1.0; problem.factors.len()];
        let region = region_around(&problem, &seeds, &weights, 2);
        let inside: Vec<usize> = (0..30).filter(|&k| region[k]).collect();
        assert_eq!(inside, vec![3, 4, 5, 6, 7, 18, 19, 20, 21, 22]);
        let ends_only = region_around(&problem, &seeds, &weights, 0);
        assert_eq!((0..30).filter(|&k| ends_only[k]).collect::<Vec<_>>(), vec![5, 20]);
    }

    #[test]
    fn an_outlier_loop_does_not_join_the_parts_it_links() {
        // Two loops: the new one (5 -> 20) and an earlier outlier (7 -> 28), weight 0.
        let mut problem = chain_with_loop(30, 5, 20);
        let outlier = problem.factors[problem.factors.len() - 1].clone();
        problem.factors.push(crate::problem::Factor {
            i: 7,
            j: 28,
            ..outlier
        });
        let count = problem.factors.len();
        let mut seeds = vec![false; count];
        seeds[count - 2] = true;
        let mut weights = vec![1.0; count];
        weights[count - 1] = 0.0;
        // 28 is three hops from 5 through the loop from 7, and eight from 20 along the chain.
        let region = region_around(&problem, &seeds, &weights, 3);
        assert!(!region[28], "reached through an outlier");
        weights[count - 1] = 1.0;
        let region = region_around(&problem, &seeds, &weights, 3);
        assert!(region[28], "an inlier loop does join them");
    }
}
