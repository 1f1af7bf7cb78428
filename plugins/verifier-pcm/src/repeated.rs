//! Places a robot's own map holds twice. In a grid of identical blocks every junction looks like every
//! other, and a loop between two of them says only "a junction": a consistent set of such loops may put
//! a robot one block off, and nothing the places show refutes it until the robots' routes run on. A
//! robot knows its own map by its own odometry: a keyframe whose descriptor looks like one of the same
//! robot's keyframes at least `repeat_beyond_m` away (by the odometry between them) shows a place that
//! repeats, and a loop that joins such a keyframe on either robot is **repeated**.
//!
//! A frame hypothesis most of whose loops are repeated is **self-aliased**: its loops are the evidence
//! every look-alike copy of the place would give too. It is granted only with evidence of another kind
//! ([`crate::earned`]): a loop whose scans show each robot's body where the loop puts it at that moment
//! (a sighting, [`crate::peer_seen`]), the frame through a third robot agreeing with every loop, the
//! keyframe pairs its frame puts in one place beyond its loops looking alike at least
//! `aliased_alike_fraction` of the time, or loops that span `aliased_min_spread_m` on each robot: more
//! than one look-alike spot (a junction, clear of the clutter that tells streets apart), where every
//! loop passed the cloud checks of its own. This is the distinctiveness test of place recognition (a
//! match counts only where the place is unlike the rest of the map, as in Lowe's ratio test), applied
//! to a whole frame hypothesis with the robots' own maps as the reference of what repeats; a descriptor
//! distance ratio alone does not separate them: on the simulator's planetary terrain the true loops'
//! partners are no more alike than their own maps' look-alikes elsewhere, as on the grid of blocks.
//!
//! The rule is off by default (`repeat_beyond_m = 0`): on bland terrain most keyframes look like another
//! of their robot's keyframes at the descriptor's candidate distance, and small true sets between many
//! robots then wait for evidence that comes late or never. The aliasing benchmark turns it on.
//!
//! The host answers whether two keyframes look alike through [`GraphView::looks_alike`]; without it (the
//! replay of a recorded problem, a descriptor that cannot compare stored keyframes) nothing is repeated
//! and the rule stands aside.

use std::collections::BTreeMap;

use skid_core::slots::GraphView;
use skid_core::{KeyframeId, RobotId};

use crate::consistency::PcmLoop;

/// What each keyframe asked about so far was found to be, and against which of its robot's keyframes.
#[derive(Default)]
pub(crate) struct Repeats {
    known: BTreeMap<KeyframeId, Repeat>,
}

#[derive(Clone, Copy)]
struct Repeat {
    found: bool,
    /// The robot's keyframes with an index below this were compared with it.
    checked_below: u32,
}

impl Repeats {
    /// How many of `members` join a repeated keyframe on either robot. `beyond_m` of 0 counts none.
    pub(crate) fn count(
        &mut self,
        beyond_m: f64,
        loops: &[PcmLoop],
        members: &[usize],
        graph: &dyn GraphView,
    ) -> usize {
        if beyond_m <= 0.0 || members.is_empty() {
            return 0;
        }
        let mut by_robot: BTreeMap<RobotId, Vec<u32>> = BTreeMap::new();
        for id in graph.keyframes() {
            by_robot.entry(id.robot).or_default().push(id.index);
        }
        for indices in by_robot.values_mut() {
            indices.sort_unstable();
        }
        members
            .iter()
            .filter(|&&k| {
                let member = &loops[k];
                [member.target, member.source].into_iter().any(|id| {
                    let own = by_robot.get(&id.robot).map_or(&[][..], Vec::as_slice);
                    self.repeated(beyond_m, id, own, graph)
                })
            })
            .count()
    }

    /// Whether `id` looks like one of its robot's keyframes `own` (sorted indices) at least `beyond_m`
    /// away; once found, it stays so.
    fn repeated(&mut self, beyond_m: f64, id: KeyframeId, own: &[u32], graph: &dyn GraphView) -> bool {
        let entry = self.known.entry(id).or_insert(Repeat {
            found: false,
            checked_below: 0,
        });
        if entry.found {
            return true;
        }
        let start = own.partition_point(|&index| index < entry.checked_below);
        entry.found = own[start..].iter().any(|&index| {
            let other = KeyframeId {
                robot: id.robot,
                index,
            };
            index != id.index
                && graph
                    .odometry_between(id, other)
                    .is_some_and(|relative| relative.target_from_source.translation.vector.norm() >= beyond_m)
                && graph.looks_alike(id, other) == Some(true)
        });
        if let Some(&last) = own.last() {
            entry.checked_below = entry.checked_below.max(last + 1);
        }
        entry.found
    }
}

#[cfg(test)]
mod tests;
