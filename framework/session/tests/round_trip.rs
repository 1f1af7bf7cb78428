//! A session written and read back is the same session, and a damaged one is refused naming the file.

#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::path::Path;

use nalgebra::{Matrix6, Translation3, UnitQuaternion};
use skid_core::{Point, Pose};
use skid_io::g2o::{Edge, PoseGraph};
use skid_session::{
    DescriptorSpec, Session, SessionKeyframe, SessionRobot, read_keyframe_cloud, read_session, write_session,
};

fn pose(x: f64, y: f64, yaw: f64) -> Pose {
    Pose::from_parts(
        Translation3::new(x, y, 0.1 * x),
        UnitQuaternion::from_euler_angles(0.01 * y, -0.02, yaw),
    )
}

fn cloud(robot: u32, index: u32) -> Vec<Point> {
    (0..(50 + index * 7))
        .map(|i| {
            Point::with_intensity(
                i as f32 * 0.25,
                robot as f32 - 3.5,
                index as f32 * 0.125,
                i as f32,
            )
        })
        .collect()
}

fn example() -> (Session, Vec<Vec<Vec<Point>>>) {
    let mut robots = Vec::new();
    let mut clouds = Vec::new();
    for robot in 0..2_u32 {
        let mut graph = PoseGraph::default();
        let keyframes: Vec<SessionKeyframe> = (0..6_u32)
            .map(|index| {
                let map_from_sensor = pose(
                    f64::from(index) * 1.5,
                    f64::from(robot) * 4.0,
                    0.1 * f64::from(index),
                );
                graph
                    .vertices
                    .insert(u64::from(robot) * 1_000_000 + u64::from(index), map_from_sensor);
                SessionKeyframe {
                    index,
                    stamp_nanos: 1_000_000_000 + u64::from(index) * 700_000_000,
                    map_from_sensor,
                    odometry_from_sensor: pose(f64::from(index) * 1.49, 0.0, 0.1 * f64::from(index)),
                    ground_truth: (robot == 1).then(|| pose(f64::from(index), 7.0, 0.3)),
                    point_count: cloud(robot, index).len(),
                    // Robot 1's last keyframe was not described.
                    descriptor: (robot == 0 || index < 5)
                        .then(|| vec![index as f32 / 7.0, -(robot as f32), 1e-7, 3.0e5]),
                }
            })
            .collect();
        for index in 0..5_u64 {
            let id = u64::from(robot) * 1_000_000 + index;
            graph.edges.push(Edge {
                from: id,
                to: id + 1,
                from_from_to: pose(1.5, 0.0, 0.1),
                information: Matrix6::identity() * 100.0,
            });
        }
        graph.fixed.push(u64::from(robot) * 1_000_000);
        clouds.push((0..6).map(|index| cloud(robot, index)).collect());
        robots.push(SessionRobot {
            robot,
            map_from_robot: (robot == 0).then(Pose::identity),
            keyframes,
            graph,
        });
    }
    let session = Session {
        name: "round-trip".into(),
        skid_version: "0.1.0".into(),
        descriptor: Some(DescriptorSpec {
            kind: "solid".into(),
            params: serde_json::json!({"num_range": 40, "fov_up_deg": 2.0}),
            length: 4,
        }),
        config_toml: "[run]\nname = \"round-trip\"\n".into(),
        robots,
    };
    (session, clouds)
}

fn assert_close(a: &Pose, b: &Pose, tolerance: f64) {
    let delta = a.inverse() * b;
    assert!(
        delta.translation.vector.norm() < tolerance && delta.rotation.angle() < tolerance,
        "{a:?} vs {b:?}"
    );
}

fn write(dir: &Path) -> Session {
    let (session, clouds) = example();
    write_session(dir, &session, |robot, index| {
        clouds.get(robot as usize)?.get(index as usize).map(Vec::as_slice)
    })
    .unwrap();
    session
}

#[test]
fn a_session_read_back_has_the_same_keyframes_poses_descriptors_and_clouds() {
    let dir = tempfile::tempdir().unwrap();
    let written = write(dir.path());
    let read = read_session(dir.path()).unwrap();
    assert_eq!(read.name, written.name);
    assert_eq!(read.descriptor, written.descriptor);
    assert_eq!(read.config_toml, written.config_toml);
    assert_eq!(read.robots.len(), 2);
    for (back, original) in read.robots.iter().zip(&written.robots) {
        assert_eq!(back.robot, original.robot);
        assert_eq!(back.map_from_robot.is_some(), original.map_from_robot.is_some());
        assert_eq!(back.keyframes.len(), original.keyframes.len());
        for (k, o) in back.keyframes.iter().zip(&original.keyframes) {
            assert_eq!(
                (k.index, k.stamp_nanos, k.point_count),
                (o.index, o.stamp_nanos, o.point_count)
            );
            // Descriptors are stored as the f32 values themselves: bit for bit.
            assert_eq!(k.descriptor, o.descriptor);
            assert_close(&k.map_from_sensor, &o.map_from_sensor, 1e-12);
            assert_close(&k.odometry_from_sensor, &o.odometry_from_sensor, 1e-12);
            assert_eq!(k.ground_truth.is_some(), o.ground_truth.is_some());
            if let (Some(a), Some(b)) = (&k.ground_truth, &o.ground_truth) {
                assert_close(a, b, 1e-12);
            }
            let points = read_keyframe_cloud(dir.path(), back, k).unwrap();
            let expected = cloud(back.robot, k.index);
            assert_eq!(points.len(), expected.len());
            for (p, e) in points.iter().zip(&expected) {
                assert_eq!((p.x, p.y, p.z, p.intensity), (e.x, e.y, e.z, e.intensity));
            }
        }
        assert_eq!(back.graph.vertices.len(), original.graph.vertices.len());
        assert_eq!(back.graph.edges.len(), original.graph.edges.len());
        assert_eq!(back.graph.fixed, original.graph.fixed);
        for (id, vertex) in &original.graph.vertices {
            assert_close(&back.graph.vertices[id], vertex, 1e-6);
        }
    }
    let info = skid_session::SessionInfo::of(&read, dir.path()).unwrap();
    assert_eq!(info.robots[1].described, 5);
    assert!(info.robots[0].placed && !info.robots[1].placed);
    assert!(
        (info.robots[0].path_length_m
            - written.robots[0].keyframes[5]
                .map_from_sensor
                .translation
                .vector
                .norm())
        .abs()
            < 0.2
    );
    assert_eq!(info.robots[0].loops, 0);
    assert!(info.bytes_on_disk > 0);
}

fn refused(dir: &Path) -> String {
    read_session(dir).unwrap_err().to_string()
}

#[test]
fn a_damaged_session_is_refused_naming_the_file_and_the_entry() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path());
    let manifest = dir.path().join("session.json");
    let text = std::fs::read_to_string(&manifest).unwrap();

    std::fs::write(&manifest, text.replace("\"version\": 1", "\"version\": 7")).unwrap();
    let error = refused(dir.path());
    assert!(
        error.contains("session.json") && error.contains("newer SKiD"),
        "{error}"
    );

    std::fs::write(&manifest, text.replace("skid-session", "something-else")).unwrap();
    assert!(refused(dir.path()).contains("not a SKiD session"));

    std::fs::write(&manifest, text.replace("\"keyframes\": 6", "\"keyframes\": 9")).unwrap();
    let error = refused(dir.path());
    assert!(
        error.contains("keyframes.json") && error.contains("says robot 0 has 9"),
        "{error}"
    );

    std::fs::write(&manifest, text.replace("\"length\": 4", "\"length\": 5")).unwrap();
    assert!(refused(dir.path()).contains("descriptors.bin"));
    std::fs::write(&manifest, &text).unwrap();

    let keyframes = dir.path().join("robot1/keyframes.json");
    let original = std::fs::read_to_string(&keyframes).unwrap();
    std::fs::write(&keyframes, original.replacen("\"index\": 3", "\"index\": 1", 1)).unwrap();
    let error = refused(dir.path());
    assert!(
        error.contains("robot1/keyframes.json") && error.contains("entry 3"),
        "{error}"
    );
    std::fs::write(
        &keyframes,
        original.replacen("\"stamp_nanos\"", "\"stamp_nanoz\"", 1),
    )
    .unwrap();
    let error = refused(dir.path());
    assert!(error.contains("[0]") && error.contains("stamp_nanoz"), "{error}");
    std::fs::write(&keyframes, &original).unwrap();

    let descriptors = dir.path().join("robot0/descriptors.bin");
    let bytes = std::fs::read(&descriptors).unwrap();
    std::fs::write(&descriptors, &bytes[..bytes.len() - 3]).unwrap();
    assert!(refused(dir.path()).contains("robot0/descriptors.bin"));
    std::fs::write(&descriptors, &bytes).unwrap();

    let session = read_session(dir.path()).unwrap();
    let robot = &session.robots[0];
    std::fs::write(
        dir.path().join("robot0/clouds/000002.ply"),
        b"ply\nformat ascii 1.0\nend_header\n",
    )
    .unwrap();
    let error = read_keyframe_cloud(dir.path(), robot, &robot.keyframes[2])
        .unwrap_err()
        .to_string();
    assert!(error.contains("000002.ply"), "{error}");

    std::fs::remove_file(&manifest).unwrap();
    assert!(refused(dir.path()).contains("not a session folder"));
}

#[test]
fn joined_sessions_keep_every_robot_renumbered_and_placed_where_the_caller_says() {
    let first = tempfile::tempdir().unwrap();
    let second = tempfile::tempdir().unwrap();
    let a = write(first.path());
    let b = write(second.path());
    let out = tempfile::tempdir().unwrap();
    let joined_dir = out.path().join("joined");
    let moved = pose(10.0, -3.0, 0.7);
    let (_, b_clouds) = example();
    let b_cloud_of = |robot: u32, index: u32| b_clouds.get(robot as usize)?.get(index as usize).cloned();
    let parts = [
        skid_session::JoinPart {
            session: &a,
            placements: a.robots.iter().map(|r| r.map_from_robot).collect(),
            clouds: skid_session::PartClouds::Folder(first.path()),
            foreign_vertices: Default::default(),
        },
        skid_session::JoinPart {
            session: &b,
            // Robot 0 of the second session is placed; its robot 1 stays unplaced.
            placements: vec![Some(moved)],
            clouds: skid_session::PartClouds::Memory(&b_cloud_of),
            foreign_vertices: Default::default(),
        },
    ];
    let joined = skid_session::write_joined(&joined_dir, "joined", &parts).unwrap();
    assert_eq!(joined.ids[1].get(&0), Some(&2));
    assert_eq!(joined.ids[1].get(&1), Some(&3));
    let read = read_session(&joined_dir).unwrap();
    assert_eq!(read.name, "joined");
    let ids: Vec<u32> = read.robots.iter().map(|r| r.robot).collect();
    assert_eq!(ids, [0, 1, 2, 3]);
    assert_close(read.robots[2].map_from_robot.as_ref().unwrap(), &moved, 1e-9);
    assert!(read.robots[1].map_from_robot.is_none() && read.robots[3].map_from_robot.is_none());
    // The second session's robot 1 is robot 3 now, in its keyframes, clouds and graph alike.
    let robot = &read.robots[3];
    assert_eq!(robot.keyframes.len(), b.robots[1].keyframes.len());
    for (k, o) in robot.keyframes.iter().zip(&b.robots[1].keyframes) {
        assert_eq!((k.index, &k.descriptor), (o.index, &o.descriptor));
        assert_close(&k.map_from_sensor, &o.map_from_sensor, 1e-12);
    }
    for keyframe in &robot.keyframes {
        assert_eq!(
            read_keyframe_cloud(&joined_dir, robot, keyframe).unwrap().len(),
            cloud(1, keyframe.index).len()
        );
    }
    assert!(robot.graph.vertices.keys().all(|id| id / 1_000_000 == 3));
    assert!(robot.graph.edges.iter().all(|e| e.from / 1_000_000 == 3));
    // Copied cloud files are the first session's, byte for byte.
    let name = skid_session::cloud_file(4);
    assert_eq!(
        std::fs::read(joined_dir.join("robot1").join(&name)).unwrap(),
        std::fs::read(first.path().join("robot1").join(&name)).unwrap()
    );

    // A session described otherwise cannot join, and no join overwrites one of its parts.
    let mut other = b.clone();
    other.descriptor.as_mut().unwrap().params = serde_json::json!({"num_range": 20, "fov_up_deg": 2.0});
    let parts = [
        skid_session::JoinPart {
            session: &a,
            placements: vec![],
            clouds: skid_session::PartClouds::Folder(first.path()),
            foreign_vertices: Default::default(),
        },
        skid_session::JoinPart {
            session: &other,
            placements: vec![],
            clouds: skid_session::PartClouds::Memory(&b_cloud_of),
            foreign_vertices: Default::default(),
        },
    ];
    let error = skid_session::write_joined(&out.path().join("other"), "x", &parts)
        .err()
        .unwrap()
        .to_string();
    assert!(error.contains("num_range"), "{error}");
    let error = skid_session::write_joined(first.path(), "x", &parts[..1])
        .err()
        .unwrap()
        .to_string();
    assert!(error.contains("overwrite"), "{error}");
}
