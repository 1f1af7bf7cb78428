//! Timestamp association with time offsets and gaps, index association, and bad input.

use skid_core::Pose;
use skid_eval::{EvalError, TimeAssociation, associate_by_index, associate_by_time};
use skid_io::trajectory::StampedPose;

use super::pose;

fn stamped(stamps: &[f64]) -> Vec<StampedPose> {
    stamps
        .iter()
        .enumerate()
        .map(|(k, &stamp_s)| StampedPose {
            stamp_s,
            world_from_sensor: pose(k as f64, 0.0, 0.0, [0.0; 3]),
        })
        .collect()
}

#[test]
fn nearest_stamp_within_max_difference() {
    // gt at 0.0 … 0.4 s; the estimate is 5 ms late, misses 0.2 s and has an extra pose 50 ms off.
    let gt = stamped(&[0.0, 0.1, 0.2, 0.3, 0.4]);
    let est = stamped(&[0.005, 0.105, 0.25, 0.305, 0.405]);
    let pairs = associate_by_time(&gt, &est, &TimeAssociation::default()).unwrap();
    // Equally long: every estimated pose looks for the nearest gt stamp (evo's rule); 0.25 is 50 ms
    // from 0.2 and 0.3, beyond 0.01 s, so it is dropped.
    assert_eq!(pairs.indices, vec![(0, 0), (1, 1), (3, 3), (4, 4)]);
    assert_eq!(pairs.stamps_s.as_deref(), Some(&[0.0, 0.1, 0.3, 0.4][..]));
    assert_eq!(pairs.est[2], est[3].world_from_sensor);

    // A 60 ms window accepts the pose 50 ms off as well.
    let wide = TimeAssociation {
        max_diff_s: 0.06,
        offset_s: 0.0,
    };
    assert_eq!(associate_by_time(&gt, &est, &wide).unwrap().len(), 5);
}

#[test]
fn offset_shifts_the_estimate_clock() {
    // The estimate's clock runs 1 s behind: nothing matches without the offset, everything with it.
    let gt = stamped(&[10.0, 10.1, 10.2, 10.3]);
    let est = stamped(&[9.0, 9.1, 9.2, 9.3]);
    assert!(matches!(
        associate_by_time(&gt, &est, &TimeAssociation::default()),
        Err(EvalError::NoAssociation { .. })
    ));
    let shifted = TimeAssociation {
        offset_s: 1.0,
        ..TimeAssociation::default()
    };
    let pairs = associate_by_time(&gt, &est, &shifted).unwrap();
    assert_eq!(pairs.indices, vec![(0, 0), (1, 1), (2, 2), (3, 3)]);
}

#[test]
fn denser_estimate_picks_nearest_per_ground_truth_pose() {
    // The estimate is longer, so each gt pose takes its nearest estimated pose.
    let gt = stamped(&[1.0, 2.0, 3.0]);
    let est = stamped(&[0.99, 1.004, 1.5, 1.996, 2.5, 3.02, 3.5]);
    let pairs = associate_by_time(&gt, &est, &TimeAssociation::default()).unwrap();
    // 1.0 → 1.004 (index 1), 2.0 → 1.996 (index 3), 3.0 → 3.02 is 20 ms away: dropped.
    assert_eq!(pairs.indices, vec![(0, 1), (1, 3)]);
    // Unsorted estimate stamps work too.
    let shuffled = stamped(&[3.5, 1.996, 0.99, 1.004]);
    let pairs = associate_by_time(&gt, &shuffled, &TimeAssociation::default()).unwrap();
    assert_eq!(pairs.indices, vec![(0, 3), (1, 1)]);
}

#[test]
fn bad_input_is_an_error() {
    let gt = stamped(&[0.0, 0.1]);
    assert!(matches!(
        associate_by_time(&[], &gt, &TimeAssociation::default()),
        Err(EvalError::TooFew { .. })
    ));
    let nan = stamped(&[0.0, f64::NAN]);
    assert!(matches!(
        associate_by_time(&gt, &nan, &TimeAssociation::default()),
        Err(EvalError::NonFinite { index: 1, .. })
    ));
    let negative = TimeAssociation {
        max_diff_s: -1.0,
        offset_s: 0.0,
    };
    assert!(matches!(
        associate_by_time(&gt, &gt, &negative),
        Err(EvalError::InvalidOption { .. })
    ));

    let poses: Vec<Pose> = (0..3).map(|k| pose(f64::from(k), 0.0, 0.0, [0.0; 3])).collect();
    assert_eq!(
        associate_by_index(&poses, &poses).unwrap().indices,
        vec![(0, 0), (1, 1), (2, 2)]
    );
    assert!(matches!(
        associate_by_index(&poses, &poses[..2]),
        Err(EvalError::LengthMismatch {
            left: 3,
            right: 2,
            ..
        })
    ));
    // The error says why the lengths matter and how to associate by time instead.
    let error = associate_by_index(&poses, &poses[..2]).unwrap_err().to_string();
    assert!(error.contains("TUM") && error.contains("by time"), "{error}");
    assert!(matches!(
        associate_by_index(&[], &[]),
        Err(EvalError::TooFew { .. })
    ));
}
