//! `skid session info PATH`: what a saved session holds — its robots, keyframes, points, paths, loops,
//! which robots are placed in the session's map frame, its descriptor and its size on disk. PATH is a
//! session folder or a run folder holding one (`runs/<name>/session`).
//!
//! `skid session merge A B … --out C`: the sessions placed in A's map frame and written as one
//! (`skid_merge`), with a table of what was placed and how well.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use skid_core::Registry;
use skid_merge::{MergeRequest, merge_sessions};
use skid_session::{SessionInfo, read_session};

use crate::commands::table::Table;

/// `skid session info PATH [--json]`.
pub fn info(path: &Path, json: bool) -> Result<()> {
    if !path.exists() {
        anyhow::bail!("{}: no such session folder", path.display());
    }
    let dir = skid_session::session_folder(path);
    let session = read_session(&dir).with_context(|| format!("reading the session in {}", dir.display()))?;
    let info = SessionInfo::of(&session, &dir)?;
    if json {
        println!("{}", serde_json::to_string(&info)?);
        return Ok(());
    }
    println!("session:    {} ({})", info.name, dir.display());
    println!("written by: SKiD {}", info.skid_version);
    match &info.descriptor {
        Some((kind, length)) => println!("descriptor: {kind}, {length} values"),
        None => println!("descriptor: none (the keyframes were not described)"),
    }
    println!("on disk:    {:.1} MB", info.bytes_on_disk as f64 / 1e6);
    let mut table = Table::new(&[
        "robot",
        "keyframes",
        "described",
        "points",
        "path m",
        "duration s",
        "loops",
        "peers held",
        "placed",
    ]);
    for robot in &info.robots {
        let peers: Vec<String> = robot.peers_in_graph.iter().map(u32::to_string).collect();
        table.row(vec![
            robot.robot.to_string(),
            robot.keyframes.to_string(),
            robot.described.to_string(),
            robot.points.to_string(),
            format!("{:.1}", robot.path_length_m),
            format!("{:.1}", robot.duration_s),
            robot.loops.to_string(),
            if peers.is_empty() {
                "-".into()
            } else {
                peers.join(",")
            },
            if robot.placed { "yes".into() } else { "no".into() },
        ]);
    }
    print!("{}", table.render());
    Ok(())
}

fn figure(value: Option<f64>, digits: usize) -> String {
    value.map_or_else(|| "-".to_owned(), |v| format!("{v:.digits$}"))
}

/// `skid session merge A B … --out C [--set KEY=VALUE]… [--json]`.
pub fn merge(
    registry: &Registry,
    sessions: Vec<PathBuf>,
    out: PathBuf,
    sets: Vec<String>,
    json: bool,
) -> Result<()> {
    for path in &sessions {
        if !path.exists() {
            anyhow::bail!("{}: no such session folder", path.display());
        }
    }
    let request = MergeRequest { sessions, out, sets };
    let report = merge_sessions(&request, registry)?;
    if json {
        println!("{}", serde_json::to_string(&report)?);
        return Ok(());
    }
    println!("base:   {}", report.base);
    let mut table = Table::new(&[
        "session",
        "keyframes",
        "robots localised",
        "loops",
        "placed",
        "error m",
        "error deg",
        "time s",
    ]);
    for session in &report.sessions {
        let localised = session.robots.iter().filter(|r| r.localised).count();
        table.row(vec![
            session.name.clone(),
            session.keyframes.to_string(),
            format!("{localised} of {}", session.robots.len()),
            session.robots.iter().map(|r| r.loops).sum::<usize>().to_string(),
            if session.placed { "yes".into() } else { "no".into() },
            figure(session.error_m, 3),
            figure(session.error_deg, 2),
            format!("{:.1}", session.localise_s),
        ]);
    }
    print!("{}", table.render());
    for session in report.sessions.iter().filter(|s| !s.placed) {
        println!(
            "not placed: {} ({})",
            session.name,
            session.reason.as_deref().unwrap_or("-")
        );
    }
    println!(
        "merged: {} ({} robots, {} keyframes, map.ply {} points) in {:.1} s",
        report.out, report.robots, report.keyframes, report.map_points, report.wall_s
    );
    Ok(())
}
