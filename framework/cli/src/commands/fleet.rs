//! `skid fleet certs`: a test fleet's CA and robot certificates for the zenoh transport's mutual TLS,
//! and the configuration lines each robot needs.

use std::path::Path;

use anyhow::Context;

/// Writes the certificates into `dir` and prints what each robot's `[transport.zenoh]` needs. A folder
/// that already holds a CA is refused unless `overwrite`: a new CA silently invalidates every robot
/// certificate the old one signed.
pub fn certs(robots: u32, years: i32, dir: &Path, overwrite: bool) -> anyhow::Result<()> {
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
    println!(
        "wrote the fleet CA {} (keep its key {} off the robots) and {robots} robot certificates",
        files.ca_certificate.display(),
        files.ca_private_key.display()
    );
    for robot in &files.robots {
        println!();
        println!(
            "# robot {}: copy ca.pem and its two files to the robot, then",
            robot.robot
        );
        println!("[transport.zenoh.tls]");
        println!(
            "ca_certificate = {:?}",
            files.ca_certificate.display().to_string()
        );
        println!("certificate = {:?}", robot.certificate.display().to_string());
        println!("private_key = {:?}", robot.private_key.display().to_string());
    }
    Ok(())
}
