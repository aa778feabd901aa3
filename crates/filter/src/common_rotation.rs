//! The one rotation that carries the nominal normals onto the calibrated ones.
//!
//! A sensor head mounted turned from its drawing, or a mounting table written in a body
//! frame turned from the gyro's, moves every normal of the head by one rotation. Per
//! photodiode that move can lie well inside the normals' prior (a head whose normals are
//! 18 deg off its boresight, turned 15 deg about it, moves each normal by 4.6 deg), the
//! residuals then have nothing to contradict, and the comparison of downlinks cannot see
//! a move that is the same in every one. The calibrated normals see it together: the
//! rotation is fitted to them by weighted least squares with their joint posterior
//! covariance (its cross terms carry the common mode: with the Sun as the only vector a
//! common rotation of the normals is told from an attitude error only through the gyro,
//! and the covariance says how well it was).
//!
//! The fit is a finding when the data determined the rotation (its chi-square against
//! its own covariance beyond the point a 3-sigma scalar test would use, 3 dof,
//! [`crate::gate::chi_square_3_threshold`]) and the rotation explains most of the
//! normals' changes (more than [`MIN_EXPLAINED`] of their chi-square against the nominal
//! mounting). Independent mounting errors of `k` photodiodes leave a rotation fitted to
//! them 3 of their `2 k` degrees of freedom, `3 / (2 k)` of the change on average, so with
//! three normals "most" would say nothing: fewer than [`MIN_PHOTODIODES`] normals are not
//! fitted. A finding is a statement of what the data say, not of a failure: the
//! calibration has already moved the normals there; what it cannot tell is why (a head
//! mounted turned, a mounting table written in another frame, or, with the Sun as the
//! only vector and a weak gyro, an attitude error the normals took up).

use nalgebra::{DMatrix, DVector, Matrix3, Rotation3, Vector3};
use serde::{Deserialize, Serialize};

use crate::calibration::Calibration;
use crate::layout::StateLayout;

/// Fewest normals a common rotation is fitted to.
pub const MIN_PHOTODIODES: usize = 4;

/// The part of the normals' changes a rotation must explain to be a finding: most of it.
pub const MIN_EXPLAINED: f64 = 0.5;

/// Gauss-Newton iterations of the fit (each a rotation of at most a few degrees once the
/// first has taken the bulk; the changes a prior allows converge in three or four).
const ITERATIONS: usize = 20;

/// The rotation of the calibrated normals from the nominal ones, as a whole.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CommonRotation {
    /// The photodiodes fitted (1-based): used, their normals estimated and not
    /// `not-determined`.
    pub photodiodes: Vec<usize>,
    /// The rotation vector (axis times angle) that takes the nominal normals onto the
    /// calibrated ones, body frame, deg.
    pub rotation_body_deg: [f64; 3],
    /// Its angle, deg.
    pub angle_deg: f64,
    /// Its 1-sigma per body axis, deg.
    pub sigma_body_deg: [f64; 3],
    /// Its chi-square against its own covariance (3 dof): how far the data put it from no
    /// rotation.
    pub chi_square: f64,
    /// The chi-square beyond which the data determined a rotation (3-sigma, 3 dof).
    pub chi_square_threshold: f64,
    /// The largest turn of the head these data would leave undetermined, deg: a turn whose
    /// chi-square reaches the threshold about the worst-determined axis,
    /// `sqrt(threshold x the largest eigenvalue of the rotation's covariance)`.
    #[serde(default)]
    pub unseen_turn_deg: f64,
    /// The part of the normals' changes (their chi-square against the nominal mounting)
    /// the rotation explains, 0..1.
    pub explained: f64,
    /// Determined and explaining most of the changes: the head (or the mounting table's
    /// frame) is turned, a finding said in the warnings.
    pub finding: bool,
}

impl CommonRotation {
    /// The warning that says the finding, or `None` when it is not one.
    pub fn warning(&self) -> Option<String> {
        if !self.finding {
            return None;
        }
        Some(format!(
            "the calibrated normals of {} are turned together from the nominal mounting by \
             {}: a sensor head mounted turned, a mounting table in another frame, or an \
             attitude error the normals took up; check the mounting",
            self.names(),
            self.figures(),
        ))
    }

    /// The fit in one sentence, finding or not (the printed summary and index.html): what
    /// the data say of the normals' common rotation, and why it is or is not a finding.
    pub fn describe(&self) -> String {
        let verdict = if self.finding {
            "a finding (see the warnings)".to_owned()
        } else if self.chi_square > self.chi_square_threshold {
            format!(
                "determined, not a finding: a finding explains more than {:.0} % (independent \
                 mounting errors of {} normals leave {:.0} % to a rotation on average)",
                100.0 * MIN_EXPLAINED,
                self.photodiodes.len(),
                100.0 * 3.0 / (2.0 * self.photodiodes.len() as f64),
            )
        } else {
            format!(
                "not determined (a determined rotation has a chi-square above {:.1}): a head \
                 mounted turned by up to about {:.0} deg would go unseen",
                self.chi_square_threshold, self.unseen_turn_deg
            )
        };
        format!("{}: {}; {verdict}", self.names(), self.figures())
    }

    fn names(&self) -> String {
        let names: Vec<String> = self
            .photodiodes
            .iter()
            .map(|i| format!("pd{i:02}"))
            .collect();
        names.join(", ")
    }

    /// The angle, axis, sigmas, chi-square and explained part.
    fn figures(&self) -> String {
        let r = Vector3::from(self.rotation_body_deg);
        let axis = r / r.norm().max(f64::MIN_POSITIVE);
        let s = self.sigma_body_deg;
        format!(
            "{:.1} deg about body ({:.3}, {:.3}, {:.3}) (rotation vector sigma {:.1}, {:.1}, \
             {:.1} deg; chi-square {:.1} for 3 dof; it explains {:.0} % of their changes)",
            self.angle_deg,
            axis.x,
            axis.y,
            axis.z,
            s[0],
            s[1],
            s[2],
            self.chi_square,
            100.0 * self.explained,
        )
    }
}

/// The common rotation of the normals of the photodiodes marked `fitted` from `initial`'s
/// to `calibration`'s, with the final `covariance` in `layout`; `None` when fewer than
/// [`MIN_PHOTODIODES`] are fitted or their covariance or the fit's normal matrix is not
/// positive definite.
pub fn common_rotation(
    initial: &Calibration,
    calibration: &Calibration,
    covariance: &DMatrix<f64>,
    layout: &StateLayout,
    fitted: &[bool],
) -> Option<CommonRotation> {
    let chosen: Vec<usize> = (0..calibration.photodiodes.len())
        .filter(|&i| fitted.get(i).copied().unwrap_or(false) && layout.normal(i).is_some())
        .collect();
    if chosen.len() < MIN_PHOTODIODES {
        return None;
    }
    let fit = Fit::new(initial, calibration, covariance, layout, &chosen)?;
    let none = fit.chi_square(&Rotation3::identity());
    let mut rotation = Rotation3::identity();
    for _ in 0..ITERATIONS {
        let (step, _) = fit.step(&rotation)?;
        rotation = Rotation3::new(step) * rotation;
        if step.norm() < 1e-12 {
            break;
        }
    }
    let (_, information) = fit.step(&rotation)?;
    let covariance_rad2 = information.try_inverse()?;
    let vector = rotation.scaled_axis();
    let chi_square = vector.dot(&(information * vector));
    let left = fit.chi_square(&rotation);
    let explained = if none > 0.0 {
        (1.0 - left / none).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let threshold = crate::gate::chi_square_3_threshold(3.0);
    let widest_rad2 = covariance_rad2.symmetric_eigenvalues().max();
    Some(CommonRotation {
        photodiodes: chosen.iter().map(|i| i + 1).collect(),
        rotation_body_deg: std::array::from_fn(|k| vector[k].to_degrees()),
        angle_deg: vector.norm().to_degrees(),
        sigma_body_deg: std::array::from_fn(|k| covariance_rad2[(k, k)].sqrt().to_degrees()),
        chi_square,
        chi_square_threshold: threshold,
        unseen_turn_deg: (threshold * widest_rad2).sqrt().to_degrees(),
        explained,
        finding: chi_square > threshold && explained > MIN_EXPLAINED,
    })
}

/// The weighted least squares of the rotation: each calibrated normal with its tangent
/// basis, the nominal normal, and the inverse of their stacked tangent covariance.
struct Fit {
    normals: Vec<FittedNormal>,
    weight: DMatrix<f64>,
}

/// A calibrated normal, its tangent basis (the covariance's) and the nominal normal.
type FittedNormal = (Vector3<f64>, (Vector3<f64>, Vector3<f64>), Vector3<f64>);

impl Fit {
    fn new(
        initial: &Calibration,
        calibration: &Calibration,
        covariance: &DMatrix<f64>,
        layout: &StateLayout,
        chosen: &[usize],
    ) -> Option<Self> {
        let states: Vec<usize> = chosen
            .iter()
            .filter_map(|&i| layout.normal(i))
            .flat_map(|d| [d, d + 1])
            .collect();
        if states.iter().any(|&k| k >= covariance.nrows()) {
            return None;
        }
        let block = covariance.select_rows(&states).select_columns(&states);
        let block = (&block + block.transpose()) * 0.5;
        let weight = block.cholesky()?.inverse();
        let normals = chosen
            .iter()
            .map(|&i| {
                let n = calibration.photodiodes[i].n_body();
                (
                    n,
                    layout.tangent_basis(i, &n),
                    initial.photodiodes[i].n_body(),
                )
            })
            .collect();
        Some(Fit { normals, weight })
    }

    /// Per normal, the tangent coordinates at the calibrated normal of the way to the
    /// rotated nominal one (the log map: along the great circle, by the angle).
    fn residual(&self, rotation: &Rotation3<f64>) -> DVector<f64> {
        let mut r = DVector::zeros(2 * self.normals.len());
        for (j, (n, basis, nominal)) in self.normals.iter().enumerate() {
            let (d1, d2) = crate::smoother::tangent_log_in(n, &(rotation * nominal), basis);
            r[2 * j] = d1;
            r[2 * j + 1] = d2;
        }
        r
    }

    fn chi_square(&self, rotation: &Rotation3<f64>) -> f64 {
        let r = self.residual(rotation);
        r.dot(&(&self.weight * &r))
    }

    /// One Gauss-Newton step (a rotation applied on the left) and the normal matrix.
    fn step(&self, rotation: &Rotation3<f64>) -> Option<(Vector3<f64>, Matrix3<f64>)> {
        let r = self.residual(rotation);
        let mut jacobian = DMatrix::zeros(r.len(), 3);
        for (j, (_, (e1, e2), nominal)) in self.normals.iter().enumerate() {
            // d(exp(d) m)/dd = -[m x]: the row of e is (m x e)^T.
            let m = rotation * nominal;
            for (row, e) in [(2 * j, e1), (2 * j + 1, e2)] {
                let g = m.cross(e);
                jacobian.row_mut(row).copy_from_slice(&[g.x, g.y, g.z]);
            }
        }
        let jw = jacobian.transpose() * &self.weight;
        let normal = &jw * &jacobian;
        let information = Matrix3::from_fn(|a, b| normal[(a, b)]);
        let gradient = &jw * &r;
        let step =
            information
                .cholesky()?
                .solve(&Vector3::new(-gradient[0], -gradient[1], -gradient[2]));
        Some((step, information))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::PdCalibration;
    use nalgebra::Matrix2;
    use pdcal_attitude::normal_from_az_el;
    use pdcal_photodiode::{MeasurementModel, Photodiode};
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    /// Six normals of a canted head and a layout whose tangent frames are theirs.
    fn head() -> (Vec<Vector3<f64>>, StateLayout) {
        let normals: Vec<Vector3<f64>> = [(0.0, 72.0), (60.0, 50.0), (120.0, 72.0)]
            .iter()
            .chain(&[(180.0, 50.0), (240.0, 72.0), (300.0, 50.0)])
            .map(|(az, el): &(f64, f64)| normal_from_az_el(az.to_radians(), el.to_radians()))
            .collect();
        let pds = normals
            .iter()
            .map(|n| Photodiode::new(1.0, *n, 0.0).expect("valid"))
            .collect();
        (
            normals,
            StateLayout::new(&MeasurementModel::paper(pds), true),
        )
    }

    fn calibration(normals: &[Vector3<f64>]) -> Calibration {
        Calibration {
            format_version: crate::calibration::CALIBRATION_FORMAT_VERSION,
            photodiodes: normals
                .iter()
                .map(|n| PdCalibration::from_normal(1.0, 0.01, n, &Matrix2::identity()))
                .collect(),
            gyro_bias_rad_s: [0.0; 3],
            gyro_bias_sigma_rad_s: [0.01; 3],
            parameters: Vec::new(),
            status: Vec::new(),
        }
    }

    /// A covariance with `sigma_rad` on every normal's tangent axes and a common part
    /// (correlation 0.3 between the photodiodes' like axes), as a Sun-only run leaves.
    fn covariance(layout: &StateLayout, sigma_rad: f64) -> DMatrix<f64> {
        let n = layout.len();
        let mut p = DMatrix::identity(n, n) * 1e-4;
        let normals: Vec<usize> = (0..layout.photodiodes())
            .filter_map(|i| layout.normal(i))
            .collect();
        for &a in &normals {
            for &b in &normals {
                for k in 0..2 {
                    p[(a + k, b + k)] = sigma_rad * sigma_rad * if a == b { 1.0 } else { 0.3 };
                }
            }
        }
        p
    }

    fn moved(normals: &[Vector3<f64>], layout: &StateLayout, d: &[[f64; 2]]) -> Vec<Vector3<f64>> {
        normals
            .iter()
            .zip(d)
            .enumerate()
            .map(|(i, (n, d))| {
                let basis = layout.tangent_basis(i, n);
                pdcal_attitude::rotate_normal_in(n, (&basis.0, &basis.1), d[0], d[1])
            })
            .collect()
    }

    /// The rotation fitted to every normal of the head.
    fn fit(
        nominal: &[Vector3<f64>],
        calibrated: &[Vector3<f64>],
        p: &DMatrix<f64>,
        layout: &StateLayout,
    ) -> CommonRotation {
        let all = vec![true; nominal.len()];
        common_rotation(
            &calibration(nominal),
            &calibration(calibrated),
            p,
            layout,
            &all,
        )
        .expect("fitted")
    }

    #[test]
    fn a_head_turned_as_a_whole_is_found_with_its_rotation() {
        let (nominal, layout) = head();
        let turn = Vector3::new(0.02, -0.05, -0.26);
        let turned: Vec<Vector3<f64>> = nominal.iter().map(|n| Rotation3::new(turn) * n).collect();
        let p = covariance(&layout, 1f64.to_radians());
        let r = fit(&nominal, &turned, &p, &layout);
        for k in 0..3 {
            assert!(
                (r.rotation_body_deg[k] - turn[k].to_degrees()).abs() < 1e-6,
                "{:?} against {turn:?}",
                r.rotation_body_deg
            );
        }
        assert!(r.explained > 0.999_999 && r.finding, "{r:?}");
        let w = r.warning().expect("a warning");
        assert!(
            w.contains("pd01, pd02, pd03, pd04, pd05, pd06") && w.contains("15.2 deg"),
            "{w}"
        );
        let d = r.describe();
        assert!(
            d.starts_with("pd01, pd02, pd03, pd04, pd05, pd06: 15.2 deg"),
            "{d}"
        );
        assert!(d.ends_with("a finding (see the warnings)"), "{d}");
        // No change at all: nothing determined.
        let none = fit(&nominal, &nominal, &p, &layout);
        assert!(none.warning().is_none());
        assert!(
            none.describe()
                .contains("not determined (a determined rotation has a chi-square above 14.2): a head mounted turned by up to about ")
        );
    }

    #[test]
    fn independent_mounting_errors_are_not_a_turned_head() {
        let (nominal, layout) = head();
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let p = covariance(&layout, 0.1f64.to_radians());
        let mut found = 0;
        for _ in 0..200 {
            let d: Vec<[f64; 2]> = (0..nominal.len())
                .map(|_| {
                    std::array::from_fn(|_| {
                        let z: f64 = StandardNormal.sample(&mut rng);
                        3f64.to_radians() * z
                    })
                })
                .collect();
            let calibrated = moved(&nominal, &layout, &d);
            let r = fit(&nominal, &calibrated, &p, &layout);
            // Determined (the sigmas are 30 times below the errors) but not most of it.
            found += usize::from(r.finding);
            if !r.finding {
                let d = r.describe();
                assert!(d.contains("; determined, not a finding: a finding explains more than 50 % (independent mounting errors of 6 normals leave 25 % to a rotation on average)"), "{d}");
            }
        }
        // A rotation takes 3 of the 12 degrees of freedom: beyond half of the change in
        // about 3 % of draws (Beta(1.5, 4.5) above 0.5).
        assert!(found <= 16, "{found} of 200 draws called a turned head");
    }

    #[test]
    fn the_rotation_sigma_is_its_spread_over_noise_drawn_from_the_covariance() {
        let (nominal, layout) = head();
        let p = covariance(&layout, 2f64.to_radians());
        let states: Vec<usize> = (0..nominal.len())
            .filter_map(|i| layout.normal(i))
            .flat_map(|d| [d, d + 1])
            .collect();
        let block = p.select_rows(&states).select_columns(&states);
        let l = block.cholesky().expect("pd").l();
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let (mut sum, mut sum_sq, mut sigma) = (Vector3::zeros(), Vector3::zeros(), [0.0; 3]);
        let draws = 2000;
        for _ in 0..draws {
            let z = DVector::from_fn(states.len(), |_, _| StandardNormal.sample(&mut rng));
            let e = &l * z;
            let d: Vec<[f64; 2]> = (0..nominal.len())
                .map(|i| [e[2 * i], e[2 * i + 1]])
                .collect();
            let calibrated = moved(&nominal, &layout, &d);
            let r = fit(&nominal, &calibrated, &p, &layout);
            let v = Vector3::from(r.rotation_body_deg);
            sum += v;
            sum_sq += v.component_mul(&v);
            sigma = r.sigma_body_deg;
        }
        for k in 0..3 {
            let mean = sum[k] / draws as f64;
            let spread = (sum_sq[k] / draws as f64 - mean * mean).sqrt();
            assert!(
                (spread / sigma[k] - 1.0).abs() < 0.08,
                "axis {k}: spread {spread:.3} deg against sigma {:.3}",
                sigma[k]
            );
        }
    }

    /// `unseen_turn_deg` is the size at which the least-determined turn reaches the
    /// threshold: every turn a little larger is determined, and the weakest direction at
    /// that size sits on the threshold.
    #[test]
    fn the_unseen_turn_is_the_largest_the_fit_leaves_undetermined() {
        let (nominal, layout) = head();
        let p = covariance(&layout, 1.5f64.to_radians());
        let unseen = fit(&nominal, &nominal, &p, &layout).unseen_turn_deg;
        let directions = 600;
        let mut weakest = f64::INFINITY;
        for k in 0..directions {
            // Fibonacci lattice: directions spread evenly over the sphere.
            let z = 1.0 - 2.0 * (k as f64 + 0.5) / directions as f64;
            let phi = k as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
            let axis = Vector3::new(
                (1.0 - z * z).sqrt() * phi.cos(),
                (1.0 - z * z).sqrt() * phi.sin(),
                z,
            );
            let chi_square_at = |deg: f64| {
                let turn = Rotation3::new(axis * deg.to_radians());
                let turned: Vec<Vector3<f64>> = nominal.iter().map(|n| turn * n).collect();
                fit(&nominal, &turned, &p, &layout)
            };
            let above = chi_square_at(1.05 * unseen);
            assert!(above.chi_square > above.chi_square_threshold, "{above:?}");
            weakest = weakest.min(chi_square_at(unseen).chi_square);
        }
        let threshold = crate::gate::chi_square_3_threshold(3.0);
        assert!(
            (weakest / threshold - 1.0).abs() < 0.05,
            "weakest chi-square {weakest:.2} at {unseen:.2} deg against {threshold:.2}"
        );
    }

    #[test]
    fn fewer_than_four_normals_are_not_fitted() {
        let (nominal, layout) = head();
        let p = covariance(&layout, 1f64.to_radians());
        let three = [true, true, true, false, false, false];
        let cal = calibration(&nominal);
        assert!(common_rotation(&cal, &cal, &p, &layout, &three).is_none());
    }
}
