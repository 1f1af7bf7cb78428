//! The subcommands' bodies.

pub mod bag;
pub mod extra;
pub mod robot;
pub mod sim_bag;
pub mod tools;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use skid_config::{ConfigSources, ResolvedConfig};
use skid_core::{Registry, Slot};

use crate::LayerArgs;

/// Every plugin the binary knows: the built-ins, then the out-of-tree libraries given on the command line.
pub fn registry(plugin_libs: &[PathBuf]) -> Result<Registry> {
    let mut registry = skid_builtin::registry().context("registering the built-in plugins")?;
    for path in plugin_libs {
        let plugin = skid_abi::load_into(&mut registry, path)
            .with_context(|| format!("loading plugin library {}", path.display()))?;
        tracing::debug!(plugin = plugin.name(), slot = %plugin.slot(), path = %path.display(), "loaded plugin library");
    }
    Ok(registry)
}

pub(crate) fn sources(profile: Option<String>, layers: &LayerArgs) -> ConfigSources {
    let mut sources = ConfigSources::discover();
    if layers.config_dir.is_some() {
        sources.config_dir = layers.config_dir.clone();
    }
    sources.profile = profile;
    sources.overlays = layers.overlays.clone();
    sources.sets = layers.sets.clone();
    sources
}

pub(crate) fn load(sources: &ConfigSources, registry: &Registry) -> Result<ResolvedConfig> {
    Ok(sources.load(registry)?)
}

/// `skid run [PROFILE]`.
pub fn run(registry: &Registry, profile: Option<String>, layers: &LayerArgs) -> Result<()> {
    let config = load(&sources(profile, layers), registry)?;
    if config.deploy.robot.is_some() {
        return robot::run_robot(registry, config);
    }
    tracing::info!(
        run = %config.run.name,
        robots = config.run.robots,
        source = %config.slot(Slot::Source).plugin,
        odometry = %config.slot(Slot::Odometry).plugin,
        "starting"
    );
    let total_scans = config.run.max_scans * u64::from(config.run.robots);
    let mut fleet = skid_runtime::Fleet::build(config, registry)?;
    let bar = progress_bar(total_scans);
    let outcome = fleet.run_lockstep(|scans| bar.set_position(scans as u64));
    bar.finish_and_clear();
    let summary = match outcome {
        Ok(summary) => summary,
        Err(error) => {
            // Stop the front-end processes before marking the run's folder.
            let config = fleet.config.clone();
            drop(fleet);
            return Err(abandoned(&config, error));
        }
    };
    let folder = skid_runtime::write_outputs(&fleet, &summary)?;
    tracing::info!(folder = %folder.display(), wall_s = summary.wall_s, "finished");
    println!("{}", serde_json::to_string(&summary)?);
    Ok(())
}

/// The error of a run that did not finish, pointing at the folder it leaves.
pub(crate) fn abandoned(config: &ResolvedConfig, error: skid_runtime::RuntimeError) -> anyhow::Error {
    let reason = error.to_string();
    match skid_runtime::abandon_run(config, &reason) {
        Some(folder) => anyhow::Error::new(error).context(format!(
            "the run did not finish; its partial outputs are in {}",
            folder.display()
        )),
        None => error.into(),
    }
}

/// A progress bar over every robot's scans (a spinner when the sources' length is unknown), drawn on
/// stderr only when it is a terminal.
fn progress_bar(total_scans: u64) -> indicatif::ProgressBar {
    let bar = if total_scans > 0 {
        indicatif::ProgressBar::new(total_scans)
    } else {
        indicatif::ProgressBar::new_spinner()
    };
    let template = if total_scans > 0 {
        "{elapsed_precise} [{bar:40}] {pos}/{len} scans ({per_sec}, eta {eta})"
    } else {
        "{elapsed_precise} {spinner} {pos} scans ({per_sec})"
    };
    if let Ok(style) = indicatif::ProgressStyle::with_template(template) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

/// `skid plugins`.
pub fn plugins(registry: &Registry, slot: Option<&str>, json: bool) -> Result<()> {
    let slots: Vec<Slot> = match slot {
        Some(key) => match Slot::from_key(key) {
            Some(slot) => vec![slot],
            None => bail!(
                "unknown slot `{key}`; slots: {}",
                Slot::ALL.map(Slot::key).join(", ")
            ),
        },
        None => Slot::ALL.to_vec(),
    };
    let infos: Vec<_> = slots.iter().flat_map(|&slot| registry.infos(slot)).collect();
    if json {
        let rows: Vec<_> = infos
            .iter()
            .map(|info| {
                serde_json::json!({
                    "slot": info.slot.key(),
                    "name": info.name,
                    "summary": info.summary,
                    "origin": info.origin,
                    "defaults": toml_to_json(info.defaults.table()),
                })
            })
            .collect();
        println!("{}", serde_json::to_string_pretty(&rows)?);
        return Ok(());
    }
    for slot in slots {
        println!("[{slot}]");
        let infos = registry.infos(slot);
        if infos.is_empty() {
            println!("  (no plugins yet; use plugin = \"none\")\n");
            continue;
        }
        for info in infos {
            println!("  {}  {}", info.name, info.summary);
            if info.origin != "built-in" {
                println!("    from {}", info.origin);
            }
            let defaults = info.defaults.to_toml_string();
            for line in defaults.lines().filter(|line| !line.trim().is_empty()) {
                println!("      {line}");
            }
            println!();
        }
    }
    Ok(())
}

fn toml_to_json(table: &toml::Table) -> serde_json::Value {
    serde_json::to_value(table).unwrap_or(serde_json::Value::Null)
}

/// `skid config show`.
pub fn config_show(registry: &Registry, profile: Option<String>, layers: &LayerArgs) -> Result<()> {
    let config = load(&sources(profile, layers), registry)?;
    print!("{}", config.to_toml_string());
    Ok(())
}

/// `skid config check FILE`.
pub fn config_check(
    registry: &Registry,
    file: &Path,
    profile: Option<String>,
    layers: &LayerArgs,
) -> Result<()> {
    let mut sources = sources(profile, layers);
    sources.overlays.insert(0, file.to_owned());
    load(&sources, registry)?;
    println!("{}: ok", file.display());
    Ok(())
}
