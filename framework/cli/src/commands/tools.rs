//! Single-stage commands that run one plugin on files, so its output can be compared with other tools:
//! `skid describe`, `skid register` and `skid odometry`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use skid_core::{Cloud, PluginContext, Registry, Slot};
use skid_io::CloudReadOptions;

use super::{load, sources};
use crate::LayerArgs;

/// The parameters the configuration gives plugin `name` of `slot` (its defaults when it has none).
/// The configured parameters of plugin `name` in `slot`, chosen with the command's `--<slot> NAME` flag.
fn params_for(registry: &Registry, layers: &LayerArgs, slot: Slot, name: &str) -> Result<skid_core::Params> {
    let known = registry.names(slot);
    if !known.iter().any(|known| known == name) {
        bail!(
            "--{} {name}: no {} plugin is called `{name}`; known: {}, or none",
            slot.key(),
            slot.key(),
            known.join(", ")
        );
    }
    let mut layers = layers.clone();
    layers.sets.push(format!("{}.plugin={name}", slot.key()));
    let config = load(&sources(None, &layers), registry)?;
    Ok(config.slot(slot).params.clone())
}

fn context() -> PluginContext {
    PluginContext {
        threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        ..PluginContext::default()
    }
}

fn read_points(path: &Path) -> Result<Cloud> {
    let cloud = skid_io::read_cloud(path, CloudReadOptions::VALID_ONLY)?;
    if let Some(warning) = cloud.report.under_count_warning(path) {
        tracing::warn!("{warning}");
    }
    Ok(Cloud::new(cloud.points))
}

fn ms_since(started: Instant) -> f64 {
    started.elapsed().as_secs_f64() * 1e3
}

/// `skid describe --descriptor NAME FILE...`: one JSON line per file.
pub fn describe(registry: &Registry, name: &str, files: &[PathBuf], layers: &LayerArgs) -> Result<()> {
    let params = params_for(registry, layers, Slot::Descriptor, name)?;
    let mut descriptor = registry.descriptor.create(name, &params, &context())?;
    for file in files {
        let cloud = read_points(file)?;
        let started = Instant::now();
        let buf = descriptor
            .describe(cloud.view())
            .with_context(|| format!("describing {}", file.display()))?;
        let line = serde_json::json!({
            "file": file.display().to_string(),
            "kind": buf.kind,
            "points": cloud.len(),
            "bytes": buf.byte_len(),
            "ms": ms_since(started),
            "values": buf.values,
        });
        println!("{line}");
    }
    Ok(())
}

/// `skid register TARGET SOURCE [--coarse NAME] [--fine NAME]`: one JSON line.
pub fn register(
    registry: &Registry,
    target: &Path,
    source: &Path,
    coarse: Option<&str>,
    fine: Option<&str>,
    layers: &LayerArgs,
) -> Result<()> {
    let (target_cloud, source_cloud) = (read_points(target)?, read_points(source)?);
    let mut stages = serde_json::Map::new();
    let mut guess = skid_core::Pose::identity();
    let mut report = serde_json::Map::new();
    if let Some(name) = coarse.filter(|n| *n != "none") {
        let params = params_for(registry, layers, Slot::Coarse, name)?;
        let mut plugin = registry.coarse.create(name, &params, &context())?;
        let started = Instant::now();
        let result = plugin.align(target_cloud.view(), source_cloud.view(), None)?;
        stages.insert("coarse_ms".into(), ms_since(started).into());
        report.insert("coarse_valid".into(), result.valid.into());
        report.insert("coarse_inliers".into(), result.inlier_count.into());
        if !result.valid {
            bail!(
                "coarse registration `{name}` found no valid alignment ({} inliers)",
                result.inlier_count
            );
        }
        guess = result.target_from_source;
    }
    let mut pose = guess;
    let mut not_converged = None;
    if let Some(name) = fine.filter(|n| *n != "none") {
        let params = params_for(registry, layers, Slot::Fine, name)?;
        let mut plugin = registry.fine.create(name, &params, &context())?;
        let started = Instant::now();
        let prepared_target = plugin.prepare(target_cloud.view())?;
        let prepared_source = plugin.prepare(source_cloud.view())?;
        stages.insert("fine_prepare_ms".into(), ms_since(started).into());
        let started = Instant::now();
        let result = plugin.refine(&prepared_target, &prepared_source, &guess)?;
        stages.insert("fine_align_ms".into(), ms_since(started).into());
        report.insert("converged".into(), result.converged.into());
        report.insert("iterations".into(), result.iterations.into());
        report.insert("inliers".into(), result.inlier_count.into());
        report.insert("inlier_ratio".into(), result.inlier_ratio.into());
        report.insert("error".into(), result.error.into());
        if let Some(reason) = &result.failure {
            report.insert("failure".into(), reason.clone().into());
        }
        pose = result.target_from_source;
        if !result.converged {
            not_converged = Some(format!(
                "fine registration `{name}` did not converge after {} iterations: {}",
                result.iterations,
                result.failure.as_deref().unwrap_or("no reason given")
            ));
        }
    }
    let matrix = pose.to_homogeneous();
    let rows: Vec<Vec<f64>> = (0..4).map(|r| (0..4).map(|c| matrix[(r, c)]).collect()).collect();
    report.insert("target_from_source".into(), serde_json::json!(rows));
    report.insert("target_points".into(), target_cloud.len().into());
    report.insert("source_points".into(), source_cloud.len().into());
    report.insert("stages".into(), stages.into());
    // The JSON line goes out either way (scripts read the last estimate); a failure still exits non-zero.
    println!("{}", serde_json::Value::Object(report));
    match not_converged {
        Some(reason) => bail!("{reason}"),
        None => Ok(()),
    }
}

/// `skid odometry SEQ_DIR [--out DIR]`: runs the configured odometry on a KITTI-format folder.
pub fn odometry(registry: &Registry, folder: &Path, out: Option<&Path>, layers: &LayerArgs) -> Result<()> {
    let mut layers = layers.clone();
    // A folder with `velodyne/` is a KITTI sequence; anything else is read as a bag (ROS 1, ROS 2, MCAP).
    let source_name = if folder.join("velodyne").is_dir() {
        "kitti"
    } else {
        "bag"
    };
    layers.sets.push(format!("source.plugin={source_name}"));
    layers.sets.push(format!(
        "source.{source_name}.path={}",
        toml_string(&folder.display().to_string())
    ));
    layers.sets.push("run.robots=1".into());
    let config = load(&sources(None, &layers), registry)?;
    let odometry_name = config.slot(Slot::Odometry).plugin.clone();
    if odometry_name == "none" {
        bail!("no odometry configured: set odometry.plugin");
    }
    let context = context();
    let source = config.slot(Slot::Source).build(&registry.source, &context)?;
    let context = context.after_source(source.as_ref());
    let odometry = config.slot(Slot::Odometry).build(&registry.odometry, &context)?;
    // The same front-end as `skid run`, so a scan the odometry cannot use is skipped here as it is there.
    let mut front_end = skid_runtime::FrontEnd {
        source,
        odometry: Some(odometry),
    };
    let (mut estimate, mut truth, mut times_ms) = (Vec::new(), Vec::new(), Vec::new());
    let mut skipped = skid_runtime::WarnLimiter::default();
    let mut scans_read = 0usize;
    let mut last_report = Instant::now();
    while let Some(output) = front_end
        .next_output()
        .map_err(|error| anyhow::Error::new(error.source).context(format!("{} plugin", error.slot)))?
    {
        scans_read += 1;
        match output.odometry {
            Some(skid_runtime::OdometryOutcome::Registered {
                world_from_sensor, ..
            }) => {
                times_ms.push(output.odometry_ms);
                estimate.push(skid_io::trajectory::StampedPose {
                    stamp_s: output.stamp_nanos as f64 * 1e-9,
                    world_from_sensor,
                });
                // Truth and estimate stay paired: a scan without ground truth drops the comparison.
                truth.push(output.ground_truth);
            }
            Some(skid_runtime::OdometryOutcome::Skipped { reason }) => {
                if let Some(count) = skipped.occurrence() {
                    tracing::warn!(
                        sequence = output.sequence,
                        skipped_so_far = count,
                        %reason,
                        "scan skipped (repeats are logged at 10, 100, 1000, …)"
                    );
                }
            }
            None => {}
        }
        if last_report.elapsed().as_secs_f64() >= 5.0 {
            tracing::info!(
                scans = scans_read,
                registered = estimate.len(),
                "odometry running"
            );
            last_report = Instant::now();
        }
        tracing::debug!(
            sequence = output.sequence,
            points = output.points,
            odometry_ms = output.odometry_ms,
            "scan"
        );
    }
    if estimate.is_empty() {
        bail!(
            "{}: no scan registered ({scans_read} read, {} skipped by `{odometry_name}`)",
            folder.display(),
            skipped.count()
        );
    }
    let truth: Vec<skid_core::Pose> = if truth.iter().all(Option::is_some) {
        truth.into_iter().flatten().collect()
    } else {
        Vec::new()
    };
    let out = out
        .map(Path::to_owned)
        .unwrap_or_else(|| PathBuf::from("runs/odometry"));
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    skid_io::trajectory::write_tum(out.join("trajectory.tum"), &estimate)?;
    let poses: Vec<_> = estimate.iter().map(|p| p.world_from_sensor).collect();
    skid_io::trajectory::write_kitti_poses(out.join("trajectory.kitti"), &poses)?;
    // The source's ground truth for the same scans, beside the estimate, so `skid eval` takes both.
    if truth.len() == poses.len() && !truth.is_empty() {
        let stamped: Vec<_> = estimate
            .iter()
            .zip(&truth)
            .map(|(scan, pose)| skid_io::trajectory::StampedPose {
                stamp_s: scan.stamp_s,
                world_from_sensor: *pose,
            })
            .collect();
        skid_io::trajectory::write_tum(out.join("ground_truth.tum"), &stamped)?;
        skid_io::trajectory::write_kitti_poses(out.join("ground_truth.kitti"), &truth)?;
    }
    let mut sorted = times_ms.clone();
    sorted.sort_by(f64::total_cmp);
    let at = |q: f64| {
        sorted
            .get(((sorted.len().saturating_sub(1)) as f64 * q).round() as usize)
            .copied()
            .unwrap_or(0.0)
    };
    let mut line = serde_json::json!({
        "frames": estimate.len(),
        "scans_read": scans_read,
        "scans_skipped": skipped.count(),
        "odometry": odometry_name,
        "ms_per_frame_median": at(0.5),
        "ms_per_frame_p90": at(0.9),
        "out": out.display().to_string(),
    });
    let mut table = super::table::Table::new(&[
        "frames",
        "skipped",
        "ms/frame median (p90)",
        "ATE m, first pose aligned",
        "final drift % of path",
    ]);
    let mut errors = (None, None);
    if truth.len() == poses.len() && !truth.is_empty() {
        let (ate_m, drift_percent) = first_pose_aligned_errors(&poses, &truth);
        line["ate_first_pose_aligned_m"] = ate_m.into();
        line["final_drift_percent"] = drift_percent.into();
        errors = (Some(format!("{ate_m:.3}")), Some(format!("{drift_percent:.2}")));
    }
    println!("{line}");
    table.row(vec![
        estimate.len().to_string(),
        skipped.count().to_string(),
        format!("{:.1} ({:.1})", at(0.5), at(0.9)),
        errors.0.unwrap_or_else(|| "- (no ground truth)".into()),
        errors.1.unwrap_or_else(|| "-".into()),
    ]);
    super::table::show(&format!(
        "\nodometry `{odometry_name}` on {}\n{}  outputs: {}\n",
        folder.display(),
        table.render(),
        out.display()
    ));
    Ok(())
}

/// Position RMSE after aligning the first poses, and the final position error in percent of the
/// ground-truth path length.
fn first_pose_aligned_errors(estimate: &[skid_core::Pose], truth: &[skid_core::Pose]) -> (f64, f64) {
    let align = truth[0] * estimate[0].inverse();
    let errors: Vec<f64> = estimate
        .iter()
        .zip(truth)
        .map(|(e, t)| ((align * e).translation.vector - t.translation.vector).norm())
        .collect();
    let rmse = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    let path_m: f64 = truth
        .windows(2)
        .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
        .sum();
    let drift = if path_m > 0.0 {
        errors.last().copied().unwrap_or(0.0) / path_m * 100.0
    } else {
        0.0
    };
    (rmse, drift)
}

/// A TOML string literal for `--set` values that may contain spaces or quotes.
fn toml_string(text: &str) -> String {
    toml::Value::String(text.to_owned()).to_string()
}
