//! `skid plugins --check LIB`: loads an out-of-tree plugin library and runs each of its plugins through
//! its slot's conformance suite (skid-testkit, the same checks the built-in plugins' tests run), reporting
//! pass or fail per check with the reason and the time taken, so that a researcher knows their plugin is a
//! good citizen before a long run.
//!
//! A suite's checks are assertions; each runs under `catch_unwind` with the panic hook silenced, and a
//! failed assertion becomes a FAIL line. A plugin that panics inside a call cannot reach here: the C ABI
//! turns that into an error, which fails the check that made the call.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use skid_abi::LoadedPlugin;
use skid_core::{PluginContext, Slot};
use skid_testkit::backend::check_backend;
use skid_testkit::descriptor::{DescriptorExpectations, check_descriptor};
use skid_testkit::odometry::{OdometryExpectations, check_odometry};
use skid_testkit::registration::{RegistrationExpectations, coarse_checks, fine_checks};
use skid_testkit::source::check_source;
use skid_testkit::threads::{
    coarse_instances_agree_under_threads, descriptor_instances_agree_under_threads,
    fine_instances_agree_under_threads,
};
use skid_testkit::verifier::check_verifier;

/// The bar a fine registration must clear: the built-in GICP's (1 m and 10° off, back within 5 cm and 0.5°).
const FINE_PERTURBATION_M: f64 = 1.0;
const FINE_PERTURBATION_DEG: f64 = 10.0;
const FINE_EXPECT: RegistrationExpectations = RegistrationExpectations {
    max_translation_error_m: 0.05,
    max_rotation_error_deg: 0.5,
};

/// The bar a coarse registration must clear: the built-in KISS-Matcher's.
const COARSE_YAWS_DEG: [f64; 4] = [0.0, 45.0, 180.0, 270.0];
const COARSE_OFFSET_M: f64 = 10.0;
const COARSE_EXPECT: RegistrationExpectations = RegistrationExpectations {
    max_translation_error_m: 0.5,
    max_rotation_error_deg: 2.0,
};

/// The name of the check that runs two instances on two threads at once.
const TWO_THREADS: &str = "two instances on two threads at once give what each gives alone";

/// How many scans of a source the check reads at most.
const SOURCE_MAX_SCANS: usize = 200;

/// One check's outcome.
struct Outcome {
    check: String,
    failure: Option<String>,
    seconds: f64,
}

/// Runs the suites of every plugin in the library at `path`; fails when any check fails.
pub fn check_library(path: &Path) -> Result<()> {
    let library =
        skid_abi::load_library(path).with_context(|| format!("loading plugin library {}", path.display()))?;
    println!(
        "{} ({}, built for SKiD {}): {} plugin(s)",
        library.path().display(),
        library.name(),
        library.framework_version(),
        library.plugins().len()
    );
    let mut outcomes = Vec::new();
    for plugin in library.plugins() {
        let serial = if plugin.is_serial() {
            " (declared serial: the host runs one call into it at a time)"
        } else {
            ""
        };
        println!(
            "[{}] {}: {}{serial}",
            plugin.slot(),
            plugin.name(),
            plugin.summary()
        );
        outcomes.extend(check_plugin(&plugin));
    }
    let failed = outcomes
        .iter()
        .filter(|outcome| outcome.failure.is_some())
        .count();
    println!(
        "{} checks, {} passed, {failed} failed",
        outcomes.len(),
        outcomes.len() - failed
    );
    if failed > 0 {
        bail!("{failed} conformance check(s) failed for {}", path.display());
    }
    Ok(())
}

/// Runs `check` with panics caught and the default panic output silenced.
fn run_check(check: &str, body: impl FnOnce()) -> Outcome {
    let started = Instant::now();
    let previous_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let result = catch_unwind(AssertUnwindSafe(body));
    std::panic::set_hook(previous_hook);
    let failure = result.err().map(|payload| {
        payload
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| payload.downcast_ref::<&str>().map(|text| (*text).to_owned()))
            .unwrap_or_else(|| "the check failed without a message".to_owned())
    });
    let outcome = Outcome {
        check: check.to_owned(),
        failure,
        seconds: started.elapsed().as_secs_f64(),
    };
    match &outcome.failure {
        None => println!("  PASS  {} ({:.2} s)", outcome.check, outcome.seconds),
        Some(reason) => println!("  FAIL  {} ({:.2} s): {reason}", outcome.check, outcome.seconds),
    }
    outcome
}

/// A failed creation, as one failed check.
fn not_created(plugin: &str, error: impl std::fmt::Display) -> Vec<Outcome> {
    let outcome = Outcome {
        check: format!("`{plugin}` builds from its default parameters"),
        failure: Some(error.to_string()),
        seconds: 0.0,
    };
    println!("  FAIL  {}: {error}", outcome.check);
    vec![outcome]
}

/// The suite of one plugin's slot.
fn check_plugin(plugin: &LoadedPlugin) -> Vec<Outcome> {
    let name = plugin.name();
    let defaults = plugin.default_params().clone();
    let context = PluginContext::default();
    match plugin.slot() {
        Slot::Fine => match plugin.create_fine(&defaults, &context) {
            Some(Ok(mut fine)) => fine_checks(FINE_PERTURBATION_M, FINE_PERTURBATION_DEG, FINE_EXPECT)
                .into_iter()
                .map(|(check, body)| run_check(check, || body(&mut fine)))
                .chain(std::iter::once_with(|| {
                    run_check(TWO_THREADS, || {
                        fine_instances_agree_under_threads(|| {
                            Box::new(created(plugin.create_fine(&defaults, &context)))
                        })
                    })
                }))
                .collect(),
            Some(Err(error)) => not_created(name, error),
            None => Vec::new(),
        },
        Slot::Coarse => match plugin.create_coarse(&defaults, &context) {
            Some(Ok(mut coarse)) => coarse_checks(COARSE_YAWS_DEG.to_vec(), COARSE_OFFSET_M, COARSE_EXPECT)
                .into_iter()
                .map(|(check, body)| run_check(check, || body(&mut coarse)))
                .chain(std::iter::once_with(|| {
                    run_check(TWO_THREADS, || {
                        coarse_instances_agree_under_threads(|| {
                            Box::new(created(plugin.create_coarse(&defaults, &context)))
                        })
                    })
                }))
                .collect(),
            Some(Err(error)) => not_created(name, error),
            None => Vec::new(),
        },
        Slot::Backend => match plugin.create_backend(&defaults, &context) {
            Some(Ok(mut backend)) => vec![run_check(
                "closes a loop; removing it restores the odometry solution",
                || {
                    check_backend(&mut backend);
                },
            )],
            Some(Err(error)) => not_created(name, error),
            None => Vec::new(),
        },
        Slot::Verifier => match plugin.create_verifier(&defaults, &context) {
            Some(Ok(mut verifier)) => vec![run_check(
                "rejects an inconsistent loop among consistent ones",
                || {
                    check_verifier(&mut verifier);
                },
            )],
            Some(Err(error)) => not_created(name, error),
            None => Vec::new(),
        },
        Slot::Source => match plugin.create_source(&defaults, &context) {
            Some(Ok(mut source)) => vec![run_check(
                "scans in order, stamps non-decreasing, finite points, a clean end",
                || {
                    check_source(&mut source, SOURCE_MAX_SCANS);
                },
            )],
            Some(Err(error)) => not_created(name, error),
            None => Vec::new(),
        },
        Slot::Odometry => match plugin.create_odometry(&defaults, &context) {
            Some(Ok(_)) => vec![run_check("recovers a known motion; bad scans are errors", || {
                check_odometry(
                    || Box::new(created(plugin.create_odometry(&defaults, &context))),
                    OdometryExpectations::default(),
                )
            })],
            Some(Err(error)) => not_created(name, error),
            None => Vec::new(),
        },
        Slot::Descriptor => {
            if let Some(Err(error)) = plugin.create_descriptor(&defaults, &context) {
                return not_created(name, error);
            }
            // A yaw hint is optional across the ABI (the host's exact L2 index, used when a plugin brings
            // no index of its own, gives none), so the suite does not require one.
            let expect = DescriptorExpectations {
                yaw_hint_tolerance_deg: None,
                ..DescriptorExpectations::default()
            };
            let fresh = || -> Box<dyn skid_core::slots::Descriptor> {
                Box::new(created(plugin.create_descriptor(&defaults, &context)))
            };
            vec![
                run_check("yaw invariance, retrieval, degenerate clouds", || {
                    check_descriptor(fresh, &expect)
                }),
                run_check(TWO_THREADS, || descriptor_instances_agree_under_threads(fresh)),
            ]
        }
        other => not_created(
            name,
            format!("no conformance suite runs for the {other} slot through the C ABI"),
        ),
    }
}

/// An instance the suite made again after it was built once (the odometry and descriptor suites make a
/// fresh one per case); a failure now fails the check.
#[allow(clippy::expect_used)] // Inside a check: a panic is the check's way to fail, caught by `run_check`.
fn created<T>(made: Option<skid_core::PluginResult<T>>) -> T {
    made.expect("the same slot as before")
        .expect("builds from its default parameters")
}
