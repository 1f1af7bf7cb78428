//! The protocol messages a robot sends its peers (descriptors, odometry chain steps, cloud requests,
//! loops) built from the host's data, and where each goes.

use std::collections::BTreeMap;

use skid_core::slots::{DescriptorBuf, Destination, LoopClosure};
use skid_core::{Keyframe, KeyframeId, RobotId};
use skid_geometry::OdometryChains;
use skid_protocol::{
    ChainEdge, CloudRequest, DescriptorBatch, DescriptorEncoding, DescriptorEntry, DescriptorValues,
    HeldKeyframe, InformationMsg, LoopMsg, Loops, Message, OdomChain, PoseMsg,
};

use crate::settings::information_from_covariance;

/// A keyframe's descriptor, for every peer, with the newest keyframe of each peer the sender's index
/// held when it looked for the keyframe's candidates.
pub fn descriptor_message(
    robot: RobotId,
    keyframe: &Keyframe,
    descriptor: &DescriptorBuf,
    held: &BTreeMap<RobotId, u32>,
) -> Message {
    let values = DescriptorValues::encode(&descriptor.values, DescriptorEncoding::F32)
        .unwrap_or(DescriptorValues::F32(descriptor.values.clone()));
    Message::Descriptors(DescriptorBatch {
        robot,
        kind: descriptor.kind.clone(),
        entries: vec![DescriptorEntry {
            keyframe_index: keyframe.id.index,
            stamp_nanos: keyframe.stamp_nanos,
            values,
            newest_held: held
                .iter()
                .map(|(&robot, &keyframe_index)| HeldKeyframe {
                    robot,
                    keyframe_index,
                })
                .collect(),
        }],
    })
}

/// Odometry steps each chain message carries: the step into its keyframe and the ones before it, so a
/// peer that lost a message (or two) in a row still learns every step from the next one.
pub const CHAIN_STEPS_PER_MESSAGE: u32 = 3;

/// The odometry steps into keyframe `index` from up to [`CHAIN_STEPS_PER_MESSAGE`] keyframes before it
/// (none for the first keyframe), with the pose of the chain's first keyframe so a peer can place the
/// chain before any loop; `None` when `chains` lacks one of them.
pub fn chain_message(chains: &OdometryChains, robot: RobotId, index: u32) -> Option<Message> {
    let from_index = index.saturating_sub(CHAIN_STEPS_PER_MESSAGE);
    let of = |index| KeyframeId { robot, index };
    let world_from_first = chains.pose(of(from_index))?;
    let mut previous = world_from_first;
    let mut edges = Vec::new();
    for step_index in from_index + 1..=index {
        let pose = chains.pose(of(step_index))?;
        let covariance = chains.step_covariance(of(step_index))?;
        edges.push(ChainEdge {
            target_from_source: PoseMsg::from_pose(&(previous.inverse() * pose)),
            information: InformationMsg::from_information(&information_from_covariance(&covariance)),
        });
        previous = pose;
    }
    Some(Message::OdomChain(OdomChain {
        robot,
        from_index,
        to_index: index,
        edges,
        world_from_first: PoseMsg::from_pose(&world_from_first),
    }))
}

/// Where a message goes: broadcasts to every peer, requests and loops to the robot concerned.
pub fn destination(robot: RobotId, message: &Message) -> Destination {
    match message {
        Message::CloudRequest(request) => request
            .keyframes
            .first()
            .map_or(Destination::AllPeers, |id| Destination::Robot(id.robot)),
        Message::Loops(loops) => loops
            .accepted
            .first()
            .map(|l| (l.target, l.source))
            .or_else(|| loops.retracted.first().copied())
            .map_or(Destination::AllPeers, |pair| {
                Destination::Robot(other_robot(robot, pair))
            }),
        _ => Destination::AllPeers,
    }
}

/// The robot at the other end of the loop between `target` and `source`, seen from `robot`.
pub fn other_robot(robot: RobotId, (target, source): (KeyframeId, KeyframeId)) -> RobotId {
    if target.robot == robot {
        source.robot
    } else {
        target.robot
    }
}

/// A request for one peer keyframe's cloud.
pub fn cloud_request(requester: RobotId, keyframe: KeyframeId) -> Message {
    Message::CloudRequest(CloudRequest {
        requester,
        keyframes: vec![keyframe],
    })
}

/// Accepted and retracted loops for the peer involved.
pub fn loops_message(
    robot: RobotId,
    accepted: &[LoopClosure],
    retracted: &[(KeyframeId, KeyframeId)],
) -> Message {
    Message::Loops(Loops {
        robot,
        accepted: accepted
            .iter()
            .map(|closure| LoopMsg {
                target: closure.target,
                source: closure.source,
                target_from_source: PoseMsg::from_pose(&closure.target_from_source),
                information: InformationMsg::from_information(&closure.information),
                // The verifier keeps the fitness to itself; 0 marks it as not reported.
                fitness_m2: 0.0,
            })
            .collect(),
        retracted: retracted.to_vec(),
    })
}
