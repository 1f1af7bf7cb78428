//! Precision-recall of place-recognition descriptors on simulated multi-robot runs, shared by the
//! `place-recognition` and `fig-pr-curves` profiles: SOLiD (Kim et al., RA-L 2024, also quantised),
//! Scan Context (Kim & Kim, IROS 2018) and LiDAR-Iris (Wang et al., IROS 2020), as in the SKiD-SLAM
//! paper's PR-curve figure.
//!
//! Protocol: a keyframe every `keyframe_every_m` metres of each robot's route; every keyframe queries an
//! index holding all keyframes of all robots, with the querying robot's own keyframes within `exclude_s`
//! seconds excluded; its best candidate is a true match when the ground-truth positions are within
//! `match_m` metres (and, for a narrow-FOV sensor, the headings within `narrow_max_yaw_deg`, since a 70°
//! sensor facing the other way sees another place). The PR curve sweeps the distance threshold
//! (skid-eval's counting: FN = queries with a match not found).

use std::path::Path;

use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use skid_core::slots::{Descriptor, DescriptorBuf};
use skid_core::{Cloud, KeyframeId, Pose};
use skid_descriptor_iris::{IrisConfig, IrisDescriptor};
use skid_descriptor_scan_context::{ScanContextConfig, ScanContextDescriptor};
use skid_descriptor_solid::{Quantization, SolidConfig, SolidDescriptor};
use skid_eval::plot::{PlotOptions, pr_curve_plot};
use skid_eval::{PrCurve, ScoredCandidate, pr_curve};
use skid_sim::{SimConfig, SimSource};

use crate::Timing;
use crate::stats::{median, time_ms};

/// One simulated world and sensor.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PrCase {
    pub name: String,
    pub world: String,
    pub sensor: String,
    /// Vertical field of view of the sensor for SOLiD, degrees.
    pub lower_fov_deg: f64,
    pub upper_fov_deg: f64,
    /// A narrow horizontal FOV: true matches must also face the same way.
    #[serde(default)]
    pub narrow: bool,
}

impl PrCase {
    /// The simulator's settings for this case: `robots` robots on `route_m`-metre routes, no IMU.
    pub fn sim_config(&self, seed: u64, robots: u32, route_m: f64) -> SimConfig {
        SimConfig {
            world: self.world.clone(),
            sensor: self.sensor.clone(),
            seed,
            robots,
            route_length_m: route_m,
            // The patterns around one shared route (leader, reverse, same direction, partial, ...):
            // every robot revisits the leader's road, so the curves have true matches of every kind.
            mission: skid_sim::Mission::SharedRoute,
            imu: false,
            ..SimConfig::default()
        }
    }

    fn new(world: &str, sensor: &str, fov_deg: (f64, f64), narrow: bool) -> Self {
        Self {
            name: format!("{world}/{sensor}"),
            world: world.to_owned(),
            sensor: sensor.to_owned(),
            lower_fov_deg: fov_deg.0,
            upper_fov_deg: fov_deg.1,
            narrow,
        }
    }
}

/// Parameters of a precision-recall run.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PrSettings {
    /// Robots per simulated run (leader, reverse, same direction, ...).
    pub robots: u32,
    /// Route length per robot, metres.
    pub route_m: f64,
    /// Distance travelled between keyframes, metres.
    pub keyframe_every_m: f64,
    /// A candidate within this ground-truth distance is a true match.
    pub match_m: f64,
    /// A robot's own keyframes closer in time than this are not candidates.
    pub exclude_s: f64,
    /// Narrow-FOV cases: a true match must also face within this yaw difference.
    pub narrow_max_yaw_deg: f64,
    /// Seed of the worlds and routes.
    pub seed: u64,
    /// Variants to compare: `solid`, `solid-u16`, `solid-u8`, `solid-no-voxel`, `scan_context`, `iris`.
    pub descriptors: Vec<String>,
    pub cases: Vec<PrCase>,
}

impl Default for PrSettings {
    fn default() -> Self {
        Self {
            robots: 3,
            route_m: 300.0,
            keyframe_every_m: 2.0,
            match_m: 5.0,
            exclude_s: 30.0,
            narrow_max_yaw_deg: 35.0,
            seed: 7,
            descriptors: [
                "solid",
                "solid-u16",
                "solid-u8",
                "solid-no-voxel",
                "scan_context",
                "iris",
            ]
            .map(str::to_owned)
            .to_vec(),
            cases: default_cases(),
        }
    }
}

/// Planetary, cave and urban with an HDL-64E, and urban with a narrow-FOV Livox-Avia-like sensor.
pub fn default_cases() -> Vec<PrCase> {
    vec![
        PrCase::new("planetary", "hdl64e", (-24.8, 2.0), false),
        PrCase::new("cave", "hdl64e", (-24.8, 2.0), false),
        PrCase::new("urban", "hdl64e", (-24.8, 2.0), false),
        PrCase::new("urban", "avia", (-38.6, 38.6), true),
    ]
}

/// A simulated keyframe: its id, time, ground-truth pose and raw cloud.
pub struct SimKeyframe {
    pub id: KeyframeId,
    pub time_s: f64,
    pub pose: Pose,
    pub cloud: Cloud,
}

/// Simulates robot `robot` of `config` and calls `visit` with a keyframe every `every_m` metres of its
/// ground-truth route; returns the number of keyframes.
pub fn for_each_keyframe(
    config: &SimConfig,
    robot: u32,
    every_m: f64,
    threads: usize,
    mut visit: impl FnMut(SimKeyframe) -> Result<()>,
) -> Result<u32> {
    let source = SimSource::new(config, robot, threads)
        .with_context(|| format!("simulating robot {robot} in {}", config.world))?;
    let mut last: Option<Pose> = None;
    let mut index = 0u32;
    for sequence in 0..source.scan_count() {
        let stamp_s = SimSource::stamp_nanos(sequence) as f64 * 1e-9;
        let pose = source.trajectory().pose_at(stamp_s);
        if last.is_some_and(|l| (l.translation.vector - pose.translation.vector).norm() < every_m) {
            continue;
        }
        last = Some(pose);
        let scan = source.scan_at(sequence);
        visit(SimKeyframe {
            id: KeyframeId::new(robot, index),
            time_s: stamp_s,
            pose: scan.ground_truth_world_from_sensor.unwrap_or(pose),
            cloud: scan.cloud(),
        })?;
        index += 1;
    }
    Ok(index)
}

/// One row of the precision-recall table.
#[derive(Serialize)]
pub struct PrRow {
    pub case: String,
    pub descriptor: String,
    pub keyframes: usize,
    pub positives: usize,
    pub max_f1: f64,
    pub recall_at_100_precision: f64,
    pub average_precision: f64,
    pub bytes_per_keyframe: usize,
    pub extract_ms_median: f64,
    pub query_ms_median: f64,
    pub stored: usize,
    pub yaw_error_deg_median: f64,
    pub yaw_error_deg_p90: f64,
    /// True top-1 matches between keyframes facing more than 135° apart (reverse revisits).
    pub reverse_true_matches: usize,
    pub mean_points_per_scan: usize,
}

/// A descriptor under test: its label, the plugin, and its size on the wire in bytes.
pub type Variant = (String, Box<dyn Descriptor>, usize);

/// The descriptor variants named in `names`, SOLiD set up for `case`'s vertical FOV.
pub fn variants(case: &PrCase, names: &[String]) -> Result<Vec<Variant>> {
    let mut out: Vec<Variant> = Vec::new();
    for name in names {
        let solid = |quantization, voxel_size_m| SolidConfig {
            lower_fov_deg: case.lower_fov_deg,
            upper_fov_deg: case.upper_fov_deg,
            quantization,
            voxel_size_m,
            ..SolidConfig::default()
        };
        let config = match name.as_str() {
            "solid" => solid(Quantization::None, 0.4),
            "solid-u16" => solid(Quantization::U16, 0.4),
            "solid-u8" => solid(Quantization::U8, 0.4),
            "solid-no-voxel" => solid(Quantization::None, 0.0),
            "scan_context" => {
                let sc = ScanContextConfig::default();
                let bytes = sc.wire_size_bytes();
                out.push((name.clone(), Box::new(ScanContextDescriptor::new(sc)?), bytes));
                continue;
            }
            "iris" => {
                let iris = IrisConfig::default();
                let bytes = iris.wire_size_bytes();
                out.push((name.clone(), Box::new(IrisDescriptor::new(iris)?), bytes));
                continue;
            }
            other => bail!(
                "unknown descriptor variant `{other}` (solid, solid-u16, solid-u8, solid-no-voxel, scan_context, iris)"
            ),
        };
        let bytes = config.wire_size_bytes();
        out.push((name.clone(), Box::new(SolidDescriptor::new(config)?), bytes));
    }
    Ok(out)
}

fn yaw_of(pose: &Pose) -> f64 {
    pose.rotation.euler_angles().2
}

fn angle_difference_deg(a_rad: f64, b_rad: f64) -> f64 {
    let d = (a_rad - b_rad).to_degrees().rem_euclid(360.0);
    d.min(360.0 - d)
}

/// What one case produced besides its rows: each variant's curve and descriptors.
pub struct CaseOutcome {
    pub curves: Vec<(String, PrCurve)>,
    /// Per variant, the descriptor of every keyframe (`None` where it could not be described).
    pub descriptors: Vec<(String, Vec<Option<DescriptorBuf>>)>,
    /// The case's PR plot as Markdown.
    pub plot_markdown: String,
}

/// Runs one case: simulates the robots, describes every keyframe with every variant, queries, pushes
/// one row per variant into `report` and writes `pr-<case>.png` into `out`.
pub fn run_case(
    settings: &PrSettings,
    case: &PrCase,
    out: &Path,
    report: &mut crate::Report,
) -> Result<CaseOutcome> {
    let threads = std::thread::available_parallelism().map_or(1, usize::from);
    let config = case.sim_config(settings.seed, settings.robots, settings.route_m);
    let mut variants = variants(case, &settings.descriptors)?;
    let mut keyframes: Vec<SimKeyframe> = Vec::new();
    let mut descriptors: Vec<Vec<Option<DescriptorBuf>>> = vec![Vec::new(); variants.len()];
    let mut extract_ms: Vec<Vec<f64>> = vec![Vec::new(); variants.len()];
    let mut points_total = 0usize;
    for robot in 0..config.robots {
        let count = for_each_keyframe(&config, robot, settings.keyframe_every_m, threads, |keyframe| {
            points_total += keyframe.cloud.len();
            for (v, (_, descriptor, _)) in variants.iter_mut().enumerate() {
                let (described, ms) = time_ms(|| descriptor.describe(keyframe.cloud.view()));
                extract_ms[v].push(ms);
                descriptors[v].push(described.ok());
            }
            // The cloud is not needed any more; keep the pose only.
            keyframes.push(SimKeyframe {
                cloud: Cloud::new(Vec::new()),
                ..keyframe
            });
            Ok(())
        })?;
        eprintln!("{}: robot {robot}: {count} keyframes", case.name);
    }
    let n = keyframes.len();
    let excluded = |q: &SimKeyframe, c: &SimKeyframe| {
        q.id.robot == c.id.robot && (q.time_s - c.time_s).abs() < settings.exclude_s
    };
    let matches = |q: &SimKeyframe, c: &SimKeyframe| {
        (q.pose.translation.vector - c.pose.translation.vector).norm() <= settings.match_m
            && (!case.narrow
                || angle_difference_deg(yaw_of(&q.pose), yaw_of(&c.pose)) <= settings.narrow_max_yaw_deg)
    };
    let has_match: Vec<bool> = keyframes
        .iter()
        .map(|q| keyframes.iter().any(|c| !excluded(q, c) && matches(q, c)))
        .collect();
    let position_of = |id: KeyframeId| keyframes.iter().position(|k| k.id == id);
    let mut curves: Vec<(String, PrCurve)> = Vec::new();
    for (v, (name, descriptor, bytes)) in variants.iter().enumerate() {
        let mut index = descriptor.new_index();
        for (k, d) in keyframes.iter().zip(&descriptors[v]) {
            if let Some(d) = d {
                index.insert(k.id, d.clone())?;
            }
        }
        let (mut scored, mut query_ms, mut yaw_errors) = (Vec::new(), Vec::new(), Vec::new());
        let mut reverse_true_matches = 0;
        for (q, query) in keyframes.iter().enumerate() {
            let best = match &descriptors[v][q] {
                Some(d) => {
                    let exclude =
                        |id: KeyframeId| position_of(id).is_none_or(|c| excluded(query, &keyframes[c]));
                    let (found, ms) = time_ms(|| index.query(d, 1, &exclude));
                    query_ms.push(ms);
                    found?.into_iter().next()
                }
                None => None,
            };
            let candidate = best.and_then(|b| position_of(b.id).map(|c| (b, c)));
            let (distance, is_true) = match candidate {
                Some((b, c)) => {
                    let is_true = matches(query, &keyframes[c]);
                    let truth = yaw_of(&(keyframes[c].pose.inverse() * query.pose));
                    if is_true && truth.abs().to_degrees() > 135.0 {
                        reverse_true_matches += 1;
                    }
                    if is_true && let Some(hint) = b.yaw_hint_rad {
                        yaw_errors.push(angle_difference_deg(hint, truth));
                    }
                    (b.distance, is_true)
                }
                None => (f64::MAX, false),
            };
            scored.push(ScoredCandidate {
                distance,
                is_true_match: is_true,
                query_has_match: has_match[q],
            });
        }
        let curve = pr_curve(&scored).with_context(|| format!("{} {name}: PR curve", case.name))?;
        report.push(&PrRow {
            case: case.name.clone(),
            descriptor: name.clone(),
            keyframes: n,
            positives: curve.positives,
            max_f1: curve.max_f1,
            recall_at_100_precision: curve.recall_at_full_precision,
            average_precision: curve.average_precision,
            bytes_per_keyframe: *bytes,
            extract_ms_median: median(&mut extract_ms[v]),
            query_ms_median: median(&mut query_ms),
            stored: index.len(),
            yaw_error_deg_median: median(&mut yaw_errors),
            yaw_error_deg_p90: Timing::from_ms(&yaw_errors).p90_ms,
            reverse_true_matches,
            mean_points_per_scan: points_total / n.max(1),
        })?;
        curves.push((name.clone(), curve));
    }
    let file = format!("pr-{}.png", case.name.replace('/', "-"));
    let named: Vec<(&str, &PrCurve)> = curves.iter().map(|(n, c)| (n.as_str(), c)).collect();
    let plot = pr_curve_plot(
        &out.join(&file),
        &format!("PR {}", case.name),
        &named,
        &PlotOptions::default(),
    )?;
    let names = variants.into_iter().map(|(name, _, _)| name);
    Ok(CaseOutcome {
        curves,
        descriptors: names.zip(descriptors).collect(),
        plot_markdown: plot.markdown(),
    })
}

/// The note under a precision-recall table: the protocol in one paragraph.
pub fn protocol_note(settings: &PrSettings) -> String {
    format!(
        "True match: ground-truth positions within {} m (narrow FOV: and headings within {}°); own keyframes within {} s excluded; one keyframe every {} m of {} m routes, {} robots (leader, reverse, same direction, ...). Times are single-threaded wall-clock medians (on a shared machine: upper bounds) per keyframe on the raw scan (`extract`) and per top-1 query over all keyframes of the case (`query`). – = not applicable.",
        settings.match_m,
        settings.narrow_max_yaw_deg,
        settings.exclude_s,
        settings.keyframe_every_m,
        settings.route_m,
        settings.robots,
    )
}
