//! Decompressing a ROS 1 bag chunk (`bz2`, or `lz4` in the LZ4 frame format) into a reused buffer that
//! must come out exactly the size the chunk header states: a lying size can neither grow memory past it
//! nor hide a truncated chunk.

use std::io::Read;

/// Sets a reused buffer's length to `len`, zero-filling only what it grows by.
pub fn resize_for(buffer: &mut Vec<u8>, len: usize) {
    if buffer.len() < len {
        buffer.resize(len, 0);
    } else {
        buffer.truncate(len);
    }
}

/// Decompresses a chunk into `out`, checking it yields exactly the announced size (so a lying size
/// can neither grow memory past it nor hide a truncated chunk).
pub fn decompress_into(
    compression: &str,
    compressed: &[u8],
    size: usize,
    out: &mut Vec<u8>,
) -> Result<(), String> {
    match compression {
        "bz2" => read_exactly(bzip2::read::BzDecoder::new(compressed), size, out, "bz2"),
        "lz4" => {
            // LZ4 expands at most 255-fold: a larger size is a lie, refused before it is allocated.
            let most = compressed
                .len()
                .saturating_mul(LZ4_MAX_EXPANSION)
                .saturating_add(1 << 16);
            if size > most {
                return Err(format!(
                    "lz4 data of {} bytes cannot decompress to the {size} bytes its header says",
                    compressed.len()
                ));
            }
            resize_for(out, size);
            crate::lz4_frame::decompress_exact(compressed, out)
        }
        other => Err(format!(
            "unknown compression `{other}` (bags use none, bz2 or lz4)"
        )),
    }
}

/// Largest expansion of LZ4 (a run of one byte is 255 times its encoded length at best).
const LZ4_MAX_EXPANSION: usize = 255;

/// Reads the decompressed stream into `out`, which grows only as data really comes out (a header that
/// announces a gigabyte over a few compressed bytes allocates nothing extra; found by fuzzing), and
/// checks it is exactly `size` bytes.
fn read_exactly(reader: impl Read, size: usize, out: &mut Vec<u8>, name: &str) -> Result<(), String> {
    out.clear();
    let limit = u64::try_from(size).unwrap_or(u64::MAX).saturating_add(1);
    reader
        .take(limit)
        .read_to_end(out)
        .map_err(|e| format!("{name} data is corrupt: {e}"))?;
    match out.len().cmp(&size) {
        std::cmp::Ordering::Equal => Ok(()),
        std::cmp::Ordering::Less => Err(format!(
            "{name} data decompresses to fewer bytes than the {size} its header says"
        )),
        std::cmp::Ordering::Greater => Err(format!(
            "{name} data decompresses to more than the {size} bytes its header says"
        )),
    }
}
