//! When an inter-robot merge is earned. PCM's consistent set between two robots is a hypothesis about
//! where one robot's frame sits in the other's; in a self-similar place several hypotheses are each
//! supported by loops that agree with one another, and pairwise consistency cannot tell a wrong one from
//! the right one. The set is granted (its loops accepted) only when
//! - its frame is not seen empty: fewer than `min_unseen_loops` of the loops the peer-visibility check
//!   refused ([`crate::peer_seen`]: a scan of that moment shows the place empty where the loop puts the
//!   other robot) are consistent with most of its loops. Such a loop implies the set's frame, so the
//!   frame puts the robot where the scans show nobody. Two robots starting on two identical junctions
//!   of a grid see a turned copy of each other's start: the loops between their first keyframes put them
//!   side by side and are refused, while the loops a few seconds on put them 10 m apart, where a
//!   keyframe's thinned cloud holds too few rays towards the other's body to judge them; all imply one
//!   frame, which the first loops' rays refute. A set refuted so is refuted for good, as a set whose
//!   predictions fail is, and the loops left are judged in its place;
//! - its loops are spread over space: on each robot, the keyframes they join span at least
//!   `min_spread_m` (not all on one spot), and
//! - it clearly dominates: it holds at least `dominance_ratio` times as many loops as the strongest
//!   rival, the consistent core of the loops that disagree with most of it (a competing frame);
//! - it keeps the robots apart: a set whose loops put the two robots on top of each other, at least two
//!   loops joining keyframes recorded within `together_within_s` of each other and measured within
//!   `together_within_m`, claims two vehicles stood in one place at one time, which they cannot. Two
//!   robots approaching look-alike places in step (a grid's junction along perpendicular streets at the
//!   same distance and speed) see a turned copy of each other's street at every moment, and their loops
//!   agree on exactly such a frame;
//! - its predictions hold: the other keyframe pairs its frame puts in one place, beyond its loops, look
//!   alike to the descriptor as well ([`crate::predicted`]);
//! - it is corroborated where the places repeat: a set most of whose loops join keyframes that look like
//!   other places of their own robot's map (a grid's junctions, [`crate::repeated`]) needs evidence the
//!   look-alike copies cannot give: `min_sightings` loops whose scans show each robot's body where they
//!   put it, every loop agreeing with the frame through a third robot, its predictions holding at
//!   `aliased_alike_fraction`, or loops spanning `aliased_min_spread_m` on each robot;
//! - it closes the cycle: where a third robot has merged with both robots, the frame through it
//!   ([`GraphView::frames_through_others`]) agrees with most of the set's loops, at each loop's place,
//!   within `cycle_tolerance_m` and `cycle_tolerance_deg`, plus `cycle_drift_fraction` of the route
//!   from the loop's keyframes to the robots' nearest inter-robot ties ([`crate::ties`]): the frame is
//!   rigid, the odometry away from where it was fixed is not. Aliasing that fools one pair of robots
//!   rarely fools two pairs into the same wrong frame.
//!
//! A granted set that stops dominating (a rival grows) is withdrawn, and its loops are retracted; when
//! the rival later dominates in turn, it is granted and the merge is redone in its frame. This is the
//! hypothesis bookkeeping the SKiD issue on self-similar places asks for, on top of PCM (Mangelson et
//! al., ICRA 2018).

use skid_core::slots::GraphView;
use skid_core::{KeyframeId, RobotId};

use std::collections::BTreeSet;

use crate::clique::{Graph, induced};
use crate::consistency::PcmLoop;
use crate::dense::consistent_core;
use crate::predicted::{Along, OverlapRule, Predicted, placements, predicted_overlaps};
use crate::repeated::Repeats;
use crate::ties::Ties;

/// What decides a grant.
#[derive(Clone, Copy, Debug)]
pub(crate) struct GrantRule {
    pub min_spread_m: f64,
    pub dominance_ratio: f64,
    pub cycle_tolerance_m: f64,
    pub cycle_tolerance_rad: f64,
    pub cycle_drift_fraction: f64,
    pub together_within_s: f64,
    pub together_within_m: f64,
    /// The peeling fraction for the rival's core (PCM's own `min_consistent_fraction`).
    pub core_fraction: f64,
    pub overlaps: OverlapRule,
    /// A keyframe that looks like one of its robot's keyframes this far away repeats
    /// ([`crate::repeated`]); 0 turns the corroboration rule off.
    pub repeat_beyond_m: f64,
    pub aliased_min_spread_m: f64,
    pub min_sightings: usize,
    pub aliased_alike_fraction: f64,
    /// Loops refused as unseen that refute a hypothesis they agree with; 0 turns the rule off.
    pub min_unseen_loops: usize,
}

/// Why a hypothesis is not granted (yet), or `None` when it is.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Withheld {
    /// The loops' keyframes on one robot span less than the rule asks.
    Clustered { spread_m: f64 },
    /// A rival hypothesis holds too many loops.
    Contested { rival: usize },
    /// The loops put both robots in one place at one time.
    Together { loops: usize },
    /// Few of the keyframe pairs its frame puts in one place, beyond its loops, look alike.
    Unconfirmed { pairs: usize, alike: usize },
    /// Most of its loops join places that repeat in a robot's own map, and nothing else vouches for it.
    Uncorroborated { repeated: usize, loops: usize },
    /// Loops the scans refuted (the other robot absent where they put it) agree with most of its loops.
    Unseen { loops: usize },
    /// The frame through a third robot disagrees with most of the loops.
    Contradicted { via: RobotId, off_m: f64, off_deg: f64 },
}

impl std::fmt::Display for Withheld {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Clustered { spread_m } => {
                write!(f, "its loops' keyframes span only {spread_m:.1} m on one robot")
            }
            Self::Together { loops } => write!(
                f,
                "{loops} of its loops put both robots in one place at one time, which two vehicles cannot be"
            ),
            Self::Unconfirmed { pairs, alike } => write!(
                f,
                "of {pairs} keyframe pairs its frame puts in one place beyond its loops, only {alike} look alike"
            ),
            Self::Uncorroborated { repeated, loops } => write!(
                f,
                "{repeated} of its {loops} loops join places its robots' own maps hold elsewhere too, and no sighting, wider span, third robot or prediction vouches for it"
            ),
            Self::Unseen { loops } => write!(
                f,
                "{loops} loops whose scans show nobody where they put the other robot agree with most of its loops"
            ),
            Self::Contested { rival } => write!(f, "a rival frame hypothesis is supported by {rival} loops"),
            Self::Contradicted { via, off_m, off_deg } => write!(
                f,
                "the frame through {via} disagrees by {off_m:.1} m and {off_deg:.1}° (median over the loops)"
            ),
        }
    }
}

/// A loop the peer-visibility check refused, and the indices of its group's loops it is consistent
/// with (pairwise, as PCM tests two loops).
pub(crate) struct Unseen {
    pub pcm_loop: PcmLoop,
    pub consistent_with: BTreeSet<usize>,
}

/// The group's state a judgement reads: its consistency graph, the loops of refuted hypotheses (which
/// contest nothing), what is known of its keyframes' repeats, and the loops the scans refuted.
pub(crate) struct Judged<'a> {
    pub consistency: &'a Graph,
    pub refuted: &'a BTreeSet<usize>,
    pub repeats: &'a mut Repeats,
    pub unseen: &'a [Unseen],
}

/// Judges the hypothesis `members` (indices into `loops`, vertices of the group's consistency graph).
pub(crate) fn judge(
    rule: &GrantRule,
    loops: &[PcmLoop],
    members: &[usize],
    group: Judged<'_>,
    graph: &dyn GraphView,
) -> Option<Withheld> {
    let Judged {
        consistency,
        refuted,
        repeats,
        unseen,
    } = group;
    let unseen = agreeing_unseen(unseen, members);
    if rule.min_unseen_loops > 0 && unseen >= rule.min_unseen_loops {
        return Some(Withheld::Unseen { loops: unseen });
    }
    let targets = members.iter().map(|&k| loops[k].target);
    let sources = members.iter().map(|&k| loops[k].source);
    let spread_m =
        spread_m(targets, graph, rule.min_spread_m).min(spread_m(sources, graph, rule.min_spread_m));
    if spread_m < rule.min_spread_m {
        return Some(Withheld::Clustered { spread_m });
    }
    let together = together(rule, loops, members, graph);
    if together >= 2 {
        return Some(Withheld::Together { loops: together });
    }
    let rival = rival_size(consistency, members, refuted, rule.core_fraction);
    if rival > 0 && (members.len() as f64) < rule.dominance_ratio * rival as f64 {
        return Some(Withheld::Contested { rival });
    }
    let predicted = predicted_overlaps(&rule.overlaps, loops, members, graph);
    if rule.overlaps.refutes(predicted) {
        return Some(Withheld::Unconfirmed {
            pairs: predicted.pairs,
            alike: predicted.alike,
        });
    }
    contradiction(rule, loops, members, graph)
        .or_else(|| uncorroborated(rule, loops, members, predicted, repeats, graph))
}

/// How many loops the scans refuted are each consistent with more than half of `members`: each implies
/// (nearly) the members' frame, and so does the robot's absence where it puts the robot.
fn agreeing_unseen(unseen: &[Unseen], members: &[usize]) -> usize {
    if members.is_empty() {
        return 0;
    }
    unseen
        .iter()
        .filter(|unseen| {
            let agreeing = members
                .iter()
                .filter(|member| unseen.consistent_with.contains(member))
                .count();
            2 * agreeing > members.len()
        })
        .count()
}

/// [`Withheld::Uncorroborated`] when most members are repeated ([`crate::repeated`]) and fewer than
/// `min_sightings` of them were sighted, they span less than `aliased_min_spread_m` on a robot, the
/// frame through a third robot does not vouch for every one, and the predictions do not hold at
/// `aliased_alike_fraction`.
fn uncorroborated(
    rule: &GrantRule,
    loops: &[PcmLoop],
    members: &[usize],
    predicted: Predicted,
    repeats: &mut Repeats,
    graph: &dyn GraphView,
) -> Option<Withheld> {
    if rule.repeat_beyond_m <= 0.0 {
        return None;
    }
    let sightings = members.iter().filter(|&&k| loops[k].sighted).count();
    if sightings >= rule.min_sightings.max(1) {
        return None;
    }
    let confirmed = predicted.pairs >= rule.overlaps.min_pairs.max(1)
        && predicted.alike as f64 >= rule.aliased_alike_fraction * predicted.pairs as f64;
    if confirmed {
        return None;
    }
    let enough_m = rule.aliased_min_spread_m;
    let targets = members.iter().map(|&k| loops[k].target);
    let sources = members.iter().map(|&k| loops[k].source);
    if enough_m > 0.0
        && spread_m(targets, graph, enough_m).min(spread_m(sources, graph, enough_m)) >= enough_m
    {
        return None;
    }
    let repeated = repeats.count(rule.repeat_beyond_m, loops, members, graph);
    if 2 * repeated <= members.len() || agrees_with_cycle(rule, loops, members, graph) {
        return None;
    }
    Some(Withheld::Uncorroborated {
        repeated,
        loops: members.len(),
    })
}

/// Where each member puts robot b against where each frame through a third robot puts it: per third
/// robot, at every member's place, the (metres, radians) between the two and the drift the route from
/// the member's keyframes to the robots' nearest ties allows on top of the tolerance, in metres.
fn offsets_through_others(
    rule: &GrantRule,
    loops: &[PcmLoop],
    members: &[usize],
    graph: &dyn GraphView,
) -> Vec<(RobotId, Vec<Offset>)> {
    let Some(first) = members.first().and_then(|&k| loops.get(k)) else {
        return Vec::new();
    };
    let (a, b) = (first.target.robot, first.source.robot);
    // The frames through others first: without them the members' placements are not needed.
    let through = graph.frames_through_others(a, b);
    if through.is_empty() {
        return Vec::new();
    }
    // Where each member's loop puts b, each robot's keyframes placed along the graph's estimate, as the
    // frames through others were: the odometry alone drifts from it by as much as the robots travelled
    // without a loop.
    let placed = placements(loops, members, graph, Along::Estimate);
    if placed.is_empty() {
        return Vec::new();
    }
    let mut by_via: Vec<(RobotId, Vec<Offset>)> = through
        .into_iter()
        .map(|(via, through)| {
            let offsets = placed
                .iter()
                .map(|placed| {
                    let by_loop = placed.a_first_from_b_first * placed.b_first_from_source;
                    let by_cycle = through * placed.b_first_from_source;
                    let change = by_loop.inverse() * by_cycle;
                    Offset {
                        off_m: change.translation.vector.norm(),
                        off_rad: change.rotation.angle(),
                        drift_allowed_m: 0.0,
                    }
                })
                .collect();
            (via, offsets)
        })
        .collect();
    // The drift allowance matters only past the fixed tolerance: the routes are measured only then.
    let past_tolerance = by_via
        .iter()
        .flat_map(|(_, offsets)| offsets)
        .any(|offset| offset.off_m > rule.cycle_tolerance_m);
    if rule.cycle_drift_fraction > 0.0 && past_tolerance {
        let ties = Ties::of(graph, &[a, b]);
        let route_m = |id| ties.distance_m(id).unwrap_or(0.0);
        let drift_allowed_m: Vec<f64> = placed
            .iter()
            .map(|placed| {
                let member = &loops[placed.member];
                rule.cycle_drift_fraction * (route_m(member.target) + route_m(member.source))
            })
            .collect();
        for (_, offsets) in &mut by_via {
            for (offset, &allowed_m) in offsets.iter_mut().zip(&drift_allowed_m) {
                offset.drift_allowed_m = allowed_m;
            }
        }
    }
    by_via
}

/// How far a frame through a third robot puts robot b from where one loop puts it.
#[derive(Clone, Copy, Debug)]
struct Offset {
    off_m: f64,
    off_rad: f64,
    /// What the odometry may have drifted between the loop's place and the robots' nearest ties.
    drift_allowed_m: f64,
}

impl Offset {
    /// Beyond the tolerance and the drift the route allows: the frame refutes the loop; within them it
    /// vouches for it.
    fn refutes(&self, rule: &GrantRule) -> bool {
        self.off_m > rule.cycle_tolerance_m + self.drift_allowed_m || self.off_rad > rule.cycle_tolerance_rad
    }
}

/// The first third robot whose frame refutes most of the members, at each member's place.
fn contradiction(
    rule: &GrantRule,
    loops: &[PcmLoop],
    members: &[usize],
    graph: &dyn GraphView,
) -> Option<Withheld> {
    for (via, mut offsets) in offsets_through_others(rule, loops, members, graph) {
        let refuting = offsets.iter().filter(|offset| offset.refutes(rule)).count();
        if 2 * refuting > offsets.len() {
            offsets.sort_by(|x, y| x.off_m.total_cmp(&y.off_m));
            let median = offsets[offsets.len() / 2];
            return Some(Withheld::Contradicted {
                via,
                off_m: median.off_m,
                off_deg: median.off_rad.to_degrees(),
            });
        }
    }
    None
}

/// Whether the frame of robot b is already known through a third robot and every member agrees with
/// every such frame: the cycle then stands as the evidence PCM otherwise waits for more loops to give.
pub(crate) fn agrees_with_cycle(
    rule: &GrantRule,
    loops: &[PcmLoop],
    members: &[usize],
    graph: &dyn GraphView,
) -> bool {
    let through = offsets_through_others(rule, loops, members, graph);
    !through.is_empty()
        && through.iter().all(|(_, offsets)| {
            offsets.len() == members.len() && offsets.iter().all(|offset| !offset.refutes(rule))
        })
}

/// How many members join keyframes recorded within `together_within_s` of each other and measured
/// within `together_within_m`: the two robots in one place at one time. 0 when the rule is off or the
/// stamps are unknown.
fn together(rule: &GrantRule, loops: &[PcmLoop], members: &[usize], graph: &dyn GraphView) -> usize {
    if rule.together_within_s <= 0.0 || rule.together_within_m <= 0.0 {
        return 0;
    }
    let within_nanos = (rule.together_within_s * 1e9) as u64;
    members
        .iter()
        .filter(|&&k| {
            let member = &loops[k];
            let stamps = graph
                .keyframe_stamp_nanos(member.target)
                .zip(graph.keyframe_stamp_nanos(member.source));
            stamps.is_some_and(|(target, source)| target.abs_diff(source) <= within_nanos)
                && member.target_from_source.translation.vector.norm() <= rule.together_within_m
        })
        .count()
}

/// The largest distance between two of the keyframes (all of one robot), from the graph's poses; the
/// relative odometry stands in when a pose is missing. The search stops at the first pair `enough_m`
/// apart or more: the rule asks only whether the spread reaches it, and a large set of loops would
/// otherwise cost the square of its size at every judgement.
fn spread_m(keyframes: impl Iterator<Item = KeyframeId>, graph: &dyn GraphView, enough_m: f64) -> f64 {
    let mut ids: Vec<KeyframeId> = keyframes.collect();
    ids.sort_unstable();
    ids.dedup();
    let positions: Vec<Option<nalgebra::Vector3<f64>>> = ids
        .iter()
        .map(|id| graph.pose(*id).map(|pose| pose.translation.vector))
        .collect();
    let mut widest = 0.0f64;
    for (i, a) in ids.iter().enumerate() {
        for (j, b) in ids.iter().enumerate().skip(i + 1) {
            let distance = match (positions[i], positions[j]) {
                (Some(pa), Some(pb)) => (pa - pb).norm(),
                _ => graph.odometry_between(*a, *b).map_or(0.0, |relative| {
                    relative.target_from_source.translation.vector.norm()
                }),
            };
            widest = widest.max(distance);
            if widest >= enough_m {
                return widest;
            }
        }
    }
    widest
}

/// The size of the strongest competing hypothesis: the consistent core of the loops outside `members`
/// that are consistent with fewer than half of `members`.
fn rival_size(
    consistency: &Graph,
    members: &[usize],
    refuted: &BTreeSet<usize>,
    core_fraction: f64,
) -> usize {
    let outside: Vec<usize> = (0..consistency.len())
        .filter(|v| !members.contains(v) && !refuted.contains(v))
        .filter(|&v| {
            let agreeing = members
                .iter()
                .filter(|&&m| consistency.neighbours(v).contains(m))
                .count();
            2 * agreeing < members.len()
        })
        .collect();
    if outside.len() < 2 {
        return outside.len().min(1);
    }
    consistent_core(&induced(consistency, &outside), core_fraction)
        .len()
        .max(1)
}
