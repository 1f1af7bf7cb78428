//! Simulator benchmark: world generation time, then scans per second and milliseconds per scan for
//! every sensor in every world, on one thread and on all available threads.
//!
//! Run with `cargo run --release -p skid-sim --bin sim-bench [-- SCANS [WORLD|SENSOR...]]`.

use std::time::Instant;

use skid_sim::{SENSOR_NAMES, SimConfig, SimSource, World, WorldKind};

/// CPU time of the calling thread in seconds (Linux `schedstat`), so the single-thread figures stay
/// meaningful on a busy machine; `None` elsewhere.
fn thread_cpu_s() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let nanos: f64 = text.split_whitespace().next()?.parse().ok()?;
    Some(nanos * 1e-9)
}

fn main() {
    // `cargo xtask bench sim` passes `--out DIR` to every profile; this one only prints its table.
    let mut raw: Vec<String> = std::env::args().skip(1).collect();
    if let Some(at) = raw.iter().position(|a| a == "--out") {
        raw.drain(at..(at + 2).min(raw.len()));
    }
    let mut args = raw.into_iter();
    let scans: u32 = args.next().and_then(|a| a.parse().ok()).unwrap_or(20);
    let names: Vec<String> = args.collect();
    let worlds: Vec<WorldKind> = {
        let named: Vec<WorldKind> = names.iter().filter_map(|a| a.parse().ok()).collect();
        if named.is_empty() {
            WorldKind::ALL.to_vec()
        } else {
            named
        }
    };
    let sensors: Vec<&str> = {
        let named: Vec<&str> = SENSOR_NAMES
            .iter()
            .copied()
            .filter(|s| names.iter().any(|n| n == s))
            .collect();
        if named.is_empty() {
            SENSOR_NAMES.to_vec()
        } else {
            named
        }
    };
    let threads = std::thread::available_parallelism().map_or(1, usize::from);
    println!(
        "{:<10} {:<8} {:>7} {:>9} {:>10} {:>10} {:>12} {:>12}",
        "world", "sensor", "threads", "rays", "points", "ms/scan", "scans/s", "cpu ms/scan"
    );
    for kind in worlds {
        let start = Instant::now();
        let world = World::shared(kind, 7);
        println!(
            "# {kind}: generated in {:.2} s, {} object triangles{}",
            start.elapsed().as_secs_f64(),
            world.triangle_count(),
            world
                .rms_slope_deg(20.0, 1.0)
                .map(|slope| format!(", RMS slope {slope:.1}° (1 m baseline, within 20 m of the lanes)"))
                .unwrap_or_default()
        );
        for &sensor in &sensors {
            for threads in [1, threads] {
                let config = SimConfig {
                    world: kind.name().to_owned(),
                    sensor: sensor.to_owned(),
                    frames: scans + 60,
                    ..SimConfig::default()
                };
                let mut source = match SimSource::new(&config, 0, threads) {
                    Ok(source) => source,
                    Err(error) => {
                        eprintln!("{kind}/{sensor}: {error}");
                        continue;
                    }
                };
                // Skip the standing start so the robot is moving, then time `scans` scans.
                source.skip_scans(60);
                let start = Instant::now();
                let cpu_start = thread_cpu_s();
                let (mut count, mut points) = (0u32, 0usize);
                for scan in source.by_ref().take(scans as usize) {
                    count += 1;
                    points += scan.points.len();
                }
                let seconds = start.elapsed().as_secs_f64();
                // Thread CPU time is only the whole cost when the scan ran on this thread.
                let cpu_ms = match (threads, cpu_start, thread_cpu_s()) {
                    (1, Some(a), Some(b)) => format!("{:.2}", (b - a) * 1e3 / f64::from(count.max(1))),
                    _ => "-".to_owned(),
                };
                let rays = source.sensor().rays_per_sweep();
                println!(
                    "{:<10} {:<8} {:>7} {:>9} {:>10} {:>10.2} {:>12.1} {:>12}",
                    kind.name(),
                    sensor,
                    threads,
                    rays,
                    points / count.max(1) as usize,
                    seconds * 1e3 / f64::from(count.max(1)),
                    f64::from(count) / seconds,
                    cpu_ms
                );
            }
        }
    }
}
