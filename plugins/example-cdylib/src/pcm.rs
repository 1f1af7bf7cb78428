//! `pcm_cdylib`: SKiD's own verifier (`skid-verifier-pcm`: the truncated-MSE fitness check, then pairwise
//! consistency maximisation) exported through the C ABI's verifier slot. The host's graph reaches it
//! through the ABI's callbacks and snapshots, seen here through skid-core's `GraphView` again.

use skid_abi::ffi::AbiLoop;
use skid_abi::transform::pose_from_abi;
use skid_abi::{ConfigError, GraphAccess, InstanceContext, VerdictOutcome, VerifierPlugin, parse_config};
use skid_core::slots::{GraphView, LoopCandidate, LoopClosure, RelativePose, Verifier};
use skid_core::{CloudView, Information, KeyframeId, Pose};
use skid_msgs::Point;
use skid_verifier_pcm::{PcmConfig, PcmVerifier};

use skid_abi::graph::{abi_id, host_id, loop_from_abi};

/// The built-in verifier's defaults as TOML; a unit test keeps them equal to `PcmConfig::default()`.
const DEFAULT_CONFIG: &str = include_str!("pcm_defaults.toml");

/// The built-in PCM verifier behind the C ABI.
pub struct PcmCdylib {
    inner: PcmVerifier,
}

/// The host's graph, lent for one submission, as skid-core's view.
struct LentGraph<'a, 'b> {
    access: &'a GraphAccess<'b>,
}

impl GraphView for LentGraph<'_, '_> {
    fn pose(&self, id: KeyframeId) -> Option<Pose> {
        self.access
            .pose(abi_id(id))
            .and_then(|pose| pose_from_abi(&pose).ok())
    }

    fn odometry_between(&self, target: KeyframeId, source: KeyframeId) -> Option<RelativePose> {
        let relative = self.access.odometry_between(abi_id(target), abi_id(source))?;
        Some(RelativePose {
            target_from_source: pose_from_abi(&relative.target_from_source).ok()?,
            covariance: Information::from_row_slice(&relative.covariance),
        })
    }

    fn keyframes(&self) -> Vec<KeyframeId> {
        self.access.keyframes().iter().copied().map(host_id).collect()
    }

    fn loops(&self) -> Vec<LoopClosure> {
        self.access
            .loops()
            .iter()
            .filter_map(|lent| loop_from_abi(lent).ok())
            .collect()
    }
}

impl VerifierPlugin for PcmCdylib {
    const NAME: &'static str = "pcm_cdylib";
    const SUMMARY: &'static str =
        "The built-in PCM verifier (fitness check, then PCM) loaded through the C ABI (example cdylib)";
    const DEFAULT_CONFIG: &'static str = DEFAULT_CONFIG;

    fn from_config(config: &str, _context: &InstanceContext) -> Result<Self, ConfigError> {
        let config: PcmConfig = parse_config(config)?;
        let inner = PcmVerifier::new(config).map_err(|error| ConfigError::from(error.to_string()))?;
        Ok(Self { inner })
    }

    fn submit(
        &mut self,
        candidate: &AbiLoop,
        target_cloud: &[Point],
        source_cloud: &[Point],
        graph: &GraphAccess<'_>,
    ) -> Result<VerdictOutcome, String> {
        let candidate = LoopCandidate {
            closure: loop_from_abi(candidate)?,
            target_cloud: CloudView::new(target_cloud),
            source_cloud: CloudView::new(source_cloud),
        };
        let verdict = self
            .inner
            .submit(&candidate, &LentGraph { access: graph })
            .map_err(|error| error.to_string())?;
        Ok(VerdictOutcome {
            accepted: verdict.accepted.iter().map(|id| id.0).collect(),
            retracted: verdict.retracted.iter().map(|id| id.0).collect(),
            rejected: verdict
                .rejected
                .into_iter()
                .map(|(id, reason)| (id.0, reason))
                .collect(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_config_text_matches_the_built_in_defaults() {
        assert_eq!(
            parse_config::<PcmConfig>(DEFAULT_CONFIG).unwrap(),
            PcmConfig::default()
        );
    }
}
