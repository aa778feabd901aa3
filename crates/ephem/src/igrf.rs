//! IGRF-14 main-field synthesis: spherical harmonics to degree 13, with secular variation.
//!
//! # Why this is hand-written
//! No well-kept IGRF crate exists for Rust. The one on crates.io, `igrf` 0.2.0 (2021), is a port
//! of the NOAA C code. It ships IGRF-13 only, and its README says "Not well tested, needs another
//! improvement pass to get rid off possible index out of bounds panics". Its time convention
//! (decimal years) also differs from the reference tables (see below). A degree-13 synthesis is
//! about a hundred lines, so it is written here and checked against ppigrf 2.1.0
//! (`fixtures/reference/igrf.csv`) and against finite differences of its own potential.
//!
//! # Model and conventions
//! - Coefficients: `fixtures/igrf/IGRF14.shc`, embedded with `include_str!` and parsed by
//!   [`Igrf::igrf14`]. It holds IGRF 1900-1940, DGRF 1945-2020, IGRF 2025 and a 2030 column
//!   that equals the 2025 value plus 5 years of the IGRF-14 secular variation.
//! - Gauss coefficients g_n^m, h_n^m in nT, Schmidt semi-normalised, no Condon-Shortley phase.
//!   Reference radius a = 6371.2 km.
//! - Potential: V = a Σ_n (a/r)^(n+1) Σ_m (g_n^m cos mφ + h_n^m sin mφ) P_n^m(cos θ), with
//!   geocentric radius r, colatitude θ and east longitude φ. The field is **B = −∇V**.
//! - Time: model epoch Y.0 is Y-01-01T00:00 UTC, and coefficients are linear in elapsed time
//!   between neighbouring epochs (ppigrf's convention). From 2025 to 2030 this is the
//!   secular-variation extrapolation. Outside 1900-01-01 to 2030-01-01 the model refuses
//!   ([`IgrfError::OutOfRange`]). Decimal-year interpolation would shift the field by up to
//!   0.21 nT; hifitime counts leap seconds in the elapsed time and ppigrf does not, which moves
//!   the interpolation weight by < 1e-8 (negligible).
//! - Output components: B_r radial out, B_θ towards increasing colatitude (**south**), B_φ east,
//!   all in nT. [`Igrf::field_ecef_nt`] returns the same vector in ECEF (ITRF) axes, and
//!   [`Igrf::field_gcrf_nt`] takes a GCRF position and returns the field in GCRF, rotating
//!   with [`crate::frames::gcrf_to_itrf`] both ways.
//!
//! # Pole safety
//! B_φ = −1/(r sin θ) ∂V/∂φ contains P_n^m / sin θ. Rather than dividing, the synthesis runs
//! the same three-term recursion on Q_n^m = P_n^m / sin θ, seeded with Q_m^m ∝ sin^(m−1) θ, and
//! differentiates the recursion for dP_n^m/dθ. Nothing divides by sin θ, so the field is finite
//! and continuous up to and at the poles (where ECEF longitude is taken as 0).
//!
//! # Symbols
//! | symbol | name in code | unit |
//! |---|---|---|
//! | a | `REFERENCE_RADIUS_KM` | km |
//! | g_n^m, h_n^m | `GaussCoefficients::g`, `GaussCoefficients::h` | nT |
//! | P_n^m, dP_n^m/dθ, P_n^m/sin θ | `Legendre::p`, `dp`, `p_over_sin` | 1 |
//! | V | `potential_nt_km` | nT km |
//! | B_r, B_θ, B_φ | `field_spherical_nt` | nT |

use hifitime::Epoch;
use nalgebra::Vector3;

/// Highest degree (and order) of IGRF-14.
pub const N_MAX: usize = 13;

/// The IGRF reference radius a (km).
pub const REFERENCE_RADIUS_KM: f64 = 6371.2;

/// Side of the fixed `[n][m]` tables, n and m in 0..=N_MAX.
const N_SIZE: usize = N_MAX + 1;

/// A `[n][m]` table of one quantity per degree and order.
type Table = [[f64; N_SIZE]; N_SIZE];

const ZERO_TABLE: Table = [[0.0; N_SIZE]; N_SIZE];

/// The IGRF-14 coefficient file, embedded at build time.
const IGRF14_SHC: &str = include_str!("../../../fixtures/igrf/IGRF14.shc");

/// Errors of the IGRF model: a bad coefficient file, a time outside the model, or a position
/// where the synthesis is undefined.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IgrfError {
    /// The SHC text could not be parsed.
    #[error("SHC coefficient file, line {line}: {reason}")]
    Parse {
        /// 1-based line number in the SHC text (0 when the problem is the whole file).
        line: usize,
        /// What was wrong.
        reason: String,
    },
    /// The requested time lies outside the model's epochs.
    #[error("time {t} is outside the IGRF validity {first} to {last}")]
    OutOfRange {
        /// The requested time.
        t: Epoch,
        /// The first model epoch.
        first: Epoch,
        /// The last model epoch (the end of the secular-variation extrapolation).
        last: Epoch,
    },
    /// The position is not a finite point outside the origin with colatitude in [0, π].
    #[error(
        "invalid position r = {r_km} km, colatitude = {colat_rad} rad, longitude = {lon_rad} rad"
    )]
    InvalidPosition {
        /// Geocentric radius (km).
        r_km: f64,
        /// Geocentric colatitude (rad).
        colat_rad: f64,
        /// East longitude (rad).
        lon_rad: f64,
    },
}

/// Gauss coefficients of one model snapshot, in nT, indexed `[n][m]`.
#[derive(Debug, Clone, PartialEq)]
pub struct GaussCoefficients {
    /// g_n^m (nT); entries with m > n or n = 0 are zero.
    pub g: [[f64; N_MAX + 1]; N_MAX + 1],
    /// h_n^m (nT); entries with m = 0, m > n or n = 0 are zero.
    pub h: [[f64; N_MAX + 1]; N_MAX + 1],
}

/// One model epoch of the coefficient file.
#[derive(Debug, Clone)]
struct Snapshot {
    epoch: Epoch,
    coeffs: GaussCoefficients,
}

/// The IGRF model: coefficient snapshots at the model epochs, interpolated linearly in elapsed
/// time (see the module docs).
#[derive(Debug, Clone)]
pub struct Igrf {
    snapshots: Vec<Snapshot>,
}

impl Igrf {
    /// IGRF-14 from the embedded `IGRF14.shc`. Errors only if the embedded file is corrupt
    /// (a test guards that it parses).
    pub fn igrf14() -> Result<Self, IgrfError> {
        Self::from_shc(IGRF14_SHC)
    }

    /// Parses a model in SHC format (comment lines `#`; a header `N_min N_max n_epochs
    /// spline_order step first last`; a line of epochs in whole years; then one line
    /// `n m c_1 .. c_k` per coefficient, m < 0 meaning h_n^|m|). Only N_min = 1, N_max ≤ 13
    /// and spline order 2 (piecewise linear) are accepted.
    pub fn from_shc(text: &str) -> Result<Self, IgrfError> {
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim()))
            .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
        let (header_line, header) = lines.next().ok_or_else(|| parse_err(0, "no header line"))?;
        let n_max = parse_header(header_line, header)?;
        let (epoch_line, epoch_text) = lines
            .next()
            .ok_or_else(|| parse_err(0, "no line of epochs"))?;
        let epochs = parse_epochs(epoch_line, epoch_text)?;
        let mut snapshots: Vec<Snapshot> = epochs
            .iter()
            .map(|&epoch| Snapshot {
                epoch,
                coeffs: GaussCoefficients {
                    g: ZERO_TABLE,
                    h: ZERO_TABLE,
                },
            })
            .collect();
        let mut seen = [[[false; 2]; N_SIZE]; N_SIZE];
        let mut count = 0;
        for (line, text) in lines {
            parse_coefficient_line(line, text, &mut snapshots, &mut seen, n_max)?;
            count += 1;
        }
        let expected = n_max * (n_max + 2);
        if count != expected {
            return Err(parse_err(
                0,
                format!("{count} coefficient lines, expected {expected} for N_max = {n_max}"),
            ));
        }
        Ok(Self { snapshots })
    }

    /// First model epoch (1900-01-01 UTC for IGRF-14).
    pub fn first_epoch(&self) -> Epoch {
        self.snapshots[0].epoch
    }

    /// Last valid time (2030-01-01 UTC for IGRF-14).
    pub fn last_epoch(&self) -> Epoch {
        self.snapshots[self.snapshots.len() - 1].epoch
    }

    /// Gauss coefficients at time `t`, linear in elapsed time between the neighbouring model
    /// epochs.
    pub fn coefficients_at(&self, t: Epoch) -> Result<GaussCoefficients, IgrfError> {
        let (first, last) = (self.first_epoch(), self.last_epoch());
        if !(t >= first && t <= last) {
            return Err(IgrfError::OutOfRange { t, first, last });
        }
        // `from_shc` guarantees at least two strictly increasing epochs.
        let k = self
            .snapshots
            .windows(2)
            .position(|w| t <= w[1].epoch)
            .unwrap_or(self.snapshots.len() - 2);
        let (s0, s1) = (&self.snapshots[k], &self.snapshots[k + 1]);
        let w = (t - s0.epoch).to_seconds() / (s1.epoch - s0.epoch).to_seconds();
        let mut out = GaussCoefficients {
            g: ZERO_TABLE,
            h: ZERO_TABLE,
        };
        for n in 1..=N_MAX {
            for m in 0..=n {
                out.g[n][m] = (1.0 - w) * s0.coeffs.g[n][m] + w * s1.coeffs.g[n][m];
                out.h[n][m] = (1.0 - w) * s0.coeffs.h[n][m] + w * s1.coeffs.h[n][m];
            }
        }
        Ok(out)
    }

    /// Field (nT) at geocentric radius `r_km`, colatitude `colat_rad` and east longitude
    /// `lon_rad`, as `[B_r (out), B_θ (south), B_φ (east)]`.
    pub fn field_spherical_nt(
        &self,
        r_km: f64,
        colat_rad: f64,
        lon_rad: f64,
        t: Epoch,
    ) -> Result<[f64; 3], IgrfError> {
        self.coefficients_at(t)?
            .field_spherical_nt(r_km, colat_rad, lon_rad)
    }

    /// Magnetic potential V (nT km) at a geocentric point; B = −∇V.
    pub fn potential_nt_km(
        &self,
        r_km: f64,
        colat_rad: f64,
        lon_rad: f64,
        t: Epoch,
    ) -> Result<f64, IgrfError> {
        self.coefficients_at(t)?
            .potential_nt_km(r_km, colat_rad, lon_rad)
    }

    /// Field (nT) in ECEF (ITRF) axes at the ECEF position `r_ecef_km`.
    pub fn field_ecef_nt(
        &self,
        r_ecef_km: &Vector3<f64>,
        t: Epoch,
    ) -> Result<Vector3<f64>, IgrfError> {
        self.coefficients_at(t)?.field_ecef_nt(r_ecef_km)
    }

    /// Field (nT) in GCRF axes at the GCRF position `r_gcrf_km`: B_gcrf = Rᵀ B_ecef(R r_gcrf)
    /// with R = [`crate::frames::gcrf_to_itrf`] (IAU-76/FK5, UT1 = UTC, no polar motion).
    pub fn field_gcrf_nt(
        &self,
        r_gcrf_km: &Vector3<f64>,
        t: Epoch,
    ) -> Result<Vector3<f64>, IgrfError> {
        let gcrf_to_itrf = crate::frames::gcrf_to_itrf(t);
        let b_ecef = self.field_ecef_nt(&(gcrf_to_itrf * r_gcrf_km), t)?;
        Ok(gcrf_to_itrf.transpose() * b_ecef)
    }
}

impl GaussCoefficients {
    /// Field (nT) as `[B_r (out), B_θ (south), B_φ (east)]`: the gradient of
    /// [`Self::potential_nt_km`] taken analytically term by term,
    /// B_r = −∂V/∂r, B_θ = −(1/r) ∂V/∂θ, B_φ = −1/(r sin θ) ∂V/∂φ.
    pub fn field_spherical_nt(
        &self,
        r_km: f64,
        colat_rad: f64,
        lon_rad: f64,
    ) -> Result<[f64; 3], IgrfError> {
        check_position(r_km, colat_rad, lon_rad)?;
        let leg = Legendre::new(colat_rad);
        let (cos_m, sin_m) = harmonics(lon_rad);
        let ratio = REFERENCE_RADIUS_KM / r_km;
        // (a/r)^(n+2), starting at n = 1.
        let mut radial = ratio * ratio * ratio;
        let (mut b_r, mut b_theta, mut b_phi) = (0.0, 0.0, 0.0);
        for n in 1..=N_MAX {
            let (mut sum_r, mut sum_theta, mut sum_phi) = (0.0, 0.0, 0.0);
            for m in 0..=n {
                let (g, h) = (self.g[n][m], self.h[n][m]);
                let even = g * cos_m[m] + h * sin_m[m];
                sum_r += even * leg.p[n][m];
                sum_theta += even * leg.dp[n][m];
                if m > 0 {
                    sum_phi += m as f64 * (g * sin_m[m] - h * cos_m[m]) * leg.p_over_sin[n][m];
                }
            }
            b_r += (n + 1) as f64 * radial * sum_r;
            b_theta -= radial * sum_theta;
            b_phi += radial * sum_phi;
            radial *= ratio;
        }
        Ok([b_r, b_theta, b_phi])
    }

    /// Magnetic potential V (nT km), V = a Σ (a/r)^(n+1) Σ (g cos mφ + h sin mφ) P_n^m.
    pub fn potential_nt_km(
        &self,
        r_km: f64,
        colat_rad: f64,
        lon_rad: f64,
    ) -> Result<f64, IgrfError> {
        check_position(r_km, colat_rad, lon_rad)?;
        let leg = Legendre::new(colat_rad);
        let (cos_m, sin_m) = harmonics(lon_rad);
        let ratio = REFERENCE_RADIUS_KM / r_km;
        let mut radial = ratio * ratio;
        let mut v = 0.0;
        for n in 1..=N_MAX {
            let sum: f64 = (0..=n)
                .map(|m| (self.g[n][m] * cos_m[m] + self.h[n][m] * sin_m[m]) * leg.p[n][m])
                .sum();
            v += radial * sum;
            radial *= ratio;
        }
        Ok(REFERENCE_RADIUS_KM * v)
    }

    /// Field (nT) in ECEF axes at the ECEF position `r_ecef_km`:
    /// B = B_r r̂ + B_θ θ̂ + B_φ φ̂. On the polar axis the longitude is taken as 0, where the
    /// pole-safe synthesis still gives the limit of the field.
    pub fn field_ecef_nt(&self, r_ecef_km: &Vector3<f64>) -> Result<Vector3<f64>, IgrfError> {
        let r_km = r_ecef_km.norm();
        let rho_km = r_ecef_km.x.hypot(r_ecef_km.y);
        let colat = rho_km.atan2(r_ecef_km.z);
        let lon = r_ecef_km.y.atan2(r_ecef_km.x);
        let [b_r, b_theta, b_phi] = self.field_spherical_nt(r_km, colat, lon)?;
        let (sin_t, cos_t) = colat.sin_cos();
        let (sin_p, cos_p) = lon.sin_cos();
        let r_hat = Vector3::new(sin_t * cos_p, sin_t * sin_p, cos_t);
        let theta_hat = Vector3::new(cos_t * cos_p, cos_t * sin_p, -sin_t);
        let phi_hat = Vector3::new(-sin_p, cos_p, 0.0);
        Ok(r_hat * b_r + theta_hat * b_theta + phi_hat * b_phi)
    }
}

/// Schmidt semi-normalised associated Legendre functions of cos θ (no Condon-Shortley phase),
/// their θ-derivatives, and P_n^m / sin θ for m ≥ 1, all without dividing by sin θ.
struct Legendre {
    p: Table,
    dp: Table,
    p_over_sin: Table,
}

impl Legendre {
    fn new(colat_rad: f64) -> Self {
        let (s, c) = colat_rad.sin_cos();
        let mut p = ZERO_TABLE;
        let mut dp = ZERO_TABLE;
        let mut q = ZERO_TABLE;
        p[0][0] = 1.0;
        for m in 1..=N_MAX {
            // Diagonal: P_m^m = k_m sin θ P_{m-1}^{m-1}, k_1 = 1, k_m = √((2m−1)/(2m)).
            let k = if m == 1 {
                1.0
            } else {
                ((2 * m - 1) as f64 / (2 * m) as f64).sqrt()
            };
            p[m][m] = k * s * p[m - 1][m - 1];
            dp[m][m] = k * (c * p[m - 1][m - 1] + s * dp[m - 1][m - 1]);
            // Q_m^m = P_m^m / sin θ = k_m sin θ Q_{m-1}^{m-1}, with Q_1^1 = 1.
            q[m][m] = if m == 1 { 1.0 } else { k * s * q[m - 1][m - 1] };
        }
        for m in 0..N_MAX {
            for n in (m + 1)..=N_MAX {
                // P_n^m = [(2n−1) cos θ P_{n−1}^m − √((n−1)²−m²) P_{n−2}^m] / √(n²−m²);
                // linear in P, so Q = P / sin θ obeys the same recursion.
                let a = (2 * n - 1) as f64;
                let b = (((n - 1) * (n - 1) - m * m) as f64).sqrt();
                let d = ((n * n - m * m) as f64).sqrt();
                let (p1, dp1, q1) = (p[n - 1][m], dp[n - 1][m], q[n - 1][m]);
                let (p2, dp2, q2) = if n >= m + 2 {
                    (p[n - 2][m], dp[n - 2][m], q[n - 2][m])
                } else {
                    (0.0, 0.0, 0.0)
                };
                p[n][m] = (a * c * p1 - b * p2) / d;
                dp[n][m] = (a * (c * dp1 - s * p1) - b * dp2) / d;
                q[n][m] = (a * c * q1 - b * q2) / d;
            }
        }
        Self {
            p,
            dp,
            p_over_sin: q,
        }
    }
}

/// cos mφ and sin mφ for m = 0..=N_MAX.
fn harmonics(lon_rad: f64) -> ([f64; N_SIZE], [f64; N_SIZE]) {
    let mut cos_m = [0.0; N_SIZE];
    let mut sin_m = [0.0; N_SIZE];
    for m in 0..N_SIZE {
        let (s, c) = (m as f64 * lon_rad).sin_cos();
        cos_m[m] = c;
        sin_m[m] = s;
    }
    (cos_m, sin_m)
}

fn check_position(r_km: f64, colat_rad: f64, lon_rad: f64) -> Result<(), IgrfError> {
    let ok = r_km.is_finite()
        && r_km > 0.0
        && (0.0..=std::f64::consts::PI).contains(&colat_rad)
        && lon_rad.is_finite();
    if ok {
        Ok(())
    } else {
        Err(IgrfError::InvalidPosition {
            r_km,
            colat_rad,
            lon_rad,
        })
    }
}

fn parse_err(line: usize, reason: impl Into<String>) -> IgrfError {
    IgrfError::Parse {
        line,
        reason: reason.into(),
    }
}

fn parse_number<T: std::str::FromStr>(line: usize, field: &str) -> Result<T, IgrfError> {
    field
        .parse()
        .map_err(|_| parse_err(line, format!("`{field}` is not a number")))
}

/// Checks the header and returns N_max.
fn parse_header(line: usize, text: &str) -> Result<usize, IgrfError> {
    let fields: Vec<&str> = text.split_whitespace().collect();
    if fields.len() < 5 {
        return Err(parse_err(
            line,
            "header needs N_min N_max n_epochs order step",
        ));
    }
    let n_min: usize = parse_number(line, fields[0])?;
    let n_max: usize = parse_number(line, fields[1])?;
    let order: usize = parse_number(line, fields[3])?;
    if n_min != 1 || n_max == 0 || n_max > N_MAX {
        return Err(parse_err(
            line,
            format!("degrees {n_min}..{n_max} not within 1..{N_MAX} starting at 1"),
        ));
    }
    if order != 2 {
        return Err(parse_err(
            line,
            format!("spline order {order}; only 2 (piecewise linear) is supported"),
        ));
    }
    Ok(n_max)
}

/// Parses the epoch line: whole years, strictly increasing, at least two.
fn parse_epochs(line: usize, text: &str) -> Result<Vec<Epoch>, IgrfError> {
    let mut epochs = Vec::new();
    for field in text.split_whitespace() {
        let year: f64 = parse_number(line, field)?;
        if year.fract() != 0.0 || !(1000.0..=9999.0).contains(&year) {
            return Err(parse_err(
                line,
                format!("epoch `{field}` is not a whole year"),
            ));
        }
        let epoch = Epoch::from_gregorian_utc_at_midnight(year as i32, 1, 1);
        if epochs.last().is_some_and(|&last| epoch <= last) {
            return Err(parse_err(line, "epochs are not strictly increasing"));
        }
        epochs.push(epoch);
    }
    if epochs.len() < 2 {
        return Err(parse_err(line, "fewer than two epochs"));
    }
    Ok(epochs)
}

/// Parses one `n m c_1 .. c_k` line into the snapshots.
fn parse_coefficient_line(
    line: usize,
    text: &str,
    snapshots: &mut [Snapshot],
    seen: &mut [[[bool; 2]; N_SIZE]; N_SIZE],
    n_max: usize,
) -> Result<(), IgrfError> {
    let fields: Vec<&str> = text.split_whitespace().collect();
    if fields.len() != snapshots.len() + 2 {
        return Err(parse_err(
            line,
            format!(
                "{} fields, expected n, m and {} values",
                fields.len(),
                snapshots.len()
            ),
        ));
    }
    let n: i64 = parse_number(line, fields[0])?;
    let m: i64 = parse_number(line, fields[1])?;
    let (nu, mu) = (n.unsigned_abs() as usize, m.unsigned_abs() as usize);
    if n < 1 || nu > n_max || mu > nu {
        return Err(parse_err(line, format!("(n, m) = ({n}, {m}) out of range")));
    }
    let is_h = usize::from(m < 0);
    if seen[nu][mu][is_h] {
        return Err(parse_err(line, format!("(n, m) = ({n}, {m}) repeated")));
    }
    seen[nu][mu][is_h] = true;
    for (snapshot, field) in snapshots.iter_mut().zip(&fields[2..]) {
        let value: f64 = parse_number(line, field)?;
        if is_h == 1 {
            snapshot.coeffs.h[nu][mu] = value;
        } else {
            snapshot.coeffs.g[nu][mu] = value;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_file_parses_with_27_epochs() {
        let model = Igrf::igrf14().expect("embedded IGRF-14 parses");
        assert_eq!(model.snapshots.len(), 27);
        assert_eq!(model.snapshots[25].coeffs.g[1][0], -29350.0);
        assert_eq!(model.snapshots[26].coeffs.h[1][1], 4438.0);
    }

    #[test]
    fn bad_text_gives_typed_errors() {
        assert!(matches!(Igrf::from_shc(""), Err(IgrfError::Parse { .. })));
        let truncated = "1 1 2 2 1 2000.0 2005.0\n 2000.0 2005.0\n 1 0 -1 -2\n";
        assert!(matches!(
            Igrf::from_shc(truncated),
            Err(IgrfError::Parse { .. })
        ));
        let bad_number = "1 1 2 2 1 2000.0 2005.0\n 2000.0 2005.0\n 1 0 x 1\n 1 1 1 1\n 1 -1 1 1\n";
        assert!(matches!(
            Igrf::from_shc(bad_number),
            Err(IgrfError::Parse { line: 3, .. })
        ));
    }

    #[test]
    fn legendre_matches_closed_forms() {
        // Schmidt semi-normalised: P_1^0 = cos, P_1^1 = sin, P_2^0 = (3cos²−1)/2,
        // P_2^1 = √3 cos sin, P_2^2 = (√3/2) sin².
        let theta: f64 = 0.7;
        let (s, c) = theta.sin_cos();
        let leg = Legendre::new(theta);
        let close = |x: f64, y: f64| (x - y).abs() < 1e-14;
        assert!(close(leg.p[1][0], c));
        assert!(close(leg.p[1][1], s));
        assert!(close(leg.p[2][0], 1.5 * c * c - 0.5));
        assert!(close(leg.p[2][1], 3f64.sqrt() * c * s));
        assert!(close(leg.p[2][2], 3f64.sqrt() / 2.0 * s * s));
        assert!(close(leg.dp[2][1], 3f64.sqrt() * (c * c - s * s)));
        assert!(close(leg.p_over_sin[2][1], 3f64.sqrt() * c));
    }
}
