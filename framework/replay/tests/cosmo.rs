//! The replay on a real COSMO-Bench problem (`cosmo_bench/tuhh_r3_00_day_wifi.jrl` of the shared data
//! folder: three robots of the MCD TUHH recording, 742 loop closures of which 73 are labelled wrong)
//! with SKiD's default verifier and back-end (PCM, then GNC-TLS in `pgo`): the problem's counts match the
//! file's own labels, both modes run through the first half of the recording, and what they report adds
//! up.

#![allow(clippy::unwrap_used, clippy::expect_used)] // Test code fails loudly by design.

use skid_backend_pgo::{PgoBackend, PgoConfig, RobustMode};
use skid_core::slots::{Backend, OptimizeBudget, Verifier};
use skid_core::{PluginContext, PluginResult, RobotId};
use skid_replay::problem::{Item, LoopLabel};
use skid_replay::{PluginFactory, ReplayMode, ReplayProblem, ReplayReport};
use skid_verifier_pcm::{PcmConfig, PcmVerifier};

/// The default configuration's verifier and back-end; `distributed` as each mode needs, and whether
/// the fleet shares its loops (`loops.fleet_loops`).
struct Defaults {
    distributed: bool,
    fleet_loops: bool,
}

impl PluginFactory for Defaults {
    fn verifier(&self, _robot: RobotId) -> PluginResult<Box<dyn Verifier>> {
        Ok(Box::new(PcmVerifier::new(PcmConfig::default())?))
    }

    fn backend(&self, robot: RobotId) -> PluginResult<Box<dyn Backend>> {
        let config = PgoConfig {
            robust: RobustMode::Gnc,
            distributed: self.distributed,
            ..PgoConfig::default()
        };
        let context = PluginContext {
            robot,
            ..PluginContext::default()
        };
        Ok(Box::new(PgoBackend::new(config, &context)?))
    }

    fn fleet_loops(&self) -> bool {
        self.fleet_loops
    }
}

fn problem() -> ReplayProblem {
    let path = skid_io::data_path("cosmo_bench/tuhh_r3_00_day_wifi.jrl").unwrap_or_else(|e| panic!("{e}"));
    ReplayProblem::from_dataset(&skid_io::jrl::read_jrl(&path).unwrap()).unwrap()
}

/// The file's own labels, read through the reader and the problem's conversion: 742 loop closures, 741
/// of them possibly wrong and 73 labelled wrong; 384 inter-robot factors, one of which the file does not
/// list as possibly wrong.
#[test]
fn the_problem_holds_every_loop_of_the_file_with_its_label() {
    let problem = problem();
    assert_eq!(problem.robots.len(), 3);
    let labels: Vec<(bool, LoopLabel)> = problem
        .events
        .iter()
        .flat_map(|event| &event.items)
        .filter_map(|item| match item {
            Item::Loop { closure, label } => Some((closure.is_inter_robot(), *label)),
            _ => None,
        })
        .collect();
    let known_inliers = labels
        .iter()
        .filter(|(_, label)| !label.potential_outlier)
        .count();
    let inter = labels.iter().filter(|(inter, _)| *inter).count();
    assert_eq!((labels.len(), known_inliers, inter), (742, 1, 384));
    assert_eq!(labels.iter().filter(|(_, label)| label.outlier).count(), 73);
    assert_eq!(problem.labels.len(), 742);
    assert_eq!(problem.labels.values().filter(|label| label.outlier).count(), 73);
}

/// What a replay of `problem` reports adds up: every loop of the problem is counted once with its label,
/// every true loop is kept or dropped, and every robot's keyframes are estimated.
fn check(report: &ReplayReport, problem: &ReplayProblem) {
    let (intra, inter) = (&report.intra, &report.inter);
    let loops = |inter_robot: bool| {
        problem
            .events
            .iter()
            .flat_map(|event| &event.items)
            .filter(
                |item| matches!(item, Item::Loop { closure, .. } if closure.is_inter_robot() == inter_robot),
            )
            .count()
    };
    assert_eq!((intra.loops, inter.loops), (loops(false), loops(true)));
    assert!(intra.labelled_outliers > 0 && inter.labelled_outliers > 0);
    for counts in [intra, inter] {
        assert!(counts.kept <= counts.accepted && counts.accepted <= counts.loops);
        assert_eq!(
            counts.kept - counts.outliers_kept + counts.inliers_dropped,
            counts.loops - counts.labelled_outliers,
            "every true loop is kept or dropped"
        );
        assert_eq!(
            counts.inliers_dropped_by.values().sum::<usize>(),
            counts.inliers_dropped,
            "every true loop dropped is dropped somewhere: {:?}",
            counts.inliers_dropped_by
        );
        assert!(counts.inliers_dropped_by.get("undecided").copied().unwrap_or(0) <= counts.undecided);
        assert!(
            !counts.inliers_dropped_by.contains_key("other"),
            "{:?}",
            counts.inliers_dropped_by
        );
    }
    assert_eq!(report.robots.len(), 3);
    for (index, robot) in report.robots.iter().enumerate() {
        let keyframes = problem
            .events
            .iter()
            .filter(|event| event.robot.0 as usize == index)
            .flat_map(|event| &event.items)
            .filter(|item| matches!(item, Item::Keyframe { .. }))
            .count();
        assert_eq!(robot.keyframes, keyframes, "robot {}", robot.robot);
        assert!(robot.ate_m.is_finite() && robot.ate_aligned_m.is_finite());
    }
}

#[test]
fn both_modes_replay_a_real_problem_and_account_for_every_loop() {
    // The first half of the recording: hundreds of loops of every kind, labelled outliers among them,
    // and a few seconds to replay (the whole problem is the benchmark's).
    let mut problem = problem();
    problem.events.truncate(problem.events.len() / 2);
    for (mode, distributed) in [(ReplayMode::Batch, false), (ReplayMode::Incremental, true)] {
        // The incremental mode shares the fleet's loops, as `skid run` does by default.
        let fleet_loops = distributed;
        let outcome = skid_replay::replay(
            &problem,
            mode,
            &Defaults {
                distributed,
                fleet_loops,
            },
            OptimizeBudget::default(),
        )
        .unwrap();
        // One latency per update: the slowest robot's share, which the robots' work summed bounds.
        assert_eq!(outcome.slowest_robot_update_ms.len(), outcome.update_ms.len());
        for (slowest_ms, summed_ms) in outcome.slowest_robot_update_ms.iter().zip(&outcome.update_ms) {
            assert!(
                *slowest_ms >= 0.0 && slowest_ms <= summed_ms,
                "{slowest_ms} ms of {summed_ms} ms"
            );
        }
        let report = ReplayReport::new(&problem, &outcome);
        check(&report, &problem);
        eprintln!("{}", serde_json::to_string(&report).unwrap());
    }
}

#[test]
fn an_accepted_loop_reaches_every_graph_when_the_fleet_shares_its_loops() {
    // The first quarter of the recording: enough loops of every kind, a few seconds to replay.
    let mut problem = problem();
    problem.events.truncate(problem.events.len() / 4);
    let inter_robot: std::collections::BTreeMap<_, bool> = problem
        .events
        .iter()
        .flat_map(|event| &event.items)
        .filter_map(|item| match item {
            Item::Loop { closure, .. } => Some((closure.id, closure.is_inter_robot())),
            _ => None,
        })
        .collect();
    for fleet_loops in [false, true] {
        let plugins = Defaults {
            distributed: true,
            fleet_loops,
        };
        let outcome = skid_replay::replay(
            &problem,
            ReplayMode::Incremental,
            &plugins,
            OptimizeBudget::default(),
        )
        .unwrap();
        let mut held = [0_usize; 2];
        for (id, fate) in outcome.loops.iter().filter(|(_, fate)| fate.accepted) {
            let inter = inter_robot[id];
            let robots_joined = if inter { 2 } else { 1 };
            let expected = if fleet_loops { 3 } else { robots_joined };
            assert_eq!(
                fate.held_in, expected,
                "loop {id:?} (inter-robot: {inter}), fleet_loops = {fleet_loops}"
            );
            held[usize::from(inter)] += 1;
        }
        assert!(
            held[0] > 0 && held[1] > 0,
            "intra and inter loops accepted: {held:?}"
        );
    }
}
