//! Attitude mathematics for pdcal: quaternions in the dataset's convention, the
//! building blocks of the multiplicative EKF, attitude from vector pairs, and the
//! photodiode-normal parametrisation of the paper.
//!
//! # Conventions
//!
//! **Quaternions are scalar last and passive** (Markley & Crassidis,
//! *Fundamentals of Spacecraft Attitude Determination and Control*, 2014, Sec. 2.9):
//! `q = [q_x, q_y, q_z, q_w]` with the attitude matrix
//!
//! ```text
//! A(q) = (q_w^2 - |q_v|^2) I + 2 q_v q_v^T - 2 q_w [q_v x],      v_B = A(q) v_I
//! ```
//!
//! mapping inertial (GCRF) components to body components. nalgebra's
//! `UnitQuaternion` is a Hamilton, active rotation: for the same four numbers its
//! `to_rotation_matrix()` is `A(q)^T`. The mapping used here is therefore
//! `Quat { x, y, z, w }  <->  UnitQuaternion::new_normalize(Quaternion::new(w, x, y, z))`
//! with `A(q) = R_nalgebra^T` (the rotation that takes body axes into inertial axes),
//! and Markley's product `q' ⊗ q` (for which `A(q' ⊗ q) = A(q') A(q)`) equals
//! nalgebra's `q * q'` (reversed order). Tests pin all three facts.
//!
//! # Modules
//!
//! - [`quat`]: [`Quat`], the scalar-last quaternion, its attitude matrix, Markley
//!   composition and the nalgebra mapping.
//! - [`mekf`]: attitude-error vector (rotation vector, `A(q_true) = A(dq(a)) A(q_est)`)
//!   and multiplicative reset, closed-form propagation from a gyro rate, the 6x6
//!   discrete `Phi` and `Qd` of attitude error + gyro bias.
//! - [`dynamics`]: the rigid body (inertia checked physical), Euler's equations, the
//!   quaternion kinematics, the gravity-gradient torque and an RK4 integrator.
//! - [`vector_pairs`]: Davenport's q-method and TRIAD.
//! - [`direction`]: photodiode normal from azimuth/elevation (paper Eq. 16), its
//!   partials (Eqs. 23-24), and a tangent-plane parametrisation free of the pole
//!   singularity ([`tangent_basis`], [`rotate_normal`]).
//!
//! # Why hand-written
//!
//! nalgebra supplies the linear algebra (`SymmetricEigen` for the q-method, rotation
//! matrix <-> quaternion); no maintained crate provides the MEKF matrices or
//! Wahba-problem solvers in this convention, and they are a few closed forms each.

pub mod direction;
pub mod dynamics;
mod error;
pub mod mekf;
pub mod quat;
mod series;
pub mod vector_pairs;

pub use direction::{
    RAX2_TABLE1_AZ_EL_DEG, TANGENT_BASIS_SINGULAR_DIRECTION, TangentFrame, az_el_from_normal,
    normal_from_az_el, normal_partials, rotate_normal, rotate_normal_in, tangent_basis,
    tangent_basis_about, wrap_deg,
};
pub use error::AttitudeError;
pub use mekf::GyroNoise;
pub use quat::Quat;
pub use vector_pairs::{VectorPair, q_method, triad};

use nalgebra::{Matrix3, Vector3};

/// The cross-product matrix `[v x]`, so that `skew(v) * w == v.cross(&w)`.
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}
