//! `skid fleet certs`: a test fleet's CA and robot certificates for the zenoh transport's mutual TLS,
//! and the configuration lines each robot needs.

use std::path::Path;

#[cfg(feature = "zenoh")]
use anyhow::Context;

/// The zenoh port robot `robot` listens on: 7447 on its own host, or 7447 + its id when every robot runs
/// on this machine.
#[cfg(feature = "zenoh")]
fn port_of(robot: u32, on_this_machine: bool) -> u32 {
    if on_this_machine { 7447 + robot } else { 7447 }
}

/// Robot `robot`'s configuration overlay: its id, the fleet size, the zenoh transport with its
/// endpoints and its three certificate files.
#[cfg(feature = "zenoh")]
fn robot_config(robot: u32, robots: u32, hosts: &[String], tls: [&Path; 3]) -> String {
    let on_this_machine = hosts.is_empty();
    let host = |id: u32| {
        hosts
            .get(id as usize)
            .map_or("127.0.0.1", String::as_str)
            .to_owned()
    };
    let listen_host = if on_this_machine {
        "127.0.0.1".to_owned()
    } else {
        "0.0.0.0".to_owned()
    };
    let connect: Vec<String> = (0..robots)
        .filter(|&other| other != robot)
        .map(|other| format!("\"tls/{}:{}\"", host(other), port_of(other, on_this_machine)))
        .collect();
    let [ca, certificate, key] = tls.map(|path| format!("{:?}", path.display().to_string()));
    format!(
        "# Robot {robot} of {robots}: `skid run --config robot-{robot}.toml` on its machine.\n\
         [run]\nrobots = {robots}\n\n[deploy]\nrobot = {robot}\n\n\
         [transport]\nplugin = \"zenoh\"\n\n[transport.zenoh]\n\
         listen = [\"tls/{listen_host}:{}\"]\nconnect = [{}]\n\n\
         [transport.zenoh.tls]\nca_certificate = {ca}\ncertificate = {certificate}\nprivate_key = {key}\n",
        port_of(robot, on_this_machine),
        connect.join(", ")
    )
}

/// Writes the certificates and each robot's configuration into `dir` and prints the configurations. A
/// folder that already holds a CA is refused unless `overwrite`: a new CA silently invalidates every
/// robot certificate the old one signed. `hosts` names the robots' addresses (empty: all on this machine).
#[cfg(feature = "zenoh")]
pub fn certs(robots: u32, years: i32, dir: &Path, overwrite: bool, hosts: &[String]) -> anyhow::Result<()> {
    if !hosts.is_empty() && hosts.len() != robots as usize {
        anyhow::bail!(
            "--hosts names {} addresses for --robots {robots}: give one per robot, in id order",
            hosts.len()
        );
    }
    let existing: Vec<String> = ["ca.pem", "ca.key"]
        .iter()
        .filter(|name| dir.join(name).exists())
        .map(|name| dir.join(name).display().to_string())
        .collect();
    if !existing.is_empty() && !overwrite {
        anyhow::bail!(
            "{} already holds a fleet CA ({}); certificates it signed stop working when it is replaced: \
             choose another folder, or pass --overwrite to replace it",
            dir.display(),
            existing.join(", ")
        );
    }
    let files = skid_transport_zenoh::write_fleet_certificates(dir, robots, years)
        .with_context(|| format!("writing the fleet's certificates into {}", dir.display()))?;
    // The configurations name the files by absolute path, so they work from any folder.
    let absolute = |path: &Path| std::fs::canonicalize(path).unwrap_or_else(|_| path.to_owned());
    println!(
        "wrote the fleet CA {} (keep its key {} off the robots) and {robots} robot certificates",
        files.ca_certificate.display(),
        files.ca_private_key.display()
    );
    for robot in &files.robots {
        let (ca, certificate, key) = (
            absolute(&files.ca_certificate),
            absolute(&robot.certificate),
            absolute(&robot.private_key),
        );
        let config = robot_config(robot.robot, robots, hosts, [&ca, &certificate, &key]);
        let path = dir.join(format!("robot-{}.toml", robot.robot));
        std::fs::write(&path, &config).with_context(|| format!("writing {}", path.display()))?;
        println!();
        println!(
            "# {}: copy it with ca.pem and the robot's two files (same paths) to robot {}",
            path.display(),
            robot.robot
        );
        print!("{config}");
    }
    Ok(())
}

/// Without the `zenoh` feature there is no transport to make certificates for.
#[cfg(not(feature = "zenoh"))]
pub fn certs(
    _robots: u32,
    _years: i32,
    _dir: &Path,
    _overwrite: bool,
    _hosts: &[String],
) -> anyhow::Result<()> {
    anyhow::bail!(
        "this skid was built without zenoh, whose mutual TLS these certificates are for; build it with \
         `cargo build --release -p skid --features zenoh`"
    )
}
