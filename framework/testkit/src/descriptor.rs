//! Conformance of descriptor plugins and their retrieval indexes: zero distance to itself, (near-)
//! invariance to yawing the scan, a yaw hint within one sector when the descriptor gives one, a farther
//! place farther away, exclusions honoured, and no NaN on degenerate clouds.

use nalgebra::{Point3, Rotation3, Vector3};
use skid_core::slots::Descriptor;
use skid_core::{Cloud, CloudView, KeyframeId, Point};

use crate::scene::{Scene, planar_pose};

/// What a descriptor must achieve.
#[derive(Clone, Debug)]
pub struct DescriptorExpectations {
    /// Yaw angles (degrees) the scan is rotated by.
    pub yaws_deg: Vec<f64>,
    /// The yawed copy must be at most this fraction of the distance to a place 25 m away.
    pub max_yawed_over_other: f64,
    /// When set, the index must return a yaw hint within this many degrees.
    pub yaw_hint_tolerance_deg: Option<f64>,
}

impl Default for DescriptorExpectations {
    fn default() -> Self {
        Self {
            yaws_deg: vec![30.0, 90.0, 180.0, 270.0],
            max_yawed_over_other: 0.5,
            yaw_hint_tolerance_deg: Some(6.0),
        }
    }
}

fn yawed(cloud: &Cloud, yaw_deg: f64) -> Cloud {
    let rotation = Rotation3::from_axis_angle(&Vector3::z_axis(), yaw_deg.to_radians());
    let points = cloud
        .points
        .iter()
        .map(|p| {
            let q = rotation * Point3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z));
            Point::with_intensity(q.x as f32, q.y as f32, q.z as f32, p.intensity)
        })
        .collect();
    Cloud::new(points)
}

/// Smallest absolute difference between two angles, in degrees.
pub fn angle_difference_deg(a_deg: f64, b_deg: f64) -> f64 {
    let d = (a_deg - b_deg).rem_euclid(360.0);
    d.min(360.0 - d)
}

/// Runs the descriptor contract on an instance from `make`.
pub fn check_descriptor(mut make: impl FnMut() -> Box<dyn Descriptor>, expect: &DescriptorExpectations) {
    let scene = Scene::new(7, 120.0);
    let here = scene.sample(&planar_pose(0.0, 0.0, 1.8, 0.0), 40_000, 80.0, 1);
    let elsewhere = scene.sample(&planar_pose(25.0, 10.0, 1.8, 0.0), 40_000, 80.0, 2);
    let mut descriptor = make();
    let base = descriptor.describe(here.view()).expect("describes a scan");
    assert!(!base.values.is_empty(), "a descriptor has values");
    assert!(
        base.values.iter().all(|v| v.is_finite()),
        "no NaN in a descriptor"
    );
    assert_eq!(base.kind, descriptor.kind());
    let other = descriptor
        .describe(elsewhere.view())
        .expect("describes another scan");

    let mut index = descriptor.new_index();
    let here_id = KeyframeId::new(0, 0);
    let other_id = KeyframeId::new(0, 1);
    index.insert(here_id, base.clone()).expect("insert");
    index.insert(other_id, other.clone()).expect("insert");
    assert_eq!(index.len(), 2);

    let found = index.query(&base, 2, &|_| false).expect("query");
    assert_eq!(found[0].id, here_id, "a descriptor retrieves itself first");
    assert!(
        found[0].distance.abs() < 1e-6,
        "distance to itself is zero, got {}",
        found[0].distance
    );
    assert!(
        found.windows(2).all(|w| w[0].distance <= w[1].distance),
        "results sorted by distance"
    );
    let distance_to_other = found
        .iter()
        .find(|c| c.id == other_id)
        .map(|c| c.distance)
        .expect("both stored");
    assert!(distance_to_other > 0.0, "different places differ");
    if let Some(between) = index.distance_between(here_id, other_id) {
        assert!(
            (between - distance_to_other).abs() <= 1e-6 * distance_to_other.max(1.0),
            "distance_between {between} is the query's distance {distance_to_other}"
        );
        assert!(
            index
                .distance_between(here_id, here_id)
                .is_some_and(|d| d.abs() < 1e-6),
            "distance_between a keyframe and itself is zero"
        );
    }
    assert_eq!(
        index.distance_between(here_id, KeyframeId::new(7, 7)),
        None,
        "no distance to a keyframe the index does not hold"
    );

    for &yaw_deg in &expect.yaws_deg {
        let query = descriptor
            .describe(yawed(&here, yaw_deg).view())
            .expect("describes the yawed scan");
        let found = index.query(&query, 1, &|_| false).expect("query");
        assert_eq!(
            found[0].id, here_id,
            "yaw {yaw_deg}°: the same place is retrieved first"
        );
        let ratio = found[0].distance / distance_to_other;
        assert!(
            ratio <= expect.max_yawed_over_other,
            "yaw {yaw_deg}°: distance {:.4} is {ratio:.2} of another place's",
            found[0].distance
        );
        if let Some(tolerance) = expect.yaw_hint_tolerance_deg {
            let hint = found[0].yaw_hint_rad.expect("a yaw hint").to_degrees();
            // The hint is the yaw of candidate_from_query; the query is the candidate turned by +yaw.
            let error = angle_difference_deg(hint, -yaw_deg);
            assert!(
                error <= tolerance,
                "yaw {yaw_deg}°: hint {hint:.1}° is {error:.1}° off"
            );
        }
    }

    let excluded = index
        .query(&base, 2, &|id| id == here_id)
        .expect("query with exclusion");
    assert!(
        excluded.iter().all(|c| c.id != here_id),
        "excluded keyframes are not returned"
    );
    assert!(index.query(&base, 0, &|_| false).expect("k = 0").is_empty());

    let degenerate = [
        Cloud::default(),
        Cloud::new(vec![Point::new(10.0, 0.0, 0.0); 500]),
        Cloud::new(
            (0..500)
                .map(|i| Point::new((i as f32).cos() * 20.0, (i as f32).sin() * 20.0, -60.0))
                .collect(),
        ),
    ];
    for (case, cloud) in degenerate.iter().enumerate() {
        if let Ok(buf) = descriptor.describe(CloudView::from(cloud)) {
            assert!(
                buf.values.iter().all(|v| v.is_finite()),
                "degenerate case {case}: NaN in the descriptor"
            );
            if let Ok(found) = index.query(&buf, 1, &|_| false) {
                assert!(
                    found.iter().all(|c| c.distance.is_finite()),
                    "degenerate case {case}: NaN distance"
                );
            }
        }
    }
}
