//! `pgo_cdylib`: SKiD's own pose-graph back-end (`skid-backend-pgo`: Levenberg-Marquardt on SE(3) with
//! the robust kernels and GNC) exported through the C ABI's back-end slot.

use skid_abi::ffi::{AbiKeyframeId, AbiLoop, AbiOptimizeReport, AbiPrior, AbiRelativePose};
use skid_abi::graph::{abi_id, abi_loop, host_id, loop_from_abi, prior_from_abi, row_major};
use skid_abi::transform::{abi_from_pose, pose_from_abi};
use skid_abi::{AbiTransform, BackendPlugin, ConfigError, InstanceContext, parse_config};
use skid_backend_pgo::{PgoBackend, PgoConfig};
use skid_core::LoopId;
use skid_core::slots::{Backend, OdometryMeasurement, OptimizeBudget};

/// The built-in back-end's defaults as TOML; a unit test keeps them equal to `PgoConfig::default()`.
const DEFAULT_CONFIG: &str = include_str!("pgo_defaults.toml");

/// The built-in pose-graph back-end behind the C ABI.
pub struct PgoCdylib {
    inner: PgoBackend,
}

impl BackendPlugin for PgoCdylib {
    const NAME: &'static str = "pgo_cdylib";
    const SUMMARY: &'static str =
        "The built-in pose-graph back-end loaded through the C ABI (example cdylib)";
    const DEFAULT_CONFIG: &'static str = DEFAULT_CONFIG;

    fn from_config(config: &str, context: &InstanceContext) -> Result<Self, ConfigError> {
        let config: PgoConfig = parse_config(config)?;
        let inner = PgoBackend::new(config, &crate::plugin_context(context))
            .map_err(|error| ConfigError::from(error.to_string()))?;
        Ok(Self { inner })
    }

    fn add_keyframe(&mut self, id: AbiKeyframeId, world_from_sensor: &AbiTransform) -> Result<(), String> {
        let pose = pose_from_abi(world_from_sensor)?;
        self.inner
            .add_keyframe(host_id(id), pose)
            .map_err(|error| error.to_string())
    }

    fn add_odometry(&mut self, edge: &AbiLoop) -> Result<(), String> {
        let edge = loop_from_abi(edge)?;
        let measurement = OdometryMeasurement {
            target: edge.target,
            source: edge.source,
            target_from_source: edge.target_from_source,
            information: edge.information,
        };
        self.inner
            .add_odometry(measurement)
            .map_err(|error| error.to_string())
    }

    fn add_loop(&mut self, lent: &AbiLoop) -> Result<(), String> {
        self.inner
            .add_loop(loop_from_abi(lent)?)
            .map_err(|error| error.to_string())
    }

    fn add_prior(&mut self, prior: &AbiPrior) -> Result<(), String> {
        let (id, world_from_sensor, information) = prior_from_abi(prior)?;
        self.inner
            .add_prior(id, world_from_sensor, information)
            .map_err(|error| error.to_string())
    }

    fn remove_loop(&mut self, id: u64) -> Result<(), String> {
        self.inner
            .remove_loop(LoopId(id))
            .map_err(|error| error.to_string())
    }

    fn optimize(&mut self, max_iterations: u64, max_duration_s: f64) -> Result<AbiOptimizeReport, String> {
        if !(max_duration_s.is_finite() && max_duration_s >= 0.0) {
            return Err(format!("the time budget {max_duration_s} s is not a duration"));
        }
        let budget = OptimizeBudget {
            max_iterations: usize::try_from(max_iterations).unwrap_or(usize::MAX),
            max_duration: std::time::Duration::from_secs_f64(max_duration_s),
        };
        let report = self.inner.optimize(budget).map_err(|error| error.to_string())?;
        Ok(AbiOptimizeReport {
            iterations: report.iterations as u64,
            initial_cost: report.initial_cost,
            final_cost: report.final_cost,
            converged: u32::from(report.converged),
            reserved: 0,
        })
    }

    fn pose(&self, id: AbiKeyframeId) -> Option<AbiTransform> {
        self.inner.graph().pose(host_id(id)).as_ref().map(abi_from_pose)
    }

    fn odometry_between(&self, target: AbiKeyframeId, source: AbiKeyframeId) -> Option<AbiRelativePose> {
        let relative = self
            .inner
            .graph()
            .odometry_between(host_id(target), host_id(source))?;
        Some(AbiRelativePose {
            target_from_source: abi_from_pose(&relative.target_from_source),
            covariance: row_major(&relative.covariance),
        })
    }

    fn keyframes(&self) -> Vec<AbiKeyframeId> {
        self.inner.graph().keyframes().into_iter().map(abi_id).collect()
    }

    fn loops(&self) -> Vec<AbiLoop> {
        self.inner.graph().loops().iter().map(abi_loop).collect()
    }

    fn rejected_loops(&self) -> Vec<u64> {
        self.inner.rejected_loops().into_iter().map(|id| id.0).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_config_text_matches_the_built_in_defaults() {
        assert_eq!(
            parse_config::<PgoConfig>(DEFAULT_CONFIG).unwrap(),
            PgoConfig::default()
        );
    }
}
