//! Communication and memory figures of the SKiD paper (Sec. "Communication and Memory"): the total
//! memory of the global descriptors a robot keeps or sends, and the message latency (time from a
//! robot sending a descriptor to another receiving it) against the distance between the robots, here
//! measured over the loopback transport's link model.

use serde::{Deserialize, Serialize};

use crate::error::EvalError;
use crate::stats::ErrorStats;
use skid_core::slots::DescriptorBuf;

/// Total memory of a set of descriptors.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DescriptorMemory {
    pub descriptors: usize,
    pub total_bytes: u64,
    /// Mean size of one descriptor, bytes (0 without descriptors).
    pub mean_bytes: f64,
    /// `total_bytes / 2²⁰`.
    pub total_mib: f64,
}

/// Sums descriptor sizes given in bytes (use the wire size when descriptors are quantised).
pub fn descriptor_memory(byte_lengths: impl IntoIterator<Item = usize>) -> DescriptorMemory {
    let mut descriptors = 0usize;
    let mut total_bytes = 0u64;
    for bytes in byte_lengths {
        descriptors += 1;
        total_bytes += bytes as u64;
    }
    DescriptorMemory {
        descriptors,
        total_bytes,
        mean_bytes: if descriptors == 0 {
            0.0
        } else {
            total_bytes as f64 / descriptors as f64
        },
        total_mib: total_bytes as f64 / (1024.0 * 1024.0),
    }
}

/// [`descriptor_memory`] of descriptors kept as `f32` vectors.
pub fn descriptor_memory_of(descriptors: &[DescriptorBuf]) -> DescriptorMemory {
    descriptor_memory(descriptors.iter().map(DescriptorBuf::byte_len))
}

/// One message sent between two robots.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LatencySample {
    /// Distance between sender and receiver when it was sent, metres.
    pub distance_m: f64,
    /// Receive time minus send time, seconds; `None` when the message never arrived.
    pub latency_s: Option<f64>,
}

impl LatencySample {
    /// A sample from send/receive clock readings in nanoseconds (`None` = lost).
    pub fn from_stamps(distance_m: f64, sent_nanos: u64, received_nanos: Option<u64>) -> Self {
        Self {
            distance_m,
            latency_s: received_nanos.map(|r| (r as f64 - sent_nanos as f64) * 1e-9),
        }
    }
}

/// Latency of the messages sent over one distance interval.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LatencyBin {
    /// The interval `[distance_min_m, distance_max_m)`.
    pub distance_min_m: f64,
    pub distance_max_m: f64,
    pub sent: usize,
    pub delivered: usize,
    /// `delivered / sent`.
    pub delivery_rate: f64,
    /// Latency statistics of the delivered messages, seconds (`None` if none arrived).
    pub latency_s: Option<ErrorStats>,
}

/// Groups samples into distance bins `[k·w, (k+1)·w)` of width `bin_width_m` and summarises each
/// non-empty bin, in order of distance. Negative or non-finite distances and latencies are errors.
pub fn latency_vs_distance(
    samples: &[LatencySample],
    bin_width_m: f64,
) -> Result<Vec<LatencyBin>, EvalError> {
    if !(bin_width_m.is_finite() && bin_width_m > 0.0) {
        return Err(EvalError::InvalidOption {
            name: "bin_width_m",
            reason: format!("{bin_width_m} is not a positive number"),
        });
    }
    if samples.is_empty() {
        return Err(EvalError::TooFew {
            what: "latency samples",
            needed: 1,
            got: 0,
        });
    }
    let mut bins: std::collections::BTreeMap<u64, (usize, Vec<f64>)> = Default::default();
    for (index, sample) in samples.iter().enumerate() {
        let bad_latency = sample.latency_s.is_some_and(|l| !(l.is_finite() && l >= 0.0));
        if !(sample.distance_m.is_finite() && sample.distance_m >= 0.0) || bad_latency {
            return Err(EvalError::NonFinite {
                what: "latency sample (distance and latency must be finite and non-negative)",
                index,
            });
        }
        let key = (sample.distance_m / bin_width_m).floor() as u64;
        let entry = bins.entry(key).or_default();
        entry.0 += 1;
        if let Some(latency) = sample.latency_s {
            entry.1.push(latency);
        }
    }
    bins.into_iter()
        .map(|(key, (sent, latencies))| {
            Ok(LatencyBin {
                distance_min_m: key as f64 * bin_width_m,
                distance_max_m: (key + 1) as f64 * bin_width_m,
                sent,
                delivered: latencies.len(),
                delivery_rate: latencies.len() as f64 / sent as f64,
                latency_s: if latencies.is_empty() {
                    None
                } else {
                    Some(ErrorStats::from_errors("latencies", &latencies)?)
                },
            })
        })
        .collect()
}
