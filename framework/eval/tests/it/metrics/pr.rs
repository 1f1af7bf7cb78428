//! The PR curve on a tiny hand example, ties, and bad input.

use skid_eval::{EvalError, ScoredCandidate, pr_curve};

use super::close;

fn candidate(distance: f64, is_true_match: bool, query_has_match: bool) -> ScoredCandidate {
    ScoredCandidate {
        distance,
        is_true_match,
        query_has_match,
    }
}

#[test]
fn pr_curve_matches_hand_computation() {
    // Five queries (given out of order): q0 d=0.1 right; q1 d=0.2 wrong but q1 has a match; q2 d=0.3
    // right; q3 d=0.4 wrong and q3 has no match; q4 d=0.5 right. Positives: q0, q1, q2, q4 = 4.
    //   τ = none: TP 0 FP 0 → P 1 (convention), R 0,   F1 0
    //   τ = 0.1:  TP 1 FP 0 → P 1,   R 0.25, F1 0.4
    //   τ = 0.2:  TP 1 FP 1 → P 0.5, R 0.25, F1 1/3
    //   τ = 0.3:  TP 2 FP 1 → P 2/3, R 0.5,  F1 4/7
    //   τ = 0.4:  TP 2 FP 2 → P 0.5, R 0.5,  F1 0.5
    //   τ = 0.5:  TP 3 FP 2 → P 0.6, R 0.75, F1 2/3
    // max F1 = 2/3 at τ = 0.5; recall at 100 % precision = 0.25;
    // AP = 0.25·1 + 0·0.5 + 0.25·(2/3) + 0·0.5 + 0.25·0.6 = 0.5666…
    let candidates = [
        candidate(0.3, true, true),
        candidate(0.1, true, true),
        candidate(0.5, true, true),
        candidate(0.2, false, true),
        candidate(0.4, false, false),
    ];
    let curve = pr_curve(&candidates).unwrap();
    assert_eq!(curve.positives, 4);
    assert_eq!(curve.points.len(), 6);
    let expected = [
        (None, 1.0, 0.0, 0.0),
        (Some(0.1), 1.0, 0.25, 0.4),
        (Some(0.2), 0.5, 0.25, 1.0 / 3.0),
        (Some(0.3), 2.0 / 3.0, 0.5, 4.0 / 7.0),
        (Some(0.4), 0.5, 0.5, 0.5),
        (Some(0.5), 0.6, 0.75, 2.0 / 3.0),
    ];
    for (point, (threshold, precision, recall, f1)) in curve.points.iter().zip(expected) {
        assert_eq!(point.threshold, threshold);
        close(point.precision, precision, 1e-12);
        close(point.recall, recall, 1e-12);
        close(point.f1, f1, 1e-12);
        assert_eq!(point.false_negatives, 4 - point.true_positives);
    }
    close(curve.max_f1, 2.0 / 3.0, 1e-12);
    assert_eq!(curve.max_f1_threshold, Some(0.5));
    close(curve.recall_at_full_precision, 0.25, 1e-12);
    close(
        curve.average_precision,
        0.25 + 0.25 * 2.0 / 3.0 + 0.25 * 0.6,
        1e-12,
    );
}

#[test]
fn tied_distances_are_accepted_together() {
    // Two candidates at the same distance, one right and one wrong: a single point with P = 0.5.
    let curve = pr_curve(&[candidate(1.0, true, true), candidate(1.0, false, true)]).unwrap();
    assert_eq!(curve.points.len(), 2);
    close(curve.points[1].precision, 0.5, 0.0);
    close(curve.points[1].recall, 0.5, 0.0);
    // The most similar candidate is already wrong: recall at 100 % precision is 0.
    assert_eq!(curve.recall_at_full_precision, 0.0);
}

#[test]
fn pr_curve_rejects_bad_input() {
    assert!(matches!(pr_curve(&[]), Err(EvalError::TooFew { .. })));
    assert!(matches!(
        pr_curve(&[candidate(f64::NAN, true, true)]),
        Err(EvalError::NonFinite { index: 0, .. })
    ));
    assert!(matches!(
        pr_curve(&[candidate(0.1, false, false)]),
        Err(EvalError::NoPositives { candidates: 1 })
    ));
    assert!(matches!(
        pr_curve(&[candidate(0.1, false, true), candidate(0.2, true, false)]),
        Err(EvalError::InconsistentLabels { index: 1 })
    ));
}
