//! Small command-line front end to the simulator library, for use before the `skid` CLI wires it in:
//!
//! `sim-tool preview WORLD OUT.png [ROBOTS [SEED]]` renders a top-down preview with the robots' paths;
//! `sim-tool export WORLD SENSOR OUT_DIR [ROBOTS [FRAMES [SEED]]]` writes KITTI folders per robot.

use std::process::ExitCode;

use skid_sim::{SimConfig, export_fleet_kitti, preview_fleet_png};

fn run(args: &[String]) -> Result<String, String> {
    let arg = |i: usize| args.get(i).map(String::as_str);
    let number = |i: usize, default: u64| {
        arg(i).map_or(Ok(default), |a| {
            a.parse::<u64>().map_err(|e| format!("`{a}`: {e}"))
        })
    };
    match (arg(0), arg(1), arg(2), arg(3)) {
        (Some("preview"), Some(world), Some(out), _) => {
            let config = SimConfig { world: world.to_owned(), robots: number(3, 3)? as u32, seed: number(4, 7)?, ..SimConfig::default() };
            preview_fleet_png(out, &config, 1024).map_err(|e| e.to_string())?;
            Ok(format!("wrote {out}"))
        }
        (Some("export"), Some(world), Some(sensor), Some(out)) => {
            let config = SimConfig {
                world: world.to_owned(),
                sensor: sensor.to_owned(),
                robots: number(4, 1)? as u32,
                frames: number(5, 100)? as u32,
                seed: number(6, 7)?,
                ..SimConfig::default()
            };
            let threads = std::thread::available_parallelism().map_or(1, usize::from);
            let summaries = export_fleet_kitti(out, &config, threads).map_err(|e| e.to_string())?;
            Ok(summaries.iter().map(|s| format!("{}: {} scans, {} points", s.dir.display(), s.scans, s.points)).collect::<Vec<_>>().join("\n"))
        }
        _ => Err("usage: sim-tool preview WORLD OUT.png [ROBOTS [SEED]] | sim-tool export WORLD SENSOR OUT_DIR [ROBOTS [FRAMES [SEED]]]".to_owned()),
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match run(&args) {
        Ok(message) => {
            println!("{message}");
            ExitCode::SUCCESS
        }
        Err(message) => {
            eprintln!("{message}");
            ExitCode::FAILURE
        }
    }
}
