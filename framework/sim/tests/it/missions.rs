//! Missions do what their names promise, in every world: robots of `explore_meet` start apart and every
//! pair meets twice (crossing at an angle, and on a reverse traverse of one robot's sector); `rendezvous` brings every
//! robot to one place; `crossing` meets only where paths cross, at an angle; `reverse` drives one route
//! both ways; `loner`'s last robot never comes near the others; `convoy` robots drive one route the same way,
//! a fixed gap apart. Checked on the routes' centre lines.

use crate::common;

use skid_sim::{CONVOY_GAP_M, Mission, WorldKind, plan_mission};

type Line = Vec<[f64; 3]>;

/// The line resampled every metre (horizontal distance), so counts below measure metres of road.
fn every_metre(line: &[[f64; 3]]) -> Vec<[f64; 2]> {
    let mut out = vec![[line[0][0], line[0][1]]];
    for w in line.windows(2) {
        let length = (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]);
        let steps = length.ceil() as usize;
        for k in 1..=steps {
            let t = k as f64 / steps as f64;
            out.push([
                w[0][0] + (w[1][0] - w[0][0]) * t,
                w[0][1] + (w[1][1] - w[0][1]) * t,
            ]);
        }
    }
    out
}

fn line_length_m(line: &[[f64; 3]]) -> f64 {
    line.windows(2)
        .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
        .sum()
}

/// Heading of `line` at each of its metre points.
fn headings(points: &[[f64; 2]]) -> Vec<f64> {
    (0..points.len())
        .map(|i| {
            let (a, b) = (points[i.saturating_sub(2)], points[(i + 2).min(points.len() - 1)]);
            (b[1] - a[1]).atan2(b[0] - a[0])
        })
        .collect()
}

/// Where `a` runs within `radius_m` of `b`: for each such metre of `a`, the heading difference of the
/// two lines there (0 = same direction, π = opposite).
fn near_headings(a: &[[f64; 3]], b: &[[f64; 3]], radius_m: f64) -> Vec<f64> {
    let (pa, pb) = (every_metre(a), every_metre(b));
    let (ha, hb) = (headings(&pa), headings(&pb));
    pa.iter()
        .enumerate()
        .filter_map(|(i, p)| {
            let (d, j) = pb
                .iter()
                .enumerate()
                .map(|(j, q)| ((p[0] - q[0]).hypot(p[1] - q[1]), j))
                .min_by(|x, y| x.0.total_cmp(&y.0))?;
            (d <= radius_m).then(|| {
                let x = (ha[i] - hb[j]).rem_euclid(std::f64::consts::TAU);
                x.min(std::f64::consts::TAU - x)
            })
        })
        .collect()
}

fn lines(kind: WorldKind, mission: Mission, robots: u32, length_m: f64) -> Vec<Line> {
    let world = common::world(kind);
    let routes = plan_mission(&world, mission, 7, robots, length_m);
    assert_eq!(routes.len(), robots as usize, "{kind} {mission:?}");
    routes.into_iter().map(|r| r.centre_line).collect()
}

#[test]
fn explore_meet_starts_apart_and_every_pair_meets_twice() {
    for kind in WorldKind::ALL {
        for length_m in [180.0, 400.0] {
            let routes = lines(kind, Mission::ExploreMeet, 3, length_m);
            for (r, line) in routes.iter().enumerate() {
                assert!(
                    line_length_m(line) > 0.8 * length_m,
                    "{kind} {length_m}: robot {r} drives {} m",
                    line_length_m(line)
                );
            }
            for a in 0..3 {
                for b in a + 1..3 {
                    let (sa, sb) = (routes[a][0], routes[b][0]);
                    let apart = (sa[0] - sb[0]).hypot(sa[1] - sb[1]);
                    assert!(
                        apart > 40.0,
                        "{kind} {length_m}: robots {a} and {b} start {apart:.0} m apart"
                    );
                    // Two encounters: crossing at the meeting junction at an angle, and one robot
                    // driving the other's sector the other way (at least 15 m of it).
                    let near = near_headings(&routes[a], &routes[b], 6.0);
                    let crossing = near.iter().any(|d| (0.5..2.6).contains(d));
                    let reverse = near.iter().filter(|d| **d > 2.6).count();
                    assert!(
                        crossing,
                        "{kind} {length_m}: robots {a} and {b} never cross at an angle"
                    );
                    assert!(
                        reverse >= 15,
                        "{kind} {length_m}: robots {a} and {b} share {reverse} m reversed"
                    );
                }
            }
        }
    }
}

#[test]
fn rendezvous_brings_everyone_to_one_place_and_crossing_meets_at_an_angle() {
    for kind in WorldKind::ALL {
        let routes = lines(kind, Mission::Rendezvous, 4, 300.0);
        let turn = |line: &Line| line[line.len() / 2];
        let place = turn(&routes[0]);
        for (r, line) in routes.iter().enumerate() {
            let here = turn(line);
            assert!(
                (here[0] - place[0]).hypot(here[1] - place[1]) < 1.0,
                "{kind}: robot {r} turns elsewhere"
            );
            let (start, end) = (line[0], line[line.len() - 1]);
            assert!(
                (start[0] - end[0]).hypot(start[1] - end[1]) < 1.0,
                "{kind}: robot {r} does not return home"
            );
        }
        let routes = lines(kind, Mission::Crossing, 2, 300.0);
        let near = near_headings(&routes[0], &routes[1], 6.0);
        assert!(!near.is_empty(), "{kind}: the crossing robots never meet");
        let along = near.iter().filter(|d| **d < 0.5 || **d > 2.6).count();
        assert!(
            along < 40,
            "{kind}: crossing robots drive {along} m of road together"
        );
        assert!(
            near.iter().any(|d| (0.5..2.6).contains(d)),
            "{kind}: the robots do not cross at an angle"
        );
    }
}

#[test]
fn reverse_drives_one_route_both_ways_and_the_loner_stays_away() {
    for kind in WorldKind::ALL {
        let routes = lines(kind, Mission::Reverse, 2, 300.0);
        let (first, last) = (routes[0][0], routes[0][routes[0].len() - 1]);
        let (start, end) = (routes[1][0], routes[1][routes[1].len() - 1]);
        assert!(
            (start[0] - last[0]).hypot(start[1] - last[1]) < 1e-6
                && (end[0] - first[0]).hypot(end[1] - first[1]) < 1e-6
        );
        let near = near_headings(&routes[1], &routes[0], 3.0);
        let whole = every_metre(&routes[1]).len();
        let backwards = near.iter().filter(|d| **d > 2.6).count();
        assert!(
            backwards * 100 >= whole * 98,
            "{kind}: robot 1 drives {} of {whole} m of robot 0's route backwards",
            backwards
        );
        let routes = lines(kind, Mission::Loner, 3, 300.0);
        for other in 0..2 {
            let near = near_headings(&routes[2], &routes[other], 30.0);
            assert!(
                near.is_empty(),
                "{kind}: the loner comes within 30 m of robot {other} ({} m)",
                near.len()
            );
        }
        assert!(
            !near_headings(&routes[0], &routes[1], 6.0).is_empty(),
            "{kind}: the others do meet"
        );
    }
}

#[test]
fn a_convoy_drives_one_route_the_same_way_a_gap_apart() {
    for kind in WorldKind::ALL {
        let length_m = 300.0;
        let routes = lines(kind, Mission::Convoy, 3, length_m);
        for (r, line) in routes.iter().enumerate() {
            let driven = line_length_m(line);
            assert!(
                (driven - length_m).abs() < 0.05 * length_m,
                "{kind}: robot {r} drives {driven:.0} m"
            );
        }
        for r in 1..3 {
            // The robot behind starts one gap (along the road) behind the one ahead, and drives where it
            // drove, in the same direction, up to the last gap of its route.
            let (ahead, behind) = (&routes[r - 1], &routes[r]);
            let (a, b) = (ahead[0], behind[0]);
            let apart = (a[0] - b[0]).hypot(a[1] - b[1]);
            assert!(
                apart <= CONVOY_GAP_M + 0.5 && apart > 0.5 * CONVOY_GAP_M,
                "{kind}: robots {} and {r} start {apart:.1} m apart",
                r - 1
            );
            let near = near_headings(behind, ahead, 1.0);
            let same_way = near.iter().filter(|d| **d < 0.3).count() as f64;
            assert!(
                same_way >= 0.95 * (length_m - CONVOY_GAP_M),
                "{kind}: robot {r} drives {same_way} m of robot {}'s route the same way",
                r - 1
            );
        }
    }
}

#[test]
fn missions_are_deterministic_and_refuse_unknown_names() {
    let world = common::world(WorldKind::Urban);
    let a = plan_mission(&world, Mission::ExploreMeet, 11, 4, 250.0);
    let b = plan_mission(&world, Mission::ExploreMeet, 11, 4, 250.0);
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.centre_line, y.centre_line);
        assert_eq!(x.role, y.role);
    }
    let error = "orbit".parse::<Mission>().unwrap_err().to_string();
    assert!(
        error.contains("orbit") && error.contains("explore_meet"),
        "{error}"
    );
}

#[test]
fn wander_starts_on_a_road_out_of_the_given_junction_and_the_route_seed_moves_the_start() {
    let world = common::world(WorldKind::Planetary);
    let graph = world.graph();
    let junction = graph.nodes.len() / 2;
    let at = graph.nodes[junction];
    let first_road_m = graph.adjacency()[junction]
        .iter()
        .map(|&edge| graph.edge_length_m(edge))
        .fold(0.0, f64::max);
    let starts: Vec<[f64; 3]> = (0..6)
        .map(|route_seed| {
            let routes = skid_sim::plan_wander(&world, 7, route_seed, Some(junction), 2, 120.0);
            assert_eq!(routes.len(), 2);
            let start = routes[0].centre_line[0];
            // On a road out of the junction: no farther from it than that road is long.
            assert!(
                (start[0] - at[0]).hypot(start[1] - at[1]) <= first_road_m + 1.0,
                "{start:?}"
            );
            let length: f64 = routes[0]
                .centre_line
                .windows(2)
                .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
                .sum();
            assert!(length > 20.0, "{length} m");
            start
        })
        .collect();
    let distinct = starts
        .iter()
        .enumerate()
        .filter(|(i, a)| {
            starts[..*i]
                .iter()
                .all(|b| (a[0] - b[0]).hypot(a[1] - b[1]) > 1.0)
        })
        .count();
    assert!(distinct >= 4, "{starts:?}");
}
