//! Total descriptor memory over a long multi-robot run, as in the SKiD-SLAM paper's Table I
//! ("Comparison of total descriptor memory usage", sharing β → α and γ → α): every robot of a simulated
//! fleet describes a keyframe every `keyframe_every_m` metres with SOLiD (Kim et al., RA-L 2024), Scan
//! Context (Kim & Kim, IROS 2018) and LiDAR-Iris (Wang et al., IROS 2020); each descriptor is wrapped in
//! the real `skid-protocol` message the runtime sends to its peers, and the bytes are summed per sender.

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use skid_core::slots::DescriptorBuf;
use skid_core::{KeyframeId, RobotId};
use skid_eval::descriptor_memory;
use skid_protocol::{
    DescriptorBatch, DescriptorEncoding, DescriptorEntry, DescriptorValues, Message, ProtocolConfig,
    ProtocolEndpoint,
};

use crate::place_recognition::{PrCase, for_each_keyframe, variants};
use crate::report::markdown_table;

/// Parameters of the memory run.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MemorySettings {
    pub world: String,
    pub sensor: String,
    /// Vertical field of view of the sensor, for SOLiD.
    pub lower_fov_deg: f64,
    pub upper_fov_deg: f64,
    pub robots: u32,
    pub route_m: f64,
    pub keyframe_every_m: f64,
    pub seed: u64,
    /// Descriptor variants (see `place_recognition::variants`).
    pub descriptors: Vec<String>,
    /// Wire encoding of the values: `f32` (what the runtime sends), `u16` or `u8`.
    pub encoding: DescriptorEncoding,
}

impl Default for MemorySettings {
    fn default() -> Self {
        Self {
            world: "urban".to_owned(),
            sensor: "os1-64".to_owned(),
            lower_fov_deg: -16.6,
            upper_fov_deg: 16.6,
            robots: 3,
            route_m: 1000.0,
            keyframe_every_m: 1.0,
            seed: 7,
            descriptors: ["scan_context", "iris", "solid"].map(str::to_owned).to_vec(),
            encoding: DescriptorEncoding::F32,
        }
    }
}

/// The protocol message carrying one keyframe's descriptor, as the runtime builds it.
pub fn descriptor_message(
    id: KeyframeId,
    stamp_nanos: u64,
    descriptor: &DescriptorBuf,
    encoding: DescriptorEncoding,
) -> Result<Message> {
    Ok(Message::Descriptors(DescriptorBatch {
        robot: id.robot,
        kind: descriptor.kind.clone(),
        entries: vec![DescriptorEntry {
            keyframe_index: id.index,
            stamp_nanos,
            values: DescriptorValues::encode(&descriptor.values, encoding)?,
            newest_held: Vec::new(),
        }],
    }))
}

/// One sender and descriptor.
#[derive(Clone, Debug, Serialize)]
pub struct MemoryRow {
    /// `β → α`: what robot β shares with α over the run.
    pub sharing: String,
    pub descriptor: String,
    pub keyframes: usize,
    /// Keyframes the descriptor refused (too few points, ...).
    pub not_described: usize,
    /// Size of one descriptor's values in memory (f32), bytes.
    pub bytes_per_descriptor: f64,
    /// Size of one encoded descriptor message, bytes (mean).
    pub bytes_per_message: f64,
    pub total_descriptor_bytes: u64,
    pub total_message_bytes: u64,
    pub total_message_mb: f64,
}

const GREEK: [&str; 6] = ["α", "β", "γ", "δ", "ε", "ζ"];

fn robot_name(robot: u32) -> String {
    GREEK
        .get(robot as usize)
        .map_or_else(|| format!("robot {robot}"), |g| (*g).to_owned())
}

/// Runs the fleet's keyframes through every descriptor; one row per sender (robots 1..) and descriptor.
pub fn descriptor_memory_rows(settings: &MemorySettings) -> Result<Vec<MemoryRow>> {
    let threads = std::thread::available_parallelism().map_or(1, usize::from);
    let case = PrCase {
        name: format!("{}/{}", settings.world, settings.sensor),
        world: settings.world.clone(),
        sensor: settings.sensor.clone(),
        lower_fov_deg: settings.lower_fov_deg,
        upper_fov_deg: settings.upper_fov_deg,
        narrow: false,
    };
    let config = case.sim_config(settings.seed, settings.robots, settings.route_m);
    let mut rows = Vec::new();
    for robot in 1..settings.robots {
        let mut described = variants(&case, &settings.descriptors)?;
        let mut endpoint = ProtocolEndpoint::new(RobotId(robot), robot, ProtocolConfig::default());
        let mut sizes: Vec<(Vec<usize>, Vec<usize>, usize)> =
            vec![(Vec::new(), Vec::new(), 0); described.len()];
        let keyframes = for_each_keyframe(&config, robot, settings.keyframe_every_m, threads, |keyframe| {
            let stamp_nanos = (keyframe.time_s * 1e9).round() as u64;
            for ((_, descriptor, _), size) in described.iter_mut().zip(sizes.iter_mut()) {
                match descriptor.describe(keyframe.cloud.view()) {
                    Ok(buf) => {
                        let message = descriptor_message(keyframe.id, stamp_nanos, &buf, settings.encoding)?;
                        size.0.push(buf.byte_len());
                        size.1
                            .push(endpoint.encode(&message).context("encoding a descriptor")?.len());
                    }
                    Err(_) => size.2 += 1,
                }
            }
            Ok(())
        })?;
        eprintln!("{}: robot {robot}: {keyframes} keyframes", case.name);
        for ((name, _, _), (values, messages, failed)) in described.iter().zip(sizes) {
            let values = descriptor_memory(values);
            let messages = descriptor_memory(messages);
            rows.push(MemoryRow {
                sharing: format!("{} → α", robot_name(robot)),
                descriptor: name.clone(),
                keyframes: keyframes as usize,
                not_described: failed,
                bytes_per_descriptor: values.mean_bytes,
                bytes_per_message: messages.mean_bytes,
                total_descriptor_bytes: values.total_bytes,
                total_message_bytes: messages.total_bytes,
                total_message_mb: messages.total_bytes as f64 / 1e6,
            });
        }
    }
    Ok(rows)
}

/// A byte count in the paper's units (kB, MB or GB, decimal).
pub fn human_bytes(bytes: u64) -> String {
    let b = bytes as f64;
    if b >= 1e9 {
        format!("{:.3} GB", b / 1e9)
    } else if b >= 1e6 {
        format!("{:.3} MB", b / 1e6)
    } else {
        format!("{:.3} kB", b / 1e3)
    }
}

/// The paper-shaped table: one line per sender, one column per descriptor (total message bytes), then
/// the sizes of one descriptor and one message.
pub fn memory_markdown(settings: &MemorySettings, rows: &[MemoryRow]) -> String {
    let mut header = vec!["Sharing".to_owned()];
    header.extend(settings.descriptors.iter().cloned());
    let mut senders: Vec<&str> = rows.iter().map(|r| r.sharing.as_str()).collect();
    senders.dedup();
    let body: Vec<Vec<String>> = senders
        .iter()
        .map(|&sender| {
            let mut cells = vec![sender.to_owned()];
            for descriptor in &settings.descriptors {
                let row = rows
                    .iter()
                    .find(|r| r.sharing == sender && &r.descriptor == descriptor);
                cells.push(row.map_or_else(String::new, |r| {
                    format!(
                        "{} ({} keyframes)",
                        human_bytes(r.total_message_bytes),
                        r.keyframes
                    )
                }));
            }
            cells
        })
        .collect();
    let sizes: Vec<Vec<String>> = settings
        .descriptors
        .iter()
        .filter_map(|d| rows.iter().find(|r| &r.descriptor == d))
        .map(|r| {
            vec![
                r.descriptor.clone(),
                format!("{:.0}", r.bytes_per_descriptor),
                format!("{:.0}", r.bytes_per_message),
            ]
        })
        .collect();
    format!(
        "# table1-descriptor-memory\n\nTotal descriptor bytes sent over the run (Table I shape; the paper's PARK scene: Scan Context 122.5 / 156.4 MB, LiDAR-Iris 6.0 / 7.7 GB, SOLiD 5.5 / 7.0 MB).\n\n{}\n{}\n{} world, {} sensor, {} robots on {} m routes, a keyframe every {} m; each descriptor in the `skid-protocol` message the runtime sends ({:?} values).\n",
        markdown_table(&header, &body),
        markdown_table(
            &[
                "descriptor".to_owned(),
                "bytes per descriptor".to_owned(),
                "bytes per message".to_owned()
            ],
            &sizes,
        ),
        settings.world,
        settings.sensor,
        settings.robots,
        settings.route_m,
        settings.keyframe_every_m,
        settings.encoding,
    )
}
