//! Reflectivity maps: parsing the shipped TOMS and CERES files into one internal layout.
//!
//! Internal layout (all maps): row `i` = latitude band from the south (centre
//! `-90 + (i + 1/2) * 180/n_lat` deg), column `j` = longitude band from -180 deg east-positive
//! (centre `-180 + (j + 1/2) * 360/n_lon` deg), value = reflectivity as a fraction in [0, 1].
//! This is Basilisk's `ALB[ilat][ilon]` and the CERES file orientation.

use std::fmt;
use std::str::FromStr;

use thiserror::Error;

/// TOMS mean reflectivity, 1.25 deg (lon) x 1 deg (lat); percent; line = longitude,
/// column = latitude north first (see `fixtures/albedo/README.md`).
const TOMS_MEAN_1P25X1: &str =
    include_str!("../../../fixtures/albedo/earthReflectivityMean_1p25x1.dat");
/// CERES 2018 all-sky albedo, 1 x 1 deg; fraction; row = latitude south first.
const CERES_1X1: &str = include_str!("../../../fixtures/albedo/Earth_ALB_2018_CERES_All_1x1.csv");
/// CERES 2018 all-sky albedo, 5 x 5 deg; fraction; row = latitude south first.
const CERES_5X5: &str = include_str!("../../../fixtures/albedo/Earth_ALB_2018_CERES_All_5x5.csv");

/// Reflectivity of the uniform map when `"uniform"` is given without a value (the value of the
/// reference table's `const03` map).
pub const DEFAULT_UNIFORM_ALBEDO: f64 = 0.3;

/// Errors from building or parsing a reflectivity map.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MapError {
    /// A field is not a number.
    #[error("{source_name}: line {line}, column {column}: cannot parse {text:?} as a number")]
    Parse {
        /// Which map text was being parsed.
        source_name: String,
        /// 1-based line number in the text.
        line: usize,
        /// 1-based field number in the line.
        column: usize,
        /// The offending field.
        text: String,
    },
    /// A line has the wrong number of fields, or the text the wrong number of lines.
    #[error("{source_name}: line {line}: expected {expected} fields, found {found}")]
    Shape {
        /// Which map text was being parsed.
        source_name: String,
        /// 1-based line number (0 when the line count is wrong).
        line: usize,
        /// Expected count (fields per line, or lines when `line` is 0).
        expected: usize,
        /// Count found.
        found: usize,
    },
    /// A value is outside [0, 1] after unit conversion, or not finite.
    #[error("{source_name}: line {line}, column {column}: reflectivity {value} outside [0, 1]")]
    OutOfRange {
        /// Which map text was being parsed.
        source_name: String,
        /// 1-based line number.
        line: usize,
        /// 1-based field number.
        column: usize,
        /// The converted value (fraction).
        value: f64,
    },
    /// A grid size of zero, an odd number of latitude bands or a uniform value outside [0, 1].
    #[error("invalid uniform map: {n_lat} x {n_lon} cells, value {value}")]
    InvalidUniform {
        /// Latitude bands.
        n_lat: usize,
        /// Longitude bands.
        n_lon: usize,
        /// Reflectivity.
        value: f64,
    },
    /// `MapChoice::from_str` got an id it does not know.
    #[error(
        "unknown albedo map {0:?}; expected toms-mean-1p25x1, ceres-1x1, ceres-5x5, uniform or uniform:<value>"
    )]
    UnknownMap(String),
}

/// A reflectivity map in the internal layout (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct ReflectivityMap {
    n_lat: usize,
    n_lon: usize,
    /// Row-major `values[i * n_lon + j]`, fraction.
    values: Vec<f64>,
}

impl ReflectivityMap {
    /// Number of latitude bands (rows).
    pub fn n_lat(&self) -> usize {
        self.n_lat
    }

    /// Number of longitude bands (columns).
    pub fn n_lon(&self) -> usize {
        self.n_lon
    }

    /// Reflectivity (fraction) of cell (row `i_lat` from the south, column `j_lon` from -180 deg).
    /// `None` outside the grid.
    pub fn get(&self, i_lat: usize, j_lon: usize) -> Option<f64> {
        (i_lat < self.n_lat && j_lon < self.n_lon).then(|| self.values[i_lat * self.n_lon + j_lon])
    }

    /// Row-major values (fraction), `values[i_lat * n_lon + j_lon]`.
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// A map with the same reflectivity `value` everywhere on `n_lat x n_lon` cells.
    pub fn uniform(n_lat: usize, n_lon: usize, value: f64) -> Result<Self, MapError> {
        if n_lat == 0 || n_lon == 0 || !(0.0..=1.0).contains(&value) {
            return Err(MapError::InvalidUniform {
                n_lat,
                n_lon,
                value,
            });
        }
        Ok(Self {
            n_lat,
            n_lon,
            values: vec![value; n_lat * n_lon],
        })
    }

    /// Parses a CERES-style CSV: one line per latitude band from the south, comma-separated
    /// fractions, one column per longitude band from -180 deg. `source_name` only labels errors.
    pub fn parse_ceres_csv(source_name: &str, text: &str) -> Result<Self, MapError> {
        let rows = parse_table(source_name, text, ',', 1.0)?;
        let n_lat = rows.len();
        let n_lon = rows.first().map_or(0, Vec::len);
        Ok(Self {
            n_lat,
            n_lon,
            values: rows.into_iter().flatten().collect(),
        })
    }

    /// Parses a TOMS `.dat`: one line per longitude band from -180 deg, space-separated
    /// percentages, one column per latitude band from the **north**. Converted to the internal
    /// layout: `refl[i_lat][i_lon] = dat[i_lon][n_lat - 1 - i_lat] / 100`.
    pub fn parse_toms_dat(source_name: &str, text: &str) -> Result<Self, MapError> {
        let lines = parse_table(source_name, text, ' ', 0.01)?;
        let n_lon = lines.len();
        let n_lat = lines.first().map_or(0, Vec::len);
        let mut values = vec![0.0; n_lat * n_lon];
        for (i_lon, line) in lines.iter().enumerate() {
            for (col, &v) in line.iter().enumerate() {
                values[(n_lat - 1 - col) * n_lon + i_lon] = v;
            }
        }
        Ok(Self {
            n_lat,
            n_lon,
            values,
        })
    }

    /// Block mean over `k_lat x k_lon` cells (unweighted, as the CERES 5x5 file is made from the
    /// 1x1 file). A coarse map for the onboard approximation. `None` when the factors do not
    /// divide the grid.
    pub fn coarsen(&self, k_lat: usize, k_lon: usize) -> Option<Self> {
        if k_lat == 0
            || k_lon == 0
            || !self.n_lat.is_multiple_of(k_lat)
            || !self.n_lon.is_multiple_of(k_lon)
        {
            return None;
        }
        let (n_lat, n_lon) = (self.n_lat / k_lat, self.n_lon / k_lon);
        let mut values = vec![0.0; n_lat * n_lon];
        for i in 0..self.n_lat {
            for j in 0..self.n_lon {
                values[(i / k_lat) * n_lon + j / k_lon] += self.values[i * self.n_lon + j];
            }
        }
        let scale = 1.0 / (k_lat * k_lon) as f64;
        values.iter_mut().for_each(|v| *v *= scale);
        Some(Self {
            n_lat,
            n_lon,
            values,
        })
    }
}

/// Splits `text` into lines of `sep`-separated numbers times `scale`, checking that every line
/// has as many fields as the first and every value is a fraction in [0, 1].
fn parse_table(
    source_name: &str,
    text: &str,
    sep: char,
    scale: f64,
) -> Result<Vec<Vec<f64>>, MapError> {
    let mut rows: Vec<Vec<f64>> = Vec::new();
    for (line_idx, line) in text.lines().enumerate() {
        let line_no = line_idx + 1;
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let fields = line
            .split(sep)
            .map(str::trim)
            .filter(|f| sep != ' ' || !f.is_empty());
        let mut row = Vec::with_capacity(rows.first().map_or(0, Vec::len));
        for (col_idx, field) in fields.enumerate() {
            let column = col_idx + 1;
            let raw: f64 = field.parse().map_err(|_| MapError::Parse {
                source_name: source_name.to_owned(),
                line: line_no,
                column,
                text: field.to_owned(),
            })?;
            let value = raw * scale;
            if !(0.0..=1.0).contains(&value) {
                return Err(MapError::OutOfRange {
                    source_name: source_name.to_owned(),
                    line: line_no,
                    column,
                    value,
                });
            }
            row.push(value);
        }
        if let Some(first) = rows.first()
            && first.len() != row.len()
        {
            return Err(MapError::Shape {
                source_name: source_name.to_owned(),
                line: line_no,
                expected: first.len(),
                found: row.len(),
            });
        }
        rows.push(row);
    }
    if rows.is_empty() || rows[0].is_empty() {
        return Err(MapError::Shape {
            source_name: source_name.to_owned(),
            line: 0,
            expected: 1,
            found: 0,
        });
    }
    Ok(rows)
}

/// Which reflectivity map to use, with stable string ids (CLI and config files).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MapChoice {
    /// `"toms-mean-1p25x1"`: TOMS mean reflectivity, 288 x 180 cells (the paper's map).
    TomsMean1p25x1,
    /// `"ceres-1x1"`: CERES 2018 all-sky albedo, 360 x 180 cells.
    Ceres1x1,
    /// `"ceres-5x5"`: CERES 2018 all-sky albedo, 72 x 36 cells.
    Ceres5x5,
    /// `"uniform:<value>"` (or `"uniform"` for [`DEFAULT_UNIFORM_ALBEDO`]): constant
    /// reflectivity on a 1 x 1 deg grid (Basilisk's 180 x 360 average model).
    Uniform(f64),
}

impl MapChoice {
    /// Builds the map from the embedded data.
    pub fn load(&self) -> Result<ReflectivityMap, MapError> {
        match *self {
            Self::TomsMean1p25x1 => ReflectivityMap::parse_toms_dat(
                "earthReflectivityMean_1p25x1.dat",
                TOMS_MEAN_1P25X1,
            ),
            Self::Ceres1x1 => {
                ReflectivityMap::parse_ceres_csv("Earth_ALB_2018_CERES_All_1x1.csv", CERES_1X1)
            }
            Self::Ceres5x5 => {
                ReflectivityMap::parse_ceres_csv("Earth_ALB_2018_CERES_All_5x5.csv", CERES_5X5)
            }
            Self::Uniform(value) => ReflectivityMap::uniform(180, 360, value),
        }
    }
}

impl fmt::Display for MapChoice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::TomsMean1p25x1 => f.write_str("toms-mean-1p25x1"),
            Self::Ceres1x1 => f.write_str("ceres-1x1"),
            Self::Ceres5x5 => f.write_str("ceres-5x5"),
            Self::Uniform(v) => write!(f, "uniform:{v}"),
        }
    }
}

impl FromStr for MapChoice {
    type Err = MapError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "toms-mean-1p25x1" => Ok(Self::TomsMean1p25x1),
            "ceres-1x1" => Ok(Self::Ceres1x1),
            "ceres-5x5" => Ok(Self::Ceres5x5),
            "uniform" => Ok(Self::Uniform(DEFAULT_UNIFORM_ALBEDO)),
            _ => {
                let value = s
                    .strip_prefix("uniform:")
                    .and_then(|v| v.parse::<f64>().ok())
                    .filter(|v| (0.0..=1.0).contains(v))
                    .ok_or_else(|| MapError::UnknownMap(s.to_owned()))?;
                Ok(Self::Uniform(value))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn toms_is_transposed_and_flipped() {
        // Two longitudes x three latitudes, north first, percent.
        let text = "10 20 30\n40 50 60\n";
        let m = ReflectivityMap::parse_toms_dat("t", text).unwrap();
        assert_eq!((m.n_lat(), m.n_lon()), (3, 2));
        // Southernmost row = last column; first longitude = first line.
        assert_eq!(m.get(0, 0), Some(0.3));
        assert_eq!(m.get(2, 1), Some(0.4));
        assert_eq!(m.get(3, 0), None);
    }

    #[test]
    fn malformed_text_reports_line_and_column() {
        let err = ReflectivityMap::parse_ceres_csv("c", "0.1,0.2\n0.3,x\n").unwrap_err();
        assert_eq!(
            err,
            MapError::Parse {
                source_name: "c".into(),
                line: 2,
                column: 2,
                text: "x".into()
            }
        );
        let err = ReflectivityMap::parse_ceres_csv("c", "0.1,0.2\n0.3\n").unwrap_err();
        assert!(matches!(
            err,
            MapError::Shape {
                line: 2,
                expected: 2,
                found: 1,
                ..
            }
        ));
        let err = ReflectivityMap::parse_ceres_csv("c", "0.1,1.2\n").unwrap_err();
        assert!(matches!(
            err,
            MapError::OutOfRange {
                line: 1,
                column: 2,
                ..
            }
        ));
        assert!(ReflectivityMap::parse_ceres_csv("c", "\n").is_err());
    }

    #[test]
    fn map_ids_round_trip() {
        for choice in [
            MapChoice::TomsMean1p25x1,
            MapChoice::Ceres1x1,
            MapChoice::Ceres5x5,
            MapChoice::Uniform(0.3),
            MapChoice::Uniform(0.25),
        ] {
            assert_eq!(choice.to_string().parse::<MapChoice>().unwrap(), choice);
        }
        assert_eq!(
            "uniform".parse::<MapChoice>().unwrap(),
            MapChoice::Uniform(0.3)
        );
        assert!("uniform:1.5".parse::<MapChoice>().is_err());
        assert!("toms".parse::<MapChoice>().is_err());
    }

    #[test]
    fn shipped_maps_have_documented_shapes_and_landmarks() {
        let toms = MapChoice::TomsMean1p25x1.load().unwrap();
        assert_eq!((toms.n_lat(), toms.n_lon()), (180, 288));
        let ceres = MapChoice::Ceres1x1.load().unwrap();
        assert_eq!((ceres.n_lat(), ceres.n_lon()), (180, 360));
        // README: the polar rows of CERES are constant, 0.69388 (south) and 0.612 (north).
        assert_eq!(ceres.get(0, 17), Some(0.69388));
        assert_eq!(ceres.get(179, 200), Some(0.612));
        let ceres5 = MapChoice::Ceres5x5.load().unwrap();
        assert_eq!((ceres5.n_lat(), ceres5.n_lon()), (36, 72));
        // README: the 5x5 file is the block mean of the 1x1 file to 8e-6.
        let block = ceres.coarsen(5, 5).unwrap();
        let max_diff = block
            .values()
            .iter()
            .zip(ceres5.values())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(max_diff < 1e-5, "{max_diff}");
        // README: TOMS is UV reflectivity, Sahara dark (~9 %), Antarctic plateau bright (~89 %).
        // Sahara cell 23.5N, 10.625E: row 113, column (10.625 + 179.375) / 1.25 = 152.
        assert!(toms.get(113, 152).unwrap() < 0.15);
        assert!(toms.get(2, 100).unwrap() > 0.8);
    }
}
