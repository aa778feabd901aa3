//! SGP4 through the crate against Vallado's verification set (AIAA 2006-6753):
//! `fixtures/reference/sgp4/SGP4-VER.TLE` and `tcppver.out` (WGS-72, opsmode 'i').
//! See that folder's README for the file quirks handled here.

use nalgebra::Vector3;
use pdcal_ephem::{OrbitError, TleOrbit};

const DIR: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../fixtures/reference/sgp4/"
);

/// One TLE of the verification file with its tsince schedule, minutes.
struct Case {
    line1: String,
    line2: String,
    start: f64,
    stop: f64,
    step: f64,
}

/// One block of tcppver.out: satellite number and data lines (tsince, r km, v km/s).
struct Expected {
    satnum: u64,
    lines: Vec<(f64, Vector3<f64>, Vector3<f64>)>,
}

fn cases() -> Vec<Case> {
    let text = std::fs::read_to_string(format!("{DIR}SGP4-VER.TLE")).expect("SGP4-VER.TLE");
    let lines: Vec<&str> = text
        .lines()
        .map(str::trim_end) // CRLF
        .filter(|l| !l.starts_with('#') && !l.is_empty())
        .collect();
    lines
        .chunks(2)
        .map(|pair| {
            let extra: Vec<f64> = pair[1][69..]
                .split_whitespace()
                .map(|x| x.parse().expect("schedule field"))
                .collect();
            Case {
                line1: pair[0].to_owned(),
                line2: pair[1].to_owned(),
                start: extra[0],
                stop: extra[1],
                step: extra[2],
            }
        })
        .collect()
}

fn expected() -> Vec<Expected> {
    let text = std::fs::read_to_string(format!("{DIR}tcppver.out")).expect("tcppver.out");
    let mut blocks: Vec<Expected> = Vec::new();
    for line in text.lines() {
        let fields: Vec<&str> = line.split_whitespace().collect();
        match fields.as_slice() {
            [num, "xx"] => blocks.push(Expected {
                satnum: num.parse().unwrap(),
                lines: vec![],
            }),
            [t, x, y, z, vx, vy, vz, ..] => {
                let f = |s: &str| s.parse::<f64>().expect("number");
                let block = blocks.last_mut().expect("data after a header");
                block.lines.push((
                    f(t),
                    Vector3::new(f(x), f(y), f(z)),
                    Vector3::new(f(vx), f(vy), f(vz)),
                ));
            }
            _ => {}
        }
    }
    blocks
}

/// The tsince values Vallado's driver prints: 0, then start..=stop by step, then stop if
/// the step does not land on it.
fn schedule(case: &Case) -> Vec<f64> {
    let mut times = vec![0.0];
    let mut t = case.start;
    while t <= case.stop + 1e-9 {
        if t != 0.0 || case.start != 0.0 {
            times.push(t);
        }
        t += case.step;
    }
    if (times[times.len() - 1] - case.stop).abs() > 1e-9 {
        times.push(case.stop);
    }
    times
}

/// Expected SGP4 error codes, in file order (README): satellite -> code.
const EXPECTED_ERRORS: [(u64, u8); 7] = [
    (22312, 1),
    (28350, 1),
    (28872, 6),
    (29141, 6),
    (33333, 4),
    (33334, 3),
    (20413, 6),
];

#[test]
fn vallado_verification_vectors() {
    let cases = cases();
    let blocks = expected();
    assert_eq!(cases.len(), 33);
    assert_eq!(blocks.len(), cases.len());
    let mut errors_seen = Vec::new();
    let (mut max_dr_km, mut max_dv_km_s, mut compared) = (0.0_f64, 0.0_f64, 0);
    for (case, block) in cases.iter().zip(&blocks) {
        // Some lines carry wrong checksums on purpose: this test (only) skips verification.
        let tle = TleOrbit::from_lines_ignoring_checksums(&case.line1, &case.line2)
            .unwrap_or_else(|e| panic!("{}: {e}", block.satnum));
        assert_eq!(tle.norad_id(), block.satnum);
        // 33334 fails at tsince 0; its one data line repeats the previous satellite's state.
        let reference: &[_] = if block.satnum == 33334 {
            &[]
        } else {
            &block.lines
        };
        let times = schedule(case);
        for (i, &tsince) in times.iter().enumerate() {
            match (tle.propagate_teme(tsince), reference.get(i)) {
                (Ok(state), Some((t_ref, r_ref, v_ref))) => {
                    assert!((tsince - t_ref).abs() < 1e-6, "{} schedule", block.satnum);
                    let dr = (state.r_teme_km - r_ref).norm();
                    let dv = (state.v_teme_km_s - v_ref).norm();
                    // Acceptance: 1 m and 1 mm/s (issue 2). A faithful port reaches 1e-6 km
                    // and 1e-9 km/s; the file prints 8 and 9 decimals.
                    assert!(dr < 1e-3, "{} t={tsince}: |dr| = {dr} km", block.satnum);
                    assert!(dv < 1e-6, "{} t={tsince}: |dv| = {dv} km/s", block.satnum);
                    max_dr_km = max_dr_km.max(dr);
                    max_dv_km_s = max_dv_km_s.max(dv);
                    compared += 1;
                }
                (Err(OrbitError::Propagation { code, .. }), None) => {
                    // The reference stops at the first error: it must be here, not earlier.
                    assert_eq!(
                        i,
                        reference.len(),
                        "{} erred early at {tsince}",
                        block.satnum
                    );
                    errors_seen.push((block.satnum, code));
                    break;
                }
                (Ok(_), None) => panic!("{} t={tsince}: expected an SGP4 error", block.satnum),
                (Err(e), _) => panic!("{} t={tsince}: unexpected {e}", block.satnum),
            }
        }
    }
    assert_eq!(errors_seen, EXPECTED_ERRORS);
    // Every data line of the file except 33334's placeholder (667 - 1).
    assert_eq!(compared, 666);
    // Measured: 4.2e-6 km and 1.9e-9 km/s.
    assert!(max_dr_km < 1e-3 && max_dv_km_s < 1e-6);
}
