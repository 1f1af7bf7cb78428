//! Parameters of the `zenoh` transport (`[transport.zenoh]`) and their translation into a zenoh
//! configuration: peer mode, explicit endpoints, no multicast or gossip scouting, a receive limit, and
//! by default mutual TLS with an access-control list that binds each robot's certificate to its keys
//! (see [`crate::access`]).

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use skid_core::PluginError;

use crate::peer::{json_string, peer_config};

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

/// How the robots' links are protected.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Security {
    /// TLS with both ends authenticated by the fleet's CA (endpoints `tls/host:port`), and zenoh's
    /// access control: a robot's certificate may publish only under its own robot id.
    #[default]
    MutualTls,
    /// Plain TCP (endpoints `tcp/host:port`): no encryption and no authentication, any device on the
    /// network can join. Only for a trusted network; the transport warns when it opens.
    PlainTcp,
}

/// The fleet's CA and this robot's certificate and key, PEM files (`skid fleet certs` makes a set).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct TlsFiles {
    /// The fleet CA's certificate: peers must present a certificate it signed.
    pub ca_certificate: PathBuf,
    /// This robot's certificate (common name `robot-<id>`), signed by the fleet CA.
    pub certificate: PathBuf,
    /// This robot's private key.
    pub private_key: PathBuf,
}

/// Parameters of the `zenoh` transport.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct ZenohConfig {
    /// Endpoints this robot listens on, e.g. `tls/0.0.0.0:7447` (`tcp/…` with `plain_tcp`).
    pub listen: Vec<String>,
    /// Endpoints of peers to connect to, e.g. `tls/192.168.1.12:7447`; retried until they answer.
    pub connect: Vec<String>,
    /// First key segment(s) of every key; robots of one fleet must share it.
    pub key_prefix: String,
    /// Largest message sent or accepted, in bytes (also zenoh's receive limit per message).
    pub max_message_bytes: usize,
    /// Received messages waiting for `poll`, in bytes, per sending peer; further messages from that peer
    /// are dropped and counted (`queue_full`).
    pub max_queued_bytes: usize,
    pub congestion: Congestion,
    /// Multicast scouting on the local network (off: only the explicit endpoints are used).
    pub multicast_scouting: bool,
    /// `mutual_tls` (the default) or `plain_tcp`, which must be asked for by name.
    pub security: Security,
    /// Certificate files for `mutual_tls`.
    pub tls: TlsFiles,
}

impl Default for ZenohConfig {
    fn default() -> Self {
        Self {
            listen: vec!["tls/0.0.0.0:7447".into()],
            connect: Vec::new(),
            key_prefix: "skid".into(),
            max_message_bytes: 8 << 20,
            max_queued_bytes: 64 << 20,
            congestion: Congestion::Drop,
            multicast_scouting: false,
            security: Security::MutualTls,
            tls: TlsFiles::default(),
        }
    }
}

impl ZenohConfig {
    /// Checks everything before opening: the parameters ([`Self::validate_params`]) and that the
    /// certificate files `mutual_tls` needs are given and exist.
    pub fn validate(&self) -> Result<(), PluginError> {
        self.validate_params()?;
        self.validate_files()
    }

    /// Checks the values that zenoh would otherwise only refuse later or not at all (what a config check
    /// can judge; whether the certificate files exist is checked when the transport opens).
    pub fn validate_params(&self) -> Result<(), PluginError> {
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
        self.validate_endpoints()
    }

    /// Endpoints match the security mode.
    fn validate_endpoints(&self) -> Result<(), PluginError> {
        let bad = |message: String| Err(PluginError::failed("zenoh", message));
        let scheme = match self.security {
            Security::MutualTls => "tls/",
            Security::PlainTcp => "tcp/",
        };
        let endpoints = self.listen.iter().map(|e| ("listen", e));
        for (key, endpoint) in endpoints.chain(self.connect.iter().map(|e| ("connect", e))) {
            if !endpoint.starts_with(scheme) {
                return bad(format!(
                    "{key} endpoint {endpoint:?} must start with {scheme:?} when security = {:?}{}",
                    self.security.name(),
                    if self.security == Security::MutualTls {
                        " (plain TCP needs security = \"plain_tcp\", said explicitly)"
                    } else {
                        ""
                    }
                ));
            }
        }
        Ok(())
    }

    /// With `mutual_tls`, the three certificate files are given and exist.
    fn validate_files(&self) -> Result<(), PluginError> {
        let bad = |message: String| Err(PluginError::failed("zenoh", message));
        if self.security == Security::MutualTls {
            let files = [
                ("tls.ca_certificate", &self.tls.ca_certificate),
                ("tls.certificate", &self.tls.certificate),
                ("tls.private_key", &self.tls.private_key),
            ];
            for (key, path) in files {
                if path.as_os_str().is_empty() {
                    return bad(format!(
                        "{key} is not set: security = \"mutual_tls\" needs the fleet CA, this robot's \
                         certificate and its key (`skid fleet certs` makes a set for testing), or \
                         security = \"plain_tcp\" on a trusted network"
                    ));
                }
                if !path.is_file() {
                    return bad(format!("{key} = {}: no such file", path.display()));
                }
            }
        }
        Ok(())
    }

    /// The zenoh configuration: peer mode, these endpoints, scouting off, the receive limit; with
    /// mutual TLS also the certificates and the access-control list of a fleet of `fleet_size` robots.
    pub fn to_zenoh(&self, fleet_size: u32) -> Result<zenoh::Config, PluginError> {
        let mut settings = vec![
            ("scouting/multicast/enabled", self.multicast_scouting.to_string()),
            ("scouting/gossip/enabled", "false".to_owned()),
            // Slack for zenoh's own framing over the payload limit.
            (
                "transport/link/rx/max_message_size",
                (self.max_message_bytes + 4096).to_string(),
            ),
        ];
        if self.security == Security::MutualTls {
            settings.extend(self.tls_settings());
            settings.extend(crate::access::acl_settings(&self.key_prefix, fleet_size));
        }
        peer_config(&self.listen, &self.connect, &settings)
            .map_err(|error| PluginError::failed("zenoh", error))
    }
}

impl Security {
    /// The name the config file uses.
    pub fn name(self) -> &'static str {
        match self {
            Self::MutualTls => "mutual_tls",
            Self::PlainTcp => "plain_tcp",
        }
    }
}

impl ZenohConfig {
    /// The TLS link settings: the same certificate for both directions, the peer's certificate required
    /// and checked against the fleet CA. Names are not checked against host names: robots are reached by
    /// address, and what identifies a robot is its certificate's common name (checked by the ACL).
    fn tls_settings(&self) -> Vec<(&'static str, String)> {
        let path = |p: &PathBuf| json_string(&p.display().to_string());
        vec![
            (
                "transport/link/tls/root_ca_certificate",
                path(&self.tls.ca_certificate),
            ),
            (
                "transport/link/tls/listen_certificate",
                path(&self.tls.certificate),
            ),
            (
                "transport/link/tls/listen_private_key",
                path(&self.tls.private_key),
            ),
            (
                "transport/link/tls/connect_certificate",
                path(&self.tls.certificate),
            ),
            (
                "transport/link/tls/connect_private_key",
                path(&self.tls.private_key),
            ),
            ("transport/link/tls/enable_mtls", "true".to_owned()),
            ("transport/link/tls/verify_name_on_connect", "false".to_owned()),
            // The admin space answers this robot's own metrics queries (refusal counts); the ACL's
            // default deny keeps peers out of it.
            ("adminspace/enabled", "true".to_owned()),
        ]
    }
}

impl skid_core::PluginParams for ZenohConfig {
    fn check(&self) -> Result<(), skid_core::ParamError> {
        self.validate_params()
            .map_err(skid_core::ParamError::from_plugin_error)
    }

    fn check_files(&self) -> Result<(), skid_core::ParamError> {
        self.validate_files()
            .map_err(skid_core::ParamError::from_plugin_error)
    }
}
