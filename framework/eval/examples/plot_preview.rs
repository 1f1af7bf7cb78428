//! Writes one plot of each kind into a folder (default `target/eval-plot-preview`) so their look can
//! be checked by eye: `cargo run -p skid-eval --example plot_preview -- OUT_DIR`.

use std::path::PathBuf;

use nalgebra::{Isometry3, Vector3};
use skid_core::Pose;
use skid_eval::plot::{
    PlotOptions, Series, SeriesStyle, line_plot, point_map, pr_curve_plot, trajectory_plot,
};
use skid_eval::{ScoredCandidate, pr_curve};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .map_or_else(|| PathBuf::from("target/eval-plot-preview"), PathBuf::from);
    let options = PlotOptions::default();

    let gt: Vec<Pose> = (0..200)
        .map(|k| {
            let s = f64::from(k) * 0.05;
            Isometry3::new(
                Vector3::new(30.0 * s.cos(), 15.0 * (2.0 * s).sin(), 0.0),
                Vector3::new(0.0, 0.0, s),
            )
        })
        .collect();
    let est: Vec<Pose> = gt
        .iter()
        .enumerate()
        .map(|(k, p)| {
            Isometry3::new(
                Vector3::new(0.01 * k as f64, 0.3 * (0.1 * k as f64).sin(), 0.0),
                Vector3::zeros(),
            ) * p
        })
        .collect();
    let written = [
        trajectory_plot(
            &out.join("trajectory.png"),
            "Top view",
            &[("ground truth", &gt), ("estimate", &est)],
            true,
            &options,
        )?,
        line_plot(
            &out.join("success_vs_yaw.png"),
            "Success rate vs yaw",
            "yaw (deg)",
            "success rate",
            vec![Series {
                name: Some("ours".into()),
                points: (0..=12)
                    .map(|k| (15.0 * f64::from(k), 1.0 - 0.02 * f64::from(k % 5)))
                    .collect(),
                color: None,
                style: SeriesStyle::LineWithMarkers,
            }],
            &options,
        )?,
        {
            let candidates: Vec<ScoredCandidate> = (0..100)
                .map(|k| ScoredCandidate {
                    distance: f64::from(k) * 0.01,
                    is_true_match: k % 7 != 3 && k < 80,
                    query_has_match: k < 90,
                })
                .collect();
            let curve = pr_curve(&candidates)?;
            pr_curve_plot(&out.join("pr.png"), "PR curve", &[("solid", &curve)], &options)?
        },
        {
            let map: Vec<[f64; 3]> = (0..40_000)
                .map(|k| {
                    let a = f64::from(k) * 0.013;
                    let r = 20.0 + 10.0 * (a * 0.37).sin();
                    [r * a.cos(), r * a.sin(), (a * 0.05).sin() * 3.0]
                })
                .collect();
            point_map(
                &out.join("map.png"),
                "Point map",
                &map,
                &[("robot", &gt)],
                &options,
            )?
        },
    ];
    for plot in written {
        println!("{} (text drawn: {})", plot.path.display(), plot.text_rendered);
    }
    Ok(())
}
