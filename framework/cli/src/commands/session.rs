//! `skid session info PATH`: what a saved session holds — its robots, keyframes, points, paths, loops,
//! which robots are placed in the session's map frame, its descriptor and its size on disk. PATH is a
//! session folder or a run folder holding one (`runs/<name>/session`).

use std::path::Path;

use anyhow::{Context, Result};
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
