//! Degeneracy of a registration (Zhang, Kaess and Singh, "On degeneracy of optimization-based state
//! estimation problems", ICRA 2016): the eigenvalues of the 6×6 information `JᵀJ` of a pose update say
//! how well the scan's geometry constrains each direction. Rotation (radians) and translation (metres)
//! have different units, so each 3×3 block is judged on its own, with the other block marginalised out
//! (the Schur complement); a direction whose eigenvalue is a small fraction of its block's largest is
//! degenerate: there the estimate should come from a prior (the IMU, a motion model), not the scan.

use nalgebra::{Matrix3, Matrix6};

/// One 3×3 block's eigen-decomposition, ascending.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlockSpectrum {
    /// Eigenvalues, smallest first.
    pub values: [f64; 3],
    /// Unit eigenvectors as columns, in the order of `values`.
    pub vectors: Matrix3<f64>,
}

impl BlockSpectrum {
    fn of(block: Matrix3<f64>) -> Self {
        let eigen = block.symmetric_eigen();
        let mut order = [0usize, 1, 2];
        order.sort_by(|&a, &b| eigen.eigenvalues[a].total_cmp(&eigen.eigenvalues[b]));
        let mut vectors = Matrix3::zeros();
        for (column, &index) in order.iter().enumerate() {
            vectors.set_column(column, &eigen.eigenvectors.column(index));
        }
        Self {
            values: order.map(|index| eigen.eigenvalues[index]),
            vectors,
        }
    }

    /// Each eigenvalue as a fraction of the largest (zeros when the block holds no information).
    pub fn ratios(&self) -> [f64; 3] {
        let largest = self.values[2];
        if largest > 0.0 {
            self.values.map(|value| (value / largest).max(0.0))
        } else {
            [0.0; 3]
        }
    }

    /// Whether some direction holds less than `ratio` of the block's best-constrained direction.
    pub fn is_degenerate(&self, ratio: f64) -> bool {
        self.values[2] > 0.0 && self.values[0] < ratio * self.values[2]
    }
}

/// The spectra of the first and second 3×3 blocks of `information`, each with the other marginalised
/// out; a singular partner leaves the block as it is.
pub fn marginal_spectra(information: &Matrix6<f64>) -> (BlockSpectrum, BlockSpectrum) {
    let aa = information.fixed_view::<3, 3>(0, 0).into_owned();
    let ab = information.fixed_view::<3, 3>(0, 3).into_owned();
    let bb = information.fixed_view::<3, 3>(3, 3).into_owned();
    let ba = ab.transpose();
    let first = bb
        .try_inverse()
        .map_or(aa, |bb_inverse| aa - ab * bb_inverse * ba);
    let second = aa
        .try_inverse()
        .map_or(bb, |aa_inverse| bb - ba * aa_inverse * ab);
    (BlockSpectrum::of(first), BlockSpectrum::of(second))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Vector3, Vector6};

    /// Point-to-plane information, translation first: each point gives J = [nᵀ, (p × n)ᵀ].
    fn information(points_and_normals: &[(Vector3<f64>, Vector3<f64>)]) -> Matrix6<f64> {
        points_and_normals.iter().fold(Matrix6::zeros(), |sum, (p, n)| {
            let j = Vector6::new(n.x, n.y, n.z, 0.0, 0.0, 0.0) + {
                let c = p.cross(n);
                Vector6::new(0.0, 0.0, 0.0, c.x, c.y, c.z)
            };
            sum + j * j.transpose()
        })
    }

    #[test]
    fn a_flat_ground_leaves_horizontal_translation_unconstrained_and_a_room_does_not() {
        let mut ground = Vec::new();
        for x in -10..=10 {
            for y in -10..=10 {
                ground.push((Vector3::new(f64::from(x), f64::from(y), -1.5), Vector3::z()));
            }
        }
        let (translation, rotation) = marginal_spectra(&information(&ground));
        assert!(translation.is_degenerate(0.05));
        // The weak directions are the horizontal ones; the strong one is vertical.
        assert!(translation.vectors.column(2).z.abs() > 0.99);
        assert!(translation.values[0].abs() < 1e-9 && translation.values[1].abs() < 1e-9);
        // Yaw is unconstrained on a plane too.
        assert!(rotation.is_degenerate(0.05));

        let mut room = ground.clone();
        for t in -10..=10 {
            let t = f64::from(t);
            for (p, n) in [
                (Vector3::new(10.0, t, 0.0), -Vector3::x()),
                (Vector3::new(-10.0, t, 0.0), Vector3::x()),
                (Vector3::new(t, 10.0, 0.0), -Vector3::y()),
                (Vector3::new(t, -10.0, 0.0), Vector3::y()),
            ] {
                room.push((p, n));
            }
        }
        let (translation, rotation) = marginal_spectra(&information(&room));
        assert!(!translation.is_degenerate(0.05), "{:?}", translation.ratios());
        assert!(!rotation.is_degenerate(0.05), "{:?}", rotation.ratios());
    }

    #[test]
    fn an_empty_information_is_not_called_degenerate_and_ratios_are_zero() {
        let (a, b) = marginal_spectra(&Matrix6::zeros());
        assert!(!a.is_degenerate(0.05) && !b.is_degenerate(0.05));
        assert_eq!(a.ratios(), [0.0; 3]);
    }
}
