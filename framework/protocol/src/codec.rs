//! Compact encodings of the two bulky payloads: keyframe clouds and global descriptors.
//!
//! **Clouds** (sent only for loop candidates, design guide §6): every coordinate is quantised to a grid
//! of `resolution_m` (1 cm by default), the points are put in Morton (Z-curve) order of their grid cells
//! so that consecutive points are neighbours, and each point is stored as the difference of its grid
//! coordinates from the previous point. Postcard writes those `i32` differences as zig-zag varints, so a
//! voxel-downsampled cloud costs about 3–5 bytes per point instead of 12 (f32 xyz). Precision: each
//! decoded coordinate lies within `resolution_m / 2` of the original (0.5 cm per axis, 0.87 cm in 3D by
//! default), far below the 0.25–1 m voxels of SKiD-SLAM's keyframes and GICP's correspondence distances.
//! The point order is not kept (a cloud is a set). Intensity, when sent, is quantised to 256 levels of
//! `[0, max]`.
//!
//! **Descriptors**: f32 values as they are, or linearly quantised between the descriptor's own minimum and
//! maximum to u8 (error ≤ range/510) or u16 (error ≤ range/131070) codes; SOLiD (the descriptor of the
//! SKiD-SLAM paper, 100 values) takes 400 bytes as f32 and about 108 bytes as u8.

use serde::{Deserialize, Serialize};
use skid_core::Point;

use crate::packed::PackedPoints;

/// Why a payload could not be encoded or decoded.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CodecError {
    #[error("point {index} is not finite")]
    NonFinitePoint { index: usize },
    #[error("resolution must be finite and positive, got {0}")]
    BadResolution(f32),
    #[error("point {index} lies {extent_m} m from the origin, beyond the {max_m} m the grid can hold")]
    OutOfRange { index: usize, extent_m: f64, max_m: f64 },
    #[error("{what}: expected {expected} values, found {found}")]
    LengthMismatch {
        what: &'static str,
        expected: usize,
        found: usize,
    },
    #[error("the coordinate differences overflow the grid at point {index}")]
    Overflow { index: usize },
    #[error("descriptor value {index} is not finite")]
    NonFiniteValue { index: usize },
    #[error("quantisation range [{min}, {max}] is invalid")]
    BadRange { min: f32, max: f32 },
    #[error("the packed cloud does not unpack: {0}")]
    Unpack(String),
}

/// Largest grid coordinate used, so that Morton keys fit 21 bits per axis after offsetting.
const MAX_GRID: i64 = (1 << 20) - 1;

/// Coarsest grid accepted, in metres per cell: any coarser and the grid's far corner (`MAX_GRID` cells
/// out) would leave the range `f32` coordinates hold meaningfully (found by fuzzing: a resolution
/// of 3e38 decoded to infinite points).
pub const MAX_RESOLUTION_M: f32 = 100.0;

/// A quantised, delta-coded point cloud.
///
/// On the wire it travels packed (see the `packed` module): postcard's bytes compressed by zstd.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(
    into = "crate::packed::PackedPoints",
    try_from = "crate::packed::PackedPoints"
)]
pub struct CompressedPoints {
    /// Grid step in metres; each coordinate is recovered within half of it.
    pub resolution_m: f32,
    /// Three grid-coordinate differences per point, from the previous point (the first from the origin).
    pub deltas: Vec<i32>,
    /// Intensity codes (one per point, `code · intensity_max / 255`), or empty when not sent.
    pub intensity_codes: Vec<u8>,
    pub intensity_max: f32,
}

impl CompressedPoints {
    /// Encodes `points`; non-finite points and points beyond ±(2²⁰−1)·resolution are refused.
    pub fn encode(points: &[Point], resolution_m: f32, with_intensity: bool) -> Result<Self, CodecError> {
        if !(resolution_m.is_finite() && resolution_m > 0.0 && resolution_m <= MAX_RESOLUTION_M) {
            return Err(CodecError::BadResolution(resolution_m));
        }
        let max_m = MAX_GRID as f64 * f64::from(resolution_m);
        let mut cells = Vec::with_capacity(points.len());
        let mut intensity_max = 0.0f32;
        for (index, point) in points.iter().enumerate() {
            if !point.is_finite() {
                return Err(CodecError::NonFinitePoint { index });
            }
            let mut cell = [0i64; 3];
            for (axis, value) in point.xyz().into_iter().enumerate() {
                let scaled = (f64::from(value) / f64::from(resolution_m)).round();
                if scaled.abs() > MAX_GRID as f64 {
                    return Err(CodecError::OutOfRange {
                        index,
                        extent_m: f64::from(value).abs(),
                        max_m,
                    });
                }
                // In range by the check above.
                cell[axis] = scaled as i64;
            }
            intensity_max = intensity_max.max(point.intensity.abs());
            cells.push((morton_key(cell), cell, point.intensity));
        }
        cells.sort_by_key(|&(key, cell, _)| (key, cell));
        let mut deltas = Vec::with_capacity(cells.len() * 3);
        let mut previous = [0i64; 3];
        for &(_, cell, _) in &cells {
            for axis in 0..3 {
                // Both coordinates are within ±2²⁰, so the difference fits an i32.
                deltas.push((cell[axis] - previous[axis]) as i32);
            }
            previous = cell;
        }
        let intensity_codes = if with_intensity {
            cells
                .iter()
                .map(|&(_, _, intensity)| quantise_unit(intensity.max(0.0), intensity_max, 255.0) as u8)
                .collect()
        } else {
            Vec::new()
        };
        Ok(Self {
            resolution_m,
            deltas,
            intensity_codes,
            intensity_max: if with_intensity { intensity_max } else { 0.0 },
        })
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.deltas.len() / 3
    }

    pub fn is_empty(&self) -> bool {
        self.deltas.is_empty()
    }

    /// Checks the structure (resolution, lengths) without decoding the points.
    pub fn validate(&self) -> Result<(), CodecError> {
        if !(self.resolution_m.is_finite()
            && self.resolution_m > 0.0
            && self.resolution_m <= MAX_RESOLUTION_M)
        {
            return Err(CodecError::BadResolution(self.resolution_m));
        }
        if !self.deltas.len().is_multiple_of(3) {
            return Err(CodecError::LengthMismatch {
                what: "coordinate differences",
                expected: self.deltas.len().div_ceil(3) * 3,
                found: self.deltas.len(),
            });
        }
        if !self.intensity_codes.is_empty() && self.intensity_codes.len() != self.len() {
            return Err(CodecError::LengthMismatch {
                what: "intensity codes",
                expected: self.len(),
                found: self.intensity_codes.len(),
            });
        }
        if !(self.intensity_max.is_finite() && self.intensity_max >= 0.0) {
            return Err(CodecError::BadRange {
                min: 0.0,
                max: self.intensity_max,
            });
        }
        Ok(())
    }

    /// Decodes the points (in Morton order); a malformed payload is an error, never a panic.
    pub fn decode(&self) -> Result<Vec<Point>, CodecError> {
        self.validate()?;
        let resolution = f64::from(self.resolution_m);
        let mut cell = [0i64; 3];
        let mut points = Vec::with_capacity(self.len());
        for (index, delta) in self.deltas.chunks_exact(3).enumerate() {
            for axis in 0..3 {
                cell[axis] += i64::from(delta[axis]);
                if cell[axis].abs() > MAX_GRID {
                    return Err(CodecError::Overflow { index });
                }
            }
            let intensity = self
                .intensity_codes
                .get(index)
                .map_or(0.0, |&code| f32::from(code) * self.intensity_max / 255.0);
            // Grid coordinates times a finite resolution are finite; f32 is the point type's precision.
            points.push(Point::with_intensity(
                (cell[0] as f64 * resolution) as f32,
                (cell[1] as f64 * resolution) as f32,
                (cell[2] as f64 * resolution) as f32,
                intensity,
            ));
        }
        Ok(points)
    }
}

/// A cloud's fields as postcard writes them before packing.
#[derive(Serialize, Deserialize)]
struct PlainPoints {
    resolution_m: f32,
    deltas: Vec<i32>,
    intensity_codes: Vec<u8>,
    intensity_max: f32,
}

impl From<CompressedPoints> for PackedPoints {
    fn from(points: CompressedPoints) -> Self {
        PackedPoints::pack(&PlainPoints {
            resolution_m: points.resolution_m,
            deltas: points.deltas,
            intensity_codes: points.intensity_codes,
            intensity_max: points.intensity_max,
        })
    }
}

impl TryFrom<PackedPoints> for CompressedPoints {
    type Error = CodecError;

    fn try_from(packed: PackedPoints) -> Result<Self, CodecError> {
        let plain: PlainPoints = packed.unpack().map_err(CodecError::Unpack)?;
        let points = Self {
            resolution_m: plain.resolution_m,
            deltas: plain.deltas,
            intensity_codes: plain.intensity_codes,
            intensity_max: plain.intensity_max,
        };
        points.validate()?;
        Ok(points)
    }
}

/// Interleaves the bits of the three offset grid coordinates (21 bits each).
fn morton_key(cell: [i64; 3]) -> u64 {
    let spread = |value: i64| -> u64 {
        // Offset into [0, 2^21); the callers keep |value| ≤ 2^20 − 1.
        let mut v = ((value + (1 << 20)) as u64) & 0x1f_ffff;
        v = (v | (v << 32)) & 0x1f_0000_0000_ffff;
        v = (v | (v << 16)) & 0x1f_0000_ff00_00ff;
        v = (v | (v << 8)) & 0x100f_00f0_0f00_f00f;
        v = (v | (v << 4)) & 0x10c3_0c30_c30c_30c3;
        (v | (v << 2)) & 0x1249_2492_4924_9249
    };
    spread(cell[0]) | (spread(cell[1]) << 1) | (spread(cell[2]) << 2)
}

/// `value / max` scaled to `[0, levels]` and rounded; 0 when the range is empty.
fn quantise_unit(value: f32, max: f32, levels: f32) -> u32 {
    if max <= 0.0 {
        return 0;
    }
    // Clamped into [0, levels], so the conversion is exact.
    ((value / max).clamp(0.0, 1.0) * levels).round() as u32
}

/// Descriptor values, as f32 or linearly quantised between their minimum and maximum.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum DescriptorValues {
    F32(Vec<f32>),
    /// One byte per value: `min + code · (max − min) / 255`.
    U8 {
        min: f32,
        max: f32,
        codes: Vec<u8>,
    },
    /// Two little-endian bytes per value: `min + code · (max − min) / 65535`.
    U16 {
        min: f32,
        max: f32,
        codes_le: Vec<u8>,
    },
}

/// How descriptors are encoded on the wire.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DescriptorEncoding {
    #[default]
    F32,
    U8,
    U16,
}

impl DescriptorValues {
    /// Encodes `values`; non-finite values are refused.
    pub fn encode(values: &[f32], encoding: DescriptorEncoding) -> Result<Self, CodecError> {
        if let Some(index) = values.iter().position(|v| !v.is_finite()) {
            return Err(CodecError::NonFiniteValue { index });
        }
        let min = values.iter().copied().fold(f32::INFINITY, f32::min);
        let max = values.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        let (min, max) = if values.is_empty() { (0.0, 0.0) } else { (min, max) };
        let code = |v: f32, levels: f32| quantise_unit(v - min, max - min, levels);
        Ok(match encoding {
            DescriptorEncoding::F32 => Self::F32(values.to_vec()),
            // Codes are at most 255 / 65535 by construction.
            DescriptorEncoding::U8 => Self::U8 {
                min,
                max,
                codes: values.iter().map(|&v| code(v, 255.0) as u8).collect(),
            },
            DescriptorEncoding::U16 => Self::U16 {
                min,
                max,
                codes_le: values
                    .iter()
                    .flat_map(|&v| (code(v, 65535.0) as u16).to_le_bytes())
                    .collect(),
            },
        })
    }

    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            Self::F32(values) => values.len(),
            Self::U8 { codes, .. } => codes.len(),
            Self::U16 { codes_le, .. } => codes_le.len() / 2,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Checks finiteness, the range and the code lengths.
    pub fn validate(&self) -> Result<(), CodecError> {
        match self {
            Self::F32(values) => match values.iter().position(|v| !v.is_finite()) {
                Some(index) => Err(CodecError::NonFiniteValue { index }),
                None => Ok(()),
            },
            Self::U8 { min, max, .. } => check_range(*min, *max),
            Self::U16 { min, max, codes_le } => {
                check_range(*min, *max)?;
                if codes_le.len().is_multiple_of(2) {
                    Ok(())
                } else {
                    Err(CodecError::LengthMismatch {
                        what: "u16 descriptor codes (bytes)",
                        expected: codes_le.len() + 1,
                        found: codes_le.len(),
                    })
                }
            }
        }
    }

    /// The f32 values (dequantised when quantised).
    pub fn decode(&self) -> Result<Vec<f32>, CodecError> {
        self.validate()?;
        Ok(match self {
            Self::F32(values) => values.clone(),
            Self::U8 { min, max, codes } => codes
                .iter()
                .map(|&c| min + f32::from(c) * (max - min) / 255.0)
                .collect(),
            Self::U16 { min, max, codes_le } => codes_le
                .chunks_exact(2)
                .map(|pair| min + f32::from(u16::from_le_bytes([pair[0], pair[1]])) * (max - min) / 65535.0)
                .collect(),
        })
    }
}

fn check_range(min: f32, max: f32) -> Result<(), CodecError> {
    if min.is_finite() && max.is_finite() && min <= max && (max - min).is_finite() {
        Ok(())
    } else {
        Err(CodecError::BadRange { min, max })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_cloud() -> Vec<Point> {
        // A voxel-like cloud: a 0.3 m lattice over a ground plane and a wall, with sub-voxel offsets.
        let mut points = Vec::new();
        for i in 0..60 {
            for j in 0..60 {
                let x = -9.0 + 0.3 * i as f32 + 0.013 * ((i * 7 + j) % 5) as f32;
                let y = -9.0 + 0.3 * j as f32;
                let z = if i > 50 {
                    0.3 * (j % 10) as f32
                } else {
                    -1.7 + 0.01 * (i % 3) as f32
                };
                points.push(Point::with_intensity(x, y, z, ((i + j) % 100) as f32));
            }
        }
        points
    }

    #[test]
    fn cloud_round_trip_within_half_resolution_and_compact() {
        let points = sample_cloud();
        let compressed = CompressedPoints::encode(&points, 0.01, false).unwrap();
        let decoded = compressed.decode().unwrap();
        assert_eq!(decoded.len(), points.len());
        let key = |p: &Point| (p.x * 1000.0).round() as i64 * 1_000_000_000 + (p.y * 1000.0).round() as i64;
        let mut original = points.clone();
        let mut back = decoded;
        original.sort_by_key(key);
        back.sort_by_key(key);
        for (a, b) in original.iter().zip(&back) {
            for (u, v) in a.xyz().iter().zip(b.xyz()) {
                assert!((u - v).abs() <= 0.005 + 1e-5, "{u} vs {v}");
            }
        }
        let bytes = postcard::to_allocvec(&compressed).unwrap().len();
        let per_point = bytes as f64 / points.len() as f64;
        assert!(per_point < 6.0, "{per_point} bytes per point");
    }

    #[test]
    fn intensity_is_quantised_to_256_levels() {
        let points = vec![
            Point::with_intensity(1.0, 2.0, 3.0, 0.0),
            Point::with_intensity(-1.0, 0.0, 0.5, 200.0),
        ];
        let decoded = CompressedPoints::encode(&points, 0.01, true)
            .unwrap()
            .decode()
            .unwrap();
        let mut intensities: Vec<f32> = decoded.iter().map(|p| p.intensity).collect();
        intensities.sort_by(f32::total_cmp);
        assert_eq!(intensities, vec![0.0, 200.0]);
    }

    #[test]
    fn bad_clouds_are_refused() {
        let nan = [Point::new(f32::NAN, 0.0, 0.0)];
        assert_eq!(
            CompressedPoints::encode(&nan, 0.01, false),
            Err(CodecError::NonFinitePoint { index: 0 })
        );
        let far = [Point::new(20_000.0, 0.0, 0.0)];
        assert!(matches!(
            CompressedPoints::encode(&far, 0.01, false),
            Err(CodecError::OutOfRange { .. })
        ));
        assert!(CompressedPoints::encode(&far, 0.0, false).is_err());
        let overflowing = CompressedPoints {
            resolution_m: 0.01,
            deltas: vec![i32::MAX, 0, 0, i32::MAX, 0, 0],
            intensity_codes: Vec::new(),
            intensity_max: 0.0,
        };
        assert!(matches!(overflowing.decode(), Err(CodecError::Overflow { .. })));
        let ragged = CompressedPoints {
            deltas: vec![1, 2],
            ..overflowing
        };
        assert!(ragged.decode().is_err());
    }

    #[test]
    fn empty_cloud_round_trips() {
        let compressed = CompressedPoints::encode(&[], 0.01, true).unwrap();
        assert!(compressed.is_empty());
        assert!(compressed.decode().unwrap().is_empty());
    }

    #[test]
    fn descriptor_quantisation_errors_are_bounded() {
        let values: Vec<f32> = (0..100).map(|i| ((i * 37) % 100) as f32 / 7.0).collect();
        let range = 99.0 / 7.0;
        for (encoding, bound) in [
            (DescriptorEncoding::F32, 0.0),
            (DescriptorEncoding::U8, range / 510.0),
            (DescriptorEncoding::U16, range / 131_070.0),
        ] {
            let decoded = DescriptorValues::encode(&values, encoding)
                .unwrap()
                .decode()
                .unwrap();
            for (a, b) in values.iter().zip(&decoded) {
                assert!((a - b).abs() <= bound * 1.01 + 1e-6, "{encoding:?}: {a} vs {b}");
            }
        }
        let u8_bytes =
            postcard::to_allocvec(&DescriptorValues::encode(&values, DescriptorEncoding::U8).unwrap())
                .unwrap()
                .len();
        assert!(u8_bytes <= 110, "{u8_bytes}");
        assert!(DescriptorValues::encode(&[1.0, f32::NAN], DescriptorEncoding::U8).is_err());
        let constant = DescriptorValues::encode(&[2.5; 4], DescriptorEncoding::U16).unwrap();
        assert_eq!(constant.decode().unwrap(), vec![2.5; 4]);
    }
}
