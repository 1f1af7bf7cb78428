//! `evaluate_files` on TUM and KITTI files written here (format detection, association, the report
//! as JSON and Markdown, bad files), and the PNG plots with and without text.

use std::path::Path;

use nalgebra::{Isometry3, Vector3};
use skid_core::Pose;
use skid_eval::plot::{
    PlotOptions, Series, SeriesStyle, line_plot, point_map, pr_curve_plot, trajectory_plot,
};
use skid_eval::{
    AlignmentKind, AssociationMode, EvalError, EvalOptions, ScoredCandidate, TrajectoryFormat, detect_format,
    evaluate_files, pr_curve,
};
use skid_io::trajectory::{StampedPose, write_kitti_poses, write_tum};

fn pose(x: f64, y: f64, yaw: f64) -> Pose {
    Isometry3::new(Vector3::new(x, y, 0.0), Vector3::new(0.0, 0.0, yaw))
}

/// The 4-pose example of the APE unit test, in numbers: ground truth on the corners of a square, the
/// estimate with corners 0 and 2 pushed 0.1 m outwards and 1 and 3 pulled 0.3 m inwards, then moved
/// rigidly far away. SE(3)-aligned ATE: errors 0.1, 0.3, 0.1, 0.3 → rmse √0.05, mean 0.2.
fn square() -> (Vec<Pose>, Vec<Pose>) {
    let corners = [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)];
    let offsets = [0.1, -0.3, 0.1, -0.3];
    let far = Isometry3::new(Vector3::new(50.0, 20.0, -3.0), Vector3::new(0.0, 0.3, 2.0));
    let gt: Vec<Pose> = corners
        .iter()
        .enumerate()
        .map(|(k, &(x, y))| pose(x, y, 0.3 * k as f64))
        .collect();
    let est = gt
        .iter()
        .zip(offsets)
        .map(|(g, d)| {
            let p = g.translation.vector;
            far * Isometry3::from_parts((p + p.normalize() * d).into(), g.rotation)
        })
        .collect();
    (gt, est)
}

fn stamp(poses: &[Pose], t0: f64) -> Vec<StampedPose> {
    poses
        .iter()
        .enumerate()
        .map(|(k, &world_from_sensor)| StampedPose {
            stamp_s: t0 + 0.1 * k as f64,
            world_from_sensor,
        })
        .collect()
}

#[test]
fn tum_and_kitti_files_give_the_hand_computed_ate() {
    let dir = tempfile::tempdir().unwrap();
    let (gt, est) = square();
    let (gt_tum, est_tum) = (dir.path().join("gt.txt"), dir.path().join("est.txt"));
    write_tum(&gt_tum, &stamp(&gt, 1000.0)).unwrap();
    // The estimate's stamps are 4 ms late: within evo's default 10 ms.
    write_tum(&est_tum, &stamp(&est, 1000.004)).unwrap();
    assert_eq!(detect_format(&gt_tum).unwrap(), TrajectoryFormat::Tum);

    let report = evaluate_files(&gt_tum, &est_tum, &EvalOptions::default()).unwrap();
    assert_eq!(report.association, AssociationMode::Timestamps);
    assert_eq!(report.associated_poses, 4);
    assert!(
        (report.ate_m.rmse - 0.05f64.sqrt()).abs() < 1e-9,
        "{}",
        report.ate_m.rmse
    );
    assert!((report.ate_m.mean - 0.2).abs() < 1e-9);
    assert!(report.are_deg.max < 1e-6);
    assert_eq!(report.rpe.pairs, 3);

    let (gt_kitti, est_kitti) = (dir.path().join("gt_poses.txt"), dir.path().join("est_poses.txt"));
    write_kitti_poses(&gt_kitti, &gt).unwrap();
    write_kitti_poses(&est_kitti, &est).unwrap();
    assert_eq!(detect_format(&gt_kitti).unwrap(), TrajectoryFormat::Kitti);
    let report = evaluate_files(&gt_kitti, &est_kitti, &EvalOptions::default()).unwrap();
    assert_eq!(report.association, AssociationMode::Index);
    assert!((report.ate_m.rmse - 0.05f64.sqrt()).abs() < 1e-9);
    // A KITTI estimate against a TUM ground truth pairs by index too.
    let mixed = evaluate_files(&gt_tum, &est_kitti, &EvalOptions::default()).unwrap();
    assert_eq!(mixed.association, AssociationMode::Index);

    // Without alignment the far-away estimate is tens of metres off.
    let raw = EvalOptions {
        alignment: AlignmentKind::None,
        ..EvalOptions::default()
    };
    assert!(evaluate_files(&gt_tum, &est_tum, &raw).unwrap().ate_m.min > 10.0);

    // The report serialises and renders.
    let json = serde_json::to_value(&report).unwrap();
    assert!((json["ate_m"]["rmse"].as_f64().unwrap() - 0.05f64.sqrt()).abs() < 1e-9);
    assert_eq!(json["alignment"]["kind"], "se3");
    let plots = report.write_plots(dir.path(), &PlotOptions::default()).unwrap();
    assert_eq!(plots.len(), 2);
    assert!(inspect(&dir.path().join("ate.png")).2 > 500);
    let markdown = report.to_markdown();
    assert!(markdown.contains("| ATE (m) | 0.223607 |"), "{markdown}");
}

#[test]
fn bad_files_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (gt, est) = square();
    let gt_path = dir.path().join("gt.kitti");
    let short_path = dir.path().join("short.kitti");
    write_kitti_poses(&gt_path, &gt).unwrap();
    write_kitti_poses(&short_path, &est[..3]).unwrap();
    let err = evaluate_files(&gt_path, &short_path, &EvalOptions::default()).unwrap_err();
    assert!(
        matches!(
            err,
            EvalError::LengthMismatch {
                left: 4,
                right: 3,
                ..
            }
        ),
        "{err}"
    );

    let empty = dir.path().join("empty.txt");
    std::fs::write(&empty, "# only a comment\n\n").unwrap();
    assert!(matches!(
        detect_format(&empty),
        Err(EvalError::UnknownFormat { .. })
    ));
    let five = dir.path().join("five.txt");
    std::fs::write(&five, "1 2 3 4 5\n").unwrap();
    let err = evaluate_files(&five, &gt_path, &EvalOptions::default()).unwrap_err();
    assert!(err.to_string().contains("5 values"), "{err}");
    let nan = dir.path().join("nan.tum");
    std::fs::write(&nan, "0 nan 0 0 0 0 0 1\n").unwrap();
    assert!(evaluate_files(&nan, &nan, &EvalOptions::default()).is_err());
    assert!(matches!(
        evaluate_files(&dir.path().join("missing.txt"), &gt_path, &EvalOptions::default()),
        Err(EvalError::Io(_))
    ));
    let by_time = EvalOptions {
        association: AssociationMode::Timestamps,
        ..EvalOptions::default()
    };
    assert!(matches!(
        evaluate_files(&gt_path, &gt_path, &by_time),
        Err(EvalError::InvalidOption { .. })
    ));
}

/// Decodes an RGB PNG: (width, height, the pixels' bytes).
fn decode(path: &Path) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buffer = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buffer).unwrap();
    buffer.truncate(info.buffer_size());
    (info.width, info.height, buffer)
}

/// Decodes a PNG and returns (width, height, number of non-white pixels).
fn inspect(path: &Path) -> (u32, u32, usize) {
    let (width, height, pixels) = decode(path);
    let inked = pixels.chunks(3).filter(|p| p != &[255, 255, 255]).count();
    (width, height, inked)
}

#[test]
fn plots_are_written_with_and_without_text() {
    let dir = tempfile::tempdir().unwrap();
    let (gt, est) = square();
    let small = PlotOptions {
        width_px: 400,
        height_px: 300,
        text: true,
    };
    let no_text = PlotOptions { text: false, ..small };

    let yaw_series = Series {
        name: Some("ours".into()),
        points: (0..=12)
            .map(|k| (15.0 * f64::from(k), 1.0 - 0.01 * f64::from(k)))
            .collect(),
        color: None,
        style: SeriesStyle::LineWithMarkers,
    };
    for (name, options) in [("with_text", small), ("without_text", no_text)] {
        let path = dir.path().join(format!("yaw_{name}.png"));
        let out = line_plot(
            &path,
            "success vs yaw",
            "yaw (deg)",
            "success rate",
            vec![yaw_series.clone()],
            &options,
        )
        .unwrap();
        let (w, h, inked) = inspect(&path);
        assert_eq!((w, h), (400, 300));
        assert!(inked > 500, "{name}: only {inked} drawn pixels");
        assert_eq!(out.legend.len(), 1);
        assert_eq!(out.legend[0].color_hex, "#1f77b4");
        if !options.text {
            assert!(!out.text_rendered);
        }
        assert!(out.markdown().contains("ours = #1f77b4"));
    }

    let candidates = [(0.1, true), (0.2, false), (0.3, true)].map(|(distance, ok)| ScoredCandidate {
        distance,
        is_true_match: ok,
        query_has_match: true,
    });
    let curve = pr_curve(&candidates).unwrap();
    let pr_path = dir.path().join("pr.png");
    pr_curve_plot(&pr_path, "PR", &[("solid", &curve)], &small).unwrap();
    assert!(inspect(&pr_path).2 > 500);

    let traj_path = dir.path().join("nested/traj.png");
    let out = trajectory_plot(
        &traj_path,
        "top view",
        &[("ground truth", &gt), ("estimate", &est)],
        true,
        &small,
    )
    .unwrap();
    assert_eq!(out.legend[0].color_hex, "#5a5a5a");
    assert!(inspect(&traj_path).2 > 500);

    let map: Vec<[f64; 3]> = (0..2000)
        .map(|k| {
            let a = f64::from(k) * 0.01;
            [10.0 * a.cos(), 10.0 * a.sin(), a]
        })
        .collect();
    let map_path = dir.path().join("map.png");
    point_map(&map_path, "map", &map, &[("gt", &gt)], &no_text).unwrap();
    assert!(inspect(&map_path).2 > 500);

    // Bad input: a NaN point, an empty chart, a tiny image.
    let nan_series = Series::line("bad", vec![(0.0, f64::NAN)]);
    assert!(matches!(
        line_plot(
            &dir.path().join("bad.png"),
            "t",
            "x",
            "y",
            vec![nan_series],
            &small
        ),
        Err(EvalError::Plot { .. })
    ));
    assert!(line_plot(&dir.path().join("empty.png"), "t", "x", "y", vec![], &small).is_err());
    let tiny = PlotOptions {
        width_px: 10,
        ..small
    };
    assert!(
        line_plot(
            &dir.path().join("tiny.png"),
            "t",
            "x",
            "y",
            vec![yaw_series],
            &tiny
        )
        .is_err()
    );
}

/// evo's statistics (rmse, mean, median, std, min, max) for one run.
type Stats6 = [f64; 6];

fn assert_stats(name: &str, ours: &skid_eval::ErrorStats, evo: Stats6) {
    let got = [ours.rmse, ours.mean, ours.median, ours.std, ours.min, ours.max];
    for (k, (g, e)) in got.iter().zip(evo).enumerate() {
        assert!(
            (g - e).abs() <= 1e-9 * e.abs().max(1.0),
            "{name} statistic {k}: ours {g}, evo {e}"
        );
    }
}

#[test]
fn equals_evo_on_a_perturbed_kitti_sequence() {
    // tests/data/evo_gt.tum is every 5th of the first 300 poses of KITTI sequence 07's ground truth;
    // evo_est.tum a perturbed estimate (rigid offset, slow yaw drift, scale 0.97, noise) whose clock is
    // 0.25 s early, with 15 % of the poses dropped. The expected numbers were printed by evo 1.38.1
    // (`evo_ape` / `evo_rpe` with `--save_results`, stats.json), with the command line noted at each.
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let (gt, est) = (data.join("evo_gt.tum"), data.join("evo_est.tum"));
    let time = skid_eval::TimeAssociation {
        offset_s: 0.25,
        ..Default::default()
    };
    let se3 = EvalOptions {
        time,
        ..EvalOptions::default()
    };
    let report = evaluate_files(&gt, &est, &se3).unwrap();
    assert_eq!(report.associated_poses, 56);
    // evo_ape tum evo_gt.tum evo_est.tum -a --t_offset 0.25 [-r angle_deg]
    #[rustfmt::skip]
    assert_stats("ATE SE(3)", &report.ate_m, [1.5189937201556674, 1.4004765400783252, 1.262243057612901, 0.5882239221271068, 0.38230665909972306, 2.519476391568023]);
    #[rustfmt::skip]
    assert_stats("ARE SE(3)", &report.are_deg, [4.167809324847543, 4.01741016505689, 4.070640491055535, 1.1095269865955038, 1.4710738981311484, 6.621484534801801]);
    // evo_rpe tum evo_gt.tum evo_est.tum -a --t_offset 0.25 [-r angle_deg]
    #[rustfmt::skip]
    assert_stats("RPE trans", &report.rpe.translation_m, [0.2997007756187549, 0.27783137701888083, 0.2740288891717484, 0.11238452228966304, 0.03715954264823337, 0.5775422721708018]);
    #[rustfmt::skip]
    assert_stats("RPE rot", &report.rpe.rotation_deg, [3.1351489144021243, 2.8764448248943406, 2.7636613472683424, 1.2470861577354573, 0.6484239598565165, 6.202984839816204]);

    // evo_ape tum evo_gt.tum evo_est.tum -as --t_offset 0.25
    // evo_rpe tum evo_gt.tum evo_est.tum -as --t_offset 0.25 --delta 10 --delta_unit m
    let sim3 = EvalOptions {
        alignment: AlignmentKind::Sim3,
        rpe: skid_eval::RpeOptions {
            delta: 10.0,
            unit: skid_eval::DeltaUnit::Metres,
            ..Default::default()
        },
        ..se3.clone()
    };
    let report = evaluate_files(&gt, &est, &sim3).unwrap();
    #[rustfmt::skip]
    assert_stats("ATE Sim(3)", &report.ate_m, [0.3338790666659717, 0.3054551693032156, 0.2940010815713315, 0.1348049357541642, 0.025778428032617744, 0.6912681239459837]);
    #[rustfmt::skip]
    assert_stats("RPE 10 m", &report.rpe.translation_m, [0.6810577478013167, 0.6237034343524818, 0.6130595604107564, 0.2735574561534035, 0.2622842975687252, 1.2792578264749268]);

    // evo_rpe tum evo_gt.tum evo_est.tum -a --t_offset 0.25 --delta 20 --delta_unit m --all_pairs -r angle_deg
    let all_pairs = EvalOptions {
        rpe: skid_eval::RpeOptions {
            delta: 20.0,
            unit: skid_eval::DeltaUnit::Metres,
            all_pairs: true,
            ..Default::default()
        },
        ..se3
    };
    let report = evaluate_files(&gt, &est, &all_pairs).unwrap();
    #[rustfmt::skip]
    assert_stats("RPE 20 m all pairs", &report.rpe.rotation_deg, [3.2556590279842244, 3.029564905437185, 3.299067139832792, 1.192078936244815, 0.5184293829603537, 5.741212135067848]);
}

/// Pixels of exactly `color` per image row.
fn colored_rows(path: &Path, color: [u8; 3]) -> Vec<Vec<u32>> {
    let (width, _, pixels) = decode(path);
    let width = width as usize;
    pixels
        .chunks(3 * width)
        .map(|row| {
            (0..width)
                .filter(|&x| row[3 * x..3 * x + 3] == color)
                .map(|x| x as u32)
                .collect()
        })
        .collect()
}

#[test]
fn the_legend_draws_ground_truth_dashed_like_its_line() {
    let dir = tempfile::tempdir().unwrap();
    let options = PlotOptions {
        width_px: 400,
        height_px: 300,
        text: true,
    };
    let color = [200, 30, 30];
    // One point draws no line, so the only pixels of the colour are the legend's swatch.
    let swatch = |style: SeriesStyle| {
        let path = dir.path().join(format!("{style:?}.png"));
        let out = line_plot(
            &path,
            "legend",
            "x",
            "y",
            vec![Series {
                name: Some("ground truth".into()),
                points: vec![(0.0, 0.0)],
                color: Some(color),
                style,
            }],
            &options,
        )
        .unwrap();
        assert_eq!(out.legend[0].style, style);
        (out, colored_rows(&path, color))
    };
    let (dashed, dashed_rows) = swatch(SeriesStyle::DashedLine);
    let (_, solid_rows) = swatch(SeriesStyle::Line);
    assert!(
        dashed.markdown().contains("ground truth = #c81e1e (dashed)"),
        "{}",
        dashed.markdown()
    );
    if !dashed.text_rendered {
        return; // No font on this machine: no legend is drawn, and the caption says it.
    }
    let widest = |rows: &[Vec<u32>]| rows.iter().max_by_key(|row| row.len()).cloned().unwrap();
    let (dashed_row, solid_row) = (widest(&dashed_rows), widest(&solid_rows));
    assert!(solid_row.len() >= 15, "the solid swatch: {solid_row:?}");
    let gaps = |row: &[u32]| row.windows(2).filter(|pair| pair[1] > pair[0] + 1).count();
    assert_eq!(gaps(&solid_row), 0, "{solid_row:?}");
    assert_eq!(
        gaps(&dashed_row),
        1,
        "the dashed swatch has one gap: {dashed_row:?}"
    );
}
