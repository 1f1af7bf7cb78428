//! Format features that the real data does not exercise, on small files built here: PCD fields of
//! every type and count in all three storages, organised clouds with NaN, PLY with extra elements and
//! list properties in ascii and binary, g2o `FIX`/tolerated tags/information layout/odometry guessing
//! in 3D, and the TORO/iSAM conventions.

// Test helpers outside #[test] functions unwrap too: a failure there is a test failure.

use std::path::PathBuf;

use nalgebra::{Isometry3, Matrix6, Translation3, UnitQuaternion, Vector3};
use skid_io::g2o::{AnyPoseGraph, Edge3, G2oReadOptions, PoseGraph3, read_g2o_3d, write_g2o_3d};
use skid_io::pcd::{PcdData, PcdWriteOptions, lzf, read_pcd, read_pcd_raw, write_pcd};
use skid_io::ply::{PlyFormat, read_ply};
use skid_io::toro::{InformationConvention, read_toro};
use skid_io::{CloudReadOptions, NonFinitePolicy};
use skid_msgs::{Point, RawPoint};
use tempfile::TempDir;

fn file(name: &str, bytes: impl AsRef<[u8]>) -> (TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    (dir, path)
}

/// One point of the mixed-type PCD: `(field bytes in FIELDS order, expected raw point)`.
fn mixed_point(i: usize) -> (Vec<Vec<u8>>, RawPoint) {
    let x = i as f64 * 1.5 - 2.0;
    let y = -(i as f32) * 0.25;
    let z = i as i16 - 3;
    let intensity = (i * 1000) as u16;
    let normal = [0.1_f32, 0.2, 0.3];
    let time = i as f32 * 1e-4;
    let ring = (i % 32) as u16;
    let fields = vec![
        x.to_le_bytes().to_vec(),
        normal.iter().flat_map(|v| v.to_le_bytes()).collect(),
        y.to_le_bytes().to_vec(),
        vec![0xAA, 0xBB, 0xCC],
        z.to_le_bytes().to_vec(),
        intensity.to_le_bytes().to_vec(),
        (i as i64 * -7).to_le_bytes().to_vec(),
        ring.to_le_bytes().to_vec(),
        time.to_le_bytes().to_vec(),
    ];
    (
        fields,
        RawPoint::new(x as f32, y, f32::from(z), f32::from(intensity), time, ring),
    )
}

const MIXED_HEADER: &str = "# mixed\nVERSION .7\nFIELDS x normal y _ z intensity big ring time\n\
SIZE 8 4 4 1 2 2 8 2 4\nTYPE F F F U I U I U F\nCOUNT 1 3 1 3 1 1 1 1 1\n\
WIDTH 7\nHEIGHT 1\nVIEWPOINT 1 2 3 1 0 0 0\nPOINTS 7\n";

#[test]
fn pcd_reads_any_field_types_in_every_storage() {
    let rows: Vec<(Vec<Vec<u8>>, RawPoint)> = (0..7).map(mixed_point).collect();
    let expected: Vec<RawPoint> = rows.iter().map(|r| r.1).collect();

    let mut binary = format!("{MIXED_HEADER}DATA binary\n").into_bytes();
    rows.iter()
        .for_each(|(fields, _)| fields.iter().for_each(|f| binary.extend_from_slice(f)));

    let mut columns = Vec::new();
    for k in 0..rows[0].0.len() {
        rows.iter()
            .for_each(|(fields, _)| columns.extend_from_slice(&fields[k]));
    }
    let packed = lzf::compress(&columns);
    let mut compressed = format!("{MIXED_HEADER}DATA binary_compressed\n").into_bytes();
    compressed.extend_from_slice(&(packed.len() as u32).to_le_bytes());
    compressed.extend_from_slice(&(columns.len() as u32).to_le_bytes());
    compressed.extend_from_slice(&packed);

    let mut ascii = format!("{MIXED_HEADER}DATA ascii\n");
    for (i, p) in expected.iter().enumerate() {
        let x = i as f64 * 1.5 - 2.0;
        ascii += &format!(
            "{x} 0.1 0.2 0.3 {} 170 187 204 {} {} {} {} {}\n",
            p.y,
            p.z,
            p.intensity,
            i as i64 * -7,
            p.ring,
            p.time_offset_s
        );
    }

    for (name, bytes) in [
        ("b.pcd", binary),
        ("c.pcd", compressed),
        ("a.pcd", ascii.into_bytes()),
    ] {
        let (_dir, path) = file(name, bytes);
        let cloud = read_pcd_raw(&path, CloudReadOptions::KEEP_ALL).unwrap();
        assert_eq!(cloud.points, expected, "{name}");
        assert_eq!(
            cloud.header.viewpoint.translation.vector,
            Vector3::new(1.0, 2.0, 3.0)
        );
        assert_eq!(cloud.header.point_bytes(), 8 + 12 + 4 + 3 + 2 + 2 + 8 + 2 + 4);
        let plain = read_pcd(&path, CloudReadOptions::KEEP_ALL).unwrap();
        assert_eq!(plain.points[3], expected[3].point());
    }
}

#[test]
fn pcd_without_intensity_and_ouster_time() {
    let header = "FIELDS x y z t\nSIZE 4 4 4 4\nTYPE F F F U\nWIDTH 2\nHEIGHT 1\nDATA ascii\n";
    let (_dir, path) = file("o.pcd", format!("{header}1 2 3 500000\n4 5 6 1500000\n"));
    let cloud = read_pcd_raw(&path, CloudReadOptions::default()).unwrap();
    assert_eq!(
        cloud.points[1],
        RawPoint::new(4.0, 5.0, 6.0, 0.0, 1.5e-3, RawPoint::UNKNOWN_RING)
    );
    assert_eq!(cloud.header.points, 2);
}

#[test]
fn organised_pcd_with_nan_keeps_or_drops() {
    let mut points = vec![Point::with_intensity(1.0, 2.0, 3.0, 4.0); 6];
    points[1] = Point::with_intensity(f32::NAN, f32::NAN, f32::NAN, 0.0);
    points[4] = Point::new(0.0, 0.0, 0.0);
    let options = PcdWriteOptions {
        organised: Some((3, 2)),
        ..PcdWriteOptions::new(PcdData::Ascii)
    };
    for data in [PcdData::Ascii, PcdData::Binary, PcdData::BinaryCompressed] {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("o.pcd");
        write_pcd(&path, &points, &PcdWriteOptions { data, ..options }).unwrap();
        let kept = read_pcd(&path, CloudReadOptions::KEEP_ALL).unwrap();
        assert_eq!(
            (kept.header.width, kept.header.height, kept.points.len()),
            (3, 2, 6)
        );
        assert!(kept.points[1].x.is_nan() && kept.points[0] == points[0]);
        assert_eq!((kept.report.non_finite, kept.report.zero), (1, 1));
        let valid = read_pcd(&path, CloudReadOptions::VALID_ONLY).unwrap();
        assert_eq!(valid.points.len(), 4);
        assert_eq!(
            (
                valid.report.dropped_non_finite,
                valid.report.dropped_zero,
                valid.report.kept()
            ),
            (1, 1, 4)
        );
        let strict = CloudReadOptions {
            non_finite: NonFinitePolicy::Error,
            drop_zero: false,
        };
        assert!(
            read_pcd(&path, strict)
                .unwrap_err()
                .to_string()
                .contains("point 1 is not finite")
        );
    }
    let dir = tempfile::tempdir().unwrap();
    let err = write_pcd(
        dir.path().join("x.pcd"),
        &points,
        &PcdWriteOptions {
            organised: Some((4, 2)),
            ..options
        },
    );
    assert!(
        err.unwrap_err()
            .to_string()
            .contains("organised size 4 x 2 does not match 6 points")
    );
}

/// A PLY header with an element before and after `vertex`, list properties in both and in `vertex`.
fn ply_header(format: &str) -> String {
    format!(
        "ply\nformat {format} 1.0\ncomment made by hand\nobj_info test\nelement camera 1\nproperty list uchar int ids\n\
         property float fov\nelement vertex 3\nproperty double x\nproperty list ushort uchar tags\nproperty float y\n\
         property float z\nproperty uchar red\nproperty ushort intensity\nelement face 2\n\
         property list uchar int vertex_indices\nproperty short flags\nend_header\n"
    )
}

#[test]
fn ply_skips_other_elements_and_list_properties() {
    let expected = [
        Point::with_intensity(1.5, 2.0, 3.0, 100.0),
        Point::with_intensity(-4.25, 5.0, 6.0, 200.0),
        Point::with_intensity(7.0, -8.0, 9.5, 65535.0),
    ];
    let tags: [&[u8]; 3] = [&[], &[1, 2, 3], &[9]];
    let faces: [&[i32]; 2] = [&[0, 1, 2], &[2, 1, 0, 5]];

    let mut ascii = ply_header("ascii");
    ascii += "2 10 11 0.5\n";
    for (p, t) in expected.iter().zip(tags) {
        let t: Vec<String> = t.iter().map(u8::to_string).collect();
        ascii += &format!(
            "{} {} {} {} {} 255 {}\n",
            p.x,
            t.len(),
            t.join(" "),
            p.y,
            p.z,
            p.intensity
        );
    }
    // The last face spans two lines: ascii data is a token stream.
    ascii += "3 0 1 2 -1\n4 2 1\n0 5 7\n";

    let binary = |big: bool| {
        let mut bytes = ply_header(if big {
            "binary_big_endian"
        } else {
            "binary_little_endian"
        })
        .into_bytes();
        macro_rules! put {
            ($v:expr) => {
                if big {
                    bytes.extend_from_slice(&$v.to_be_bytes())
                } else {
                    bytes.extend_from_slice(&$v.to_le_bytes())
                }
            };
        }
        put!(2_u8);
        put!(10_i32);
        put!(11_i32);
        put!(0.5_f32);
        for (p, t) in expected.iter().zip(tags) {
            put!(f64::from(p.x));
            put!(t.len() as u16);
            t.iter().for_each(|v| put!(*v));
            put!(p.y);
            put!(p.z);
            put!(255_u8);
            put!(p.intensity as u16);
        }
        for face in faces {
            put!(face.len() as u8);
            face.iter().for_each(|v| put!(*v));
            put!(-1_i16);
        }
        bytes
    };
    for (name, bytes) in [
        ("a.ply", ascii.into_bytes()),
        ("le.ply", binary(false)),
        ("be.ply", binary(true)),
    ] {
        let (_dir, path) = file(name, bytes);
        let cloud = read_ply(&path, CloudReadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(cloud.points, expected, "{name}");
        assert_eq!(cloud.header.elements.len(), 3);
        assert_eq!(cloud.header.comments, ["made by hand", "test"]);
        let format = cloud.header.format;
        assert_eq!(format == PlyFormat::Ascii, name == "a.ply");
    }
    // A truncated list in binary data names the offset and the sizes.
    let bytes = binary(false);
    let (_dir, path) = file("cut.ply", &bytes[..bytes.len() - 4]);
    let err = read_ply(&path, CloudReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("element \"face\" #1 property \"vertex_indices\" needs 4 bytes, found 2"),
        "{err}"
    );
}

fn iso(x: f64, y: f64, z: f64, roll: f64, pitch: f64, yaw: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(roll, pitch, yaw),
    )
}

#[test]
fn g2o_3d_fix_tolerated_tags_information_and_chaining() {
    let text = "\
# comment line
PARAMS_SE3OFFSET 0 0 0 0 0 0 0 1
VERTEX_SE3:QUAT 10 1 2 3 0 0 0 1
FIX 10
VERTEX_XYZ 99 1 1 1
EDGE_SE3:QUAT 10 11 1 0 0 0 0 0.7071067811865476 0.7071067811865476 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21
EDGE_SE3:QUAT 11 12 1 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1
EDGE_SE3_XYZ 10 99 0 0 0 1 0 0 1 0 1
EDGE_SE3:QUAT 12 10 0 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1   # loop closure
";
    let (_dir, path) = file("g.g2o", text);
    let (graph, report) = read_g2o_3d(&path, &G2oReadOptions::default()).unwrap();
    assert_eq!(graph.fixed, [10]);
    assert_eq!(report.vertex_lines, 1);
    assert_eq!(report.skipped.values().sum::<usize>(), 3);
    assert_eq!(report.guessed, [11, 12]);
    // Upper triangle row by row: (0,0)=1 .. (0,5)=6, (1,1)=7 .. (5,5)=21, mirrored.
    let info = graph.edges[0].information;
    assert_eq!(
        (
            info[(0, 5)],
            info[(5, 0)],
            info[(1, 1)],
            info[(2, 3)],
            info[(5, 5)]
        ),
        (6.0, 6.0, 7.0, 13.0, 21.0)
    );
    // Vertex 11 = vertex 10 * (1 m forward, 90 deg yaw); vertex 12 = 1 m further along the new heading.
    let v11 = graph.vertices[&11];
    let v12 = graph.vertices[&12];
    assert!((v11.translation.vector - Vector3::new(2.0, 2.0, 3.0)).norm() < 1e-12);
    assert!((v12.translation.vector - Vector3::new(2.0, 3.0, 3.0)).norm() < 1e-12);

    // Round trip, FIX included.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.g2o");
    write_g2o_3d(&out, &graph).unwrap();
    let (back, report) = read_g2o_3d(&out, &G2oReadOptions::default()).unwrap();
    assert!(report.guessed.is_empty());
    assert_eq!(
        (back.fixed.clone(), back.edges.len(), back.vertices.len()),
        (vec![10], 3, 3)
    );
    for (a, b) in graph.edges.iter().zip(&back.edges) {
        assert_eq!(a.information, b.information);
        assert!(a.from_from_to.rotation.angle_to(&b.from_from_to.rotation) < 1e-12);
    }
}

#[test]
fn g2o_3d_chain_from_the_origin_matches_ground_truth() {
    // A noise-free trajectory: the edges alone (no vertices) must rebuild it from the identity.
    let truth: Vec<Isometry3<f64>> = (0..20)
        .map(|i| {
            iso(
                f64::from(i),
                (f64::from(i) * 0.3).sin(),
                0.1 * f64::from(i),
                0.01 * f64::from(i),
                -0.02,
                0.2 * f64::from(i),
            )
        })
        .collect();
    let start = truth[0];
    let truth: Vec<Isometry3<f64>> = truth.iter().map(|t| start.inverse() * t).collect();
    let mut graph = PoseGraph3::default();
    for i in 0..19 {
        let from_from_to = truth[i].inverse() * truth[i + 1];
        graph.edges.push(Edge3 {
            from: i as u64,
            to: i as u64 + 1,
            from_from_to,
            information: Matrix6::identity(),
        });
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("chain.g2o");
    write_g2o_3d(&path, &graph).unwrap();
    let (read, report) = read_g2o_3d(&path, &G2oReadOptions::default()).unwrap();
    assert_eq!(report.guessed.len(), 20);
    for (i, t) in truth.iter().enumerate() {
        assert!(
            (read.vertices[&(i as u64)].to_homogeneous() - t.to_homogeneous())
                .abs()
                .max()
                < 1e-9,
            "vertex {i}"
        );
    }
}

#[test]
fn toro_and_isam_conventions() {
    // TORO 2D information order is Ixx Ixy Iyy Itt Ixt Iyt.
    let (_dir, path) = file(
        "t.graph",
        "VERTEX2 0 0 0 0\nVERTEX2 1 1 0 0\nEDGE2 0 1 1 0 0.5 1 2 3 4 5 6\nEQUIV 0 1\n",
    );
    let read = read_toro(&path, InformationConvention::Toro, &G2oReadOptions::default()).unwrap();
    let AnyPoseGraph::TwoD(graph) = read.graph else {
        panic!("2D expected")
    };
    let info = graph.edges[0].information;
    assert_eq!(
        (
            info[(0, 0)],
            info[(0, 1)],
            info[(1, 1)],
            info[(2, 2)],
            info[(0, 2)],
            info[(1, 2)]
        ),
        (1.0, 2.0, 3.0, 4.0, 5.0, 6.0)
    );
    assert_eq!(read.equivalences, [(0, 1)]);
    // iSAM stores the square root: diag(10, 10, 20) means information diag(100, 100, 400). No vertices:
    // chained from the origin.
    let (_dir, path) = file(
        "i.txt",
        "ODOMETRY 0 1 1 0 0 10 0 0 10 0 20\nEDGE2 1 2 1 0 1.5707963267948966 10 0 0 10 0 20\n",
    );
    let read = read_toro(
        &path,
        InformationConvention::IsamSquareRoot,
        &G2oReadOptions::default(),
    )
    .unwrap();
    let AnyPoseGraph::TwoD(graph) = read.graph else {
        panic!("2D expected")
    };
    assert_eq!(
        graph.edges[1].information,
        nalgebra::Matrix3::from_diagonal(&Vector3::new(100.0, 100.0, 400.0))
    );
    assert!((graph.vertices[&2].translation.vector - nalgebra::Vector2::new(2.0, 0.0)).norm() < 1e-12);
    // TORO 3D: roll pitch yaw, default information identity (rotation block scaled by 4 for g2o).
    let (_dir, path) = file("s.graph", "VERTEX3 0 0 0 0 0 0 0\nEDGE3 0 1 1 2 3 0.1 0.2 0.3\n");
    let read = read_toro(&path, InformationConvention::Toro, &G2oReadOptions::default()).unwrap();
    let AnyPoseGraph::ThreeD(graph) = read.graph else {
        panic!("3D expected")
    };
    let edge = &graph.edges[0];
    assert!(
        (edge.from_from_to.to_homogeneous() - iso(1.0, 2.0, 3.0, 0.1, 0.2, 0.3).to_homogeneous())
            .abs()
            .max()
            < 1e-15
    );
    assert_eq!((edge.information[(0, 0)], edge.information[(3, 3)]), (1.0, 4.0));
    assert_eq!(graph.vertices.len(), 2);
}
