//! SKiD loop verification: the two-stage outlier rejection of SKiD-SLAM (Kim et al., §IV-D): a
//! truncated-MSE fitness check of each loop's clouds ([`fitness`]) and a check that the two clouds do
//! not see through each other ([`free_space`]), a bound on an intra-robot loop's disagreement with the
//! robot's odometry ([`odometry_bound`]), then pairwise consistency maximisation (PCM; Mangelson
//! et al., ICRA 2018) over the loops of each robot pair ([`pcm`], [`consistency`], [`clique`],
//! [`dense`]).
//!
//! Plugins (verifier slot):
//! - `pcm`: both stages; loops of a robot pair are accepted as the consistent core of their
//!   consistency graph (every accepted loop consistent with at least 90 % of the others, found by
//!   peeling; or, with `min_consistent_fraction = 1`, the maximum clique), updated as loops arrive, and
//!   earlier acceptances are retracted when the accepted set changes. Between two robots the set is a
//!   frame hypothesis, granted only when its loops are spread over space and it clearly dominates the
//!   strongest rival hypothesis ([`earned`]), and while the other keyframe pairs its frame puts in one
//!   place look alike too ([`predicted`]), and, where most of its loops join places that repeat in a
//!   robot's own map, once a loop's scans show the other robot where it puts it or its loops span more
//!   than one look-alike spot ([`repeated`], [`peer_seen`]); a granted set that stops dominating or
//!   whose predictions fail is retracted.
//! - `gnc`: the cloud checks only (truncated MSE, free space), accepting the rest; pair it with `[backend.pgo] robust = "gnc"` so
//!   graduated non-convexity with a truncated-least-squares loss rejects outliers in the back-end.
//!
//! `plugin = "none"` (no verifier) is the runtime's business, for ablation.

pub mod clique;
pub mod consistency;
pub mod dense;
mod earned;
pub mod fitness;
pub mod free_space;
pub mod lie;
pub mod odometry_bound;
pub mod pcm;
pub mod peer_seen;
mod predicted;
mod repeated;
#[cfg(test)]
mod test_scene;
mod ties;
pub mod verifier;

use skid_core::slots::Verifier;
use skid_core::{PluginContext, PluginEntry, PluginError, Registry};

pub use consistency::{PcmLoop, squared_mahalanobis};
pub use fitness::{Fitness, FitnessConfig};
pub use pcm::{Pcm, PcmParams, PcmUpdate};
pub use verifier::{GncConfig, GncVerifier, PcmConfig, PcmVerifier};

/// Registers `pcm` and `gnc` in the verifier slot.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    let pcm = PluginEntry::new(
        "pcm",
        "Truncated-MSE fitness and free-space checks, then pairwise consistency maximisation",
        |config: PcmConfig, _context: &PluginContext| {
            Ok(Box::new(PcmVerifier::from_checked(config)) as Box<dyn Verifier>)
        },
    )?;
    registry.verifier.register(pcm)?;
    let gnc = PluginEntry::new(
        "gnc",
        "Truncated-MSE fitness and free-space checks only; outliers left to GNC-TLS in the back-end (robust = \"gnc\")",
        |config: GncConfig, _context: &PluginContext| {
            Ok(Box::new(GncVerifier::from_checked(config)?) as Box<dyn Verifier>)
        },
    )?;
    registry.verifier.register(gnc)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pcm_passes_the_verifier_conformance_suite() {
        let mut verifier = PcmVerifier::new(PcmConfig::default()).unwrap();
        skid_testkit::verifier::check_verifier(&mut verifier);
    }

    #[test]
    fn plugins_register_with_defaults() {
        let mut registry = Registry::new();
        register(&mut registry).unwrap();
        assert!(register(&mut registry).is_err(), "registering twice is refused");
    }
}
