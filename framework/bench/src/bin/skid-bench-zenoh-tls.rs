//! `cargo xtask bench zenoh-tls`: the cost of mutual TLS on the zenoh transport beside plain TCP: bytes
//! on the wire of the default pipeline run as three robot processes, and one-way message latency (the
//! method is `skid_bench::wire_security`'s). Parameters in `configs/bench/zenoh-tls.toml`.

use std::path::Path;
use std::process::Command;
use std::sync::atomic::Ordering;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use skid_bench::wire_security::{CountingRelay, certificates, free_port, one_way_latency, scheme};
use skid_config::ConfigSources;
use skid_runtime::SingleRobot;
use skid_transport_zenoh::{FleetFiles, Security};

/// The child role: robot `SKID_BENCH_TLS_ROBOT` with the `--set`s in `SKID_BENCH_TLS_SETS`.
const CHILD_ROBOT: &str = "SKID_BENCH_TLS_ROBOT";
const CHILD_SETS: &str = "SKID_BENCH_TLS_SETS";
const CHILD_SUMMARY: &str = "SKID_BENCH_TLS_SUMMARY";

#[derive(Debug, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct Settings {
    /// Scans per robot of the three-process run (the default configuration's 1200 is 2 minutes).
    max_scans: u64,
    /// Round trips per payload size in the latency measurement.
    latency_rounds: usize,
    /// Payload sizes in bytes: a descriptor batch, an odometry chain, a keyframe cloud.
    payload_bytes: Vec<usize>,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            max_scans: 1200,
            latency_rounds: 200,
            payload_bytes: vec![300, 4_000, 250_000],
        }
    }
}

#[derive(Debug, Serialize)]
struct FleetRow {
    security: &'static str,
    wire_bytes: u64,
    protocol_bytes: u64,
    wall_s: f64,
    inter_robot_loops: u64,
    ate_m: Vec<Option<f64>>,
}

#[derive(Debug, Serialize)]
struct LatencyRow {
    security: &'static str,
    payload_bytes: usize,
    median_ms: f64,
    p90_ms: f64,
}

/// Runs one robot in this process and writes its summary (the child role).
fn child(robot: &str) -> Result<()> {
    let registry = skid_builtin::registry().context("registering the built-in plugins")?;
    let sets: Vec<String> = std::env::var(CHILD_SETS)?.lines().map(str::to_owned).collect();
    let sources = ConfigSources {
        config_dir: Some(skid_bench::profile::workspace_root().join("configs")),
        sets,
        ..ConfigSources::default()
    };
    let config = sources
        .load(&registry)
        .with_context(|| format!("configuring robot {robot}"))?;
    let mut single = SingleRobot::build(config, &registry)?;
    let summary = single.run(|_| {})?;
    std::fs::write(std::env::var(CHILD_SUMMARY)?, serde_json::to_string(&summary)?)?;
    Ok(())
}

/// The default pipeline as three processes over zenoh with `security`; every link through a relay.
fn fleet_run(security: Security, certs: &FleetFiles, settings: &Settings, out: &Path) -> Result<FleetRow> {
    let listen = [free_port()?, free_port()?, free_port()?];
    // Robot j connects to each robot i < j through its own relay.
    let relays = [(1, 0), (2, 0), (2, 1)].map(|(_, to)| CountingRelay::start(listen[to]));
    let relays: Vec<CountingRelay> = relays.into_iter().collect::<Result<_>>()?;
    let connect: [Vec<u16>; 3] = [vec![], vec![relays[0].port], vec![relays[1].port, relays[2].port]];
    let name = scheme(security);
    let started = Instant::now();
    let mut children = Vec::new();
    for robot in 0..3u32 {
        let files = &certs.robots[robot as usize];
        let endpoints = |ports: &[u16]| {
            let quoted: Vec<String> = ports
                .iter()
                .map(|p| format!("\"{name}/127.0.0.1:{p}\""))
                .collect();
            format!("[{}]", quoted.join(","))
        };
        let sets = [
            format!("deploy.robot={robot}"),
            "deploy.linger_s=10".to_owned(),
            "transport.plugin=zenoh".to_owned(),
            format!("transport.zenoh.security=\"{}\"", security.name()),
            format!("transport.zenoh.listen={}", endpoints(&[listen[robot as usize]])),
            format!("transport.zenoh.connect={}", endpoints(&connect[robot as usize])),
            format!(
                "transport.zenoh.key_prefix=\"skid-bench/{name}/{}\"",
                std::process::id()
            ),
            format!(
                "transport.zenoh.tls.ca_certificate=\"{}\"",
                certs.ca_certificate.display()
            ),
            format!(
                "transport.zenoh.tls.certificate=\"{}\"",
                files.certificate.display()
            ),
            format!(
                "transport.zenoh.tls.private_key=\"{}\"",
                files.private_key.display()
            ),
            format!("run.max_scans={}", settings.max_scans),
            format!("run.output_dir=\"{}\"", out.join("runs").display()),
            format!("run.name={name}"),
        ];
        let summary = out.join(format!("{name}-robot{robot}.json"));
        let child = Command::new(std::env::current_exe()?)
            .env(CHILD_ROBOT, robot.to_string())
            .env(CHILD_SETS, sets.join("\n"))
            .env(CHILD_SUMMARY, &summary)
            .spawn()?;
        children.push((child, summary));
    }
    let mut row = FleetRow {
        security: name,
        wire_bytes: 0,
        protocol_bytes: 0,
        wall_s: 0.0,
        inter_robot_loops: 0,
        ate_m: Vec::new(),
    };
    for (mut child, summary) in children {
        if !child.wait()?.success() {
            bail!("a {name} robot process failed");
        }
        let summary: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&summary)?)?;
        let robot = &summary["robots"][0];
        row.protocol_bytes += robot["messages"]["sent_total"]["bytes"].as_u64().unwrap_or(0);
        row.inter_robot_loops += robot["loops"]["accepted_inter"].as_u64().unwrap_or(0);
        row.ate_m.push(robot["ate_first_pose_aligned_m"].as_f64());
    }
    row.wall_s = started.elapsed().as_secs_f64();
    row.wire_bytes = relays
        .iter()
        .map(|relay| relay.bytes.load(Ordering::Relaxed))
        .sum();
    Ok(row)
}

fn main() -> Result<()> {
    if let Ok(robot) = std::env::var(CHILD_ROBOT) {
        return child(&robot);
    }
    skid_bench::run_profile("zenoh-tls", |settings: &Settings, report, out| {
        let certs = certificates(out, 3)?;
        let mut fleets = Vec::new();
        let mut latencies = Vec::new();
        for security in [Security::PlainTcp, Security::MutualTls] {
            for &bytes in &settings.payload_bytes {
                let timing = one_way_latency(security, &certs, bytes, settings.latency_rounds)?;
                let row = LatencyRow {
                    security: scheme(security),
                    payload_bytes: bytes,
                    median_ms: timing.median_ms,
                    p90_ms: timing.p90_ms,
                };
                eprintln!(
                    "{}: {bytes} B one way {:.3} ms median",
                    row.security, row.median_ms
                );
                report.push(&row)?;
                latencies.push(row);
            }
            let row = fleet_run(security, &certs, settings, out)?;
            eprintln!(
                "{}: {} wire bytes for {} protocol bytes, {:.0} s",
                row.security, row.wire_bytes, row.protocol_bytes, row.wall_s
            );
            report.push(&row)?;
            fleets.push(row);
        }
        Ok(markdown(&fleets, &latencies))
    })
}

fn markdown(fleets: &[FleetRow], latencies: &[LatencyRow]) -> String {
    let mut text = "# Zenoh: mutual TLS against plain TCP\n\n## Bytes of the default pipeline, three robot \
                    processes\n\n| link | bytes on the wire | protocol bytes sent | wire / protocol | wall s | \
                    inter-robot loops | ATE per robot (m) |\n|---|---|---|---|---|---|---|\n"
        .to_owned();
    for row in fleets {
        let ate: Vec<String> = row
            .ate_m
            .iter()
            .map(|a| a.map_or("–".into(), |v| format!("{v:.3}")))
            .collect();
        text.push_str(&format!(
            "| {} | {} | {} | {:.3} | {:.0} | {} | {} |\n",
            row.security,
            row.wire_bytes,
            row.protocol_bytes,
            row.wire_bytes as f64 / row.protocol_bytes.max(1) as f64,
            row.wall_s,
            row.inter_robot_loops,
            ate.join(" / ")
        ));
    }
    text.push_str(
        "\n## One-way latency on 127.0.0.1\n\n| link | payload B | median ms | p90 ms |\n|---|---|---|---|\n",
    );
    for row in latencies {
        text.push_str(&format!(
            "| {} | {} | {:.3} | {:.3} |\n",
            row.security, row.payload_bytes, row.median_ms, row.p90_ms
        ));
    }
    text
}
