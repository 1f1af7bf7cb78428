//! Traverse lanes off road: centre lines that meander between junctions as a rover's planned traverse
//! does around terrain it prefers to avoid, and a bucketed index answering "how far is the nearest lane"
//! quickly, which the generators ask for every crater, boulder and rock they place.

use super::graph::segment_distance_xy;
use crate::noise::fbm2;
use crate::rng::combine;

/// A lane from `a` to `b` sampled every `step_m`, bent sideways by up to about `meander_m` (fBm along
/// the lane, zero at both ends so lanes still meet at their junctions). Heights are left at zero.
pub fn meandering_lane(
    seed: u64,
    lane: u64,
    a: [f64; 3],
    b: [f64; 3],
    meander_m: f64,
    step_m: f64,
) -> Vec<[f64; 3]> {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let length = dx.hypot(dy);
    let steps = (length / step_m).ceil().max(1.0) as usize;
    let (nx, ny) = if length > 0.0 {
        (-dy / length, dx / length)
    } else {
        (0.0, 0.0)
    };
    let key = combine(seed, lane);
    (0..=steps)
        .map(|k| {
            let t = k as f64 / steps as f64;
            let along_m = t * length;
            let taper = (std::f64::consts::PI * t).sin();
            let offset = meander_m * taper * fbm2(key, along_m / 45.0, 3.7, 2, 0.5);
            [a[0] + dx * t + nx * offset, a[1] + dy * t + ny * offset, 0.0]
        })
        .collect()
}

/// Segments of every lane bucketed on a square grid, for nearest-lane distance queries.
#[derive(Clone, Debug)]
pub struct LaneIndex {
    cell_m: f64,
    origin_m: f64,
    cells: usize,
    segments: Vec<([f64; 3], [f64; 3])>,
    /// Segment indices per cell, row-major.
    buckets: Vec<Vec<u32>>,
}

impl LaneIndex {
    /// An index of `lines` over the square [origin, origin + cells · cell_m)²; segments are entered in
    /// every cell within `reach_m` of them, so queries up to `reach_m` away are exact.
    pub fn new(lines: &[Vec<[f64; 3]>], origin_m: f64, cells: usize, cell_m: f64, reach_m: f64) -> Self {
        let segments: Vec<([f64; 3], [f64; 3])> = lines
            .iter()
            .flat_map(|line| line.windows(2).map(|w| (w[0], w[1])))
            .collect();
        let mut buckets = vec![Vec::new(); cells * cells];
        let cell_of = |v: f64| (((v - origin_m) / cell_m).floor().max(0.0) as usize).min(cells - 1);
        for (index, (a, b)) in segments.iter().enumerate() {
            let (i0, i1) = (
                cell_of(a[0].min(b[0]) - reach_m),
                cell_of(a[0].max(b[0]) + reach_m),
            );
            let (j0, j1) = (
                cell_of(a[1].min(b[1]) - reach_m),
                cell_of(a[1].max(b[1]) + reach_m),
            );
            for j in j0..=j1 {
                for i in i0..=i1 {
                    buckets[j * cells + i].push(index as u32);
                }
            }
        }
        Self {
            cell_m,
            origin_m,
            cells,
            segments,
            buckets,
        }
    }

    /// Horizontal distance from (x, y) to the nearest lane; infinity when none is within the index's
    /// reach (or the point lies outside the indexed square).
    pub fn distance_m(&self, x: f64, y: f64) -> f64 {
        let (fi, fj) = (
            ((x - self.origin_m) / self.cell_m).floor(),
            ((y - self.origin_m) / self.cell_m).floor(),
        );
        if fi < 0.0 || fj < 0.0 || fi >= self.cells as f64 || fj >= self.cells as f64 {
            return f64::INFINITY;
        }
        self.buckets[fj as usize * self.cells + fi as usize]
            .iter()
            .map(|&s| {
                let (a, b) = self.segments[s as usize];
                segment_distance_xy(x, y, a, b)
            })
            .fold(f64::INFINITY, f64::min)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_meet_their_ends_and_the_index_agrees_with_brute_force() {
        let a = [-40.0, -5.0, 0.0];
        let b = [60.0, 20.0, 0.0];
        let lane = meandering_lane(3, 1, a, b, 8.0, 2.0);
        assert!((lane[0][0] - a[0]).abs() < 1e-9 && (lane[0][1] - a[1]).abs() < 1e-9);
        let last = lane[lane.len() - 1];
        assert!((last[0] - b[0]).abs() < 1e-9 && (last[1] - b[1]).abs() < 1e-9);
        let bend = lane
            .iter()
            .map(|p| segment_distance_xy(p[0], p[1], a, b))
            .fold(0.0, f64::max);
        assert!(bend > 0.5 && bend < 10.0, "meander {bend}");
        let index = LaneIndex::new(std::slice::from_ref(&lane), -128.0, 64, 4.0, 20.0);
        for (x, y) in [(0.0, 0.0), (10.0, 15.0), (-35.0, -12.0), (55.0, 30.0)] {
            let brute = lane
                .windows(2)
                .map(|w| segment_distance_xy(x, y, w[0], w[1]))
                .fold(f64::INFINITY, f64::min);
            let indexed = index.distance_m(x, y);
            if brute <= 20.0 {
                assert!((indexed - brute).abs() < 1e-9, "({x}, {y}): {indexed} vs {brute}");
            } else {
                assert!(indexed >= 20.0);
            }
        }
    }
}
