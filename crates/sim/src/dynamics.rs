//! The simulator's disturbance torques on top of the rigid-body dynamics of
//! [`pdcal_attitude::dynamics`] (re-exported here): which torques act and their inertial
//! environment over one interval.

use nalgebra::Vector3;
use pdcal_attitude::Quat;
pub use pdcal_attitude::dynamics::*;

/// Which disturbance torques act (all off is torque-free motion).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Disturbances {
    /// Gravity-gradient torque on.
    pub gravity_gradient: bool,
    /// Residual magnetic dipole, body frame, A m^2 (zero for none).
    pub dipole_body_a_m2: Vector3<f64>,
}

/// The inertial environment over one interval `[0, dt]`: position and magnetic field at
/// both ends, interpolated linearly in between (both change on the orbital time scale,
/// ~100 min, so over a 1 s interval the linear interpolant is exact to ~1e-7 relative).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TorqueEnvironment {
    /// Position at the start and end of the interval, GCRF, km.
    pub r_gcrf_km: [Vector3<f64>; 2],
    /// Magnetic field at the start and end of the interval, GCRF, nT.
    pub b_gcrf_nt: [Vector3<f64>; 2],
    /// Length of the interval, s.
    pub dt_s: f64,
}

impl TorqueEnvironment {
    /// Total disturbance torque at time `t_s` into the interval, body frame, N m.
    pub fn torque(
        &self,
        body: &RigidBody,
        disturbances: &Disturbances,
        t_s: f64,
        q: &Quat,
    ) -> Vector3<f64> {
        let has_dipole = disturbances.dipole_body_a_m2 != Vector3::zeros();
        if !disturbances.gravity_gradient && !has_dipole {
            return Vector3::zeros();
        }
        let f = if self.dt_s > 0.0 {
            t_s / self.dt_s
        } else {
            0.0
        };
        let a = q.attitude_matrix();
        let mut torque = Vector3::zeros();
        if disturbances.gravity_gradient {
            let r = self.r_gcrf_km[0].lerp(&self.r_gcrf_km[1], f);
            torque += gravity_gradient_torque(body.inertia_kg_m2(), &(a * r));
        }
        if has_dipole {
            let b = self.b_gcrf_nt[0].lerp(&self.b_gcrf_nt[1], f);
            torque += magnetic_dipole_torque(&disturbances.dipole_body_a_m2, &(a * b));
        }
        torque
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rax2_body() -> RigidBody {
        RigidBody::new(nalgebra::Matrix3::from_diagonal(&Vector3::new(
            0.0314, 0.0314, 0.0050,
        )))
        .unwrap()
    }
    #[test]
    fn dipole_torque_is_cross_product_in_tesla() {
        let tau = magnetic_dipole_torque(
            &Vector3::new(0.0, 0.0, 0.1),
            &Vector3::new(30_000.0, 0.0, 0.0),
        );
        // 0.1 A m^2 x 3e-5 T along +y.
        assert!((tau - Vector3::new(0.0, 3e-6, 0.0)).norm() < 1e-20);
    }

    #[test]
    fn dipole_torque_conserves_energy_in_constant_field() {
        // With a constant inertial field the magnetic potential -m.B is conservative:
        // T + (-m.B_body) must stay constant; it checks the sign and frame of the torque.
        let body = rax2_body();
        let dist = Disturbances {
            gravity_gradient: false,
            dipole_body_a_m2: Vector3::new(0.0, 0.0, 0.05),
        };
        let b = Vector3::new(20_000.0, -10_000.0, 25_000.0);
        let env = TorqueEnvironment {
            r_gcrf_km: [Vector3::x() * 7000.0; 2],
            b_gcrf_nt: [b; 2],
            dt_s: 1.0,
        };
        let total = |s: &AttitudeState| {
            body.kinetic_energy_j(&s.w_body_rad_s)
                - dist.dipole_body_a_m2.dot(&(s.q.to_body(&b) * 1e-9))
        };
        let mut s = AttitudeState {
            q: Quat::new_normalized(0.3, 0.1, 0.2, 0.9).unwrap(),
            w_body_rad_s: Vector3::new(0.02, 0.01, -0.03),
        };
        let e0 = total(&s);
        for _ in 0..600 {
            s = propagate(&body, &s, 1.0, DEFAULT_MAX_STEP_S, &|t, q| {
                env.torque(&body, &dist, t, q)
            })
            .unwrap();
        }
        // The magnetic energy (~1e-6 J) is comparable to the kinetic one, so a wrong sign
        // would change the total at the 1e-1 relative level; RK4 error is ~1e-12.
        assert!(
            (total(&s) / e0 - 1.0).abs() < 1e-9,
            "{}",
            total(&s) / e0 - 1.0
        );
    }
}
