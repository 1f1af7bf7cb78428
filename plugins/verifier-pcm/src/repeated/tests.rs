//! Tests of the corroboration rule on a grid whose junctions all look alike: robot 0 drives a street
//! through two junctions, robot 1 starts on a crossing street 50 m away and passes a third junction,
//! and five loops join robot 1's keyframes there to robot 0's second junction as one place.

use nalgebra::Vector3;
use skid_core::slots::{GraphView, LoopClosure, RelativePose};
use skid_core::{Information, KeyframeId, LoopId, Pose};

use crate::consistency::PcmLoop;
use crate::pcm::{Pcm, PcmParams, PcmUpdate};

/// PCM's defaults with the rule on, as the aliasing benchmark runs it.
fn with_rule() -> PcmParams {
    PcmParams {
        repeat_beyond_m: 20.0,
        ..PcmParams::default()
    }
}

/// Junctions every 50 m on the streets `y = 0` and `x = 100`. Robot 0 drives `y = 0` eastwards from
/// `x = 0`, 2 m per keyframe (junctions at its keyframes 0, 25 and 50); robot 1 drives `x = 100`
/// northwards from `y = 40` (the junction at `y = 50` at its keyframe 5). A keyframe within 4 m of a
/// junction looks like every other such keyframe, of either robot; others look alike only where they
/// truly are within 3 m.
struct Grid;

impl Grid {
    fn truth(id: KeyframeId) -> Pose {
        let k = f64::from(id.index);
        match id.robot.0 {
            0 => Pose::new(Vector3::new(2.0 * k, 0.0, 0.0), Vector3::zeros()),
            _ => Pose::new(
                Vector3::new(100.0, 40.0 + 2.0 * k, 0.0),
                Vector3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2),
            ),
        }
    }

    fn known(id: KeyframeId) -> bool {
        match id.robot.0 {
            0 => id.index <= 30,
            _ => id.index <= 7,
        }
    }

    fn near_junction(id: KeyframeId) -> bool {
        let p = Self::truth(id).translation.vector;
        let nearest = |v: f64| (v / 50.0).round() * 50.0;
        (p.x - nearest(p.x)).abs() <= 4.0 && (p.y - nearest(p.y)).abs() <= 4.0
    }

    /// Loop `n` joins robot 0's keyframe `23 + n` to robot 1's keyframe `3 + n` as one place.
    fn look_alike_loop(n: u32, sighted: bool) -> PcmLoop {
        let closure = LoopClosure {
            id: LoopId(u64::from(n)),
            target: KeyframeId::new(0, 23 + n),
            source: KeyframeId::new(1, 3 + n),
            target_from_source: Pose::identity(),
            information: Information::identity() * 1e4,
        };
        let mut pcm_loop = PcmLoop::from_closure(&closure).unwrap();
        pcm_loop.sighted = sighted;
        pcm_loop
    }
}

impl GraphView for Grid {
    fn pose(&self, id: KeyframeId) -> Option<Pose> {
        Self::known(id).then(|| Self::truth(id))
    }
    fn odometry_between(&self, target: KeyframeId, source: KeyframeId) -> Option<RelativePose> {
        (target.robot == source.robot && Self::known(target) && Self::known(source)).then(|| RelativePose {
            target_from_source: Self::truth(target).inverse() * Self::truth(source),
            covariance: Information::identity() * 1e-5 * f64::from(target.index.abs_diff(source.index)),
        })
    }
    fn keyframes(&self) -> Vec<KeyframeId> {
        (0..=30)
            .map(|i| KeyframeId::new(0, i))
            .chain((0..=7).map(|i| KeyframeId::new(1, i)))
            .collect()
    }
    fn loops(&self) -> Vec<LoopClosure> {
        Vec::new()
    }
    fn looks_alike(&self, a: KeyframeId, b: KeyframeId) -> Option<bool> {
        let truly = (Self::truth(a).translation.vector - Self::truth(b).translation.vector).norm() <= 3.0;
        Some(truly || Self::near_junction(a) && Self::near_junction(b))
    }
}

/// The five loops through `pcm`, loop `sighted` (if any) with a sighting; the last update.
fn five_loops(pcm: &mut Pcm, sighted: Option<u32>) -> PcmUpdate {
    let mut last = PcmUpdate::default();
    let mut accepted = Vec::new();
    for n in 0..5 {
        last = pcm
            .add(Grid::look_alike_loop(n, sighted == Some(n)), &Grid)
            .unwrap();
        accepted.extend(last.accepted.iter().copied());
    }
    last.accepted = accepted;
    last
}

#[test]
fn a_merge_of_places_that_repeat_waits_for_other_evidence() {
    // The five loops agree, span 8 m on each robot, have no rival and predict nothing beyond
    // themselves: every other rule grants them, and they put robot 1 50 m and 90° off. Robot 0's own
    // map holds another junction 46 m from the loops' one, so they show a place that repeats.
    let update = five_loops(&mut Pcm::new(with_rule()).unwrap(), None);
    assert!(update.accepted.is_empty(), "{update:?}");
    let reason = update.withheld.expect("withheld");
    assert!(reason.starts_with("5 of its 5 loops join places"), "{reason}");
    // With the rule off (the default) the same loops merge the robots.
    let off = PcmParams::default();
    let update = five_loops(&mut Pcm::new(off).unwrap(), None);
    assert_eq!(update.accepted.len(), 5, "{update:?}");
    // A place that repeats only within the rule's reach does not count as repeating.
    let near = PcmParams {
        repeat_beyond_m: 60.0,
        ..with_rule()
    };
    assert_eq!(five_loops(&mut Pcm::new(near).unwrap(), None).accepted.len(), 5);
    // Loops spanning more than the look-alike spot on each robot need no other evidence.
    let short = PcmParams {
        aliased_min_spread_m: 8.0,
        ..with_rule()
    };
    assert_eq!(five_loops(&mut Pcm::new(short).unwrap(), None).accepted.len(), 5);
}

#[test]
fn a_sighting_vouches_for_a_merge_of_places_that_repeat() {
    let update = five_loops(&mut Pcm::new(with_rule()).unwrap(), Some(2));
    assert_eq!(update.accepted.len(), 5, "{update:?}");
    assert_eq!(update.withheld, None);
    // Two sightings asked for, one given: it waits.
    let two = PcmParams {
        min_sightings: 2,
        ..with_rule()
    };
    assert!(
        five_loops(&mut Pcm::new(two).unwrap(), Some(2))
            .accepted
            .is_empty()
    );
}
