//! Bad bags get clear errors naming the file (and the offset, topic or message), never a panic or an
//! allocation sized by a lying length field: truncation, corrupt and unknown chunk compression, lying
//! sizes, clouds without x/y/z or with a `row_step` that disagrees with the data, an MCAP channel without
//! its schema; and a bounded mutation fuzz over every container that CI runs on each test pass.

use crate::generated;

use std::path::Path;

use generated::fixtures;
use skid_bag::msgs::motion::{decode_imu, decode_odometry, decode_pose_stamped, decode_tf_message};
use skid_bag::msgs::point_cloud2::{CloudLayout, PointCloud2, raw_points};
use skid_bag::{Bag, BagError, MessageReader, WireReader};

/// Reads every message of a bag and decodes what SKiD decodes; the first error, if any.
fn read_everything(path: &Path) -> Result<usize, BagError> {
    let mut bag = Bag::open(path)?;
    let mut count = 0;
    while let Some(message) = bag.next_message()? {
        count += 1;
        let Ok(mut reader) = WireReader::new(&message.data, message.connection.encoding) else {
            continue;
        };
        match message.connection.message_type.as_str() {
            "sensor_msgs/PointCloud2" => {
                if let Ok(cloud) = PointCloud2::decode(&mut reader)
                    && let Ok(layout) = CloudLayout::detect(&cloud.fields)
                {
                    let decoded = raw_points(&cloud, &layout);
                    assert!(decoded.points.len() <= cloud.point_count());
                }
            }
            "sensor_msgs/Imu" => drop(decode_imu(&mut reader)),
            "nav_msgs/Odometry" => drop(decode_odometry(&mut reader)),
            "geometry_msgs/PoseStamped" => drop(decode_pose_stamped(&mut reader)),
            "tf2_msgs/TFMessage" => drop(decode_tf_message(&mut reader)),
            _ => {}
        }
    }
    Ok(count)
}

fn mutated(name: &str, edit: impl FnOnce(&mut Vec<u8>)) -> (tempfile::TempDir, std::path::PathBuf) {
    let mut bytes = std::fs::read(fixtures().join(name)).unwrap();
    edit(&mut bytes);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    (dir, path)
}

fn find(bytes: &[u8], needle: &[u8]) -> usize {
    bytes.windows(needle.len()).position(|w| w == needle).unwrap()
}

#[test]
fn a_corrupt_lz4_chunk_is_an_error_with_file_and_offset() {
    let (_dir, path) = mutated("lz4.bag", |bytes| {
        let at = find(bytes, b"compression=lz4") + 200;
        for byte in &mut bytes[at..at + 64] {
            *byte ^= 0x5a;
        }
    });
    let error = read_everything(&path).unwrap_err().to_string();
    assert!(
        error.contains("lz4.bag") && error.contains("byte offset") && error.contains("lz4"),
        "{error}"
    );
}

#[test]
fn an_unknown_compression_is_named() {
    let (_dir, path) = mutated("bz2.bag", |bytes| {
        let at = find(bytes, b"compression=bz2");
        bytes[at + 12..at + 15].copy_from_slice(b"xz9");
    });
    let error = read_everything(&path).unwrap_err().to_string();
    assert!(error.contains("unknown compression `xz9`"), "{error}");
}

#[test]
fn lying_sizes_are_refused_before_allocating() {
    // A chunk announcing 4 GB uncompressed.
    let (_dir, path) = mutated("lz4.bag", |bytes| {
        let at = find(bytes, b"size=") + 5;
        bytes[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    });
    let error = read_everything(&path).unwrap_err().to_string();
    assert!(
        error.contains("4294967295") && error.contains("lz4.bag"),
        "{error}"
    );
    // The bag header's own length field.
    let (_dir, path) = mutated("none.bag", |bytes| {
        bytes[13..17].copy_from_slice(&0x7fff_ffffu32.to_le_bytes());
    });
    let error = read_everything(&path).unwrap_err().to_string();
    assert!(
        error.contains("none.bag") && error.contains("byte offset 13"),
        "{error}"
    );
}

#[test]
fn truncated_files_end_with_a_warning_or_an_error_never_a_panic() {
    for name in ["none.bag", "lz4.bag", "zstd.mcap", "lz4.mcap"] {
        let full = std::fs::read(fixtures().join(name)).unwrap();
        for keep in [0, 5, 13, 100, full.len() / 3, full.len() / 2, full.len() - 40] {
            let (_dir, path) = mutated(name, |bytes| bytes.truncate(keep));
            match read_everything(&path) {
                Ok(count) => assert!(count < 1000, "{name} cut at {keep}"),
                Err(error) => assert!(error.to_string().contains(name), "{name} cut at {keep}: {error}"),
            }
        }
    }
    let (_dir, path) = mutated("none.bag", |bytes| bytes.truncate(10));
    let error = Bag::open(&path).err().unwrap().to_string();
    assert!(error.contains("none.bag") && error.contains("ROS 1"), "{error}");
}

#[test]
fn a_truncated_mcap_is_read_up_to_the_cut() {
    for name in ["zstd.mcap", "lz4.mcap"] {
        let full = read_everything(&fixtures().join(name)).unwrap();
        let bytes = std::fs::read(fixtures().join(name)).unwrap();
        // Cut inside the data section (the summary and footer go with the tail, as when a recorder dies).
        let (_dir, path) = mutated(name, |bytes| bytes.truncate(bytes.len() * 2 / 3));
        let read = read_everything(&path).unwrap_or_else(|error| panic!("{name}: {error}"));
        assert!(
            read > 0 && read < full,
            "{name}: {read} of {full} messages from {} bytes",
            bytes.len()
        );
    }
}

#[test]
fn clouds_without_xyz_or_with_a_wrong_row_step_are_named() {
    let mut bag = Bag::open(&fixtures().join("bad_clouds.bag")).unwrap();
    let mut errors = Vec::new();
    while let Some(message) = bag.next_message().unwrap() {
        let mut reader = WireReader::new(&message.data, message.connection.encoding).unwrap();
        let error = match PointCloud2::decode(&mut reader) {
            Ok(cloud) => CloudLayout::detect(&cloud.fields).unwrap_err(),
            Err(error) => error,
        };
        errors.push((message.connection.topic.clone(), error.to_string()));
    }
    assert_eq!(errors.len(), 2);
    assert!(
        errors[0].1.contains("no numeric field `x`") && errors[0].1.contains("[a, b, c]"),
        "{errors:?}"
    );
    assert!(errors[1].1.contains("row_step 240"), "{errors:?}");
}

#[test]
fn an_mcap_channel_without_its_schema_is_an_error() {
    let path = fixtures().join("no_schema.mcap");
    let error = read_everything(&path).unwrap_err().to_string();
    assert!(
        error.contains("no_schema.mcap") && error.contains("/points") && error.contains("schema"),
        "{error}"
    );
}

/// A small xorshift generator, so the fuzz is the same on every run.
struct Xorshift(u64);

impl Xorshift {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    fn below(&mut self, bound: usize) -> usize {
        (self.next() % bound.max(1) as u64) as usize
    }
}

#[test]
fn bounded_mutation_fuzz_of_every_container_never_panics() {
    let mut random = Xorshift(0x5eed_1234_abcd_0001);
    let names = [
        "none.bag",
        "bz2.bag",
        "lz4.bag",
        "unindexed.bag",
        "zstd.mcap",
        "lz4.mcap",
        "bad_clouds.bag",
    ];
    let dir = tempfile::tempdir().unwrap();
    let mut outcomes = (0, 0);
    for round in 0..140 {
        let name = names[round % names.len()];
        let mut bytes = std::fs::read(fixtures().join(name)).unwrap();
        for _ in 0..1 + random.below(8) {
            let at = random.below(bytes.len());
            match random.below(4) {
                0 => bytes[at] ^= 1 << random.below(8),
                1 => bytes[at] = 0xff,
                2 => {
                    let end = (at + 4).min(bytes.len());
                    bytes[at..end].fill(0);
                }
                _ => bytes.truncate(at.max(1)),
            }
        }
        let path = dir.path().join(format!("{round}-{name}"));
        std::fs::write(&path, &bytes).unwrap();
        match read_everything(&path) {
            Ok(_) => outcomes.0 += 1,
            Err(error) => {
                assert!(error.to_string().contains(&format!("{round}-{name}")), "{error}");
                outcomes.1 += 1;
            }
        }
        std::fs::remove_file(&path).unwrap();
    }
    // Both outcomes happen: the fuzz reaches the decoders and the error paths.
    assert!(outcomes.0 > 10 && outcomes.1 > 10, "{outcomes:?}");
}
