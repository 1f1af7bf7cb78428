//! A JRL dataset as the replay feeds it to SKiD's plugins: robots numbered in the file's order, pose
//! keys as keyframe ids, every robot's entries merged into one sequence of events by stamp, and each
//! factor turned into what the back-end and the verifier take (a keyframe with its initial pose,
//! odometry, a prior, a loop with its labels).
//!
//! Conventions. JRL between factors measure `key2` in `key1`'s frame with a covariance of the residual
//! `Log(Z⁻¹ T₁⁻¹ T₂)`, perturbed on the right, which is the information the back-end slot takes (the
//! reader has already put translation first). The verifier's odometry chains hold each step's covariance
//! perturbed on the left, in the earlier keyframe's frame: `Ad(Z) Σ Ad(Z)ᵀ`.

use std::collections::btree_map::Entry;
use std::collections::{BTreeMap, BTreeSet};

use skid_core::slots::{LoopClosure, OdometryMeasurement};
use skid_core::{Information, KeyframeId, LoopId, Pose, RobotId};
use skid_io::jrl::{JrlDataset, JrlFactor, JrlKey};

use crate::ReplayError;

/// What the file says of a loop.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoopLabel {
    /// The file lists it among the factors that may be wrong: it goes through the verifier.
    pub potential_outlier: bool,
    /// The file's label says it is wrong.
    pub outlier: bool,
}

/// One thing a robot learns at an event.
#[derive(Clone, Debug)]
pub enum Item {
    /// A new keyframe of the event's robot, at the file's initial estimate (or its odometry).
    Keyframe { id: KeyframeId, initial: Pose },
    /// Odometry between consecutive keyframes of the event's robot; `step_covariance` is the step's
    /// covariance perturbed on the left, as the verifier's chains hold it.
    Odometry {
        measurement: Box<OdometryMeasurement>,
        step_covariance: Box<Information>,
    },
    /// A prior on one of the event's robot's keyframes.
    Prior {
        id: KeyframeId,
        world_from_sensor: Pose,
        information: Information,
    },
    /// A loop the event's robot found (intra-robot, or with a peer).
    Loop { closure: LoopClosure, label: LoopLabel },
}

/// Everything one robot learns at one stamp (one entry of its list in the file).
#[derive(Clone, Debug)]
pub struct Event {
    pub stamp: u64,
    pub robot: RobotId,
    pub items: Vec<Item>,
}

/// One robot of the problem.
#[derive(Clone, Debug)]
pub struct ReplayRobot {
    pub letter: char,
    /// The reference trajectory by keyframe index.
    pub ground_truth: BTreeMap<u32, Pose>,
    /// The stamp (nanoseconds, the file's clock) of the entry that introduced each keyframe.
    pub stamps: BTreeMap<u32, u64>,
}

/// A problem ready to replay.
#[derive(Clone, Debug)]
pub struct ReplayProblem {
    pub name: String,
    /// Indexed by `RobotId`.
    pub robots: Vec<ReplayRobot>,
    /// Every robot's entries, ordered by stamp (ties in robot order, then in file order).
    pub events: Vec<Event>,
    /// Every loop's label, by id.
    pub labels: BTreeMap<LoopId, LoopLabel>,
}

impl ReplayProblem {
    /// Converts a dataset. Refused: more robots or pose indices than keyframe ids hold, a between factor
    /// of one robot's keyframes that is neither odometry between consecutive keyframes nor a loop, and
    /// factors naming a keyframe of the event's robot that no odometry or prior introduces.
    pub fn from_dataset(dataset: &JrlDataset) -> Result<Self, ReplayError> {
        let robot_of: BTreeMap<char, RobotId> = dataset
            .robots
            .iter()
            .enumerate()
            .map(|(index, robot)| {
                u32::try_from(index)
                    .map(|number| (robot.letter, RobotId(number)))
                    .map_err(|_| ReplayError::Unsupported(format!("{index} robots")))
            })
            .collect::<Result<_, _>>()?;
        let id_of = |key: JrlKey| -> Result<KeyframeId, ReplayError> {
            let robot = *robot_of.get(&key.robot()).ok_or_else(|| {
                ReplayError::Unsupported(format!("key {key} of a robot the file does not list"))
            })?;
            let index = u32::try_from(key.index()).map_err(|_| {
                ReplayError::Unsupported(format!(
                    "key {key}: pose indices above {} are not supported",
                    u32::MAX
                ))
            })?;
            Ok(KeyframeId { robot, index })
        };

        let mut robots = Vec::new();
        let mut sequences = Vec::new();
        let mut labels = BTreeMap::new();
        let mut next_loop = 0_u64;
        for (number, robot) in dataset.robots.iter().enumerate() {
            let own = RobotId(number as u32);
            // The robot's own poses from its part of the problem (which also holds its view of the peers'
            // poses its factors name).
            let own_values = |values: &BTreeMap<JrlKey, Pose>| -> Result<BTreeMap<u32, Pose>, ReplayError> {
                let mut own_values = BTreeMap::new();
                for (key, pose) in values {
                    let id = id_of(*key)?;
                    if id.robot == own {
                        own_values.insert(id.index, *pose);
                    }
                }
                Ok(own_values)
            };
            let ground_truth = own_values(&robot.ground_truth)?;
            let initial = own_values(&robot.initialization)?;
            let mut known: BTreeMap<u32, Pose> = BTreeMap::new();
            let mut stamps = BTreeMap::new();
            for entry in &robot.entries {
                let mut items = Vec::new();
                for measurement in &entry.measurements {
                    match &measurement.factor {
                        JrlFactor::Prior {
                            key,
                            world_from_pose,
                            covariance,
                        } => {
                            let id = id_of(*key)?;
                            if id.robot != own {
                                return Err(ReplayError::Unsupported(format!(
                                    "robot {}'s list holds a prior on {key}, another robot's pose",
                                    robot.letter
                                )));
                            }
                            if let Entry::Vacant(slot) = known.entry(id.index) {
                                let pose = initial.get(&id.index).copied().unwrap_or(*world_from_pose);
                                slot.insert(pose);
                                items.push(Item::Keyframe { id, initial: pose });
                            }
                            items.push(Item::Prior {
                                id,
                                world_from_sensor: *world_from_pose,
                                information: inverse(covariance, &key.to_string())?,
                            });
                        }
                        JrlFactor::Between {
                            target,
                            source,
                            target_from_source,
                            covariance,
                        } => {
                            let (target_id, source_id) = (id_of(*target)?, id_of(*source)?);
                            let information = inverse(covariance, &format!("{target} -> {source}"))?;
                            let consecutive = target_id.robot == source_id.robot
                                && target_id.robot == own
                                && target_id.index.abs_diff(source_id.index) == 1;
                            if consecutive && !measurement.potential_outlier {
                                // Odometry, forwards.
                                let (earlier, later, step, step_information) =
                                    if target_id.index < source_id.index {
                                        (target_id, source_id, *target_from_source, information)
                                    } else {
                                        // The residual turns into −Ad(Z) r: the information into
                                        // Ad(Z⁻¹)ᵀ Ω Ad(Z⁻¹).
                                        let back = target_from_source.inverse();
                                        let ad = skid_geometry::adjoint(&back);
                                        (source_id, target_id, back, ad.transpose() * information * ad)
                                    };
                                let Some(&earlier_pose) = known.get(&earlier.index) else {
                                    return Err(ReplayError::Unsupported(format!(
                                        "odometry {target} -> {source} starts at a pose robot {} has not reached",
                                        robot.letter
                                    )));
                                };
                                if let Entry::Vacant(slot) = known.entry(later.index) {
                                    let pose =
                                        initial.get(&later.index).copied().unwrap_or(earlier_pose * step);
                                    slot.insert(pose);
                                    items.push(Item::Keyframe {
                                        id: later,
                                        initial: pose,
                                    });
                                }
                                let right = step_information.try_inverse().unwrap_or(*covariance);
                                let ad = skid_geometry::adjoint(&step);
                                items.push(Item::Odometry {
                                    measurement: Box::new(OdometryMeasurement {
                                        target: earlier,
                                        source: later,
                                        target_from_source: step,
                                        information: step_information,
                                    }),
                                    step_covariance: Box::new(ad * right * ad.transpose()),
                                });
                            } else {
                                let id = LoopId(next_loop);
                                next_loop += 1;
                                let label = LoopLabel {
                                    potential_outlier: measurement.potential_outlier,
                                    outlier: measurement.outlier,
                                };
                                labels.insert(id, label);
                                items.push(Item::Loop {
                                    closure: LoopClosure {
                                        id,
                                        target: target_id,
                                        source: source_id,
                                        target_from_source: *target_from_source,
                                        information,
                                    },
                                    label,
                                });
                            }
                        }
                    }
                }
                for item in &items {
                    if let Item::Keyframe { id, .. } = item {
                        stamps.insert(id.index, entry.stamp);
                    }
                }
                sequences.push(Event {
                    stamp: entry.stamp,
                    robot: own,
                    items,
                });
            }
            robots.push(ReplayRobot {
                letter: robot.letter,
                ground_truth,
                stamps,
            });
        }
        // A stable sort keeps ties in robot order, then in file order.
        sequences.sort_by_key(|event| event.stamp);
        let problem = Self {
            name: dataset.name.clone(),
            robots,
            events: sequences,
            labels,
        };
        problem.check_loops_reach_keyframes()?;
        Ok(problem)
    }

    /// Every loop names keyframes that some robot's odometry or prior introduces.
    fn check_loops_reach_keyframes(&self) -> Result<(), ReplayError> {
        let introduced: BTreeSet<KeyframeId> = self
            .events
            .iter()
            .flat_map(|event| &event.items)
            .filter_map(|item| match item {
                Item::Keyframe { id, .. } => Some(*id),
                _ => None,
            })
            .collect();
        for item in self.events.iter().flat_map(|event| &event.items) {
            if let Item::Loop { closure, .. } = item
                && let Some(missing) = [closure.target, closure.source]
                    .into_iter()
                    .find(|id| !introduced.contains(id))
            {
                return Err(ReplayError::Unsupported(format!(
                    "a loop names keyframe {missing}, which no odometry or prior of its robot introduces"
                )));
            }
        }
        Ok(())
    }

    /// The number of keyframes of every robot.
    pub fn keyframe_count(&self) -> usize {
        self.events
            .iter()
            .flat_map(|event| &event.items)
            .filter(|item| matches!(item, Item::Keyframe { .. }))
            .count()
    }
}

/// The information of a covariance the reader checked positive definite.
fn inverse(covariance: &Information, what: &str) -> Result<Information, ReplayError> {
    covariance
        .try_inverse()
        .map(|information| (information + information.transpose()) * 0.5)
        .ok_or_else(|| ReplayError::Unsupported(format!("{what}: the covariance cannot be inverted")))
}
