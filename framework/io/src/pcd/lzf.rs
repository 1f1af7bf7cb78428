//! LZF compression, as used by PCL for `DATA binary_compressed` PCD files (liblzf by Marc Lehmann).
//!
//! Written here because the crates.io LZF crates are either deprecated (`lzf`) or new and
//! single-release (`lzf-rust`), and the format is tiny. A compressed stream is a sequence of chunks,
//! each introduced by a control byte `c`:
//!
//! * `c < 32` (`000LLLLL`): a **literal run**: the next `c + 1` bytes are copied to the output as is.
//! * `c >= 32` (`LLLooooo`): a **back-reference**. `len = c >> 5`; when `len == 7` the next byte is added
//!   to it (so `len` goes up to 262). The next byte `b` completes the offset:
//!   `distance = ((c & 0x1f) << 8) + b + 1` (1..=8192). Then `len + 2` bytes (3..=264) are copied from
//!   `distance` bytes back in the output, one by one, so a reference may overlap the bytes it produces
//!   (a run of one repeated byte is a back-reference with distance 1).
//!
//! There is no header and no checksum; the container (the PCD header) stores both sizes.

/// Longest match a back-reference can encode (`7 + 255 + 2`).
const MAX_MATCH: usize = 264;
/// Farthest back a reference can point.
const MAX_DISTANCE: usize = 8192;
/// Longest literal run one control byte can announce.
const MAX_LITERALS: usize = 32;
/// log2 of the size of the compressor's hash table.
const HASH_BITS: u32 = 14;

/// Decompresses `input`, which must expand to exactly `expected_len` bytes.
///
/// On failure returns the offset within `input` of the chunk that is wrong and a sentence saying why.
pub fn decompress(input: &[u8], expected_len: usize) -> Result<Vec<u8>, (usize, String)> {
    // One 3-byte back-reference expands to at most 264 bytes, which bounds a trustworthy allocation.
    let mut out: Vec<u8> = Vec::with_capacity(expected_len.min(input.len().saturating_mul(88)));
    let mut i = 0;
    while i < input.len() {
        let chunk_start = i;
        let ctrl = usize::from(input[i]);
        i += 1;
        if ctrl < 32 {
            let run = ctrl + 1;
            let Some(literals) = input.get(i..i + run) else {
                return Err((
                    chunk_start,
                    format!("literal run of {run} bytes runs past the end of the compressed data"),
                ));
            };
            if out.len() + run > expected_len {
                return Err((
                    chunk_start,
                    format!("output exceeds the announced {expected_len} bytes"),
                ));
            }
            out.extend_from_slice(literals);
            i += run;
        } else {
            let mut len = ctrl >> 5;
            if len == 7 {
                let Some(&extra) = input.get(i) else {
                    return Err((
                        chunk_start,
                        "back-reference length byte missing at the end".to_owned(),
                    ));
                };
                len += usize::from(extra);
                i += 1;
            }
            let Some(&low) = input.get(i) else {
                return Err((
                    chunk_start,
                    "back-reference offset byte missing at the end".to_owned(),
                ));
            };
            i += 1;
            let distance = ((ctrl & 0x1f) << 8) + usize::from(low) + 1;
            if distance > out.len() {
                return Err((
                    chunk_start,
                    format!(
                        "back-reference {distance} bytes back but only {} bytes decoded",
                        out.len()
                    ),
                ));
            }
            let len = len + 2;
            if out.len() + len > expected_len {
                return Err((
                    chunk_start,
                    format!("output exceeds the announced {expected_len} bytes"),
                ));
            }
            let from = out.len() - distance;
            for k in 0..len {
                let byte = out[from + k];
                out.push(byte);
            }
        }
    }
    if out.len() != expected_len {
        return Err((
            input.len(),
            format!("decoded {} bytes, header announces {expected_len}", out.len()),
        ));
    }
    Ok(out)
}

/// Compresses `input` (greedy matching with a hash of the next three bytes, like liblzf).
pub fn compress(input: &[u8]) -> Vec<u8> {
    let n = input.len();
    let mut out = Vec::with_capacity(n / 2 + 16);
    let mut table = vec![usize::MAX; 1 << HASH_BITS];
    let mut literal_start = 0;
    let mut ip = 0;
    while ip + 3 <= n {
        let h = hash3(input[ip], input[ip + 1], input[ip + 2]);
        let candidate = table[h];
        table[h] = ip;
        if candidate != usize::MAX
            && ip - candidate <= MAX_DISTANCE
            && input[candidate..candidate + 3] == input[ip..ip + 3]
        {
            let max_len = MAX_MATCH.min(n - ip);
            let mut len = 3;
            while len < max_len && input[candidate + len] == input[ip + len] {
                len += 1;
            }
            push_literals(&mut out, &input[literal_start..ip]);
            push_reference(&mut out, ip - candidate - 1, len);
            // Index the positions inside the match so later data can refer to them too.
            let end = ip + len;
            let mut k = ip + 1;
            while k < end && k + 3 <= n {
                table[hash3(input[k], input[k + 1], input[k + 2])] = k;
                k += 1;
            }
            ip = end;
            literal_start = ip;
        } else {
            ip += 1;
        }
    }
    push_literals(&mut out, &input[literal_start..]);
    out
}

/// Hash of three bytes into the compressor's table.
fn hash3(a: u8, b: u8, c: u8) -> usize {
    let v = (u32::from(a) << 16) | (u32::from(b) << 8) | u32::from(c);
    (v.wrapping_mul(2_654_435_761) >> (32 - HASH_BITS)) as usize
}

/// Appends literal runs of at most 32 bytes each.
fn push_literals(out: &mut Vec<u8>, literals: &[u8]) {
    for run in literals.chunks(MAX_LITERALS) {
        out.push((run.len() - 1) as u8);
        out.extend_from_slice(run);
    }
}

/// Appends a back-reference copying `len` (3..=264) bytes from `distance_minus_one + 1` bytes back.
fn push_reference(out: &mut Vec<u8>, distance_minus_one: usize, len: usize) {
    let code = len - 2;
    let high = (distance_minus_one >> 8) as u8;
    let low = (distance_minus_one & 0xff) as u8;
    if code < 7 {
        out.push(((code as u8) << 5) | high);
    } else {
        out.push((7 << 5) | high);
        out.push((code - 7) as u8);
    }
    out.push(low);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_varied_inputs() {
        let mut inputs: Vec<Vec<u8>> = vec![vec![], vec![7], b"abcabcabcabcabcabc".to_vec(), vec![0; 10_000]];
        let mut state = 12345_u32;
        let noise: Vec<u8> = (0..50_000)
            .map(|_| {
                state = state.wrapping_mul(1_103_515_245).wrapping_add(12345);
                (state >> 24) as u8
            })
            .collect();
        inputs.push(noise.clone());
        inputs.push(noise.iter().map(|b| b & 0x3).collect());
        for input in inputs {
            let packed = compress(&input);
            assert_eq!(decompress(&packed, input.len()).unwrap(), input);
        }
        assert!(compress(&[0; 10_000]).len() < 200);
    }

    #[test]
    fn known_stream_and_corruption() {
        // Literal "ab" then a back-reference of 4 bytes, distance 2: "ababab".
        let stream = [1, b'a', b'b', (2 << 5), 1];
        assert_eq!(decompress(&stream, 6).unwrap(), b"ababab");
        assert!(decompress(&stream, 5).is_err());
        assert_eq!(decompress(&[(1 << 5), 9], 3).unwrap_err().0, 0);
        assert!(decompress(&[5, 1, 2], 6).is_err());
    }
}
