//! The scalar-last attitude quaternion of the dataset format.

use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::skew;

/// Unit attitude quaternion, scalar last, `v_B = A(q) v_I` (see the crate's Conventions).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quat {
    /// Vector part, x component.
    pub x: f64,
    /// Vector part, y component.
    pub y: f64,
    /// Vector part, z component.
    pub z: f64,
    /// Scalar part.
    pub w: f64,
}

impl Quat {
    /// The identity attitude (body axes equal inertial axes).
    pub const IDENTITY: Quat = Quat {
        x: 0.0,
        y: 0.0,
        z: 0.0,
        w: 1.0,
    };

    /// Builds a quaternion from its four components and normalises it.
    /// Returns `None` for a zero or non-finite input.
    pub fn new_normalized(x: f64, y: f64, z: f64, w: f64) -> Option<Quat> {
        let norm = (x * x + y * y + z * z + w * w).sqrt();
        (norm.is_finite() && norm > 0.0).then(|| Quat {
            x: x / norm,
            y: y / norm,
            z: z / norm,
            w: w / norm,
        })
    }

    /// Vector part `q_v`.
    pub fn vector(&self) -> Vector3<f64> {
        Vector3::new(self.x, self.y, self.z)
    }

    /// Euclidean norm of the four components (1 for a valid attitude).
    pub fn norm(&self) -> f64 {
        (self.x * self.x + self.y * self.y + self.z * self.z + self.w * self.w).sqrt()
    }

    /// The attitude matrix `A(q) = (q_w^2 - |q_v|^2) I + 2 q_v q_v^T - 2 q_w [q_v x]`.
    #[inline]
    pub fn attitude_matrix(&self) -> Matrix3<f64> {
        let v = self.vector();
        Matrix3::identity() * (self.w * self.w - v.norm_squared()) + v * v.transpose() * 2.0
            - skew(&v) * (2.0 * self.w)
    }

    /// Body components of an inertial vector: `A(q) v_I`.
    pub fn to_body(&self, v_inertial: &Vector3<f64>) -> Vector3<f64> {
        self.attitude_matrix() * v_inertial
    }

    /// Markley's composition `self ⊗ other`, defined so that
    /// `A(self ⊗ other) = A(self) A(other)`: apply `other` first, then `self`.
    pub fn compose(&self, other: &Quat) -> Quat {
        Quat::from_nalgebra(&(other.to_nalgebra() * self.to_nalgebra()))
    }

    /// The inverse (conjugate) attitude, `A(q^-1) = A(q)^T`.
    pub fn inverse(&self) -> Quat {
        Quat {
            x: -self.x,
            y: -self.y,
            z: -self.z,
            w: self.w,
        }
    }

    /// The same rotation with a non-negative scalar part (q and -q are one attitude).
    pub fn canonical(&self) -> Quat {
        if self.w < 0.0 {
            Quat {
                x: -self.x,
                y: -self.y,
                z: -self.z,
                w: -self.w,
            }
        } else {
            *self
        }
    }

    /// nalgebra's unit quaternion with the same components; its rotation matrix is `A(q)^T`.
    pub fn to_nalgebra(&self) -> UnitQuaternion<f64> {
        UnitQuaternion::new_normalize(Quaternion::new(self.w, self.x, self.y, self.z))
    }

    /// The inverse of [`Quat::to_nalgebra`].
    pub fn from_nalgebra(q: &UnitQuaternion<f64>) -> Quat {
        Quat {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        }
    }

    /// The quaternion of a proper orthogonal attitude matrix `A` (v_B = A v_I).
    pub fn from_attitude_matrix(a: &Matrix3<f64>) -> Quat {
        let rotation = nalgebra::Rotation3::from_matrix_unchecked(a.transpose());
        Quat::from_nalgebra(&UnitQuaternion::from_rotation_matrix(&rotation))
    }

    /// Rotation angle between two attitudes, radians in `[0, pi]`.
    pub fn angle_to(&self, other: &Quat) -> f64 {
        let dot = (self.x * other.x + self.y * other.y + self.z * other.z + self.w * other.w).abs();
        2.0 * dot.min(1.0).acos()
    }
}
