//! Watching robots as they run: a [`HostObserver`] attached to a robot of a [`crate::Fleet`] (or of a
//! [`crate::SingleRobot`]) hears of every scan its host records, of every optimisation of the host's
//! back-end and of the end of the run, and reads what it needs from the host at that moment. A live
//! ROS 2 bridge (`skid-ros2-live`) is one; the runtime knows nothing of what observers do with it.
//!
//! Observers run on the host's thread between scans, so they must be quick: anything slow (sending over
//! a network) belongs on their own queue or thread, and dropping a message is better than stalling the
//! robot.

use skid_core::RobotId;

use crate::host::RobotHost;

/// Something that watches one robot's run. Every method has a default that does nothing.
pub trait HostObserver: Send {
    /// The host recorded a scan: the newest of `host.scans`.
    fn scan(&mut self, host: &RobotHost) {
        let _ = host;
    }

    /// The host's back-end optimised its graph (after a scan, or at the end of the run).
    fn optimized(&mut self, host: &RobotHost) {
        let _ = host;
    }

    /// The run ended: the host's state is final.
    fn finished(&mut self, host: &RobotHost) {
        let _ = host;
    }
}

/// The observers of a fleet's robots.
#[derive(Default)]
pub struct Observers {
    attached: Vec<(RobotId, Box<dyn HostObserver>)>,
}

impl std::fmt::Debug for Observers {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Observers")
            .field("attached", &self.attached.len())
            .finish()
    }
}

impl Observers {
    /// Attaches `observer` to robot `robot`.
    pub fn attach(&mut self, robot: RobotId, observer: Box<dyn HostObserver>) {
        self.attached.push((robot, observer));
    }

    pub fn is_empty(&self) -> bool {
        self.attached.is_empty()
    }

    fn of(&mut self, robot: RobotId) -> impl Iterator<Item = &mut Box<dyn HostObserver>> {
        self.attached
            .iter_mut()
            .filter(move |(id, _)| *id == robot)
            .map(|(_, observer)| observer)
    }

    /// Tells `host`'s observers about the step it just took: a new scan when its scan count grew past
    /// `scans_before`, an optimisation when its count grew past `optimizations_before`.
    pub(crate) fn after_step(&mut self, host: &RobotHost, scans_before: usize, optimizations_before: u64) {
        let (scanned, optimised) = (
            host.scans().len() > scans_before,
            host.optimizations() > optimizations_before,
        );
        for observer in self.of(host.robot()) {
            if scanned {
                observer.scan(host);
            }
            if optimised {
                observer.optimized(host);
            }
        }
    }

    /// Tells every robot's observers that the run ended (after the final optimisation).
    pub(crate) fn finished(&mut self, hosts: &[RobotHost]) {
        for host in hosts {
            for observer in self.of(host.robot()) {
                observer.optimized(host);
                observer.finished(host);
            }
        }
    }
}
