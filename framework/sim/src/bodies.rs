//! The other robots of the fleet as solid bodies in each robot's sweeps. Robots are physical things: a
//! robot's LiDAR sees a peer that stands within its range and line of sight, and a field team's scans
//! hold each other's rovers. A simulator that renders no robot lets a frame hypothesis put two robots a
//! few metres apart at one moment without any scan contradicting it; with bodies, the scans say whether
//! the peer was there (the verifier's peer-visibility check, `skid_verifier_pcm::peer_seen`).
//!
//! Each body is a box fixed to its robot's sensor frame, following the robot's ground-truth trajectory
//! (standing at its first pose before its route starts and at its last after it ends). The boxes are
//! the carriers' rough sizes: a ground rover's chassis of 1.0 × 0.8 m under its sensor mast (a Clearpath
//! Husky is 0.99 × 0.67 × 0.39 m), a quadruped's body of 1.0 × 0.5 m (Boston Dynamics Spot: 1.1 × 0.5 m),
//! the person carrying a handheld unit, a drone of 0.7 × 0.7 m. Every one of them holds the core that
//! the verifier looks for by default: 0.3 × 0.3 × 0.1 m centred 0.3 m below the sensor.

use std::sync::Arc;

use crate::gait::{self, Profile};
use crate::geometry::{Ray, V3};
use crate::trajectory::Trajectory;

/// A carrier's body as a box in its sensor frame (x forward, z up): centre and half extents, metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyShape {
    pub centre_m: [f32; 3],
    pub half_extents_m: [f32; 3],
}

impl BodyShape {
    /// The body of a `profile` carrier whose ground sensor mount is `ground_mount_m` high.
    pub fn of(profile: Profile, ground_mount_m: f64) -> Self {
        let mount_m = gait::mount_height_m(profile, ground_mount_m) as f32;
        match profile {
            // A chassis from 0.15 m above the ground to 0.15 m under the sensor (the mast between).
            Profile::Ground | Profile::FastTurn => {
                let bottom = (0.15 - mount_m).min(-0.35);
                Self::spanning([-0.5, -0.4, bottom], [0.5, 0.4, -0.15])
            }
            // The body from 0.05 m above the legs' hips to just under the sensor on its back.
            Profile::Legged => Self::spanning([-0.5, -0.25, -0.40], [0.5, 0.25, -0.05]),
            // A person holding the unit at chest height, standing behind it.
            Profile::Handheld => Self::spanning([-0.45, -0.25, -mount_m], [0.15, 0.25, 0.35]),
            // A multirotor's frame, battery and landing gear around the sensor (a DJI M300 stands 0.43 m).
            Profile::Aerial => Self::spanning([-0.35, -0.35, -0.40], [0.35, 0.35, 0.05]),
        }
    }

    fn spanning(min: [f32; 3], max: [f32; 3]) -> Self {
        Self {
            centre_m: std::array::from_fn(|i| 0.5 * (min[i] + max[i])),
            half_extents_m: std::array::from_fn(|i| 0.5 * (max[i] - min[i])),
        }
    }
}

/// A robot body: its sensor's trajectory and its shape.
#[derive(Clone)]
pub struct Body {
    pub trajectory: Arc<Trajectory>,
    pub shape: BodyShape,
}

/// A body at one instant, in the world frame.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PlacedBody {
    centre: V3,
    /// Columns are the body's axes in the world frame.
    axes: [V3; 3],
    half: V3,
}

impl PlacedBody {
    fn at(body: &Body, t_s: f64) -> Self {
        let pose = body.trajectory.pose_at(t_s);
        let [cx, cy, cz] = body.shape.centre_m.map(f64::from);
        let centre = pose * nalgebra::Point3::new(cx, cy, cz);
        let m = pose.rotation.to_rotation_matrix();
        let axis = |c: usize| V3::from_f64(m[(0, c)], m[(1, c)], m[(2, c)]);
        let [hx, hy, hz] = body.shape.half_extents_m;
        Self {
            centre: V3::from_f64(centre.x, centre.y, centre.z),
            axes: [axis(0), axis(1), axis(2)],
            half: V3::new(hx, hy, hz),
        }
    }

    /// Where `ray` enters the box within `t_max`, and the world normal of the face it enters.
    pub(crate) fn cast(&self, ray: &Ray, t_max: f32) -> Option<(f32, V3)> {
        let offset = ray.origin - self.centre;
        // Most rays pass far from a body: test its bounding sphere first.
        let along = -offset.dot(ray.dir);
        let radius_squared = self.half.dot(self.half);
        if along < -self.half.norm() || offset.dot(offset) - along * along > radius_squared {
            return None;
        }
        let local = |v: V3| V3::new(v.dot(self.axes[0]), v.dot(self.axes[1]), v.dot(self.axes[2]));
        let local_ray = Ray::new(local(offset), local(ray.dir));
        let min = V3::new(-self.half.x, -self.half.y, -self.half.z);
        let t = local_ray.slab(min, self.half, t_max)?;
        if t <= 0.0 {
            // The ray starts inside the box (the sensor of a robot inside another): no return.
            return None;
        }
        let hit = local_ray.at(t);
        let scaled = [hit.x / self.half.x, hit.y / self.half.y, hit.z / self.half.z];
        let face = (0..3)
            .max_by(|&a, &b| scaled[a].abs().total_cmp(&scaled[b].abs()))
            .unwrap_or(2);
        Some((t, self.axes[face] * scaled[face].signum()))
    }
}

/// The fleet's other robots, as one robot's sweeps see them.
#[derive(Clone, Default)]
pub struct Peers {
    bodies: Vec<Body>,
}

impl Peers {
    pub fn new(bodies: Vec<Body>) -> Self {
        Self { bodies }
    }

    /// The bodies that may be within `reach_m` of `position` during a sweep from `start_s` to `end_s`
    /// (checked at both ends, with the distance a robot covers in a sweep as slack).
    pub(crate) fn within(&self, position: V3, start_s: f64, end_s: f64, reach_m: f32) -> Vec<&Body> {
        self.bodies
            .iter()
            .filter(|body| {
                [start_s, end_s].iter().any(|&t| {
                    let p = body.trajectory.pose_at(t).translation.vector;
                    (V3::from_f64(p.x, p.y, p.z) - position).norm() <= reach_m + 5.0
                })
            })
            .collect()
    }

    /// `bodies` at `t_s`.
    pub(crate) fn placed(bodies: &[&Body], t_s: f64) -> Vec<PlacedBody> {
        bodies.iter().map(|body| PlacedBody::at(body, t_s)).collect()
    }
}

/// The nearest body `ray` meets within `t_max`: range and the face's normal.
pub(crate) fn cast_bodies(placed: &[PlacedBody], ray: &Ray, t_max: f32) -> Option<(f32, V3)> {
    let mut best: Option<(f32, V3)> = None;
    for body in placed {
        let limit = best.map_or(t_max, |(t, _)| t);
        if let Some(hit) = body.cast(ray, limit) {
            best = Some(hit);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use skid_core::Pose;

    fn standing(x: f64, yaw_rad: f64) -> Arc<Trajectory> {
        let pose = Pose::from_parts(
            nalgebra::Translation3::new(x, 0.0, 0.8),
            nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_rad),
        );
        Arc::new(Trajectory::new(0.0, 0.1, vec![pose; 8]))
    }

    #[test]
    fn every_carrier_holds_the_verifiers_default_core() {
        let core_min = [-0.15f32, -0.15, -0.35];
        let core_max = [0.15f32, 0.15, -0.25];
        for profile in [
            Profile::Ground,
            Profile::FastTurn,
            Profile::Legged,
            Profile::Handheld,
            Profile::Aerial,
        ] {
            let shape = BodyShape::of(profile, 0.8);
            for axis in 0..3 {
                let (c, h) = (shape.centre_m[axis], shape.half_extents_m[axis]);
                assert!(
                    c - h <= core_min[axis] + 1e-6 && c + h >= core_max[axis] - 1e-6,
                    "{profile:?} axis {axis}"
                );
            }
        }
    }

    #[test]
    fn a_ray_meets_the_near_face_of_a_turned_body() {
        let body = Body {
            trajectory: standing(5.0, std::f64::consts::FRAC_PI_2),
            shape: BodyShape::of(Profile::Ground, 0.8),
        };
        let placed = Peers::placed(&[&body], 1.0);
        // From 0.4 m above the ground at x = 0 straight along +x: the body, turned by 90°, is 0.8 m deep
        // along x, so its near face is at x = 4.6.
        let ray = Ray::new(V3::new(0.0, 0.0, 0.4), V3::new(1.0, 0.0, 0.0));
        let (range, normal) = cast_bodies(&placed, &ray, 100.0).expect("the ray meets the body");
        assert!((range - 4.6).abs() < 1e-4, "{range}");
        assert!(
            (normal.x + 1.0).abs() < 1e-4 || (normal.x - 1.0).abs() < 1e-4,
            "{normal:?}"
        );
        // Above the body (at the sensor's height, 0.8 m, the mast is not modelled) nothing is met.
        let over = Ray::new(V3::new(0.0, 0.0, 0.9), V3::new(1.0, 0.0, 0.0));
        assert!(cast_bodies(&placed, &over, 100.0).is_none());
        // Nor beyond the range limit.
        assert!(cast_bodies(&placed, &ray, 4.0).is_none());
    }

    #[test]
    fn bodies_far_from_a_sweep_are_left_out() {
        let near = Body {
            trajectory: standing(5.0, 0.0),
            shape: BodyShape::of(Profile::Ground, 0.8),
        };
        let far = Body {
            trajectory: standing(500.0, 0.0),
            shape: BodyShape::of(Profile::Aerial, 0.8),
        };
        let peers = Peers::new(vec![near, far]);
        assert_eq!(peers.within(V3::new(0.0, 0.0, 0.8), 0.0, 0.1, 100.0).len(), 1);
    }
}
