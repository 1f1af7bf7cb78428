//! Tests of the prediction check: the binomial tail, and a true and a wrong frame on a road where true
//! revisits look alike one time in five and two different places never do.

use super::*;
use nalgebra::Vector3;
use skid_core::slots::{LoopClosure, RelativePose};
use skid_core::{Information, LoopId};

#[test]
fn the_binomial_tail_matches_its_closed_forms() {
    let close = |x: f64, y: f64| (x - y).abs() < 1e-12;
    assert!(close(at_most_probability(10, 10, 0.3), 1.0));
    assert!(close(at_most_probability(3, 10, 0.0), 1.0));
    // None of ten: q^10; at most one of ten: q^10 + 10 p q^9.
    assert!(close(at_most_probability(0, 10, 0.3), 0.7f64.powi(10)));
    let expected = 0.7f64.powi(10) + 10.0 * 0.3 * 0.7f64.powi(9);
    assert!(close(at_most_probability(1, 10, 0.3), expected));
    // A long route does not underflow: at most half of 2001 at one half is one half.
    assert!((at_most_probability(1000, 2001, 0.5) - 0.5).abs() < 1e-9);
}

/// Robot 0 drives a straight road (keyframes 2 m apart, 120 of them); robot 1 drives the same road from
/// robot 0's keyframe 50 on for 21 keyframes. Two keyframes look alike when they are truly within 3 m
/// and the place is one the descriptor recognises (one in five), never otherwise.
struct BlandRoad;

fn position(id: KeyframeId) -> Vector3<f64> {
    let start = if id.robot.0 == 0 { 0.0 } else { 100.0 };
    Vector3::new(start + 2.0 * f64::from(id.index), 0.0, 0.0)
}

fn pose(id: KeyframeId) -> Pose {
    Pose::new(position(id), Vector3::zeros())
}

impl GraphView for BlandRoad {
    fn pose(&self, id: KeyframeId) -> Option<Pose> {
        Some(pose(id))
    }
    fn odometry_between(&self, target: KeyframeId, source: KeyframeId) -> Option<RelativePose> {
        (target.robot == source.robot).then(|| RelativePose {
            target_from_source: pose(target).inverse() * pose(source),
            covariance: Information::identity() * 1e-5,
        })
    }
    fn keyframes(&self) -> Vec<KeyframeId> {
        let robot0 = (0..120).map(|index| KeyframeId::new(0, index));
        robot0
            .chain((0..21).map(|index| KeyframeId::new(1, index)))
            .collect()
    }
    fn loops(&self) -> Vec<LoopClosure> {
        Vec::new()
    }
    fn looks_alike(&self, a: KeyframeId, b: KeyframeId) -> Option<bool> {
        let truly = (position(a) - position(b)).norm() <= 3.0;
        Some(truly && (a.index + b.index).is_multiple_of(5))
    }
}

/// Loops joining robot 1's keyframes 0–4 with robot 0's 50–54 in a frame `shift_m` along the road from
/// the truth, and what the set predicts beyond them.
fn predictions(rule: &OverlapRule, shift_m: f64) -> Predicted {
    let shift = Pose::new(Vector3::new(shift_m, 0.0, 0.0), Vector3::zeros());
    let loops: Vec<PcmLoop> = (0..5u32)
        .map(|i| {
            let (target, source) = (KeyframeId::new(0, 50 + i), KeyframeId::new(1, i));
            let closure = LoopClosure {
                id: LoopId(u64::from(i)),
                target,
                source,
                target_from_source: pose(target).inverse() * shift * pose(source),
                information: Information::identity() * 1e4,
            };
            PcmLoop::from_closure(&closure).expect("a valid loop")
        })
        .collect();
    let members: Vec<usize> = (0..loops.len()).collect();
    predicted_overlaps(rule, &loops, &members, &BlandRoad)
}

fn rule(refutation_significance: f64) -> OverlapRule {
    OverlapRule {
        radius_m: 3.0,
        beyond_m: 10.0,
        min_pairs: 10,
        min_alike_fraction: 0.3,
        refutation_significance,
    }
}

#[test]
fn a_true_frame_a_little_below_the_fraction_stands_and_a_wrong_one_is_refuted() {
    let truth = predictions(&rule(0.05), 0.0);
    assert!((10..=14).contains(&truth.pairs), "{truth:?}");
    assert!(truth.alike >= 2, "{truth:?}");
    assert!(
        truth.alike * 10 < 3 * truth.pairs,
        "below the fraction: {truth:?}"
    );
    assert!(
        rule(1.0).refutes(truth),
        "the fraction alone refutes the true frame"
    );
    assert!(
        !rule(0.05).refutes(truth),
        "as few alike are likely from a true frame"
    );
    // Robot 1 placed 30 m ahead of where it was: every predicted pair is two places 30 m apart.
    let wrong = predictions(&rule(0.05), 30.0);
    assert!(wrong.pairs >= 15 && wrong.alike == 0, "{wrong:?}");
    assert!(rule(0.05).refutes(wrong), "{wrong:?}");
}
