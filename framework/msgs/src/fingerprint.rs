//! A fingerprint of the wire types' layout, compared across the plugin boundary.

use crate::{
    CloudHeader, DescriptorHeader, ImuSample, Information6, KeyframeHeader, LoopMeasurement, OdometryEdge,
    Point, PoseWire, RawPoint, WireType,
};

/// FNV-1a over a byte string, usable in constant context.
const fn fnv1a(mut hash: u64, bytes: &[u8]) -> u64 {
    let mut i = 0;
    while i < bytes.len() {
        hash ^= bytes[i] as u64;
        hash = hash.wrapping_mul(0x0000_0100_0000_01b3);
        i += 1;
    }
    hash
}

/// Folds one type's name, size and alignment into the running hash.
const fn fold<T: WireType>(hash: u64) -> u64 {
    let hash = fnv1a(hash, T::TYPE_NAME.as_bytes());
    let hash = fnv1a(hash, &(std::mem::size_of::<T>() as u64).to_le_bytes());
    fnv1a(hash, &(std::mem::align_of::<T>() as u64).to_le_bytes())
}

/// Computes the layout fingerprint of every wire type in this crate.
pub const fn layout_fingerprint() -> u64 {
    let mut hash = 0xcbf2_9ce4_8422_2325;
    hash = fold::<Point>(hash);
    hash = fold::<RawPoint>(hash);
    hash = fold::<ImuSample>(hash);
    hash = fold::<PoseWire>(hash);
    hash = fold::<CloudHeader>(hash);
    hash = fold::<KeyframeHeader>(hash);
    hash = fold::<DescriptorHeader>(hash);
    hash = fold::<Information6>(hash);
    hash = fold::<OdometryEdge>(hash);
    fold::<LoopMeasurement>(hash)
}

/// The layout fingerprint of this build's wire types.
pub const LAYOUT_FINGERPRINT: u64 = layout_fingerprint();

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fingerprint_depends_on_names_and_sizes() {
        assert_ne!(fold::<Point>(1), fold::<RawPoint>(1));
        assert_eq!(LAYOUT_FINGERPRINT, layout_fingerprint());
    }
}
