//! Parameters of the `zenoh` transport (`[transport.zenoh]`) and their translation into a zenoh
//! configuration: peer mode, explicit endpoints, no multicast or gossip scouting, and a receive limit.

use serde::{Deserialize, Serialize};
use skid_core::PluginError;

/// What a sender does when the network cannot keep up.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Congestion {
    /// Drop the message (a slow peer never stalls the robot; the protocol resends what matters).
    #[default]
    Drop,
    /// Wait until the message can be queued.
    Block,
}

/// Parameters of the `zenoh` transport.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct ZenohConfig {
    /// Endpoints this robot listens on, e.g. `tcp/0.0.0.0:7447`.
    pub listen: Vec<String>,
    /// Endpoints of peers to connect to, e.g. `tcp/192.168.1.12:7447`; retried until they answer.
    pub connect: Vec<String>,
    /// First key segment(s) of every key; robots of one fleet must share it.
    pub key_prefix: String,
    /// Largest message sent or accepted, in bytes (also zenoh's receive limit per message).
    pub max_message_bytes: usize,
    /// Received messages waiting for `poll`, in bytes; further messages are dropped and counted.
    pub max_queued_bytes: usize,
    pub congestion: Congestion,
    /// Multicast scouting on the local network (off: only the explicit endpoints are used).
    pub multicast_scouting: bool,
}

impl Default for ZenohConfig {
    fn default() -> Self {
        Self {
            listen: vec!["tcp/0.0.0.0:7447".into()],
            connect: Vec::new(),
            key_prefix: "skid".into(),
            max_message_bytes: 8 << 20,
            max_queued_bytes: 64 << 20,
            congestion: Congestion::Drop,
            multicast_scouting: false,
        }
    }
}

fn json_strings(values: &[String]) -> String {
    let quoted: Vec<String> = values
        .iter()
        .map(|v| format!("\"{}\"", v.replace('\\', "\\\\").replace('"', "\\\"")))
        .collect();
    format!("[{}]", quoted.join(","))
}

impl ZenohConfig {
    /// Checks the values that zenoh would otherwise only refuse later or not at all.
    pub fn validate(&self) -> Result<(), PluginError> {
        let bad = |message: String| Err(PluginError::failed("zenoh", message));
        if self.listen.is_empty() && self.connect.is_empty() {
            return bad(
                "neither `listen` nor `connect` endpoints are given: the robot could reach nobody".into(),
            );
        }
        let prefix_ok = !self.key_prefix.is_empty()
            && self.key_prefix.split('/').all(|chunk| {
                !chunk.is_empty() && chunk.chars().all(|c| !matches!(c, '*' | '$' | '?' | '#' | ' '))
            });
        if !prefix_ok {
            return bad(format!(
                "key_prefix {:?} must be non-empty '/'-separated chunks without wildcards",
                self.key_prefix
            ));
        }
        if self.max_message_bytes == 0 || self.max_queued_bytes < self.max_message_bytes {
            return bad("max_message_bytes must be positive and at most max_queued_bytes".into());
        }
        Ok(())
    }

    /// The zenoh configuration: peer mode, these endpoints, scouting off, the receive limit.
    pub fn to_zenoh(&self) -> Result<zenoh::Config, PluginError> {
        let mut config = zenoh::Config::default();
        let settings = [
            ("mode", "\"peer\"".to_owned()),
            ("listen/endpoints", json_strings(&self.listen)),
            ("connect/endpoints", json_strings(&self.connect)),
            ("scouting/multicast/enabled", self.multicast_scouting.to_string()),
            ("scouting/gossip/enabled", "false".to_owned()),
            // Slack for zenoh's own framing over the payload limit.
            (
                "transport/link/rx/max_message_size",
                (self.max_message_bytes + 4096).to_string(),
            ),
        ];
        for (key, value) in settings {
            config
                .insert_json5(key, &value)
                .map_err(|error| PluginError::failed("zenoh", format!("config {key} = {value}: {error}")))?;
        }
        Ok(config)
    }
}

impl skid_core::PluginParams for ZenohConfig {
    fn check(&self) -> Result<(), skid_core::ParamError> {
        self.validate().map_err(skid_core::ParamError::from_plugin_error)
    }
}
