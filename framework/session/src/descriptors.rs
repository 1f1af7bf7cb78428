//! `robot<i>/descriptors.bin`: a robot's keyframe descriptors, little-endian (layout in the crate doc).

/// The file's first bytes.
const MAGIC: &[u8; 8] = b"SKIDDESC";

/// The version of the descriptor file this crate writes and reads.
const VERSION: u32 = 1;

/// Bytes before the first entry: magic, version, length, count.
const HEADER_BYTES: usize = 8 + 4 + 4 + 8;

/// A decoded descriptor file: the descriptor length and each keyframe index with its values.
pub type DecodedDescriptors = (usize, Vec<(u32, Vec<f32>)>);

/// The file's bytes for `entries` (keyframe index, values), each of `length` values.
pub fn encode_descriptors(length: usize, entries: &[(u32, &[f32])]) -> Result<Vec<u8>, String> {
    let length_u32 =
        u32::try_from(length).map_err(|_| format!("a descriptor of {length} values is too long"))?;
    let mut bytes = Vec::with_capacity(HEADER_BYTES + entries.len() * (4 + 4 * length));
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&VERSION.to_le_bytes());
    bytes.extend_from_slice(&length_u32.to_le_bytes());
    bytes.extend_from_slice(&(entries.len() as u64).to_le_bytes());
    for (index, values) in entries {
        if values.len() != length {
            return Err(format!(
                "keyframe {index}'s descriptor has {} values where the session's have {length}",
                values.len()
            ));
        }
        bytes.extend_from_slice(&index.to_le_bytes());
        for value in *values {
            bytes.extend_from_slice(&value.to_le_bytes());
        }
    }
    Ok(bytes)
}

fn read_u32(bytes: &[u8], at: usize) -> Option<u32> {
    let field: [u8; 4] = bytes.get(at..at + 4)?.try_into().ok()?;
    Some(u32::from_le_bytes(field))
}

/// The descriptor length and the entries of a descriptor file, or why the bytes are not one (naming the
/// entry where it matters).
pub fn decode_descriptors(bytes: &[u8]) -> Result<DecodedDescriptors, String> {
    if bytes.len() < HEADER_BYTES || &bytes[..8] != MAGIC {
        return Err("not a SKiD descriptor file (it does not start with SKIDDESC and its header)".into());
    }
    let version = read_u32(bytes, 8).unwrap_or(0);
    if version != VERSION {
        return Err(format!(
            "descriptor file version {version}; this SKiD reads version {VERSION}"
        ));
    }
    let length = read_u32(bytes, 12).unwrap_or(0) as usize;
    let count_field: [u8; 8] = bytes[16..24]
        .try_into()
        .map_err(|_| "the header's entry count is cut short".to_string())?;
    let count = u64::from_le_bytes(count_field);
    let entry_bytes = 4 + 4 * length as u64;
    let body = (bytes.len() - HEADER_BYTES) as u64;
    if count.checked_mul(entry_bytes) != Some(body) {
        return Err(format!(
            "the header announces {count} descriptors of {length} values ({entry_bytes} bytes each), but \
             {body} bytes follow it"
        ));
    }
    let mut entries = Vec::with_capacity(count as usize);
    for entry in bytes[HEADER_BYTES..].chunks_exact(entry_bytes as usize) {
        let index = read_u32(entry, 0).unwrap_or(0);
        let values: Vec<f32> = entry[4..]
            .chunks_exact(4)
            .map(|v| f32::from_le_bytes([v[0], v[1], v[2], v[3]]))
            .collect();
        if values.iter().any(|v| !v.is_finite()) {
            return Err(format!(
                "keyframe {index}'s descriptor holds a value that is not finite"
            ));
        }
        entries.push((index, values));
    }
    Ok((length, entries))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn descriptors_round_trip_and_lying_counts_are_refused() {
        let a = [0.5_f32, -1.0, 3.25];
        let b = [1.0_f32, 2.0, 3.0];
        let bytes = encode_descriptors(3, &[(4, &a), (9, &b)]).unwrap();
        let (length, entries) = decode_descriptors(&bytes).unwrap();
        assert_eq!(length, 3);
        assert_eq!(entries, vec![(4, a.to_vec()), (9, b.to_vec())]);

        let mut lying = bytes.clone();
        lying[16..24].copy_from_slice(&u64::MAX.to_le_bytes());
        let error = decode_descriptors(&lying).unwrap_err();
        assert!(error.contains("announces"), "{error}");
        let error = decode_descriptors(&bytes[..bytes.len() - 1]).unwrap_err();
        assert!(error.contains("bytes follow"), "{error}");
        assert!(decode_descriptors(b"PLY").is_err());
        assert!(encode_descriptors(2, &[(0, &a)]).is_err());
    }
}
