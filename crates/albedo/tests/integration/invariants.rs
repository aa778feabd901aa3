//! Invariants: night side, normals away from Earth, culled == unculled == naive, no growth
//! of the buffers after warm-up, the gradient of the ratio, typed errors on bad input.

use crate::common;

use std::f64::consts::PI;

use common::random_unit;

use nalgebra::{Matrix3, Rotation3, Vector3};
use pdcal_albedo::{
    AU_KM, AlbedoError, AlbedoIrradiance, AlbedoModel, AlbedoView, LinearAlbedo, MapChoice,
    TILE_COLS, authalic_radius_km,
};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

fn toms() -> AlbedoModel {
    AlbedoModel::from_choice(&MapChoice::TomsMean1p25x1).unwrap()
}

fn random_rotation(rng: &mut StdRng) -> Matrix3<f64> {
    let axis = random_unit(rng);
    Rotation3::new(axis * rng.random::<f64>() * PI).into_inner()
}

/// A random geometry: satellite 200 km .. 36000 km altitude, including positions over the
/// poles and the dateline, Sun at ~1 AU in a random direction, random Earth rotation.
fn random_geometry(rng: &mut StdRng, k: usize) -> (Vector3<f64>, Vector3<f64>, Matrix3<f64>) {
    let rot = random_rotation(rng);
    let alt = match k % 4 {
        0 => 200.0,
        1 => 600.0 + 400.0 * rng.random::<f64>(),
        2 => 2000.0,
        _ => 35786.0,
    };
    // Some sub-satellite points exactly over a pole or on the dateline (ECEF).
    let dir_ecef = match k % 7 {
        0 => Vector3::z(),
        1 => -Vector3::x(),
        _ => random_unit(rng),
    };
    let r_sat_gcrf = rot.transpose() * dir_ecef * (authalic_radius_km() + alt);
    // Sun within 80 deg of the satellite direction so that lit cells are in view.
    let sun = (dir_ecef + 0.8 * random_unit(rng)).normalize();
    let r_sun_gcrf = rot.transpose() * sun * AU_KM * (0.98 + 0.04 * rng.random::<f64>());
    (r_sat_gcrf, r_sun_gcrf, rot)
}

#[test]
fn fast_equals_unculled_and_naive() {
    let model = toms();
    let mut rng = StdRng::seed_from_u64(13);
    let (mut fast, mut all) = (AlbedoView::new(), AlbedoView::new());
    let mut worst = 0.0f64;
    for k in 0..28 {
        let (r_sat, r_sun, rot) = random_geometry(&mut rng, k);
        model.compute_into(&mut fast, &r_sat, &r_sun, &rot).unwrap();
        model
            .compute_into_unculled(&mut all, &r_sat, &r_sun, &rot)
            .unwrap();
        // The culling drops only cells the exact test would reject.
        assert_eq!(fast.len(), all.len(), "geometry {k}");
        assert!(!fast.is_empty(), "geometry {k} should see lit cells");
        let normals: Vec<Vector3<f64>> = (0..6).map(|_| random_unit(&mut rng)).collect();
        let mut normals = normals;
        normals.push(fast.nadir_gcrf());
        let cos_fov: Vec<f64> = (0..normals.len())
            .map(|m| [1e-17, 0.5, 0.2][m % 3])
            .collect();
        let mut out = vec![0.0; normals.len()];
        fast.ratios(&normals, &cos_fov, &mut out);
        let mut naive = vec![(0.0, Vector3::zeros()); normals.len()];
        model
            .naive_ratios(&r_sat, &r_sun, &rot, &normals, &cos_fov, &mut naive)
            .unwrap();
        for m in 0..normals.len() {
            let (want, want_vec) = naive[m];
            let (got, got_vec) = fast.ratio_and_vector(&normals[m], cos_fov[m]);
            // Same cells and terms; only the summation order differs: 1e-12 relative
            // (absolute floor 1e-16 for zero results).
            let scale = want.abs().max(1e-16 / 1e-12);
            for value in [out[m], got, all.ratio(&normals[m], cos_fov[m])] {
                let rel = (value - want).abs() / scale;
                worst = worst.max(rel);
                assert!(
                    rel < 1e-12,
                    "geometry {k} normal {m}: {value:e} vs {want:e}"
                );
            }
            assert!((got_vec - want_vec).norm() <= 1e-12 * want_vec.norm().max(1e-4));
        }
    }
    eprintln!("worst fast-vs-naive relative difference: {worst:e}");
}

#[test]
fn padded_rows_equal_naive() {
    // TOMS in 2 x 10 deg blocks: 36 columns, not a multiple of TILE_COLS, so the fast loop
    // pads each row (to 40) and must skip the padding; a non-uniform map catches any column
    // shift. Same 1e-12 relative tolerance as above.
    let map = MapChoice::TomsMean1p25x1
        .load()
        .unwrap()
        .coarsen(2, 8)
        .unwrap();
    assert_ne!(map.n_lon() % TILE_COLS, 0);
    let model = AlbedoModel::new(&map);
    let mut rng = StdRng::seed_from_u64(17);
    let (mut fast, mut all) = (AlbedoView::new(), AlbedoView::new());
    for k in 0..14 {
        let (r_sat, r_sun, rot) = random_geometry(&mut rng, k);
        model.compute_into(&mut fast, &r_sat, &r_sun, &rot).unwrap();
        model
            .compute_into_unculled(&mut all, &r_sat, &r_sun, &rot)
            .unwrap();
        assert_eq!(fast.len(), all.len(), "geometry {k}");
        // Padding never counts: at most every real cell is lit and seen.
        assert!(fast.len() <= model.n_cells());
        let mut normals: Vec<Vector3<f64>> = (0..5).map(|_| random_unit(&mut rng)).collect();
        normals.push(fast.nadir_gcrf());
        let cos_fov = vec![0.3; normals.len()];
        let mut naive = vec![(0.0, Vector3::zeros()); normals.len()];
        model
            .naive_ratios(&r_sat, &r_sun, &rot, &normals, &cos_fov, &mut naive)
            .unwrap();
        for (m, n) in normals.iter().enumerate() {
            let want = naive[m].0;
            let scale = want.abs().max(1e-16 / 1e-12);
            for got in [fast.ratio(n, cos_fov[m]), all.ratio(n, cos_fov[m])] {
                assert!(
                    (got - want).abs() / scale < 1e-12,
                    "geometry {k} normal {m}: {got:e} vs {want:e}"
                );
            }
        }
    }
}

#[test]
fn zero_on_the_night_side() {
    let model = toms();
    let mut view = AlbedoView::new();
    let mut rng = StdRng::seed_from_u64(5);
    for _ in 0..10 {
        let rot = random_rotation(&mut rng);
        let sun = random_unit(&mut rng);
        // Satellite over the anti-solar point at 600 km: its visible cap (24 deg) is dark.
        let r_sat = -sun * (authalic_radius_km() + 600.0);
        model
            .compute_into(&mut view, &r_sat, &(sun * AU_KM), &rot)
            .unwrap();
        assert!(view.is_empty());
        assert_eq!(view.max_ratio(), 0.0);
        assert_eq!(view.ratio(&view.nadir_gcrf(), 0.0), 0.0);
    }
}

#[test]
fn zero_for_normals_facing_away_from_earth() {
    let model = toms();
    let mut view = AlbedoView::new();
    let sun = Vector3::new(0.3, -0.5, 0.8).normalize();
    let r_sat = sun * (authalic_radius_km() + 600.0);
    model
        .compute_into(&mut view, &r_sat, &(sun * AU_KM), &Matrix3::identity())
        .unwrap();
    assert!(view.len() > 1000);
    // Zenith, and a normal 160 deg from nadir (beyond 90 deg + rho = 156 deg).
    let zenith = -view.nadir_gcrf();
    let side = zenith.cross(&Vector3::x()).normalize();
    let tilted = Rotation3::new(side * 20f64.to_radians()) * zenith;
    for n in [zenith, tilted] {
        assert_eq!(view.ratio(&n, 0.0), 0.0);
        assert_eq!(view.ratio_and_vector(&n, 0.0).1, Vector3::zeros());
    }
    // The unculled loop agrees that no cell faces such a normal.
    let mut out = [(1.0, Vector3::zeros()); 2];
    model
        .naive_ratios(
            &r_sat,
            &(sun * AU_KM),
            &Matrix3::identity(),
            &[zenith, tilted],
            &[0.0, 0.0],
            &mut out,
        )
        .unwrap();
    assert_eq!(out[0].0 + out[1].0, 0.0);
}

#[test]
fn vector_is_the_gradient_of_the_ratio() {
    // With fov 90 deg the ratio is continuous and piecewise linear in n, so central
    // differences with h = 1e-6 match sum c u except when a cell centre lies within 1e-6 rad
    // of the horizon of n (contributing < c * 1e-6): tolerance 1e-6 relative to |sum c u|.
    let model = toms();
    let mut view = AlbedoView::new();
    let mut rng = StdRng::seed_from_u64(21);
    let h = 1e-6;
    for k in 0..100 {
        let (r_sat, r_sun, rot) = random_geometry(&mut rng, 1 + 4 * (k % 2));
        model.compute_into(&mut view, &r_sat, &r_sun, &rot).unwrap();
        let n = random_unit(&mut rng);
        let (_, grad) = view.ratio_and_vector(&n, 0.0);
        for axis in 0..3 {
            let e = Vector3::ith(axis, h);
            let fd = (view.ratio(&(n + e), 0.0) - view.ratio(&(n - e), 0.0)) / (2.0 * h);
            let tol = 1e-6 * view.sum_cu().norm().max(1e-12);
            assert!(
                (fd - grad[axis]).abs() <= tol,
                "state {k} axis {axis}: {fd} vs {}",
                grad[axis]
            );
        }
    }
}

#[test]
fn buffers_stop_growing_after_warm_up() {
    let model = toms();
    let mut view = AlbedoView::new();
    let mut rng = StdRng::seed_from_u64(8);
    let steps: Vec<_> = (0..12).map(|k| random_geometry(&mut rng, k)).collect();
    for (r_sat, r_sun, rot) in &steps {
        model.compute_into(&mut view, r_sat, r_sun, rot).unwrap();
    }
    let capacity = view.capacity();
    for (r_sat, r_sun, rot) in &steps {
        model.compute_into(&mut view, r_sat, r_sun, rot).unwrap();
        assert_eq!(view.capacity(), capacity);
    }
}

#[test]
fn bad_inputs_are_typed_errors() {
    let model = AlbedoModel::from_choice(&MapChoice::Ceres5x5).unwrap();
    let mut view = AlbedoView::new();
    let r_sat = Vector3::new(7000.0, 0.0, 0.0);
    let r_sun = Vector3::new(AU_KM, 0.0, 0.0);
    let id = Matrix3::identity();
    let nan = Vector3::new(f64::NAN, 0.0, 0.0);
    assert_eq!(
        model.compute_into(&mut view, &nan, &r_sun, &id),
        Err(AlbedoError::NonFinite {
            what: "r_sat_gcrf_km"
        })
    );
    assert_eq!(
        model.compute_into(&mut view, &r_sat, &Vector3::zeros(), &id),
        Err(AlbedoError::ZeroSun)
    );
    assert!(matches!(
        model.compute_into(&mut view, &r_sat, &r_sun, &(id * 2.0)),
        Err(AlbedoError::NotRotation { .. })
    ));
    // Below the surface: nothing in view, not an error.
    model
        .compute_into(&mut view, &(r_sat * 0.5), &r_sun, &id)
        .unwrap();
    assert!(view.is_empty());
}

/// A [`LinearAlbedo`] about `n0` reproduces the full model there, and follows it closely
/// while the normal turns by the small corrections of a filter step. Measured (seed 5,
/// 400 normals, gate at 90 deg): worst 5.7e-6 of the full-disc sum at 1e-3 rad and 3.8e-7
/// at 1e-4 rad. Between first and second order: cells crossing the gate each change the sum
/// by at most `c |n.u|` (first order, small weights), the curvature where the gate cuts the
/// disc adds the second-order part. In volts, 5.7e-6 of a 0.3 disc sum times C = 3.7 V is
/// 6e-6 V, 4e-4 of the photodiode noise. Bounds: 3x the measured values.
#[test]
fn linearised_albedo_follows_the_full_model() {
    let model = toms();
    let mut rng = StdRng::seed_from_u64(5);
    let mut view = AlbedoView::new();
    let (mut worst_3, mut worst_4) = (0.0f64, 0.0f64);
    for _ in 0..20 {
        let sun = random_unit(&mut rng);
        let sat = (sun + 0.9 * random_unit(&mut rng)).normalize();
        let r_sat = sat * (authalic_radius_km() + 600.0);
        model
            .compute_into(&mut view, &r_sat, &(sun * AU_KM), &Matrix3::identity())
            .unwrap();
        let scale = view.max_ratio();
        if scale < 0.02 {
            continue;
        }
        for _ in 0..20 {
            let n0 = random_unit(&mut rng);
            let (ratio0, vector_gcrf) = view.ratio_and_vector(&n0, 0.0);
            let linear = LinearAlbedo {
                n0_gcrf: n0,
                ratio0,
                vector_gcrf,
            };
            assert_eq!(linear.ratio_and_vector(&n0, 0.0), (ratio0, vector_gcrf));
            let axis = random_unit(&mut rng);
            for (angle, worst) in [(1e-3, &mut worst_3), (1e-4, &mut worst_4)] {
                let n = Rotation3::new(axis * angle) * n0;
                let error = (linear.ratio(&n, 0.0) - view.ratio(&n, 0.0)).abs() / scale;
                *worst = worst.max(error);
            }
        }
    }
    eprintln!("linearised albedo: worst {worst_3:e} at 1e-3 rad, {worst_4:e} at 1e-4 rad");
    assert!(worst_3 < 2e-5, "1e-3 rad: {worst_3:e}");
    assert!(worst_4 < 1.2e-6, "1e-4 rad: {worst_4:e}");
}

/// A latitude-corrected model equals the model of the map with each row's reflectivity
/// multiplied by the factor at the row's latitude.
#[test]
fn latitude_factor_equals_the_rescaled_map() {
    use pdcal_albedo::ReflectivityMap;
    let (n_lat, n_lon) = (36, 72);
    let base_value = |i: usize, j: usize| 0.1 + 0.004 * i as f64 + 0.001 * (j % 7) as f64;
    let csv = |f: &dyn Fn(usize, usize) -> f64| -> String {
        (0..n_lat)
            .map(|i| {
                (0..n_lon)
                    .map(|j| format!("{}", f(i, j)))
                    .collect::<Vec<_>>()
                    .join(",")
            })
            .collect::<Vec<_>>()
            .join("\n")
    };
    let base_map = ReflectivityMap::parse_ceres_csv("base", &csv(&base_value)).unwrap();
    let base = AlbedoModel::new(&base_map);
    let factor = |lat: f64| 1.0 + 0.4 * lat.sin() - 0.2 * lat.cos();
    let lat_of = |i: usize| base.cell_centre_rad(i, 0).unwrap().0;
    let scaled_map = ReflectivityMap::parse_ceres_csv(
        "scaled",
        &csv(&|i, j| base_value(i, j) * factor(lat_of(i))),
    )
    .unwrap();
    let expected = AlbedoModel::new(&scaled_map);
    let corrected = base.with_latitude_factor(factor);
    let mut rng = StdRng::seed_from_u64(31);
    let (mut a, mut b) = (AlbedoView::new(), AlbedoView::new());
    let mut checked = 0;
    for k in 0..24 {
        let (r_sat, r_sun, rot) = random_geometry(&mut rng, k);
        corrected
            .compute_into(&mut a, &r_sat, &r_sun, &rot)
            .unwrap();
        expected.compute_into(&mut b, &r_sat, &r_sun, &rot).unwrap();
        for _ in 0..8 {
            let n = random_unit(&mut rng);
            let (x, y) = (a.ratio(&n, 0.0), b.ratio(&n, 0.0));
            assert!((x - y).abs() <= 1e-12 * (1.0 + y.abs()), "{x} vs {y}");
            checked += usize::from(y > 0.0);
        }
    }
    assert!(checked > 20, "{checked} lit checks");
}
