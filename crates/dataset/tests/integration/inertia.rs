//! The optional inertia tensor (`inertia_kg_m2`): read as written, products defaulting to
//! zero, and a tensor no rigid body has refused with the place of the field.

use crate::common;

use common::{TLE1, TLE2};
use pdcal_dataset::{Inertia, meta_from_str};

/// dataset.ron with one photodiode and `inertia` as the last field (line 8).
fn meta_text(inertia: &str) -> String {
    format!(
        "(\n    format_version: 1,\n    name: \"inertia\",\n    epoch_utc: \"2011-11-04T18:29:45Z\",\n    \
         orbit: Tle(line1: \"{TLE1}\", line2: \"{TLE2}\"),\n    \
         photodiodes: [(azimuth_deg: 17.0, elevation_deg: -10.0)],\n    \
         noise: (gyro_rad_s: 0.0008),\n    inertia_kg_m2: {inertia},\n)\n"
    )
}

#[test]
fn a_tensor_is_read_with_absent_products_zero() {
    let meta = meta_from_str(&meta_text("(xx: 0.0314, yy: 0.0314, zz: 0.005)")).unwrap();
    assert_eq!(
        meta.inertia_kg_m2,
        Some(Inertia {
            xx: 0.0314,
            yy: 0.0314,
            zz: 0.005,
            xy: 0.0,
            xz: 0.0,
            yz: 0.0,
        })
    );
    let full = meta_from_str(&meta_text(
        "(xx: 0.185, yy: 0.144, zz: 0.061, xy: 0.002, xz: -0.001, yz: 0.0015)",
    ))
    .unwrap();
    let j = full.inertia_kg_m2.unwrap().matrix();
    assert_eq!((j[(0, 1)], j[(1, 0)], j[(2, 1)]), (0.002, 0.002, 0.0015));
    let absent = meta_text("()").replace("    inertia_kg_m2: (),\n", "");
    assert_eq!(meta_from_str(&absent).unwrap().inertia_kg_m2, None);
}

#[test]
fn unphysical_tensors_are_refused_at_the_field() {
    for (tensor, why) in [
        // I_1 + I_2 < I_3: no rigid body.
        ("(xx: 1.0, yy: 1.0, zz: 2.5)", "not physical"),
        // Negative moment.
        ("(xx: -1.0, yy: 1.0, zz: 1.0)", "not physical"),
        // Products too large: an eigenvalue below zero.
        ("(xx: 1.0, yy: 1.0, zz: 1.0, xy: 1.5)", "not physical"),
        (
            "(xx: 1.0, yy: inf, zz: 1.0)",
            "yy = inf is not a finite number",
        ),
        // The entry at fault is named, not blamed on symmetry.
        (
            "(xx: NaN, yy: 1.0, zz: 1.0)",
            "xx = NaN is not a finite number",
        ),
        // A moment no spacecraft has: a unit mistake, not a body to calibrate with.
        (
            "(xx: 1e-30, yy: 1e-30, zz: 1e-30)",
            "xx = 1e-30 kg m^2 is outside any spacecraft's",
        ),
        (
            "(xx: 0.0314, yy: 0.0314, zz: 5e10)",
            "zz = 5e10 kg m^2 is outside",
        ),
    ] {
        let e = meta_from_str(&meta_text(tensor)).unwrap_err().to_string();
        assert!(
            e.starts_with("dataset.ron:8:5 (inertia_kg_m2): not a rigid body's inertia"),
            "{tensor}: {e}"
        );
        assert!(e.contains(why), "{tensor}: {e}");
    }
    let e = meta_from_str(&meta_text("(xx: 1.0, yy: 1.0, zz: 1.0, xy: 0.1, yx: 0.1)"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("unknown field `yx`"), "{e}");
}
