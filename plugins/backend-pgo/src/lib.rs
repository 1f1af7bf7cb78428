//! SKiD back-end: SE(3)/SE(2) pose-graph optimisation by Levenberg-Marquardt on the manifold with analytic
//! Jacobians and faer's sparse Cholesky (SKiD-SLAM, Kim et al., eq. 6: the distributed pose graph of one
//! robot), with robust kernels, GNC-TLS, a chordal initialisation, and a g2o file API for `skid pgo`.
//!
//! | module | what |
//! |---|---|
//! | [`group`], [`se3`], [`se2`] | residuals `Log(Z⁻¹ T_i⁻¹ T_j)` (GTSAM's convention) and their Jacobians |
//! | [`problem`] | validated problem (bad edges are errors naming the edge) |
//! | [`linear`] | block-sparse normal equations, AMD ordering, symbolic factorisation reused per topology |
//! | [`lm`] | Levenberg-Marquardt loop |
//! | [`robust`], [`gnc`] | Huber, Cauchy, TLS kernels; graduated non-convexity |
//! | [`chordal`] | chordal initialisation |
//! | [`chain`], [`distributed`], [`backend`] | the `pgo` plugin: odometry chains, the distributed subgraph |
//! | [`g2o_file`] | `optimize_g2o_file` and `write_g2o` for the command line |

pub mod backend;
pub mod chain;
pub mod chordal;
pub mod distributed;
pub mod error;
pub mod g2o_file;
pub mod gnc;
pub mod gnc_warm;
pub mod group;
pub mod incremental;
pub mod linear;
pub mod lm;
pub mod own_chain;
pub mod problem;
pub mod region;
pub mod robust;
pub mod se2;
pub mod se3;

use skid_core::slots::Backend;
use skid_core::{PluginContext, PluginEntry, PluginError, Registry};

pub use backend::{PgoBackend, PgoConfig};
pub use error::{EdgeLabel, PgoError};
pub use g2o_file::{
    Initialization, PgoOptions, PgoReport, RobustMode, optimize_g2o_file, optimize_pose_graph, write_g2o,
};

/// Registers `pgo` in the back-end slot.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    let entry = PluginEntry::new(
        "pgo",
        "Distributed SE(3) pose-graph optimisation: Levenberg-Marquardt on sparse Cholesky, robust kernels, GNC",
        |config: PgoConfig, context: &PluginContext| {
            Ok(Box::new(PgoBackend::new(config, context)?) as Box<dyn Backend>)
        },
    )?;
    registry.backend.register(entry)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pgo_passes_the_backend_conformance_suite() {
        let mut backend = PgoBackend::new(PgoConfig::default(), &PluginContext::default()).unwrap();
        skid_testkit::backend::check_backend(&mut backend);
    }

    #[test]
    fn pgo_passes_it_centralised_and_with_gnc() {
        let config = PgoConfig {
            distributed: false,
            robust: RobustMode::Gnc,
            ..PgoConfig::default()
        };
        let mut backend = PgoBackend::new(config, &PluginContext::default()).unwrap();
        skid_testkit::backend::check_backend(&mut backend);
    }

    #[test]
    fn registers_once() {
        let mut registry = Registry::new();
        register(&mut registry).unwrap();
        assert!(register(&mut registry).is_err());
    }
}
