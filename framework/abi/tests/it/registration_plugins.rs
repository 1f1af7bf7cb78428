//! Plugins of every slot across the C ABI: the Rust examples' KITTI source, KISS-ICP odometry, PCM
//! verifier and pose-graph back-end against their built-ins or suites, and registration: the C++ example (`point_to_plane_icp`, built by
//! skid-example-cpp's build script) and the Rust example (`gicp_cdylib`) pass the fine slot's
//! conformance suite when loaded, the Rust one gives the built-in GICP's result on a real scan pair, and
//! a C fixture compiled here with the system C compiler shows that what a plugin returns is checked: a
//! null table entry, a prepared cloud claiming more points than it was given, a failure text longer
//! than its buffer, a non-rigid transform.

// Each test binary uses a different part of the shared support module.
#[allow(dead_code)]
use crate::support;

use std::path::{Path, PathBuf};
use std::process::Command;

use skid_abi::{AbiError, load_library};
use skid_core::slots::FineRegistration;
use skid_core::{CloudView, Params, PluginContext, Pose, Registry};
use skid_testkit::registration::{RegistrationExpectations, check_fine};
use support::library;

fn fine(registry: &Registry, name: &str, config: &str) -> Box<dyn FineRegistration> {
    let params = Params::from_toml_str(config).unwrap();
    registry
        .fine
        .create(name, &params, &PluginContext::default())
        .unwrap()
}

const EXPECT: RegistrationExpectations = RegistrationExpectations {
    max_translation_error_m: 0.05,
    max_rotation_error_deg: 0.5,
};

#[test]
fn the_cpp_point_to_plane_icp_passes_the_fine_conformance_suite() {
    let mut registry = Registry::new();
    let plugin = load_library(skid_example_cpp::LIBRARY_PATH).unwrap();
    assert_eq!(plugin.name(), "skid-example-cpp");
    plugin.register(&mut registry).unwrap();
    let mut icp = fine(&registry, "point_to_plane_icp", "");
    check_fine(icp.as_mut(), 1.0, 10.0, EXPECT);

    let error = registry
        .validate(
            skid_core::Slot::Fine,
            "point_to_plane_icp",
            &Params::from_toml_str("num_neighbours = 5").unwrap(),
        )
        .unwrap_err();
    assert!(
        error.to_string().contains("num_neighbours") && error.to_string().contains("unknown key"),
        "{error}"
    );
    let error = registry
        .validate(
            skid_core::Slot::Fine,
            "point_to_plane_icp",
            &Params::from_toml_str("max_iterations = 0").unwrap(),
        )
        .unwrap_err();
    assert!(error.to_string().contains("max_iterations"), "{error}");
}

#[test]
fn gicp_through_the_abi_conforms_and_equals_the_built_in_on_a_real_pair() {
    let mut registry = Registry::new();
    let example = load_library(library("skid-example-cdylib")).unwrap();
    let names: Vec<&str> = example.plugins().iter().map(|plugin| plugin.name()).collect();
    assert_eq!(
        names,
        [
            "kitti_cdylib",
            "kiss_icp_cdylib",
            "ring_histogram",
            "gicp_cdylib",
            "pcm_cdylib",
            "pgo_cdylib"
        ]
    );
    example.register(&mut registry).unwrap();
    skid_fine_gicp::register(&mut registry).unwrap();
    let mut loaded = fine(&registry, "gicp_cdylib", "");
    check_fine(loaded.as_mut(), 1.0, 10.0, EXPECT);

    let mut built_in = fine(&registry, "gicp", "");
    let (target, source) = (support::kitti_scan(0), support::kitti_scan(5));
    let guess = Pose::translation(2.0, 0.0, 0.0);
    let mut results = Vec::new();
    for registration in [&mut built_in, &mut loaded] {
        let prepared_target = registration.prepare(CloudView::new(&target)).unwrap();
        let prepared_source = registration.prepare(CloudView::new(&source)).unwrap();
        results.push((
            prepared_source.cloud.len(),
            registration
                .refine(&prepared_target, &prepared_source, &guess)
                .unwrap(),
        ));
    }
    assert_eq!(results[0].0, results[1].0, "the same downsampled cloud");
    let (a, b) = (&results[0].1, &results[1].1);
    assert!(a.converged && b.converged);
    assert_eq!(a.iterations, b.iterations);
    assert!(
        (a.target_from_source.to_homogeneous() - b.target_from_source.to_homogeneous())
            .abs()
            .max()
            < 1e-9
    );
    assert!((a.information - b.information).abs().max() <= 1e-9 * a.information.abs().max());
}

/// Compiles the C fixture into a library named `name`, with extra compiler arguments.
fn compile_fixture(name: &str, extra: &[&str]) -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("lib{name}.so"));
    let compiler = std::env::var("CC").unwrap_or_else(|_| "cc".to_owned());
    let status = Command::new(&compiler)
        .args([
            "-std=c11", "-O1", "-fPIC", "-shared", "-Wall", "-Wextra", "-Werror",
        ])
        .args(extra)
        .arg("-I")
        .arg(root.join("include"))
        .arg("-o")
        .arg(&out)
        .arg(root.join("tests/c/broken_fine.c"))
        .status()
        .unwrap_or_else(|error| panic!("running the C compiler `{compiler}`: {error}"));
    assert!(status.success(), "compiling the C fixture failed");
    out
}

#[test]
fn kiss_icp_through_the_abi_conforms_and_follows_the_built_in_on_kitti() {
    let mut registry = Registry::new();
    load_library(library("skid-example-cdylib"))
        .unwrap()
        .register(&mut registry)
        .unwrap();
    skid_odometry_kiss::register(&mut registry).unwrap();
    let context = PluginContext::default();
    let make = |name: &str| {
        registry
            .odometry
            .create(name, &Params::default(), &context)
            .unwrap()
    };
    skid_testkit::odometry::check_odometry(
        || make("kiss_icp_cdylib"),
        skid_testkit::odometry::OdometryExpectations::default(),
    );

    let (mut built_in, mut loaded) = (make("kiss_icp"), make("kiss_icp_cdylib"));
    let mut keyframes = 0;
    for frame in 0..16 {
        let scan = skid_core::Scan {
            robot: skid_core::RobotId(0),
            sequence: frame,
            stamp_nanos: u64::from(frame) * 100_000_000,
            points: support::kitti_scan(frame)
                .iter()
                .map(|p| {
                    skid_core::RawPoint::new(
                        p.x,
                        p.y,
                        p.z,
                        p.intensity,
                        0.0,
                        skid_core::RawPoint::UNKNOWN_RING,
                    )
                })
                .collect(),
            ..skid_core::Scan::default()
        };
        let (a, b) = (built_in.register(&scan).unwrap(), loaded.register(&scan).unwrap());
        assert!(
            (a.world_from_sensor.to_homogeneous() - b.world_from_sensor.to_homogeneous())
                .abs()
                .max()
                < 1e-9,
            "frame {frame}: the same code gives the same pose"
        );
        assert_eq!(a.keyframe.is_some(), b.keyframe.is_some(), "frame {frame}");
        if let (Some(a), Some(b)) = (a.keyframe, b.keyframe) {
            assert_eq!(a.id, b.id);
            assert_eq!(a.cloud.points, b.cloud.points);
            keyframes += 1;
        }
    }
    assert!(
        keyframes >= 2,
        "KITTI's first 16 frames drive about 13 m: {keyframes} keyframes"
    );
}

#[test]
fn the_kitti_source_through_the_abi_conforms_and_reads_what_the_built_in_reads() {
    let mut registry = Registry::new();
    load_library(library("skid-example-cdylib"))
        .unwrap()
        .register(&mut registry)
        .unwrap();
    skid_source_files::register(&mut registry).unwrap();
    let context = PluginContext::default();
    let make = |name: &str| {
        registry
            .source
            .create(name, &Params::default(), &context)
            .unwrap()
    };
    let mut loaded = make("kitti_cdylib");
    assert_eq!(loaded.remaining_hint(), Some(16));
    assert!(!loaded.provides_imu());
    assert_eq!(skid_testkit::source::check_source(loaded.as_mut(), 100), 16);

    let (mut built_in, mut loaded) = (make("kitti"), make("kitti_cdylib"));
    while let Some(expected) = built_in.next_scan().unwrap() {
        let scan = loaded
            .next_scan()
            .unwrap()
            .expect("as many scans as the built-in");
        assert_eq!(
            (scan.sequence, scan.stamp_nanos),
            (expected.sequence, expected.stamp_nanos)
        );
        assert_eq!(scan.points, expected.points);
        assert_eq!(
            scan.ground_truth_world_from_sensor.is_some(),
            expected.ground_truth_world_from_sensor.is_some()
        );
    }
    assert!(loaded.next_scan().unwrap().is_none(), "and no more");
}

#[test]
fn pcm_through_the_abi_passes_the_verifier_suite() {
    let mut registry = Registry::new();
    load_library(library("skid-example-cdylib"))
        .unwrap()
        .register(&mut registry)
        .unwrap();
    let mut verifier = registry
        .verifier
        .create("pcm_cdylib", &Params::default(), &PluginContext::default())
        .unwrap();
    // The suite submits consistent loops and one that is not, through a graph the host lends by callback.
    skid_testkit::verifier::check_verifier(verifier.as_mut());
}

#[test]
fn the_pose_graph_back_end_through_the_abi_passes_the_back_end_suite() {
    let mut registry = Registry::new();
    load_library(library("skid-example-cdylib"))
        .unwrap()
        .register(&mut registry)
        .unwrap();
    let mut backend = registry
        .backend
        .create("pgo_cdylib", &Params::default(), &PluginContext::default())
        .unwrap();
    // The suite builds a graph, closes a loop, reads poses and odometry back through the graph view (each
    // a call into the plugin), and removes the loop again.
    skid_testkit::backend::check_backend(backend.as_mut());
}

#[test]
fn a_library_with_a_null_table_entry_is_refused_naming_the_plugin() {
    let path = compile_fixture("skid_fixture_null_entry", &["-DSKID_FIXTURE_NULL_ENTRY"]);
    let error = load_library(&path).unwrap_err();
    assert!(matches!(error, AbiError::Malformed { .. }), "{error}");
    let text = error.to_string();
    assert!(
        text.contains("`liar`") && text.contains("fine function table has a null entry"),
        "{text}"
    );
    assert!(
        text.contains("libskid_fixture_null_entry.so"),
        "the library is named: {text}"
    );
}

#[test]
fn an_entry_exported_as_data_is_refused_instead_of_called() {
    // The fixture's other functions go unused in this build, which the warnings flags would refuse.
    let path = compile_fixture(
        "skid_fixture_entry_as_data",
        &[
            "-DSKID_FIXTURE_ENTRY_AS_DATA",
            "-DSKID_PLUGIN_ENTRY_DECLARED",
            "-Wno-error",
        ],
    );
    let error = load_library(&path).unwrap_err();
    assert!(matches!(error, AbiError::Malformed { .. }), "{error}");
    let text = error.to_string();
    assert!(
        text.contains("`skid_plugin_entry` is data, not a function")
            && text.contains("libskid_fixture_entry_as_data.so"),
        "{text}"
    );
}

#[test]
fn a_library_built_for_another_wire_layout_is_refused_before_its_plugins_are_read() {
    let path = compile_fixture("skid_fixture_wrong_layout", &["-DSKID_FIXTURE_WRONG_LAYOUT"]);
    let error = load_library(&path).unwrap_err();
    assert!(matches!(error, AbiError::Layout { .. }), "{error}");
    let text = error.to_string();
    assert!(
        text.contains("wire type layout mismatch") && text.contains("libskid_fixture_wrong_layout.so"),
        "{text}"
    );
}

#[test]
fn what_a_plugin_returns_is_checked_before_it_reaches_the_pipeline() {
    let path = compile_fixture("skid_fixture_liar", &[]);
    let mut registry = Registry::new();
    load_library(&path).unwrap().register(&mut registry).unwrap();
    let cloud = support::kitti_scan(0);
    let guess = Pose::translation(0.5, 0.0, 0.0);

    let mut honest = fine(&registry, "liar", "");
    let prepared = honest.prepare(CloudView::new(&cloud[..1000])).unwrap();
    assert_eq!(prepared.cloud.len(), 1000);
    let result = honest.refine(&prepared, &prepared, &guess).unwrap();
    assert!(result.converged && result.failure.is_none());
    assert_eq!(result.target_from_source, guess);

    let mut overcounting = fine(&registry, "overcounting_liar", "");
    let error = overcounting
        .prepare(CloudView::new(&cloud[..1000]))
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("claims 1001 points") && error.contains("cloud of 1000"),
        "{error}"
    );
    let error = overcounting
        .refine(&prepared, &prepared, &guess)
        .unwrap_err()
        .to_string();
    assert!(error.contains("another plugin prepared"), "{error}");

    for (behaviour, expected) in [
        ("long_failure", "failure text of"),
        ("scaled", "not a rotation"),
        ("fails", "the liar gives up"),
    ] {
        let mut liar = fine(&registry, "liar", &format!("behaviour = \"{behaviour}\""));
        let prepared = liar.prepare(CloudView::new(&cloud[..1000])).unwrap();
        let error = liar.refine(&prepared, &prepared, &guess).unwrap_err().to_string();
        assert!(
            error.contains(expected) && error.contains("liar"),
            "{behaviour}: {error}"
        );
    }
}

/// Runs the two-thread fine check on the fixture's `liar` with a racy shared scratch buffer, from the
/// library at `path`; the panic message when the check fails.
fn racy_liar_under_threads(path: &Path) -> Option<String> {
    let liar = load_library(path).unwrap().plugin("liar").unwrap();
    let params = Params::from_toml_str("behaviour = \"racy\"").unwrap();
    let make = || -> Box<dyn FineRegistration> {
        Box::new(
            liar.create_fine(&params, &PluginContext::default())
                .unwrap()
                .unwrap(),
        )
    };
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        skid_testkit::threads::fine_instances_agree_under_threads(make)
    }))
    .err()
    .map(|payload| payload.downcast_ref::<String>().cloned().unwrap_or_default())
}

#[test]
fn shared_state_is_caught_under_threads_unless_the_plugin_declares_itself_serial() {
    let independent = compile_fixture("skid_fixture_racy", &[]);
    assert!(
        !load_library(&independent)
            .unwrap()
            .plugin("liar")
            .unwrap()
            .is_serial()
    );
    let failure = racy_liar_under_threads(&independent)
        .expect("instances sharing a scratch buffer disagree when they run at the same time");
    assert!(
        failure.contains("differs from the same call alone") && failure.contains("declaring itself serial"),
        "{failure}"
    );

    let serial = compile_fixture("skid_fixture_serial", &["-DSKID_FIXTURE_SERIAL"]);
    assert!(load_library(&serial).unwrap().plugin("liar").unwrap().is_serial());
    assert_eq!(
        racy_liar_under_threads(&serial),
        None,
        "the host keeps a serial plugin's calls apart"
    );
}

#[test]
fn a_plugin_pinned_to_its_creating_thread_is_refused_naming_the_library_and_plugin() {
    let path = compile_fixture("skid_fixture_pinned", &["-DSKID_FIXTURE_PINNED"]);
    let error = load_library(&path).unwrap_err();
    assert!(matches!(error, AbiError::Threading { .. }), "{error}");
    let text = error.to_string();
    assert!(
        text.contains("libskid_fixture_pinned.so")
            && text.contains("`liar`")
            && text.contains("stay on the thread that created it"),
        "{text}"
    );
}

/// A C file that includes the header (twice) and defines the entry point as the header documents it
/// compiles as strict C99 and as C++17, every warning an error.
#[test]
fn the_header_compiles_as_strict_c99_and_as_cpp17() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let compilers = [
        (
            std::env::var("CC").unwrap_or_else(|_| "cc".to_owned()),
            ["-std=c99", "-x", "c"],
        ),
        (
            std::env::var("CXX").unwrap_or_else(|_| "c++".to_owned()),
            ["-std=c++17", "-x", "c++"],
        ),
    ];
    for (compiler, language) in compilers {
        let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("strict_header{}.o", language[0]));
        let output = Command::new(&compiler)
            .args(language)
            .args(["-Wall", "-Wextra", "-pedantic", "-Werror", "-c"])
            .arg("-I")
            .arg(root.join("include"))
            .arg("-o")
            .arg(&out)
            .arg(root.join("tests/c/strict_header.c"))
            .output()
            .unwrap_or_else(|error| panic!("running the compiler `{compiler}`: {error}"));
        assert!(
            output.status.success(),
            "{compiler} {language:?} refused the header:\n{}",
            String::from_utf8_lossy(&output.stderr)
        );
    }
}
