//! The subcommands' bodies.

pub mod bag;
pub mod extra;
pub mod fleet;
pub mod pcm;
pub mod plot;
pub mod plugin_check;
pub mod replay;
pub mod robot;
pub mod session;
pub mod sim_bag;
pub mod table;
pub mod tools;
pub mod viewers;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use skid_config::{ConfigSources, ResolvedConfig};
use skid_core::{Registry, Slot};

use crate::LayerArgs;

/// Every plugin the binary knows: the built-ins, then the out-of-tree libraries given on the command line.
pub fn registry(plugin_libs: &[PathBuf]) -> Result<Registry> {
    let mut registry = skid_builtin::registry().context("registering the built-in plugins")?;
    // An empty entry (`SKID_PLUGIN_LIBS=":"`, a trailing `:`) names no library.
    for path in plugin_libs.iter().filter(|path| !path.as_os_str().is_empty()) {
        let library = skid_abi::load_into(&mut registry, path)
            .with_context(|| format!("loading plugin library {}", path.display()))?;
        for plugin in library.plugins() {
            tracing::debug!(library = library.name(), plugin = plugin.name(), slot = %plugin.slot(), path = %path.display(), "loaded plugin");
        }
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
pub fn run(
    registry: &Registry,
    profile: Option<String>,
    layers: &LayerArgs,
    viewers: &viewers::Viewers,
) -> Result<()> {
    let config = load(&sources(profile, layers), registry)?;
    if config.deploy.robot.is_some() {
        return robot::run_robot(registry, config, viewers);
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
    let _viewers = viewers.attach(&mut fleet)?;
    tracing::info!(robots = fleet.robots.len(), "plugins built; running");
    let bar = progress_bar(total_scans);
    let mut progress = ProgressLog::new(total_scans);
    let started = std::time::Instant::now();
    let outcome = fleet.run_lockstep(|scans| {
        bar.set_position(scans as u64);
        progress.update(scans as u64);
    });
    bar.finish_and_clear();
    let summary = match outcome {
        Ok(summary) => summary,
        Err(error) => {
            // What exists at the stop goes into the incomplete folder; then the front-end processes
            // stop, and the folder is marked with the reason.
            let reason = error.to_string();
            let partial =
                skid_runtime::RunSummary::interrupted(&fleet, started.elapsed().as_secs_f64(), &reason);
            tracing::info!(%reason, "the run stopped early; writing what it has");
            if let Err(write_error) = skid_runtime::write_partial_outputs(&fleet, &partial) {
                tracing::warn!(error = %write_error, "could not write the partial outputs");
            }
            let config = fleet.config.clone();
            drop(fleet);
            return Err(abandoned(&config, error));
        }
    };
    tracing::info!(
        scans = progress.scans,
        wall_s = summary.wall_s,
        "robots finished; writing outputs"
    );
    let (folder, metrics) = skid_runtime::write_outputs(&fleet, &summary)?;
    tracing::info!(folder = %folder.display(), wall_s = summary.wall_s, "finished");
    println!("{}", serde_json::to_string(&summary)?);
    table::show(&table::run_table(&summary, &metrics, &folder));
    check_every_robot_registered(&summary)
}

/// A run in which a robot registered no scan produced nothing for it: that is a failure, with the
/// reason, even though the outputs were written.
pub(crate) fn check_every_robot_registered(summary: &skid_runtime::RunSummary) -> Result<()> {
    let empty: Vec<String> = summary
        .robots
        .iter()
        .filter(|robot| robot.scans == 0)
        .map(|robot| {
            if robot.scans_read == 0 {
                format!("robot {} read no scan from its source", robot.robot)
            } else {
                format!(
                    "robot {} read {} scans and the odometry skipped every one (the log says why)",
                    robot.robot, robot.scans_read
                )
            }
        })
        .collect();
    if !empty.is_empty() {
        bail!("the run registered no scan for {}", empty.join("; "));
    }
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

/// Progress as log lines every few seconds when stderr is not a terminal (a log file, CI), where the
/// progress bar is not drawn.
struct ProgressLog {
    total_scans: u64,
    scans: u64,
    started: std::time::Instant,
    last: std::time::Instant,
    enabled: bool,
    /// Whether the end of the scans was said (the loops, the last optimisation and the outputs follow).
    scans_done: bool,
}

impl ProgressLog {
    const PERIOD_S: f64 = 10.0;

    fn new(total_scans: u64) -> Self {
        let now = std::time::Instant::now();
        Self {
            total_scans,
            scans: 0,
            started: now,
            last: now,
            enabled: !std::io::IsTerminal::is_terminal(&std::io::stderr()),
            scans_done: false,
        }
    }

    fn update(&mut self, scans: u64) {
        self.scans = scans;
        if self.total_scans > 0 && scans >= self.total_scans && !self.scans_done {
            // The estimate below counts scans only; say when they are done, since the loops still in
            // flight, the last optimisation and the outputs take a while longer.
            self.scans_done = true;
            tracing::info!(
                "all {scans} scans read in {:.0} s; finishing the loops in flight, optimising and writing \
                 the outputs",
                self.started.elapsed().as_secs_f64()
            );
            return;
        }
        if !self.enabled || self.last.elapsed().as_secs_f64() < Self::PERIOD_S {
            return;
        }
        self.last = std::time::Instant::now();
        let elapsed_s = self.started.elapsed().as_secs_f64();
        let rate = scans as f64 / elapsed_s.max(1e-9);
        if self.total_scans > 0 {
            let remaining_s = self.total_scans.saturating_sub(scans) as f64 / rate.max(1e-9);
            tracing::info!(
                "{scans}/{} scans ({:.0}%), {rate:.1} scans/s, {elapsed_s:.0} s elapsed, about {remaining_s:.0} s of scans left",
                self.total_scans,
                100.0 * scans as f64 / self.total_scans as f64
            );
        } else {
            tracing::info!("{scans} scans, {rate:.1} scans/s, {elapsed_s:.0} s elapsed");
        }
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
                    "docs": info.docs,
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
            print_parameters(info.defaults.table(), &info.docs, "");
            println!();
        }
    }
    Ok(())
}

/// A plugin's default parameters, one per line with what it means, nested tables as `[a.b]` headers.
fn print_parameters(table: &toml::Table, docs: &skid_core::registry::ParamDocs, prefix: &str) {
    let mut nested = Vec::new();
    for (key, value) in table {
        let full = if prefix.is_empty() {
            key.clone()
        } else {
            format!("{prefix}.{key}")
        };
        match value {
            toml::Value::Table(inner) => nested.push((full, inner)),
            _ => {
                let shown = format!("{key} = {value}");
                match docs.get(&full) {
                    Some(doc) => println!("      {shown:<36} # {doc}"),
                    None => println!("      {shown}"),
                }
            }
        }
    }
    for (full, inner) in nested {
        match docs.get(&full) {
            Some(doc) => println!("      [{full}]  # {doc}"),
            None => println!("      [{full}]"),
        }
        print_parameters(inner, docs, &full);
    }
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
    let config = sources.load_and_check_files(registry)?;
    let transport = &config.slot(skid_core::Slot::Transport).plugin;
    println!(
        "{}: ok (every value is in range and the files it names exist here; the `{transport}` transport's \
         endpoints and peers are only tried when it opens, at `skid run`)",
        file.display()
    );
    Ok(())
}
