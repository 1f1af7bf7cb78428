//! GNC-TLS warm-started from an earlier solution ([`crate::gnc`]): the loops new since the last run
//! graduate while the earlier ones keep their labels, first over the region around the new loops
//! ([`crate::region`]), and then every loop is re-labelled at the nominal threshold. This keeps the
//! back-end's cost per loop change flat as a mission grows ([`crate::incremental`]).

use crate::error::PgoError;
use crate::gnc::{GncOutcome, GncSettings, graduate_free, polish_settings, readmit, solve_start};
use crate::group::PoseGroup;
use crate::lm::{FixedWeights, SystemCache, optimize};
use crate::problem::Problem;
use crate::region::region_around;

/// GNC-TLS warm-started from an earlier solution.
/// Loops that carry an earlier label in `earlier` (by factor) keep it while the loops new since then
/// graduate at `threshold_squared` (the earlier run's, variance factor included) from the current
/// poses; then every loop is re-labelled against the nominal threshold until no label changes, as after
/// a full run, so new evidence can still overturn an earlier label.
///
/// With a [`WarmRegion`], the new loops graduate with only the poses within that many factors of their
/// ends free ([`crate::region`]), and the whole graph then takes their labels in one refinement. If a
/// new loop ends there as an outlier, a loop must never be rejected only because the region was too
/// small to bend to it: the warm run is done again over the whole graph from the same start, or, when
/// the caller settles such a rejection by a full run anyway ([`WarmRegion::whole_graph_on_rejection`]
/// false), the region's labels are returned with the poses put back, and the caller runs it.
pub fn gnc_tls_warm<G: PoseGroup<D>, const D: usize>(
    problem: &mut Problem<G, D>,
    settings: &GncSettings,
    threshold_squared: f64,
    earlier: &[Option<f64>],
    region: Option<WarmRegion>,
    cache: &mut SystemCache<D>,
) -> Result<GncOutcome, PgoError> {
    settings.check()?;
    if earlier.len() != problem.factors.len() || !(threshold_squared.is_finite() && threshold_squared > 0.0) {
        return Err(PgoError::Option(
            "a warm GNC start needs one earlier label per factor and a positive threshold".into(),
        ));
    }
    let mut weights = vec![1.0; problem.factors.len()];
    let mut free = vec![false; problem.factors.len()];
    for (k, factor) in problem.factors.iter().enumerate() {
        if factor.robust {
            match earlier[k] {
                Some(label) => weights[k] = label,
                None => free[k] = true,
            }
        }
    }
    if let Some(WarmRegion {
        hops,
        whole_graph_on_rejection,
    }) = region
    {
        let region = region_around(problem, &free, &weights, hops);
        let free_poses = |fixed: &[bool]| fixed.iter().filter(|f| !**f).count();
        let everywhere = free_poses(&problem.fixed);
        let fixed_outside: Vec<bool> = problem
            .fixed
            .iter()
            .zip(&region)
            .map(|(f, inside)| *f || !inside)
            .collect();
        let inside = free_poses(&fixed_outside);
        if inside < everywhere {
            let (whole_fixed, start_poses) = (
                std::mem::replace(&mut problem.fixed, fixed_outside),
                problem.poses.clone(),
            );
            // The region's structure changes with every call: its own cache, the whole graph's kept.
            let local = graduate_warm(
                problem,
                settings,
                threshold_squared,
                &weights,
                &free,
                &mut SystemCache::default(),
            );
            problem.fixed = whole_fixed;
            let mut outcome = local?;
            let rejected_new = free
                .iter()
                .zip(&outcome.weights)
                .any(|(is_new, w)| *is_new && *w == 0.0);
            if !rejected_new {
                let whole = optimize(
                    problem,
                    &FixedWeights(&outcome.weights),
                    &polish_settings(&settings.inner),
                    cache,
                )?;
                outcome.total_iterations += whole.iterations;
                outcome.factorizations += whole.factorizations;
                outcome.last = whole;
                outcome.region_poses = Some(inside);
                readmit(problem, settings, &mut outcome, cache)?;
                return Ok(outcome);
            }
            problem.poses = start_poses;
            if !whole_graph_on_rejection {
                outcome.region_poses = Some(inside);
                return Ok(outcome);
            }
        }
    }
    let mut outcome = graduate_warm(problem, settings, threshold_squared, &weights, &free, cache)?;
    readmit(problem, settings, &mut outcome, cache)?;
    Ok(outcome)
}

/// The region a warm run graduates its new loops over first.
#[derive(Clone, Copy, Debug)]
pub struct WarmRegion {
    /// Poses within this many factors of a new loop's ends are free.
    pub hops: usize,
    /// When a new loop ends as an outlier in the region: run the warm start again over the whole graph
    /// (true), or return the region's labels with the poses as they were (false).
    pub whole_graph_on_rejection: bool,
}

/// The graduated part of a warm run: the start's solve, then the loops marked `free` graduating at
/// `threshold_squared` while the others keep the weight `weights` gives them.
fn graduate_warm<G: PoseGroup<D>, const D: usize>(
    problem: &mut Problem<G, D>,
    settings: &GncSettings,
    threshold_squared: f64,
    weights: &[f64],
    free: &[bool],
    cache: &mut SystemCache<D>,
) -> Result<GncOutcome, PgoError> {
    let start = solve_start(problem, settings, cache, weights, free)?;
    let mut outcome = graduate_free(
        problem,
        settings,
        threshold_squared,
        cache,
        weights.to_vec(),
        free,
        &start,
    )?;
    outcome.total_iterations += start.solve.iterations;
    outcome.factorizations += start.solve.factorizations;
    Ok(outcome)
}

#[cfg(test)]
mod tests {
    use super::{WarmRegion, gnc_tls_warm};
    use crate::gnc::tests::two_laps;
    use crate::gnc::{GncSettings, gnc_tls, strict_threshold};
    use crate::lm::SystemCache;

    #[test]
    fn new_loops_graduated_over_their_region_end_where_the_whole_graph_does() {
        // The laps' loops but one (and the wrong one) solved first; the one left out comes back as new,
        // alone and then with the wrong loop.
        let (mut problem, wrong) = two_laps();
        let new_loop = wrong - 4;
        let wrong_factor = problem.factors.remove(wrong);
        let new_factor = problem.factors.remove(new_loop);
        let settings = GncSettings::default();
        let first = gnc_tls(&mut problem, &settings, &mut SystemCache::default()).expect("GNC runs");
        let threshold = strict_threshold(&first, settings.threshold_squared);
        let solved = problem.clone();
        let earlier: Vec<Option<f64>> = problem
            .factors
            .iter()
            .zip(&first.weights)
            .map(|(f, w)| f.robust.then_some(*w))
            .collect();
        for (added, with_wrong) in [
            (vec![new_factor.clone()], false),
            (vec![new_factor, wrong_factor], true),
        ] {
            let mut grown = solved.clone();
            grown.factors.extend(added.iter().cloned());
            let mut labels = earlier.clone();
            labels.extend(added.iter().map(|_| None));
            let run = |region: Option<WarmRegion>| {
                let mut problem = grown.clone();
                let outcome = gnc_tls_warm(
                    &mut problem,
                    &settings,
                    threshold,
                    &labels,
                    region,
                    &mut SystemCache::default(),
                )
                .expect("a warm run");
                (problem, outcome)
            };
            let region = |whole_graph_on_rejection| {
                Some(WarmRegion {
                    hops: 1,
                    whole_graph_on_rejection,
                })
            };
            let (whole, whole_outcome) = run(None);
            let (local, local_outcome) = run(region(true));
            assert_eq!(
                local_outcome.weights, whole_outcome.weights,
                "wrong loop added: {with_wrong}"
            );
            assert_eq!(whole_outcome.weights.last() == Some(&0.0), with_wrong);
            if with_wrong {
                assert_eq!(
                    local_outcome.region_poses, None,
                    "a rejected new loop is judged over the whole graph"
                );
            } else {
                let region = local_outcome.region_poses.expect("graduated over the region");
                assert!(region < 10, "{region} poses free of {}", grown.poses.len() - 1);
            }
            for (a, b) in local.poses.iter().zip(&whole.poses) {
                assert!((a.translation.vector - b.translation.vector).norm() < 1e-4);
            }
            // A caller that settles a rejection by a full run gets the region's verdict and the start back.
            let (stopped, outcome) = run(region(false));
            if with_wrong {
                assert_eq!(
                    outcome.weights.last(),
                    Some(&0.0),
                    "the region rejects the wrong loop"
                );
                assert!(outcome.region_poses.is_some());
                for (a, b) in stopped.poses.iter().zip(&grown.poses) {
                    assert_eq!(
                        a.translation.vector, b.translation.vector,
                        "the start is put back"
                    );
                }
            } else {
                assert_eq!(outcome.weights, local_outcome.weights);
            }
        }
    }
}
