//! The access-control list a mutual-TLS fleet runs with (zenoh's `access_control`, checked by every peer
//! on what it receives and what it forwards): a robot is the holder of the certificate whose common name
//! is `robot-<id>`, and it may
//! - publish messages only under its own id (`<prefix>/msg/<to>/<id>`) and hold only its own liveliness
//!   token (`<prefix>/alive/<id>`);
//! - subscribe only to messages for itself or for all (`<prefix>/msg/<id>/*`, `<prefix>/msg/all/*`);
//! - watch the fleet's liveliness tokens.
//!
//! Everything else is denied, so a peer with no certificate of the fleet never gets a link (TLS refuses
//! it first), one whose certificate is not a fleet robot's gets nothing through, and one that claims
//! another robot's id in its keys has those messages dropped on arrival and counted (see
//! [`crate::refusals`]).

/// The common name of robot `id`'s certificate.
pub fn common_name(id: u32) -> String {
    format!("robot-{id}")
}

/// One rule as zenoh's JSON5 configuration spells it.
fn rule(id: &str, messages: &[&str], flows: &[&str], key_exprs: &[String]) -> String {
    let quoted = |items: &[&str]| {
        items
            .iter()
            .map(|item| format!("\"{item}\""))
            .collect::<Vec<_>>()
            .join(",")
    };
    let keys: Vec<&str> = key_exprs.iter().map(String::as_str).collect();
    format!(
        "{{\"id\":\"{id}\",\"messages\":[{}],\"flows\":[{}],\"permission\":\"allow\",\"key_exprs\":[{}]}}",
        quoted(messages),
        quoted(flows),
        quoted(&keys)
    )
}

/// The `access_control` settings for robots `0..fleet_size` under `prefix`.
pub fn acl_settings(prefix: &str, fleet_size: u32) -> Vec<(&'static str, String)> {
    let mut rules = Vec::new();
    let mut subjects = Vec::new();
    let mut policies = Vec::new();
    for robot in 0..fleet_size {
        let own = |what: &str| format!("{prefix}/{what}");
        // What the robot may send us (ingress) and what we may pass on to it (egress).
        rules.push(rule(
            &format!("from_{robot}"),
            &["put"],
            &["ingress"],
            &[own(&format!("msg/*/{robot}"))],
        ));
        rules.push(rule(
            &format!("token_{robot}"),
            &["liveliness_token"],
            &["ingress"],
            &[own(&format!("alive/{robot}"))],
        ));
        rules.push(rule(
            &format!("listens_{robot}"),
            &["declare_subscriber"],
            &["ingress"],
            &[own(&format!("msg/{robot}/*")), own("msg/all/*")],
        ));
        rules.push(rule(
            &format!("to_{robot}"),
            &["put"],
            &["egress"],
            &[own(&format!("msg/{robot}/*")), own("msg/all/*")],
        ));
        subjects.push(format!(
            "{{\"id\":\"robot_{robot}\",\"cert_common_names\":[\"{}\"]}}",
            common_name(robot)
        ));
        policies.push(format!(
            "{{\"rules\":[\"from_{robot}\",\"token_{robot}\",\"listens_{robot}\",\"to_{robot}\",\"fleet_both\",\"fleet_out\"],\"subjects\":[\"robot_{robot}\"]}}"
        ));
    }
    // Presence and subscriptions any fleet robot exchanges in both directions.
    let alive = format!("{prefix}/alive/*");
    rules.push(rule(
        "fleet_both",
        &["declare_liveliness_subscriber", "liveliness_query", "reply"],
        &["ingress", "egress"],
        std::slice::from_ref(&alive),
    ));
    rules.push(rule(
        "fleet_out",
        &["liveliness_token", "declare_subscriber"],
        &["egress"],
        &[alive, format!("{prefix}/msg/*/*")],
    ));
    vec![
        ("access_control/enabled", "true".to_owned()),
        ("access_control/default_permission", "\"deny\"".to_owned()),
        ("access_control/rules", format!("[{}]", rules.join(","))),
        ("access_control/subjects", format!("[{}]", subjects.join(","))),
        ("access_control/policies", format!("[{}]", policies.join(","))),
    ]
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn the_list_is_accepted_by_zenoh() {
        let mut config = zenoh::Config::default();
        for (key, value) in acl_settings("skid/test", 3) {
            config.insert_json5(key, &value).unwrap();
        }
        let rendered = format!("{config:?}");
        assert!(rendered.contains("robot-2"));
    }
}
