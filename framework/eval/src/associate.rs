//! Pairing the poses of a ground-truth and an estimated trajectory before comparing them: by timestamp
//! (nearest stamp within a maximum difference, the rule of evo's `--t_max_diff` / `--t_offset`, default
//! 0.01 s) or by index (KITTI pose files carry no stamps).

use serde::{Deserialize, Serialize};

use crate::error::EvalError;
use crate::geometry::check_poses;
use skid_core::Pose;
use skid_io::trajectory::StampedPose;

/// evo's default `--t_max_diff`, in seconds.
pub const DEFAULT_MAX_DIFF_S: f64 = 0.01;

/// Options of timestamp association.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TimeAssociation {
    /// Largest accepted |stamp_gt − (stamp_est + offset_s)|, in seconds.
    pub max_diff_s: f64,
    /// Added to every estimated stamp before matching (evo's `--t_offset`), in seconds.
    pub offset_s: f64,
}

impl Default for TimeAssociation {
    fn default() -> Self {
        Self {
            max_diff_s: DEFAULT_MAX_DIFF_S,
            offset_s: 0.0,
        }
    }
}

/// Pose pairs at the same time: `gt[i]` and `est[i]` belong together.
#[derive(Clone, Debug, PartialEq)]
pub struct Associated {
    pub gt: Vec<Pose>,
    pub est: Vec<Pose>,
    /// Stamps of the pairs (the ground truth's), when known.
    pub stamps_s: Option<Vec<f64>>,
    /// For each pair, the indices into the original ground-truth and estimated sequences.
    pub indices: Vec<(usize, usize)>,
}

impl Associated {
    pub fn len(&self) -> usize {
        self.gt.len()
    }

    pub fn is_empty(&self) -> bool {
        self.gt.is_empty()
    }
}

fn check_stamped(what: &'static str, poses: &[StampedPose]) -> Result<(), EvalError> {
    if poses.is_empty() {
        return Err(EvalError::TooFew {
            what,
            needed: 1,
            got: 0,
        });
    }
    if let Some(index) = poses.iter().position(|p| !p.stamp_s.is_finite()) {
        return Err(EvalError::NonFinite { what, index });
    }
    let bare: Vec<Pose> = poses.iter().map(|p| p.world_from_sensor).collect();
    check_poses(what, &bare)
}

/// The index in `stamps_sorted` (an index permutation of `stamps` in increasing order) of the stamp
/// closest to `query`; ties go to the lower original index, like `numpy.argmin`.
fn nearest(stamps: &[f64], sorted: &[usize], query: f64) -> usize {
    let split = sorted.partition_point(|&i| stamps[i] < query);
    let mut best: Option<(f64, usize)> = None;
    // Candidates: the run of equal stamps just below `query` and the run at or above it.
    let mut consider = |i: usize| {
        let d = (stamps[i] - query).abs();
        match best {
            Some((bd, bi)) if d > bd || (d == bd && i > bi) => {}
            _ => best = Some((d, i)),
        }
    };
    if split > 0 {
        let below = stamps[sorted[split - 1]];
        for &i in sorted[..split].iter().rev().take_while(|&&i| stamps[i] == below) {
            consider(i);
        }
    }
    if split < sorted.len() {
        let above = stamps[sorted[split]];
        for &i in sorted[split..].iter().take_while(|&&i| stamps[i] == above) {
            consider(i);
        }
    }
    best.map_or(0, |(_, i)| i)
}

/// Associates by timestamp, as evo's `associate_trajectories` does: every pose of the shorter
/// trajectory (ground truth when equally long) takes the pose of the other with the nearest stamp, kept
/// when the difference is at most `max_diff_s`. A pose of the longer trajectory may be used twice.
pub fn associate_by_time(
    gt: &[StampedPose],
    est: &[StampedPose],
    options: &TimeAssociation,
) -> Result<Associated, EvalError> {
    check_stamped("ground-truth trajectory", gt)?;
    check_stamped("estimated trajectory", est)?;
    if !(options.max_diff_s.is_finite() && options.max_diff_s >= 0.0) {
        return Err(EvalError::InvalidOption {
            name: "max_diff_s",
            reason: format!(
                "{} is not a finite non-negative number of seconds",
                options.max_diff_s
            ),
        });
    }
    if !options.offset_s.is_finite() {
        return Err(EvalError::InvalidOption {
            name: "offset_s",
            reason: "must be finite".into(),
        });
    }
    let gt_stamps: Vec<f64> = gt.iter().map(|p| p.stamp_s).collect();
    let est_stamps: Vec<f64> = est.iter().map(|p| p.stamp_s + options.offset_s).collect();
    let est_longer = est.len() > gt.len();
    let (short, long) = if est_longer {
        (&gt_stamps, &est_stamps)
    } else {
        (&est_stamps, &gt_stamps)
    };
    let mut sorted: Vec<usize> = (0..long.len()).collect();
    sorted.sort_by(|&a, &b| long[a].total_cmp(&long[b]));

    let mut indices = Vec::new();
    for (i_short, &stamp) in short.iter().enumerate() {
        let i_long = nearest(long, &sorted, stamp);
        if (long[i_long] - stamp).abs() <= options.max_diff_s {
            indices.push(if est_longer {
                (i_short, i_long)
            } else {
                (i_long, i_short)
            });
        }
    }
    if indices.is_empty() {
        return Err(EvalError::NoAssociation {
            max_diff_s: options.max_diff_s,
            offset_s: options.offset_s,
        });
    }
    Ok(Associated {
        gt: indices.iter().map(|&(g, _)| gt[g].world_from_sensor).collect(),
        est: indices.iter().map(|&(_, e)| est[e].world_from_sensor).collect(),
        stamps_s: Some(indices.iter().map(|&(g, _)| gt[g].stamp_s).collect()),
        indices,
    })
}

/// Associates by index: `gt[i]` with `est[i]`. The two must be equally long and non-empty.
pub fn associate_by_index(gt: &[Pose], est: &[Pose]) -> Result<Associated, EvalError> {
    if gt.len() != est.len() {
        return Err(EvalError::LengthMismatch {
            what: "trajectories associated by index (files without stamps, such as KITTI pose files, pair \
                   pose i with pose i; give both as TUM files, which carry stamps, to associate them by time)",
            left: gt.len(),
            right: est.len(),
        });
    }
    if gt.is_empty() {
        return Err(EvalError::TooFew {
            what: "trajectory poses",
            needed: 1,
            got: 0,
        });
    }
    check_poses("ground-truth trajectory", gt)?;
    check_poses("estimated trajectory", est)?;
    Ok(Associated {
        gt: gt.to_vec(),
        est: est.to_vec(),
        stamps_s: None,
        indices: (0..gt.len()).map(|i| (i, i)).collect(),
    })
}
