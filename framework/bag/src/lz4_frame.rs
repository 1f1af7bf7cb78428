//! The LZ4 frame format (lz4/doc/lz4_Frame_format.md, version 1.6.x) decoded straight into one output
//! buffer: a ROS 1 bag's `lz4` chunk is a frame whose uncompressed size the chunk header states, so each
//! block is decompressed into its place in the chunk buffer, with no intermediate block buffer and no
//! copy out of one. Linked blocks (what `roslz4` and Python's `lz4.frame` write) reach back into the
//! previous 64 KiB of output, which is simply the bytes before the block in the same buffer. The frame
//! is parsed and checked here; each compressed block is decoded by liblz4 ([`crate::lz4_block`]).
//!
//! A frame is the magic number `0x184D2204`, a descriptor (FLG and BD bytes, the optional content size
//! and dictionary id, a header checksum), data blocks (a `u32` size whose top bit marks a stored block,
//! the block, an optional xxHash32 of it), an end mark of zero and an optional xxHash32 of the content.
//! Concatenated frames and skippable frames (magic `0x184D2A5_`) are allowed. Every check the format
//! offers is made: the version bits, the header checksum, block sizes against the declared maximum, the
//! block and content checksums, and the total against the size the caller expects.

use twox_hash::XxHash32;

const MAGIC: u32 = 0x184D_2204;
const SKIPPABLE_MAGIC: std::ops::RangeInclusive<u32> = 0x184D_2A50..=0x184D_2A5F;
const FLG_VERSION_MASK: u8 = 0b1100_0000;
const FLG_VERSION_01: u8 = 0b0100_0000;
const FLG_INDEPENDENT_BLOCKS: u8 = 0b0010_0000;
const FLG_BLOCK_CHECKSUMS: u8 = 0b0001_0000;
const FLG_CONTENT_SIZE: u8 = 0b0000_1000;
const FLG_CONTENT_CHECKSUM: u8 = 0b0000_0100;
const FLG_DICTIONARY_ID: u8 = 0b0000_0001;
const STORED_BLOCK_BIT: u32 = 0x8000_0000;
/// How far back a linked block's matches may reach.
const WINDOW_BYTES: usize = 64 * 1024;

/// Takes bytes off the front of the compressed input, naming what was cut short.
struct Input<'a> {
    bytes: &'a [u8],
    position: usize,
}

impl<'a> Input<'a> {
    fn take(&mut self, count: usize, what: &str) -> Result<&'a [u8], String> {
        let taken = self
            .position
            .checked_add(count)
            .and_then(|end| self.bytes.get(self.position..end))
            .ok_or_else(|| format!("lz4 data is cut short in {what} at byte {}", self.position))?;
        self.position += count;
        Ok(taken)
    }

    fn u32(&mut self, what: &str) -> Result<u32, String> {
        let bytes = self.take(4, what)?;
        Ok(u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]))
    }

    fn is_empty(&self) -> bool {
        self.position >= self.bytes.len()
    }
}

/// What a frame's descriptor says about the blocks that follow.
struct Descriptor {
    independent_blocks: bool,
    block_checksums: bool,
    content_checksum: bool,
    max_block_bytes: usize,
}

fn read_descriptor(input: &mut Input<'_>) -> Result<Descriptor, String> {
    let start = input.position;
    let flags = input.take(2, "a frame descriptor")?;
    let (flg, bd) = (flags[0], flags[1]);
    if flg & FLG_VERSION_MASK != FLG_VERSION_01 {
        return Err(format!("lz4 frame version bits are {:#04b}, not 01", flg >> 6));
    }
    if flg & FLG_DICTIONARY_ID != 0 {
        return Err("lz4 frame needs an external dictionary, which a bag cannot carry".to_owned());
    }
    let max_block_bytes = match (bd >> 4) & 0b111 {
        4 => 64 << 10,
        5 => 256 << 10,
        6 => 1 << 20,
        7 => 4 << 20,
        other => return Err(format!("lz4 frame has an invalid block size code {other}")),
    };
    if flg & FLG_CONTENT_SIZE != 0 {
        input.take(8, "a frame descriptor")?;
    }
    let described = &input.bytes[start..input.position];
    let header_checksum = input.take(1, "a frame descriptor")?[0];
    if (XxHash32::oneshot(0, described) >> 8) as u8 != header_checksum {
        return Err("lz4 frame descriptor checksum does not match".to_owned());
    }
    Ok(Descriptor {
        independent_blocks: flg & FLG_INDEPENDENT_BLOCKS != 0,
        block_checksums: flg & FLG_BLOCK_CHECKSUMS != 0,
        content_checksum: flg & FLG_CONTENT_CHECKSUM != 0,
        max_block_bytes,
    })
}

/// Decompresses the frames in `compressed` into `out`, which must come out exactly full: fewer or more
/// bytes than `out.len()` is an error, as is any corruption the format can detect.
pub fn decompress_exact(compressed: &[u8], out: &mut [u8]) -> Result<(), String> {
    let mut input = Input {
        bytes: compressed,
        position: 0,
    };
    let mut written = 0;
    while !input.is_empty() {
        let magic = input.u32("a frame's magic number")?;
        if SKIPPABLE_MAGIC.contains(&magic) {
            let skipped = input.u32("a skippable frame")? as usize;
            input.take(skipped, "a skippable frame")?;
            continue;
        }
        if magic != MAGIC {
            return Err(format!(
                "lz4 frame magic number is {magic:#010x}, not {MAGIC:#010x}"
            ));
        }
        written = decompress_frame(&mut input, out, written)?;
    }
    if written != out.len() {
        return Err(format!(
            "lz4 data decompresses to {written} bytes, fewer than the {} its header says",
            out.len()
        ));
    }
    Ok(())
}

/// Decodes one frame's blocks into `out[written..]`; returns the new count of bytes written.
fn decompress_frame(input: &mut Input<'_>, out: &mut [u8], mut written: usize) -> Result<usize, String> {
    let descriptor = read_descriptor(input)?;
    let frame_start = written;
    loop {
        let block_header = input.u32("a block size")?;
        if block_header == 0 {
            break;
        }
        let block_bytes = (block_header & !STORED_BLOCK_BIT) as usize;
        if block_bytes > descriptor.max_block_bytes {
            return Err(format!(
                "lz4 block of {block_bytes} bytes is larger than the frame's {}-byte maximum",
                descriptor.max_block_bytes
            ));
        }
        let block = input.take(block_bytes, "a block")?;
        if descriptor.block_checksums && input.u32("a block checksum")? != XxHash32::oneshot(0, block) {
            return Err(format!(
                "lz4 block checksum does not match at output byte {written}"
            ));
        }
        let out_bytes = out.len();
        let too_much = || format!("lz4 data decompresses to more than the {out_bytes} bytes its header says");
        let room = descriptor.max_block_bytes.min(out_bytes - written);
        let room_limited_by_size = room < descriptor.max_block_bytes;
        let produced = if block_header & STORED_BLOCK_BIT != 0 {
            out[written..written + room]
                .get_mut(..block_bytes)
                .ok_or_else(too_much)?
                .copy_from_slice(block);
            block_bytes
        } else {
            let window_start = if descriptor.independent_blocks {
                written
            } else {
                written.saturating_sub(WINDOW_BYTES).max(frame_start)
            };
            crate::lz4_block::decompress_after_prefix(block, out, window_start, written, room).ok_or_else(|| {
                if room_limited_by_size {
                    format!("lz4 data decompresses to more than the {out_bytes} bytes its header says, or a block at output byte {written} is corrupt")
                } else {
                    format!("lz4 block at output byte {written} is corrupt")
                }
            })?
        };
        written += produced;
    }
    if descriptor.content_checksum
        && input.u32("the content checksum")? != XxHash32::oneshot(0, &out[frame_start..written])
    {
        return Err("lz4 content checksum does not match".to_owned());
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use std::io::Write;

    use lz4_flex::frame::{BlockMode, BlockSize, FrameEncoder, FrameInfo};

    use super::decompress_exact;

    /// 600 KiB that compresses (repeated structure) but not trivially (a varying counter).
    fn content() -> Vec<u8> {
        (0..600 * 1024u32).map(|i| ((i / 7) ^ (i % 251)) as u8).collect()
    }

    /// A frame written by lz4_flex's own encoder, an implementation independent of this decoder.
    fn frame(info: FrameInfo, content: &[u8]) -> Vec<u8> {
        let mut encoder = FrameEncoder::with_frame_info(info, Vec::new());
        encoder.write_all(content).unwrap();
        encoder.finish().unwrap()
    }

    fn every_frame_kind() -> Vec<(String, FrameInfo)> {
        let mut kinds = Vec::new();
        for mode in [BlockMode::Linked, BlockMode::Independent] {
            for size in [BlockSize::Max64KB, BlockSize::Max256KB, BlockSize::Max4MB] {
                for checksums in [false, true] {
                    let info = FrameInfo::new()
                        .block_mode(mode)
                        .block_size(size)
                        .block_checksums(checksums)
                        .content_checksum(checksums)
                        .content_size(checksums.then_some(600 * 1024));
                    kinds.push((format!("{mode:?} {size:?} checksums {checksums}"), info));
                }
            }
        }
        kinds
    }

    #[test]
    fn every_block_mode_size_and_checksum_setting_round_trips() {
        let content = content();
        for (name, info) in every_frame_kind() {
            let compressed = frame(info, &content);
            let mut out = vec![0u8; content.len()];
            decompress_exact(&compressed, &mut out).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(out == content, "{name}: content differs");
        }
    }

    #[test]
    fn incompressible_data_in_stored_blocks_and_concatenated_frames_round_trip() {
        let mut state = 0x2545_f491u32;
        let noise: Vec<u8> = (0..200_000)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 17;
                state ^= state << 5;
                state as u8
            })
            .collect();
        let mut compressed = frame(FrameInfo::new(), &noise);
        compressed.extend(frame(FrameInfo::new(), &content()));
        let mut out = vec![0u8; noise.len() + content().len()];
        decompress_exact(&compressed, &mut out).unwrap();
        assert!(out[..noise.len()] == noise[..] && out[noise.len()..] == content()[..]);
    }

    #[test]
    fn a_size_that_disagrees_with_the_content_is_refused_both_ways() {
        let compressed = frame(FrameInfo::new(), &content());
        let mut short = vec![0u8; content().len() - 1];
        let error = decompress_exact(&compressed, &mut short).unwrap_err();
        assert!(error.contains("more than"), "{error}");
        let mut long = vec![0u8; content().len() + 1];
        let error = decompress_exact(&compressed, &mut long).unwrap_err();
        assert!(error.contains("fewer than"), "{error}");
    }

    #[test]
    fn corruption_is_reported_never_a_panic() {
        let content = content();
        let checked = FrameInfo::new().block_checksums(true).content_checksum(true);
        let compressed = frame(checked, &content);
        let mut out = vec![0u8; content.len()];
        let mut detected = 0;
        for position in (0..compressed.len()).step_by(97) {
            let mut broken = compressed.clone();
            broken[position] ^= 0x5a;
            detected += usize::from(decompress_exact(&broken, &mut out).is_err());
        }
        // With both checksums on, every flipped byte is caught.
        assert_eq!(detected, compressed.len().div_ceil(97));
        for cut in [0, 3, 6, compressed.len() / 2, compressed.len() - 1] {
            assert!(
                decompress_exact(&compressed[..cut.max(1)], &mut out).is_err(),
                "cut at {cut}"
            );
        }
        let plain = frame(FrameInfo::new(), &content);
        for position in (0..plain.len()).step_by(31) {
            let mut broken = plain.clone();
            broken[position] = broken[position].wrapping_add(1);
            let _ = decompress_exact(&broken, &mut out);
        }
    }
}
