//! Writing bags: ROS 1 bags ([`Ros1Writer`]), bare MCAP files ([`McapWriter`]) and ROS 2 MCAP bag folders
//! ([`McapBagWriter`]), the message serialization they share ([`WireWriter`], [`encode`], and [`viz`] for
//! paths, transforms and markers), and [`RobotBagWriter`], which records one robot's scans, IMU samples
//! and ground truth on the standard topics.

pub mod encode;
mod mcap_bag;
mod mcap_writer;
mod ros1;
pub mod viz;
mod wire_writer;

use std::path::{Path, PathBuf};

use skid_msgs::{ImuSample, RawPoint};

pub use encode::WrittenType;
pub use mcap_bag::McapBagWriter;
pub use mcap_writer::{McapWriter, WrittenMcap, WrittenTopic};
pub use ros1::{Ros1Compression, Ros1Writer};
pub use wire_writer::WireWriter;

use crate::error::BagError;
use crate::wire::Encoding;

/// The container a [`RobotBagWriter`] writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BagFormat {
    /// A ROS 1 `.bag` file with LZ4 chunks.
    Ros1,
    /// A ROS 2 bag folder with MCAP storage.
    Mcap,
}

enum Container {
    Ros1(Ros1Writer),
    Mcap(Box<McapBagWriter>),
}

/// The topics a robot's recording uses.
pub const POINTS_TOPIC: &str = "/points";
pub const IMU_TOPIC: &str = "/imu";
pub const GROUND_TRUTH_TOPIC: &str = "/ground_truth";

/// Records one robot: clouds on [`POINTS_TOPIC`], IMU on [`IMU_TOPIC`], ground truth (Odometry of
/// `lidar` in `world`) on [`GROUND_TRUTH_TOPIC`], each message's receive time its stamp.
pub struct RobotBagWriter {
    container: Container,
    encoding: Encoding,
    /// Connection or channel ids of the points, IMU and ground-truth topics.
    ids: [u32; 3],
    sequence: [u32; 3],
}

impl RobotBagWriter {
    /// Creates `path` (a `.bag` file for ROS 1, a bag folder for MCAP).
    pub fn create(path: &Path, format: BagFormat) -> Result<Self, BagError> {
        let topics = [
            (POINTS_TOPIC, WrittenType::PointCloud2),
            (IMU_TOPIC, WrittenType::Imu),
            (GROUND_TRUTH_TOPIC, WrittenType::Odometry),
        ];
        let mut ids = [0u32; 3];
        let (container, encoding) = match format {
            BagFormat::Ros1 => {
                let mut writer = Ros1Writer::create(path, Ros1Compression::Lz4)?;
                for (slot, (topic, kind)) in ids.iter_mut().zip(topics) {
                    let encoding = Encoding::Ros1;
                    *slot = writer.add_connection(
                        topic,
                        kind.name(encoding),
                        kind.md5sum(),
                        &kind.definition(encoding),
                    );
                }
                (Container::Ros1(writer), Encoding::Ros1)
            }
            BagFormat::Mcap => {
                let mut writer = McapBagWriter::create(path)?;
                for (slot, (topic, kind)) in ids.iter_mut().zip(topics) {
                    let encoding = Encoding::Cdr;
                    *slot = u32::from(writer.add_topic(
                        topic,
                        kind.name(encoding),
                        &kind.definition(encoding),
                    )?);
                }
                (Container::Mcap(Box::new(writer)), Encoding::Cdr)
            }
        };
        Ok(Self {
            container,
            encoding,
            ids,
            sequence: [0; 3],
        })
    }

    fn write(&mut self, slot: usize, time_nanos: u64, data: &[u8]) -> Result<(), BagError> {
        self.sequence[slot] += 1;
        match &mut self.container {
            Container::Ros1(writer) => writer.write(self.ids[slot], time_nanos, data),
            Container::Mcap(writer) => writer.write(
                u16::try_from(self.ids[slot]).unwrap_or(u16::MAX),
                time_nanos,
                data,
            ),
        }
    }

    /// One scan in the `lidar` frame; point times are offsets from `stamp_nanos`.
    pub fn write_scan(&mut self, stamp_nanos: u64, points: &[RawPoint]) -> Result<(), BagError> {
        let data = encode::point_cloud2(self.encoding, self.sequence[0], stamp_nanos, "lidar", points);
        self.write(0, stamp_nanos, &data)
    }

    /// One IMU sample in the `lidar` frame.
    pub fn write_imu(&mut self, sample: &ImuSample) -> Result<(), BagError> {
        let data = encode::imu(self.encoding, self.sequence[1], "lidar", sample);
        self.write(1, sample.stamp_nanos, &data)
    }

    /// The ground-truth pose of `lidar` in `world`.
    pub fn write_ground_truth(
        &mut self,
        stamp_nanos: u64,
        translation_m: [f64; 3],
        rotation_xyzw: [f64; 4],
    ) -> Result<(), BagError> {
        let data = encode::odometry(
            self.encoding,
            self.sequence[2],
            stamp_nanos,
            ("world", "lidar"),
            translation_m,
            rotation_xyzw,
        );
        self.write(2, stamp_nanos, &data)
    }

    /// Finishes the file (index, summary, metadata); returns the bag's path.
    pub fn finish(self) -> Result<PathBuf, BagError> {
        match self.container {
            Container::Ros1(writer) => writer.finish(),
            Container::Mcap(writer) => writer.finish(),
        }
    }
}
