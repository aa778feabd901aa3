//! Mountings and polarities the data contradict, found before the filter runs.
//!
//! The filter linearises each photodiode's measurement about its nominal normal with a
//! prior of [`FilterConfig::initial_normal_sigma_deg`] per axis; a normal given off by
//! 180 deg (a sign slip in a mounting table) or a photodiode wired with reversed polarity
//! (negative outputs in the Sun) is far outside what that linearisation can pull in: the
//! scale factor is driven negative or the photodiode is counted never lit. Revealing such
//! errors is what on-orbit calibration is for, so they are findings, not failures.
//!
//! For each photodiode the Sun direction in the body frame is estimated at sampled sunlit
//! rows from the *other* photodiodes (the least-squares Sun vector of
//! `pdcal_photodiode::estimate_sun_vector`, nominal normals, maximum outputs as scale
//! factors, back-facing photodiodes dropped), and the photodiode's strong outputs are
//! regressed on it: `y_k / F_k = g^T s_k` (paper Eq. 15 without albedo, `F` the Sun's
//! distance factor). `g / |g|` is the normal the data support and `|g|` its scale factor.
//! Only outputs above [`STRONG_FRACTION`] of the photodiode's peak enter, and, with the
//! albedo model, only outputs above the largest albedo any attitude could give at that row
//! (the photodiode's scale, its peak or the lit photodiodes' median peak whichever is
//! larger, times the sum over the lit cells in view, `AlbedoView::max_ratio`), in the Sun
//! vectors as in the regression: a face that rarely sees the Sun reads albedo at a third
//! of its peak and more, and a regression on it finds the Earth's side, not its normal. A photodiode whose strong outputs
//! are negative is fitted on the negated outputs, and is a polarity finding when that fit
//! explains them ([`MIN_EXPLAINED`]); a normal more than [`finding_angle_deg`] from the
//! nominal one is a mounting finding. Photodiodes with a finding are left out of the Sun
//! vectors and every fit is repeated once, so one wrong photodiode does not bend the
//! others' fits.
//!
//! [`apply`] then calibrates from what the data say: the supported normal replaces the
//! nominal one and a reversed photodiode's outputs are negated (or, when the data give no
//! direction, the photodiode is left out, with that reason).

use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use pdcal_albedo::{AlbedoModel, AlbedoView};
use pdcal_attitude::{az_el_from_normal, normal_from_az_el};
use pdcal_dataset::{DatasetMeta, Telemetry};
use pdcal_photodiode::{Photodiode, SunEstimate, SunVectorOptions, estimate_sun_vector};
use serde::Serialize;

use crate::references::albedo_into;
use crate::{FilterConfig, FilterError, References};

/// Most rows the check samples (evenly spread): enough for thousands of strong outputs
/// per photodiode over any number of orbits, few enough to cost a fraction of the run.
pub const MAX_SAMPLED_ROWS: usize = 20_000;

/// Outputs above this fraction of a photodiode's peak enter its regression.
pub const STRONG_FRACTION: f64 = 0.3;

/// Fewest strong outputs with an observable Sun vector a regression needs.
pub const MIN_SAMPLES: usize = 30;

/// Fraction of the strong outputs' sum of squares the regression must explain for a
/// finding (a fit of noise or of an unmodelled light explains little of it).
pub const MIN_EXPLAINED: f64 = 0.8;

/// Smallest eigenvalue of the mean `s s^T` of the regression's Sun directions for the
/// fitted normal to count as determined in all three axes (the Sun-vector least squares'
/// own bound, 0.1, on the singular value).
pub const MIN_DIRECTION_EIGENVALUE: f64 = 0.01;

/// Prior sigmas beyond which a normal is a finding, and the least angle that is.
pub const FINDING_SIGMAS: f64 = 5.0;
/// See [`FINDING_SIGMAS`]: the Sun vectors the regression uses are themselves uncalibrated
/// (about 10 deg off), so a smaller angle is not a reliable finding.
pub const MIN_FINDING_ANGLE_DEG: f64 = 30.0;

/// The angle between the nominal and the supported normal beyond which the nominal
/// mounting is a finding: [`FINDING_SIGMAS`] prior sigmas, at least
/// [`MIN_FINDING_ANGLE_DEG`].
pub fn finding_angle_deg(config: &FilterConfig) -> f64 {
    (FINDING_SIGMAS * config.initial_normal_sigma_deg).max(MIN_FINDING_ANGLE_DEG)
}

/// What the data say about one photodiode.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MountingFinding {
    /// 1-based photodiode index (`pdNN`).
    pub photodiode: usize,
    /// The outputs are negative in the Sun: the polarity is reversed.
    pub polarity_reversed: bool,
    /// dataset.ron's azimuth, deg.
    pub nominal_azimuth_deg: f64,
    /// dataset.ron's elevation, deg.
    pub nominal_elevation_deg: f64,
    /// The azimuth the data support, deg (absent when they give no direction).
    pub supported_azimuth_deg: Option<f64>,
    /// The elevation the data support, deg.
    pub supported_elevation_deg: Option<f64>,
    /// Angle between the nominal and the supported normal, deg.
    pub angle_deg: Option<f64>,
    /// The scale factor the regression gives, V (at 1 AU).
    pub supported_scale_v: f64,
    /// Strong outputs the regression used.
    pub samples: usize,
    /// What the calibration does about it ([`Action`]).
    pub action: Action,
}

/// What the calibration does with a finding.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Action {
    /// Calibrated from the supported normal (and the outputs negated when reversed).
    CalibratedFromSupported,
    /// Calibrated from its nominal normal with the outputs negated (the normal agrees).
    CalibratedNegated,
    /// Left out: the data contradict the nominal normal but do not fix another one.
    Excluded,
}

impl MountingFinding {
    /// One line for the printed output and `summary.json` `warnings`.
    pub fn message(&self) -> String {
        let pd = format!("pd{:02}", self.photodiode);
        let nominal = format!(
            "az {:.1}, el {:.1} deg",
            self.nominal_azimuth_deg, self.nominal_elevation_deg
        );
        let mut what = Vec::new();
        if self.polarity_reversed {
            what.push(format!(
                "its outputs are negative in the Sun (polarity reversed; {} strong samples)",
                self.samples
            ));
        }
        if let (Some(az), Some(el), Some(angle)) = (
            self.supported_azimuth_deg,
            self.supported_elevation_deg,
            self.angle_deg,
        ) && angle > 0.0
            && self.action != Action::CalibratedNegated
        {
            what.push(format!(
                "its outputs follow a normal at az {az:.1}, el {el:.1} deg, {angle:.0} deg from \
                 the nominal {nominal}"
            ));
        } else if self.action == Action::Excluded {
            what.push(format!(
                "its outputs contradict the nominal {nominal} but fix no other normal"
            ));
        }
        let action = match self.action {
            Action::CalibratedFromSupported if self.polarity_reversed => {
                "calibrated from that normal with its outputs negated"
            }
            Action::CalibratedFromSupported => "calibrated from that normal",
            Action::CalibratedNegated => "calibrated with its outputs negated",
            Action::Excluded => "left out of the calibration",
        };
        format!(
            "{pd}: the data contradict dataset.ron: {}; {action}",
            what.join("; ")
        )
    }
}

/// One photodiode's regression on the Sun directions.
#[derive(Debug, Clone, Copy)]
struct Fit {
    /// `g` of `y / F = g^T s`.
    g: Vector3<f64>,
    /// Strong outputs used.
    samples: usize,
    /// Fraction of their sum of squares explained.
    explained: f64,
    /// Smallest eigenvalue of the mean `s s^T`.
    min_eigenvalue: f64,
}

/// The sampled sunlit rows: distance factor and the outputs of every photodiode.
struct Sampled {
    factor: Vec<f64>,
    /// The telemetry row of each sampled row.
    rows: Vec<usize>,
    /// `outputs[k][i]`: photodiode `i` at sampled row `k` (NaN when not sampled).
    outputs: Vec<Vec<f64>>,
}

/// Finds the photodiodes whose data contradict their nominal mounting or polarity
/// (module doc). `pd_sigma_v` is the photodiode noise the filter uses.
pub fn check_mountings(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
    references: &References<'_>,
    config: &FilterConfig,
    pd_sigma_v: f64,
    albedo: Option<&AlbedoModel>,
) -> Result<Vec<MountingFinding>, FilterError> {
    let m = meta.photodiodes.len();
    if m < 4 || telemetry.is_empty() {
        return Ok(Vec::new());
    }
    let sampled = sample_rows(telemetry, references, config)?;
    let lit_v = config.min_lit_output_sigmas * pd_sigma_v;
    // Scale factors for the Sun vector: each photodiode's largest output of either sign
    // (a reversed one's magnitude is as good a guess as a normal one's).
    let peaks: Vec<f64> = (0..m)
        .map(|i| {
            (sampled.outputs.iter())
                .map(|row| row[i].abs())
                .filter(|y| y.is_finite())
                .fold(0.0, f64::max)
        })
        .collect();
    let nominal: Vec<Vector3<f64>> = meta
        .photodiodes
        .iter()
        .map(|p| normal_from_az_el(p.azimuth_deg.to_radians(), p.elevation_deg.to_radians()))
        .collect();
    let strong = strong_outputs(&peaks, lit_v);
    let albedo_ratio = match albedo {
        Some(model) => albedo_ratios(&sampled, &strong, references, model)?,
        None => vec![0.0; sampled.rows.len()],
    };
    let bounds = Bounds {
        strong,
        albedo_scale: albedo_scales(&peaks, lit_v),
        albedo_ratio,
    };
    let mut left_out = vec![false; m];
    let mut findings = Vec::new();
    // Two passes: the second without the photodiodes the first found wrong.
    for _ in 0..2 {
        let fits = fit_all(
            &sampled, &bounds, &nominal, &peaks, &left_out, lit_v, pd_sigma_v,
        )?;
        findings = (0..m)
            .filter_map(|i| judge(i, &fits[i], &nominal[i], meta, config))
            .collect::<Vec<_>>();
        let wrong: Vec<bool> = (0..m)
            .map(|i| findings.iter().any(|f| f.photodiode == i + 1))
            .collect();
        if wrong == left_out || !wrong.iter().any(|w| *w) {
            break;
        }
        left_out = wrong;
    }
    Ok(findings)
}

/// The finding of photodiode `i` from its fits (normal and reversed outputs), if any.
fn judge(
    i: usize,
    fits: &(Option<Fit>, Option<Fit>),
    nominal: &Vector3<f64>,
    meta: &DatasetMeta,
    config: &FilterConfig,
) -> Option<MountingFinding> {
    let (fit, reversed) = match fits {
        (_, Some(neg)) if neg.explained >= MIN_EXPLAINED => (neg, true),
        (Some(pos), _) => (pos, false),
        _ => return None,
    };
    if fit.explained < MIN_EXPLAINED {
        return None;
    }
    let mount = &meta.photodiodes[i];
    let determined = fit.min_eigenvalue >= MIN_DIRECTION_EIGENVALUE;
    let direction = fit.g.try_normalize(0.0)?;
    let angle_deg = direction.angle(nominal).to_degrees();
    // A direction the Sun directions do not fix in all axes can still contradict the
    // nominal one plainly: the photodiode is lit when the Sun is behind it.
    let contradicts = angle_deg > finding_angle_deg(config);
    let action = match (contradicts, determined) {
        (false, _) if reversed => Action::CalibratedNegated,
        (false, _) => return None,
        (true, true) => Action::CalibratedFromSupported,
        (true, false) if angle_deg > 90.0 => Action::Excluded,
        (true, false) if reversed => Action::CalibratedNegated,
        (true, false) => return None,
    };
    let (az, el) = az_el_from_normal(&direction);
    let given = action == Action::CalibratedFromSupported;
    Some(MountingFinding {
        photodiode: i + 1,
        polarity_reversed: reversed,
        nominal_azimuth_deg: mount.azimuth_deg,
        nominal_elevation_deg: mount.elevation_deg,
        supported_azimuth_deg: given.then(|| az.to_degrees()),
        supported_elevation_deg: given.then(|| el.to_degrees()),
        angle_deg: given.then_some(angle_deg),
        supported_scale_v: fit.g.norm(),
        samples: fit.samples,
        action,
    })
}

/// Rows in full Sun, at most [`MAX_SAMPLED_ROWS`], evenly spread.
fn sample_rows(
    telemetry: &Telemetry,
    references: &References<'_>,
    config: &FilterConfig,
) -> Result<Sampled, FilterError> {
    let rows = telemetry.len();
    let stride = rows.div_ceil(MAX_SAMPLED_ROWS).max(1);
    let mut sampled = Sampled {
        factor: Vec::new(),
        rows: Vec::new(),
        outputs: Vec::new(),
    };
    for k in (0..rows).step_by(stride) {
        let outputs: Vec<f64> = (telemetry.pd_v.iter())
            .map(|col| col.get(k).unwrap_or(f64::NAN))
            .collect();
        if outputs.iter().all(|y| y.is_nan()) {
            continue;
        }
        let reference = references.at(k)?;
        if reference.sun_fraction < config.min_sun_fraction {
            continue;
        }
        sampled.factor.push(reference.sun_distance_factor());
        sampled.rows.push(k);
        sampled.outputs.push(outputs);
    }
    Ok(sampled)
}

/// Per photodiode, its regression on the Sun vectors of the photodiodes not `left_out`
/// (nor itself): on its positive strong outputs and on its negated negative ones.
#[allow(clippy::type_complexity)]
fn fit_all(
    sampled: &Sampled,
    bounds: &Bounds,
    nominal: &[Vector3<f64>],
    peaks: &[f64],
    left_out: &[bool],
    lit_v: f64,
    pd_sigma_v: f64,
) -> Result<Vec<(Option<Fit>, Option<Fit>)>, FilterError> {
    let m = nominal.len();
    let photodiodes: Vec<Photodiode> = nominal
        .iter()
        .zip(peaks)
        .map(|(n, &peak)| Photodiode {
            n_body: *n,
            scale_v: if peak > lit_v { peak } else { 1.0 },
            noise_v: pd_sigma_v,
            fov_half_angle_rad: None,
        })
        .collect();
    let mut accumulators = vec![[Accumulator::default(), Accumulator::default()]; m];
    let strong = &bounds.strong;
    let options = SunVectorOptions::default();
    let lit_sigmas = options.threshold.volts(pd_sigma_v);
    let mut others = vec![f64::NAN; m];
    for ((row, &factor), &ratio) in sampled
        .outputs
        .iter()
        .zip(&sampled.factor)
        .zip(&bounds.albedo_ratio)
    {
        let direct = |i: usize| row[i].abs() > bounds.albedo_scale[i] * ratio;
        if !(0..m).any(|i| row[i].abs() >= strong[i] && direct(i)) {
            continue;
        }
        for (i, o) in others.iter_mut().enumerate() {
            *o = if left_out[i] || peaks[i] <= lit_v || !direct(i) {
                f64::NAN
            } else {
                row[i]
            };
        }
        let options = SunVectorOptions {
            sun_distance_factor: factor,
            ..options
        };
        let estimate = estimate_sun_vector(&photodiodes, &others, None, &options)?;
        let SunEstimate::Observable(all) = estimate else {
            continue;
        };
        // The photodiodes that solution used (lit, facing it), as normal equations, so
        // that each one's own equation can be taken out (leave one out) in 3x3.
        let mut normal_matrix = Matrix3::zeros();
        let mut rhs = Vector3::zeros();
        let mut used = vec![None; m];
        let mut count = 0;
        for (i, pd) in photodiodes.iter().enumerate() {
            let y = others[i];
            if y > lit_sigmas && pd.n_body.dot(&all.direction_body) > 0.0 {
                let y = y / (factor * pd.scale_v);
                normal_matrix += pd.n_body * pd.n_body.transpose();
                rhs += pd.n_body * y;
                used[i] = Some(y);
                count += 1;
            }
        }
        for i in 0..m {
            let y = row[i];
            if y.is_nan() || y.abs() < strong[i] || !direct(i) {
                continue;
            }
            let s = match used[i] {
                None => Some(all.direction_body),
                Some(own) => {
                    let n = &photodiodes[i].n_body;
                    solve_direction(
                        &(normal_matrix - n * n.transpose()),
                        &(rhs - n * own),
                        count - 1,
                        options.min_singular_value,
                    )
                }
            };
            if let Some(s) = s {
                let side = usize::from(y < 0.0);
                accumulators[i][side].add(&s, y.abs() / factor);
            }
        }
    }
    Ok(accumulators
        .iter()
        .map(|[pos, neg]| (pos.fit(), neg.fit()))
        .collect())
}

/// Which outputs enter the regressions.
struct Bounds {
    /// Per photodiode, the least output of a regression ([`STRONG_FRACTION`] of its peak).
    strong: Vec<f64>,
    /// Per photodiode, its scale for the albedo bound ([`albedo_scales`]).
    albedo_scale: Vec<f64>,
    /// Per sampled row, the largest albedo ratio any attitude could give (0 without the
    /// albedo model, and at rows without a strong output, which no regression uses).
    albedo_ratio: Vec<f64>,
}

/// Per photodiode, the least output of a regression.
fn strong_outputs(peaks: &[f64], lit_v: f64) -> Vec<f64> {
    peaks
        .iter()
        .map(|&p| (STRONG_FRACTION * p).max(lit_v))
        .collect()
}

/// The largest albedo ratio at each sampled row with a strong output
/// (`AlbedoView::max_ratio`), 0 at the others.
fn albedo_ratios(
    sampled: &Sampled,
    strong: &[f64],
    references: &References<'_>,
    model: &AlbedoModel,
) -> Result<Vec<f64>, FilterError> {
    let mut view = AlbedoView::new();
    sampled
        .rows
        .iter()
        .zip(&sampled.outputs)
        .map(|(&k, row)| {
            if !row.iter().zip(strong).any(|(y, s)| y.abs() >= *s) {
                return Ok(0.0);
            }
            albedo_into(&references.at(k)?, model, &mut view, k)?;
            Ok(view.max_ratio())
        })
        .collect()
}

/// Each photodiode's scale for the albedo bound: its peak, or the median peak of the lit
/// photodiodes when larger (a photodiode that never faced the Sun peaks at albedo; the
/// photodiodes are assumed of one type, as the initial scales are,
/// [`crate::init::initial_scales`]).
fn albedo_scales(peaks: &[f64], lit_v: f64) -> Vec<f64> {
    let mut lit: Vec<f64> = peaks.iter().copied().filter(|&p| p > lit_v).collect();
    lit.sort_by(f64::total_cmp);
    let median = lit.get(lit.len() / 2).copied().unwrap_or(0.0);
    peaks.iter().map(|&p| p.max(median)).collect()
}

/// The unit Sun direction of the normal equations of `used` photodiodes, when observable
/// (at least 3, smallest singular value of the normals at least `min_singular_value`).
fn solve_direction(
    normal_matrix: &Matrix3<f64>,
    rhs: &Vector3<f64>,
    used: usize,
    min_singular_value: f64,
) -> Option<Vector3<f64>> {
    if used < 3 {
        return None;
    }
    let smallest = SymmetricEigen::new(*normal_matrix).eigenvalues.min();
    if smallest.is_nan() || smallest.max(0.0).sqrt() < min_singular_value {
        return None;
    }
    let s = normal_matrix.cholesky()?.solve(rhs);
    s.iter()
        .all(|x| x.is_finite())
        .then(|| s.try_normalize(0.0))
        .flatten()
}

/// Normal equations of one regression `y = g^T s`.
#[derive(Debug, Clone, Copy, Default)]
struct Accumulator {
    sst: Matrix3<f64>,
    sy: Vector3<f64>,
    yy: f64,
    n: usize,
}

impl Accumulator {
    fn add(&mut self, s: &Vector3<f64>, y: f64) {
        self.sst += s * s.transpose();
        self.sy += s * y;
        self.yy += y * y;
        self.n += 1;
    }

    fn fit(&self) -> Option<Fit> {
        if self.n < MIN_SAMPLES || self.yy <= 0.0 {
            return None;
        }
        let min_eigenvalue = SymmetricEigen::new(self.sst / self.n as f64)
            .eigenvalues
            .min();
        // Ridge-free where determined; otherwise the least-norm answer along the axes the
        // directions span, by the pseudo-inverse.
        let g = self.sst.pseudo_inverse(1e-9 * self.n as f64).ok()? * self.sy;
        // Residual sum of squares from the normal equations: yy - 2 g^T sy + g^T S g.
        let ssr = (self.yy - 2.0 * g.dot(&self.sy) + g.dot(&(self.sst * g))).max(0.0);
        Some(Fit {
            g,
            samples: self.n,
            explained: 1.0 - ssr / self.yy,
            min_eigenvalue,
        })
    }
}

/// Applies the findings: a supported normal replaces the nominal one, a reversed
/// photodiode's outputs are negated, an excluded photodiode's samples are blanked (it
/// then counts as never lit).
pub fn apply(findings: &[MountingFinding], meta: &mut DatasetMeta, telemetry: &mut Telemetry) {
    for f in findings {
        let i = f.photodiode - 1;
        let (Some(mount), Some(column)) = (meta.photodiodes.get_mut(i), telemetry.pd_v.get_mut(i))
        else {
            continue;
        };
        if let (Some(az), Some(el)) = (f.supported_azimuth_deg, f.supported_elevation_deg) {
            mount.azimuth_deg = az;
            mount.elevation_deg = el;
        }
        for k in 0..column.len() {
            match f.action {
                Action::Excluded => column.set(k, None),
                _ if f.polarity_reversed => {
                    if let Some(y) = column.get(k) {
                        column.set(k, Some(-y));
                    }
                }
                _ => {}
            }
        }
    }
}
