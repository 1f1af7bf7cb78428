//! Correspondences from descriptor matching, as KISS-Matcher (Lim et al., ICRA 2025) establishes them:
//! nearest neighbours in descriptor space (an exact kd-tree over the larger set, queried by the smaller),
//! a cap on the squared descriptor distance, Lowe's ratio test on squared distances, a mutual
//! (cross-check) filter, and at most `max_correspondences` kept, the most distinctive (lowest ratio) first.

use rayon::prelude::*;

use crate::features::{DESCRIPTOR_LEN, Descriptor};
use crate::kdtree::KdTree;

/// Matching rules.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MatchParams {
    /// Keep a match only when each descriptor is the other's nearest neighbour.
    pub mutual: bool,
    /// Keep a match only when (nearest squared distance) / (second nearest squared distance) is at most
    /// this; 1.0 or more disables the test.
    pub ratio: f32,
    /// Largest squared descriptor distance of a match.
    pub max_squared_distance: f32,
    /// Most correspondences kept (lowest ratio first, then lowest squared distance); 0 keeps all.
    pub max_correspondences: usize,
}

/// One putative correspondence between a source keypoint and a target keypoint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Match {
    pub source: u32,
    pub target: u32,
    /// Squared descriptor distance.
    pub squared_distance: f32,
    /// Nearest over second-nearest squared distance (0 when the ratio test is off).
    pub ratio: f32,
}

type FeatureTree = KdTree<DESCRIPTOR_LEN>;

/// The matched keypoints' positions, in double precision: (source points, target points), pair by pair.
pub fn matched_points(
    matches: &[Match],
    source: &crate::features::Features,
    target: &crate::features::Features,
) -> (Vec<nalgebra::Vector3<f64>>, Vec<nalgebra::Vector3<f64>>) {
    matches
        .iter()
        .map(|m| {
            (
                source.points[m.source as usize].cast(),
                target.points[m.target as usize].cast(),
            )
        })
        .unzip()
}

/// Matches `source` descriptors against `target` descriptors; runs on the current rayon pool and returns
/// the same matches, in the same order, whatever its size.
pub fn match_descriptors(source: &[Descriptor], target: &[Descriptor], params: &MatchParams) -> Vec<Match> {
    if source.is_empty() || target.is_empty() {
        return Vec::new();
    }
    // Query with the smaller set, as the reference does; `swapped` when the queries are target descriptors.
    let swapped = target.len() < source.len();
    let (queries, stored) = if swapped {
        (target, source)
    } else {
        (source, target)
    };
    let stored_tree = FeatureTree::build(stored);
    let use_ratio = params.ratio < 1.0 && stored.len() >= 2;

    // Forward search: each query's nearest stored descriptor, filtered by distance and ratio.
    let forward: Vec<Option<(u32, f32, f32)>> = queries
        .par_iter()
        .map(|query| {
            let (item, distance, second) = if use_ratio {
                let found = stored_tree.nearest_two(query);
                let (item, distance) = found.first?;
                (item, distance, found.second.map(|(_, d)| d))
            } else {
                let (item, distance) = stored_tree.nearest_one(query)?;
                (item, distance, None)
            };
            if distance.is_nan() || distance > params.max_squared_distance {
                return None;
            }
            let ratio = match second {
                Some(second) if use_ratio => {
                    let ratio = if second > 0.0 { distance / second } else { 1.0 };
                    if ratio > params.ratio {
                        return None;
                    }
                    ratio
                }
                _ => 0.0,
            };
            Some((item, distance, ratio))
        })
        .collect();

    // Backward search, only for the stored descriptors some query picked.
    let backward: Vec<Option<u32>> = if params.mutual {
        let query_tree = FeatureTree::build(queries);
        let mut picked = vec![false; stored.len()];
        forward
            .iter()
            .flatten()
            .for_each(|&(j, _, _)| picked[j as usize] = true);
        picked
            .par_iter()
            .enumerate()
            .map(|(j, &picked)| {
                if picked {
                    query_tree.nearest_one(&stored[j]).map(|(i, _)| i)
                } else {
                    None
                }
            })
            .collect()
    } else {
        Vec::new()
    };

    let mut matches: Vec<Match> = forward
        .iter()
        .enumerate()
        .filter_map(|(i, found)| {
            let (j, squared_distance, ratio) = (*found)?;
            if params.mutual && backward[j as usize] != Some(i as u32) {
                return None;
            }
            let (source, target) = if swapped { (j, i as u32) } else { (i as u32, j) };
            Some(Match {
                source,
                target,
                squared_distance,
                ratio,
            })
        })
        .collect();
    if params.max_correspondences > 0 && matches.len() > params.max_correspondences {
        matches.sort_by(|a, b| {
            a.ratio
                .total_cmp(&b.ratio)
                .then(a.squared_distance.total_cmp(&b.squared_distance))
                .then(a.source.cmp(&b.source))
        });
        matches.truncate(params.max_correspondences);
        matches.sort_by_key(|m| (m.source, m.target));
    }
    matches
}

#[cfg(test)]
mod tests {
    use super::*;

    fn descriptor(seed: u32) -> Descriptor {
        let mut d = [0.0f32; DESCRIPTOR_LEN];
        for (k, v) in d.iter_mut().enumerate() {
            *v = ((seed as f32 * 12.9898 + k as f32 * 78.233).sin() * 43758.547)
                .fract()
                .abs()
                * 10.0;
        }
        d
    }

    fn params() -> MatchParams {
        MatchParams {
            mutual: true,
            ratio: 0.9,
            max_squared_distance: 900.0,
            max_correspondences: 5000,
        }
    }

    #[test]
    fn finds_planted_pairs_in_either_role() {
        let source: Vec<Descriptor> = (0..200).map(descriptor).collect();
        // The target holds source descriptor 3k + 1 (slightly changed) at position k, plus others.
        let mut target: Vec<Descriptor> = (0..60)
            .map(|k| {
                let mut d = descriptor(3 * k + 1);
                d[0] += 0.01;
                d
            })
            .collect();
        target.extend((1000..1100).map(descriptor));
        for (a, b, flip) in [(&source, &target, false), (&target, &source, true)] {
            let matches = match_descriptors(a, b, &params());
            let planted = matches
                .iter()
                .filter(|m| {
                    let (s, t) = if flip {
                        (m.target, m.source)
                    } else {
                        (m.source, m.target)
                    };
                    t < 60 && s == 3 * t + 1
                })
                .count();
            assert_eq!(planted, 60, "flip {flip}: {matches:?}");
        }
    }

    #[test]
    fn ratio_test_and_cap_and_distance_limit_apply() {
        let source: Vec<Descriptor> = (0..50).map(descriptor).collect();
        // Two identical copies of each: the nearest and second nearest tie, so the ratio test drops all.
        let target: Vec<Descriptor> = (0..50).flat_map(|k| [descriptor(k), descriptor(k)]).collect();
        assert!(match_descriptors(&source, &target, &params()).is_empty());
        let no_ratio = MatchParams {
            ratio: 1.0,
            mutual: false,
            ..params()
        };
        assert_eq!(match_descriptors(&source, &target, &no_ratio).len(), 50);
        let capped = MatchParams {
            max_correspondences: 7,
            ..no_ratio
        };
        assert_eq!(match_descriptors(&source, &target, &capped).len(), 7);
        let far: Vec<Descriptor> = (0..50).map(|k| descriptor(k).map(|v| v + 100.0)).collect();
        assert!(match_descriptors(&source, &far, &no_ratio).is_empty());
        assert!(match_descriptors(&[], &far, &no_ratio).is_empty());
    }
}
