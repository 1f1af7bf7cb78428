//! Commands over whole files and the simulator: `skid eval`, `skid pgo` and `skid sim export|preview`.

use std::path::Path;

use anyhow::{Context, Result};
use skid_backend_pgo::{Initialization, PgoOptions, RobustMode};
use skid_eval::EvalOptions;
use skid_eval::umeyama::AlignmentKind;
use skid_sim::SimConfig;

/// `skid eval --gt GT --est EST [--align se3|sim3|none]`: one JSON line in evo's definitions.
pub fn eval(gt: &Path, est: &Path, align: &str) -> Result<()> {
    let alignment = match align {
        "se3" => AlignmentKind::Se3,
        "sim3" => AlignmentKind::Sim3,
        "none" => AlignmentKind::None,
        other => anyhow::bail!("unknown alignment `{other}`; expected se3, sim3 or none"),
    };
    let options = EvalOptions {
        alignment,
        ..EvalOptions::default()
    };
    let report = skid_eval::evaluate_files(gt, est, &options)?;
    println!("{}", serde_json::to_string(&report)?);
    let mut table = super::table::Table::new(&["metric", "rmse", "mean", "median", "max"]);
    let mut row = |name: &str, stats: &skid_eval::ErrorStats| {
        table.row(vec![
            name.to_owned(),
            format!("{:.4}", stats.rmse),
            format!("{:.4}", stats.mean),
            format!("{:.4}", stats.median),
            format!("{:.4}", stats.max),
        ]);
    };
    row("ATE (m)", &report.ate_m);
    row("ARE (deg)", &report.are_deg);
    row("RPE translation (m)", &report.rpe.translation_m);
    row("RPE rotation (deg)", &report.rpe.rotation_deg);
    super::table::show(&format!(
        "\n{} poses paired ({:?}, {:?} alignment)\n{}",
        report.associated_poses,
        report.association,
        alignment,
        table.render()
    ));
    if let Some(warning) = report.alignment_conditioning.warning() {
        tracing::warn!("{warning}");
    }
    Ok(())
}

/// `skid pgo FILE.g2o [--robust ..] [--init ..] [--out OUT.g2o]`: one JSON line.
pub fn pgo(file: &Path, robust: &str, init: &str, out: Option<&Path>) -> Result<()> {
    let options = PgoOptions {
        robust: RobustMode::parse(robust)?,
        init: Initialization::parse(init)?,
        ..PgoOptions::default()
    };
    tracing::info!(file = %file.display(), robust, init, "optimising");
    let (mut report, graph) = skid_backend_pgo::optimize_g2o_file(file, &options)?;
    tracing::info!(
        iterations = report.iterations,
        time_s = report.time_s,
        final_cost = report.final_cost,
        "optimised"
    );
    if let Some(out) = out {
        skid_backend_pgo::write_g2o(out, &graph)?;
    }
    report.costs.clear();
    println!("{}", serde_json::to_string(&report)?);
    let mut table = super::table::Table::new(&[
        "vertices",
        "edges (loops)",
        "robust",
        "iterations",
        "cost start → final",
        "outliers",
        "time s",
        "stop",
    ]);
    table.row(vec![
        report.vertices.to_string(),
        format!("{} ({})", report.edges, report.loop_edges),
        report.robust.clone(),
        report.iterations.to_string(),
        format!("{:.6} → {:.6}", report.start_cost, report.final_cost),
        report.outliers.to_string(),
        format!("{:.3}", report.time_s),
        report.stop.clone(),
    ]);
    super::table::show(&format!("\n{}\n{}", file.display(), table.render()));
    if !report.converged {
        anyhow::bail!(
            "{}: the optimisation did not converge ({})",
            file.display(),
            report.stop
        );
    }
    Ok(())
}

/// The simulator configuration of `skid sim` from its flags.
pub struct SimArgs<'a> {
    pub world: &'a str,
    pub sensor: &'a str,
    pub robots: u32,
    pub frames: u32,
    pub seed: u64,
    pub mission: &'a str,
    pub route_length_m: f64,
}

fn sim_config(args: &SimArgs<'_>) -> Result<SimConfig> {
    let config = SimConfig {
        world: args.world.to_owned(),
        sensor: args.sensor.to_owned(),
        robots: args.robots,
        frames: args.frames,
        seed: args.seed,
        mission: args.mission.parse()?,
        route_length_m: args.route_length_m,
        ..SimConfig::default()
    };
    config.validate()?;
    Ok(config)
}

/// `skid sim export`: every robot as a KITTI-format folder under `out`.
pub fn sim_export(args: &SimArgs<'_>, format: &str, out: &Path, overwrite: bool) -> Result<()> {
    let config = sim_config(args)?;
    let bag_format = match format {
        "kitti" => None,
        "ros1" => Some(skid_bag::write::BagFormat::Ros1),
        "mcap" => Some(skid_bag::write::BagFormat::Mcap),
        other => anyhow::bail!("unknown export format `{other}`; expected kitti, ros1 or mcap"),
    };
    // Written whole into `<out>.incomplete/` and renamed at the end, so an export never mixes with
    // what was in the folder before, and an interrupted one is plainly marked.
    let staged = skid_io::staged::StagedFolder::new(out);
    let existing = if overwrite {
        skid_io::staged::Existing::Replace
    } else {
        skid_io::staged::Existing::Refuse
    };
    staged.begin(existing, "the simulator export")?;
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    if let Some(bag_format) = bag_format {
        super::sim_bag::export_fleet_bags(&config, bag_format, staged.path(), out, threads)?;
    } else {
        let summaries = skid_sim::export_fleet_kitti(staged.path(), &config, threads)?;
        for (robot, summary) in summaries.iter().enumerate() {
            let folder = summary
                .dir
                .strip_prefix(staged.path())
                .map_or_else(|_| summary.dir.clone(), |relative| out.join(relative));
            println!(
                "{}",
                serde_json::json!({
                    "robot": robot,
                    "folder": folder.display().to_string(),
                    "scans": summary.scans,
                    "points": summary.points,
                })
            );
        }
    }
    staged.commit()?;
    Ok(())
}

/// `skid sim preview`: a top-down PNG of the world with every robot's route.
pub fn sim_preview(args: &SimArgs<'_>, out: &Path, size_px: u32) -> Result<()> {
    let config = sim_config(args)?;
    skid_sim::preview_fleet_png(out, &config, size_px)?;
    println!("{}", serde_json::json!({ "png": out.display().to_string() }));
    Ok(())
}

/// `skid stage front-end`: one robot's source and odometry as a separate process, fed the host's
/// effective configuration (environment variables were already applied by the host).
pub fn stage_front_end(
    registry: &skid_core::Registry,
    config_file: &Path,
    robot: u32,
    namespace: &str,
    skip: u64,
) -> Result<()> {
    let sources = skid_config::ConfigSources {
        overlays: vec![config_file.to_owned()],
        use_env: false,
        ..skid_config::ConfigSources::default()
    };
    let config = sources
        .load(registry)
        .with_context(|| format!("loading {}", config_file.display()))?;
    skid_runtime::run_front_end_stage(&config, registry, skid_core::RobotId(robot), namespace, skip)?;
    Ok(())
}
