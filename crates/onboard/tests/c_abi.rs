//! The C ABI: the core built as a `no_std` static library the way a flight build is (panic
//! abort, a panic handler that is an undefined symbol, no global allocator), the header's
//! layouts against the Rust declarations, and `c/replay.c`, compiled with the system C
//! compiler, giving bit for bit the Rust results on recorded rows.
//!
//! The link of `replay.c` is the proof that the core neither links `std` (the library's own
//! panic handler would clash with std's), nor allocates (there is no allocator to link), nor
//! keeps a panic path after optimisation (the handler's symbol is undefined).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use pdcal_attitude::{RAX2_TABLE1_AZ_EL_DEG, normal_from_az_el};
use pdcal_onboard::ffi::{PdcalCalibration, PdcalEarth, PdcalGrid, PdcalSunEstimate};
use pdcal_onboard::{
    Calibration, EARTH_RADIUS_KM, EarthInput, MAX_PHOTODIODES, Options, Photodiode,
    ReflectivityGrid, SunEstimate, estimate_sun,
};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal, UnitSphere};

fn crate_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Builds the static library and `replay.c` once per test binary; the path of the program.
fn replay() -> &'static Path {
    static BUILT: OnceLock<PathBuf> = OnceLock::new();
    BUILT.get_or_init(|| {
        let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("onboard-c");
        let manifest = crate_dir().join("c/staticlib/Cargo.toml");
        let status = Command::new(env!("CARGO"))
            .args(["build", "--release", "--quiet", "--manifest-path"])
            .arg(&manifest)
            .arg("--target-dir")
            .arg(out.join("target"))
            .status()
            .expect("cargo runs");
        assert!(status.success(), "the no_std static library did not build");
        let library = out.join("target/release/libpdcal_onboard_c.a");
        let program = out.join("replay");
        let output = Command::new("cc")
            .args(["-std=c11", "-Wall", "-Wextra", "-Werror", "-O2", "-I"])
            .arg(crate_dir().join("c"))
            .arg(crate_dir().join("c/replay.c"))
            .arg(&library)
            .args(["-Wl,--gc-sections", "-o"])
            .arg(&program)
            .output()
            .expect("the system C compiler runs");
        assert!(
            output.status.success(),
            "replay.c did not link against the core (a panic path or std left in?):\n{}",
            String::from_utf8_lossy(&output.stderr)
        );
        program
    })
}

fn run(arg: &str) -> String {
    let output = Command::new(replay())
        .arg(arg)
        .output()
        .expect("replay runs");
    assert!(output.status.success(), "replay failed: {output:?}");
    String::from_utf8(output.stdout).expect("ASCII")
}

#[test]
fn the_header_layouts_are_the_rust_layouts() {
    use core::mem::{offset_of, size_of};
    let expected = format!(
        "photodiode {} {} {}\ncalibration {} {}\ngrid {} {}\nearth {} {} {}\noptions {} {} {}\n\
         estimate {} {} {} {}\n",
        size_of::<Photodiode<f32>>(),
        offset_of!(Photodiode<f32>, normal_sigma_rad),
        offset_of!(Photodiode<f32>, enabled),
        size_of::<PdcalCalibration>(),
        offset_of!(PdcalCalibration, photodiodes),
        size_of::<PdcalGrid>(),
        offset_of!(PdcalGrid, cells),
        size_of::<PdcalEarth>(),
        offset_of!(PdcalEarth, ecef_from_body),
        offset_of!(PdcalEarth, grid),
        size_of::<Options<f32>>(),
        offset_of!(Options<f32>, albedo_passes),
        offset_of!(Options<f32>, max_misfit_sigmas),
        size_of::<PdcalSunEstimate>(),
        offset_of!(PdcalSunEstimate, used_mask),
        offset_of!(PdcalSunEstimate, validity),
        offset_of!(PdcalSunEstimate, albedo),
    );
    assert_eq!(run("layout"), expected);
    let header = std::fs::read_to_string(crate_dir().join("c/pdcal_onboard.h")).unwrap();
    assert!(header.contains(&format!(
        "#define PDCAL_MAX_PHOTODIODES {MAX_PHOTODIODES}\n"
    )));
}

/// RAX-2's photodiodes (paper Table 1), with scales and a few disabled or odd channels.
fn calibration(rng: &mut StdRng) -> Calibration<f32, 17> {
    let mut photodiodes = RAX2_TABLE1_AZ_EL_DEG.map(|(az, el)| {
        let n = normal_from_az_el(az.to_radians(), el.to_radians()).map(|x| x as f32);
        let mut pd = Photodiode::cosine(rng.random_range(3.5..3.9), n.into(), 0.015);
        pd.scale_sigma_v = 0.01;
        pd.normal_sigma_rad = 0.002;
        pd.dark_v = 0.01;
        pd
    });
    photodiodes[4].enabled = false;
    photodiodes[9].fov_half_angle_rad = 1.2;
    Calibration {
        count: 17,
        photodiodes,
    }
}

/// The rows file, and the Rust estimates of the same rows.
fn recorded_rows(
    seed: u64,
    grid: Option<(usize, usize, &[u8])>,
) -> (String, Vec<SunEstimate<f32>>) {
    let mut rng = StdRng::seed_from_u64(seed);
    let cal = calibration(&mut rng);
    let mut text = format!("count {}\n", cal.count);
    for p in &cal.photodiodes {
        let [x, y, z] = p.normal_body;
        writeln!(
            text,
            "pd {} {x} {y} {z} {} {} {} {} {} {}",
            p.scale_v,
            p.dark_v,
            p.fov_half_angle_rad,
            p.noise_v,
            p.scale_sigma_v,
            p.normal_sigma_rad,
            u8::from(p.enabled)
        )
        .unwrap();
    }
    let grid = grid.map(|(n_lat, n_lon, cells)| {
        write!(text, "grid {n_lat} {n_lon}").unwrap();
        cells.iter().for_each(|c| write!(text, " {c}").unwrap());
        text.push('\n');
        ReflectivityGrid::new(n_lat, n_lon, cells).unwrap()
    });
    let noise = Normal::new(0.0f32, 0.015).unwrap();
    let mut estimates = Vec::new();
    for row in 0..300 {
        let sun: [f32; 3] = UnitSphere.sample(&mut rng);
        let up: [f32; 3] = UnitSphere.sample(&mut rng);
        let y: [f32; 17] = core::array::from_fn(|i| {
            let p = &cal.photodiodes[i];
            let cos: f32 = p.normal_body.iter().zip(&sun).map(|(a, b)| a * b).sum();
            // Every tenth row dark (eclipse), the others lit with a little Earth light.
            let light = if row % 10 == 0 {
                0.0
            } else {
                cos.max(0.0) + 0.05 * rng.random::<f32>()
            };
            p.dark_v + p.scale_v * light + noise.sample(&mut rng)
        });
        let (axis, angle): ([f32; 3], f32) =
            (UnitSphere.sample(&mut rng), rng.random_range(0.0..3.0));
        let m = rotation(axis, angle);
        let has_earth = row % 3 != 0;
        let earth = EarthInput {
            earth_body: up.map(|x| -x),
            orbit_radius_km: EARTH_RADIUS_KM as f32 + 500.0,
            ecef_from_body: (row % 2 == 0).then_some(m),
            grid: grid.as_ref(),
        };
        write!(text, "row").unwrap();
        y.iter().for_each(|v| write!(text, " {v}").unwrap());
        let [ex, ey, ez] = earth.earth_body;
        write!(
            text,
            " {} {ex} {ey} {ez} {} {}",
            u8::from(has_earth),
            earth.orbit_radius_km,
            u8::from(earth.ecef_from_body.is_some())
        )
        .unwrap();
        m.iter()
            .flatten()
            .for_each(|v| write!(text, " {v}").unwrap());
        text.push('\n');
        let earth = has_earth.then_some(&earth);
        estimates.push(estimate_sun(&y, &cal, earth, &Options::default()));
    }
    (text, estimates)
}

fn rotation([x, y, z]: [f32; 3], angle: f32) -> [[f32; 3]; 3] {
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    [
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ]
}

fn expected_line(e: &SunEstimate<f32>) -> String {
    let [x, y, z] = e.sun_body;
    format!(
        "{} {} {} {} {:08x} {:08x} {:08x} {:08x} {:08x} {:08x}",
        e.validity as u32,
        e.albedo as u32,
        e.n_used,
        e.used_mask,
        x.to_bits(),
        y.to_bits(),
        z.to_bits(),
        e.magnitude.to_bits(),
        e.cone_sigma_rad.to_bits(),
        e.misfit.to_bits()
    )
}

fn compare(name: &str, text: &str, estimates: &[SunEstimate<f32>]) {
    let path = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::write(&path, text).unwrap();
    let printed = run(path.to_str().unwrap());
    let lines: Vec<&str> = printed.lines().collect();
    assert_eq!(lines.len(), estimates.len());
    for (k, (line, e)) in lines.iter().zip(estimates).enumerate() {
        assert_eq!(*line, expected_line(e), "row {k}");
    }
    let valid = estimates.iter().filter(|e| e.validity as u32 == 0).count();
    assert!(
        valid > estimates.len() / 4,
        "only {valid} valid rows: the comparison is thin"
    );
}

#[test]
fn the_c_program_gives_the_rust_results_without_a_grid() {
    let (text, estimates) = recorded_rows(11, None);
    compare("rows-uniform.txt", &text, &estimates);
}

#[test]
fn the_c_program_gives_the_rust_results_with_a_grid() {
    let cells: Vec<u8> = (0..18 * 36).map(|k| (k * 37 % 230) as u8).collect();
    let (text, estimates) = recorded_rows(12, Some((18, 36, &cells)));
    compare("rows-grid.txt", &text, &estimates);
}
