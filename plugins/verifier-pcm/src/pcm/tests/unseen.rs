//! Tests of the rule that loops the peer-visibility check refused speak against the frame hypotheses
//! they agree with: two robots on gentle curves ([`super::Curves`]), a wrong frame that its own loops
//! cannot tell from the right one.

use super::*;

/// Robot 1's world 6 m too far along: the wrong frame of these tests.
fn wrong_offset() -> Pose {
    Pose::new(Vector3::new(6.0, 0.0, 0.0), Vector3::zeros())
}

/// Grants four loops of the wrong frame, spread over 6 m on each robot, and returns the accepted set.
fn granted_wrong_set(pcm: &mut Pcm) -> BTreeSet<LoopId> {
    let k = KeyframeId::new;
    let mut accepted = BTreeSet::new();
    for (id, index) in [(1, 2), (2, 4), (3, 6), (4, 5)] {
        add_tracking(
            pcm,
            &mut accepted,
            aligned_loop(id, k(0, index), k(1, index), &wrong_offset(), Pose::identity()),
        );
    }
    assert_eq!(
        accepted,
        (1..=4).map(LoopId).collect(),
        "unrivalled and spread: granted"
    );
    accepted
}

#[test]
fn loops_seen_empty_that_agree_with_a_granted_frame_withdraw_it_for_good() {
    let mut pcm = Pcm::new(PcmParams {
        min_loops_before_decision: 2,
        ..PcmParams::default()
    })
    .unwrap();
    let k = KeyframeId::new;
    let mut accepted = granted_wrong_set(&mut pcm);
    // One loop of the same frame whose scans show nobody where it puts robot 1: not enough alone.
    let first = aligned_loop(20, k(0, 0), k(1, 0), &wrong_offset(), Pose::identity());
    assert_eq!(pcm.add_unseen(first, &Curves).unwrap(), Vec::<LoopId>::new());
    assert_eq!(pcm.accepted().len(), 4);
    // A refused loop of another frame says nothing about this one.
    let elsewhere = pcm_loop(21, k(0, 1), k(1, 1), Pose::identity());
    assert_eq!(pcm.add_unseen(elsewhere, &Curves).unwrap(), Vec::<LoopId>::new());
    assert_eq!(pcm.accepted().len(), 4);
    // A second one of the wrong frame refutes it: the merge is withdrawn.
    let second = aligned_loop(22, k(0, 1), k(1, 0), &wrong_offset(), Pose::identity());
    let withdrawn = pcm.add_unseen(second, &Curves).unwrap();
    assert_eq!(withdrawn, (1..=4).map(LoopId).collect::<Vec<_>>());
    accepted.clear();
    assert!(pcm.accepted().is_empty());
    // The refuted loops contest nothing: the right frame is granted as soon as its own loops earn it,
    // without outnumbering the wrong one twice, and a late loop of the wrong frame joins no merge.
    for (n, index) in [10, 14, 18].into_iter().enumerate() {
        add_tracking(
            &mut pcm,
            &mut accepted,
            pcm_loop(30 + n as u64, k(0, index), k(1, index), Pose::identity()),
        );
    }
    assert_eq!(accepted, (30..33).map(LoopId).collect());
    let late = aligned_loop(40, k(0, 8), k(1, 8), &wrong_offset(), Pose::identity());
    let update = add_tracking(&mut pcm, &mut accepted, late);
    assert!(!update.in_leading_set, "{update:?}");
    assert_eq!(accepted, (30..33).map(LoopId).collect());
}

#[test]
fn loops_seen_empty_count_for_nothing_with_the_rule_off_or_within_a_robot() {
    let mut pcm = Pcm::new(PcmParams {
        min_loops_before_decision: 2,
        min_unseen_loops: 0,
        ..PcmParams::default()
    })
    .unwrap();
    let k = KeyframeId::new;
    granted_wrong_set(&mut pcm);
    for (id, (a, b)) in [(20, (0, 0)), (21, (1, 0)), (22, (0, 1))] {
        let unseen = aligned_loop(id, k(0, a), k(1, b), &wrong_offset(), Pose::identity());
        assert!(pcm.add_unseen(unseen, &Curves).unwrap().is_empty());
    }
    assert_eq!(pcm.accepted().len(), 4);
    // On: an intra-robot loop is never kept, and an id PCM took already is an error.
    let mut pcm = Pcm::new(PcmParams::default()).unwrap();
    let intra = pcm_loop(1, k(0, 0), k(0, 9), Pose::identity());
    assert!(pcm.add_unseen(intra, &Curves).unwrap().is_empty());
    pcm.add(pcm_loop(2, k(0, 3), k(1, 3), Pose::identity()), &Curves)
        .unwrap();
    assert!(
        pcm.add_unseen(pcm_loop(2, k(0, 3), k(1, 3), Pose::identity()), &Curves)
            .is_err()
    );
}
