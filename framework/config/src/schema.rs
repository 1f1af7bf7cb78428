//! The shape of a SKiD configuration file: run and deploy sections, and one table per plugin slot.

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

/// The plugin name that leaves an optional slot empty (every slot but `source`).
pub const NONE_PLUGIN: &str = "none";

/// The plugin name of a slot's chooser (the odometry's `auto`): its defaults hold one table per plugin it
/// chooses between, and those tables are set as that plugin's own `[slot.plugin]` table.
pub const AUTO_PLUGIN: &str = "auto";

/// Most robots a fleet may have.
pub const MAX_ROBOTS: u32 = 16;

/// `[run]`: what to run and where to write it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RunSection {
    /// Name of the run; outputs go to `<output_dir>/<name>/`.
    pub name: String,
    /// Number of robots in the fleet (1 to 16).
    pub robots: u32,
    /// Seed for every random choice, so lockstep runs are reproducible.
    pub seed: u64,
    /// Worker threads for the whole host; 0 means one per core.
    pub threads: usize,
    /// Folder under which each run writes its own folder.
    pub output_dir: PathBuf,
    /// Stop each robot after this many scans; 0 means run until the source ends.
    pub max_scans: u64,
}

impl Default for RunSection {
    fn default() -> Self {
        Self {
            name: "default".to_owned(),
            robots: 3,
            seed: 7,
            threads: 0,
            output_dir: PathBuf::from("runs"),
            max_scans: 0,
        }
    }
}

/// How the robots and their stages are laid out on threads and processes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DeployMode {
    /// One thread runs every robot step by step; bit-for-bit reproducible.
    #[default]
    Lockstep,
    /// One process per robot, stages on threads.
    Threads,
    /// Stage groups in separate processes connected by shared memory.
    Processes,
}

/// `[deploy]`: the process model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DeploySection {
    pub mode: DeployMode,
    /// Run only this robot of the fleet (0-based, below `run.robots`) in this process, in real time,
    /// talking to its peers through the transport; unset runs the whole fleet.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub robot: Option<u32>,
    /// Single-robot mode: how fast scans are played relative to their stamps (1 = real time, 2 = twice
    /// as fast); 0 plays them as fast as the robot can process them.
    pub playback_speed: f64,
    /// Single-robot mode: the longest the robot keeps answering its peers after its source has ended, in
    /// seconds, so their late cloud requests and loops still get through; it stops sooner once every
    /// robot of the fleet says in its heartbeat that it is settled (source ended, nothing waited for).
    pub linger_s: f64,
}

impl Default for DeploySection {
    fn default() -> Self {
        Self {
            mode: DeployMode::default(),
            robot: None,
            playback_speed: 1.0,
            linger_s: 5.0,
        }
    }
}

impl DeploySection {
    /// Checks the section against the fleet size; the message names the offending key.
    pub fn validate(&self, robots: u32) -> Result<(), SectionError> {
        if let Some(robot) = self.robot
            && robot >= robots
        {
            return SectionError::at(
                "deploy.robot",
                format!(
                    "deploy.robot = {robot}, but the fleet has {robots} robot(s) (run.robots); expected 0 to {}",
                    robots.saturating_sub(1)
                ),
            );
        }
        if !(self.playback_speed.is_finite() && self.playback_speed >= 0.0) {
            return SectionError::at(
                "deploy.playback_speed",
                format!(
                    "deploy.playback_speed = {} must be finite and non-negative (0 = as fast as possible)",
                    self.playback_speed
                ),
            );
        }
        if !(self.linger_s.is_finite() && self.linger_s >= 0.0) {
            return SectionError::at(
                "deploy.linger_s",
                format!(
                    "deploy.linger_s = {} must be finite and non-negative",
                    self.linger_s
                ),
            );
        }
        Ok(())
    }
}

/// A value of a section that is out of range, with the key it is about.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{key}: {message}")]
pub struct SectionError {
    /// The full dotted key.
    pub key: &'static str,
    pub message: String,
}

impl SectionError {
    fn at(key: &'static str, message: String) -> Result<(), Self> {
        Err(Self { key, message })
    }
}

/// `[output]`: what a run writes besides its trajectories, metrics and plots.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OutputSection {
    /// Write `run.mcap`, the run record ROS 2 tools, Foxglove Studio and `rosbags` open: trajectories,
    /// keyframe clouds, the merged map, loop closures and the map frames.
    pub record: bool,
    /// Edge of the voxels the record's keyframe clouds are thinned with, metres (0 keeps every point).
    pub record_voxel_m: f64,
    /// Write `session/`, the run as a session a later run can relocalise in, grow or merge with
    /// (`skid-session`: every robot's keyframes, optimised poses, descriptors, clouds and pose graph).
    pub session: bool,
    /// Publish each robot's odometry, `/tf`, optimised path, map and loops live as ROS 2 topics over
    /// zenoh, the way `rmw_zenoh` (Jazzy) does, so RViz2 on a ROS 2 machine sees the running fleet.
    pub ros2: bool,
    /// Zenoh endpoints the live ROS 2 output connects to (a ROS 2 machine's `rmw_zenohd` router, e.g.
    /// `tcp/192.168.1.10:7447`).
    pub ros2_connect: Vec<String>,
    /// Endpoints it listens on, for ROS 2 nodes or a router to connect to.
    pub ros2_listen: Vec<String>,
    /// The ROS 2 domain id (`ROS_DOMAIN_ID`) the topics are published in.
    pub ros2_domain_id: u32,
    /// Publish the merged map every this many optimisations (it is also published at the end).
    pub ros2_map_every: u32,
    /// Edge of the voxels the live map is thinned with, metres.
    pub ros2_voxel_m: f64,
}

impl Default for OutputSection {
    fn default() -> Self {
        Self {
            record: true,
            record_voxel_m: 0.5,
            session: true,
            ros2: false,
            ros2_connect: Vec::new(),
            ros2_listen: Vec::new(),
            ros2_domain_id: 0,
            ros2_map_every: 5,
            ros2_voxel_m: 0.5,
        }
    }
}

impl OutputSection {
    /// Checks the section; the message names the offending key.
    pub fn validate(&self) -> Result<(), SectionError> {
        if !(self.record_voxel_m.is_finite() && self.record_voxel_m >= 0.0) {
            return SectionError::at(
                "output.record_voxel_m",
                format!(
                    "output.record_voxel_m = {} must be finite and non-negative (0 keeps every point)",
                    self.record_voxel_m
                ),
            );
        }
        if !(self.ros2_voxel_m.is_finite() && self.ros2_voxel_m > 0.0) {
            return SectionError::at(
                "output.ros2_voxel_m",
                format!(
                    "output.ros2_voxel_m = {} must be a positive number of metres",
                    self.ros2_voxel_m
                ),
            );
        }
        // rmw_zenoh accepts domain ids up to 232, as DDS does.
        if self.ros2_domain_id > 232 {
            return SectionError::at(
                "output.ros2_domain_id",
                format!(
                    "output.ros2_domain_id = {} must be within 0–232",
                    self.ros2_domain_id
                ),
            );
        }
        for (key, endpoints) in [
            ("output.ros2_connect", &self.ros2_connect),
            ("output.ros2_listen", &self.ros2_listen),
        ] {
            if let Some(endpoint) = endpoints.iter().find(|endpoint| !endpoint.contains('/')) {
                return SectionError::at(
                    key,
                    format!("`{endpoint}` is not a zenoh endpoint like `tcp/192.168.1.10:7447`"),
                );
            }
        }
        Ok(())
    }
}

/// `[loops]`: how the runtime turns descriptors into loop candidates and loops into graph updates.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LoopsSection {
    /// Look for loops with the robot's own earlier keyframes.
    pub intra_robot: bool,
    /// Look for loops with peers' keyframes.
    pub inter_robot: bool,
    /// Candidates retrieved per query.
    pub candidates: usize,
    /// Largest descriptor distance accepted as a candidate; 0 uses the descriptor's own threshold.
    pub max_descriptor_distance: f64,
    /// The robot's own most recent keyframes excluded from intra-robot queries.
    pub exclude_recent_keyframes: u32,
    /// Standard deviation of odometry edges between keyframes: translation (m) per metre travelled,
    /// with a floor of `odometry_sigma_min_m`, and rotation (degrees) per keyframe.
    pub odometry_sigma_per_m: f64,
    pub odometry_sigma_min_m: f64,
    pub odometry_sigma_rotation_deg: f64,
    /// Standard deviation of an accepted loop's measurement, translation (m) and rotation (degrees) per
    /// axis, as the verifier's consistency test weighs it; the back-end takes the translation σ and its
    /// own `backend_loop_sigma_rotation_deg` (this rotation σ when that is 0). A registration's own Hessian
    /// sums over thousands of points and would make a loop far more certain than it is, so a loop gets a
    /// fixed, honest value. The simulator's accepted loops are off by 0.04–0.12° per axis (RMS, with a
    /// tail to 1°) and the real HDL-32E pair by 0.24° after KISS-Matcher + GICP; the verifier's test
    /// needs that tail, hence 1°.
    pub loop_sigma_m: f64,
    pub loop_sigma_rotation_deg: f64,
    /// Rotation standard deviation (degrees per axis) with which the back-end weighs an accepted loop,
    /// when it differs from the one the verifier tests it with; 0 weighs it as `loop_sigma_rotation_deg`.
    /// The verifier's test needs the tail of a registration's error (the simulator's loops reach 1°),
    /// the back-end's least squares its typical size (0.04–0.12° RMS in the simulator, 0.24° on the real
    /// HDL-32E pair), beside the odometry's 0.2° per keyframe. At the default 0.25° the rotation a
    /// cycle of robots closes is spread along the odometry rather than left to the loops: sixteen robots
    /// chained five deep sit within 0.65 m by `T_β,APE` instead of 1.1 m at 1°. On three robots it costs
    /// the default run its direct merge of robots 0 and 1 (52 inter-robot loops instead of 65, robot 1
    /// placed through robot 2): the changed estimate changes the order of events, and PCM's prediction
    /// check then refutes that true set.
    pub backend_loop_sigma_rotation_deg: f64,
    /// Optimise the pose graph after this many new keyframes (and after every accepted loop).
    pub optimize_every_keyframes: u32,
    /// Iterations allowed per optimisation.
    pub optimize_iterations: usize,
    /// When the coarse registration reports its result invalid (too few inliers), still refine its
    /// estimate with the fine registration and let the verifier (truncated MSE, overlap, PCM) judge the
    /// loop, instead of dropping the candidate. Terrain with few distinct features (planetary) often
    /// leaves the coarse stage with too few inliers although its estimate is within the fine stage's
    /// basin.
    pub refine_invalid_coarse: bool,
    /// Refuse a loop whose coarse registration found a rival alignment (a distinct one, among the
    /// correspondences the best leaves out) with at least this fraction of the best one's inliers: a
    /// symmetric or repetitive place admits several alignments, and picking one there is how false
    /// inter-robot merges begin. 0 turns the test off (the default); at 1 only a rival as strong as the
    /// best refuses. Off by default because it is not yet selective enough: on the simulated registration
    /// table, 0.5 refuses no true pair on planetary or cave ground but 28 % of the true urban pairs (a
    /// street admits shifted alignments nearly as strong), and only 3 of 13 wrong urban ones; a ray-cast
    /// hall with 90° symmetry scores 0.62 and the real HDL-32E pair 0.
    pub ambiguous_rival_ratio: f64,
    /// Inter-robot candidates admitted to registration per budget period, and the most that may wait
    /// for a peer's cloud at once; the rest queue, best first (a robot not yet in this robot's frame,
    /// then a cloud already held or asked for, then the closest descriptor).
    pub inter_robot_budget: usize,
    /// The budget's period, seconds of robot time.
    pub budget_period_s: f64,
    /// A candidate still queued, or still waiting for its cloud, this many seconds after it was raised
    /// (or admitted) expires and is counted.
    pub candidate_expiry_s: f64,
    /// Most inter-robot candidates queued per robot; a full queue pushes out its worst.
    pub candidate_queue: usize,
    /// Grid step clouds are quantised to for peers, metres (each coordinate within half of it). The
    /// keyframes are 0.25 m voxel centroids, so a 5 cm grid changes registration by less than its noise.
    pub cloud_grid_m: f64,
    /// A cloud is sent to the same peer again only this many seconds after the first copy (longer than
    /// a link holds a message back, so the first copy must have been lost: the default link model
    /// queues a message up to 5 s, then a 26 kB cloud takes 4.2 s at its slowest rate, 50 kbit/s).
    pub cloud_resend_after_s: f64,
    /// Also send every loop this robot's verifier accepted (its intra-robot loops and those with peers)
    /// to every peer, and hold the loops peers send between other robots in the back-end once a second
    /// verifier of this robot's accepts them, placing a robot it has no loop with through the robots it
    /// has (Swarm-SLAM's fleet graph; Kimera-Multi shares what its outlier rejection kept). On by
    /// default: on COSMO-Bench's real problems it brings every robot of the distributed replay within
    /// 1.25× of GTSAM's centralised GNC, and with 16 robots it places every robot within 1 m of the
    /// truth. Off: a robot's graph holds its own loops and its loops with peers, each peer joined by its
    /// odometry alone (the paper's distributed graph), and its verifier and back-end do less work.
    pub fleet_loops: bool,
}

impl Default for LoopsSection {
    fn default() -> Self {
        Self {
            intra_robot: true,
            inter_robot: true,
            candidates: 3,
            max_descriptor_distance: 0.0,
            exclude_recent_keyframes: 30,
            odometry_sigma_per_m: 0.01,
            odometry_sigma_min_m: 0.01,
            odometry_sigma_rotation_deg: 0.2,
            loop_sigma_m: 0.1,
            loop_sigma_rotation_deg: 1.0,
            backend_loop_sigma_rotation_deg: 0.25,
            optimize_every_keyframes: 10,
            optimize_iterations: 30,
            refine_invalid_coarse: true,
            ambiguous_rival_ratio: 0.0,
            inter_robot_budget: 6,
            budget_period_s: 1.0,
            candidate_expiry_s: 30.0,
            candidate_queue: 64,
            cloud_grid_m: 0.05,
            cloud_resend_after_s: 10.0,
            fleet_loops: true,
        }
    }
}

impl LoopsSection {
    /// Checks the section; the message names the offending key.
    pub fn validate(&self) -> Result<(), SectionError> {
        if !(0.0..=1.0).contains(&self.ambiguous_rival_ratio) {
            return SectionError::at(
                "loops.ambiguous_rival_ratio",
                format!(
                    "loops.ambiguous_rival_ratio = {} must lie in [0, 1] (0 turns the ambiguity test off)",
                    self.ambiguous_rival_ratio
                ),
            );
        }
        if self.inter_robot_budget == 0 {
            return SectionError::at(
                "loops.inter_robot_budget",
                "loops.inter_robot_budget = 0 would verify no inter-robot candidate; set loops.inter_robot = false to turn them off"
                    .to_owned(),
            );
        }
        if self.backend_loop_sigma_rotation_deg != 0.0
            && !(1e-3..=90.0).contains(&self.backend_loop_sigma_rotation_deg)
        {
            return SectionError::at(
                "loops.backend_loop_sigma_rotation_deg",
                format!(
                    "loops.backend_loop_sigma_rotation_deg = {} must be 0 (as loops.loop_sigma_rotation_deg) or lie in [0.001, 90]",
                    self.backend_loop_sigma_rotation_deg
                ),
            );
        }
        if self.candidate_queue == 0 {
            return SectionError::at(
                "loops.candidate_queue",
                "loops.candidate_queue must hold at least one candidate".to_owned(),
            );
        }
        for (key, value, low, high) in [
            ("loops.budget_period_s", self.budget_period_s, 1e-3, 3600.0),
            (
                "loops.candidate_expiry_s",
                self.candidate_expiry_s,
                1e-3,
                86_400.0,
            ),
            ("loops.cloud_grid_m", self.cloud_grid_m, 1e-4, 0.5),
            ("loops.loop_sigma_m", self.loop_sigma_m, 1e-4, 100.0),
            (
                "loops.loop_sigma_rotation_deg",
                self.loop_sigma_rotation_deg,
                1e-3,
                90.0,
            ),
            (
                "loops.cloud_resend_after_s",
                self.cloud_resend_after_s,
                0.0,
                3600.0,
            ),
        ] {
            if !(low..=high).contains(&value) {
                return SectionError::at(key, format!("{key} = {value} must lie in [{low}, {high}]"));
            }
        }
        Ok(())
    }
}

/// What a run does with a prior session (`[prior] mode`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PriorMode {
    /// The prior is a map the robots place themselves in; it does not change.
    #[default]
    Localise,
    /// The robots localise in the prior as under `localise` and run full SLAM beside it (loops within
    /// each robot and between robots, as `own_loops = true`), and the run's session is the prior grown
    /// by them: the prior's robots as they were, then this run's robots, each placed in the prior's map
    /// frame where its localisation (or its fleet's) put it, or kept unplaced.
    Extend,
}

/// `[prior]`: a session an earlier run left, that this run's robots localise in (and, under `extend`,
/// grow).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PriorSection {
    /// The session folder (`runs/<name>/session`, or the run folder holding it); none when absent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub path: Option<PathBuf>,
    /// `localise`: every robot queries its keyframes against the prior's descriptors, registers and
    /// verifies the candidates as inter-robot loops with a peer that does not move, and is placed in the
    /// prior's map frame once the verifier grants a consistent set of them.
    pub mode: PriorMode,
    /// Also close loops within each robot and between the fleet's robots, as without a prior (full SLAM
    /// beside the localisation); off, a robot closes loops only with the prior, which is what a robot
    /// in a known map needs and costs far less.
    pub own_loops: bool,
    /// Once localised, a robot registers its candidates with the prior at every this many keyframes
    /// only (1: at every keyframe), enough to keep the placement current.
    pub track_every_keyframes: u32,
    /// Where each robot starts in the prior's map, when the user knows it roughly: one
    /// `[x_m, y_m, z_m, yaw_deg]` per robot, in robot order (robots past the list's end get none). A
    /// hinted robot registers only candidates whose prior keyframe lies within `hint_radius_m` of where
    /// the hint and its odometry put it.
    pub hints: Vec<[f64; 4]>,
    /// How far from a hinted position a prior keyframe may be and still be a candidate, metres.
    pub hint_radius_m: f64,
}

impl Default for PriorSection {
    fn default() -> Self {
        Self {
            path: None,
            mode: PriorMode::Localise,
            own_loops: false,
            track_every_keyframes: 5,
            hints: Vec::new(),
            hint_radius_m: 30.0,
        }
    }
}

impl PriorSection {
    /// Checks that a path, when given, names a folder, and that tracking is at least every keyframe.
    pub fn validate(&self) -> Result<(), SectionError> {
        if !(self.hint_radius_m.is_finite() && self.hint_radius_m > 0.0) {
            return SectionError::at(
                "prior.hint_radius_m",
                format!(
                    "prior.hint_radius_m = {} must be a positive number of metres",
                    self.hint_radius_m
                ),
            );
        }
        if self.hints.iter().flatten().any(|v| !v.is_finite()) {
            return SectionError::at(
                "prior.hints",
                "prior.hints holds a number that is not finite".to_owned(),
            );
        }
        if self.track_every_keyframes == 0 {
            return SectionError::at(
                "prior.track_every_keyframes",
                "prior.track_every_keyframes = 0: at least 1 (1 registers at every keyframe)".to_owned(),
            );
        }
        match &self.path {
            Some(path) if !path.is_dir() => SectionError::at(
                "prior.path",
                format!(
                    "{} is not a folder (a session folder, or a run folder holding one)",
                    path.display()
                ),
            ),
            _ => Ok(()),
        }
    }
}

/// A slot table as written: the selected plugin and the parameter tables of any plugins.
#[derive(Clone, Debug, Deserialize)]
pub(crate) struct RawSlot {
    pub plugin: String,
    #[serde(flatten)]
    pub tables: BTreeMap<String, toml::Value>,
}

/// The whole file as written, before plugin parameters are checked.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawConfig {
    #[serde(default)]
    pub run: RunSection,
    #[serde(default)]
    pub deploy: DeploySection,
    #[serde(default)]
    pub loops: LoopsSection,
    #[serde(default)]
    pub output: OutputSection,
    #[serde(default)]
    pub prior: PriorSection,
    pub source: Option<RawSlot>,
    pub odometry: Option<RawSlot>,
    pub descriptor: Option<RawSlot>,
    pub coarse: Option<RawSlot>,
    pub fine: Option<RawSlot>,
    pub verifier: Option<RawSlot>,
    pub backend: Option<RawSlot>,
    pub transport: Option<RawSlot>,
}

impl RawConfig {
    /// The table of a slot, by slot.
    pub fn slot(&self, slot: skid_core::Slot) -> Option<&RawSlot> {
        use skid_core::Slot;
        match slot {
            Slot::Source => self.source.as_ref(),
            Slot::Odometry => self.odometry.as_ref(),
            Slot::Descriptor => self.descriptor.as_ref(),
            Slot::Coarse => self.coarse.as_ref(),
            Slot::Fine => self.fine.as_ref(),
            Slot::Verifier => self.verifier.as_ref(),
            Slot::Backend => self.backend.as_ref(),
            Slot::Transport => self.transport.as_ref(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deploy_robot_must_be_in_the_fleet() {
        let mut deploy = DeploySection::default();
        assert_eq!(deploy.validate(3), Ok(()));
        deploy.robot = Some(2);
        assert_eq!(deploy.validate(3), Ok(()));
        deploy.robot = Some(3);
        let error = deploy.validate(3).unwrap_err();
        assert_eq!(error.key, "deploy.robot");
        assert!(error.message.contains("0 to 2"), "{error}");
        deploy.robot = Some(0);
        deploy.linger_s = -1.0;
        assert_eq!(deploy.validate(3).unwrap_err().key, "deploy.linger_s");
        deploy.linger_s = 1.0;
        deploy.playback_speed = f64::NAN;
        assert_eq!(deploy.validate(3).unwrap_err().key, "deploy.playback_speed");
        let output = OutputSection {
            ros2_listen: vec!["localhost:7447".into()],
            ..OutputSection::default()
        };
        assert_eq!(output.validate().unwrap_err().key, "output.ros2_listen");
    }

    #[test]
    fn deploy_robot_is_omitted_when_unset() {
        let shown = toml::to_string(&DeploySection::default()).unwrap();
        assert!(!shown.contains("robot"), "{shown}");
        let parsed: DeploySection = toml::from_str("robot = 1").unwrap();
        assert_eq!(parsed.robot, Some(1));
        assert_eq!(parsed.linger_s, 5.0);
    }
}
