//! The core against its model: exact recovery without noise, the albedo against
//! `pdcal-albedo`'s cell model, f32 against f64, and totality on hostile inputs.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use nalgebra::{Matrix3, Vector3};
use pdcal_albedo::{AlbedoIrradiance, AlbedoModel, AlbedoView, MapChoice};
use pdcal_attitude::{RAX2_TABLE1_AZ_EL_DEG, normal_from_az_el};
use pdcal_onboard::{
    AlbedoUse, Calibration, EARTH_RADIUS_KM, EarthInput, MAX_PHOTODIODES, Options, Photodiode,
    ReflectivityGrid, Validity, albedo_ratios, estimate_sun,
};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal, UnitSphere};

const SCALE_V: f64 = 3.7;
const NOISE_V: f64 = 0.015;

fn normal(az_deg: f64, el_deg: f64) -> [f64; 3] {
    normal_from_az_el(az_deg.to_radians(), el_deg.to_radians()).into()
}

fn rax2() -> Calibration<f64, 17> {
    Calibration {
        count: 17,
        photodiodes: RAX2_TABLE1_AZ_EL_DEG
            .map(|(az, el)| Photodiode::cosine(SCALE_V, normal(az, el), NOISE_V)),
    }
}

fn to_f32(cal: &Calibration<f64, 17>) -> Calibration<f32, 17> {
    Calibration {
        count: cal.count,
        photodiodes: cal.photodiodes.map(|p| Photodiode {
            scale_v: p.scale_v as f32,
            normal_body: p.normal_body.map(|x| x as f32),
            dark_v: p.dark_v as f32,
            fov_half_angle_rad: p.fov_half_angle_rad as f32,
            noise_v: p.noise_v as f32,
            scale_sigma_v: p.scale_sigma_v as f32,
            normal_sigma_rad: p.normal_sigma_rad as f32,
            enabled: p.enabled,
        }),
    }
}

fn unit(rng: &mut StdRng) -> [f64; 3] {
    UnitSphere.sample(rng)
}

fn angle_deg(a: [f64; 3], b: [f64; 3]) -> f64 {
    // atan2 of the cross and dot products: acos loses half the digits near 0.
    let (a, b) = (Vector3::from(a), Vector3::from(b));
    a.cross(&b).norm().atan2(a.dot(&b)).to_degrees()
}

/// The outputs of the cosine model with albedo `albedo[i]` and Gaussian noise of `noise_v`.
fn outputs(
    cal: &Calibration<f64, 17>,
    sun: [f64; 3],
    albedo: &[f64; 17],
    noise_v: f64,
    rng: &mut StdRng,
) -> [f64; 17] {
    let noise = Normal::new(0.0, noise_v.max(1e-300)).unwrap();
    let mut out = [0.0; 17];
    for ((o, pd), e) in out.iter_mut().zip(&cal.photodiodes).zip(albedo) {
        let n = Vector3::from(pd.normal_body);
        let direct = n.dot(&Vector3::from(sun)).max(0.0);
        let jitter = if noise_v > 0.0 {
            noise.sample(rng)
        } else {
            0.0
        };
        *o = pd.scale_v * (direct + e) + jitter;
    }
    out
}

#[test]
fn without_noise_or_albedo_the_sun_is_recovered_exactly() {
    let cal = rax2();
    let mut rng = StdRng::seed_from_u64(1);
    let mut valid = 0;
    for _ in 0..500 {
        let sun = unit(&mut rng);
        let y = outputs(&cal, sun, &[0.0; 17], 0.0, &mut rng);
        let options = Options {
            albedo_bound: 0.0,
            ..Options::default()
        };
        let e = estimate_sun(&y, &cal, None, &options);
        if e.validity == Validity::Valid {
            valid += 1;
            assert!(
                angle_deg(e.sun_body, sun) < 1e-9,
                "{:?} vs {sun:?}",
                e.sun_body
            );
            assert!((e.magnitude - 1.0).abs() < 1e-9);
        } else {
            assert!(matches!(
                e.validity,
                Validity::TooFewLit | Validity::DegenerateGeometry
            ));
        }
    }
    // RAX-2's head sees most directions with three or more non-coplanar photodiodes.
    assert!(valid > 400, "{valid} of 500 valid");
}

#[test]
fn the_cone_describes_the_errors_of_noisy_outputs() {
    let cal = rax2();
    let mut rng = StdRng::seed_from_u64(2);
    let (mut sum_z2, mut n) = (0.0, 0);
    for _ in 0..2000 {
        let sun = unit(&mut rng);
        let y = outputs(&cal, sun, &[0.0; 17], NOISE_V, &mut rng);
        let options = Options {
            albedo_bound: 0.0,
            ..Options::default()
        };
        let e = estimate_sun(&y, &cal, None, &options);
        if e.validity != Validity::Valid {
            continue;
        }
        let err = angle_deg(e.sun_body, sun).to_radians();
        // Two tangent axes: the squared error over the cone's variance averages 1.
        sum_z2 += err * err / (e.cone_sigma_rad * e.cone_sigma_rad);
        n += 1;
    }
    let mean = sum_z2 / n as f64;
    assert!(
        n > 1500 && (0.8..1.25).contains(&mean),
        "mean normalised error^2 {mean} over {n}"
    );
}

/// A 5-deg TOMS grid in bytes, as an export would hold it.
fn toms_bytes(k_lat: usize, k_lon: usize) -> (usize, usize, Vec<u8>, AlbedoModel) {
    let map = MapChoice::TomsMean1p25x1
        .load()
        .unwrap()
        .coarsen(k_lat, k_lon)
        .unwrap();
    let bytes = map
        .values()
        .iter()
        .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
        .collect();
    (map.n_lat(), map.n_lon(), bytes, AlbedoModel::new(&map))
}

#[test]
fn the_grid_albedo_matches_pdcal_albedo_cell_model() {
    let (n_lat, n_lon, bytes, model) = toms_bytes(1, 1);
    let grid = ReflectivityGrid::new(n_lat, n_lon, &bytes).unwrap();
    let mut rng = StdRng::seed_from_u64(3);
    let mut view = AlbedoView::new();
    let identity = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let mut largest = 0.0f64;
    for _ in 0..200 {
        let up = Vector3::from(unit(&mut rng));
        let radius = EARTH_RADIUS_KM + rng.random_range(400.0..900.0);
        let sun = Vector3::from(unit(&mut rng));
        // Sun at 1 AU, so that the reference's distance factor is 1.
        model
            .compute_into(
                &mut view,
                &(up * radius),
                &(sun * 1.495_978_707e8),
                &Matrix3::identity(),
            )
            .unwrap();
        let normals: Vec<[f64; 3]> = (0..8).map(|_| unit(&mut rng)).collect();
        let earth = EarthInput {
            earth_body: (-up).into(),
            orbit_radius_km: radius,
            ecef_from_body: Some(identity),
            grid: Some(&grid),
        };
        let mut ours = [0.0; 8];
        albedo_ratios(sun.into(), &earth, 0.3, &normals, &mut ours);
        for (n, e) in normals.iter().zip(ours) {
            let reference = view.ratio(&Vector3::from(*n), 0.0);
            largest = largest.max(reference);
            // Spherical against authalic cell areas and bytes against floats: 1.5 %.
            assert!(
                (e - reference).abs() <= 0.015 * reference + 1e-5,
                "{e} vs {reference}"
            );
        }
    }
    assert!(
        largest > 0.1,
        "the geometries reached albedo of {largest} only"
    );
}

fn earth_for(up: [f64; 3], radius: f64) -> EarthInput<'static, f64> {
    EarthInput {
        earth_body: up.map(|x| -x),
        orbit_radius_km: radius,
        ecef_from_body: None,
        grid: None,
    }
}

#[test]
fn albedo_compensation_removes_the_bias_of_an_earth_facing_head() {
    let cal = rax2();
    let mut rng = StdRng::seed_from_u64(4);
    let normals = cal.photodiodes.map(|p| p.normal_body);
    let (mut with, mut without, mut n) = (0.0, 0.0, 0);
    for _ in 0..300 {
        let sun = unit(&mut rng);
        // The Earth within 100 deg of the Sun's opposite: a lit Earth below.
        let up = unit(&mut rng);
        if Vector3::from(up).dot(&Vector3::from(sun)) < 0.2 {
            continue;
        }
        let earth = earth_for(up, EARTH_RADIUS_KM + 500.0);
        let mut albedo = [0.0; 17];
        albedo_ratios(sun, &earth, 0.3, &normals, &mut albedo);
        let y = outputs(&cal, sun, &albedo, NOISE_V, &mut rng);
        let compensated = estimate_sun(&y, &cal, Some(&earth), &Options::default());
        let plain = Options {
            albedo_bound: 0.0,
            ..Options::default()
        };
        let raw = estimate_sun(&y, &cal, None, &plain);
        if compensated.validity != Validity::Valid || raw.validity == Validity::InvalidInput {
            continue;
        }
        assert_eq!(compensated.albedo, AlbedoUse::Uniform);
        with += angle_deg(compensated.sun_body, sun);
        without += angle_deg(raw.sun_body, sun);
        n += 1;
    }
    let (with, without) = (with / n as f64, without / n as f64);
    assert!(n > 100, "{n} valid");
    assert!(
        with < 0.3 && without > 3.0 * with,
        "mean error {with} deg compensated, {without} deg not"
    );
}

#[test]
fn f32_stays_within_a_hundredth_of_a_degree_of_f64() {
    let cal = rax2();
    let cal32 = to_f32(&cal);
    let (n_lat, n_lon, bytes, _) = toms_bytes(5, 4);
    let grid = ReflectivityGrid::new(n_lat, n_lon, &bytes).unwrap();
    let mut rng = StdRng::seed_from_u64(5);
    let normals = cal.photodiodes.map(|p| p.normal_body);
    let mut worst = 0.0f64;
    let mut compared = 0;
    for _ in 0..300 {
        let sun = unit(&mut rng);
        let up = unit(&mut rng);
        let rotation = nalgebra::Rotation3::from_scaled_axis(Vector3::from(unit(&mut rng)) * 2.0);
        let m: [[f64; 3]; 3] = rotation.matrix().transpose().into();
        let earth = EarthInput {
            earth_body: rotation
                .inverse_transform_vector(&Vector3::from(up))
                .map(|x| -x)
                .into(),
            orbit_radius_km: EARTH_RADIUS_KM + 600.0,
            ecef_from_body: Some(m),
            grid: Some(&grid),
        };
        let mut albedo = [0.0; 17];
        albedo_ratios(sun, &earth, 0.3, &normals, &mut albedo);
        let y = outputs(&cal, sun, &albedo, NOISE_V, &mut rng);
        let e64 = estimate_sun(&y, &cal, Some(&earth), &Options::default());
        let earth32 = EarthInput {
            earth_body: earth.earth_body.map(|x| x as f32),
            orbit_radius_km: earth.orbit_radius_km as f32,
            ecef_from_body: Some(m.map(|r| r.map(|x| x as f32))),
            grid: Some(&grid),
        };
        let e32 = estimate_sun(
            &y.map(|x| x as f32),
            &cal32,
            Some(&earth32),
            &Options::default(),
        );
        assert_eq!(e64.albedo, AlbedoUse::Grid);
        if e64.validity == Validity::Valid && e32.validity == Validity::Valid {
            worst = worst.max(angle_deg(e64.sun_body, e32.sun_body.map(f64::from)));
            compared += 1;
        }
    }
    assert!(
        compared > 150 && worst < 0.01,
        "worst {worst} deg over {compared}"
    );
}

#[test]
fn eclipse_too_few_and_coplanar_are_flagged() {
    let cal = rax2();
    let options = Options::default();
    assert_eq!(
        estimate_sun(&[0.0; 17], &cal, None, &options).validity,
        Validity::Eclipse
    );
    let mut one = [0.0; 17];
    one[12] = SCALE_V;
    assert_eq!(
        estimate_sun(&one, &cal, None, &options).validity,
        Validity::TooFewLit
    );
    // Three photodiodes with one normal: lit, but the direction is not determined.
    let mut same = Calibration {
        count: 3,
        photodiodes: [Photodiode::cosine(1.0, [0.0, 0.0, 1.0], 0.01); 3],
    };
    same.photodiodes[1].normal_body = [0.0, 1e-4, 1.0];
    let e = estimate_sun(&[1.0; 3], &same, None, &options);
    assert_eq!(e.validity, Validity::DegenerateGeometry);
}

#[test]
fn contradicting_outputs_are_flagged() {
    let cal = rax2();
    let mut rng = StdRng::seed_from_u64(6);
    let mut flagged = 0;
    let mut trials = 0;
    for _ in 0..200 {
        let sun = unit(&mut rng);
        let mut y = outputs(&cal, sun, &[0.0; 17], NOISE_V, &mut rng);
        let options = Options {
            albedo_bound: 0.0,
            ..Options::default()
        };
        if estimate_sun(&y, &cal, None, &options).n_used < 5 {
            continue;
        }
        // The brightest channel doubled (a wrong gain): far beyond the noise.
        let k = (0..17).max_by(|&a, &b| y[a].total_cmp(&y[b])).unwrap();
        y[k] *= 2.0;
        trials += 1;
        if estimate_sun(&y, &cal, None, &options).validity == Validity::Contradictory {
            flagged += 1;
        }
    }
    assert!(
        trials > 50 && flagged as f64 > 0.9 * trials as f64,
        "{flagged} of {trials}"
    );
}

/// Values a hostile caller can pass.
fn hostile(rng: &mut StdRng) -> f64 {
    match rng.random_range(0..9) {
        0 => f64::NAN,
        1 => f64::INFINITY,
        2 => f64::NEG_INFINITY,
        3 => 0.0,
        4 => 1e308,
        5 => -1e308,
        6 => f64::MIN_POSITIVE,
        7 => rng.random_range(-1.0..1.0),
        _ => rng.random_range(-10.0..10.0),
    }
}

#[test]
fn any_input_gives_an_estimate_or_a_flag() {
    let mut rng = StdRng::seed_from_u64(7);
    let bytes = [200u8; 18 * 36];
    let grid = ReflectivityGrid::new(18, 36, &bytes).unwrap();
    for _ in 0..20_000 {
        let mut cal = rax2();
        cal.count = rng.random_range(0..20);
        for pd in cal.photodiodes.iter_mut() {
            if rng.random_bool(0.3) {
                pd.scale_v = hostile(&mut rng);
                pd.normal_body = [hostile(&mut rng), hostile(&mut rng), hostile(&mut rng)];
                pd.dark_v = hostile(&mut rng);
                pd.fov_half_angle_rad = hostile(&mut rng);
                pd.noise_v = hostile(&mut rng);
                pd.scale_sigma_v = hostile(&mut rng);
                pd.normal_sigma_rad = hostile(&mut rng);
            }
        }
        let y: [f64; 17] = core::array::from_fn(|_| hostile(&mut rng));
        let m = [
            [hostile(&mut rng), 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let earth = EarthInput {
            earth_body: [hostile(&mut rng), hostile(&mut rng), hostile(&mut rng)],
            orbit_radius_km: hostile(&mut rng) * 1e4,
            ecef_from_body: rng.random_bool(0.5).then_some(m),
            grid: rng.random_bool(0.5).then_some(&grid),
        };
        let mut options = Options::default();
        if rng.random_bool(0.2) {
            options.lit_sigmas = hostile(&mut rng);
            options.sun_distance_factor = hostile(&mut rng);
            options.albedo_passes = rng.random_range(0..40);
        }
        let e = estimate_sun(&y, &cal, rng.random_bool(0.5).then_some(&earth), &options);
        if e.validity == Validity::Valid {
            let n = Vector3::from(e.sun_body).norm();
            assert!(
                (n - 1.0).abs() < 1e-9 && e.cone_sigma_rad.is_finite(),
                "{e:?}"
            );
        }
    }
}

#[test]
fn a_count_beyond_the_buffer_or_the_maximum_is_invalid_input() {
    let mut cal = rax2();
    cal.count = 18;
    let options = Options::default();
    assert_eq!(
        estimate_sun(&[1.0; 17], &cal, None, &options).validity,
        Validity::InvalidInput
    );
    let big = Calibration {
        count: MAX_PHOTODIODES + 1,
        photodiodes: [Photodiode::cosine(1.0, [0.0, 0.0, 1.0], 0.01); MAX_PHOTODIODES + 1],
    };
    let y = [1.0; MAX_PHOTODIODES + 1];
    assert_eq!(
        estimate_sun(&y, &big, None, &options).validity,
        Validity::InvalidInput
    );
}

#[test]
fn grid_dimensions_must_match_the_cells() {
    assert!(ReflectivityGrid::new(2, 3, &[0; 6]).is_some());
    assert!(ReflectivityGrid::new(2, 3, &[0; 5]).is_none());
    assert!(ReflectivityGrid::new(0, 3, &[]).is_none());
    assert!(ReflectivityGrid::new(usize::MAX, 2, &[0; 4]).is_none());
}
