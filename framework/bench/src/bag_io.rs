//! Bag decoding throughput for `cargo xtask bench io`: every `PointCloud2` of a bag read and turned into
//! SKiD's points on one thread, beside the same work by `rosbags`' `AnyReader` + numpy (the peer,
//! `framework/bench/python/rosbags_decode.py`, run with `$SKID_PYTHON` in the same run).

use std::path::Path;
use std::process::Command;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use serde::Serialize;
use skid_bag::msgs::point_cloud2::{CloudLayout, PointCloud2, raw_points};
use skid_bag::{Bag, MessageReader, WireReader};

use crate::Timing;

/// One bag's figures, SKiD's and the peer's.
#[derive(Serialize)]
pub struct BagRow {
    pub bag: String,
    pub bytes: u64,
    pub messages: usize,
    pub points: usize,
    pub skid_median_ms: f64,
    pub skid_mb_per_s: f64,
    pub skid_mpoints_per_s: f64,
    pub rosbags_median_ms: Option<f64>,
    pub rosbags_mb_per_s: Option<f64>,
    pub speedup: Option<f64>,
}

/// Decodes every cloud of `topic` once; returns (messages, points).
pub fn decode_all(path: &Path, topic: &str) -> Result<(usize, usize)> {
    let mut bag = Bag::open(path)?;
    bag.select_topics(&[topic.to_owned()]);
    let (mut messages, mut points) = (0, 0);
    let mut layout: Option<CloudLayout> = None;
    while let Some(message) = bag.next_message()? {
        let mut reader = WireReader::new(&message.data, message.connection.encoding)?;
        let cloud = PointCloud2::decode(&mut reader)?;
        let layout = match &layout {
            Some(layout) => layout,
            None => layout.insert(CloudLayout::detect(&cloud.fields)?),
        };
        points += raw_points(&cloud, layout).points.len();
        messages += 1;
    }
    Ok((messages, points))
}

fn bag_bytes(path: &Path) -> Result<u64> {
    let mut total = 0;
    for file in skid_bag::bag_files(path)? {
        total += std::fs::metadata(&file)
            .with_context(|| format!("{}", file.display()))?
            .len();
    }
    Ok(total)
}

/// The peer's per-run times in ms, or `None` (with a warning) when no Python with rosbags is available.
fn rosbags_runs_ms(
    path: &Path,
    topic: &str,
    runs: usize,
    expected_points: usize,
) -> Result<Option<Vec<f64>>> {
    let Some(python) = std::env::var_os("SKID_PYTHON") else {
        eprintln!(
            "bench io: SKID_PYTHON is not set (cargo xtask bench sets it); the rosbags peer is skipped"
        );
        return Ok(None);
    };
    let script = crate::profile::workspace_root().join("framework/bench/python/rosbags_decode.py");
    let output = Command::new(python)
        .arg(script)
        .arg(path)
        .arg(topic)
        .arg(runs.to_string())
        .output()
        .context("running the rosbags peer")?;
    if !output.status.success() {
        bail!(
            "the rosbags peer failed: {}",
            String::from_utf8_lossy(&output.stderr)
        );
    }
    let line: serde_json::Value = serde_json::from_slice(&output.stdout)?;
    if line["points"].as_u64() != Some(expected_points as u64) {
        bail!(
            "the peer decoded {} points, SKiD {expected_points}",
            line["points"]
        );
    }
    let runs = line["runs_ms"]
        .as_array()
        .map(|runs| runs.iter().filter_map(serde_json::Value::as_f64).collect());
    Ok(runs)
}

/// Measures one bag: `rounds` rounds, each `runs_per_round` full decodes by SKiD and then as many by the
/// peer, so both see the machine in the same state (a shared machine's speed drifts over seconds).
pub fn measure(
    label: &str,
    path: &Path,
    topic: &str,
    rounds: usize,
    runs_per_round: usize,
) -> Result<BagRow> {
    let bytes = bag_bytes(path)?;
    let (mut messages, mut points) = (0, 0);
    let (mut skid_ms, mut peer_ms) = (Vec::new(), Some(Vec::new()));
    for _ in 0..rounds {
        for _ in 0..runs_per_round {
            let started = Instant::now();
            (messages, points) = decode_all(path, topic)?;
            skid_ms.push(started.elapsed().as_secs_f64() * 1e3);
        }
        if let Some(all_peer_ms) = peer_ms.as_mut() {
            match rosbags_runs_ms(path, topic, runs_per_round, points)? {
                Some(runs) => all_peer_ms.extend(runs),
                None => peer_ms = None,
            }
        }
    }
    let skid = Timing::from_ms(&skid_ms).median_ms;
    let peer = peer_ms.map(|runs| Timing::from_ms(&runs).median_ms);
    let mb_per_s = |ms: f64| bytes as f64 / 1e6 / (ms / 1e3);
    Ok(BagRow {
        bag: label.to_owned(),
        bytes,
        messages,
        points,
        skid_median_ms: skid,
        skid_mb_per_s: mb_per_s(skid),
        skid_mpoints_per_s: points as f64 / 1e6 / (skid / 1e3),
        rosbags_median_ms: peer,
        rosbags_mb_per_s: peer.map(mb_per_s),
        speedup: peer.map(|peer| peer / skid),
    })
}
