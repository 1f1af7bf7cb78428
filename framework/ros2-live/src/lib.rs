//! Live ROS 2 output: each robot's odometry, transforms, optimised path, map and loops published while
//! it runs, as ROS 2 topics on zenoh the way `rmw_zenoh` (ROS 2 Jazzy's zenoh middleware) publishes
//! them, so RViz2 on a ROS 2 machine whose `rmw_zenohd` router SKiD connects to sees a running fleet
//! without any bridge. The topics and frames are in [`publisher`]; the keys, attachments and
//! liveliness tokens in [`keys`].
//!
//! [`attach`] opens one zenoh session for the process and attaches a [`Ros2Live`] observer to every
//! robot of a fleet (`skid run --set output.ros2=true`).

pub mod keys;
mod publisher;

use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};

use skid_runtime::Fleet;
use zenoh::Wait;
use zenoh::liveliness::LivelinessToken;

pub use publisher::Ros2Live;

/// Why the live output could not start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    #[error("live ROS 2 output: {0}")]
    Zenoh(String),
}

/// What the live output needs to know (from `[output]`).
#[derive(Clone, Debug, PartialEq)]
pub struct LiveSettings {
    /// Endpoints to connect to (a ROS 2 machine's router).
    pub connect: Vec<String>,
    /// Endpoints to listen on.
    pub listen: Vec<String>,
    pub domain_id: u32,
    /// Publish the map every this many optimisations (0: only at the end).
    pub map_every: u32,
    /// Voxel edge of the published map, metres.
    pub voxel_m: f64,
    /// The robots localise in a prior map (`[prior]`): publish their standing in it.
    pub prior: bool,
}

/// One zenoh session shared by every robot of the process, and the entity ids rmw_zenoh numbers its
/// nodes and publishers with (unique within a session).
#[derive(Clone)]
pub struct SharedSession {
    session: zenoh::Session,
    next_entity: Arc<AtomicU32>,
}

impl std::fmt::Debug for SharedSession {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SharedSession").field("id", &self.id()).finish()
    }
}

impl SharedSession {
    /// Opens a peer session with the settings' endpoints (no multicast scouting: endpoints are explicit).
    pub fn open(settings: &LiveSettings) -> Result<Self, LiveError> {
        let config = skid_transport_zenoh::peer::peer_config(&settings.listen, &settings.connect, &[])
            .map_err(LiveError::Zenoh)?;
        let session = zenoh::open(config)
            .wait()
            .map_err(|e| LiveError::Zenoh(format!("opening the zenoh session: {e}")))?;
        Ok(Self {
            session,
            next_entity: Arc::new(AtomicU32::new(0)),
        })
    }

    pub fn session(&self) -> &zenoh::Session {
        &self.session
    }

    /// The session id as rmw_zenoh writes it in liveliness tokens (lowercase hexadecimal).
    pub fn id(&self) -> String {
        self.session.zid().to_string()
    }

    /// A fresh entity id.
    pub fn next_entity_id(&self) -> u32 {
        self.next_entity.fetch_add(1, Ordering::Relaxed)
    }

    /// Declares a liveliness token on `key`.
    pub fn token(&self, key: &str) -> Result<LivelinessToken, LiveError> {
        self.session
            .liveliness()
            .declare_token(key)
            .wait()
            .map_err(|e| LiveError::Zenoh(format!("declaring the liveliness token {key}: {e}")))
    }
}

/// Opens one session and attaches a live ROS 2 output to every robot of `fleet`.
pub fn attach(fleet: &mut Fleet, settings: &LiveSettings) -> Result<SharedSession, LiveError> {
    let session = SharedSession::open(settings)?;
    for robot in &fleet.robots {
        let live = Ros2Live::new(&session, robot.robot(), settings.clone())?;
        fleet.observers.attach(robot.robot(), Box::new(live));
    }
    tracing::info!(
        session = %session.id(),
        domain_id = settings.domain_id,
        robots = fleet.robots.len(),
        "publishing live ROS 2 topics (rmw_zenoh keys)"
    );
    Ok(session)
}
