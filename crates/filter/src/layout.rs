//! The error-state layout: which state index holds what.
//!
//! ```text
//! [ a (3) | beta (3) | pd 1: C, d1, d2 | pd 2: C, d1, d2 | ... | extra parameters
//!   | albedo gain g (optional) | body rate, dipole, inertia (optional) ]
//! ```
//!
//! The paper orders Eq. (17) as `[a, beta, C, alpha, eps]`; here each photodiode's states are
//! contiguous, so that its H row (6 non-zeros: `a`, `C_i`, `d1_i`, `d2_i`) touches two short
//! runs. `(d1, d2)` is the tangent-plane correction of the normal (see [`crate`] docs) in
//! place of `(alpha, eps)`. Without normal states ([`crate::Mode::ScaleOnly`]) a photodiode
//! has only `C`. Extra states are model parameters marked [`ParameterRole::Estimated`]
//! (e.g. dark offsets added by the diagnosis workflow): adding one is a change of the
//! measurement model's data, not of this code.
//!
//! [`ParameterRole::Estimated`]: pdcal_photodiode::ParameterRole::Estimated

use nalgebra::Vector3;
use pdcal_attitude::TangentFrame;
use pdcal_photodiode::{MeasurementModel, ParameterRole};

/// State index of the attitude error `a` (3 states).
pub const ATTITUDE: usize = 0;
/// State index of the gyro bias `beta` (3 states).
pub const BIAS: usize = 3;
/// Number of attitude and bias states.
pub const CORE: usize = 6;

/// One estimated model parameter held as a state.
#[derive(Debug, Clone, PartialEq)]
pub struct ExtraState {
    /// Index in [`MeasurementModel::parameters`] order.
    pub parameter: usize,
    /// State index.
    pub state: usize,
    /// The photodiode it acts on (`None`: all).
    pub photodiode: Option<usize>,
    /// Parameter name.
    pub name: String,
    /// Parameter unit.
    pub unit: String,
}

/// Where each state lives.
#[derive(Debug, Clone, PartialEq)]
pub struct StateLayout {
    len: usize,
    scale: Vec<usize>,
    normal: Vec<Option<usize>>,
    extras: Vec<ExtraState>,
    pd_extras: Vec<Vec<usize>>,
    /// Per photodiode, the normal the tangent bases are taken about (its initial value).
    reference_normals: Vec<Vector3<f64>>,
    /// Per photodiode, the frame of its reference normal, computed once (the part of
    /// [`pdcal_attitude::tangent_basis_about`] that does not depend on the current normal).
    reference_frames: Vec<TangentFrame>,
    /// State index of the body-rate error `dw` (3 states, then the 3 of the residual
    /// dipole `dm`, last), with dynamics only.
    rate: Option<usize>,
    /// State index of the correlated albedo gain `g` ([`crate::filter::AlbedoGainNoise`]).
    albedo_gain: Option<usize>,
}

impl StateLayout {
    /// The layout for `model`'s photodiodes, with or without normal states, and one extra
    /// state per parameter of `model` marked estimated.
    pub fn new(model: &MeasurementModel, estimate_normals: bool) -> Self {
        let m = model.photodiodes().len();
        let per_pd = if estimate_normals { 3 } else { 1 };
        let scale = (0..m).map(|i| CORE + per_pd * i).collect();
        let normal = (0..m)
            .map(|i| estimate_normals.then_some(CORE + per_pd * i + 1))
            .collect();
        let mut next = CORE + per_pd * m;
        let mut extras = Vec::new();
        for (k, (_, p)) in model.parameters().enumerate() {
            if p.role == ParameterRole::Estimated {
                extras.push(ExtraState {
                    parameter: k,
                    state: next,
                    photodiode: p.photodiode,
                    name: p.name.clone(),
                    unit: p.unit.clone(),
                });
                next += 1;
            }
        }
        let pd_extras = (0..m)
            .map(|i| {
                extras
                    .iter()
                    .enumerate()
                    .filter(|(_, e)| e.photodiode.is_none_or(|j| j == i))
                    .map(|(k, _)| k)
                    .collect()
            })
            .collect();
        let reference_normals: Vec<Vector3<f64>> =
            model.photodiodes().iter().map(|p| p.n_body).collect();
        StateLayout {
            len: next,
            scale,
            normal,
            extras,
            pd_extras,
            reference_frames: reference_normals.iter().map(TangentFrame::about).collect(),
            reference_normals,
            rate: None,
            albedo_gain: None,
        }
    }

    /// Appends the albedo gain state `g` (albedo seen = `(1 + g)` times the modelled one)
    /// after every state so far, once; its index.
    pub fn add_albedo_gain(&mut self) -> usize {
        *self.albedo_gain.get_or_insert_with(|| {
            self.len += 1;
            self.len - 1
        })
    }

    /// State index of the albedo gain `g`, when it is a state.
    pub fn albedo_gain(&self) -> Option<usize> {
        self.albedo_gain
    }

    /// Appends the three body-rate states, the three residual-dipole states and the three
    /// moment corrections of the inertia of the dynamics-aided propagation
    /// ([`crate::rate`]) after every other state, once; the first index of the rate's.
    pub fn add_rate_states(&mut self) -> usize {
        *self.rate.get_or_insert_with(|| {
            self.len += 9;
            self.len - 9
        })
    }

    /// State index of the body-rate error `dw` (3 states), with dynamics only.
    pub fn rate(&self) -> Option<usize> {
        self.rate
    }

    /// State index of the residual-dipole error `dm` (3 states), with dynamics only.
    pub fn dipole(&self) -> Option<usize> {
        self.rate.map(|k| k + 3)
    }

    /// State index of the inertia's moment-correction error `dc` (3 states), with
    /// dynamics only.
    pub fn moment_fraction(&self) -> Option<usize> {
        self.rate.map(|k| k + 6)
    }

    /// Sets the normals the tangent bases are taken about (the filter's initial normals).
    pub fn set_reference_normals(&mut self, normals: &[Vector3<f64>]) {
        self.reference_normals = normals.to_vec();
        self.reference_frames = normals.iter().map(TangentFrame::about).collect();
    }

    /// The tangent basis in which photodiode `i`'s normal correction `(d1, d2)` and its
    /// covariance are expressed when the normal is `n`: smooth everywhere except at the
    /// antipode of the photodiode's initial normal
    /// ([`pdcal_attitude::tangent_basis_about`]). A fixed global basis would break on some
    /// mounting direction (the attitude crate's sits on the cube corner -(1,1,1)/sqrt(3),
    /// where the sso-6u scenario mounts a photodiode), scrambling that sensor's covariance.
    pub fn tangent_basis(&self, i: usize, n: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        match self.reference_frames.get(i) {
            Some(frame) => frame.basis_at(n),
            None => pdcal_attitude::tangent_basis(n),
        }
    }

    /// Number of states `n`.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Always false (there are at least the 6 attitude and bias states).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Number of photodiodes.
    pub fn photodiodes(&self) -> usize {
        self.scale.len()
    }

    /// State index of `C_i`.
    pub fn scale(&self, i: usize) -> usize {
        self.scale[i]
    }

    /// State index of `d1_i` (`d2_i` follows), if normals are estimated.
    pub fn normal(&self, i: usize) -> Option<usize> {
        self.normal[i]
    }

    /// The extra states.
    pub fn extras(&self) -> &[ExtraState] {
        &self.extras
    }

    /// Indices into [`StateLayout::extras`] of the states that can act on photodiode `i`.
    pub fn extras_of(&self, i: usize) -> &[usize] {
        &self.pd_extras[i]
    }

    /// Largest number of non-zeros in a photodiode's H row.
    pub fn max_row_len(&self) -> usize {
        CORE + self.pd_extras.iter().map(Vec::len).max().unwrap_or(0)
            + usize::from(self.albedo_gain.is_some())
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;
    use pdcal_photodiode::{MeasurementModel, Photodiode};

    use super::*;

    #[test]
    fn cached_bases_equal_the_attitude_crate_s() {
        // Reference normals over the sphere (including the cube corners where the global
        // basis breaks) and current normals tilted from them by up to 60 deg, and the
        // antipode (the half-turn branch): the same bits as `tangent_basis_about`.
        let mut refs: Vec<Vector3<f64>> = (0..40)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / 40.0;
                let r = (1.0 - z * z).sqrt();
                Vector3::new(r * (2.4 * i as f64).cos(), r * (2.4 * i as f64).sin(), z)
            })
            .collect();
        refs.push(Vector3::new(1.0, 1.0, 1.0) * 3.0);
        refs.push(-Vector3::new(1.0, 1.0, 1.0));
        let pds = refs
            .iter()
            .map(|n| Photodiode::new(1.0, *n, 0.0).expect("valid"))
            .collect();
        let layout = StateLayout::new(&MeasurementModel::paper(pds), true);
        for (i, r) in refs.iter().enumerate() {
            let r = r.normalize();
            let (t, _) = pdcal_attitude::tangent_basis(&r);
            let mut normals = vec![-r];
            for k in 0..12 {
                let angle = 1.05 * k as f64 / 11.0;
                let dir = t * (0.5 * k as f64).cos() + r.cross(&t) * (0.5 * k as f64).sin();
                normals.push(r * angle.cos() + dir * angle.sin());
            }
            for n in &normals {
                assert_eq!(
                    layout.tangent_basis(i, n),
                    pdcal_attitude::tangent_basis_about(n, &refs[i]),
                    "photodiode {i}"
                );
            }
        }
    }
}
