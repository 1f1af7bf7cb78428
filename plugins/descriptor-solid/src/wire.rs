//! SOLiD on the wire (Kim et al., RA-L 2024, motivate SOLiD by its size: 100 f32 = 400 bytes): the plain
//! f32 encoding and an optional quantised one with u8 or u16 codes per value.
//!
//! Quantised layout, little-endian: the R-SOLiD scale (f32), the A-SOLiD scale (f32), then one code per
//! value, R-SOLiD first. A value v of a part whose largest value is s is sent as round(v / s · L) with
//! L = 255 (u8) or 65,535 (u16) and read back as code · s / L. Both parts are non-negative (weighted
//! counts), so the codes cover [0, s]. The default 40 + 60 bins take 108 bytes (u8) or 208 bytes (u16)
//! instead of 400.

use serde::{Deserialize, Serialize};
use skid_core::{PluginError, PluginResult};

/// How SOLiD values are encoded for sending.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum Quantization {
    /// Plain f32 values.
    #[default]
    None,
    /// One byte per value plus one f32 scale per part.
    U8,
    /// Two bytes per value plus one f32 scale per part.
    U16,
}

impl Quantization {
    /// Largest code, or `None` for plain f32.
    fn levels(self) -> Option<f32> {
        match self {
            Self::None => None,
            Self::U8 => Some(f32::from(u8::MAX)),
            Self::U16 => Some(f32::from(u16::MAX)),
        }
    }

    /// Bytes per value.
    pub fn bytes_per_value(self) -> usize {
        match self {
            Self::None => 4,
            Self::U8 => 1,
            Self::U16 => 2,
        }
    }
}

/// Bytes on the wire for `num_values` values split in two parts.
pub fn wire_size_bytes(num_values: usize, quantization: Quantization) -> usize {
    let scales = if quantization == Quantization::None {
        0
    } else {
        2 * 4
    };
    scales + num_values * quantization.bytes_per_value()
}

/// The largest value of a part (0 when empty or all zero) and the code of each value.
fn codes(part: &[f32], levels: f32) -> (f32, impl Iterator<Item = u32> + '_) {
    let scale = part.iter().copied().fold(0.0f32, f32::max);
    let codes = part.iter().map(move |&v| {
        if scale > 0.0 {
            (v.max(0.0) / scale * levels).round() as u32
        } else {
            0
        }
    });
    (scale, codes)
}

/// Replaces each value by what a receiver decodes from its quantised code.
pub fn quantize_in_place(part: &mut [f32], quantization: Quantization) {
    let Some(levels) = quantization.levels() else {
        return;
    };
    let (scale, codes) = codes(part, levels);
    let decoded: Vec<f32> = codes.map(|code| code as f32 * (scale / levels)).collect();
    part.copy_from_slice(&decoded);
}

/// Encodes R-SOLiD (`values[..num_range]`) and A-SOLiD (the rest) for sending.
pub fn encode(values: &[f32], num_range: usize, quantization: Quantization) -> Vec<u8> {
    let Some(levels) = quantization.levels() else {
        return values.iter().flat_map(|v| v.to_le_bytes()).collect();
    };
    let mut bytes = Vec::with_capacity(wire_size_bytes(values.len(), quantization));
    let (range_part, azimuth_part) = values.split_at(num_range.min(values.len()));
    let (range_scale, range_codes) = codes(range_part, levels);
    let (azimuth_scale, azimuth_codes) = codes(azimuth_part, levels);
    bytes.extend(range_scale.to_le_bytes());
    bytes.extend(azimuth_scale.to_le_bytes());
    for code in range_codes.chain(azimuth_codes) {
        match quantization {
            Quantization::U8 => bytes.push(code.min(255) as u8),
            _ => bytes.extend((code.min(65_535) as u16).to_le_bytes()),
        }
    }
    bytes
}

/// Decodes what [`encode`] produced for a descriptor of `num_range` + `num_azimuth` values.
pub fn decode(
    bytes: &[u8],
    num_range: usize,
    num_azimuth: usize,
    quantization: Quantization,
) -> PluginResult<Vec<f32>> {
    let num_values = num_range + num_azimuth;
    let expected = wire_size_bytes(num_values, quantization);
    if bytes.len() != expected {
        return Err(PluginError::InvalidInput(format!(
            "a SOLiD of {num_values} values encoded as {quantization:?} takes {expected} bytes, got {}",
            bytes.len()
        )));
    }
    let f32_at = |offset: usize| {
        f32::from_le_bytes([
            bytes[offset],
            bytes[offset + 1],
            bytes[offset + 2],
            bytes[offset + 3],
        ])
    };
    let Some(levels) = quantization.levels() else {
        let values: Vec<f32> = (0..num_values).map(|i| f32_at(4 * i)).collect();
        if values.iter().any(|v| !v.is_finite()) {
            return Err(PluginError::InvalidInput(
                "a decoded SOLiD value is not finite".into(),
            ));
        }
        return Ok(values);
    };
    let (range_scale, azimuth_scale) = (f32_at(0), f32_at(4));
    if !(range_scale.is_finite() && azimuth_scale.is_finite() && range_scale >= 0.0 && azimuth_scale >= 0.0) {
        return Err(PluginError::InvalidInput(format!(
            "SOLiD scales {range_scale}, {azimuth_scale} are not valid"
        )));
    }
    let payload = &bytes[8..];
    Ok((0..num_values)
        .map(|i| {
            let code = match quantization {
                Quantization::U8 => f32::from(payload[i]),
                _ => f32::from(u16::from_le_bytes([payload[2 * i], payload[2 * i + 1]])),
            };
            let scale = if i < num_range { range_scale } else { azimuth_scale };
            code * (scale / levels)
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Vec<f32> {
        (0..100).map(|i| ((i * 37) % 101) as f32 * 1.7).collect()
    }

    #[test]
    fn sizes() {
        assert_eq!(wire_size_bytes(100, Quantization::None), 400);
        assert_eq!(wire_size_bytes(100, Quantization::U8), 108);
        assert_eq!(wire_size_bytes(100, Quantization::U16), 208);
        for q in [Quantization::None, Quantization::U8, Quantization::U16] {
            assert_eq!(encode(&sample(), 40, q).len(), wire_size_bytes(100, q));
        }
    }

    #[test]
    fn round_trips_within_half_a_step() {
        for (q, levels) in [
            (Quantization::None, 0.0f32),
            (Quantization::U8, 255.0),
            (Quantization::U16, 65_535.0),
        ] {
            let values = sample();
            let decoded = decode(&encode(&values, 40, q), 40, 60, q).unwrap();
            for (part, range) in [(&values[..40], 0..40), (&values[40..], 40..100)] {
                let max = part.iter().copied().fold(0.0, f32::max);
                let step = if levels > 0.0 { max / levels } else { 0.0 };
                for i in range {
                    assert!(
                        (decoded[i] - values[i]).abs() <= 0.5 * step + 1e-4 * max,
                        "{q:?} value {i}"
                    );
                }
            }
            // What describe() hands out already is what the receiver decodes.
            let mut quantized = values.clone();
            let (range, azimuth) = quantized.split_at_mut(40);
            quantize_in_place(range, q);
            quantize_in_place(azimuth, q);
            let again = decode(&encode(&quantized, 40, q), 40, 60, q).unwrap();
            for (a, b) in again.iter().zip(&quantized) {
                assert!((a - b).abs() <= 1e-5 * b.abs().max(1.0));
            }
        }
    }

    #[test]
    fn all_zero_parts_and_bad_bytes() {
        let zeros = vec![0.0f32; 100];
        assert_eq!(
            decode(&encode(&zeros, 40, Quantization::U8), 40, 60, Quantization::U8).unwrap(),
            zeros
        );
        assert!(decode(&[0u8; 7], 40, 60, Quantization::U8).is_err());
        let mut bad = encode(&zeros, 40, Quantization::U8);
        bad[..4].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(decode(&bad, 40, 60, Quantization::U8).is_err());
    }
}
