//! End-to-end tests of dynamic plugins: the test builds the example and fixture cdylibs, loads them
//! through the host, registers them into a `Registry` and runs them on a real KITTI scan.

// Test helpers outside `#[test]` functions may unwrap: a failure there is a test failure.

use crate::support;

use skid_abi::{AbiError, load_library};
use skid_core::slots::DescriptorBuf;
use skid_core::{CloudView, KeyframeId, Params, PluginContext, PluginError, Registry, Slot};
use support::{kitti_scan, library, yawed};

fn l2(a: &DescriptorBuf, b: &DescriptorBuf) -> f64 {
    a.values
        .iter()
        .zip(&b.values)
        .map(|(x, y)| f64::from(x - y).powi(2))
        .sum::<f64>()
        .sqrt()
}

fn params(text: &str) -> Params {
    Params::from_toml_str(text).unwrap()
}

/// A registry holding the example plugin.
fn registry_with_example() -> Registry {
    let mut registry = Registry::new();
    let plugin = load_library(library("skid-example-cdylib")).unwrap();
    plugin.register(&mut registry).unwrap();
    registry
}

#[test]
fn example_plugin_registers_and_is_yaw_invariant_on_a_kitti_scan() {
    let registry = registry_with_example();
    let infos = registry.infos(Slot::Descriptor);
    assert_eq!(infos.len(), 1);
    assert_eq!(infos[0].name, "ring_histogram");
    assert!(
        infos[0].origin.contains("skid_example_cdylib"),
        "{}",
        infos[0].origin
    );
    assert_eq!(
        infos[0]
            .defaults
            .table()
            .get("num_rings")
            .and_then(|v| v.as_integer()),
        Some(20)
    );

    let mut descriptor = registry
        .descriptor
        .create("ring_histogram", &Params::default(), &PluginContext::default())
        .unwrap();
    assert_eq!(descriptor.kind(), "ring_histogram");
    let scan = kitti_scan(0);
    assert!(scan.len() > 100_000, "{} points", scan.len());
    let original = descriptor.describe(CloudView::new(&scan)).unwrap();
    assert_eq!(original.kind, "ring_histogram");
    assert_eq!(original.values.len(), 20 * 8);
    let total: f32 = original.values.iter().sum();
    assert!((total - 1.0).abs() < 1e-4, "fractions sum to {total}");

    let turned = descriptor.describe(CloudView::new(&yawed(&scan, 1.234))).unwrap();
    let elsewhere = descriptor.describe(CloudView::new(&kitti_scan(15))).unwrap();
    let (yaw_distance, place_distance) = (l2(&original, &turned), l2(&original, &elsewhere));
    eprintln!("ring histogram L2 distance: yawed copy {yaw_distance:.2e}, 13 m further {place_distance:.3e}");
    assert!(
        yaw_distance < 1e-3,
        "yawing the scan moved the descriptor by {yaw_distance}"
    );
    assert!(
        place_distance > 10.0 * yaw_distance,
        "13 m away: {place_distance}, yawed: {yaw_distance}"
    );

    let mut index = descriptor.new_index();
    index.insert(KeyframeId::new(0, 0), original).unwrap();
    index.insert(KeyframeId::new(0, 15), elsewhere).unwrap();
    let found = index.query(&turned, 2, &|_| false).unwrap();
    assert_eq!(found[0].id, KeyframeId::new(0, 0));
    assert_eq!(found.len(), 2);
    assert_eq!(index.len(), 2);
}

#[test]
fn the_plugins_own_index_retrieves_by_its_own_distance() {
    let registry = registry_with_example();
    let mut descriptor = registry
        .descriptor
        .create("ring_histogram", &Params::default(), &PluginContext::default())
        .unwrap();
    let (here, there) = (kitti_scan(0), kitti_scan(15));
    let (a, b) = (
        descriptor.describe(CloudView::new(&here)).unwrap(),
        descriptor.describe(CloudView::new(&there)).unwrap(),
    );
    let mut index = descriptor.new_index();
    index.insert(KeyframeId::new(0, 0), a.clone()).unwrap();
    index.insert(KeyframeId::new(0, 15), b.clone()).unwrap();
    assert_eq!(index.len(), 2);
    let found = index.query(&a, 5, &|_| false).unwrap();
    assert_eq!(found.len(), 2, "no more than stored");
    assert_eq!(found[0].id, KeyframeId::new(0, 0));
    let chi_squared: f64 = a
        .values
        .iter()
        .zip(&b.values)
        .map(|(&x, &y)| (f64::from(x), f64::from(y)))
        .filter(|(x, y)| x + y > 0.0)
        .map(|(x, y)| (x - y).powi(2) / (x + y))
        .sum();
    assert!(
        (found[1].distance - chi_squared).abs() < 1e-9 * chi_squared.max(1.0),
        "the plugin's chi-squared distance, not L2: {} vs {chi_squared} (L2 {})",
        found[1].distance,
        l2(&a, &b)
    );
    let excluded = index.query(&a, 5, &|id| id == KeyframeId::new(0, 0)).unwrap();
    assert_eq!(
        excluded.iter().map(|c| c.id).collect::<Vec<_>>(),
        [KeyframeId::new(0, 15)]
    );
    let other_kind = DescriptorBuf {
        kind: "solid".to_owned(),
        values: a.values.clone(),
    };
    assert!(
        index.insert(KeyframeId::new(1, 0), other_kind).is_err(),
        "another kind is refused"
    );
}

#[test]
fn a_bad_config_key_is_named() {
    let registry = registry_with_example();
    let error = registry
        .validate(Slot::Descriptor, "ring_histogram", &params("num_ringz = 12"))
        .unwrap_err();
    let PluginError::Params(param_error) = &error else {
        panic!("expected a parameter error, got {error}")
    };
    assert_eq!(param_error.path, "num_ringz");
    assert!(param_error.message.contains("num_rings"), "{error}");
    assert!(error.to_string().contains("num_ringz"), "{error}");

    let context = PluginContext::default();
    let Err(error) = registry
        .descriptor
        .create("ring_histogram", &params("num_bands = 0"), &context)
    else {
        panic!("a zero band count was accepted")
    };
    assert!(
        matches!(&error, PluginError::Params(e) if e.path == "num_bands"),
        "{error}"
    );
    assert!(
        registry
            .validate(Slot::Descriptor, "ring_histogram", &params("num_rings = 4"))
            .is_ok()
    );
}

#[test]
fn libraries_from_another_abi_or_without_entry_or_not_libraries_are_refused() {
    let error = load_library(library("skid-fixture-abi-wrong-version")).unwrap_err();
    assert!(
        matches!(
            error,
            AbiError::AbiVersion {
                plugin: 9999,
                host: skid_abi::ABI_VERSION,
                ..
            }
        ),
        "{error}"
    );
    assert!(
        error.to_string().contains(&format!(
            "plugin built for ABI v9999, host speaks v{}",
            skid_abi::ABI_VERSION
        )),
        "{error}"
    );

    let error = load_library(library("skid-fixture-abi-no-entry")).unwrap_err();
    assert!(matches!(error, AbiError::MissingSymbol { .. }), "{error}");
    assert!(error.to_string().contains("skid_plugin_entry"), "{error}");

    let not_a_library = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("not_a_plugin.so");
    std::fs::write(&not_a_library, "this is text, not an ELF file\n").unwrap();
    let error = load_library(&not_a_library).unwrap_err();
    assert!(matches!(error, AbiError::NotALibrary { .. }), "{error}");
    assert!(
        error.to_string().contains("not a loadable plugin library"),
        "{error}"
    );

    let error = load_library("/nonexistent/libnothing.so").unwrap_err();
    assert!(matches!(error, AbiError::NotFound { .. }), "{error}");
}

#[test]
fn a_descriptor_with_non_finite_values_is_refused_at_the_boundary_naming_the_plugin() {
    let mut registry = Registry::new();
    let plugin = load_library(library("skid-fixture-abi-panics")).unwrap();
    plugin.register(&mut registry).unwrap();
    let mut descriptor = registry
        .descriptor
        .create(
            "panicky",
            &params("panic_in = \"never\"\nnan_values = true"),
            &PluginContext::default(),
        )
        .unwrap();
    let points = kitti_scan(0);
    let Err(error) = descriptor.describe(CloudView::new(&points)) else {
        panic!("a NaN descriptor crossed the boundary");
    };
    let text = error.to_string();
    assert!(text.contains("panicky") && text.contains("finite"), "{text}");
}

#[test]
fn a_panicking_plugin_becomes_an_error_and_the_host_keeps_running() {
    let mut registry = Registry::new();
    let plugin = load_library(library("skid-fixture-abi-panics")).unwrap();
    plugin.register(&mut registry).unwrap();
    let context = PluginContext::default();
    let points = kitti_scan(0);

    let Err(error) = registry
        .descriptor
        .create("panicky", &params("panic_in = \"create\""), &context)
    else {
        panic!("create should have panicked")
    };
    assert!(
        matches!(&error, PluginError::Panicked { plugin, message } if plugin == "panicky" && message.contains("told to panic in create")),
        "{error}"
    );
    let error = registry
        .validate(Slot::Descriptor, "panicky", &params("panic_in = \"create\""))
        .unwrap_err();
    assert!(error.to_string().contains("panicked"), "{error}");

    let mut descriptor = registry
        .descriptor
        .create("panicky", &Params::default(), &context)
        .unwrap();
    let error = descriptor.describe(CloudView::new(&points)).unwrap_err();
    assert!(
        matches!(&error, PluginError::Panicked { message, .. } if message.contains("told to panic in describe")),
        "{error}"
    );
    assert!(
        error.to_string().contains("abi-panics/src/lib.rs:"),
        "the panic's location is reported: {error}"
    );
    let error = descriptor.describe(CloudView::new(&points)).unwrap_err();
    assert!(
        error.to_string().contains("create a new one"),
        "a poisoned instance must refuse calls: {error}"
    );
    drop(descriptor);

    let mut fresh = registry
        .descriptor
        .create("panicky", &params("panic_in = \"never\""), &context)
        .unwrap();
    let mean = fresh.describe(CloudView::new(&points)).unwrap();
    assert_eq!(mean.values.len(), 3);

    // The good plugin still loads and works in the same process.
    load_library(library("skid-example-cdylib"))
        .unwrap()
        .register(&mut registry)
        .unwrap();
    let mut good = registry
        .descriptor
        .create("ring_histogram", &Params::default(), &context)
        .unwrap();
    assert_eq!(good.describe(CloudView::new(&points)).unwrap().values.len(), 160);
}

#[test]
fn plugin_tracing_events_reach_the_host() {
    let registry = registry_with_example();
    let context = PluginContext {
        robot: skid_core::RobotId(3),
        ..PluginContext::default()
    };
    registry
        .descriptor
        .create("ring_histogram", &params("num_rings = 7"), &context)
        .unwrap();
    let events = support::capture::global().events();
    let ready = events
        .iter()
        .find(|event| event.fields.contains("ring histogram ready") && event.fields.contains("robot=3"))
        .unwrap_or_else(|| panic!("the plugin's event did not reach the host: {events:?}"));
    assert_eq!(ready.target, skid_abi::host::PLUGIN_TARGET);
    assert_eq!(ready.level, tracing::Level::INFO);
    assert!(
        ready.fields.contains("library=skid-example-cdylib"),
        "{}",
        ready.fields
    );
    assert!(
        ready.fields.contains("plugin_target=skid_example_cdylib"),
        "{}",
        ready.fields
    );
    assert!(ready.fields.contains("rings=7"), "{}", ready.fields);
}

#[test]
fn loading_twice_returns_the_same_plugin_and_registering_twice_is_refused() {
    let first = load_library(library("skid-example-cdylib")).unwrap();
    let second = load_library(library("skid-example-cdylib")).unwrap();
    assert_eq!(first.path(), second.path());
    assert_eq!(first.framework_version(), skid_abi::FRAMEWORK_VERSION);
    let mut registry = Registry::new();
    first.register(&mut registry).unwrap();
    let error = second.register(&mut registry).unwrap_err();
    assert!(
        matches!(
            &error,
            AbiError::Register {
                source: PluginError::DuplicatePlugin { .. },
                ..
            }
        ),
        "{error}"
    );
}
