//! When an inter-robot merge is earned. PCM's consistent set between two robots is a hypothesis about
//! where one robot's frame sits in the other's; in a self-similar place several hypotheses are each
//! supported by loops that agree with one another, and pairwise consistency cannot tell a wrong one from
//! the right one. The set is granted (its loops accepted) only when
//! - its loops are spread over space: on each robot, the keyframes they join span at least
//!   `min_spread_m` (not all on one spot), and
//! - it clearly dominates: it holds at least `dominance_ratio` times as many loops as the strongest
//!   rival, the consistent core of the loops that disagree with most of it (a competing frame).
//!
//! A granted set that stops dominating (a rival grows) is withdrawn, and its loops are retracted; when
//! the rival later dominates in turn, it is granted and the merge is redone in its frame. This is the
//! hypothesis bookkeeping the SKiD issue on self-similar places asks for, on top of PCM (Mangelson et
//! al., ICRA 2018).

use skid_core::KeyframeId;
use skid_core::slots::GraphView;

use crate::clique::Graph;
use crate::consistency::PcmLoop;
use crate::dense::consistent_core;

/// What decides a grant.
#[derive(Clone, Copy, Debug)]
pub(crate) struct GrantRule {
    pub min_spread_m: f64,
    pub dominance_ratio: f64,
    /// The peeling fraction for the rival's core (PCM's own `min_consistent_fraction`).
    pub core_fraction: f64,
}

/// Why a hypothesis is not granted (yet), or `None` when it is.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Withheld {
    /// The loops' keyframes on one robot span less than the rule asks.
    Clustered { spread_m: f64 },
    /// A rival hypothesis holds too many loops.
    Contested { rival: usize },
}

impl std::fmt::Display for Withheld {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Clustered { spread_m } => {
                write!(f, "its loops' keyframes span only {spread_m:.1} m on one robot")
            }
            Self::Contested { rival } => write!(f, "a rival frame hypothesis is supported by {rival} loops"),
        }
    }
}

/// Judges the hypothesis `members` (indices into `loops`, vertices of `consistency`).
pub(crate) fn judge(
    rule: &GrantRule,
    loops: &[PcmLoop],
    consistency: &Graph,
    members: &[usize],
    graph: &dyn GraphView,
) -> Option<Withheld> {
    let spread_m = spread_m(members.iter().map(|&k| loops[k].target), graph)
        .min(spread_m(members.iter().map(|&k| loops[k].source), graph));
    if spread_m < rule.min_spread_m {
        return Some(Withheld::Clustered { spread_m });
    }
    let rival = rival_size(consistency, members, rule.core_fraction);
    (rival > 0 && (members.len() as f64) < rule.dominance_ratio * rival as f64)
        .then_some(Withheld::Contested { rival })
}

/// The largest distance between two of the keyframes (all of one robot), from the graph's poses; the
/// relative odometry stands in when a pose is missing.
fn spread_m(keyframes: impl Iterator<Item = KeyframeId>, graph: &dyn GraphView) -> f64 {
    let mut ids: Vec<KeyframeId> = keyframes.collect();
    ids.sort_unstable();
    ids.dedup();
    let mut widest = 0.0f64;
    for (i, a) in ids.iter().enumerate() {
        for b in &ids[i + 1..] {
            let distance = match (graph.pose(*a), graph.pose(*b)) {
                (Some(pa), Some(pb)) => (pa.translation.vector - pb.translation.vector).norm(),
                _ => graph.odometry_between(*a, *b).map_or(0.0, |relative| {
                    relative.target_from_source.translation.vector.norm()
                }),
            };
            widest = widest.max(distance);
        }
    }
    widest
}

/// The size of the strongest competing hypothesis: the consistent core of the loops outside `members`
/// that are consistent with fewer than half of `members`.
fn rival_size(consistency: &Graph, members: &[usize], core_fraction: f64) -> usize {
    let outside: Vec<usize> = (0..consistency.len())
        .filter(|v| !members.contains(v))
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
    let mut induced = Graph::new(outside.len());
    for (i, &a) in outside.iter().enumerate() {
        for (j, &b) in outside.iter().enumerate().skip(i + 1) {
            if consistency.neighbours(a).contains(b) {
                induced.add_edge(i, j);
            }
        }
    }
    consistent_core(&induced, core_fraction).len().max(1)
}
