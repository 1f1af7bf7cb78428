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
            resize_for(out, size);
            crate::lz4_frame::decompress_exact(compressed, out)
        }
        other => Err(format!(
            "unknown compression `{other}` (bags use none, bz2 or lz4)"
        )),
    }
}

fn read_exactly(mut reader: impl Read, size: usize, out: &mut Vec<u8>, name: &str) -> Result<(), String> {
    resize_for(out, size);
    reader.read_exact(out).map_err(|e| match e.kind() {
        std::io::ErrorKind::UnexpectedEof => {
            format!("{name} data decompresses to fewer bytes than the {size} its header says")
        }
        _ => format!("{name} data is corrupt: {e}"),
    })?;
    let mut extra = [0u8; 1];
    match reader.read(&mut extra) {
        Ok(0) => Ok(()),
        Ok(_) => Err(format!(
            "{name} data decompresses to more than the {size} bytes its header says"
        )),
        Err(e) => Err(format!("{name} data is corrupt after {size} bytes: {e}")),
    }
}
