//! Malformed, truncated and lying inputs, written to a temporary directory: every reader must return an
//! error (never panic) whose `Display` names the file and the line or byte offset, and truncation errors
//! must say how many bytes were expected and found.

// Test helpers outside #[test] functions unwrap too: a failure there is a test failure.

use std::path::PathBuf;

use skid_io::g2o::{G2oReadOptions, MissingVertices, read_g2o, read_g2o_2d, read_g2o_3d};
use skid_io::kitti::{kitti_bin_bytes, read_kitti_bin, read_kitti_calib, read_kitti_times};
use skid_io::pcd::{PcdData, PcdWriteOptions, pcd_bytes, read_pcd};
use skid_io::ply::{PlyFormat, ply_bytes, read_ply};
use skid_io::toro::{InformationConvention, read_toro};
use skid_io::trajectory::{read_kitti_poses, read_tum};
use skid_io::{CloudReadOptions, IoError, Location, NonFinitePolicy};
use skid_msgs::Point;
use tempfile::TempDir;

/// Writes `bytes` as `name` in a fresh directory; the directory lives as long as the returned guard.
fn file(name: &str, bytes: impl AsRef<[u8]>) -> (TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    (dir, path)
}

/// The error's text, checked to start with the file's path.
fn message<T: std::fmt::Debug>(result: Result<T, IoError>, path: &std::path::Path) -> String {
    let text = result.unwrap_err().to_string();
    assert!(
        text.starts_with(&path.display().to_string()),
        "error does not name the file: {text}"
    );
    text
}

fn points(n: usize) -> Vec<Point> {
    (0..n)
        .map(|i| Point::with_intensity(i as f32, -(i as f32) * 0.5, 1.25, 0.5))
        .collect()
}

const OPTIONS: CloudReadOptions = CloudReadOptions {
    non_finite: NonFinitePolicy::Drop,
    drop_zero: false,
};

#[test]
fn truncated_kitti_bin_names_offset_and_sizes() {
    let mut bytes = kitti_bin_bytes(&points(3));
    bytes.extend_from_slice(&[0; 7]);
    let (_dir, path) = file("000000.bin", bytes);
    let text = message(read_kitti_bin(&path, OPTIONS), &path);
    assert!(
        text.contains("truncated at byte offset 48") && text.contains("needs 16 bytes, found 7"),
        "{text}"
    );
}

#[test]
fn non_finite_kitti_point_is_reported_with_its_offset() {
    let mut cloud = points(4);
    cloud[2].y = f32::NAN;
    let (_dir, path) = file("nan.bin", kitti_bin_bytes(&cloud));
    let strict = CloudReadOptions {
        non_finite: NonFinitePolicy::Error,
        drop_zero: false,
    };
    let text = message(read_kitti_bin(&path, strict), &path);
    assert!(text.contains("byte offset 32: point 2 is not finite"), "{text}");
    let dropped = read_kitti_bin(&path, OPTIONS).unwrap();
    assert_eq!((dropped.points.len(), dropped.report.dropped_non_finite), (3, 1));
    let kept = read_kitti_bin(&path, CloudReadOptions::KEEP_ALL).unwrap();
    assert_eq!((kept.points.len(), kept.report.non_finite), (4, 1));
}

#[test]
fn pcd_header_lying_about_points_is_a_truncation_error() {
    let good = pcd_bytes(&points(10), &PcdWriteOptions::new(PcdData::Binary), "x".as_ref()).unwrap();
    let header_len = String::from_utf8_lossy(&good).find("DATA binary\n").unwrap() + 12;
    let header = String::from_utf8(good[..header_len].to_vec()).unwrap();
    let header = header
        .replace("WIDTH 10\n", "WIDTH 100\n")
        .replace("POINTS 10\n", "POINTS 100\n");
    let mut bytes = header.into_bytes();
    bytes.extend_from_slice(&good[header_len..]);
    let (_dir, path) = file("lies.pcd", &bytes);
    let text = message(read_pcd(&path, OPTIONS), &path);
    let offset = bytes.len() - 160;
    assert!(
        text.contains(&format!("truncated at byte offset {offset}"))
            && text.contains("needs 1600 bytes, found 160"),
        "{text}"
    );
}

#[test]
fn pcd_points_disagreeing_with_width_names_the_points_line() {
    let good = pcd_bytes(&points(2), &PcdWriteOptions::new(PcdData::Ascii), "x".as_ref()).unwrap();
    let bad = String::from_utf8(good).unwrap().replace("POINTS 2", "POINTS 3");
    let (_dir, path) = file("points.pcd", bad);
    let text = message(read_pcd(&path, OPTIONS), &path);
    assert!(
        text.contains("line 10: POINTS 3 disagrees with WIDTH x HEIGHT = 2 x 1"),
        "{text}"
    );
}

#[test]
fn pcd_ascii_errors_name_the_line() {
    let good = String::from_utf8(
        pcd_bytes(&points(3), &PcdWriteOptions::new(PcdData::Ascii), "x".as_ref()).unwrap(),
    )
    .unwrap();
    // Header is 11 lines; data lines are 12, 13, 14.
    let bad_number = good.replace("1 -0.5 1.25 0.5", "1 -0.5 1.2.5 0.5");
    let (_dir, path) = file("bad.pcd", bad_number);
    let text = message(read_pcd(&path, OPTIONS), &path);
    assert!(
        text.contains("line 13: field 3") && text.contains("\"1.2.5\""),
        "{text}"
    );

    let short = good.replace("2 -1 1.25 0.5\n", "");
    let (_dir, path) = file("short.pcd", short);
    let text = message(read_pcd(&path, OPTIONS), &path);
    assert!(
        text.contains("POINTS announces 3 points but the ascii data has 2"),
        "{text}"
    );

    let extra_field = good.replace("1 -0.5 1.25 0.5", "1 -0.5 1.25 0.5 7");
    let (_dir, path) = file("extra.pcd", extra_field);
    assert!(message(read_pcd(&path, OPTIONS), &path).contains("line 13: unexpected extra field 5"));

    let nan = good.replace("1 -0.5 1.25 0.5", "nan nan nan 0.5");
    let (_dir, path) = file("nan.pcd", nan);
    let strict = CloudReadOptions {
        non_finite: NonFinitePolicy::Error,
        drop_zero: false,
    };
    assert!(message(read_pcd(&path, strict), &path).contains("line 13: point 1 is not finite"));
    let read = read_pcd(&path, OPTIONS).unwrap();
    assert_eq!((read.points.len(), read.report.dropped_non_finite), (2, 1));
}

#[test]
fn pcd_header_errors_name_the_line() {
    let good = String::from_utf8(
        pcd_bytes(&points(1), &PcdWriteOptions::new(PcdData::Ascii), "x".as_ref()).unwrap(),
    )
    .unwrap();
    for (from, to, expected) in [
        ("DATA ascii", "DATA zipped", "line 11: unknown DATA kind"),
        (
            "TYPE F F F F",
            "TYPE F F F X",
            "line 5: field \"intensity\": TYPE X with SIZE 4 is not supported",
        ),
        (
            "SIZE 4 4 4 4",
            "SIZE 4 4 4",
            "line 4: SIZE has 3 entries for 4 FIELDS",
        ),
        (
            "WIDTH 1",
            "WIDTH one",
            "line 7: field 2 (WIDTH): cannot parse \"one\"",
        ),
        (
            "FIELDS x y z intensity",
            "FIELDS a y z intensity",
            "PCD has no \"x\" field",
        ),
        (
            "VERSION 0.7",
            "BOGUS 1",
            "line 2: unknown PCD header keyword \"BOGUS\"",
        ),
        (
            "COUNT 1 1 1 1",
            "COUNT 1 1 1 0",
            "line 6: field \"intensity\" has COUNT 0",
        ),
        (
            "POINTS 1\n",
            "POINTS 18446744073709551615\n",
            "line 10: POINTS 18446744073709551615 disagrees",
        ),
    ] {
        let (_dir, path) = file("h.pcd", good.replace(from, to));
        let text = message(read_pcd(&path, OPTIONS), &path);
        assert!(text.contains(expected), "{text}");
    }
    let (_dir, path) = file("nodata.pcd", "VERSION 0.7\nFIELDS x y z\n");
    assert!(message(read_pcd(&path, OPTIONS), &path).contains("end of file before the DATA line"));
}

#[test]
fn compressed_pcd_truncation_and_corruption() {
    let good = pcd_bytes(
        &points(50),
        &PcdWriteOptions::new(PcdData::BinaryCompressed),
        "x".as_ref(),
    )
    .unwrap();
    let header_len = String::from_utf8_lossy(&good)
        .find("binary_compressed\n")
        .unwrap()
        + 18;
    let compressed = u32::from_le_bytes(good[header_len..header_len + 4].try_into().unwrap()) as usize;
    let (_dir, path) = file("cut.pcd", &good[..good.len() - 5]);
    let text = message(read_pcd(&path, OPTIONS), &path);
    assert!(
        text.contains(&format!("truncated at byte offset {}", header_len + 8))
            && text.contains(&format!("needs {compressed} bytes, found {}", compressed - 5)),
        "{text}"
    );
    let (_dir, path) = file("sizes.pcd", &good[..header_len + 3]);
    assert!(message(read_pcd(&path, OPTIONS), &path).contains("needs 8 bytes, found 3"));
    // A back-reference pointing before the start of the output.
    let mut corrupt = good.clone();
    corrupt[header_len + 8] = 0xE0;
    corrupt[header_len + 9] = 0x00;
    corrupt[header_len + 10] = 0xFF;
    let (_dir, path) = file("corrupt.pcd", &corrupt);
    let text = message(read_pcd(&path, OPTIONS), &path);
    assert!(
        text.contains(&format!(
            "byte offset {}: LZF data: back-reference",
            header_len + 8
        )),
        "{text}"
    );
}

#[test]
fn ply_errors_name_offset_or_line() {
    let binary = ply_bytes(&points(5), PlyFormat::BinaryLittleEndian);
    let header_len = String::from_utf8_lossy(&binary).find("end_header\n").unwrap() + 11;
    let (_dir, path) = file("cut.ply", &binary[..binary.len() - 10]);
    let text = message(read_ply(&path, OPTIONS), &path);
    assert!(
        text.contains(&format!("truncated at byte offset {header_len}"))
            && text.contains("element \"vertex\" (5 x 16 bytes) needs 80 bytes, found 70"),
        "{text}"
    );
    let ascii = String::from_utf8(ply_bytes(&points(3), PlyFormat::Ascii)).unwrap();
    // Header: ply, format, comment, element, 4 properties, end_header = 9 lines; vertex 1 is line 11.
    let (_dir, path) = file("bad.ply", ascii.replace("1 -0.5 1.25 0.5", "1 -0.5 x 0.5"));
    let text = message(read_ply(&path, OPTIONS), &path);
    assert!(
        text.contains("line 11: element \"vertex\" #1 property \"z\": cannot parse \"x\""),
        "{text}"
    );
    let (_dir, path) = file("short.ply", ascii.replace("2 -1 1.25 0.5\n", ""));
    assert!(message(read_ply(&path, OPTIONS), &path).contains("file ends before element \"vertex\" #2"));
    let (_dir, path) = file("fmt.ply", ascii.replace("format ascii 1.0", "format utf8 1.0"));
    assert!(message(read_ply(&path, OPTIONS), &path).contains("line 2: unknown PLY format \"utf8\""));
    // Huge counts in a corrupt header give errors, not an allocation failure or an endless loop.
    let huge = ascii.replace("element vertex 3", "element vertex 18446744073709551615");
    let (_dir, path) = file("huge.ply", huge);
    assert!(message(read_ply(&path, OPTIONS), &path).contains("file ends before element \"vertex\" #3"));
    let empty = ascii.replace("end_header", "element nothing 18446744073709551615\nend_header");
    let (_dir, path) = file("empty.ply", empty);
    assert_eq!(read_ply(&path, OPTIONS).unwrap().points.len(), 3);
    let (_dir, path) = file("noply.ply", "PLY\n");
    assert!(message(read_ply(&path, OPTIONS), &path).contains("line 1: not a PLY file"));
}

#[test]
fn g2o_errors_name_the_line() {
    let good = "# tiny graph\nVERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n";
    let options = G2oReadOptions::default();
    let cases = [
        (
            good.replace("VERTEX_SE2 1 1 0 0", "VERTEX_SE2 1 1 zero 0"),
            "line 3: field 4 (x y theta): cannot parse \"zero\"",
        ),
        (
            good.replace(" 0 1 0 1\n", " 0 1 0\n"),
            "line 4: expected information matrix entry",
        ),
        (
            good.replace("VERTEX_SE2 1 1 0 0", "VERTEX_SE2 1 1 0 0 9"),
            "line 3: unexpected extra field 6",
        ),
        (
            format!("{good}VERTEX_SE2 1 2 0 0\n"),
            "line 5: vertex 1 is listed twice (first at line 3)",
        ),
        (
            format!("{good}VERTEX_SE3:QUAT 2 0 0 0 0 0 0 1\n"),
            "line 5: VERTEX_SE3:QUAT does not belong",
        ),
        (
            format!("{good}EDGE_SE2_BOGUS 0 1\n"),
            "line 5: unknown g2o tag \"EDGE_SE2_BOGUS\"",
        ),
        (
            good.replace("VERTEX_SE2 0 0 0 0", "VERTEX_SE2 -1 0 0 0"),
            "line 2: field 2 (vertex id): cannot parse \"-1\"",
        ),
        (
            good.replace("1 0 0 1 0 1\n", "1 0 0 inf 0 1\n"),
            "line 4: field 10 (information matrix entry (6 upper-triangular values)) is not finite: inf",
        ),
    ];
    for (text, expected) in cases {
        let (_dir, path) = file("g.g2o", text);
        let message = message(read_g2o(&path, &options), &path);
        assert!(message.contains(expected), "{message}");
    }
    // A 3D zero quaternion.
    let (_dir, path) = file("q.g2o", "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 0\n");
    assert!(
        message(read_g2o_3d(&path, &options), &path).contains("line 1: quaternion (0, 0, 0, 0) has norm 0")
    );
    // Lenient reading skips and lists the bad lines.
    let (_dir, path) = file(
        "g.g2o",
        format!("{good}garbage here\nEDGE_SE2 1 2 1 0 0 1 0 0 1 0 1 extra\n"),
    );
    let lenient = G2oReadOptions {
        skip_malformed: true,
        ..G2oReadOptions::default()
    };
    let (graph, report) = read_g2o_2d(&path, &lenient).unwrap();
    assert_eq!((graph.edges.len(), report.malformed_lines), (1, vec![5, 6]));
}

#[test]
fn missing_vertex_is_an_error_when_asked_and_reported_otherwise() {
    let text = "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\nEDGE_SE2 1 7 1 0 0 1 0 0 1 0 1\n";
    let (_dir, path) = file("m.g2o", text);
    let strict = G2oReadOptions {
        missing_vertices: MissingVertices::Error,
        ..G2oReadOptions::default()
    };
    let text = message(read_g2o_2d(&path, &strict), &path);
    assert!(
        text.contains("line 4: edge 1 -> 7 names vertex 7, which has no VERTEX_SE2 line"),
        "{text}"
    );
    let (graph, report) = read_g2o_2d(&path, &G2oReadOptions::default()).unwrap();
    assert_eq!((report.unresolved, graph.missing_vertices()), (vec![7], vec![7]));
}

#[test]
fn trajectory_and_kitti_text_errors_name_the_line() {
    let tum = "# stamp tx ty tz qx qy qz qw\n0.0 0 0 0 0 0 0 1\n0.1 1 0 0 0 0 0 l\n";
    let (_dir, path) = file("t.tum", tum);
    let text = message(read_tum(&path), &path);
    assert!(
        text.contains("line 3: field 8 (quaternion qx qy qz qw): cannot parse \"l\""),
        "{text}"
    );
    let (_dir, path) = file("t.tum", "0.0 0 0 0 0 0 0\n");
    assert!(message(read_tum(&path), &path).contains("line 1: expected quaternion qx qy qz qw as field 8"));

    let identity = "1 0 0 0 0 1 0 0 0 0 1 0\n";
    let (_dir, path) = file("p.txt", format!("{identity}1 0 0 0 0 2 0 0 0 0 1 0\n"));
    let text = message(read_kitti_poses(&path), &path);
    assert!(
        text.contains("line 2: matrix is") && text.contains("away from the nearest rotation"),
        "{text}"
    );
    let (_dir, path) = file("p.txt", format!("{identity}-1 0 0 0 0 1 0 0 0 0 1 0\n"));
    assert!(message(read_kitti_poses(&path), &path).contains("line 2: rotation matrix has determinant -1"));
    let (_dir, path) = file("p.txt", format!("{identity}1 0 0 0 0 1 0 0 0 0 1\n"));
    assert!(
        message(read_kitti_poses(&path), &path)
            .contains("line 2: expected 3x4 pose matrix entry as field 12")
    );

    let (_dir, path) = file("times.txt", "0.0\n0.1\n0,2\n");
    assert!(
        message(read_kitti_times(&path), &path)
            .contains("line 3: field 1 (time in seconds): cannot parse \"0,2\"")
    );
    let (_dir, path) = file("calib.txt", "P0: 1 2 3\n");
    assert!(message(read_kitti_calib(&path), &path).contains("no \"Tr:\" line"));
    let (_dir, path) = file("calib.txt", "Tr: 1 0 0 0 0 1 0 0 0 0 1\n");
    assert!(message(read_kitti_calib(&path), &path).contains("line 1: Tr needs 12 numbers, found 11"));
}

#[test]
fn toro_errors_name_the_line() {
    let (_dir, path) = file(
        "w.graph",
        "VERTEX2 0 0 0 0\nVERTEX2 1 1 0 0\nEDGE2 0 1 1 0 0 1 0 1 1 0\n",
    );
    let text = message(
        read_toro(&path, InformationConvention::Toro, &G2oReadOptions::default()),
        &path,
    );
    assert!(
        text.contains("line 3: expected information entry (6 values) as field 12, found end of line"),
        "{text}"
    );
    let (_dir, path) = file("w.graph", "VERTEX2 0 0 0 0\nVERTEX3 1 0 0 0 0 0 0\n");
    let text = message(
        read_toro(&path, InformationConvention::Toro, &G2oReadOptions::default()),
        &path,
    );
    assert!(
        text.contains("line 2: unknown or wrong-dimension TORO/iSAM tag \"VERTEX3\""),
        "{text}"
    );
}

#[test]
fn missing_file_is_an_io_error_naming_it() {
    let path = PathBuf::from("/nonexistent/dir/scan.pcd");
    let err = read_pcd(&path, OPTIONS).unwrap_err();
    assert!(matches!(err, IoError::Io { .. }));
    assert!(
        err.to_string().starts_with("/nonexistent/dir/scan.pcd: "),
        "{err}"
    );
    assert_eq!(err.location(), None);
    let err = read_kitti_bin(&path, OPTIONS).unwrap_err();
    assert_eq!(err.path(), path.as_path());
    assert!(Location::Line(3).to_string() == "line 3");
}

#[test]
fn truncated_and_corrupted_files_never_panic() {
    let cloud = points(40);
    let mut samples: Vec<(&str, Vec<u8>)> = vec![("k.bin", kitti_bin_bytes(&cloud))];
    for data in [PcdData::Ascii, PcdData::Binary, PcdData::BinaryCompressed] {
        samples.push((
            "p.pcd",
            pcd_bytes(&cloud, &PcdWriteOptions::new(data), "x".as_ref()).unwrap(),
        ));
    }
    for format in [
        PlyFormat::Ascii,
        PlyFormat::BinaryLittleEndian,
        PlyFormat::BinaryBigEndian,
    ] {
        samples.push(("p.ply", ply_bytes(&cloud, format)));
    }
    samples.push(("g.g2o", b"VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nEDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\nFIX 0\n".to_vec()));
    samples.push((
        "g.graph",
        b"VERTEX2 0 0 0 0\nEDGE2 0 1 1 0 0 1 0 1 1 0 0\nEQUIV 0 1\n".to_vec(),
    ));
    samples.push(("t.tum", b"0 1 2 3 0 0 0 1\n1 1 2 3 0 0 0.5 1\n".to_vec()));
    samples.push(("p.txt", b"1 0 0 0 0 1 0 0 0 0 1 0\n".to_vec()));

    let dir = tempfile::tempdir().unwrap();
    let mut state = 0x2545_F491_u32;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state as usize
    };
    let mut errors = 0;
    for (name, good) in &samples {
        let path = dir.path().join(name);
        let mut variants: Vec<Vec<u8>> = (0..good.len()).step_by(13).map(|n| good[..n].to_vec()).collect();
        for _ in 0..40 {
            let mut bad = good.clone();
            for _ in 0..1 + next() % 4 {
                let at = next() % bad.len();
                bad[at] = next() as u8;
            }
            variants.push(bad);
        }
        for bytes in variants {
            std::fs::write(&path, &bytes).unwrap();
            let ok = match *name {
                "k.bin" => read_kitti_bin(&path, OPTIONS).is_ok(),
                "p.pcd" => read_pcd(&path, OPTIONS).is_ok(),
                "p.ply" => read_ply(&path, OPTIONS).is_ok(),
                "g.g2o" => read_g2o(&path, &G2oReadOptions::default()).is_ok(),
                "g.graph" => {
                    read_toro(&path, InformationConvention::Toro, &G2oReadOptions::default()).is_ok()
                }
                "t.tum" => read_tum(&path).is_ok(),
                _ => read_kitti_poses(&path).is_ok(),
            };
            errors += usize::from(!ok);
        }
    }
    assert!(errors > 60, "only {errors} of the damaged files were rejected");
}
