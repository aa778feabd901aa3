//! The 48 signed permutations of three axes (24 proper rotations and their mirror images).

use nalgebra::Matrix3;

/// How many signed permutations there are.
pub const SIGNED_PERMUTATIONS: usize = 48;

/// Every signed permutation matrix, the identity first.
pub fn signed_permutations() -> Vec<Matrix3<f64>> {
    let orders = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut out = Vec::with_capacity(SIGNED_PERMUTATIONS);
    for order in orders {
        for signs in 0..8u8 {
            let mut m = Matrix3::zeros();
            for (row, &column) in order.iter().enumerate() {
                let sign = if signs & (1 << row) != 0 { -1.0 } else { 1.0 };
                m[(row, column)] = sign;
            }
            out.push(m);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn there_are_48_distinct_orthogonal_ones_half_proper_identity_first() {
        let all = signed_permutations();
        assert_eq!(all.len(), 48);
        assert_eq!(all[0], Matrix3::identity());
        for (i, a) in all.iter().enumerate() {
            assert!((a * a.transpose() - Matrix3::identity()).norm() < 1e-15);
            for b in &all[i + 1..] {
                assert_ne!(a, b);
            }
        }
        let proper = all.iter().filter(|m| m.determinant() > 0.0).count();
        assert_eq!(proper, 24);
    }
}
