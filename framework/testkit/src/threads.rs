//! Conformance under threads. SKiD calls one instance from one thread at a time, but it moves
//! instances between worker threads and, with several robots in one process, runs different instances
//! of the same plugin at the same time. A plugin whose instances share mutable state (a global scratch
//! buffer, a library that is not re-entrant) gives wrong answers then, silently. These checks catch it:
//! two instances, each with its own input, run on two threads at once, released together by a barrier,
//! must give what each gives when it runs alone.
//!
//! A plugin that cannot avoid shared state declares itself serial in its C ABI declaration, and the host
//! then runs one call into it at a time, which these checks also exercise.

use std::fmt::Debug;
use std::sync::Barrier;

use nalgebra::Vector3;
use skid_core::Cloud;
use skid_core::Pose;
use skid_core::slots::{CoarseRegistration, Descriptor, FineRegistration};

use crate::pose_error;
use crate::registration::synthetic_pair;
use crate::scene::{Scene, planar_pose};

/// How many times each thread repeats its call while the other runs.
const ROUNDS: usize = 4;

/// Runs `run` on a fresh instance for each input alone, then on two fresh instances on two threads at
/// once (each repeating its own input [`ROUNDS`] times), and asserts with `agree` that every concurrent
/// result matches the lone one.
pub fn instances_agree_under_threads<P, I, R>(
    make: impl Fn() -> P + Sync,
    inputs: &[I; 2],
    run: impl Fn(&mut P, &I) -> R + Sync,
    agree: impl Fn(&R, &R) -> Result<(), String>,
) where
    P: Send,
    I: Sync,
    R: Debug + Send,
{
    let alone: Vec<R> = inputs.iter().map(|input| run(&mut make(), input)).collect();
    let barrier = Barrier::new(inputs.len());
    let together: Vec<Vec<R>> = std::thread::scope(|scope| {
        let workers: Vec<_> = inputs
            .iter()
            .map(|input| {
                let mut instance = make();
                let (barrier, run) = (&barrier, &run);
                scope.spawn(move || {
                    barrier.wait();
                    (0..ROUNDS).map(|_| run(&mut instance, input)).collect()
                })
            })
            .collect();
        workers
            .into_iter()
            .map(|worker| worker.join().expect("a worker thread panicked"))
            .collect()
    });
    for (input, (lone, concurrent)) in alone.iter().zip(&together).enumerate() {
        for (round, result) in concurrent.iter().enumerate() {
            if let Err(difference) = agree(lone, result) {
                panic!(
                    "input {input}, round {round} on two threads at once differs from the same call alone: \
                     {difference}; does the plugin keep state shared by its instances without declaring itself serial?"
                );
            }
        }
    }
}

/// Fine registration: prepare and refine from two different guesses, on two threads at once.
pub fn fine_instances_agree_under_threads(make: impl Fn() -> Box<dyn FineRegistration> + Sync) {
    let (target, source, truth) = synthetic_pair(&planar_pose(2.0, 1.0, 1.8, 5f64.to_radians()), 20_000);
    let guesses = [
        truth * Pose::new(Vector3::new(0.5, 0.0, 0.0), Vector3::new(0.0, 0.0, 0.05)),
        truth * Pose::new(Vector3::new(0.0, -0.4, 0.1), Vector3::new(0.02, 0.0, -0.08)),
    ];
    instances_agree_under_threads(
        make,
        &guesses,
        |fine, guess| {
            let prepared_target = fine.prepare(target.view()).map_err(|error| error.to_string())?;
            let prepared_source = fine.prepare(source.view()).map_err(|error| error.to_string())?;
            fine.refine(&prepared_target, &prepared_source, guess)
                .map(|result| (result.target_from_source, result.converged))
                .map_err(|error| error.to_string())
        },
        |lone, concurrent| poses_agree(lone, concurrent, 1e-6),
    );
}

/// Coarse registration: two different unknown transforms, on two threads at once.
pub fn coarse_instances_agree_under_threads(make: impl Fn() -> Box<dyn CoarseRegistration> + Sync) {
    let pairs: [(Cloud, Cloud, Pose); 2] = [
        synthetic_pair(&planar_pose(8.0, 0.0, 1.8, 40f64.to_radians()), 10_000),
        synthetic_pair(&planar_pose(-6.0, 4.0, 1.8, 200f64.to_radians()), 10_000),
    ];
    instances_agree_under_threads(
        make,
        &pairs,
        |coarse, (target, source, _)| {
            coarse
                .align(target.view(), source.view(), None)
                .map(|result| (result.target_from_source, result.valid))
                .map_err(|error| error.to_string())
        },
        |lone, concurrent| poses_agree(lone, concurrent, 1e-4),
    );
}

/// Descriptors: two different places, described on two threads at once.
pub fn descriptor_instances_agree_under_threads(make: impl Fn() -> Box<dyn Descriptor> + Sync) {
    let scene = Scene::new(7, 120.0);
    let places = [
        scene.sample(&planar_pose(0.0, 0.0, 1.8, 0.0), 30_000, 80.0, 1),
        scene.sample(&planar_pose(25.0, 10.0, 1.8, 0.0), 30_000, 80.0, 2),
    ];
    instances_agree_under_threads(
        make,
        &places,
        |descriptor, cloud| {
            descriptor
                .describe(cloud.view())
                .map(|described| described.values)
                .map_err(|error| error.to_string())
        },
        |lone, concurrent| match (lone, concurrent) {
            (Ok(a), Ok(b)) if a.len() != b.len() => Err(format!("{} values against {}", b.len(), a.len())),
            (Ok(a), Ok(b)) => {
                let scale = a
                    .iter()
                    .fold(1e-12_f32, |largest, value| largest.max(value.abs()));
                let worst = a
                    .iter()
                    .zip(b)
                    .map(|(x, y)| (x - y).abs())
                    .fold(0.0_f32, f32::max);
                if worst <= 1e-5 * scale {
                    Ok(())
                } else {
                    Err(format!("values differ by up to {worst} (largest value {scale})"))
                }
            }
            (a, b) => same_outcome(a, b),
        },
    );
}

/// Two registration outcomes agree: both errors, or transforms within `tolerance` (metres and
/// degrees) with the same verdict.
fn poses_agree(
    lone: &Result<(Pose, bool), String>,
    concurrent: &Result<(Pose, bool), String>,
    tolerance: f64,
) -> Result<(), String> {
    match (lone, concurrent) {
        (Ok((a, a_verdict)), Ok((b, b_verdict))) => {
            let (translation_m, rotation_deg) = pose_error(a, b);
            if a_verdict != b_verdict {
                Err(format!("verdict {b_verdict} against {a_verdict} alone"))
            } else if translation_m > tolerance || rotation_deg > tolerance {
                Err(format!("off by {translation_m:.3e} m, {rotation_deg:.3e}°"))
            } else {
                Ok(())
            }
        }
        (a, b) => same_outcome(a, b),
    }
}

/// Outcomes of which at least one is an error agree only when both are.
fn same_outcome<T: Debug>(lone: &Result<T, String>, concurrent: &Result<T, String>) -> Result<(), String> {
    match (lone, concurrent) {
        (Err(_), Err(_)) => Ok(()),
        (Ok(_), Err(error)) => Err(format!("failed ({error}) where it succeeds alone")),
        (Err(error), Ok(_)) => Err(format!("succeeded where it fails alone ({error})")),
        (Ok(a), Ok(b)) => Err(format!("{b:?} against {a:?} alone")),
    }
}
