//! The SKiD-SLAM paper's scan-level registration table on simulated pairs (`skid-sim`): per world,
//! pairs along one route — same direction 10 m apart, reverse viewpoint 10 m apart, and partial overlap
//! 25 m apart — and per method RTE, RRE and success rate. Fine-only methods start from an
//! odometry-like prior (the truth off by a fixed-seed error of up to `prior_translation_m` horizontally
//! and `prior_yaw_deg` in yaw); coarse methods need no prior.

use anyhow::Result;
use nalgebra::{UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use skid_core::{Cloud, Pose};
use skid_eval::registration::RegistrationPair;
use skid_sim::motion::{MotionSpec, trajectory};
use skid_sim::{ScanNoise, Sensor, World, WorldKind, plan_route, simulate_sweep};

use super::{METHOD_NAMES, Methods, check_methods, summary};
use crate::Report;

/// Parameters of the simulated table.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimTableSettings {
    /// Threads every plugin may use.
    pub threads: usize,
    /// `planetary`, `cave`, `urban`.
    pub worlds: Vec<String>,
    pub sensor: String,
    /// Pairs per world and pair kind (three kinds).
    pub pairs_per_kind: usize,
    pub seed: u64,
    /// Error of the fine methods' prior: up to this much horizontally, metres ...
    pub prior_translation_m: f64,
    /// ... and this much in yaw, degrees.
    pub prior_yaw_deg: f64,
    pub methods: Vec<String>,
}

impl Default for SimTableSettings {
    fn default() -> Self {
        Self {
            threads: 2,
            worlds: ["planetary", "cave", "urban"].map(str::to_owned).to_vec(),
            sensor: "os1-64".to_owned(),
            pairs_per_kind: 4,
            seed: 7,
            prior_translation_m: 1.5,
            prior_yaw_deg: 20.0,
            // Every method but those the paper's table leaves out (RANSAC alone, GICP from the identity).
            methods: METHOD_NAMES
                .iter()
                .filter(|name| !matches!(**name, "RANSAC" | "GICP (identity)"))
                .map(|name| (*name).to_owned())
                .collect(),
        }
    }
}

/// A simulated scan pair: target, source and the true `target_from_source`.
pub struct SimPair {
    pub kind: &'static str,
    pub target: Cloud,
    pub source: Cloud,
    pub truth: Pose,
}

/// Pairs from one world: along one route, a target pose every ~70 m and a source pose 10 m (same
/// direction or turned around) or 25 m (partial overlap) further on.
pub fn sim_pairs(kind: WorldKind, sensor: &str, per_kind: usize, seed: u64) -> Result<Vec<SimPair>> {
    let world = World::generate(kind, seed);
    let sensor = Sensor::by_name(sensor)?;
    let route = plan_route(&world, seed, 0, 80.0 * per_kind as f64 + 60.0);
    let path = trajectory(&world, &route, &MotionSpec::default());
    // Poses every metre of travel, so "10 m further" is a distance along the route.
    let mut along: Vec<Pose> = Vec::new();
    let mut t = path.start_s();
    while t <= path.end_s() {
        let pose = path.pose_at(t);
        if along
            .last()
            .is_none_or(|last: &Pose| (pose.translation.vector - last.translation.vector).norm() >= 1.0)
        {
            along.push(pose);
        }
        t += 0.02;
    }
    let scan = |pose: &Pose, key: u64| -> Cloud {
        let pose = *pose;
        let points = simulate_sweep(
            &world,
            &sensor,
            &move |_| pose,
            0.0,
            &ScanNoise::default(),
            key,
            true,
        );
        Cloud::new(points.iter().map(|p| p.point()).collect())
    };
    let mut pairs = Vec::new();
    for k in 0..per_kind {
        let anchor = 20 + 70 * k;
        for (name, gap, turn) in [
            ("same direction 10 m", 10, false),
            ("reverse 10 m", 10, true),
            ("partial 25 m", 25, false),
        ] {
            let (Some(a), Some(b)) = (along.get(anchor), along.get(anchor + gap)) else {
                continue;
            };
            let b = if turn {
                b * UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::PI)
            } else {
                *b
            };
            let key = seed ^ ((k as u64) << 8) ^ u64::from(gap as u32) ^ u64::from(turn);
            pairs.push(SimPair {
                kind: name,
                target: scan(a, key),
                source: scan(&b, key ^ 0xabcd),
                truth: a.inverse() * b,
            });
        }
    }
    Ok(pairs)
}

/// A fixed pseudo-random number in [-1, 1) for pair `index` and `salt`.
fn unit(index: usize, salt: u64) -> f64 {
    let h = (index as u64 + 1).wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ salt.wrapping_mul(0xbf58_476d_1ce4_e5b9);
    ((h >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
}

/// Runs every method on every world's pairs and pushes one row per world and method into `report`.
pub fn sim_table(methods: &mut Methods, settings: &SimTableSettings, report: &mut Report) -> Result<()> {
    check_methods(&settings.methods)?;
    for world in &settings.worlds {
        let kind: WorldKind = world.parse()?;
        let pairs = sim_pairs(kind, &settings.sensor, settings.pairs_per_kind, settings.seed)?;
        let count = settings.methods.len();
        let mut estimates: Vec<Vec<RegistrationPair>> = vec![Vec::new(); count];
        let mut times: Vec<Vec<f64>> = vec![Vec::new(); count];
        let mut cpu: Vec<Vec<f64>> = vec![Vec::new(); count];
        for (index, pair) in pairs.iter().enumerate() {
            let prior = pair.truth
                * Pose::new(
                    Vector3::new(
                        settings.prior_translation_m * unit(index, 1),
                        settings.prior_translation_m * unit(index, 2),
                        0.0,
                    ),
                    Vector3::z() * settings.prior_yaw_deg.to_radians() * unit(index, 3),
                );
            for (m, method) in settings.methods.iter().enumerate() {
                let outcome = methods.run(method, &pair.target, &pair.source, &prior)?;
                estimates[m].push(RegistrationPair {
                    estimated: outcome.estimate,
                    ground_truth: pair.truth,
                });
                times[m].push(outcome.time_ms);
                cpu[m].extend(outcome.cpu_ms);
            }
            eprintln!("{kind}: pair {index} ({}) done", pair.kind);
        }
        for (m, method) in settings.methods.iter().enumerate() {
            report.push(&summary(
                &format!("sim {kind} ({} pairs)", pairs.len()),
                method,
                &estimates[m],
                &times[m],
                &cpu[m],
            )?)?;
        }
    }
    Ok(())
}
