//! Per-robot odometry chains with prefix compositions, so that the relative odometry between any two
//! keyframes of one robot, and its first-order covariance, cost O(1) (what pairwise consistency asks
//! the graph for, many times per loop; covariance propagation as in Smith, Self & Cheeseman, "Estimating
//! uncertain spatial relationships in robotics", 1990, on SE(3) as in Barfoot & Furgale, T-RO 2014).
//!
//! Keyframes of a robot are kept in index order; a keyframe continues the chain of the previous one when
//! an odometry measurement links the two, otherwise it starts a new segment. For keyframe `k` of a
//! segment starting at `s`, the prefix holds `T_sk` and the covariance `Σ_sk` of `T_sk` perturbed on the
//! left (expressed in frame `s`): `Σ_sk = Σ_s,k−1 + Ad(T_sk) Σ_k Ad(T_sk)ᵀ`, where `Σ_k` is the step's
//! covariance (the inverse of its information, perturbed on the right as in the residual).

use std::collections::BTreeMap;

use nalgebra::Matrix6;
use skid_core::slots::RelativePose;
use skid_core::{KeyframeId, Pose, RobotId};

use crate::se3::se3_adjoint;

/// One odometry measurement into a keyframe from the previous one.
#[derive(Clone, Copy, Debug)]
pub struct Step {
    /// Index of the earlier keyframe.
    pub from: u32,
    pub from_from_to: Pose,
    pub covariance: Matrix6<f64>,
}

/// Prefix data of one keyframe.
#[derive(Clone, Copy, Debug)]
struct Prefix {
    segment: usize,
    /// Index of the segment's first keyframe.
    segment_start: u32,
    start_from_this: Pose,
    covariance: Matrix6<f64>,
}

/// The keyframes and odometry of one robot.
#[derive(Clone, Debug, Default)]
pub struct Chain {
    /// Keyframe indices in order, with the odometry step into each (when it continues the chain).
    steps: BTreeMap<u32, Option<Step>>,
    prefix: BTreeMap<u32, Prefix>,
}

impl Chain {
    /// Adds a keyframe without odometry.
    pub fn add_keyframe(&mut self, index: u32) {
        self.steps.insert(index, None);
        self.rebuild_from(index);
    }

    /// Records the odometry step into keyframe `to`.
    pub fn add_step(&mut self, to: u32, step: Step) {
        self.steps.insert(to, Some(step));
        self.rebuild_from(to);
    }

    /// The odometry step into `to`, if any.
    pub fn step(&self, to: u32) -> Option<&Step> {
        self.steps.get(&to)?.as_ref()
    }

    /// Keyframe indices in order.
    pub fn indices(&self) -> impl Iterator<Item = u32> + '_ {
        self.steps.keys().copied()
    }

    /// Keyframe indices strictly between `low` and `high`, in order.
    pub fn indices_between(&self, low: u32, high: u32) -> impl Iterator<Item = u32> + '_ {
        use std::ops::Bound::Excluded;
        let range = (low < high).then_some((Excluded(low), Excluded(high)));
        range
            .into_iter()
            .flat_map(|bounds| self.steps.range(bounds).map(|(k, _)| *k))
    }

    /// Keyframe indices after `low`, in order.
    pub fn indices_after(&self, low: u32) -> impl Iterator<Item = u32> + '_ {
        use std::ops::Bound::{Excluded, Unbounded};
        self.steps.range((Excluded(low), Unbounded)).map(|(k, _)| *k)
    }

    /// Recomputes the prefixes from keyframe `index` on (appending is O(1)).
    fn rebuild_from(&mut self, index: u32) {
        let mut previous = self.prefix.range(..index).next_back().map(|(k, p)| (*k, *p));
        let indices: Vec<u32> = self.steps.range(index..).map(|(k, _)| *k).collect();
        for k in indices {
            let step = self.steps.get(&k).copied().flatten();
            let prefix = match (previous, step) {
                (Some((previous_index, p)), Some(step)) if step.from == previous_index => {
                    let start_from_this = p.start_from_this * step.from_from_to;
                    let ad = se3_adjoint(&start_from_this);
                    Prefix {
                        segment: p.segment,
                        segment_start: p.segment_start,
                        start_from_this,
                        covariance: p.covariance + ad * step.covariance * ad.transpose(),
                    }
                }
                _ => Prefix {
                    segment: previous.map_or(0, |(_, p)| p.segment + 1),
                    segment_start: k,
                    start_from_this: Pose::identity(),
                    covariance: Matrix6::zeros(),
                },
            };
            self.prefix.insert(k, prefix);
            previous = Some((k, prefix));
        }
    }

    /// The segment of a keyframe and its segment's first index.
    pub fn segment(&self, index: u32) -> Option<(usize, u32)> {
        self.prefix.get(&index).map(|p| (p.segment, p.segment_start))
    }

    /// `target_from_source` by odometry and its covariance perturbed on the left in the target frame;
    /// `None` for unknown keyframes or keyframes in different segments.
    pub fn between(&self, target: u32, source: u32) -> Option<RelativePose> {
        let (t, s) = (self.prefix.get(&target)?, self.prefix.get(&source)?);
        if t.segment != s.segment {
            return None;
        }
        let target_from_source = t.start_from_this.inverse() * s.start_from_this;
        let (low, high, low_pose) = if target <= source {
            (t, s, t.start_from_this)
        } else {
            (s, t, s.start_from_this)
        };
        let ad_low = se3_adjoint(&low_pose.inverse());
        let mut covariance = ad_low * (high.covariance - low.covariance) * ad_low.transpose();
        if target > source {
            // That was the covariance of source_from_target in the source frame; invert the pose.
            let ad = se3_adjoint(&target_from_source);
            covariance = ad * covariance * ad.transpose();
        }
        Some(RelativePose {
            target_from_source,
            covariance: (covariance + covariance.transpose()) * 0.5,
        })
    }
}

/// Odometry chains of every robot.
#[derive(Clone, Debug, Default)]
pub struct Chains {
    pub robots: BTreeMap<RobotId, Chain>,
}

impl Chains {
    pub fn between(&self, target: KeyframeId, source: KeyframeId) -> Option<RelativePose> {
        if target.robot != source.robot {
            return None;
        }
        self.robots
            .get(&target.robot)?
            .between(target.index, source.index)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    /// Covariance of `target_from_source` by explicit first-order propagation over the steps in between.
    fn reference_covariance(steps: &[(Pose, Matrix6<f64>)], from: usize, to: usize) -> Matrix6<f64> {
        let mut pose = Pose::identity();
        let mut covariance = Matrix6::zeros();
        for (step, step_covariance) in &steps[from + 1..=to] {
            pose *= step;
            let ad = se3_adjoint(&pose);
            covariance += ad * step_covariance * ad.transpose();
        }
        covariance
    }

    #[test]
    fn prefixes_give_relative_odometry_and_covariance() {
        let mut chain = Chain::default();
        let mut steps = Vec::new();
        for k in 0..8u32 {
            let step = Pose::new(
                Vector3::new(1.0, 0.1 * f64::from(k), 0.0),
                Vector3::new(0.0, 0.05, 0.2),
            );
            let covariance = Matrix6::identity() * (1e-3 * f64::from(k + 1));
            steps.push((step, covariance));
            chain.add_keyframe(k);
            if k > 0 {
                chain.add_step(
                    k,
                    Step {
                        from: k - 1,
                        from_from_to: step,
                        covariance,
                    },
                );
            }
        }
        let forward = chain.between(2, 6).unwrap();
        let expected: Pose = steps[3..=6]
            .iter()
            .map(|(s, _)| *s)
            .fold(Pose::identity(), |a, b| a * b);
        assert!(
            (forward.target_from_source.inverse() * expected)
                .translation
                .vector
                .norm()
                < 1e-12
        );
        let reference = reference_covariance(&steps, 2, 6);
        assert!((forward.covariance - reference).norm() < 1e-12 * reference.norm().max(1.0));
        let backward = chain.between(6, 2).unwrap();
        let ad = se3_adjoint(&backward.target_from_source);
        assert!((backward.covariance - ad * reference * ad.transpose()).norm() < 1e-9);
        assert!(chain.between(3, 3).unwrap().covariance.norm() < 1e-15);
    }

    #[test]
    fn a_gap_splits_the_chain() {
        let mut chain = Chain::default();
        for k in [0u32, 1, 2, 5, 6] {
            chain.add_keyframe(k);
        }
        let step = Step {
            from: 0,
            from_from_to: Pose::identity(),
            covariance: Matrix6::identity(),
        };
        chain.add_step(1, step);
        chain.add_step(2, Step { from: 1, ..step });
        chain.add_step(6, Step { from: 5, ..step });
        assert!(chain.between(0, 2).is_some());
        assert!(chain.between(5, 6).is_some());
        assert!(chain.between(2, 5).is_none());
        // Filling the gap later joins the segments.
        chain.add_step(5, Step { from: 2, ..step });
        assert!(chain.between(0, 6).is_some());
    }
}
