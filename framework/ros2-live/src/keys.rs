//! The names `rmw_zenoh` (ROS 2 Jazzy's zenoh middleware) gives things on a zenoh network, as its design
//! document describes them (github.com/ros2/rmw_zenoh, docs/design.md) and its nodes put them:
//!
//! - a topic's data is put on `<domain id>/<topic without the leading slash>/<type, the DDS way>/<type
//!   hash>`, e.g. `0/robot0/odometry/nav_msgs::msg::dds_::Odometry_/RIHS01_3cc9…`;
//! - every message carries an attachment: the publisher's sequence number and source timestamp (two
//!   little-endian `i64`, nanoseconds since the epoch) and its 16-byte GID, which zenoh's serializer
//!   writes as a sequence (a LEB128 length, here 16, then the bytes);
//! - nodes and publishers announce themselves for the ROS graph (`ros2 topic list`, RViz2's topic
//!   choices) with liveliness tokens `@ros2_lv/<domain>/<session id>/<node id>/<entity id>/<kind>/
//!   <enclave>/<namespace>/<node name>[/<topic>/<type>/<type hash>/<QoS>]`, names mangled with `/`
//!   written `%` and an empty name written `%`.
//!
//! The type hashes (REP 2016's `RIHS01`, a SHA-256 of the type description) are those of ROS 2 Jazzy's
//! message definitions; a test recomputes them with `rosbags`.

/// A ROS 2 message type SKiD publishes, with what its keys need.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ros2Type {
    Odometry,
    Path,
    PointCloud2,
    MarkerArray,
    TfMessage,
    String,
}

impl Ros2Type {
    pub const ALL: [Ros2Type; 6] = [
        Ros2Type::Odometry,
        Ros2Type::Path,
        Ros2Type::PointCloud2,
        Ros2Type::MarkerArray,
        Ros2Type::TfMessage,
        Ros2Type::String,
    ];

    /// The type's name, `pkg/msg/Type`.
    pub const fn name(self) -> &'static str {
        match self {
            Ros2Type::Odometry => "nav_msgs/msg/Odometry",
            Ros2Type::Path => "nav_msgs/msg/Path",
            Ros2Type::PointCloud2 => "sensor_msgs/msg/PointCloud2",
            Ros2Type::MarkerArray => "visualization_msgs/msg/MarkerArray",
            Ros2Type::TfMessage => "tf2_msgs/msg/TFMessage",
            Ros2Type::String => "std_msgs/msg/String",
        }
    }

    /// The RIHS01 hash of the type's Jazzy description.
    pub const fn hash(self) -> &'static str {
        match self {
            Ros2Type::Odometry => "RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0",
            Ros2Type::Path => "RIHS01_1957a5bb3cee5da65c4e52e52b65a93df227efce4c20f8458b36e73066ca334b",
            Ros2Type::PointCloud2 => {
                "RIHS01_9198cabf7da3796ae6fe19c4cb3bdd3525492988c70522628af5daa124bae2b5"
            }
            Ros2Type::MarkerArray => {
                "RIHS01_86cb8800b6fb05b5eff1abd7a56f62a5641d3ae9a1c29e78e67e704f1d067dcf"
            }
            Ros2Type::TfMessage => "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
            Ros2Type::String => "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
        }
    }

    /// The type written the DDS way, `pkg::msg::dds_::Type_`.
    pub fn dds_name(self) -> String {
        let mut parts = self.name().split('/');
        let (package, _, name) = (
            parts.next().unwrap_or_default(),
            parts.next(),
            parts.next().unwrap_or_default(),
        );
        format!("{package}::msg::dds_::{name}_")
    }
}

/// A name with every `/` written `%`; the empty name (and `/` alone) is `%`.
pub fn mangle(name: &str) -> String {
    if name.is_empty() || name == "/" {
        "%".to_owned()
    } else {
        name.replace('/', "%")
    }
}

/// The key a topic's data is put on.
pub fn data_key(domain_id: u32, topic: &str, kind: Ros2Type) -> String {
    format!(
        "{domain_id}/{}/{}/{}",
        topic.trim_start_matches('/'),
        kind.dds_name(),
        kind.hash()
    )
}

/// The node's liveliness token.
pub fn node_token(domain_id: u32, session_id: &str, node_id: u32, namespace: &str, node: &str) -> String {
    format!(
        "@ros2_lv/{domain_id}/{session_id}/{node_id}/{node_id}/NN/%/{}/{node}",
        mangle(namespace)
    )
}

/// A publisher's liveliness token, with best-effort, volatile, keep-last-10 QoS (`2::,10:,:,:,,`: a
/// component equal to rmw_zenoh's default is left empty, reliable being the default).
pub fn publisher_token(
    domain_id: u32,
    session_id: &str,
    (node_id, entity_id): (u32, u32),
    (namespace, node): (&str, &str),
    topic: &str,
    kind: Ros2Type,
) -> String {
    format!(
        "@ros2_lv/{domain_id}/{session_id}/{node_id}/{entity_id}/MP/%/{}/{node}/{}/{}/{}/2::,10:,:,:,,",
        mangle(namespace),
        mangle(topic),
        kind.dds_name(),
        kind.hash()
    )
}

/// The attachment of one message: sequence number, source timestamp and the publisher's GID.
pub fn attachment(sequence: i64, source_timestamp_nanos: i64, gid: &[u8; 16]) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(33);
    bytes.extend_from_slice(&sequence.to_le_bytes());
    bytes.extend_from_slice(&source_timestamp_nanos.to_le_bytes());
    // The GID as a sequence: its length as LEB128 (16 fits one byte), then the bytes.
    bytes.push(16);
    bytes.extend_from_slice(gid);
    bytes
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_and_tokens_follow_rmw_zenoh() {
        assert_eq!(
            data_key(0, "/robot0/odometry", Ros2Type::Odometry),
            format!(
                "0/robot0/odometry/nav_msgs::msg::dds_::Odometry_/{}",
                Ros2Type::Odometry.hash()
            )
        );
        assert_eq!(mangle("/robot1/path"), "%robot1%path");
        assert_eq!(mangle(""), "%");
        assert_eq!(
            node_token(0, "aac3", 0, "/robot1", "skid"),
            "@ros2_lv/0/aac3/0/0/NN/%/%robot1/skid"
        );
        let token = publisher_token(3, "aac3", (0, 4), ("/robot1", "skid"), "/tf", Ros2Type::TfMessage);
        assert!(token.starts_with(
            "@ros2_lv/3/aac3/0/4/MP/%/%robot1/skid/%tf/tf2_msgs::msg::dds_::TFMessage_/RIHS01_"
        ));
        assert!(token.ends_with("/2::,10:,:,:,,"));
        let bytes = attachment(7, 1_000, &[9; 16]);
        assert_eq!(bytes.len(), 33);
        assert_eq!(&bytes[..8], &7i64.to_le_bytes());
        assert_eq!(bytes[16], 16);
    }
}
