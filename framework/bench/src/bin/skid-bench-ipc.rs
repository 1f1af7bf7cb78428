//! `cargo xtask bench ipc`: one-way latency of keyframes between two processes over skid-ipc's iceoryx2
//! ports (design guide §5, the `processes` deployment), with the subscriber asleep on the event service
//! as a stage would be. This binary is the subscriber; it re-runs itself as the publisher process.
//!
//! Latency = receive time − the stamp the publisher writes right before `send`, both from the system
//! clock (one clock for both processes on one machine). "read" stops when the sample is in hand (header
//! and slice readable in place); "touched" after the subscriber has read every point once.

use std::process::{Command, Stdio};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result, bail};
use clap::Parser;
use serde::Serialize;
use skid_bench::{BenchArgs, Report, Timing};
use skid_core::Point;
use skid_ipc::{Keyframes, ProcessNode};
use skid_msgs::KeyframeHeader;

#[derive(Parser, Debug)]
struct Args {
    #[command(flatten)]
    bench: BenchArgs,
    /// Publisher role (internal): the namespace to publish on.
    #[arg(long, hide = true)]
    publish: Option<String>,
    #[arg(long, hide = true, default_value_t = 0)]
    points: usize,
    /// Messages per payload size.
    #[arg(long, default_value_t = 1000)]
    messages: usize,
    /// Pause between messages, microseconds (the subscriber is asleep when each arrives).
    #[arg(long, default_value_t = 2000)]
    period_us: u64,
}

/// Messages at the start of each run left out of the statistics (page faults, first connections).
const WARM_UP: usize = 20;

fn now_nanos() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
}

fn publish(namespace: &str, points: usize, messages: usize, period: Duration) -> Result<()> {
    let node = ProcessNode::new("bench-publisher", namespace)?;
    let publisher = node.publisher::<Keyframes>()?;
    if !publisher.wait_for_subscribers(1, Duration::from_secs(10))? {
        bail!("no subscriber appeared on {namespace}");
    }
    for sequence in 0..messages {
        let mut loan = publisher.loan_with(points, |i| Point::with_intensity(i as f32, 1.0, 2.0, 3.0))?;
        *loan.header_mut() = KeyframeHeader {
            stamp_nanos: now_nanos(),
            sequence: sequence as u32,
            point_count: points as u32,
            ..KeyframeHeader::default()
        };
        loan.send()?;
        std::thread::sleep(period);
    }
    Ok(())
}

#[derive(Serialize)]
struct Row {
    payload: String,
    points: usize,
    messages: usize,
    received: usize,
    read_p50_us: f64,
    read_p90_us: f64,
    read_max_us: f64,
    touched_p50_us: f64,
    touched_p90_us: f64,
    reference: String,
}

fn measure(args: &Args, points: usize) -> Result<Row> {
    let namespace = format!("skid-bench-{}-{points}", std::process::id());
    let node = ProcessNode::new("bench-subscriber", &namespace)?;
    let subscriber = node.subscriber::<Keyframes>()?;
    let mut child = Command::new(std::env::current_exe()?)
        .args(["--publish", &namespace, "--points", &points.to_string()])
        .args([
            "--messages",
            &args.messages.to_string(),
            "--period-us",
            &args.period_us.to_string(),
        ])
        .stdout(Stdio::null())
        .spawn()
        .context("starting the publisher process")?;
    let (mut read_us, mut touched_us) = (Vec::new(), Vec::new());
    let mut checksum = 0.0f64;
    while read_us.len() < args.messages {
        let Some(sample) = subscriber.receive(Duration::from_secs(5))? else {
            break;
        };
        let read = now_nanos();
        checksum += sample.items().iter().map(|p| f64::from(p.x)).sum::<f64>();
        let touched = now_nanos();
        let stamp = sample.header().stamp_nanos;
        read_us.push(read.saturating_sub(stamp) as f64 / 1e3);
        touched_us.push(touched.saturating_sub(stamp) as f64 / 1e3);
    }
    let status = child.wait()?;
    if !status.success() {
        bail!("the publisher process failed: {status}");
    }
    let received = read_us.len();
    let expected = (points * points.saturating_sub(1) / 2) as f64 * received as f64;
    if (checksum - expected).abs() > 1e-6 * expected.max(1.0) {
        bail!("payload checksum {checksum} differs from the expected {expected}");
    }
    let keep = |v: &[f64]| v.get(WARM_UP.min(v.len())..).unwrap_or(&[]).to_vec();
    let read = Timing::from_ms(&keep(&read_us));
    let touched = Timing::from_ms(&keep(&touched_us));
    let bytes = points * std::mem::size_of::<Point>();
    Ok(Row {
        payload: if bytes >= 1 << 20 {
            format!("{} MB keyframe", bytes >> 20)
        } else {
            format!("{} KB keyframe", bytes.div_ceil(1024))
        },
        points,
        messages: args.messages,
        received,
        read_p50_us: read.median_ms,
        read_p90_us: read.p90_ms,
        read_max_us: read.max_ms,
        touched_p50_us: touched.median_ms,
        touched_p90_us: touched.p90_ms,
        reference: if points == 131_072 {
            "iceoryx2 alone here: ~35 us p50 for 2 MB with event wake-up (CRATES.md)".into()
        } else {
            String::new()
        },
    })
}

fn main() -> Result<()> {
    let args = Args::parse();
    if let Some(namespace) = &args.publish {
        return publish(
            namespace,
            args.points,
            args.messages,
            Duration::from_micros(args.period_us),
        );
    }
    let mut report = Report::new("ipc");
    for points in [128, 16_384, 131_072] {
        let row = measure(&args, points)?;
        println!(
            "{}: read p50 {:.1} us, p90 {:.1} us; touched p50 {:.1} us ({} of {} received)",
            row.payload, row.read_p50_us, row.read_p90_us, row.touched_p50_us, row.received, row.messages
        );
        report.push(&row)?;
    }
    report.write(&args.bench.out)
}
