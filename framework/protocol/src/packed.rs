//! The wire form of a keyframe cloud: a [`crate::codec::CompressedPoints`] (quantised, Morton-ordered,
//! delta-coded) written by postcard and compressed by zstd (RFC 8878). Morton order leaves the
//! coordinate differences small and alike: on a KITTI scan thinned to 0.25 m voxels the entropy coder
//! takes the varints' 3.0 bytes per point to 1.8 at a 5 cm grid (at 1 cm, 3.2 to 2.6).
//!
//! A peer's packed cloud is hostile input: it is unpacked through a bounded reader, so a small frame
//! that claims (or expands to) more than [`MAX_UNPACKED_BYTES`] is refused before it is held in memory,
//! and the unpacked points are validated as any decoded cloud is.

use std::io::Read;

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

/// Most bytes a packed cloud may unpack to: 16 MiB, room for about four million points, thirty times a
/// 64-beam scan with every return.
pub const MAX_UNPACKED_BYTES: u64 = 16 << 20;

/// The zstd level clouds are packed at: the library's default, fast on both sides.
const PACK_LEVEL: i32 = 3;

/// The packed bytes that travel in place of a cloud's fields.
#[derive(Serialize, Deserialize)]
pub(crate) struct PackedPoints(Vec<u8>);

impl PackedPoints {
    /// Packs `value`: postcard, then zstd. Writing into memory cannot fail but by exhausting it; an
    /// empty payload then fails to unpack on the other side rather than panicking here.
    pub(crate) fn pack(value: &impl Serialize) -> Self {
        let bytes = postcard::to_allocvec(value)
            .ok()
            .and_then(|plain| zstd::bulk::compress(&plain, PACK_LEVEL).ok())
            .unwrap_or_default();
        Self(bytes)
    }

    /// Unpacks through the bound; the message says why it failed.
    pub(crate) fn unpack<T: DeserializeOwned>(&self) -> Result<T, String> {
        let decoder =
            zstd::stream::read::Decoder::new(self.0.as_slice()).map_err(|error| error.to_string())?;
        let mut plain = Vec::new();
        decoder
            .take(MAX_UNPACKED_BYTES + 1)
            .read_to_end(&mut plain)
            .map_err(|error| error.to_string())?;
        if plain.len() as u64 > MAX_UNPACKED_BYTES {
            return Err(format!("it unpacks to more than {MAX_UNPACKED_BYTES} bytes"));
        }
        postcard::from_bytes(&plain).map_err(|error| error.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::CompressedPoints;
    use skid_core::Point;

    fn plane_points() -> Vec<Point> {
        // A 0.25 m lattice on a gently sloped plane, as a voxel-thinned keyframe shows ground.
        (0..80)
            .flat_map(|i| (0..80).map(move |j| (i, j)))
            .map(|(i, j)| {
                let (x, y) = (i as f32 * 0.25 - 10.0, j as f32 * 0.25 - 10.0);
                Point::new(x, y, 0.05 * x - 1.7)
            })
            .collect()
    }

    #[test]
    fn a_packed_cloud_travels_in_fewer_bytes_and_comes_back_the_same() {
        let points = CompressedPoints::encode(&plane_points(), 0.01, false).unwrap();
        // The varints alone: the deltas as postcard writes them.
        let plain = postcard::to_allocvec(&points.deltas).unwrap();
        let wire = postcard::to_allocvec(&points).unwrap();
        assert!(
            wire.len() * 2 < plain.len(),
            "{} packed of {} plain",
            wire.len(),
            plain.len()
        );
        let back: CompressedPoints = postcard::from_bytes(&wire).unwrap();
        assert_eq!(back, points);
    }

    #[test]
    fn a_packed_cloud_that_expands_past_the_bound_is_refused() {
        // Zeros pack to almost nothing: a small frame that unpacks to 32 MiB.
        let bomb = zstd::bulk::compress(&vec![0u8; 32 << 20], PACK_LEVEL).unwrap();
        assert!(bomb.len() < 64 << 10, "{}", bomb.len());
        let wire = postcard::to_allocvec(&PackedPoints(bomb)).unwrap();
        let error = postcard::from_bytes::<CompressedPoints>(&wire).unwrap_err();
        assert!(matches!(error, postcard::Error::SerdeDeCustom), "{error:?}");
        let direct = PackedPoints(zstd::bulk::compress(&vec![0u8; 32 << 20], PACK_LEVEL).unwrap())
            .unpack::<Vec<u8>>()
            .unwrap_err();
        assert!(direct.contains("more than"), "{direct}");
    }

    #[test]
    fn bytes_that_are_not_a_zstd_frame_are_refused() {
        let wire = postcard::to_allocvec(&PackedPoints(b"not zstd at all".to_vec())).unwrap();
        assert!(postcard::from_bytes::<CompressedPoints>(&wire).is_err());
    }
}
