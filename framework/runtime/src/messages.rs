//! The protocol messages a robot sends its peers (descriptors, odometry chain steps, cloud requests,
//! loops) built from the host's data, and where each goes.

use std::collections::BTreeMap;

use skid_core::slots::{DescriptorBuf, Destination, LoopClosure};
use skid_core::{Information, Keyframe, KeyframeId, Pose, RobotId};
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

/// The odometry step into keyframe `index` (from `index - 1`; none for the first keyframe), with the
/// pose of the chain's first keyframe so a peer can place the chain before any loop.
pub fn chain_message(
    robot: RobotId,
    index: u32,
    world_from_keyframe: &Pose,
    step: Pose,
    covariance: Information,
) -> Message {
    let (from_index, edges) = match index {
        0 => (0, Vec::new()),
        _ => (
            index - 1,
            vec![ChainEdge {
                target_from_source: PoseMsg::from_pose(&step),
                information: InformationMsg::from_information(&information_from_covariance(&covariance)),
            }],
        ),
    };
    Message::OdomChain(OdomChain {
        robot,
        from_index,
        to_index: index,
        edges,
        world_from_first: PoseMsg::from_pose(&(world_from_keyframe * step.inverse())),
    })
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
            .map_or(Destination::AllPeers, |(target, source)| {
                Destination::Robot(if target.robot == robot {
                    source.robot
                } else {
                    target.robot
                })
            }),
        _ => Destination::AllPeers,
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
