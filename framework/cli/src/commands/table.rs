//! The short tables `skid run`, `skid odometry`, `skid pgo` and `skid eval` print on stderr for people,
//! while the JSON line on stdout stays for scripts.

use std::fmt::Write as _;

use skid_runtime::{FALSE_MERGE_DEG, FALSE_MERGE_M, LoopTruth, RunMetrics, RunSummary};

/// Prints a human summary on stderr, unless the log is quiet (`-q`, or `RUST_LOG` below info).
pub fn show(text: &str) {
    if tracing::enabled!(tracing::Level::INFO) {
        eprint!("{text}");
    }
}

/// Left-aligned text columns with a header row and a rule.
pub struct Table {
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl Table {
    pub fn new(header: &[&str]) -> Self {
        Self {
            header: header.iter().map(|h| (*h).to_owned()).collect(),
            rows: Vec::new(),
        }
    }

    pub fn row(&mut self, cells: Vec<String>) {
        self.rows.push(cells);
    }

    pub fn render(&self) -> String {
        let columns = self.header.len();
        let widths: Vec<usize> = (0..columns)
            .map(|c| {
                std::iter::once(&self.header)
                    .chain(&self.rows)
                    .filter_map(|row| row.get(c))
                    .map(|cell| cell.chars().count())
                    .max()
                    .unwrap_or(0)
            })
            .collect();
        let mut text = String::new();
        let line = |text: &mut String, row: &[String]| {
            let cells: Vec<String> = row
                .iter()
                .zip(&widths)
                .map(|(cell, width)| format!("{cell:<width$}"))
                .collect();
            let _ = writeln!(text, "  {}", cells.join("  ").trim_end());
        };
        line(&mut text, &self.header);
        let rule: Vec<String> = widths.iter().map(|w| "-".repeat(*w)).collect();
        line(&mut text, &rule);
        for row in &self.rows {
            line(&mut text, row);
        }
        text
    }
}

/// Bytes in the largest unit that keeps the number above 1.
pub fn human_bytes(bytes: u64) -> String {
    let value = bytes as f64;
    match bytes {
        0..1_000 => format!("{bytes} B"),
        1_000..1_000_000 => format!("{:.1} kB", value / 1e3),
        1_000_000..1_000_000_000 => format!("{:.2} MB", value / 1e6),
        _ => format!("{:.2} GB", value / 1e9),
    }
}

fn or_dash(value: Option<String>) -> String {
    value.unwrap_or_else(|| "-".to_owned())
}

/// The per-robot table after a run: path, ATE after SE(3) alignment (`metrics.json`'s `ate_m`; the
/// summary's `ate_first_pose_aligned_m` aligns the first poses only), the α/β error, loops, bytes and time.
pub fn run_table(summary: &RunSummary, metrics: &RunMetrics, folder: &std::path::Path) -> String {
    let mut table = Table::new(&[
        "robot",
        "scans",
        "keyframes",
        "path m",
        "ATE m, SE(3)-aligned (% path)",
        "α/β error m / °",
        "loops acc/rej/undecided",
        "inter cand. raised/verified/expired/waiting",
        "sent",
        "stages s",
    ]);
    let mut notes = Vec::new();
    for (robot, measured) in summary.robots.iter().zip(&metrics.robots) {
        let loops = &measured.loops;
        let trajectory = measured.trajectory.as_ref();
        if let Some(warning) = trajectory.and_then(|t| t.alignment_conditioning.warning()) {
            notes.push(format!("robot {}: {warning}", robot.robot));
        }
        if let Some(reason) = &measured.alignment_unavailable {
            notes.push(format!("robot {}: no α/β error: {reason}", robot.robot));
        }
        if robot.scans_skipped > 0 {
            notes.push(format!(
                "robot {}: {} of {} scans skipped by the odometry",
                robot.robot, robot.scans_skipped, robot.scans_read
            ));
        }
        table.row(vec![
            robot.robot.to_string(),
            robot.scans.to_string(),
            robot.keyframes.to_string(),
            format!("{:.1}", robot.estimated_path_length_m),
            or_dash(trajectory.map(|t| format!("{:.3} ({:.2}%)", t.ate_m.rmse, t.ate_percent_of_path))),
            or_dash(measured.alignment.as_ref().map(|a| {
                let via = a.joined_via.map(|via| format!(" via {via}")).unwrap_or_default();
                format!(
                    "{:.3} / {:.2}{via}",
                    a.beta_alignment_error.translation_m, a.beta_alignment_error.rotation_deg
                )
            })),
            format!(
                "{}/{}/{}",
                loops.accepted_intra + loops.accepted_inter,
                loops.rejected,
                loops.undecided
            ),
            format!(
                "{}/{}/{}/{}",
                loops.candidates_inter,
                loops.inter_admitted,
                loops.expired,
                loops.queued + loops.awaiting_cloud
            ),
            human_bytes(measured.bytes_sent_total),
            format!("{:.1}", robot.stage_ms.values().sum::<f64>() / 1e3),
        ]);
    }
    if metrics.inter_robot_candidates == 0 && summary.robots.len() > 1 {
        notes.push(
            "no inter-robot loop candidate: the robots did not see a common place (a short run ends before \
             they meet; raise run.max_scans or choose a mission where they do)"
                .to_owned(),
        );
    }
    let mut text = format!(
        "\nrun `{}` finished in {:.1} s: {} inter-robot loops accepted of {} candidates, {} sent\n",
        summary.name,
        summary.wall_s,
        metrics.inter_robot_loops_accepted,
        metrics.inter_robot_candidates,
        human_bytes(metrics.bytes_sent_total)
    );
    if summary.robots.len() > 1 {
        let _ = writeln!(
            text,
            "  in robot 0's frame: {} of {} robots; clouds {} per accepted inter-robot loop",
            metrics.robots_in_alpha_frame,
            summary.robots.len() - 1,
            metrics
                .cloud_bytes_per_inter_loop
                .map_or_else(|| "-".to_owned(), |bytes| human_bytes(bytes as u64)),
        );
    }
    let checked: usize = metrics.robots.iter().map(|r| r.loops_against_truth.checked).sum();
    if checked > 0 {
        let worst = |of: fn(&LoopTruth) -> f64| {
            metrics
                .robots
                .iter()
                .map(|r| of(&r.loops_against_truth))
                .fold(0.0, f64::max)
        };
        let _ = writeln!(
            text,
            "  against the ground truth: {} false loops (past {} m or {}°) in the graphs' {} loops, worst {:.2} m / {:.2}°",
            metrics.false_loops_in_graphs,
            FALSE_MERGE_M,
            FALSE_MERGE_DEG,
            checked,
            worst(|truth| truth.worst_error_m),
            worst(|truth| truth.worst_error_deg),
        );
    }
    if let Some(network) = &summary.network {
        let share = |count: u64| 100.0 * count as f64 / network.sent_messages.max(1) as f64;
        let _ = writeln!(
            text,
            "  simulated links: {} messages to peers, {:.1}% delivered (mean {:.0} ms), {:.1}% lost on the air, \
             {:.1}% dropped by full radio queues, {:.1}% out of reach",
            network.sent_messages,
            share(network.delivered_messages),
            network.mean_latency_ms,
            share(network.lost),
            share(network.queue_full),
            share(network.unreachable),
        );
    }
    text.push_str(&table.render());
    for note in notes {
        let _ = writeln!(text, "  note: {note}");
    }
    let _ = writeln!(text, "  outputs: {}", folder.display());
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_line_up_and_bytes_read_naturally() {
        let mut table = Table::new(&["robot", "path m"]);
        table.row(vec!["0".into(), "175.2".into()]);
        table.row(vec!["10".into(), "3.0".into()]);
        let text = table.render();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "  robot  path m");
        assert_eq!(lines[1], "  -----  ------");
        assert_eq!(lines[3], "  10     3.0");
        assert_eq!(human_bytes(999), "999 B");
        assert_eq!(human_bytes(7_500_000), "7.50 MB");
    }
}
