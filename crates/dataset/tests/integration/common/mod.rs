//! Datasets shared by the integration tests.
#![allow(dead_code)]

use nalgebra::{Vector3, Vector4};
use pdcal_dataset::{
    Dataset, DatasetMeta, Effect, EpochUtc, NoiseHints, NominalMount, OrbitSpec, Samples,
    Telemetry, TruePd, TruthConstants, TruthSeries,
};

/// The RAX-2-like TLE of docs/rax2-scenario.md (valid checksums).
pub const TLE1: &str = "1 37853U 11061D   11308.77065972  .00000000  00000-0  20000-4 0  9997";
/// Line 2 of the same.
pub const TLE2: &str = "2 37853 101.7000  50.0000 0300509 130.0000 230.0000 14.86144463  1000";

/// Table 1 of the paper: nominal azimuth/elevation of the 17 RAX-2 photodiodes.
pub fn rax2_mounts() -> Vec<NominalMount> {
    let az = [
        17.0, 0.0, -17.0, -162.0, 180.0, 162.0, 72.0, 107.0, 90.0, -107.0, -72.0, -90.0, 0.0, 0.0,
        0.0, 0.0, 0.0,
    ];
    let el = [
        -10.0, 20.0, -10.0, -10.0, 20.0, -10.0, 10.0, 10.0, -20.0, 10.0, 10.0, -20.0, 90.0, 90.0,
        90.0, -90.0, -90.0,
    ];
    az.iter()
        .zip(el)
        .map(|(&azimuth_deg, elevation_deg)| NominalMount {
            azimuth_deg,
            elevation_deg,
            panel: None,
            fov_deg: None,
        })
        .collect()
}

/// Awkward floats: signed zero, subnormal, extremes, values with no short decimal form.
pub const AWKWARD: [f64; 9] = [
    -0.0,
    5e-324,
    1e-300,
    f64::MAX,
    f64::MIN_POSITIVE,
    0.1 + 0.2,
    -1.0 / 3.0,
    123_456_789.123_456_79,
    1e16,
];

/// A deterministic pseudo-random stream (splitmix64) so the data has full-precision digits.
pub struct Stream(u64);

impl Stream {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// Uniform in [-1, 1) with all 53 bits used.
    pub fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    pub fn vec3(&mut self, scale: f64) -> Vector3<f64> {
        Vector3::new(
            self.next() * scale,
            self.next() * scale,
            self.next() * scale,
        )
    }
}

/// A simulated-looking dataset with every optional part present, empty cells of every kind,
/// and the awkward floats planted in the photodiode and gyro columns.
pub fn full_dataset(rows: usize) -> Dataset {
    let mounts = rax2_mounts();
    let n = mounts.len();
    let meta = DatasetMeta {
        format_version: 1,
        name: "round-trip".into(),
        epoch_utc: EpochUtc::parse("2011-11-04T18:29:45Z").unwrap(),
        orbit: OrbitSpec::Tle {
            line1: TLE1.into(),
            line2: TLE2.into(),
        },
        photodiodes: mounts,
        noise: Some(NoiseHints {
            gyro_rad_s: Some(0.0008),
            mag_nt: Some(320.0),
            photodiode_v: Some(0.015),
        }),
        inertia_kg_m2: Some(pdcal_dataset::Inertia {
            xx: 0.185,
            yy: 0.144,
            zz: 0.061,
            xy: 0.002,
            xz: -0.001,
            yz: 0.0015,
        }),
    };
    let mut s = Stream::new(7);
    let mut tm = Telemetry {
        mag_nt: Some(Default::default()),
        pd_v: vec![Samples::new(); n],
        ..Telemetry::default()
    };
    for k in 0..rows {
        tm.t_s.push(k as f64 + 0.25 * s.next().abs());
        // Gyro every row but the 5th; magnetometer every other row.
        tm.gyro_rad_s.push((k % 5 != 4).then(|| s.vec3(0.05)));
        if let Some(m) = tm.mag_nt.as_mut() {
            m.push((k % 2 == 0).then(|| s.vec3(40_000.0)));
        }
        for (i, pd) in tm.pd_v.iter_mut().enumerate() {
            let v = match (k + i) % 7 {
                0 => None,
                1 => Some(AWKWARD[(k + i) % AWKWARD.len()]),
                _ => Some(3.6 * s.next().abs()),
            };
            pd.push(v);
        }
    }
    tm.gyro_rad_s
        .set(1, Some(Vector3::new(AWKWARD[0], AWKWARD[1], AWKWARD[2])));
    Dataset {
        meta,
        telemetry: tm,
        truth: Some((truth_series(rows, &mut s), truth_constants(n))),
    }
}

fn truth_series(rows: usize, s: &mut Stream) -> TruthSeries {
    let mut ts = TruthSeries::default();
    for k in 0..rows {
        ts.t_s.push(k as f64);
        let q = Vector4::new(s.next(), s.next(), s.next(), s.next()).normalize();
        ts.q.push(q);
        ts.w_body_rad_s.push(s.vec3(0.1));
        ts.gyro_bias_rad_s.push(s.vec3(0.003));
        ts.sun_body.push(s.vec3(1.0).normalize());
        ts.eclipse.push(s.next().abs());
        ts.r_gcrf_km.push(s.vec3(7000.0));
        ts.mag_body_nt.push(s.vec3(40_000.0));
    }
    ts
}

/// True constants with every effect on.
pub fn truth_constants(n: usize) -> TruthConstants {
    TruthConstants {
        photodiodes: (0..n)
            .map(|i| TruePd {
                scale_v: 3.5 + 0.0234567 * i as f64,
                azimuth_deg: 17.0 + 1.1 * i as f64,
                elevation_deg: -7.9 + 0.3 * i as f64,
            })
            .collect(),
        effects: vec![
            Effect::Albedo {
                map: "toms-mean-1p25x1".into(),
            },
            Effect::FovRolloff {
                start_rad: 60f64.to_radians(),
                cutoff_rad: 85f64.to_radians(),
            },
            Effect::DarkOffset {
                volts: (0..n).map(|i| 0.001 * i as f64).collect(),
            },
            Effect::Saturation { volts: 3.3 },
            Effect::Penumbra,
            Effect::TimeOffset { seconds: 0.25 },
            Effect::ScaleDrift {
                fraction_per_hour: vec![-0.01; n],
            },
            Effect::MagBias {
                bias_nt: [150.0, -80.0, 0.1 + 0.2],
            },
            Effect::GyroScale {
                scale_error: [0.01, -0.005, 0.0],
            },
        ],
        magnetometer: Some(pdcal_dataset::TrueMagnetometer {
            matrix: [[1.03, 0.02, -0.01], [0.0, 0.97, 0.015], [0.0, 0.0, 1.01]],
            bias_nt: [3000.0, -2500.0, 4100.5],
            current_bias_nt_per_a: vec![("cur_px_A".into(), [400.0, -300.0, 650.25])],
        }),
    }
}

/// The smallest variant: positions in telemetry, no magnetometer, no noise hints, no truth.
pub fn minimal_dataset(rows: usize) -> Dataset {
    let mut s = Stream::new(11);
    let meta = DatasetMeta {
        format_version: 1,
        name: "positions".into(),
        epoch_utc: EpochUtc::parse("2024-02-29 23:59:59.123456789 UTC").unwrap(),
        orbit: OrbitSpec::PositionColumns,
        photodiodes: rax2_mounts()[..3].to_vec(),
        noise: None,
        inertia_kg_m2: None,
    };
    let mut tm = Telemetry {
        pd_v: vec![Samples::new(); 3],
        r_gcrf_km: Some(Default::default()),
        ..Telemetry::default()
    };
    for k in 0..rows {
        tm.t_s.push(0.1 * k as f64);
        tm.gyro_rad_s.push(Some(s.vec3(0.05)));
        for pd in &mut tm.pd_v {
            pd.push((k % 3 != 0).then(|| s.next()));
        }
        if let Some(r) = tm.r_gcrf_km.as_mut() {
            r.push((k % 4 != 3).then(|| s.vec3(7000.0)));
        }
    }
    Dataset {
        meta,
        telemetry: tm,
        truth: None,
    }
}

/// Every f64 of a dataset, in a fixed order, as bits, with `None` cells marked, so two
/// datasets can be compared bit for bit (`PartialEq` would call -0.0 equal to 0.0).
pub fn bits(ds: &Dataset) -> Vec<Option<u64>> {
    let mut out = Vec::new();
    let mut f = |x: f64| out.push(Some(x.to_bits()));
    let meta = &ds.meta;
    for m in &meta.photodiodes {
        f(m.azimuth_deg);
        f(m.elevation_deg);
    }
    if let Some(n) = &meta.noise {
        for v in [n.gyro_rad_s, n.mag_nt, n.photodiode_v]
            .into_iter()
            .flatten()
        {
            f(v);
        }
    }
    let tm = &ds.telemetry;
    tm.t_s.iter().for_each(|&x| f(x));
    let mut out2 = Vec::new();
    let mut g = |v: Option<Vector3<f64>>| match v {
        Some(v) => out2.extend(v.iter().map(|x| Some(x.to_bits()))),
        None => out2.push(None),
    };
    tm.gyro_rad_s.iter().for_each(&mut g);
    tm.mag_nt.iter().flat_map(|c| c.iter()).for_each(&mut g);
    tm.r_gcrf_km.iter().flat_map(|c| c.iter()).for_each(&mut g);
    for pd in &tm.pd_v {
        out2.extend(pd.iter().map(|x| x.map(f64::to_bits)));
    }
    out.extend(out2);
    if let Some((ts, tc)) = &ds.truth {
        let mut h = |x: f64| out.push(Some(x.to_bits()));
        ts.t_s.iter().for_each(|&x| h(x));
        ts.eclipse.iter().for_each(|&x| h(x));
        ts.q.iter().flat_map(|q| q.iter()).for_each(|&x| h(x));
        for col in [
            &ts.w_body_rad_s,
            &ts.gyro_bias_rad_s,
            &ts.sun_body,
            &ts.r_gcrf_km,
            &ts.mag_body_nt,
        ] {
            col.iter().flat_map(|v| v.iter()).for_each(|&x| h(x));
        }
        for pd in &tc.photodiodes {
            h(pd.scale_v);
            h(pd.azimuth_deg);
            h(pd.elevation_deg);
        }
    }
    out
}
