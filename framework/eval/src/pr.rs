//! Precision-recall curve of place recognition over the descriptor distance threshold, as the SKiD
//! paper evaluates inter-robot place recognition (Sec. "PR curve"): precision = TP/(TP+FP),
//! recall = TP/(TP+FN).
//!
//! Each query contributes its best candidate with a descriptor distance (smaller is more similar). At a
//! threshold τ the candidate is *accepted* when `distance ≤ τ`. An accepted candidate that is a true
//! match is a TP, any other accepted candidate an FP. The positives are the queries that have a true
//! match at all, so FN = positives − TP: a query whose true match was missed, rejected, or beaten by a
//! wrong candidate counts against recall. When each input is a single candidate pair rather than a
//! query, set `query_has_match = is_true_match` and this reduces to the plain pair-wise counts.
//!
//! Conventions: the curve has one point per distinct distance, plus a first point where nothing is
//! accepted; where nothing is accepted precision is defined as 1 (no false alarm was raised) and recall
//! is 0. An input without any positive is an error, since recall is undefined.

use serde::{Deserialize, Serialize};

use crate::error::EvalError;

/// One query's best candidate.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ScoredCandidate {
    /// Descriptor distance; smaller is more similar.
    pub distance: f64,
    /// The candidate is a ground-truth match of the query.
    pub is_true_match: bool,
    /// The query has a ground-truth match somewhere (counted as a positive).
    pub query_has_match: bool,
}

/// One point of the curve.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PrPoint {
    /// Candidates with `distance ≤ threshold` are accepted (`None` for the accept-nothing point).
    pub threshold: Option<f64>,
    pub true_positives: usize,
    pub false_positives: usize,
    pub false_negatives: usize,
    pub precision: f64,
    pub recall: f64,
    pub f1: f64,
}

/// The curve and its summary numbers.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PrCurve {
    /// Points in order of increasing threshold (recall never decreases along it).
    pub points: Vec<PrPoint>,
    /// Number of positives (queries with a true match).
    pub positives: usize,
    /// Number of candidates.
    pub candidates: usize,
    /// Largest F1 over the thresholds, with the point reaching it.
    pub max_f1: f64,
    pub max_f1_threshold: Option<f64>,
    /// Largest recall among points with at least one accepted candidate and no false positive
    /// (0 when even the most similar candidate is wrong).
    pub recall_at_full_precision: f64,
    /// Area under the step curve, `Σ (R_k − R_{k−1}) · P_k` (average precision).
    pub average_precision: f64,
}

fn point(threshold: Option<f64>, tp: usize, fp: usize, positives: usize) -> PrPoint {
    let precision = if tp + fp == 0 {
        1.0
    } else {
        tp as f64 / (tp + fp) as f64
    };
    let recall = tp as f64 / positives as f64;
    let f1 = if precision + recall > 0.0 {
        2.0 * precision * recall / (precision + recall)
    } else {
        0.0
    };
    PrPoint {
        threshold,
        true_positives: tp,
        false_positives: fp,
        false_negatives: positives - tp,
        precision,
        recall,
        f1,
    }
}

/// Computes the PR curve of `candidates` (see the module documentation for the counting rules).
pub fn pr_curve(candidates: &[ScoredCandidate]) -> Result<PrCurve, EvalError> {
    if candidates.is_empty() {
        return Err(EvalError::TooFew {
            what: "PR curve candidates",
            needed: 1,
            got: 0,
        });
    }
    for (index, c) in candidates.iter().enumerate() {
        if !c.distance.is_finite() {
            return Err(EvalError::NonFinite {
                what: "PR curve candidate distance",
                index,
            });
        }
        if c.is_true_match && !c.query_has_match {
            return Err(EvalError::InconsistentLabels { index });
        }
    }
    let positives = candidates.iter().filter(|c| c.query_has_match).count();
    if positives == 0 {
        return Err(EvalError::NoPositives {
            candidates: candidates.len(),
        });
    }
    let mut sorted = candidates.to_vec();
    sorted.sort_by(|a, b| a.distance.total_cmp(&b.distance));

    let mut points = vec![point(None, 0, 0, positives)];
    let (mut tp, mut fp) = (0usize, 0usize);
    let mut k = 0;
    while k < sorted.len() {
        let threshold = sorted[k].distance;
        // Accept every candidate tied at this distance together.
        while k < sorted.len() && sorted[k].distance == threshold {
            if sorted[k].is_true_match {
                tp += 1;
            } else {
                fp += 1;
            }
            k += 1;
        }
        points.push(point(Some(threshold), tp, fp, positives));
    }

    let mut best = points[0];
    let mut recall_at_full_precision = 0.0f64;
    let mut average_precision = 0.0;
    for pair in points.windows(2) {
        let (previous, current) = (pair[0], pair[1]);
        if current.f1 > best.f1 {
            best = current;
        }
        if current.false_positives == 0 && current.true_positives > 0 {
            recall_at_full_precision = recall_at_full_precision.max(current.recall);
        }
        average_precision += (current.recall - previous.recall) * current.precision;
    }
    Ok(PrCurve {
        points,
        positives,
        candidates: candidates.len(),
        max_f1: best.f1,
        max_f1_threshold: best.threshold,
        recall_at_full_precision,
        average_precision,
    })
}
