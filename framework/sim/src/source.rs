//! The `sim` source: a robot driving its route through a generated world, producing scans with
//! per-point time offsets, IMU samples and exact ground truth, as a [`skid_core::slots::Source`] and as
//! a plain iterator.

use std::sync::Arc;

use serde::{Deserialize, Serialize};
use skid_core::slots::Source;
use skid_core::{PluginContext, PluginEntry, PluginError, PluginResult, Registry, RobotId, Scan};

use crate::SimError;
use crate::bodies::{Body, BodyShape, Peers};
use crate::gait::Profile;
use crate::imu::{ImuNoise, ImuSimulator};
use crate::mission::{Mission, plan_mission, plan_wander};
use crate::motion::{MotionSpec, trajectory};
use crate::rng::combine;
use crate::route::Route;
use crate::scan::{ScanNoise, simulate_sweep_among};
use crate::sensor::{SWEEP_PERIOD_S, Sensor};
use crate::sensor_errors::BeamErrors;
use crate::trajectory::Trajectory;
use crate::world::{World, WorldKind};

/// Largest fleet the simulator plans routes for.
pub const MAX_ROBOTS: u32 = 16;

/// How far the simulated sensors are from perfect.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum NoiseModel {
    /// The data sheets' errors (see [`crate::sensor_errors`] and [`ImuNoise`]).
    #[default]
    Datasheet,
    /// No errors: for tests that check geometry.
    Ideal,
}

/// Parameters of the `sim` source (`[source.sim]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct SimConfig {
    /// `planetary`, `cave`, `urban` or `blocks` (the urban grid made of identical blocks).
    pub world: String,
    /// Seeds the world, the routes and every noise stream.
    pub seed: u64,
    /// `vlp16`, `os1-32`, `os1-64`, `hdl64e` or `avia`.
    pub sensor: String,
    /// Fleet size, 1 to 16. Not a configuration key: in a run the fleet size is `run.robots` (one source
    /// of truth), and the export tools set it from their `--robots` flag.
    #[serde(skip)]
    pub robots: u32,
    /// What the fleet does: `explore_meet` (robots start apart, explore, cross at a junction and drive
    /// each other's paths backwards), `rendezvous`, `crossing`, `reverse`, `partial`, `loner` (one robot
    /// never meets the others), `shared_route` (patterns around one base walk) or `convoy` (one route
    /// the same way, robots a fixed gap apart).
    pub mission: Mission,
    /// The season the world is seen in: 0 is the world as `seed` generates it; another value changes its
    /// loose objects (the planetary world's rocks: 15 % gone, 30 % moved 0.5–3 m), the terrain and the
    /// roads staying, as a later visit to a mapped place finds it.
    pub season: u32,
    /// `wander`: the junction every robot starts at (an index into the world's road graph); unset, one
    /// `route_seed` picks.
    pub start_junction: Option<u32>,
    /// `wander`: varies the start, the roads taken and the sensors' noise without changing the world.
    pub route_seed: u64,
    /// Scans to produce; 0 = until the end of the route.
    pub frames: u32,
    /// Approximate route length.
    pub route_length_m: f64,
    /// Cruise speed (ground robots typically 0.5–2 m/s).
    pub speed_mps: f64,
    /// `ground` or `aerial`.
    pub profile: Profile,
    /// `datasheet`: the sensor's and the IMU's errors at their data sheets' values (range precision by
    /// signal-to-noise ratio, detection threshold, beam-angle errors, mixed returns at depth edges, IMU
    /// white noise and bias drift); `ideal`: exact ranges, angles and IMU samples, no dropouts or
    /// spurious returns (for tests that check geometry).
    pub noise: NoiseModel,
    /// Multiplies the sensor's range noise σ (0 = exact ranges).
    pub range_noise_scale: f64,
    /// Probability that a return is lost.
    pub dropout_rate: f64,
    /// Probability that a return is replaced by a spurious one (dust, multipath reflection).
    pub spurious_rate: f64,
    /// Attach IMU samples to scans.
    pub imu: bool,
    /// IMU noise; the IMU is ideal when `imu_noise` is false.
    pub imu_noise: bool,
    pub imu_model: ImuNoise,
    /// Where the IMU sits on the sensor: its pose in the LiDAR frame as `[x, y, z, roll, pitch, yaw]`
    /// (metres, degrees). Scans report the inverse as `imu_from_sensor`.
    pub imu_mount: [f64; 6],
    /// The IMU's clock runs this many seconds ahead of the LiDAR's (its stamps carry the offset).
    pub imu_clock_offset_s: f64,
    /// How far robots drive to the right of their route's centre line, metres (negative: to the left);
    /// unset = the world's default (urban 1.75, planetary 1.0, cave 0.3), so robots meeting on a route
    /// in opposite directions see it from different places.
    pub keep_right_m: Option<f64>,
    /// Threads for ray casting; 0 = the plugin context's budget.
    pub threads: usize,
    /// Render the fleet's other robots as solid bodies ([`crate::bodies`]): a robot's sweeps see the
    /// peers within its range and line of sight, as a field team's do.
    pub robot_bodies: bool,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            world: "planetary".to_owned(),
            seed: 7,
            sensor: "os1-64".to_owned(),
            robots: 3,
            noise: NoiseModel::Datasheet,
            mission: Mission::ExploreMeet,
            season: 0,
            start_junction: None,
            route_seed: 0,
            frames: 0,
            route_length_m: 600.0,
            speed_mps: 1.0,
            profile: Profile::Ground,
            range_noise_scale: 1.0,
            dropout_rate: 0.01,
            spurious_rate: 0.0005,
            imu: true,
            imu_noise: true,
            imu_model: ImuNoise::default(),
            imu_mount: [0.0; 6],
            imu_clock_offset_s: 0.0,
            keep_right_m: None,
            threads: 0,
            robot_bodies: true,
        }
    }
}

impl SimConfig {
    /// The world this configuration sees (its kind, seed and season) and every robot's route in it: what
    /// the source drives and the preview draws.
    pub fn world_and_routes(&self, kind: WorldKind) -> (Arc<World>, Vec<Route>) {
        let world = World::shared_in_season(kind, self.seed, self.season);
        let routes = match self.mission {
            Mission::Wander => plan_wander(
                &world,
                self.seed,
                self.route_seed,
                self.start_junction.map(|junction| junction as usize),
                self.robots,
                self.route_length_m,
            ),
            mission => plan_mission(&world, mission, self.seed, self.robots, self.route_length_m),
        };
        (world, routes)
    }

    /// Checks every value, naming the first bad one.
    pub fn validate(&self) -> Result<(WorldKind, Sensor), SimError> {
        let kind: WorldKind = self.world.parse()?;
        let sensor = Sensor::by_name(&self.sensor)?;
        if self.robots == 0 || self.robots > MAX_ROBOTS {
            return Err(SimError::RobotCount {
                robots: self.robots,
                max: MAX_ROBOTS,
            });
        }
        let check = |ok: bool, key: &'static str, what: String| {
            if ok {
                Ok(())
            } else {
                Err(SimError::invalid(key, what))
            }
        };
        check(
            (0.1..=20.0).contains(&self.speed_mps),
            "speed_mps",
            format!("speed_mps = {} must be within 0.1–20 m/s", self.speed_mps),
        )?;
        check(
            (50.0..=5000.0).contains(&self.route_length_m),
            "route_length_m",
            format!(
                "route_length_m = {} must be within 50–5000 m",
                self.route_length_m
            ),
        )?;
        check(
            self.range_noise_scale >= 0.0 && self.range_noise_scale.is_finite(),
            "range_noise_scale",
            format!("range_noise_scale = {} must be ≥ 0", self.range_noise_scale),
        )?;
        for (name, rate) in [
            ("dropout_rate", self.dropout_rate),
            ("spurious_rate", self.spurious_rate),
        ] {
            check(
                (0.0..=1.0).contains(&rate),
                name,
                format!("{name} = {rate} must be within 0–1"),
            )?;
        }
        check(
            self.imu_model.rate_hz >= 10.0 && self.imu_model.rate_hz <= 2000.0,
            "imu_model.rate_hz",
            format!(
                "imu_model.rate_hz = {} must be within 10–2000",
                self.imu_model.rate_hz
            ),
        )?;
        check(
            self.imu_mount.iter().all(|v| v.is_finite())
                && self.imu_mount[..3].iter().all(|v| v.abs() <= 2.0),
            "imu_mount",
            format!(
                "imu_mount = {:?} must be finite, with a lever arm of at most 2 m per axis",
                self.imu_mount
            ),
        )?;
        check(
            self.imu_clock_offset_s.abs() <= 1.0,
            "imu_clock_offset_s",
            format!(
                "imu_clock_offset_s = {} must be within ±1 s",
                self.imu_clock_offset_s
            ),
        )?;
        if let Some(keep_right_m) = self.keep_right_m {
            check(
                keep_right_m.is_finite() && keep_right_m.abs() <= 3.0,
                "keep_right_m",
                format!("keep_right_m = {keep_right_m} must be within ±3 m"),
            )?;
        }
        Ok((kind, sensor))
    }

    /// The IMU's pose in the sensor frame.
    pub fn sensor_from_imu(&self) -> skid_core::Pose {
        let [x, y, z, roll, pitch, yaw] = self.imu_mount;
        skid_core::Pose::from_parts(
            nalgebra::Translation3::new(x, y, z),
            nalgebra::UnitQuaternion::from_euler_angles(
                roll.to_radians(),
                pitch.to_radians(),
                yaw.to_radians(),
            ),
        )
    }

    /// The scan degradations of a unit of `sensor` whose beam-angle errors are drawn from `unit_seed`.
    pub fn scan_noise(&self, sensor: &Sensor, unit_seed: u64) -> ScanNoise {
        match self.noise {
            NoiseModel::Ideal => ScanNoise::NONE,
            NoiseModel::Datasheet => ScanNoise {
                range_noise_scale: self.range_noise_scale,
                dropout_rate: self.dropout_rate,
                spurious_rate: self.spurious_rate,
                mixed_returns: true,
                beam_errors: BeamErrors::drawn(sensor, 1.0, unit_seed),
            },
        }
    }

    /// The IMU's noise, `None` for a perfect IMU.
    pub fn imu_noise(&self) -> Option<ImuNoise> {
        (self.imu_noise && self.noise == NoiseModel::Datasheet).then_some(self.imu_model)
    }

    /// The motion parameters.
    pub fn motion(&self) -> MotionSpec {
        let kind = self.world.parse().unwrap_or(WorldKind::Planetary);
        MotionSpec {
            speed_mps: self.speed_mps,
            profile: self.profile,
            keep_right_m: self
                .keep_right_m
                .unwrap_or_else(|| MotionSpec::default_keep_right_m(kind)),
            ..MotionSpec::default()
        }
    }
}

/// One simulated robot.
pub struct SimSource {
    world: Arc<World>,
    sensor: Sensor,
    route: Route,
    trajectory: Arc<Trajectory>,
    robot: RobotId,
    noise: ScanNoise,
    imu: Option<ImuSimulator>,
    imu_from_sensor: skid_core::Pose,
    key: u64,
    next_sequence: u32,
    scan_count: u32,
    pool: Option<rayon::ThreadPool>,
    /// The other robots' bodies (empty with `robot_bodies = false` or a fleet of one).
    peers: Peers,
}

impl std::fmt::Debug for SimSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimSource")
            .field("robot", &self.robot)
            .field("sensor", &self.sensor.name)
            .field("next_sequence", &self.next_sequence)
            .finish()
    }
}

impl SimSource {
    /// Robot `robot` of the fleet described by `config`, casting rays on `threads` threads.
    pub fn new(config: &SimConfig, robot: u32, threads: usize) -> Result<Self, SimError> {
        let (kind, sensor) = config.validate()?;
        if robot >= config.robots {
            return Err(SimError::RobotIndex {
                index: robot,
                robots: config.robots,
            });
        }
        let (world, routes) = config.world_and_routes(kind);
        let motion = config.motion();
        let route = routes.get(robot as usize).cloned().ok_or(SimError::RobotIndex {
            index: robot,
            robots: config.robots,
        })?;
        let trajectory = Arc::new(trajectory(&world, &route, &motion));
        let peers = if config.robot_bodies {
            let shape = BodyShape::of(motion.profile, motion.mount_height_m);
            let bodies = routes
                .iter()
                .enumerate()
                .filter(|&(other, _)| other != robot as usize)
                .map(|(_, other)| Body {
                    trajectory: Arc::new(crate::motion::trajectory(&world, other, &motion)),
                    shape,
                })
                .collect();
            Peers::new(bodies)
        } else {
            Peers::default()
        };
        // The last sweep must end before the trajectory does.
        let available = ((trajectory.end_s() - SWEEP_PERIOD_S) / SWEEP_PERIOD_S)
            .floor()
            .max(0.0) as u32;
        let scan_count = if config.frames == 0 {
            available
        } else {
            config.frames.min(available)
        };
        // The route seed varies the noise too (0 leaves it as it always was).
        let key = combine(combine(config.seed, 0x5ca1), u64::from(robot));
        let key = if config.route_seed == 0 {
            key
        } else {
            combine(key, config.route_seed)
        };
        let imu = config.imu.then(|| {
            ImuSimulator::new(config.imu_noise(), combine(key, 1))
                .mounted(config.sensor_from_imu(), config.imu_clock_offset_s)
        });
        let noise = config.scan_noise(&sensor, combine(key, 3));
        let pool = if threads > 1 {
            Some(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .map_err(|e| SimError::invalid("threads", format!("thread pool: {e}")))?,
            )
        } else {
            None
        };
        Ok(Self {
            world,
            sensor,
            route,
            trajectory,
            robot: RobotId(robot),
            noise,
            imu,
            imu_from_sensor: config.sensor_from_imu().inverse(),
            key,
            next_sequence: 0,
            scan_count,
            pool,
            peers,
        })
    }

    pub fn world(&self) -> &Arc<World> {
        &self.world
    }

    pub fn sensor(&self) -> &Sensor {
        &self.sensor
    }

    pub fn route(&self) -> &Route {
        &self.route
    }

    /// The ground-truth trajectory of the sensor frame.
    pub fn trajectory(&self) -> &Arc<Trajectory> {
        &self.trajectory
    }

    /// Scans this source produces in total.
    pub fn scan_count(&self) -> u32 {
        self.scan_count
    }

    /// Stamp of scan `sequence`.
    pub fn stamp_nanos(sequence: u32) -> u64 {
        u64::from(sequence) * (SWEEP_PERIOD_S * 1e9) as u64
    }

    /// Scan `sequence` without IMU samples, computed directly (any order; identical to the scan the
    /// iterator yields, whose IMU samples depend on the scans before it).
    pub fn scan_at(&self, sequence: u32) -> Scan {
        let stamp_nanos = Self::stamp_nanos(sequence);
        let sweep_start_s = stamp_nanos as f64 * 1e-9;
        let trajectory = Arc::clone(&self.trajectory);
        let poses = move |t: f64| trajectory.pose_at(t);
        let key = combine(self.key, u64::from(sequence) + 2);
        let points = match &self.pool {
            Some(pool) => pool.install(|| {
                simulate_sweep_among(
                    (&self.world, &self.peers),
                    &self.sensor,
                    &poses,
                    sweep_start_s,
                    &self.noise,
                    key,
                    true,
                )
            }),
            None => simulate_sweep_among(
                (&self.world, &self.peers),
                &self.sensor,
                &poses,
                sweep_start_s,
                &self.noise,
                key,
                false,
            ),
        };
        Scan {
            robot: self.robot,
            sequence,
            stamp_nanos,
            points,
            imu: Vec::new(),
            ground_truth_world_from_sensor: Some(self.trajectory.pose_at(sweep_start_s)),
            imu_from_sensor: Some(self.imu_from_sensor),
        }
    }

    /// The next scan, or `None` at the end of the route.
    pub fn next_sim_scan(&mut self) -> Option<Scan> {
        if self.next_sequence >= self.scan_count {
            return None;
        }
        let mut scan = self.scan_at(self.next_sequence);
        self.next_sequence += 1;
        if let Some(imu) = self.imu.as_mut() {
            scan.imu = imu.samples_until(&self.trajectory, scan.stamp_nanos);
        }
        Some(scan)
    }

    /// Skips `count` scans (their IMU samples are dropped too).
    pub fn skip_scans(&mut self, count: u32) {
        if count == 0 {
            return;
        }
        self.next_sequence = (self.next_sequence + count).min(self.scan_count);
        if let Some(imu) = self.imu.as_mut() {
            let _ = imu.samples_until(
                &self.trajectory,
                Self::stamp_nanos(self.next_sequence.saturating_sub(1)),
            );
        }
    }
}

impl Iterator for SimSource {
    type Item = Scan;

    fn next(&mut self) -> Option<Scan> {
        self.next_sim_scan()
    }
}

impl Source for SimSource {
    fn next_scan(&mut self) -> PluginResult<Option<Scan>> {
        Ok(self.next_sim_scan())
    }

    fn provides_imu(&self) -> bool {
        self.imu.is_some()
    }

    fn remaining_hint(&self) -> Option<usize> {
        Some((self.scan_count - self.next_sequence) as usize)
    }
}

/// Adds the `sim` source to `registry`.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    registry.source.register(PluginEntry::new(
        "sim",
        "Built-in LiDAR simulator: planetary/cave/urban worlds, VLP-16/OS1/HDL-64E/Avia, IMU and ground truth",
        |config: SimConfig, context: &PluginContext| {
            // Inside a run the fleet size is the run's (`run.robots`); `robots` serves the export tools.
            let config = SimConfig { robots: context.fleet_size.max(1), ..config };
            let threads = if config.threads == 0 { context.threads.max(1) } else { config.threads };
            Ok(Box::new(SimSource::new(&config, context.robot.0, threads)?) as Box<dyn Source>)
        },
    )?)
}

impl skid_core::PluginParams for SimConfig {
    fn check(&self) -> Result<(), skid_core::ParamError> {
        self.validate()
            .map(drop)
            .map_err(|error| match error.config_key() {
                Some(key) => skid_core::ParamError::at(key, error.to_string()),
                None => skid_core::ParamError::named_in(error.to_string()),
            })
    }
}
