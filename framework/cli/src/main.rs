//! `skid`: the SKiD command line.
//!
//! - `skid run [PROFILE]` runs the fleet described by the default configuration (plus a profile);
//! - `skid plugins` lists every registered plugin with its default parameters;
//! - `skid config show|check` prints the merged configuration or validates a file;
//! - `skid bag info` describes a ROS bag or MCAP file.
//!
//! `-v`/`-vv` and `-q` set the log level; `RUST_LOG` overrides both.

/// The allocator of every SKiD process. Scans come and go as buffers of megabytes: glibc's allocator
/// hands each one back to the kernel when it is freed and page-faults to get it again for the next
/// scan, while mimalloc keeps the pages for reuse (bag decoding runs 25-45% faster with it; see
/// `cargo xtask bench io`).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

mod commands;
mod logging;
#[cfg(feature = "rerun")]
mod rerun_view;
mod signals;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};

#[derive(Parser, Debug)]
#[command(
    name = "skid",
    version,
    about = "SKiD: robust, lightweight, distributed multi-robot LiDAR SLAM"
)]
struct Cli {
    /// More log output (-v debug, -vv trace).
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    /// Only warnings and errors.
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    quiet: bool,
    /// Load an out-of-tree plugin library (a cdylib built with `skid-abi`); repeatable. Also read from
    /// `SKID_PLUGIN_LIBS` when no `--plugin-lib` is given (paths separated by `:`; empty entries are
    /// ignored).
    #[arg(long = "plugin-lib", value_name = "PATH", global = true)]
    plugin_libs: Vec<PathBuf>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Run the fleet: every robot's pipeline on its source, outputs under `<output_dir>/<name>/`.
    Run {
        /// Profile overlay from `configs/profiles/` (for example `scan_context`).
        profile: Option<String>,
        /// The same as the positional PROFILE.
        #[arg(long = "profile", value_name = "PROFILE", conflicts_with = "profile")]
        profile_flag: Option<String>,
        #[command(flatten)]
        layers: LayerArgs,
        /// Stream the run to a running Rerun viewer at URL (default rerun+http://127.0.0.1:9876/proxy;
        /// start one with `rerun`). Needs skid built with `--features rerun`.
        #[arg(long, value_name = "URL", num_args = 0..=1, default_missing_value = "rerun+http://127.0.0.1:9876/proxy")]
        rerun: Option<String>,
        /// Save the run as a Rerun recording (.rrd) for `rerun FILE.rrd`. Needs `--features rerun`.
        #[arg(long, value_name = "FILE", conflicts_with = "rerun")]
        rerun_save: Option<PathBuf>,
    },
    /// List every registered plugin: slot, name, summary and default parameters.
    Plugins {
        /// Only this slot (source, odometry, descriptor, coarse, fine, verifier, backend, transport).
        #[arg(long)]
        slot: Option<String>,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
        /// Run the slot's conformance suite on every plugin of this out-of-tree library and report each
        /// check (exit status 1 when one fails).
        #[arg(long, value_name = "LIB")]
        check: Option<PathBuf>,
    },
    /// Show or check configurations.
    #[command(subcommand)]
    Config(ConfigCommand),
    /// Print the descriptors of point-cloud files (KITTI .bin, PCD, PLY) as JSON lines.
    Describe {
        /// Descriptor plugin (solid, scan_context, iris, …).
        #[arg(long, default_value = "solid")]
        descriptor: String,
        /// Point-cloud files (KITTI .bin, PCD or PLY).
        #[arg(required = true)]
        files: Vec<PathBuf>,
        #[command(flatten)]
        layers: LayerArgs,
    },
    /// Register SOURCE to TARGET (point-cloud files) and print target_from_source and stage timings.
    Register {
        /// The fixed cloud (KITTI .bin, PCD or PLY).
        target: PathBuf,
        /// The cloud to move onto the target.
        source: PathBuf,
        /// Coarse registration plugin, or `none` to start from the identity.
        #[arg(long, default_value = "none")]
        coarse: String,
        /// Fine registration plugin, or `none`.
        #[arg(long, default_value = "gicp")]
        fine: String,
        #[command(flatten)]
        layers: LayerArgs,
    },
    /// Draw a run's plots again (trajectories.png, errors.png, map.png) from its record, RUN_DIR/run.mcap.
    Plot {
        /// The run's folder (`runs/<name>`).
        run_dir: PathBuf,
    },
    /// Trajectory errors of EST against GT (TUM or KITTI files): ATE/ARE after alignment, RPE, drift.
    Eval {
        /// Ground-truth trajectory (TUM or KITTI poses, detected from the content).
        #[arg(long)]
        gt: PathBuf,
        /// Estimated trajectory (TUM or KITTI poses).
        #[arg(long)]
        est: PathBuf,
        /// Alignment before the absolute errors: se3 (evo -a), sim3 (evo -as) or none.
        #[arg(long, default_value = "se3", value_parser = ["se3", "sim3", "none"])]
        align: String,
    },
    /// Optimise a g2o pose graph (2D or 3D) and print iterations, time and costs (GTSAM convention).
    Pgo {
        /// A g2o file (2D or 3D: VERTEX_SE2/EDGE_SE2 or VERTEX_SE3:QUAT/EDGE_SE3:QUAT).
        file: PathBuf,
        /// Robust kernel on loop closures (gnc: graduated non-convexity with truncated least squares).
        #[arg(long, default_value = "none", value_parser = ["none", "huber", "cauchy", "tls", "gnc"])]
        robust: String,
        /// Initial guess: file (the file's poses) or chordal (the chordal relaxation).
        #[arg(long, default_value = "file", value_parser = ["file", "chordal"])]
        init: String,
        /// Write the optimised graph here as g2o.
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Pairwise consistency maximisation on a multi-robot pose graph: per-robot g2o files (or folders of
    /// them) with GTSAM symbol keys; prints the accepted loop closures and the time.
    Pcm {
        /// g2o files, or folders whose .g2o files are all read.
        #[arg(required = true)]
        paths: Vec<PathBuf>,
        /// Replace the files' information matrices by identities.
        #[arg(long)]
        unit_covariance: bool,
        /// Then optimise the odometry and the accepted loops: gnc (graduated non-convexity, TLS).
        #[arg(long, value_parser = ["gnc"])]
        then: Option<String>,
        /// One JSON line instead of the text.
        #[arg(long)]
        json: bool,
    },
    /// Replay a recorded collaborative SLAM problem (a JSON Robot Log file, e.g. COSMO-Bench) through the
    /// configured verifier and back-end; prints each robot's ATE against the file's ground truth and the
    /// loops kept and dropped against its outlier labels.
    Replay {
        /// The `.jrl` file.
        file: PathBuf,
        /// incremental: one verifier and back-end per robot, measurements in stamp order, accepted
        /// inter-robot loops shared as `skid run` shares them; batch: one graph holding every robot.
        #[arg(long, default_value = "incremental", value_parser = ["incremental", "batch"])]
        mode: String,
        /// Write each robot's trajectory.tum, ground_truth.tum and pose_graph.g2o under DIR/robot_<letter>/.
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// One JSON line instead of the table.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        layers: LayerArgs,
    },
    /// Inspect ROS bags and MCAP files.
    #[command(subcommand)]
    Bag(BagCommand),
    /// Inspect and merge the sessions runs leave (`runs/<name>/session`).
    #[command(subcommand)]
    Session(SessionCommand),
    /// Fleet set-up for real networks.
    #[command(subcommand)]
    Fleet(FleetCommand),
    /// The simulator on its own: export KITTI-format folders or a preview PNG.
    Sim {
        #[command(subcommand)]
        command: SimCommand,
    },
    /// Run the configured odometry alone on a KITTI-format folder or a bag (topics from `[source.bag]`,
    /// e.g. `--set source.bag.points_topic=/points`); writes TUM and KITTI trajectories.
    Odometry {
        /// A KITTI sequence folder (with `velodyne/`), a ROS 1 `.bag`, a ROS 2 bag folder or an `.mcap` file.
        folder: PathBuf,
        /// Output folder for trajectory.tum and trajectory.kitti [default: runs/odometry].
        #[arg(long)]
        out: Option<PathBuf>,
        #[command(flatten)]
        layers: LayerArgs,
    },
    /// One stage of a robot in its own process (started by `skid run` under `deploy.mode = "processes"`).
    #[command(hide = true)]
    Stage {
        #[command(subcommand)]
        command: StageCommand,
    },
}

#[derive(Subcommand, Debug)]
enum BagCommand {
    /// Topics, message types, counts, rates, duration, and each point-cloud topic's field layout.
    Info {
        /// A ROS 1 `.bag`, a ROS 2 bag folder (`metadata.yaml` + `.mcap`/`.db3`) or an `.mcap` file.
        path: PathBuf,
        /// Print one JSON line instead of the table.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Subcommand, Debug)]
enum SessionCommand {
    /// Robots, keyframes, points, path lengths, loops and placements of a session, its descriptor and
    /// size on disk.
    Info {
        /// A session folder, or a run folder holding one.
        path: PathBuf,
        /// Print one JSON line instead of the table.
        #[arg(long)]
        json: bool,
    },
    /// Place sessions in the first one's map frame by inter-session loops (the configured descriptor,
    /// registration and verifier, as in a run) and write them as one session with its `map.ply` and
    /// `merge.json`; a session whose place is not verified, or whose robots disagree on it, is reported
    /// and left out.
    Merge {
        /// Session folders (or run folders holding one); the first is the base.
        #[arg(required = true, num_args = 2..)]
        sessions: Vec<PathBuf>,
        /// The folder the merged session is written to (it must not exist or be empty).
        #[arg(long)]
        out: PathBuf,
        /// Override a value of each session's configuration while it is localised:
        /// `--set section.key=value` (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        sets: Vec<String>,
        /// Print the report as one JSON line instead of the table.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Subcommand, Debug)]
enum FleetCommand {
    /// Write a test fleet's certificates for the zenoh transport's mutual TLS: a CA (`ca.pem`, `ca.key`)
    /// and `robot-<id>.pem`/`.key` for robots 0..ROBOTS, and each robot's configuration `robot-<id>.toml`
    /// (its `deploy.robot`, endpoints and certificate files; for `skid run --config FILE`), printed too.
    Certs {
        /// Number of robots.
        #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
        robots: u32,
        /// Years the certificates stay valid.
        #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(i32).range(1..=30))]
        years: i32,
        /// The folder to write into (created when missing).
        dir: PathBuf,
        /// Replace a CA already in the folder (the robots' certificates signed by it stop working).
        #[arg(long)]
        overwrite: bool,
        /// The robots' addresses, one per robot in id order (e.g. `10.0.0.10,10.0.0.11`): each robot
        /// listens on port 7447 of every interface and connects to the others. Without it every robot runs
        /// on this machine, robot i on 127.0.0.1 port 7447 + i.
        #[arg(long, value_delimiter = ',')]
        hosts: Vec<String>,
    },
}

#[derive(Subcommand, Debug)]
enum StageCommand {
    /// Source and odometry of one robot, publishing each scan's output over iceoryx2.
    FrontEnd {
        /// The host's effective configuration.
        #[arg(long)]
        config_file: PathBuf,
        #[arg(long)]
        robot: u32,
        /// iceoryx2 namespace of this robot's topics.
        #[arg(long)]
        namespace: String,
        /// Outputs the host already has (after a restart): replayed without publishing.
        #[arg(long, default_value_t = 0)]
        skip: u64,
        /// Exit when standard input closes (the host holds its other end).
        #[arg(long)]
        exit_with_host: bool,
    },
}

#[derive(Args, Debug)]
struct SimFlags {
    /// The world to simulate.
    #[arg(long, default_value = "planetary", value_parser = ["planetary", "cave", "urban", "blocks"])]
    world: String,
    /// The LiDAR model.
    #[arg(long, default_value = "os1-64", value_parser = ["vlp16", "os1-32", "os1-64", "hdl64e", "avia"])]
    sensor: String,
    /// Robots (1 to 16).
    #[arg(long, default_value_t = 3)]
    robots: u32,
    /// Scans per robot; 0 runs each route to its end.
    #[arg(long, default_value_t = 0)]
    frames: u32,
    /// Seeds the world, the routes and every noise stream (the same seed gives the same scans).
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// What the fleet does.
    #[arg(long, default_value = "explore_meet", value_parser = ["explore_meet", "rendezvous", "crossing", "reverse", "partial", "loner", "shared_route", "convoy"])]
    mission: String,
    /// Length of each robot's route, metres.
    #[arg(long, value_name = "METRES", default_value_t = 600.0)]
    route_length_m: f64,
}

#[derive(Subcommand, Debug)]
enum SimCommand {
    /// Write each robot as a KITTI-format folder (velodyne/*.bin, times.txt, poses.txt, calib.txt), a
    /// ROS 1 bag (`robotN.bag`, LZ4 chunks) or a ROS 2 MCAP bag folder (`robotN/`), with /points, /imu
    /// and /ground_truth.
    Export {
        #[command(flatten)]
        flags: SimFlags,
        /// kitti (velodyne/*.bin folders), ros1 (.bag) or mcap (ROS 2 bag folders).
        #[arg(long, default_value = "kitti", value_parser = ["kitti", "ros1", "mcap"])]
        format: String,
        /// Output folder; it must not exist or be empty unless `--overwrite`.
        out: PathBuf,
        /// Replace a non-empty OUT (whole, once the export is complete).
        #[arg(long)]
        overwrite: bool,
    },
    /// Write a top-down PNG of the world with the routes.
    Preview {
        #[command(flatten)]
        flags: SimFlags,
        /// The PNG file to write.
        out: PathBuf,
        /// Width and height of the image in pixels.
        #[arg(long, default_value_t = 1024)]
        size_px: u32,
    },
}

#[derive(Subcommand, Debug)]
enum ConfigCommand {
    /// Print the merged, validated configuration as TOML.
    Show {
        /// Profile overlay from configs/profiles/ (or the embedded copy).
        #[arg(long)]
        profile: Option<String>,
        #[command(flatten)]
        layers: LayerArgs,
    },
    /// Validate FILE (an overlay on the default configuration); exits non-zero with the file, key and
    /// expected values when something is wrong.
    Check {
        /// The overlay file to check.
        file: PathBuf,
        /// Profile overlay applied under FILE.
        #[arg(long)]
        profile: Option<String>,
        #[command(flatten)]
        layers: LayerArgs,
    },
}

/// Configuration layers shared by every command that loads a configuration.
#[derive(Args, Debug, Clone, Default)]
struct LayerArgs {
    /// Override one value: `--set section.key=value` (repeatable; TOML values, bare strings allowed).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// Extra overlay files merged after the profile (repeatable).
    #[arg(long = "config", value_name = "FILE")]
    overlays: Vec<PathBuf>,
    /// Configuration folder holding `default.toml` and `profiles/` [default: $SKID_CONFIG_DIR, else the
    /// nearest `configs/` above the current folder, else the embedded default].
    #[arg(long, value_name = "DIR")]
    config_dir: Option<PathBuf>,
}

impl SimFlags {
    fn args(&self) -> commands::extra::SimArgs<'_> {
        commands::extra::SimArgs {
            world: &self.world,
            sensor: &self.sensor,
            robots: self.robots,
            frames: self.frames,
            seed: self.seed,
            mission: &self.mission,
            route_length_m: self.route_length_m,
        }
    }
}

/// The error and its causes on one line, each said once (an error whose message already quotes its
/// cause is not followed by it again), with control characters from file contents escaped so a
/// corrupt header cannot write to the terminal.
fn error_text(error: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in error.chain() {
        let part = cause.to_string();
        if part.is_empty() || text.contains(&part) {
            continue;
        }
        if !text.is_empty() {
            text.push_str(": ");
        }
        text.push_str(&part);
    }
    text.chars()
        .flat_map(|c| {
            let escaped: Vec<char> = if c.is_control() && c != '\n' {
                c.escape_default().collect()
            } else {
                vec![c]
            };
            escaped
        })
        .collect()
}

/// The signal that stopped the command, when its error is an interrupted run.
fn interrupted_by(error: &anyhow::Error) -> Option<i32> {
    error.chain().find_map(|cause| match cause.downcast_ref() {
        Some(skid_runtime::RuntimeError::Interrupted { signal }) => Some(*signal),
        _ => None,
    })
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    logging::init(cli.verbose, cli.quiet);
    // A front-end stage dies with its signal (its host notices); every other command stops cleanly.
    if !matches!(cli.command, Command::Stage { .. }) {
        signals::install();
    }
    // `--plugin-lib` wins over the environment, as for every other option.
    let mut plugin_libs = cli.plugin_libs.clone();
    if let Some(listed) = std::env::var_os("SKID_PLUGIN_LIBS").filter(|_| plugin_libs.is_empty()) {
        plugin_libs.extend(std::env::split_paths(&listed).filter(|path| !path.as_os_str().is_empty()));
    }
    let result = commands::registry(&plugin_libs).and_then(|registry| match cli.command {
        Command::Run {
            profile,
            profile_flag,
            layers,
            rerun,
            rerun_save,
        } => {
            let viewers = commands::viewers::Viewers {
                rerun_url: rerun,
                rerun_save,
            };
            commands::run(&registry, profile.or(profile_flag), &layers, &viewers)
        }
        Command::Plugins {
            check: Some(library), ..
        } => commands::plugin_check::check_library(&library),
        Command::Plugins { slot, json, .. } => commands::plugins(&registry, slot.as_deref(), json),
        Command::Config(ConfigCommand::Show { profile, layers }) => {
            commands::config_show(&registry, profile, &layers)
        }
        Command::Config(ConfigCommand::Check {
            file,
            profile,
            layers,
        }) => commands::config_check(&registry, &file, profile, &layers),
        Command::Describe {
            descriptor,
            files,
            layers,
        } => commands::tools::describe(&registry, &descriptor, &files, &layers),
        Command::Register {
            target,
            source,
            coarse,
            fine,
            layers,
        } => commands::tools::register(&registry, &target, &source, Some(&coarse), Some(&fine), &layers),
        Command::Eval { gt, est, align } => commands::extra::eval(&gt, &est, &align),
        Command::Plot { run_dir } => commands::plot::plot(&run_dir),
        Command::Pcm {
            paths,
            unit_covariance,
            then,
            json,
        } => commands::pcm::pcm(&paths, unit_covariance, then.is_some(), json),
        Command::Pgo {
            file,
            robust,
            init,
            out,
        } => commands::extra::pgo(&file, &robust, &init, out.as_deref()),
        Command::Replay {
            file,
            mode,
            out,
            json,
            layers,
        } => commands::replay::replay(&registry, &file, &mode, out.as_deref(), json, &layers),
        Command::Sim {
            command:
                SimCommand::Export {
                    flags,
                    format,
                    out,
                    overwrite,
                },
        } => commands::extra::sim_export(&flags.args(), &format, &out, overwrite),
        Command::Sim {
            command: SimCommand::Preview { flags, out, size_px },
        } => commands::extra::sim_preview(&flags.args(), &out, size_px),
        Command::Bag(BagCommand::Info { path, json }) => commands::bag::info(&path, json),
        Command::Session(SessionCommand::Info { path, json }) => commands::session::info(&path, json),
        Command::Session(SessionCommand::Merge {
            sessions,
            out,
            sets,
            json,
        }) => commands::session::merge(&registry, sessions, out, sets, json),
        Command::Fleet(FleetCommand::Certs {
            hosts,
            robots,
            years,
            dir,
            overwrite,
        }) => commands::fleet::certs(robots, years, &dir, overwrite, &hosts),
        Command::Odometry { folder, out, layers } => {
            commands::tools::odometry(&registry, &folder, out.as_deref(), &layers)
        }
        Command::Stage {
            command:
                StageCommand::FrontEnd {
                    config_file,
                    robot,
                    namespace,
                    skip,
                    exit_with_host,
                },
        } => {
            if exit_with_host {
                skid_runtime::exit_when_host_exits();
            }
            commands::extra::stage_front_end(&registry, &config_file, robot, &namespace, skip)
        }
    });
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {}", error_text(&error));
            match interrupted_by(&error) {
                Some(signal) => ExitCode::from(signals::exit_status(signal)),
                None => ExitCode::FAILURE,
            }
        }
    }
}
