//! The free-space check: two registered scans of one place must not see through each other.
//!
//! A LiDAR return at range `r` along a ray says that the ray crossed empty space up to `r`. When a loop's
//! alignment is right, a point of one scan lies on or behind what the other scan saw in its direction
//! (or where the other scan did not look); when the alignment joins two different places that merely
//! look alike, the objects in which they differ (the parked cars of two identical blocks, a door open in
//! one corridor and shut in the other) stand where the other scan's rays passed through. This is the
//! free-space violation test of Huber & Hebert ("Fully automatic registration of multiple 3D data
//! sets", Image and Vision Computing 21(7), 2003), which they use to verify pairwise matches before a
//! multi-view merge. The truncated MSE ([`crate::fitness`]) cannot see it: it scores only the points
//! that found a neighbour, and two identical facades give it a perfect score.
//!
//! ## Definition
//!
//! Each cloud is in its sensor's frame. A scan's **range image** ([`range_image`]) holds, per pixel of
//! `pixel_deg` in azimuth and elevation over the whole sphere, the nearest return's range. A point `q`
//! of the other scan, moved into this scan's frame at range `r_q`, is judged against `r_near`, the
//! nearest return around its direction: in its pixel's column and the columns on either side, the
//! nearest ray at or above and at or below it within `max_beam_gap_deg`. Where the rays do not surround
//! `q` (the top edge of an object, the edge of the field of view) nothing is decided. With the margin
//! `m = margin_m + margin_fraction · r_near`, the point
//!
//! * **violates** this scan's free space when `r_q < r_near − m` and `q` is at least
//!   `min_surface_distance_m` from every point of this scan (on the ground ahead, seen at grazing
//!   incidence, centimetres of height move a ray's hit by metres along the ray, not off the ground);
//! * **agrees** when `|r_q − r_near| ≤ m`;
//! * is hidden from this scan otherwise, which says nothing.
//!
//! Real scans violate a little wherever they are right: a beam that straddles a depth edge returns a
//! range between the two surfaces (the veil of mixed returns), foliage lets some rays through, and
//! things move. Those violations are stray points. An object one scan holds and the other does not is
//! a surface of them, so the check counts a violation only when at least `min_cluster_neighbours`
//! other violations lie within `cluster_radius_m`, and a loop fails when such **clustered** violations
//! make up more than `max_clustered_fraction` of the points decided (violating or agreeing), both
//! directions together (source points in the target's image, target points in the source's), each
//! scan's queries thinned to `query_voxel_m` voxels, once at least `min_decided_points` are decided.
//!
//! What the defaults were chosen on (2026-12-01; `cargo xtask bench table2-registration` reports the
//! check on its pairs): real scans of one place, registered by GICP, give at most 0.21 % clustered
//! violations (120 pairs of the 16 KITTI 00 sweeps, up to 11.7 m apart) and none (the HDL-32E pair);
//! 296 true loop candidates of four simulated city runs at most 0.25 %. Of 866 false ones (more than
//! 5 m or 10° off) the median is 4.5 % and 77 % exceed the 0.5 % bound; most of those that do not join
//! the identical junctions where two robots of the grid of identical blocks start, where no parked
//! car is near (the merge rules of [`crate::earned`] are what stands there).

mod indexed;
mod range_image;

use nalgebra::Point3;
use serde::{Deserialize, Serialize};
use skid_core::{ParamError, Point, Pose};
use skid_geometry::voxel_downsample;

use indexed::IndexedScan;
use range_image::clustered;

/// Parameters of the free-space check.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct FreeSpaceConfig {
    /// Run the check (off: loops go from the truncated MSE straight to the consistency stage).
    pub enabled: bool,
    /// Edge of a range-image pixel, degrees, in azimuth and elevation.
    pub pixel_deg: f64,
    /// Widest gap between a sensor's beams, in elevation, across which the scan still counts as having
    /// looked, degrees (a VLP-16's beams are 2° apart, an HDL-32E's 1.33°, an OS1-64's 0.5°).
    pub max_beam_gap_deg: f64,
    /// Fixed part of the margin by which a point must lie in front of the other scan's returns to
    /// violate its free space (and within which it agrees with them), metres.
    pub margin_m: f64,
    /// Part of the margin that grows with the range of the other scan's return.
    pub margin_fraction: f64,
    /// A point in front of the other scan's returns violates its free space only when it also lies at
    /// least this far from every point of the other scan, metres.
    pub min_surface_distance_m: f64,
    /// The cosine of the steepest incidence at which a ray's range is trusted to the margin: the margin
    /// along a ray grows as one over the cosine of the angle between the ray and the point's surface
    /// normal, down to this cosine (0.26: 75° from the normal).
    pub min_incidence_cos: f64,
    /// A violation counts only with at least this many other violations within `cluster_radius_m`
    /// (metres) of it: an object, not a stray return.
    pub min_cluster_neighbours: usize,
    pub cluster_radius_m: f64,
    /// Largest fraction of clustered violations among the decided points (violating or agreeing)
    /// accepted.
    pub max_clustered_fraction: f64,
    /// Fewest decided points, both directions together, for the check to judge at all (fewer: it
    /// passes the loop, having no evidence).
    pub min_decided_points: usize,
    /// Voxel size the points queried against the other scan's image are thinned to, metres; 0 queries
    /// every point.
    pub query_voxel_m: f64,
    /// Points nearer their own sensor than this are left out of both the images and the queries (the
    /// carrier's own body), metres.
    pub min_range_m: f64,
}

impl Default for FreeSpaceConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            pixel_deg: 1.0,
            max_beam_gap_deg: 2.5,
            margin_m: 0.5,
            margin_fraction: 0.03,
            min_surface_distance_m: 0.5,
            min_incidence_cos: 0.26,
            min_cluster_neighbours: 3,
            cluster_radius_m: 1.0,
            max_clustered_fraction: 0.005,
            min_decided_points: 200,
            query_voxel_m: 0.5,
            min_range_m: 1.0,
        }
    }
}

/// What the check counted on one loop, both directions together.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FreeSpaceCount {
    /// Points lying in front of every return of the other scan around their direction, away from its
    /// surfaces.
    pub violating: usize,
    /// Of them, those with enough violating neighbours to be part of an object.
    pub clustered: usize,
    /// Points on what the other scan saw in their direction.
    pub agreeing: usize,
    /// Points hidden from the other scan, or where it did not look.
    pub undecided: usize,
}

impl FreeSpaceCount {
    fn decided(&self) -> usize {
        self.violating + self.agreeing
    }

    /// Violations over the decided points (0 when none is decided).
    pub fn violation_fraction(&self) -> f64 {
        self.violating as f64 / self.decided().max(1) as f64
    }

    /// Clustered violations over the decided points (0 when none is decided): what the check judges.
    pub fn clustered_fraction(&self) -> f64 {
        self.clustered as f64 / self.decided().max(1) as f64
    }

    fn add(self, other: FreeSpaceCount) -> FreeSpaceCount {
        FreeSpaceCount {
            violating: self.violating + other.violating,
            clustered: self.clustered + other.clustered,
            agreeing: self.agreeing + other.agreeing,
            undecided: self.undecided + other.undecided,
        }
    }
}

impl FreeSpaceConfig {
    /// Checks that every value is usable; the error is at the offending key.
    pub fn validate(&self) -> Result<(), ParamError> {
        if !(self.pixel_deg.is_finite() && self.pixel_deg > 0.0 && self.pixel_deg <= 10.0) {
            return Err(ParamError::at(
                "pixel_deg",
                format!("must lie in (0, 10] degrees, got {}", self.pixel_deg),
            ));
        }
        if !(self.cluster_radius_m.is_finite() && self.cluster_radius_m > 0.0) {
            return Err(ParamError::at(
                "cluster_radius_m",
                format!(
                    "must be a positive number of metres, got {}",
                    self.cluster_radius_m
                ),
            ));
        }
        for (value, key) in [
            (self.max_beam_gap_deg, "max_beam_gap_deg"),
            (self.margin_m, "margin_m"),
            (self.margin_fraction, "margin_fraction"),
            (self.min_surface_distance_m, "min_surface_distance_m"),
            (self.query_voxel_m, "query_voxel_m"),
            (self.min_range_m, "min_range_m"),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ParamError::at(
                    key,
                    format!("must be finite and not negative, got {value}"),
                ));
            }
        }
        if !(self.min_incidence_cos > 0.0 && self.min_incidence_cos <= 1.0) {
            return Err(ParamError::at(
                "min_incidence_cos",
                format!("must lie in (0, 1], got {}", self.min_incidence_cos),
            ));
        }
        if !(0.0..=1.0).contains(&self.max_clustered_fraction) {
            return Err(ParamError::at(
                "max_clustered_fraction",
                format!("must lie in [0, 1], got {}", self.max_clustered_fraction),
            ));
        }
        Ok(())
    }

    /// Counts, both ways, the points of each cloud that violate, agree with or are hidden from the other
    /// cloud's free space under `target_from_source`. Non-finite points are left out.
    pub fn count(&self, target: &[Point], source: &[Point], target_from_source: &Pose) -> FreeSpaceCount {
        let target = IndexedScan::new(target, self.pixel_deg, self.min_range_m);
        let source = IndexedScan::new(source, self.pixel_deg, self.min_range_m);
        let source_in_target = self.count_one_way(&target, &source, target_from_source);
        let target_in_source = self.count_one_way(&source, &target, &target_from_source.inverse());
        source_in_target.add(target_in_source)
    }

    /// Counts the points of `queried` against `seen`'s free space, after moving them by
    /// `seen_from_queried`.
    fn count_one_way(
        &self,
        seen: &IndexedScan,
        queried: &IndexedScan,
        seen_from_queried: &Pose,
    ) -> FreeSpaceCount {
        let mut count = FreeSpaceCount::default();
        let thinned;
        let queries = if self.query_voxel_m > 0.0 {
            thinned = voxel_downsample(&queried.points, self.query_voxel_m as f32);
            &thinned
        } else {
            &queried.points
        };
        let reach = (self.max_beam_gap_deg / self.pixel_deg).ceil() as usize;
        let min_surface_m2 = self.min_surface_distance_m * self.min_surface_distance_m;
        let mut violations = Vec::new();
        for point in queries {
            let own = Point3::new(f64::from(point.x), f64::from(point.y), f64::from(point.z));
            if own.coords.norm() < self.min_range_m {
                continue;
            }
            let moved = seen_from_queried * own;
            let judged = seen
                .image
                .pixel_of(&moved)
                .and_then(|(pixel, range_m)| seen.image.around(pixel, reach).map(|around| (range_m, around)));
            let Some((range_m, around)) = judged else {
                count.undecided += 1;
                continue;
            };
            // The margin is a distance across the point's surface; along a ray that meets the surface
            // at grazing incidence (the ground far ahead) it stretches by the secant of the incidence.
            // Rays around one direction that end metres apart (a depth edge) leave the free space's end
            // uncertain by as much again.
            let ray = moved.coords / range_m;
            let incidence_cos = queried
                .normal_at(&own)
                .map_or(1.0, |normal| {
                    (seen_from_queried.rotation * normal).dot(&ray).abs()
                })
                .max(self.min_incidence_cos);
            let near_m = around.nearest_m;
            let margin_m = (self.margin_m + self.margin_fraction * near_m) / incidence_cos
                + (around.farthest_m - near_m);
            if range_m < near_m - margin_m && seen.nearest_squared_m2(&moved) >= min_surface_m2 {
                count.violating += 1;
                violations.push(moved);
            } else if range_m <= near_m + margin_m {
                count.agreeing += 1;
            } else {
                count.undecided += 1;
            }
        }
        count.clustered = clustered(&violations, self.cluster_radius_m, self.min_cluster_neighbours);
        count
    }

    /// `None` when `count` passes, else the reason it fails.
    pub fn judge(&self, count: &FreeSpaceCount) -> Option<String> {
        let (decided, fraction) = (count.decided(), count.clustered_fraction());
        (decided >= self.min_decided_points && fraction > self.max_clustered_fraction).then(|| {
            format!(
                "free space: {:.2} % of the {decided} points both scans see stand where the other saw through (> {:.2} %)",
                100.0 * fraction,
                100.0 * self.max_clustered_fraction
            )
        })
    }
}

#[cfg(test)]
mod tests;
