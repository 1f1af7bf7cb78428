//! `cargo xtask bench place-recognition`: precision-recall of the three place-recognition descriptors —
//! SOLiD (Kim et al., RA-L 2024, also u16/u8-quantised), Scan Context (Kim & Kim, IROS 2018) and
//! LiDAR-Iris (Wang et al., IROS 2020) — on simulated three-robot runs (leader, reverse-direction and
//! same-direction overlaps) in the planetary, cave and urban worlds with an HDL-64E, and in the urban
//! world with a narrow-FOV Livox-Avia-like sensor; plus extraction and query times, bytes per keyframe,
//! and query time over 10,000 stored descriptors.
//!
//! Protocol: a keyframe every `--keyframe-every-m` metres of each robot's route; every keyframe queries
//! an index holding all keyframes of all robots, with the querying robot's own keyframes within
//! `--exclude-s` seconds excluded; its best candidate is a true match when the ground-truth positions
//! are within `--match-m` metres (and, for the narrow-FOV sensor, the headings within
//! `--narrow-max-yaw-deg`, since a 70° sensor facing the other way sees another place). The PR curve
//! sweeps the distance threshold (skid-eval's counting: FN = queries with a match not found).

use std::path::Path;

use anyhow::{Context, Result};
use clap::Parser;
use serde::Serialize;
use skid_bench::stats::time_ms;
use skid_bench::{BenchArgs, Report, Timing};
use skid_core::slots::{Descriptor, DescriptorBuf};
use skid_core::{KeyframeId, Pose};
use skid_descriptor_iris::{IrisConfig, IrisDescriptor};
use skid_descriptor_scan_context::{ScanContextConfig, ScanContextDescriptor};
use skid_descriptor_solid::{Quantization, SolidConfig, SolidDescriptor};
use skid_eval::plot::{PlotOptions, pr_curve_plot};
use skid_eval::{PrCurve, ScoredCandidate, pr_curve};
use skid_sim::{SimConfig, SimSource};

#[derive(Parser, Debug)]
struct Args {
    #[command(flatten)]
    bench: BenchArgs,
    /// Route length per robot, in metres.
    #[arg(long, default_value_t = 300.0)]
    route_m: f64,
    /// Distance travelled between keyframes, in metres.
    #[arg(long, default_value_t = 2.0)]
    keyframe_every_m: f64,
    /// A candidate within this ground-truth distance is a true match.
    #[arg(long, default_value_t = 5.0)]
    match_m: f64,
    /// A robot's own keyframes closer in time than this are not candidates.
    #[arg(long, default_value_t = 30.0)]
    exclude_s: f64,
    /// Narrow-FOV case: a true match must also face within this yaw difference.
    #[arg(long, default_value_t = 35.0)]
    narrow_max_yaw_deg: f64,
    /// Stored descriptors for the query-time scaling test.
    #[arg(long, default_value_t = 10_000)]
    scale_size: usize,
    /// Seed of the worlds and routes.
    #[arg(long, default_value_t = 7)]
    seed: u64,
}

/// One simulated world and sensor.
struct Case {
    name: &'static str,
    world: &'static str,
    sensor: &'static str,
    /// Vertical FOV of the sensor for SOLiD, degrees.
    fov_deg: (f64, f64),
    narrow: bool,
}

const CASES: &[Case] = &[
    Case {
        name: "planetary/hdl64e",
        world: "planetary",
        sensor: "hdl64e",
        fov_deg: (-24.8, 2.0),
        narrow: false,
    },
    Case {
        name: "cave/hdl64e",
        world: "cave",
        sensor: "hdl64e",
        fov_deg: (-24.8, 2.0),
        narrow: false,
    },
    Case {
        name: "urban/hdl64e",
        world: "urban",
        sensor: "hdl64e",
        fov_deg: (-24.8, 2.0),
        narrow: false,
    },
    Case {
        name: "urban/avia",
        world: "urban",
        sensor: "avia",
        fov_deg: (-38.6, 38.6),
        narrow: true,
    },
];

/// A keyframe with its ground truth.
struct Keyframe {
    id: KeyframeId,
    time_s: f64,
    pose: Pose,
}

#[derive(Serialize)]
struct Row {
    case: String,
    descriptor: String,
    keyframes: usize,
    positives: usize,
    max_f1: f64,
    recall_at_100_precision: f64,
    average_precision: f64,
    bytes_per_keyframe: usize,
    extract_ms_median: f64,
    query_ms_median: f64,
    stored: usize,
    yaw_error_deg_median: f64,
    yaw_error_deg_p90: f64,
    /// True top-1 matches between keyframes facing more than 135° apart (reverse revisits).
    reverse_true_matches: usize,
    mean_points_per_scan: usize,
}

/// A descriptor under test: its label, the plugin, and its size on the wire in bytes.
type Variant = (String, Box<dyn Descriptor>, usize);

fn variants(case: &Case) -> Result<Vec<Variant>> {
    let solid = |quantization| SolidConfig {
        lower_fov_deg: case.fov_deg.0,
        upper_fov_deg: case.fov_deg.1,
        quantization,
        ..SolidConfig::default()
    };
    let mut out: Vec<(String, Box<dyn Descriptor>, usize)> = Vec::new();
    let variants = [
        ("solid", Quantization::None, 0.4),
        ("solid-u16", Quantization::U16, 0.4),
        ("solid-u8", Quantization::U8, 0.4),
        ("solid-no-voxel", Quantization::None, 0.0),
    ];
    for (name, q, voxel_size_m) in variants {
        let config = SolidConfig {
            voxel_size_m,
            ..solid(q)
        };
        let bytes = config.wire_size_bytes();
        out.push((name.to_owned(), Box::new(SolidDescriptor::new(config)?), bytes));
    }
    let sc = ScanContextConfig::default();
    out.push((
        "scan_context".to_owned(),
        Box::new(ScanContextDescriptor::new(sc.clone())?),
        sc.wire_size_bytes(),
    ));
    let iris = IrisConfig::default();
    out.push((
        "iris".to_owned(),
        Box::new(IrisDescriptor::new(iris.clone())?),
        iris.wire_size_bytes(),
    ));
    Ok(out)
}

fn yaw_of(pose: &Pose) -> f64 {
    pose.rotation.euler_angles().2
}

fn angle_difference_deg(a_rad: f64, b_rad: f64) -> f64 {
    let d = (a_rad - b_rad).to_degrees().rem_euclid(360.0);
    d.min(360.0 - d)
}

fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// Descriptors kept for the scaling test: SOLiD's and Scan Context's of every keyframe.
#[derive(Default)]
struct Pools {
    solid: Vec<DescriptorBuf>,
    scan_context: Vec<DescriptorBuf>,
}

fn run_case(
    args: &Args,
    case: &Case,
    report: &mut Report,
    plots: &mut Vec<String>,
    pools: &mut Pools,
) -> Result<()> {
    let threads = std::thread::available_parallelism().map_or(1, usize::from);
    let config = SimConfig {
        world: case.world.to_owned(),
        sensor: case.sensor.to_owned(),
        seed: args.seed,
        robots: 3,
        route_length_m: args.route_m,
        imu: false,
        ..SimConfig::default()
    };
    let mut variants = variants(case)?;
    let mut keyframes = Vec::new();
    let mut descriptors: Vec<Vec<Option<DescriptorBuf>>> = vec![Vec::new(); variants.len()];
    let mut extract_ms: Vec<Vec<f64>> = vec![Vec::new(); variants.len()];
    let mut points_total = 0usize;
    for robot in 0..config.robots {
        let source =
            SimSource::new(&config, robot, threads).with_context(|| format!("simulating {}", case.name))?;
        let mut last: Option<Pose> = None;
        let mut index = 0u32;
        for sequence in 0..source.scan_count() {
            let stamp_s = SimSource::stamp_nanos(sequence) as f64 * 1e-9;
            let pose = source.trajectory().pose_at(stamp_s);
            if last.is_some_and(|l| {
                (l.translation.vector - pose.translation.vector).norm() < args.keyframe_every_m
            }) {
                continue;
            }
            last = Some(pose);
            let scan = source.scan_at(sequence);
            let cloud = scan.cloud();
            points_total += cloud.len();
            for (v, (_, descriptor, _)) in variants.iter_mut().enumerate() {
                let (described, ms) = time_ms(|| descriptor.describe(cloud.view()));
                extract_ms[v].push(ms);
                descriptors[v].push(described.ok());
            }
            keyframes.push(Keyframe {
                id: KeyframeId::new(robot, index),
                time_s: stamp_s,
                pose: scan.ground_truth_world_from_sensor.unwrap_or(pose),
            });
            index += 1;
        }
        eprintln!(
            "{}: robot {robot} ({:?}) {index} keyframes",
            case.name,
            source.route().overlap
        );
    }
    let n = keyframes.len();
    let excluded =
        |q: &Keyframe, c: &Keyframe| q.id.robot == c.id.robot && (q.time_s - c.time_s).abs() < args.exclude_s;
    let matches = |q: &Keyframe, c: &Keyframe| {
        (q.pose.translation.vector - c.pose.translation.vector).norm() <= args.match_m
            && (!case.narrow
                || angle_difference_deg(yaw_of(&q.pose), yaw_of(&c.pose)) <= args.narrow_max_yaw_deg)
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
        report.push(&Row {
            case: case.name.to_owned(),
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
    if !case.narrow {
        pools.solid.extend(descriptors[0].iter().flatten().cloned());
        pools
            .scan_context
            .extend(descriptors[4].iter().flatten().cloned());
    }
    let file = format!("pr-{}.png", case.name.replace('/', "-"));
    let named: Vec<(&str, &PrCurve)> = curves.iter().map(|(n, c)| (n.as_str(), c)).collect();
    let plot = pr_curve_plot(
        &args.bench.out.join(&file),
        &format!("PR {}", case.name),
        &named,
        &PlotOptions::default(),
    )?;
    plots.push(plot.markdown());
    Ok(())
}

/// Query time over `size` stored descriptors made from `pool` with small multiplicative noise.
fn scaling(
    name: &str,
    descriptor: impl Descriptor,
    pool: &[DescriptorBuf],
    size: usize,
    k: usize,
) -> Result<Row> {
    let mut index = descriptor.new_index();
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut noise = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        1.0 + 0.1 * ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) as f32
    };
    for i in 0..size {
        let base = &pool[i % pool.len()];
        let values = base.values.iter().map(|v| v * noise()).collect();
        index.insert(
            KeyframeId::new((i % 16) as u32, i as u32),
            DescriptorBuf {
                kind: base.kind.clone(),
                values,
            },
        )?;
    }
    let (_, build_ms) = time_ms(|| index.query(&pool[0], k, &|_| false));
    let mut times = Vec::new();
    for q in pool.iter().cycle().take(500) {
        let (found, ms) = time_ms(|| index.query(q, k, &|id| id.robot.0 == 3));
        found?;
        times.push(ms);
    }
    let timing = Timing::from_ms(&times);
    eprintln!(
        "{name}: {size} stored, first query (tree build) {build_ms:.2} ms, query k={k} median {:.3} ms, p90 {:.3} ms",
        timing.median_ms, timing.p90_ms
    );
    Ok(Row {
        case: format!("query over {size} (k={k}; first query with tree build {build_ms:.1} ms)"),
        descriptor: name.to_owned(),
        keyframes: 0,
        positives: 0,
        max_f1: f64::NAN,
        recall_at_100_precision: f64::NAN,
        average_precision: f64::NAN,
        bytes_per_keyframe: 0,
        extract_ms_median: f64::NAN,
        query_ms_median: timing.median_ms,
        stored: index.len(),
        yaw_error_deg_median: f64::NAN,
        yaw_error_deg_p90: f64::NAN,
        reverse_true_matches: 0,
        mean_points_per_scan: 0,
    })
}

fn append(path: &Path, text: &str) -> Result<()> {
    let mut table = std::fs::read_to_string(path).unwrap_or_default();
    table.push_str(text);
    std::fs::write(path, table).with_context(|| format!("writing {}", path.display()))
}

fn main() -> Result<()> {
    let args = Args::parse();
    std::fs::create_dir_all(&args.bench.out)?;
    let mut report = Report::new("place-recognition");
    let (mut plots, mut pools) = (Vec::new(), Pools::default());
    for case in CASES {
        run_case(&args, case, &mut report, &mut plots, &mut pools)?;
    }
    if !pools.solid.is_empty() {
        for k in [1, 50] {
            report.push(&scaling(
                "solid",
                SolidDescriptor::new(SolidConfig::default())?,
                &pools.solid,
                args.scale_size,
                k,
            )?)?;
        }
    }
    if !pools.scan_context.is_empty() {
        let descriptor = ScanContextDescriptor::new(ScanContextConfig::default())?;
        report.push(&scaling(
            "scan_context",
            descriptor,
            &pools.scan_context,
            args.scale_size,
            1,
        )?)?;
    }
    report.write(&args.bench.out)?;
    let notes = format!(
        "\nTrue match: ground-truth positions within {} m (narrow FOV: and headings within {}°); own keyframes within {} s excluded; one keyframe every {} m of {} m routes, 3 robots (leader, reverse, same direction). Times are single-threaded wall-clock medians (on a shared machine: upper bounds) per keyframe on the raw scan (`extract`) and per top-1 query over all keyframes of the case (`query`). NaN = not applicable.\n\n{}",
        args.match_m,
        args.narrow_max_yaw_deg,
        args.exclude_s,
        args.keyframe_every_m,
        args.route_m,
        plots.join("\n")
    );
    append(&args.bench.out.join("table.md"), &notes)?;
    Ok(())
}
