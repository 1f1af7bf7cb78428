//! `cargo xtask bench fig-pr-curves`: the SKiD-SLAM paper's PR-curve figure — precision-recall of SOLiD
//! (Kim et al., RA-L 2024), Scan Context (Kim & Kim, IROS 2018) and LiDAR-Iris (Wang et al., IROS 2020)
//! per environment (planetary, cave, urban, narrow FOV), on simulated multi-robot runs. Parameters in
//! `configs/bench/fig-pr-curves.toml`; the protocol is `skid_bench::place_recognition`'s.

use skid_bench::markdown_table;
use skid_bench::place_recognition::{PrSettings, protocol_note, run_case};

fn main() -> anyhow::Result<()> {
    skid_bench::run_profile("fig-pr-curves", |settings: &PrSettings, report, out| {
        let mut header = vec!["environment".to_owned()];
        for name in &settings.descriptors {
            header.push(format!("{name} max F1 / R@100%P / AP"));
        }
        let (mut body, mut plots) = (Vec::new(), Vec::new());
        for case in &settings.cases {
            let outcome = run_case(settings, case, out, report)?;
            let mut cells = vec![case.name.clone()];
            for (_, curve) in &outcome.curves {
                cells.push(format!(
                    "{:.3} / {:.3} / {:.3}",
                    curve.max_f1, curve.recall_at_full_precision, curve.average_precision
                ));
            }
            body.push(cells);
            plots.push(outcome.plot_markdown);
        }
        Ok(format!(
            "# fig-pr-curves\n\nPlace recognition per environment (the paper's PR-curve figure; one curve per descriptor in each PNG).\n\n{}\n{}\n\n{}\n",
            markdown_table(&header, &body),
            protocol_note(settings),
            plots.join("\n")
        ))
    })
}
