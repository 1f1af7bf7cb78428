//! `cargo xtask bench place-recognition`: precision-recall of SOLiD (Kim et al., RA-L 2024, also
//! u16/u8-quantised), Scan Context (Kim & Kim, IROS 2018) and LiDAR-Iris (Wang et al., IROS 2020) on
//! simulated three-robot runs in the planetary, cave and urban worlds with an HDL-64E, and in the urban
//! world with a narrow-FOV Livox-Avia-like sensor (see `skid_bench::place_recognition` for the
//! protocol); plus extraction and query times, bytes per keyframe, and query time over 10,000 stored
//! descriptors.

use anyhow::Result;
use clap::Parser;
use skid_bench::place_recognition::{PrRow, PrSettings, protocol_note, run_case};
use skid_bench::stats::time_ms;
use skid_bench::{BenchArgs, Report, Timing, append_markdown};
use skid_core::KeyframeId;
use skid_core::slots::{Descriptor, DescriptorBuf};
use skid_descriptor_scan_context::{ScanContextConfig, ScanContextDescriptor};
use skid_descriptor_solid::{SolidConfig, SolidDescriptor};

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

/// Query time over `size` stored descriptors made from `pool` with small multiplicative noise.
fn scaling(
    name: &str,
    descriptor: impl Descriptor,
    pool: &[DescriptorBuf],
    size: usize,
    k: usize,
) -> Result<PrRow> {
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
    Ok(PrRow {
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

fn main() -> Result<()> {
    let args = Args::parse();
    let out = &args.bench.out;
    std::fs::create_dir_all(out)?;
    let settings = PrSettings {
        route_m: args.route_m,
        keyframe_every_m: args.keyframe_every_m,
        match_m: args.match_m,
        exclude_s: args.exclude_s,
        narrow_max_yaw_deg: args.narrow_max_yaw_deg,
        seed: args.seed,
        ..PrSettings::default()
    };
    let mut report = Report::new("place-recognition");
    let (mut plots, mut solid_pool, mut scan_context_pool) = (Vec::new(), Vec::new(), Vec::new());
    for case in &settings.cases {
        let outcome = run_case(&settings, case, out, &mut report)?;
        plots.push(outcome.plot_markdown);
        if case.narrow {
            continue;
        }
        for (name, descriptors) in outcome.descriptors {
            match name.as_str() {
                "solid" => solid_pool.extend(descriptors.into_iter().flatten()),
                "scan_context" => scan_context_pool.extend(descriptors.into_iter().flatten()),
                _ => {}
            }
        }
    }
    if !solid_pool.is_empty() {
        for k in [1, 50] {
            let descriptor = SolidDescriptor::new(SolidConfig::default())?;
            report.push(&scaling("solid", descriptor, &solid_pool, args.scale_size, k)?)?;
        }
    }
    if !scan_context_pool.is_empty() {
        let descriptor = ScanContextDescriptor::new(ScanContextConfig::default())?;
        report.push(&scaling(
            "scan_context",
            descriptor,
            &scan_context_pool,
            args.scale_size,
            1,
        )?)?;
    }
    report.write(out)?;
    append_markdown(
        out,
        &format!("\n{}\n\n{}", protocol_note(&settings), plots.join("\n")),
    )?;
    Ok(())
}
