//! The smoother replays the forward pass from its checkpoints: in a joint run a replay that
//! starts before a later data set's first acquisition must restart the gyro bias there as
//! the forward pass did, or it follows another trajectory (another segment end, other
//! rows) and `estimates_smoothed.csv` holds rows of no forward segment. The pyramid head
//! of issue 20, seed 2, three downlinks, Sun only: the second downlink's first segment is
//! lost after 54 rows; a replay without the restart held it for 252.

use pdcal::calibrate::{RunConfig, run_sets};
use pdcal::output::OutputDir;
use pdcal_filter::Mode;

/// `(t_s, segment)` and the attitude of every row of an estimates file.
fn rows(path: &std::path::Path) -> Vec<((String, String), [f64; 4])> {
    let mut reader = csv::Reader::from_path(path).unwrap();
    let header = reader.headers().unwrap().clone();
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let (t, segment) = (col("t_s"), col("segment"));
    let q = ["q_x", "q_y", "q_z", "q_w"].map(col);
    reader
        .records()
        .map(|r| {
            let r = r.unwrap();
            let key = (r[t].to_owned(), r[segment].to_owned());
            (key, q.map(|k| r[k].parse().unwrap()))
        })
        .collect()
}

#[test]
fn a_joint_runs_smoothed_rows_are_its_forward_rows() {
    let tmp = tempfile::tempdir().unwrap();
    let sets: Vec<_> = (0..3)
        .map(|j| crate::common::downlink_set(crate::common::pyramid_downlink(2, j), j))
        .collect();
    let config = RunConfig {
        mode: Mode::PhotodiodeOnly,
        ..RunConfig::default()
    };
    let out = tmp.path().join("out");
    let dir = OutputDir::create(&out, "calibrate").unwrap();
    let (outcome, _) = run_sets(sets, dir, &config, None).unwrap();
    let forward = rows(&out.join("estimates.csv"));
    let smoothed = rows(&out.join("estimates_smoothed.csv"));
    let first_difference = (forward.iter().zip(&smoothed)).position(|(f, s)| f.0 != s.0);
    assert!(
        first_difference.is_none() && forward.len() == smoothed.len(),
        "{} forward rows, {} smoothed; first different row {first_difference:?}",
        forward.len(),
        smoothed.len()
    );
    // A segment's last row has nothing after it: smoothed and forward are one estimate.
    let segments = &outcome.run.segments;
    assert!(segments.len() >= 3, "{} segments", segments.len());
    let mut ends = 0;
    for k in 0..forward.len() {
        let last = forward
            .get(k + 1)
            .is_none_or(|next| next.0.1 != forward[k].0.1);
        if last {
            let (f, s) = (forward[k].1, smoothed[k].1);
            let dot: f64 = (0..4).map(|i| f[i] * s[i]).sum();
            assert!(dot.abs() > 1.0 - 1e-12, "row {k}: {f:?} against {s:?}");
            ends += 1;
        }
    }
    assert!(ends >= 3, "{ends} segment ends");
}
