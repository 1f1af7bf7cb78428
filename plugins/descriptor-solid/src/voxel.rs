//! Voxel downsampling for SOLiD (Kim et al., RA-L 2024, count points of a keyframe voxelised at 0.4 m):
//! the same rule as `skid_geometry::voxel_downsample` (the first point of every occupied voxel, in input
//! order), as the indices of the kept points, which extraction then bins.
//!
//! Occupied voxels are bits of a dense grid over the box every point SOLiD can count lies in (the range
//! limit around the sensor, the heights the vertical field of view reaches there): 3.3 MB for the
//! default 80 m and 0.4 m, of which a scan touches a small part, reused from scan to scan and cleared
//! word by word where it was written. A point outside that box (beyond the range limit, say) is looked
//! up in a hash set instead, with the voxel key packed into a u64 and a cheap integer hash; so which
//! points are kept never depends on the box, only how fast. A hash set for every point took about 1.2 ms
//! of a 120k-point KITTI scan (SipHash about 4 ms), the grid about 0.7 ms.
//!
//! Voxel indices in the hash set are packed in 21 bits per axis (±1,048,576 voxels, ±419 km at 0.4 m);
//! farther points would share keys, but they lie far beyond any range limit the descriptor accepts.

use std::collections::HashSet;
use std::hash::{BuildHasherDefault, Hasher};

use skid_core::Point;

/// The largest grid kept, in voxels (bits): 128 Mbit = 16 MB. A finer voxel or a longer range than
/// that uses the hash set alone.
const MAX_GRID_VOXELS: u64 = 1 << 27;

/// splitmix64's finaliser: every input bit reaches every output bit, so both the low bits (the bucket)
/// and the high bits (the control byte) of the hash table are well spread.
#[derive(Default)]
struct Mix64(u64);

impl Hasher for Mix64 {
    fn finish(&self) -> u64 {
        let mut x = self.0;
        x ^= x >> 30;
        x = x.wrapping_mul(0xbf58_476d_1ce4_e5b9);
        x ^= x >> 27;
        x = x.wrapping_mul(0x94d0_49bb_1331_11eb);
        x ^ (x >> 31)
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = self.0.rotate_left(8) ^ u64::from(b);
        }
    }

    fn write_u64(&mut self, value: u64) {
        self.0 = value;
    }
}

/// ⌊v⌋ as an integer (saturating far outside i64). `f32::floor` is a call into libm on x86-64 without
/// SSE4.1, a fifth of extraction time; a truncating cast corrected for negative fractions is not.
#[inline]
fn floor_to_i64(v: f32) -> i64 {
    let truncated = v as i64;
    if (truncated as f32) > v {
        truncated.saturating_sub(1)
    } else {
        truncated
    }
}

/// Points whose grid cells are computed together, in a loop without branches the compiler vectorises.
const BLOCK: usize = 256;

/// The cell of a point outside the grid.
const OUTSIDE: u32 = u32::MAX;

/// The cell of a point with a coordinate or intensity that is not finite.
const NOT_FINITE: u32 = u32::MAX - 1;

/// No cell at all (before the first point). The three markers lie above every grid cell.
const NO_CELL: u32 = u32::MAX - 2;

/// The box of the dense grid, in voxel indices: the lowest voxel on each axis and the voxels per axis.
/// The box holds the origin and at most [`MAX_GRID_VOXELS`] voxels, so every index fits an i32 and
/// every cell a u32. Its x and y sides are powers of two, so a cell is made by shifts, not
/// multiplications (which SSE2 has no 32-bit form of).
#[derive(Clone, Copy, Debug)]
struct GridBox {
    lowest: [i32; 3],
    voxels: [u32; 3],
    x_bits: u32,
    y_bits: u32,
}

impl GridBox {
    /// The cell of each point of `block`, [`OUTSIDE`] or [`NOT_FINITE`]. (The grid has fewer cells than
    /// either.)
    fn cells(&self, inverse_size: f32, block: &[Point], cells: &mut [u32]) {
        let [vx, vy, vz] = self.voxels;
        for (cell, point) in cells.iter_mut().zip(block) {
            // ⌊v⌋ by a truncating cast corrected for negative fractions (`f32::floor` is a call into
            // libm on x86-64 without SSE4.1). A value beyond i32 saturates and lands outside the box.
            let offset = |v: f32, lowest: i32| {
                let scaled = v * inverse_size;
                let truncated = scaled as i32;
                let floor = truncated.wrapping_sub(i32::from((truncated as f32) > scaled));
                floor.wrapping_sub(lowest) as u32
            };
            let (x, y, z) = (
                offset(point.x, self.lowest[0]),
                offset(point.y, self.lowest[1]),
                offset(point.z, self.lowest[2]),
            );
            let inside = (x < vx) & (y < vy) & (z < vz);
            let packed = (z << (self.x_bits + self.y_bits)) | (y << self.x_bits) | x;
            let finite =
                point.x.is_finite() & point.y.is_finite() & point.z.is_finite() & point.intensity.is_finite();
            *cell = match (finite, inside) {
                (false, _) => NOT_FINITE,
                (true, true) => packed,
                (true, false) => OUTSIDE,
            };
        }
    }
}

/// The voxels taken in one scan, and the memory reused from scan to scan.
#[derive(Clone, Debug)]
pub struct VoxelOccupancy {
    inverse_size: f32,
    grid: Option<GridBox>,
    bits: Vec<u64>,
    /// Words of `bits` written since the last clear.
    written_words: Vec<usize>,
    outside: HashSet<u64, BuildHasherDefault<Mix64>>,
    kept: Vec<usize>,
}

impl VoxelOccupancy {
    /// Occupancy of voxels of `voxel_size_m` (> 0, finite), with the dense grid over x and y in
    /// [−half_width_m, half_width_m] and z in [z_min_m, z_max_m] (the box is widened to hold the
    /// origin). The grid's memory is taken on first use.
    pub fn new(voxel_size_m: f32, half_width_m: f32, z_min_m: f32, z_max_m: f32) -> Self {
        let inverse_size = 1.0 / voxel_size_m;
        let index = |v: f32| floor_to_i64(v * inverse_size);
        let lowest = [-half_width_m, -half_width_m, z_min_m].map(|v| index(v.min(0.0)));
        let highest = [half_width_m, half_width_m, z_max_m].map(|v| index(v.max(0.0)));
        // Clamped so the product cannot overflow; a clamped axis refuses the grid anyway.
        let limit = i128::from(MAX_GRID_VOXELS) + 1;
        let mut voxels =
            [0, 1, 2].map(|axis| (i128::from(highest[axis]) - i128::from(lowest[axis]) + 1).clamp(1, limit));
        for side in &mut voxels[..2] {
            // A side is at most `limit`, so this stays far from overflow.
            *side = (*side as u64).next_power_of_two().into();
        }
        let fits = voxels.iter().product::<i128>() <= i128::from(MAX_GRID_VOXELS);
        let grid = fits.then(|| GridBox {
            lowest: lowest.map(|v| v as i32),
            voxels: voxels.map(|n| n as u32),
            x_bits: voxels[0].trailing_zeros(),
            y_bits: voxels[1].trailing_zeros(),
        });
        Self {
            inverse_size,
            grid,
            bits: Vec::new(),
            written_words: Vec::new(),
            outside: HashSet::default(),
            kept: Vec::new(),
        }
    }

    /// The indices of the first point of every voxel of `points`, in input order (the occupancy is
    /// cleared first). `Err(i)`: point `i` is not finite.
    pub fn first_per_voxel(&mut self, points: &[Point]) -> Result<&[usize], usize> {
        self.clear();
        if self.bits.is_empty()
            && let Some(grid) = self.grid
        {
            let voxels = grid.voxels.iter().map(|&n| n as usize).product::<usize>();
            self.bits = vec![0u64; voxels.div_ceil(64)];
        }
        let mut cells = [OUTSIDE; BLOCK];
        // The cell of the last point in the grid: a scan's next point often shares it.
        let mut last_cell = NO_CELL;
        for (block_index, block) in points.chunks(BLOCK).enumerate() {
            let start = block_index * BLOCK;
            match &self.grid {
                Some(grid) => grid.cells(self.inverse_size, block, &mut cells[..block.len()]),
                None => cells.fill(OUTSIDE),
            }
            for (offset, (point, &cell)) in block.iter().zip(&cells).enumerate() {
                let first = if cell < NO_CELL {
                    let repeated = cell == last_cell;
                    last_cell = cell;
                    !repeated && self.take_cell(cell as usize)
                } else if cell == OUTSIDE && point.is_finite() {
                    self.take_outside(point)
                } else {
                    return Err(start + offset);
                };
                if first {
                    self.kept.push(start + offset);
                }
            }
        }
        Ok(&self.kept)
    }

    /// Takes a grid cell; true when it was free.
    #[inline]
    fn take_cell(&mut self, cell: usize) -> bool {
        let (word, mask) = (cell / 64, 1u64 << (cell % 64));
        let old = self.bits[word];
        if old & mask != 0 {
            return false;
        }
        if old == 0 {
            self.written_words.push(word);
        }
        self.bits[word] = old | mask;
        true
    }

    /// Takes the voxel of a point outside the grid in the hash set; true when it was free.
    fn take_outside(&mut self, point: &Point) -> bool {
        let axis = |v: f32| (floor_to_i64(v * self.inverse_size) as u64) & 0x1f_ffff;
        self.outside
            .insert(axis(point.x) << 42 | axis(point.y) << 21 | axis(point.z))
    }

    /// Frees every voxel, keeping the memory for the next scan.
    fn clear(&mut self) {
        for &word in &self.written_words {
            self.bits[word] = 0;
        }
        self.written_words.clear();
        self.outside.clear();
        self.kept.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kept(occupancy: &mut VoxelOccupancy, points: &[Point]) -> Vec<Point> {
        let kept = occupancy.first_per_voxel(points).unwrap();
        kept.iter().map(|&i| points[i]).collect()
    }

    #[test]
    fn agrees_with_the_geometry_crate_inside_and_outside_the_grid() {
        let points: Vec<Point> = (0..20_000)
            .map(|i| {
                let t = i as f32 * 0.013;
                Point::new(
                    t.sin() * 30.0 * (1.0 + t * 0.01),
                    t.cos() * 25.0,
                    (t * 3.1).sin() * 4.0 - 1.5,
                )
            })
            .collect();
        for size in [0.1f32, 0.4, 1.0] {
            let expected = skid_geometry::voxel_downsample(&points, size);
            // A grid holding every point, one holding some of them, none at all.
            for (half_width, z_min, z_max) in [(80.0, -10.0, 10.0), (20.0, -2.0, 1.0), (0.0, 0.0, 0.0)] {
                let mut occupancy = VoxelOccupancy::new(size, half_width, z_min, z_max);
                // Twice, so clearing between scans is checked too.
                assert_eq!(kept(&mut occupancy, &points), expected);
                assert_eq!(kept(&mut occupancy, &points), expected);
            }
        }
    }

    #[test]
    fn floors_like_the_library() {
        for v in [
            0.0f32, -0.0, 0.5, -0.5, 1.0, -1.0, 2.999_999, -2.999_999, 1e9, -1e9, 3.4e38, -3.4e38,
        ] {
            assert_eq!(floor_to_i64(v), v.floor() as i64, "{v}");
        }
    }

    #[test]
    fn the_first_point_that_is_not_finite_is_named() {
        let mut points = vec![Point::new(1.0, 2.0, 0.5); 200];
        points[130].y = f32::NAN;
        points[170].z = f32::INFINITY;
        let mut occupancy = VoxelOccupancy::new(0.4, 80.0, -37.0, 3.0);
        assert_eq!(occupancy.first_per_voxel(&points), Err(130));
    }

    #[test]
    fn a_grid_too_large_falls_back_to_the_hash_set() {
        let occupancy = VoxelOccupancy::new(0.01, 1.0e4, -1.0e3, 1.0e3);
        assert!(occupancy.grid.is_none());
        let occupancy = VoxelOccupancy::new(0.4, f32::MAX, -1.0, 1.0);
        assert!(occupancy.grid.is_none());
    }
}
