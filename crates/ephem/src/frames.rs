//! Rotations between GCRF, TEME and the Earth-fixed frame (ITRF without polar motion).
//!
//! The chain is the classical IAU-76/FK5 one (Vallado, *Fundamentals of Astrodynamics and
//! Applications*, 4th ed., Sec. 3.7; Seidelmann, *Explanatory Supplement*, 1992, Sec. 3.2):
//!
//! ```text
//! v_itrf = R3(GAST) · N · P · B · v_gcrf        (polar motion W = I)
//! v_gcrf = Bᵀ · Pᵀ · Nᵀ · R3(GMST82 − GAST) · v_teme
//! ```
//!
//! - B: IERS 2003 frame bias (GCRF -> mean J2000), 23 mas.
//! - P: IAU-76 precession (Lieske 1977 ζ, θ, z), mean J2000 -> mean of date.
//! - N: IAU-1980 nutation, truncated to the 35 terms with an amplitude of at least 1 mas;
//!   mean of date -> true of date.
//! - GAST = GMST82 + Δψ cos ε̄ + 0.00264″ sin Ω + 0.000063″ sin 2Ω (IAU 1994 equation of the
//!   equinoxes).
//! - UT1 = UTC, so GMST is evaluated at UTC; polar motion is ignored.
//!
//! Every `Rk(a)` is a frame rotation (a vector keeps its place, the axes turn by `a`).

use hifitime::Epoch;
use nalgebra::Matrix3;

/// Arcseconds to radians.
const ARCSEC: f64 = std::f64::consts::PI / (180.0 * 3600.0);
/// Julian date of J2000.0 (2000-01-01T12:00, in whichever scale the argument is).
const JD_J2000: f64 = 2_451_545.0;
/// Days per Julian century.
const DAYS_PER_CENTURY: f64 = 36_525.0;

/// The IAU-1980 nutation terms kept (out of 106): multipliers of the Delaunay arguments
/// (l, l', F, D, Ω), then Δψ = (a + a_t T) sin(arg) and Δε = (b + b_t T) cos(arg), in units of
/// 0.1 mas (T in Julian centuries TT). All terms with |a| ≥ 10 or |b| ≥ 10 are kept; the 71
/// dropped terms sum to at most 0.0186″ in Δψ and 0.0056″ in Δε (sum of their absolute
/// amplitudes), which moves a position at LEO radius (7000 km) by at most 0.7 m.
const NUTATION_1980: [([i8; 5], f64, f64, f64, f64); 35] = [
    ([0, 0, 0, 0, 1], -171_996.0, -174.2, 92_025.0, 8.9),
    ([0, 0, 2, -2, 2], -13_187.0, -1.6, 5_736.0, -3.1),
    ([0, 0, 2, 0, 2], -2_274.0, -0.2, 977.0, -0.5),
    ([0, 0, 0, 0, 2], 2_062.0, 0.2, -895.0, 0.5),
    ([0, 1, 0, 0, 0], 1_426.0, -3.4, 54.0, -0.1),
    ([1, 0, 0, 0, 0], 712.0, 0.1, -7.0, 0.0),
    ([0, 1, 2, -2, 2], -517.0, 1.2, 224.0, -0.6),
    ([0, 0, 2, 0, 1], -386.0, -0.4, 200.0, 0.0),
    ([1, 0, 2, 0, 2], -301.0, 0.0, 129.0, -0.1),
    ([0, -1, 2, -2, 2], 217.0, -0.5, -95.0, 0.3),
    ([1, 0, 0, -2, 0], -158.0, 0.0, -1.0, 0.0),
    ([0, 0, 2, -2, 1], 129.0, 0.1, -70.0, 0.0),
    ([-1, 0, 2, 0, 2], 123.0, 0.0, -53.0, 0.0),
    ([0, 0, 0, 2, 0], 63.0, 0.0, -2.0, 0.0),
    ([1, 0, 0, 0, 1], 63.0, 0.1, -33.0, 0.0),
    ([-1, 0, 2, 2, 2], -59.0, 0.0, 26.0, 0.0),
    ([-1, 0, 0, 0, 1], -58.0, -0.1, 32.0, 0.0),
    ([1, 0, 2, 0, 1], -51.0, 0.0, 27.0, 0.0),
    ([2, 0, 0, -2, 0], 48.0, 0.0, 1.0, 0.0),
    ([-2, 0, 2, 0, 1], 46.0, 0.0, -24.0, 0.0),
    ([0, 0, 2, 2, 2], -38.0, 0.0, 16.0, 0.0),
    ([2, 0, 2, 0, 2], -31.0, 0.0, 13.0, 0.0),
    ([2, 0, 0, 0, 0], 29.0, 0.0, -1.0, 0.0),
    ([1, 0, 2, -2, 2], 29.0, 0.0, -12.0, 0.0),
    ([0, 0, 2, 0, 0], 26.0, 0.0, -1.0, 0.0),
    ([0, 0, 2, -2, 0], -22.0, 0.0, 0.0, 0.0),
    ([-1, 0, 2, 0, 1], 21.0, 0.0, -10.0, 0.0),
    ([0, 2, 0, 0, 0], 17.0, -0.1, 0.0, 0.0),
    ([0, 2, 2, -2, 2], -16.0, 0.1, 7.0, 0.0),
    ([-1, 0, 0, 2, 1], 16.0, 0.0, -8.0, 0.0),
    ([0, 1, 0, 0, 1], -15.0, 0.0, 9.0, 0.0),
    ([1, 0, 0, -2, 1], -13.0, 0.0, 7.0, 0.0),
    ([0, -1, 0, 0, 1], -12.0, 0.0, 6.0, 0.0),
    ([2, 0, -2, 0, 0], 11.0, 0.0, 0.0, 0.0),
    ([-1, 0, 2, 2, 1], -10.0, 0.0, 5.0, 0.0),
];

/// Frame rotation about x by `a` rad.
pub fn rot1(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, s, 0.0, -s, c)
}

/// Frame rotation about y by `a` rad.
pub fn rot2(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, 0.0, -s, 0.0, 1.0, 0.0, s, 0.0, c)
}

/// Frame rotation about z by `a` rad.
pub fn rot3(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0)
}

/// Julian centuries of TT since J2000.0 (the argument of precession and nutation).
pub fn centuries_tt(t: Epoch) -> f64 {
    (t.to_jde_tt_days() - JD_J2000) / DAYS_PER_CENTURY
}

/// Julian centuries of UT1 since J2000.0, with UT1 = UTC (the argument of GMST).
fn centuries_ut1(t: Epoch) -> f64 {
    (crate::time::jd_utc(t) - JD_J2000) / DAYS_PER_CENTURY
}

/// IERS 2003 frame bias B (v_meanJ2000 = B v_gcrf): dα0 = −14.6 mas, ξ0 = −16.617 mas,
/// η0 = −6.819 mas (IERS Conventions 2003, Eq. 5.28).
pub fn frame_bias() -> Matrix3<f64> {
    let d_alpha0 = -0.0146 * ARCSEC;
    let xi0 = -0.016_617 * ARCSEC;
    let eta0 = -0.006_819 * ARCSEC;
    rot1(-eta0) * rot2(xi0) * rot3(d_alpha0)
}

/// IAU-76 precession P (v_meanOfDate = P v_meanJ2000), Lieske et al. (1977) angles.
pub fn precession_iau76(t: Epoch) -> Matrix3<f64> {
    let tc = centuries_tt(t);
    let zeta = ((0.017_998 * tc + 0.301_88) * tc + 2306.2181) * tc * ARCSEC;
    let theta = ((-0.041_833 * tc - 0.426_65) * tc + 2004.3109) * tc * ARCSEC;
    let z = ((0.018_203 * tc + 1.094_68) * tc + 2306.2181) * tc * ARCSEC;
    rot3(-z) * rot2(theta) * rot3(-zeta)
}

/// Mean obliquity of the ecliptic, IAU 1980, in rad.
pub fn mean_obliquity_iau80(t: Epoch) -> f64 {
    let tc = centuries_tt(t);
    (((0.001_813 * tc - 0.000_59) * tc - 46.8150) * tc + 84_381.448) * ARCSEC
}

/// Nutation angles of the IAU-1980 theory (truncated to 35 terms, see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nutation {
    /// Nutation in longitude Δψ, rad.
    pub dpsi_rad: f64,
    /// Nutation in obliquity Δε, rad.
    pub deps_rad: f64,
    /// Mean obliquity ε̄ of date, rad.
    pub mean_obliquity_rad: f64,
    /// Longitude of the Moon's mean ascending node Ω, rad (for the equation of the equinoxes).
    pub moon_node_rad: f64,
}

/// Delaunay arguments (l, l', F, D, Ω) in rad, IAU 1980 (Seidelmann 1992, Sec. 3.222).
fn delaunay_arguments(tc: f64) -> [f64; 5] {
    let rev = 1_296_000.0; // arcseconds per revolution
    let poly = |c0: f64, c1: f64, c2: f64, c3: f64, revs: f64| {
        let arcsec = ((c3 * tc + c2) * tc + c1) * tc + c0;
        ((arcsec + (revs * tc).rem_euclid(1.0) * rev) * ARCSEC).rem_euclid(std::f64::consts::TAU)
    };
    [
        poly(485_866.733, 715_922.633, 31.310, 0.064, 1325.0),
        poly(1_287_099.804, 1_292_581.224, -0.577, -0.012, 99.0),
        poly(335_778.877, 295_263.137, -13.257, 0.011, 1342.0),
        poly(1_072_261.307, 1_105_601.328, -6.891, 0.019, 1236.0),
        poly(450_160.280, -482_890.539, 7.455, 0.008, -5.0),
    ]
}

/// IAU-1980 nutation at `t` (TT argument).
pub fn nutation_iau80(t: Epoch) -> Nutation {
    let tc = centuries_tt(t);
    let args = delaunay_arguments(tc);
    let (mut dpsi, mut deps) = (0.0, 0.0);
    // Smallest terms first, so the sum loses less to rounding.
    for (m, a, a_t, b, b_t) in NUTATION_1980.iter().rev() {
        let arg: f64 = m.iter().zip(args).map(|(&k, x)| f64::from(k) * x).sum();
        dpsi += (a + a_t * tc) * arg.sin();
        deps += (b + b_t * tc) * arg.cos();
    }
    Nutation {
        dpsi_rad: dpsi * 1e-4 * ARCSEC,
        deps_rad: deps * 1e-4 * ARCSEC,
        mean_obliquity_rad: mean_obliquity_iau80(t),
        moon_node_rad: args[4],
    }
}

impl Nutation {
    /// Nutation matrix N (v_trueOfDate = N v_meanOfDate).
    pub fn matrix(&self) -> Matrix3<f64> {
        let eps = self.mean_obliquity_rad;
        rot1(-(eps + self.deps_rad)) * rot3(-self.dpsi_rad) * rot1(eps)
    }

    /// Equation of the equinoxes GAST − GMST, rad, with the two IAU 1994 terms in Ω.
    pub fn equation_of_equinoxes(&self) -> f64 {
        let om = self.moon_node_rad;
        self.dpsi_rad * self.mean_obliquity_rad.cos()
            + (0.002_64 * om.sin() + 0.000_063 * (2.0 * om).sin()) * ARCSEC
    }
}

/// Greenwich mean sidereal time, IAU 1982 (Aoki et al.), rad in [0, 2π), with UT1 = UTC.
pub fn gmst82(t: Epoch) -> f64 {
    let tu = centuries_ut1(t);
    // Seconds of time; 876600 h × 3600 s is the whole-day part of the linear rate.
    let seconds =
        67_310.548_41 + (876_600.0 * 3600.0 + 8_640_184.812_866) * tu + 0.093_104 * tu * tu
            - 6.2e-6 * tu * tu * tu;
    (seconds.rem_euclid(86_400.0) / 86_400.0 * std::f64::consts::TAU)
        .rem_euclid(std::f64::consts::TAU)
}

/// Greenwich apparent sidereal time, rad: GMST82 plus the equation of the equinoxes.
pub fn gast(t: Epoch) -> f64 {
    gmst82(t) + nutation_iau80(t).equation_of_equinoxes()
}

/// GCRF -> true equator and equinox of date: N · P · B.
pub fn gcrf_to_tod(t: Epoch) -> Matrix3<f64> {
    nutation_iau80(t).matrix() * precession_iau76(t) * frame_bias()
}

/// GCRF -> Earth-fixed (ITRF with polar motion ignored): `v_itrf = R v_gcrf`.
///
/// R = R3(GAST) · N · P · B with UT1 = UTC. Against an IAU 2006/2000A chain with the true
/// UT1 (skyfield, `igrf_frames.csv`) the direction error is dominated by UT1 − UTC
/// (≤ 0.9 s, ≤ 0.004°); see the crate docs for the measured sizes.
pub fn gcrf_to_itrf(t: Epoch) -> Matrix3<f64> {
    let nut = nutation_iau80(t);
    let gast = gmst82(t) + nut.equation_of_equinoxes();
    rot3(gast) * nut.matrix() * precession_iau76(t) * frame_bias()
}

/// TEME (the SGP4 output frame) -> GCRF: `v_gcrf = M v_teme`.
///
/// M = Bᵀ · Pᵀ · Nᵀ · R3(GMST82 − GAST): TEME shares the true equator of date and has its x
/// axis on the mean equinox, so it differs from true-of-date by the equation of the
/// equinoxes about z. Velocities rotate with the same matrix (TEME is treated as
/// quasi-inertial, no ω × r term), as in the reference table.
pub fn teme_to_gcrf(t: Epoch) -> Matrix3<f64> {
    let nut = nutation_iau80(t);
    let teme_to_tod = rot3(-nut.equation_of_equinoxes());
    (nut.matrix() * precession_iau76(t) * frame_bias()).transpose() * teme_to_tod
}

#[cfg(test)]
mod tests {
    use super::*;

    fn orthonormal_error(m: &Matrix3<f64>) -> f64 {
        (m * m.transpose() - Matrix3::identity()).abs().max()
    }

    #[test]
    fn rotations_are_proper_and_orthonormal() {
        let t = Epoch::from_gregorian_utc(2011, 11, 4, 18, 29, 45, 0);
        for m in [
            gcrf_to_itrf(t),
            teme_to_gcrf(t),
            frame_bias(),
            precession_iau76(t),
        ] {
            // 1e-14: a product of a few exact rotations in f64.
            assert!(orthonormal_error(&m) < 1e-14);
            assert!((m.determinant() - 1.0).abs() < 1e-14);
        }
    }

    #[test]
    fn rot3_turns_the_frame_not_the_vector() {
        // A frame turned +90 deg about z sees the old x axis at -y.
        let v = rot3(std::f64::consts::FRAC_PI_2) * nalgebra::Vector3::x();
        assert!((v - nalgebra::Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-15);
    }

    #[test]
    fn gmst_at_j2000_matches_the_iau82_constant() {
        // At 2000-01-01T12:00 UT1, GMST82 = 67310.54841 s = 280.46061837 deg (Vallado Ex. 3-5
        // quotes 280.4606°); UT1 = UTC here, 1e-9 deg is rounding.
        let t = Epoch::from_gregorian_utc(2000, 1, 1, 12, 0, 0, 0);
        let deg = gmst82(t).to_degrees();
        assert!((deg - 67_310.548_41 / 240.0).abs() < 1e-9, "{deg}");
    }

    #[test]
    fn nutation_is_of_the_expected_size() {
        // The 18.6-year term dominates: |Δψ| ≤ 17.2″ + 1.3″ + …, |Δε| ≤ 9.2″ + 0.6″ + … .
        let t = Epoch::from_gregorian_utc(2011, 11, 4, 0, 0, 0, 0);
        let n = nutation_iau80(t);
        assert!(n.dpsi_rad.abs() / ARCSEC < 19.5);
        assert!(n.deps_rad.abs() / ARCSEC < 10.5);
        assert!((n.mean_obliquity_rad.to_degrees() - 23.438).abs() < 0.01);
    }
}
