//! The link model of the loopback transport: bandwidth, latency, jitter, loss, duplication, reordering,
//! a maximum range and a range-dependent degradation curve.
//!
//! The default curve is shaped after the latency-versus-distance measurements of the SKiD-SLAM paper
//! (Table "Latency Comparison", Sec. IV-E: a field Wi-Fi whose signal weakens from about 20 m, where
//! larger descriptors start to see multi-second delays while SOLiD's 400 bytes still arrive in
//! 30–60 ms). It is a simulation aid, not a radio model: effective application throughput drops and
//! latency and loss rise with distance, linearly between the curve's points.

use serde::{Deserialize, Serialize};
use skid_core::ParamError;

/// Link quality at one distance; the model interpolates linearly between points.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RangePoint {
    pub distance_m: f64,
    /// Multiplies `bandwidth_bps` (1 = full rate).
    pub bandwidth_factor: f64,
    /// Added to `latency_ms`.
    pub extra_latency_ms: f64,
    /// Added to `loss` (probability, 0–1).
    pub extra_loss: f64,
}

impl RangePoint {
    const fn new(distance_m: f64, bandwidth_factor: f64, extra_latency_ms: f64, extra_loss: f64) -> Self {
        Self {
            distance_m,
            bandwidth_factor,
            extra_latency_ms,
            extra_loss,
        }
    }
}

/// How messages fare between two robots.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct LinkModel {
    /// Effective application throughput of a robot's radio at short range, bits per second; every
    /// message a robot sends occupies its radio for `8 · bytes / (bandwidth · factor)`. `inf` = no limit.
    pub bandwidth_bps: f64,
    /// One-way latency at short range, milliseconds.
    pub latency_ms: f64,
    /// Uniform random extra latency in `[0, jitter_ms]`, milliseconds (also reorders close messages).
    pub jitter_ms: f64,
    /// Probability that a message is lost.
    pub loss: f64,
    /// Probability that a message is delivered twice.
    pub duplicate: f64,
    /// Probability that a message is held back by `reorder_delay_ms`, so later ones overtake it.
    pub reorder: f64,
    pub reorder_delay_ms: f64,
    /// Beyond this distance no message gets through; `None` = unlimited.
    pub max_range_m: Option<f64>,
    /// Degradation with distance (sorted by distance; empty = none). Beyond the last point its values hold.
    pub range_curve: Vec<RangePoint>,
    /// A message that would wait longer than this in the sender's radio queue is dropped (tail drop).
    pub max_queue_ms: f64,
    /// Messages up to this many bytes go before larger ones queued in the sender's radio, as a
    /// fair-queuing Wi-Fi driver serves sparse flows first; 0 keeps one first-in, first-out queue.
    pub sparse_bytes: usize,
}

impl Default for LinkModel {
    fn default() -> Self {
        Self {
            bandwidth_bps: 1.0e6,
            latency_ms: 28.0,
            jitter_ms: 2.0,
            loss: 0.0,
            duplicate: 0.0,
            reorder: 0.0,
            reorder_delay_ms: 50.0,
            max_range_m: None,
            range_curve: vec![
                RangePoint::new(0.0, 1.0, 0.0, 0.0),
                RangePoint::new(15.0, 1.0, 0.0, 0.0),
                RangePoint::new(20.0, 0.25, 5.0, 0.01),
                RangePoint::new(30.0, 0.1, 20.0, 0.05),
                RangePoint::new(60.0, 0.05, 50.0, 0.2),
            ],
            max_queue_ms: 5_000.0,
            sparse_bytes: 1500,
        }
    }
}

/// The link quality at one distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkQuality {
    pub bandwidth_bps: f64,
    pub latency_ms: f64,
    pub loss: f64,
}

impl LinkModel {
    /// An ideal link: no latency, no bandwidth limit, no loss, no degradation.
    pub fn ideal() -> Self {
        Self {
            bandwidth_bps: f64::INFINITY,
            latency_ms: 0.0,
            jitter_ms: 0.0,
            range_curve: Vec::new(),
            ..Self::default()
        }
    }

    /// Checks every value; the error is at the offending key.
    pub fn validate(&self) -> Result<(), ParamError> {
        let probability = |value: f64, key: &str| {
            if (0.0..=1.0).contains(&value) {
                Ok(())
            } else {
                Err(ParamError::at(
                    key,
                    format!("must be a probability in [0, 1], got {value}"),
                ))
            }
        };
        let non_negative = |value: f64, key: &str| {
            if value.is_finite() && value >= 0.0 {
                Ok(())
            } else {
                Err(ParamError::at(
                    key,
                    format!("must be finite and non-negative, got {value}"),
                ))
            }
        };
        if self.bandwidth_bps.is_nan() || self.bandwidth_bps <= 0.0 {
            return Err(ParamError::at(
                "bandwidth_bps",
                format!("must be positive, got {}", self.bandwidth_bps),
            ));
        }
        non_negative(self.latency_ms, "latency_ms")?;
        non_negative(self.jitter_ms, "jitter_ms")?;
        non_negative(self.reorder_delay_ms, "reorder_delay_ms")?;
        non_negative(self.max_queue_ms, "max_queue_ms")?;
        probability(self.loss, "loss")?;
        probability(self.duplicate, "duplicate")?;
        probability(self.reorder, "reorder")?;
        if let Some(range) = self.max_range_m {
            non_negative(range, "max_range_m")?;
        }
        // A point of the curve is refused at `range_curve`, the message naming the point and its field.
        let mut previous = f64::NEG_INFINITY;
        for (i, point) in self.range_curve.iter().enumerate() {
            let at_point = |problem: String| ParamError::at("range_curve", format!("point {i}: {problem}"));
            for (value, field) in [
                (point.distance_m, "distance_m"),
                (point.extra_latency_ms, "extra_latency_ms"),
            ] {
                if !(value.is_finite() && value >= 0.0) {
                    return Err(at_point(format!(
                        "{field} must be finite and non-negative, got {value}"
                    )));
                }
            }
            if point.distance_m <= previous {
                return Err(at_point("the distances must increase strictly".into()));
            }
            previous = point.distance_m;
            if !(point.bandwidth_factor.is_finite() && point.bandwidth_factor > 0.0) {
                return Err(at_point(format!(
                    "bandwidth_factor must be positive, got {}",
                    point.bandwidth_factor
                )));
            }
            if !(0.0..=1.0).contains(&point.extra_loss) {
                return Err(at_point(format!(
                    "extra_loss must be a probability in [0, 1], got {}",
                    point.extra_loss
                )));
            }
        }
        Ok(())
    }

    /// The link quality at `distance_m`, or `None` beyond `max_range_m`.
    pub fn quality_at(&self, distance_m: f64) -> Option<LinkQuality> {
        if self.max_range_m.is_some_and(|range| distance_m > range) {
            return None;
        }
        let (factor, extra_latency_ms, extra_loss) = self.curve_at(distance_m);
        Some(LinkQuality {
            bandwidth_bps: self.bandwidth_bps * factor,
            latency_ms: self.latency_ms + extra_latency_ms,
            loss: (self.loss + extra_loss).clamp(0.0, 1.0),
        })
    }

    fn curve_at(&self, distance_m: f64) -> (f64, f64, f64) {
        let values = |p: &RangePoint| (p.bandwidth_factor, p.extra_latency_ms, p.extra_loss);
        let Some(first) = self.range_curve.first() else {
            return (1.0, 0.0, 0.0);
        };
        if distance_m <= first.distance_m {
            return values(first);
        }
        for pair in self.range_curve.windows(2) {
            let (a, b) = (&pair[0], &pair[1]);
            if distance_m <= b.distance_m {
                let t = (distance_m - a.distance_m) / (b.distance_m - a.distance_m);
                let lerp = |u: f64, v: f64| u + t * (v - u);
                return (
                    lerp(a.bandwidth_factor, b.bandwidth_factor),
                    lerp(a.extra_latency_ms, b.extra_latency_ms),
                    lerp(a.extra_loss, b.extra_loss),
                );
            }
        }
        self.range_curve.last().map_or((1.0, 0.0, 0.0), values)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_model_is_valid_and_degrades_with_distance() {
        let model = LinkModel::default();
        model.validate().unwrap();
        let near = model.quality_at(5.0).unwrap();
        let mid = model.quality_at(25.0).unwrap();
        let far = model.quality_at(500.0).unwrap();
        assert_eq!(near.bandwidth_bps, 1.0e6);
        assert!((mid.bandwidth_bps - 0.175e6).abs() < 1.0);
        assert!((mid.latency_ms - 40.5).abs() < 1e-9);
        assert!(far.bandwidth_bps < mid.bandwidth_bps && far.loss > mid.loss);
        let ranged = LinkModel {
            max_range_m: Some(30.0),
            ..model
        };
        assert!(ranged.quality_at(30.5).is_none());
    }

    #[test]
    fn invalid_models_are_refused() {
        for bad in [
            LinkModel {
                loss: 1.5,
                ..LinkModel::default()
            },
            LinkModel {
                bandwidth_bps: 0.0,
                ..LinkModel::default()
            },
            LinkModel {
                latency_ms: f64::NAN,
                ..LinkModel::default()
            },
            LinkModel {
                range_curve: vec![
                    RangePoint::new(10.0, 1.0, 0.0, 0.0),
                    RangePoint::new(5.0, 1.0, 0.0, 0.0),
                ],
                ..LinkModel::default()
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }
}
