//! Synthetic datasets built in the test, without the simulator: a constant-rate tumble, a
//! fixed Sun, a slowly turning field, photodiode outputs from the cosine law (paper Eq. 15
//! without albedo) with seeded Gaussian noise.
#![allow(dead_code)]

use nalgebra::Vector3;
use pdcal_attitude::mekf::propagate;
use pdcal_attitude::{Quat, normal_from_az_el};
use pdcal_dataset::{DatasetMeta, Telemetry, meta_from_str};
use pdcal_ephem::Reference;
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal};

/// Table 1 of the paper: intended azimuth/elevation, deg.
pub const RAX2_NOMINAL: [(f64, f64); 17] = pdcal_attitude::RAX2_TABLE1_AZ_EL_DEG;

/// One synthetic case.
#[derive(Clone, Debug)]
pub struct Case {
    /// Nominal mounts (az, el) deg, as written to dataset.ron.
    pub nominal: Vec<(f64, f64)>,
    /// True normals.
    pub true_normals: Vec<Vector3<f64>>,
    /// True scales, V.
    pub true_scales: Vec<f64>,
    /// True dark offsets, V (added to every output).
    pub dark_offsets: Vec<f64>,
    /// Rows.
    pub steps: usize,
    /// Sample period, s.
    pub dt_s: f64,
    /// Body rate at t = 0, rad/s; the transverse part precesses about body z at
    /// `precession_rad_s` (torque-free axisymmetric body), zero for a constant rate.
    pub rate_rad_s: Vector3<f64>,
    /// Precession rate of the body rate about body z, rad/s.
    pub precession_rad_s: f64,
    /// True gyro bias, rad/s.
    pub bias_rad_s: Vector3<f64>,
    /// Noise sigmas.
    pub pd_sigma_v: f64,
    /// Magnetometer sigma, nT.
    pub mag_sigma_nt: f64,
    /// Gyro sigma per sample, rad/s.
    pub gyro_sigma_rad_s: f64,
    /// Rows in eclipse (sun_fraction 0), as a range.
    pub eclipse: std::ops::Range<usize>,
    /// Write magnetometer columns.
    pub with_mag: bool,
    /// Seed.
    pub seed: u64,
}

impl Case {
    /// RAX-2 layout, true normals tilted from nominal by a seeded error, scales 3.5-3.9 V.
    pub fn rax2(seed: u64, steps: usize) -> Self {
        let mut rng = StdRng::seed_from_u64(seed);
        let tilt = Normal::new(0.0, 5.0).unwrap();
        let nominal: Vec<(f64, f64)> = RAX2_NOMINAL.to_vec();
        let true_normals = nominal
            .iter()
            .map(|&(az, el)| {
                let n = normal_from_az_el(az.to_radians(), el.to_radians());
                let d1: f64 = tilt.sample(&mut rng);
                let d2: f64 = tilt.sample(&mut rng);
                pdcal_attitude::rotate_normal(&n, d1.to_radians(), d2.to_radians())
            })
            .collect();
        let true_scales = (0..nominal.len())
            .map(|i| 3.5 + 0.4 * ((i * 7 % 17) as f64) / 16.0)
            .collect();
        Case {
            dark_offsets: vec![0.0; nominal.len()],
            nominal,
            true_normals,
            true_scales,
            steps,
            dt_s: 1.0,
            rate_rad_s: Vector3::new(2.0, -3.0, 1.5).map(f64::to_radians),
            precession_rad_s: 1.5f64.to_radians(),
            bias_rad_s: Vector3::new(0.1, -0.2, 0.15).map(f64::to_radians),
            pd_sigma_v: 0.015,
            mag_sigma_nt: 320.0,
            gyro_sigma_rad_s: 0.05f64.to_radians(),
            eclipse: 0..0,
            with_mag: true,
            seed,
        }
    }

    /// The Sun direction (fixed), GCRF.
    pub fn sun_gcrf() -> Vector3<f64> {
        Vector3::new(0.8, 0.5, 0.33).normalize()
    }

    /// The field, GCRF, nT: turning once per 97-minute orbit in a plane tilted to the Sun.
    pub fn field_gcrf(t_s: f64) -> Vector3<f64> {
        let w = 2.0 * std::f64::consts::PI / 5820.0;
        let (s, c) = (w * t_s).sin_cos();
        Vector3::new(c, 0.3 * s, 0.9 * s) * 30_000.0
    }

    /// Body rate at time t.
    pub fn rate_at(&self, t_s: f64) -> Vector3<f64> {
        let (s, c) = (self.precession_rad_s * t_s).sin_cos();
        let w = self.rate_rad_s;
        Vector3::new(c * w.x - s * w.y, s * w.x + c * w.y, w.z)
    }

    /// True attitudes at every row: 20 midpoint substeps per sample.
    pub fn true_attitudes(&self) -> Vec<Quat> {
        const SUB: usize = 20;
        let mut q = Quat::new_normalized(0.1, -0.3, 0.2, 0.9).unwrap();
        let h = self.dt_s / SUB as f64;
        let mut out = Vec::with_capacity(self.steps);
        for k in 0..self.steps {
            out.push(q);
            for j in 0..SUB {
                let t = k as f64 * self.dt_s + (j as f64 + 0.5) * h;
                q = propagate(&q, &self.rate_at(t), h);
            }
        }
        out
    }

    /// Builds (meta, telemetry, references, true attitudes).
    pub fn build(&self) -> (DatasetMeta, Telemetry, Vec<Reference>, Vec<Quat>) {
        let mut rng = StdRng::seed_from_u64(self.seed.wrapping_mul(7919).wrapping_add(1));
        let std = Normal::new(0.0, 1.0).unwrap();
        let m = self.nominal.len();
        let mut tel = Telemetry {
            mag_nt: self.with_mag.then(Default::default),
            pd_v: vec![pdcal_dataset::Samples::with_capacity(self.steps); m],
            ..Telemetry::default()
        };
        let mut refs = Vec::with_capacity(self.steps);
        let mut truth = Vec::with_capacity(self.steps);
        let sun = Self::sun_gcrf();
        let attitudes = self.true_attitudes();
        for (k, &q) in attitudes.iter().enumerate() {
            let t = k as f64 * self.dt_s;
            let a = q.attitude_matrix();
            let b = Self::field_gcrf(t);
            let lit = !self.eclipse.contains(&k);
            let mut noise3 = || {
                Vector3::new(
                    std.sample(&mut rng),
                    std.sample(&mut rng),
                    std.sample(&mut rng),
                )
            };
            tel.t_s.push(t);
            tel.gyro_rad_s.push(Some(
                self.rate_at(t) + self.bias_rad_s + noise3() * self.gyro_sigma_rad_s,
            ));
            if let Some(mag) = tel.mag_nt.as_mut() {
                mag.push(Some(a * b + noise3() * self.mag_sigma_nt));
            }
            let reference = Reference {
                r_gcrf_km: Vector3::new(7000.0, 0.0, 0.0),
                sun_gcrf_km: sun * 1.496e8,
                sun_gcrf_unit: sun,
                b_gcrf_nt: b,
                sun_fraction: if lit { 1.0 } else { 0.0 },
                gcrf_to_itrf: nalgebra::Matrix3::identity(),
            };
            // The true scales are at 1 AU, as the filter's.
            let flux = reference.sun_distance_factor();
            refs.push(reference);
            let s_body = a * sun;
            for i in 0..m {
                let cos = self.true_normals[i].dot(&s_body);
                let direct = if lit && cos > 0.0 {
                    flux * self.true_scales[i] * cos
                } else {
                    0.0
                };
                let y = direct + self.dark_offsets[i] + self.pd_sigma_v * std.sample(&mut rng);
                tel.pd_v[i].push(Some(y));
            }
            truth.push(q);
        }
        (self.meta(), tel, refs, truth)
    }

    /// dataset.ron for this case, through the dataset crate's reader.
    pub fn meta(&self) -> DatasetMeta {
        let pds: Vec<String> = self
            .nominal
            .iter()
            .map(|(az, el)| format!("(azimuth_deg: {az:?}, elevation_deg: {el:?})"))
            .collect();
        let hint = |name: &str, v: f64| {
            if v > 0.0 {
                format!("{name}: {v:?}, ")
            } else {
                String::new()
            }
        };
        let text = format!(
            "(format_version: 1, name: \"synthetic\", epoch_utc: \"2011-11-04T18:29:45Z\",
              orbit: Tle(
                line1: \"1 37853U 11061D   11308.77065972  .00000000  00000-0  20000-4 0  9997\",
                line2: \"2 37853 101.7000  50.0000 0300509 130.0000 230.0000 14.86144463  1000\"),
              photodiodes: [{}],
              noise: ({}{}{}))",
            pds.join(", "),
            hint("gyro_rad_s", self.gyro_sigma_rad_s),
            hint("mag_nT", self.mag_sigma_nt),
            hint("photodiode_V", self.pd_sigma_v),
        );
        meta_from_str(&text).expect("synthetic dataset.ron parses")
    }
}

/// Angle between two unit vectors, deg.
pub fn angle_deg(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    a.normalize()
        .cross(&b.normalize())
        .norm()
        .atan2(a.dot(b))
        .to_degrees()
}
