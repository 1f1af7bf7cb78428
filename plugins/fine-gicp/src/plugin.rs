//! The `gicp` fine-registration plugin: its rayon pool, `prepare`/`refine`, and the checks that turn
//! degenerate input into a "not converged" result with a reason.

use std::fmt;
use std::time::Instant;

use nalgebra::{Matrix6, SymmetricEigen};
use serde::Serialize;
use skid_core::slots::{FineAlignment, FineRegistration, PreparedCloud};
use skid_core::{CloudView, Information, PluginContext, PluginError, PluginResult, Pose};

use crate::PLUGIN_NAME;
use crate::config::{GicpConfig, Variant};
use crate::prepared::{self, PreparedData};
use crate::solver::{self, Problem, Solution};
use crate::voxelmap::search_offsets;

/// Which of the two clouds a reason is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    Target,
    Source,
}

impl fmt::Display for Role {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Role::Target => "target",
            Role::Source => "source",
        })
    }
}

/// Why a registration did not converge.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "reason", rename_all = "snake_case")]
pub enum Failure {
    /// A cloud has fewer points (after downsampling) than `min_points`.
    TooFewPoints {
        cloud: Role,
        points: usize,
        needed: usize,
    },
    /// A cloud's points lie on a line: rotation about it and translation along it are unobservable.
    Collinear { cloud: Role, second_extent_m: f64 },
    /// A cloud's points lie on a plane: in-plane motion is unobservable.
    Coplanar { cloud: Role, thickness_m: f64 },
    /// No source point has a target point within the maximum correspondence distance.
    NoCorrespondences { max_correspondence_m: f64 },
    /// Fewer inliers than `min_inliers`.
    TooFewInliers { inliers: usize, needed: usize },
    /// The Hessian at the solution is (numerically) singular: some motion is unconstrained.
    IllConditioned {
        min_eigenvalue: f64,
        max_eigenvalue: f64,
    },
    /// The steps were still above the epsilons after `max_iterations` linearisations.
    MaxIterations { iterations: usize },
    /// The optimisation produced a non-finite pose or cost; the guess is returned.
    NumericalFailure,
}

impl fmt::Display for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Failure::TooFewPoints {
                cloud,
                points,
                needed,
            } => {
                write!(
                    f,
                    "the {cloud} cloud has {points} points after downsampling, at least {needed} needed"
                )
            }
            Failure::Collinear {
                cloud,
                second_extent_m,
            } => write!(
                f,
                "the {cloud} cloud is collinear (second principal extent {second_extent_m:.3} m): rotation about \
                 and translation along the line are unobservable"
            ),
            Failure::Coplanar { cloud, thickness_m } => write!(
                f,
                "the {cloud} cloud is coplanar (thickness {thickness_m:.3} m): in-plane motion is unobservable"
            ),
            Failure::NoCorrespondences { max_correspondence_m } => {
                write!(
                    f,
                    "no correspondence within the maximum distance of {max_correspondence_m} m"
                )
            }
            Failure::TooFewInliers { inliers, needed } => {
                write!(f, "{inliers} inlier correspondences, at least {needed} needed")
            }
            Failure::IllConditioned {
                min_eigenvalue,
                max_eigenvalue,
            } => write!(
                f,
                "the Hessian is singular (eigenvalues {min_eigenvalue:.3e} to {max_eigenvalue:.3e}): some motion is \
                 unconstrained"
            ),
            Failure::MaxIterations { iterations } => {
                write!(f, "not converged after {iterations} iterations")
            }
            Failure::NumericalFailure => f.write_str("the optimisation produced non-finite numbers"),
        }
    }
}

/// Everything `refine` found out: the slot's result, why it did not converge (if so), and timing.
#[derive(Clone, Debug)]
pub struct RefineReport {
    pub alignment: FineAlignment,
    /// `Some` exactly when `alignment.converged` is false (`alignment.failure` holds its sentence).
    pub failure: Option<Failure>,
    /// Linearisations of the coarse stage, included in `alignment.iterations`.
    pub coarse_iterations: usize,
    /// Wall-clock time of the optimisation, in milliseconds.
    pub align_ms: f64,
}

/// Smallest Hessian eigenvalue, relative to the largest, that still counts as constrained.
const MIN_RELATIVE_EIGENVALUE: f64 = 1e-9;

/// The plugin: GICP, VGICP, point-to-point or point-to-plane ICP, on its own rayon pool.
pub struct GicpRegistration {
    config: GicpConfig,
    pool: rayon::ThreadPool,
}

impl fmt::Debug for GicpRegistration {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("GicpRegistration")
            .field("config", &self.config)
            .field("threads", &self.pool.current_num_threads())
            .finish()
    }
}

impl GicpRegistration {
    /// Validates the configuration and builds the rayon pool of `context.threads` threads.
    pub fn new(config: GicpConfig, context: &PluginContext) -> PluginResult<Self> {
        config.validate()?;
        Self::from_checked(config, context)
    }

    /// [`GicpRegistration::new`] for a configuration the registry has checked already (it is checked once, when
    /// the configuration is loaded).
    pub(crate) fn from_checked(config: GicpConfig, context: &PluginContext) -> PluginResult<Self> {
        let threads = context.threads.max(1);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("skid-gicp-{i}"))
            .build()
            .map_err(|e| PluginError::failed(PLUGIN_NAME, format!("cannot start {threads} threads: {e}")))?;
        Ok(Self { config, pool })
    }

    pub fn config(&self) -> &GicpConfig {
        &self.config
    }

    /// Like [`FineRegistration::refine`], with the reason for a failure and the time taken.
    pub fn refine_report(
        &mut self,
        target: &PreparedCloud,
        source: &PreparedCloud,
        guess: &Pose,
    ) -> PluginResult<RefineReport> {
        let start = Instant::now();
        if !(guess.translation.vector.iter().all(|v| v.is_finite())
            && guess.rotation.coords.iter().all(|v| v.is_finite()))
        {
            return Err(PluginError::InvalidInput(format!(
                "{PLUGIN_NAME}: the initial guess is not finite"
            )));
        }
        let target_data = prepared::data_of(target, &self.config, "target")?;
        let source_data = prepared::data_of(source, &self.config, "source")?;
        let config = &self.config;
        let unmoved = |failure: Failure| RefineReport {
            alignment: FineAlignment {
                target_from_source: *guess,
                information: Information::zeros(),
                converged: false,
                iterations: 0,
                inlier_count: 0,
                inlier_ratio: 0.0,
                error: 0.0,
                failure: Some(failure.to_string()),
            },
            failure: Some(failure),
            coarse_iterations: 0,
            align_ms: start.elapsed().as_secs_f64() * 1e3,
        };
        for (role, data) in [(Role::Target, target_data), (Role::Source, source_data)] {
            if data.len() < config.min_points.max(1) {
                return Ok(unmoved(Failure::TooFewPoints {
                    cloud: role,
                    points: data.len(),
                    needed: config.min_points,
                }));
            }
        }
        let offsets = search_offsets(config.voxel_search_offsets);
        let problem = |variant, target, source, distance: f64| Problem {
            variant,
            target,
            source,
            max_sq_distance: distance * distance,
            voxel_offsets: &offsets,
        };
        let (solution, coarse_iterations) = self.pool.install(|| {
            let mut start = *guess;
            let mut coarse_iterations = 0;
            if config.coarse_correspondence_m > 0.0 {
                // The coarse levels when prepared (else the fine points), with a wider reach. VGICP's voxel
                // map reaches only neighbouring voxels, so its first stage is GICP on points.
                let (coarse_target, coarse_source) = match (&target_data.coarse, &source_data.coarse) {
                    (Some(target), Some(source)) => (&**target, &**source),
                    _ => (target_data, source_data),
                };
                let coarse_variant = if config.variant == Variant::Vgicp {
                    Variant::Gicp
                } else {
                    config.variant
                };
                let coarse = solver::solve(
                    &problem(
                        coarse_variant,
                        coarse_target,
                        coarse_source,
                        config.coarse_correspondence_m,
                    ),
                    guess,
                    config,
                    config.coarse_max_iterations,
                );
                coarse_iterations = coarse.iterations;
                // A coarse stage that found nothing to hold on to (tiny coarse levels, a guess out of
                // reach) leaves the guess to the final stage.
                if solution_is_finite(&coarse) && coarse.inliers >= config.min_inliers.max(1) {
                    start = coarse.pose;
                }
            }
            let mut fine = solver::solve(
                &problem(
                    config.variant,
                    target_data,
                    source_data,
                    config.max_correspondence_m,
                ),
                &start,
                config,
                config.max_iterations,
            );
            fine.iterations += coarse_iterations;
            (fine, coarse_iterations)
        });
        if !solution_is_finite(&solution) {
            return Ok(unmoved(Failure::NumericalFailure));
        }
        let failure = self.diagnose(target_data, source_data, &solution);
        Ok(RefineReport {
            alignment: FineAlignment {
                target_from_source: solution.pose,
                information: translation_first(&solution.hessian),
                converged: failure.is_none(),
                iterations: solution.iterations,
                inlier_count: solution.inliers,
                inlier_ratio: solution.inliers as f64 / source_data.len() as f64,
                error: solution.error,
                failure: failure.as_ref().map(Failure::to_string),
            },
            failure,
            coarse_iterations,
            align_ms: start.elapsed().as_secs_f64() * 1e3,
        })
    }

    /// The first reason the solution cannot be trusted, if any.
    fn diagnose(&self, target: &PreparedData, source: &PreparedData, solution: &Solution) -> Option<Failure> {
        let config = &self.config;
        for (role, data) in [(Role::Target, target), (Role::Source, source)] {
            let [thinnest, second, _] = data.principal_extents_m();
            if second < config.min_extent_m {
                return Some(Failure::Collinear {
                    cloud: role,
                    second_extent_m: second,
                });
            }
            if thinnest < config.min_extent_m {
                return Some(Failure::Coplanar {
                    cloud: role,
                    thickness_m: thinnest,
                });
            }
        }
        if solution.inliers == 0 {
            return Some(Failure::NoCorrespondences {
                max_correspondence_m: config.max_correspondence_m,
            });
        }
        if solution.inliers < config.min_inliers {
            return Some(Failure::TooFewInliers {
                inliers: solution.inliers,
                needed: config.min_inliers,
            });
        }
        let eigenvalues = SymmetricEigen::new(solution.hessian).eigenvalues;
        let (min, max) = (eigenvalues.min(), eigenvalues.max());
        if !(max > 0.0 && min > MIN_RELATIVE_EIGENVALUE * max) {
            return Some(Failure::IllConditioned {
                min_eigenvalue: min,
                max_eigenvalue: max,
            });
        }
        if !solution.converged {
            return Some(Failure::MaxIterations {
                iterations: solution.iterations,
            });
        }
        None
    }
}

fn solution_is_finite(solution: &Solution) -> bool {
    solution.pose.translation.vector.iter().all(|v| v.is_finite())
        && solution.pose.rotation.coords.iter().all(|v| v.is_finite())
        && solution.hessian.iter().all(|v| v.is_finite())
        && solution.error.is_finite()
}

/// Reorders a Hessian from (rotation, translation) to the slot's (translation, rotation).
fn translation_first(hessian: &Matrix6<f64>) -> Information {
    let order = [3, 4, 5, 0, 1, 2];
    Information::from_fn(|row, col| hessian[(order[row], order[col])])
}

impl FineRegistration for GicpRegistration {
    fn prepare(&mut self, cloud: CloudView<'_>) -> PluginResult<PreparedCloud> {
        let config = &self.config;
        self.pool.install(|| prepared::prepare(config, cloud))
    }

    fn refine(
        &mut self,
        target: &PreparedCloud,
        source: &PreparedCloud,
        guess: &Pose,
    ) -> PluginResult<FineAlignment> {
        self.refine_report(target, source, guess)
            .map(|report| report.alignment)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn information_is_reordered_translation_first() {
        let hessian = Matrix6::from_fn(|r, c| (r * 6 + c) as f64);
        let info = translation_first(&hessian);
        assert_eq!(info[(0, 0)], hessian[(3, 3)]);
        assert_eq!(info[(0, 3)], hessian[(3, 0)]);
        assert_eq!(info[(5, 2)], hessian[(2, 5)]);
    }

    #[test]
    fn failures_read_as_sentences() {
        let text = Failure::Coplanar {
            cloud: Role::Source,
            thickness_m: 0.001,
        }
        .to_string();
        assert!(text.contains("source") && text.contains("coplanar"), "{text}");
        let json = format!(
            "{:?}",
            Failure::NoCorrespondences {
                max_correspondence_m: 1.0
            }
        );
        assert!(json.contains("NoCorrespondences"));
    }
}
