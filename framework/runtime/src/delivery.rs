//! Moving messages between a robot's host and its transport: encoding and sending what the host
//! produced, and receiving, decoding and handling what arrived (with the replies it calls for). A send
//! that fails is logged, never fatal: a robot never stops because a peer cannot be reached.

use std::time::Duration;

use skid_config::ResolvedConfig;
use skid_core::slots::Destination;
use skid_protocol::{Incoming, Message};

use crate::error::RuntimeError;
use crate::host::RobotHost;

/// Encodes and sends messages from `robot` to their destinations. A send that fails (link down,
/// oversized) is logged: a robot never stops because a peer cannot be reached.
pub(crate) fn send_all(robot: &mut RobotHost, messages: Vec<Message>) {
    for message in messages {
        let destination = match message {
            Message::Loops(_) if robot.loops_to_fleet => Destination::AllPeers,
            _ => crate::messages::destination(robot.robot(), &message),
        };
        send_to(robot, destination, message);
    }
}

/// Encodes and sends one message from `robot` to `destination`; a failure is logged, never fatal.
pub(crate) fn send_to(robot: &mut RobotHost, destination: Destination, message: Message) {
    let robot_id = robot.robot();
    // A prior map is a silent peer: nothing is sent to it.
    if let Destination::Robot(to) = destination
        && crate::prior::is_prior_robot(to)
    {
        return;
    }
    let Some((transport, protocol)) = robot.transport_and_protocol() else {
        return;
    };
    match protocol.encode(&message) {
        Ok(bytes) => {
            if let Err(error) = transport.send(destination, &bytes) {
                tracing::warn!(robot = %robot_id, %error, "send failed");
            }
        }
        Err(error) => tracing::warn!(robot = %robot_id, %error, "message not encoded"),
    }
}

/// Receives and handles everything waiting for `robot`; returns how many messages it handled.
pub(crate) fn deliver_to(robot: &mut RobotHost, config: &ResolvedConfig) -> Result<usize, RuntimeError> {
    deliver_filtered(robot, config, |_| true)
}

/// [`deliver_to`], with `keep` seeing (and possibly editing) every new message before it is handled;
/// a message for which it returns false is dropped.
pub(crate) fn deliver_filtered(
    robot: &mut RobotHost,
    config: &ResolvedConfig,
    mut keep: impl FnMut(&mut skid_protocol::Received) -> bool,
) -> Result<usize, RuntimeError> {
    let Some((transport, _)) = robot.transport_and_protocol() else {
        return Ok(0);
    };
    let datagrams = match transport.poll(Duration::ZERO) {
        Ok(datagrams) => datagrams,
        Err(error) => {
            tracing::warn!(robot = %robot.robot(), %error, "poll failed");
            return Ok(0);
        }
    };
    let count = datagrams.len();
    let mut outbox = Vec::new();
    let mut replies = Vec::new();
    for datagram in datagrams {
        match robot.protocol_mut().receive(datagram.from, &datagram.payload) {
            Ok(Incoming::Message(mut received)) => {
                if !keep(&mut received) {
                    continue;
                }
                robot.handle_message(config, datagram.from, received.message, &mut replies, &mut outbox)?;
            }
            Ok(Incoming::Dropped { .. }) => {}
            Err(error) => {
                let robot_id = robot.robot();
                robot
                    .peer_faults_mut()
                    .note_malformed(robot_id, datagram.from, error.class(), &error);
            }
        }
    }
    send_all(robot, outbox);
    for (to, message) in replies {
        send_to(robot, Destination::Robot(to), message);
    }
    Ok(count)
}
