//! The configuration of a zenoh peer session on explicit endpoints: peer mode, where it listens and
//! whom it connects to, no multicast scouting. The inter-robot transport, the live ROS 2 source and the
//! live ROS 2 output all open such a session; each adds its own settings after these.

/// A zenoh configuration for a peer listening on `listen` and connecting to `connect` (zenoh endpoint
/// strings, `tcp/127.0.0.1:7447`), with `extra` JSON5 settings applied after the peer ones; the error
/// names the setting zenoh refused.
pub fn peer_config(
    listen: &[String],
    connect: &[String],
    extra: &[(&str, String)],
) -> Result<zenoh::Config, String> {
    let mut config = zenoh::Config::default();
    let base = [
        ("mode", "\"peer\"".to_owned()),
        ("listen/endpoints", json_strings(listen)),
        ("connect/endpoints", json_strings(connect)),
        ("scouting/multicast/enabled", "false".to_owned()),
    ];
    for (key, value) in base.iter().chain(extra) {
        config
            .insert_json5(key, value)
            .map_err(|error| format!("zenoh {key} = {value}: {error}"))?;
    }
    Ok(config)
}

/// A JSON string literal (quotes and backslashes escaped).
pub(crate) fn json_string(value: &str) -> String {
    let escaped = value.replace('\\', "\\\\").replace('"', "\\\"");
    format!("\"{escaped}\"")
}

/// A JSON array of string literals.
pub(crate) fn json_strings(values: &[String]) -> String {
    let quoted: Vec<String> = values.iter().map(|v| json_string(v)).collect();
    format!("[{}]", quoted.join(","))
}
