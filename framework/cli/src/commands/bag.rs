//! `skid bag info PATH`: what a user runs first on a new recording — storage, duration, and per topic
//! the message type, count and rate; for each point-cloud topic the layout found in its first message
//! (which field is time, ring and intensity) and its point count.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, Result};
use skid_bag::msgs::point_cloud2::{CloudLayout, PointCloud2};
use skid_bag::{Bag, MessageReader, WireReader, detect_storage};

/// What `bag info` learns about one topic.
#[derive(Default)]
struct TopicSummary {
    message_type: String,
    encoding: String,
    count: u64,
    first_nanos: u64,
    last_nanos: u64,
    /// For point clouds: the first message's layout and point count, or why it could not be read.
    cloud: Option<String>,
}

/// `skid bag info PATH [--json]`.
pub fn info(path: &Path, json: bool) -> Result<()> {
    if !path.exists() {
        anyhow::bail!("{}: no such file or folder", path.display());
    }
    let mut bag = Bag::open(path)?;
    let storages: Vec<String> = bag
        .files()
        .iter()
        .map(|file| detect_storage(file).map(|s| s.name().to_owned()))
        .collect::<Result<_, _>>()?;
    let bytes: u64 = bag
        .files()
        .iter()
        .map(|file| std::fs::metadata(file).map(|m| m.len()))
        .collect::<Result<Vec<_>, _>>()
        .with_context(|| format!("reading the size of {}", path.display()))?
        .iter()
        .sum();
    let mut topics: BTreeMap<String, TopicSummary> = BTreeMap::new();
    while let Some(message) = bag.next_message()? {
        let connection = &message.connection;
        let summary = topics.entry(connection.topic.clone()).or_default();
        if summary.count == 0 {
            summary.message_type.clone_from(&connection.message_type);
            summary.encoding = format!("{:?}", connection.encoding).to_lowercase();
            summary.first_nanos = message.log_time_nanos;
            if connection.message_type == "sensor_msgs/PointCloud2" {
                summary.cloud = Some(describe_cloud(&message.data, connection.encoding));
            }
        }
        summary.count += 1;
        summary.first_nanos = summary.first_nanos.min(message.log_time_nanos);
        summary.last_nanos = summary.last_nanos.max(message.log_time_nanos);
    }
    let start = topics.values().map(|t| t.first_nanos).min().unwrap_or(0);
    let end = topics.values().map(|t| t.last_nanos).max().unwrap_or(0);
    let duration_s = (end - start) as f64 * 1e-9;
    if json {
        let rows: Vec<_> = topics
            .iter()
            .map(|(topic, s)| {
                serde_json::json!({
                    "topic": topic, "type": s.message_type, "encoding": s.encoding, "count": s.count,
                    "rate_hz": rate_hz(s), "cloud_layout": s.cloud,
                })
            })
            .collect();
        let line = serde_json::json!({
            "path": path.display().to_string(), "storage": storages, "bytes": bytes,
            "start_s": start as f64 * 1e-9, "duration_s": duration_s, "topics": rows,
        });
        println!("{line}");
        return Ok(());
    }
    println!("path:      {}", path.display());
    println!(
        "storage:   {} ({} file(s), {:.1} MB)",
        storages.join(", "),
        storages.len(),
        bytes as f64 / 1e6
    );
    println!("start:     {:.6} s since the epoch", start as f64 * 1e-9);
    println!("duration:  {duration_s:.3} s");
    println!("topics:");
    let width = topics.keys().map(String::len).max().unwrap_or(0);
    for (topic, summary) in &topics {
        println!(
            "  {topic:<width$}  {:<28} {:>8} msgs  {:>8.2} Hz  ({})",
            summary.message_type,
            summary.count,
            rate_hz(summary),
            summary.encoding
        );
        if let Some(cloud) = &summary.cloud {
            println!("  {:<width$}    layout: {cloud}", "");
        }
    }
    Ok(())
}

fn rate_hz(summary: &TopicSummary) -> f64 {
    let span_s = (summary.last_nanos - summary.first_nanos) as f64 * 1e-9;
    if summary.count < 2 || span_s <= 0.0 {
        return 0.0;
    }
    (summary.count - 1) as f64 / span_s
}

fn describe_cloud(data: &[u8], encoding: skid_bag::Encoding) -> String {
    let decoded = WireReader::new(data, encoding).and_then(|mut reader| {
        let cloud = PointCloud2::decode(&mut reader)?;
        let layout = CloudLayout::detect(&cloud.fields)?;
        Ok(format!(
            "{}; {} x {} points, point_step {}{}",
            layout.describe(),
            cloud.height,
            cloud.width,
            cloud.point_step,
            if cloud.is_bigendian { ", big-endian" } else { "" }
        ))
    });
    decoded.unwrap_or_else(|error| format!("unreadable first message: {error}"))
}
