//! The whole trajectory evaluation `skid eval --gt GT --est EST` runs: associate, align with Umeyama
//! (SE(3) by default, like `evo_ape … -a`), then ATE/ARE, RPE and drift, gathered in a serialisable
//! [`EvalReport`] that also renders as Markdown. Metric definitions follow evo, the tool the SKiD paper
//! used (Sec. "Multi-Robot Alignment Error").

use std::fmt::Write as _;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::ape::{AlignmentSummary, align, ape_of_aligned};
use crate::associate::{Associated, TimeAssociation, associate_by_index, associate_by_time};
use crate::conditioning::{AlignmentConditioning, alignment_conditioning};
use crate::drift::{DriftOptions, DriftResult, drift};
use crate::error::EvalError;
use crate::plot::{PlotOptions, PlotOutput, Series, line_plot, trajectory_plot};
use crate::rpe::{RpeOptions, RpeResult, rpe};
use crate::stats::ErrorStats;
use crate::trajectory::{Trajectory, TrajectoryFormat, read_trajectory};
use crate::umeyama::AlignmentKind;
use skid_core::Pose;

/// How ground-truth and estimated poses are paired.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AssociationMode {
    /// By timestamp when both trajectories have stamps, else by index.
    #[default]
    Auto,
    Timestamps,
    Index,
}

/// Options of [`evaluate`] and [`evaluate_files`].
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EvalOptions {
    /// Alignment before the absolute errors (default SE(3), evo `-a`).
    pub alignment: AlignmentKind,
    pub association: AssociationMode,
    /// Timestamp association parameters (evo `--t_max_diff 0.01`, `--t_offset 0`).
    pub time: TimeAssociation,
    pub rpe: RpeOptions,
    pub drift: DriftOptions,
    /// Forces the ground-truth file format instead of detecting it.
    pub gt_format: Option<TrajectoryFormat>,
    /// Forces the estimate file format instead of detecting it.
    pub est_format: Option<TrajectoryFormat>,
}

/// Everything `skid eval` reports for one ground-truth/estimate pair.
#[derive(Clone, Debug, Serialize)]
pub struct EvalReport {
    pub gt_path: Option<String>,
    pub est_path: Option<String>,
    pub gt_format: TrajectoryFormat,
    pub est_format: TrajectoryFormat,
    pub gt_poses: usize,
    pub est_poses: usize,
    /// Pose pairs compared after association.
    pub associated_poses: usize,
    /// The association actually used (`timestamps` or `index`).
    pub association: AssociationMode,
    pub alignment: AlignmentSummary,
    /// ATE: `‖t_est_aligned − t_gt‖`, metres.
    pub ate_m: ErrorStats,
    /// ARE: angle of `R_gt⁻¹ R_est_aligned`, degrees.
    pub are_deg: ErrorStats,
    /// Whether the alignment fixes its rotation; when it does not, the ARE is not meaningful.
    pub alignment_conditioning: AlignmentConditioning,
    pub rpe: RpeResult,
    /// Drift; `None` with `drift_error` set when it cannot be computed (e.g. a standing ground truth).
    pub drift: Option<DriftResult>,
    pub drift_error: Option<String>,
    /// The associated ground-truth poses, for plots.
    #[serde(skip)]
    pub gt_associated: Vec<Pose>,
    /// The associated estimate after alignment, for plots.
    #[serde(skip)]
    pub est_aligned: Vec<Pose>,
    /// The ATE of every associated pose, metres, for plots.
    #[serde(skip)]
    pub ate_errors_m: Vec<f64>,
}

fn associate(
    gt: &Trajectory,
    est: &Trajectory,
    options: &EvalOptions,
) -> Result<(Associated, AssociationMode), EvalError> {
    let stamped = gt.stamped().zip(est.stamped());
    match (options.association, stamped) {
        (AssociationMode::Auto | AssociationMode::Timestamps, Some((gt_s, est_s))) => Ok((
            associate_by_time(&gt_s, &est_s, &options.time)?,
            AssociationMode::Timestamps,
        )),
        (AssociationMode::Timestamps, None) => Err(EvalError::InvalidOption {
            name: "association",
            reason: "timestamp association needs stamps in both trajectories (KITTI files have none)".into(),
        }),
        (AssociationMode::Auto | AssociationMode::Index, _) => {
            Ok((associate_by_index(&gt.poses, &est.poses)?, AssociationMode::Index))
        }
    }
}

/// Evaluates an estimated trajectory against ground truth (both already in memory).
pub fn evaluate(gt: &Trajectory, est: &Trajectory, options: &EvalOptions) -> Result<EvalReport, EvalError> {
    let (pairs, association) = associate(gt, est, options)?;
    let aligned = align(&pairs.gt, &pairs.est, options.alignment)?;
    let summary = AlignmentSummary::new(options.alignment, &aligned.gt_from_est);
    let ape = ape_of_aligned(&pairs.gt, aligned.est_aligned, summary)?;
    let rpe = rpe(&pairs.gt, &ape.est_aligned, &options.rpe)?;
    let (drift, drift_error) = match drift(&pairs.gt, &ape.est_aligned, &options.drift) {
        Ok(d) => (Some(d), None),
        Err(e) => (None, Some(e.to_string())),
    };
    Ok(EvalReport {
        gt_path: None,
        est_path: None,
        gt_format: gt.format,
        est_format: est.format,
        gt_poses: gt.poses.len(),
        est_poses: est.poses.len(),
        associated_poses: pairs.len(),
        association,
        alignment: ape.alignment,
        ate_m: ape.translation_m,
        are_deg: ape.rotation_deg,
        alignment_conditioning: alignment_conditioning(&pairs.gt),
        rpe,
        drift,
        drift_error,
        gt_associated: pairs.gt,
        est_aligned: ape.est_aligned,
        ate_errors_m: ape.translation_errors_m,
    })
}

/// Reads two trajectory files (TUM or KITTI, detected by content) and evaluates the estimate; the
/// function behind `skid eval --gt GT --est EST`. The numbers equal those of
/// `evo_ape tum GT EST -a` (or `evo_ape kitti …`) and `evo_rpe … -a` for the same options (checked
/// against evo 1.38.1). KITTI rotations are re-orthonormalised on reading (see `skid_io`) while evo
/// uses the printed matrices as they are, so on KITTI files relative errors can differ from evo's in
/// the 8th significant digit.
pub fn evaluate_files(gt: &Path, est: &Path, options: &EvalOptions) -> Result<EvalReport, EvalError> {
    let gt_trajectory = read_trajectory(gt, options.gt_format)?;
    let est_trajectory = read_trajectory(est, options.est_format)?;
    let mut report = evaluate(&gt_trajectory, &est_trajectory, options)?;
    report.gt_path = Some(gt.display().to_string());
    report.est_path = Some(est.display().to_string());
    Ok(report)
}

fn stats_row(text: &mut String, name: &str, s: &ErrorStats) {
    let _ = writeln!(
        text,
        "| {name} | {:.6} | {:.6} | {:.6} | {:.6} | {:.6} | {:.6} | {} |",
        s.rmse, s.mean, s.median, s.std, s.min, s.max, s.count
    );
}

impl EvalReport {
    /// Writes `trajectory.png` (top view of the ground truth and the aligned estimate) and `ate.png`
    /// (translation error along the associated poses) into `dir`.
    pub fn write_plots(&self, dir: &Path, options: &PlotOptions) -> Result<Vec<PlotOutput>, EvalError> {
        let trajectory = trajectory_plot(
            &dir.join("trajectory.png"),
            "Trajectory (top view)",
            &[
                ("ground truth", &self.gt_associated),
                ("estimate (aligned)", &self.est_aligned),
            ],
            true,
            options,
        )?;
        let ate = line_plot(
            &dir.join("ate.png"),
            "Absolute translation error",
            "associated pose",
            "ATE (m)",
            vec![Series::line(
                "ATE",
                self.ate_errors_m
                    .iter()
                    .enumerate()
                    .map(|(k, e)| (k as f64, *e))
                    .collect(),
            )],
            options,
        )?;
        Ok(vec![trajectory, ate])
    }

    /// The report as Markdown: inputs, alignment, one table of error statistics, drift.
    pub fn to_markdown(&self) -> String {
        let mut text = String::from("# Trajectory evaluation\n\n");
        let path = |p: &Option<String>| p.clone().unwrap_or_else(|| "(in memory)".into());
        let _ = writeln!(
            text,
            "- ground truth: `{}` ({:?}, {} poses)",
            path(&self.gt_path),
            self.gt_format,
            self.gt_poses
        );
        let _ = writeln!(
            text,
            "- estimate: `{}` ({:?}, {} poses)",
            path(&self.est_path),
            self.est_format,
            self.est_poses
        );
        let _ = writeln!(
            text,
            "- associated pairs: {} (by {:?})",
            self.associated_poses, self.association
        );
        let a = &self.alignment;
        let _ = writeln!(
            text,
            "- alignment {:?}: rotation {:.4}°, translation [{:.4}, {:.4}, {:.4}] m, scale {:.6}\n",
            a.kind, a.rotation_angle_deg, a.translation_m[0], a.translation_m[1], a.translation_m[2], a.scale
        );
        text.push_str(
            "| metric | rmse | mean | median | std | min | max | n |\n|---|---|---|---|---|---|---|---|\n",
        );
        stats_row(&mut text, "ATE (m)", &self.ate_m);
        stats_row(&mut text, "ARE (deg)", &self.are_deg);
        let unit = match self.rpe.options.unit {
            crate::rpe::DeltaUnit::Frames => "frames",
            crate::rpe::DeltaUnit::Metres => "m",
        };
        let delta = self.rpe.options.delta;
        stats_row(
            &mut text,
            &format!("RPE trans, Δ={delta} {unit} (m)"),
            &self.rpe.translation_m,
        );
        stats_row(
            &mut text,
            &format!("RPE rot, Δ={delta} {unit} (deg)"),
            &self.rpe.rotation_deg,
        );
        text.push('\n');
        if let Some(warning) = self.alignment_conditioning.warning() {
            let _ = writeln!(text, "Note: {warning}.");
        }
        match (&self.drift, &self.drift_error) {
            (Some(d), _) => {
                let _ = write!(
                    text,
                    "Drift over {:.1} m of path: end point {:.3} %",
                    d.path_length_m, d.endpoint_percent
                );
                if let (Some(t), Some(r)) = (d.translation_percent, d.rotation_deg_per_100m) {
                    let _ = write!(
                        text,
                        "; KITTI segments ({}) {t:.3} %, {r:.4} deg/100 m",
                        d.segments
                    );
                }
                text.push('\n');
            }
            (None, Some(e)) => {
                let _ = writeln!(text, "Drift not computed: {e}");
            }
            (None, None) => {}
        }
        text
    }
}
