//! `cargo xtask bench zenoh-tls`: what mutual TLS costs on the zenoh transport, beside plain TCP.
//!
//! - **Bytes**: the default pipeline as three robot processes (this binary re-run in a child role, one
//!   `SingleRobot` each) over zenoh, every link passing through a counting TCP relay, so the bytes are
//!   those on the wire, TLS records and handshakes included.
//! - **Latency**: two transports in one process, one-way time of a message (half a round trip) for a
//!   descriptor-sized, a chain-sized and a cloud-sized payload, median and 90th percentile.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use skid_core::RobotId;
use skid_core::slots::{Destination, Transport};
use skid_transport_zenoh::{FleetFiles, Security, ZenohConfig, ZenohTransport};

use crate::stats::Timing;

/// A free TCP port on 127.0.0.1.
pub fn free_port() -> Result<u16> {
    Ok(TcpListener::bind("127.0.0.1:0")?.local_addr()?.port())
}

/// The endpoint scheme of `security`.
pub fn scheme(security: Security) -> &'static str {
    match security {
        Security::MutualTls => "tls",
        Security::PlainTcp => "tcp",
    }
}

/// Robot `robot`'s zenoh configuration.
pub fn zenoh_config(
    security: Security,
    certs: &FleetFiles,
    robot: u32,
    listen: Option<u16>,
    connect: &[u16],
    prefix: &str,
) -> ZenohConfig {
    let endpoint = |port: &u16| format!("{}/127.0.0.1:{port}", scheme(security));
    ZenohConfig {
        listen: listen.iter().map(endpoint).collect(),
        connect: connect.iter().map(endpoint).collect(),
        key_prefix: prefix.to_owned(),
        security,
        // A robot outside the fleet gets no files, which opening the transport reports by key.
        tls: certs.tls_for(robot).unwrap_or_default(),
        ..ZenohConfig::default()
    }
}

/// A TCP relay from a local port to `target`, counting the bytes it carries in both directions.
pub struct CountingRelay {
    pub port: u16,
    pub bytes: Arc<AtomicU64>,
}

fn pump(mut from: TcpStream, mut to: TcpStream, bytes: &AtomicU64) {
    let mut buffer = vec![0u8; 64 << 10];
    while let Ok(read) = from.read(&mut buffer) {
        if read == 0 || to.write_all(&buffer[..read]).is_err() {
            break;
        }
        bytes.fetch_add(read as u64, Ordering::Relaxed);
    }
    let _ = to.shutdown(std::net::Shutdown::Both);
}

impl CountingRelay {
    /// Starts relaying connections on a new port to `target_port` (threads end with the process).
    pub fn start(target_port: u16) -> Result<Self> {
        let listener = TcpListener::bind("127.0.0.1:0")?;
        let port = listener.local_addr()?.port();
        let bytes = Arc::new(AtomicU64::new(0));
        let counter = Arc::clone(&bytes);
        std::thread::spawn(move || {
            for incoming in listener.incoming().flatten() {
                let Ok(outgoing) = TcpStream::connect(("127.0.0.1", target_port)) else {
                    continue;
                };
                let (Ok(incoming_copy), Ok(outgoing_copy)) = (incoming.try_clone(), outgoing.try_clone())
                else {
                    continue;
                };
                let (up, down) = (Arc::clone(&counter), Arc::clone(&counter));
                std::thread::spawn(move || pump(incoming, outgoing, &up));
                std::thread::spawn(move || pump(outgoing_copy, incoming_copy, &down));
            }
        });
        Ok(Self { port, bytes })
    }
}

/// One-way latency of `payload_bytes` messages between two transports: half of each round trip.
pub fn one_way_latency(
    security: Security,
    certs: &FleetFiles,
    payload_bytes: usize,
    rounds: usize,
) -> Result<Timing> {
    let prefix = format!("skid-bench-tls/{}/{payload_bytes}", std::process::id());
    let port = free_port()?;
    let mut a = ZenohTransport::open(
        RobotId(0),
        zenoh_config(security, certs, 0, Some(port), &[], &prefix),
        2,
    )?;
    let mut b = ZenohTransport::open(
        RobotId(1),
        zenoh_config(security, certs, 1, None, &[port], &prefix),
        2,
    )?;
    if !(a.wait_for_peers(&[RobotId(1)], Duration::from_secs(10))?
        && b.wait_for_peers(&[RobotId(0)], Duration::from_secs(10))?)
    {
        bail!("the two {} transports did not find each other", scheme(security));
    }
    let payload = vec![0x5Au8; payload_bytes];
    let mut samples_ms = Vec::with_capacity(rounds);
    for round in 0..rounds + 5 {
        let started = Instant::now();
        a.send(Destination::Robot(RobotId(1)), &payload)?;
        wait_for_one(&mut b)?;
        b.send(Destination::Robot(RobotId(0)), &payload)?;
        wait_for_one(&mut a)?;
        // The first rounds warm the links up.
        if round >= 5 {
            samples_ms.push(started.elapsed().as_secs_f64() * 1e3 / 2.0);
        }
    }
    Ok(Timing::from_ms(&samples_ms))
}

fn wait_for_one(transport: &mut ZenohTransport) -> Result<()> {
    let deadline = Instant::now() + Duration::from_secs(10);
    while Instant::now() < deadline {
        if !transport.poll(Duration::from_millis(100))?.is_empty() {
            return Ok(());
        }
    }
    bail!("a message was lost between two transports on 127.0.0.1")
}

/// Writes the fleet's certificates for `robots` robots under `out`.
pub fn certificates(out: &Path, robots: u32) -> Result<FleetFiles> {
    skid_transport_zenoh::write_fleet_certificates(&out.join("certs"), robots, 1)
        .context("writing certificates")
}
