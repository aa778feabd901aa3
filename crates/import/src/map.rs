//! The column map (`map.ron`): its types, the RON reader, and the checks that need no export.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use pdcal_dataset::{
    DatasetMeta, EpochUtc, FileFaultKind, Inertia, NoiseHints, NominalMount, OrbitSpec,
};
use serde::Deserialize;

use crate::error::{ErrorKind, ImportError, clip, line_col, number, quote, text_of};
use crate::timeform::{TimeForm, TimeReader};
use crate::units::Quantity;

/// The only map `format_version` this crate reads.
pub const MAP_FORMAT_VERSION: u32 = 1;

/// The map as written (`docs/import.md`); see [`ImportMap`] for the checked form.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapSpec {
    /// Always [`MAP_FORMAT_VERSION`].
    pub format_version: u32,
    /// The dataset's name; default: the export's file name without extension.
    #[serde(default)]
    pub name: Option<String>,
    /// The time column and its form.
    pub time: TimeColumn,
    /// Sentinel values of every column: a cell holding one is treated as empty.
    #[serde(default)]
    pub sentinels: Vec<Sentinel>,
    /// The gyro's three columns, body frame; absent for data without a gyro (the filter
    /// then needs `inertia_kg_m2`, docs/dataset-format.md).
    #[serde(default)]
    pub gyro: Option<VectorColumns>,
    /// The magnetometer's three columns, body frame; absent for photodiode-only data.
    #[serde(default)]
    pub mag: Option<VectorColumns>,
    /// One entry per photodiode, in the order they become `pd01_V`, `pd02_V`, ...
    pub photodiodes: Vec<PhotodiodeColumn>,
    /// Temperature columns, each of one photodiode or of one panel's photodiodes.
    #[serde(default)]
    pub temperatures: Vec<TemperatureColumnMap>,
    /// Current columns (panel and battery currents, torquer commands), each becoming
    /// telemetry.csv's `cur_<name>_A`.
    #[serde(default)]
    pub currents: Vec<CurrentColumnMap>,
    /// Where the orbit comes from.
    pub orbit: OrbitMap,
    /// Noise hints copied into dataset.ron (same fields and units).
    #[serde(default)]
    pub noise: Option<NoiseHints>,
    /// The inertia tensor copied into dataset.ron (same fields and units).
    #[serde(default)]
    pub inertia_kg_m2: Option<Inertia>,
    /// The export's cell separator; detected from the header when absent.
    #[serde(default)]
    pub delimiter: Option<Delimiter>,
    /// What to do with rows whose time equals the previous kept row's.
    #[serde(default)]
    pub duplicate_times: DuplicateTimes,
}

/// The export's cell separator.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
pub enum Delimiter {
    /// `,`
    Comma,
    /// `;` (exports of tools set to a locale with a decimal comma)
    Semicolon,
    /// A tab character.
    Tab,
    /// Any run of spaces and tabs (fixed-width or aligned text; no quoting).
    Whitespace,
}

impl Delimiter {
    /// The delimiter as the output says it.
    pub fn describe(self) -> &'static str {
        match self {
            Delimiter::Comma => "comma (',')",
            Delimiter::Semicolon => "semicolon (';')",
            Delimiter::Tab => "tab",
            Delimiter::Whitespace => "whitespace",
        }
    }

    /// The byte of a single-character delimiter; `None` for [`Delimiter::Whitespace`].
    pub(crate) fn byte(self) -> Option<u8> {
        match self {
            Delimiter::Comma => Some(b','),
            Delimiter::Semicolon => Some(b';'),
            Delimiter::Tab => Some(b'\t'),
            Delimiter::Whitespace => None,
        }
    }
}

/// What the import does with rows whose time equals the previous kept row's (firmware that
/// writes several frames with one time tag).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
pub enum DuplicateTimes {
    /// An error naming both rows (the default: nothing is dropped unsaid).
    #[default]
    Refuse,
    /// The first row of each time is kept, the others dropped and counted.
    KeepFirst,
    /// The rows of one time become one: each column the mean of its non-empty cells.
    Average,
}

/// A cell value meaning "no value": a number (compared as a number, so `65535`, `65535.0`
/// and `6.5535e4` are one sentinel) or a text (compared with the trimmed cell exactly, as
/// `"N/A"`, `"NaN"`, `"---"` are written by ground tools).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum Sentinel {
    /// A numeric sentinel.
    Number(f64),
    /// A text sentinel.
    Text(String),
}

/// The sentinels that apply to one column, split for matching.
#[derive(Clone, Debug, Default)]
pub(crate) struct Sentinels {
    numbers: Vec<f64>,
    texts: Vec<String>,
}

impl Sentinels {
    /// The union of sentinel lists (a column's own and the map's global ones).
    pub(crate) fn of(lists: &[&[Sentinel]]) -> Self {
        let mut out = Sentinels::default();
        for s in lists.iter().flat_map(|l| l.iter()) {
            match s {
                Sentinel::Number(v) => out.numbers.push(*v),
                Sentinel::Text(t) => out.texts.push(t.trim().to_owned()),
            }
        }
        out
    }

    /// Whether the (trimmed) cell text is a text sentinel.
    pub(crate) fn text(&self, cell: &str) -> bool {
        self.texts.iter().any(|t| t == cell)
    }

    /// Whether the cell's number is a numeric sentinel.
    pub(crate) fn number(&self, value: f64) -> bool {
        self.numbers.contains(&value)
    }
}

/// The time column.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeColumn {
    /// Header of the column.
    pub column: String,
    /// How its cells are written.
    pub form: TimeForm,
    /// Values that mean "no time" (the row is dropped), beside the global sentinels.
    #[serde(default)]
    pub sentinels: Vec<Sentinel>,
}

/// One numeric column and how its cells become the dataset's unit.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Column {
    /// Header of the column; or give `columns`.
    #[serde(default)]
    pub column: Option<String>,
    /// A linear combination of columns, `[("V5", 1.0), ("VN", -1.0)]`, converted as one
    /// value by `unit` or `counts`; or give `column`.
    #[serde(default)]
    pub columns: Option<Vec<(String, f64)>>,
    /// The unit the cells are in; or give `counts`.
    #[serde(default)]
    pub unit: Option<String>,
    /// Raw counts with a linear conversion; or give `unit`.
    #[serde(default)]
    pub counts: Option<Counts>,
    /// Values of this column that mean "not sampled", beside the global sentinels.
    #[serde(default)]
    pub sentinels: Vec<Sentinel>,
}

impl Column {
    /// The export columns and their coefficients: `[(column, 1.0)]` for a single column.
    /// Empty when neither or both of `column` and `columns` are given (refused by
    /// [`parse_map`]).
    pub fn terms(&self) -> Vec<(String, f64)> {
        match (&self.column, &self.columns) {
            (Some(name), None) => vec![(name.clone(), 1.0)],
            (None, Some(terms)) => terms.clone(),
            _ => Vec::new(),
        }
    }

    /// The name that places the column in the map text: its header, or the first of a
    /// combination.
    pub(crate) fn first_name(&self) -> Option<&str> {
        match (&self.column, &self.columns) {
            (Some(name), _) => Some(name),
            (None, Some(terms)) => terms.first().map(|(n, _)| n.as_str()),
            _ => None,
        }
    }

    /// The column as the output names it: its header, or the combination written out
    /// (`V5 - VN`, `0.5*A + 0.5*B`), each header escaped and cut.
    pub fn label(&self) -> String {
        let terms = self.terms();
        if let [(name, c)] = terms.as_slice()
            && *c == 1.0
        {
            return crate::error::shown(name);
        }
        let mut out = String::new();
        for (i, (name, c)) in terms.iter().enumerate() {
            let name = crate::error::shown(name);
            let (sign, magnitude) = if *c < 0.0 { ("-", -c) } else { ("+", *c) };
            match (i, sign) {
                (0, "-") => out.push('-'),
                (0, _) => {}
                _ => out.push_str(&format!(" {sign} ")),
            }
            if magnitude == 1.0 {
                out.push_str(&name);
            } else {
                out.push_str(&format!("{magnitude}*{name}"));
            }
        }
        out
    }
}

/// A linear conversion of raw counts: `value = gain * count + offset`, in `unit`.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Counts {
    /// Units per count (nonzero).
    pub gain: f64,
    /// Value at count 0, in `unit`.
    #[serde(default)]
    pub offset: f64,
    /// The unit of `gain * count + offset`.
    pub unit: String,
}

/// Three columns of a vector sensor.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VectorColumns {
    /// x component.
    pub x: Column,
    /// y component.
    pub y: Column,
    /// z component.
    pub z: Column,
}

/// One photodiode: its column, conversion and nominal mounting.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhotodiodeColumn {
    /// As [`Column::column`].
    #[serde(default)]
    pub column: Option<String>,
    /// As [`Column::columns`].
    #[serde(default)]
    pub columns: Option<Vec<(String, f64)>>,
    /// As [`Column::unit`] (`V`, `mV`).
    #[serde(default)]
    pub unit: Option<String>,
    /// As [`Column::counts`].
    #[serde(default)]
    pub counts: Option<Counts>,
    /// As [`Column::sentinels`].
    #[serde(default)]
    pub sentinels: Vec<Sentinel>,
    /// Nominal azimuth, body frame, degrees (dataset.ron's).
    pub azimuth_deg: f64,
    /// Nominal elevation, body frame, degrees.
    pub elevation_deg: f64,
    /// The panel, as in dataset.ron (optional).
    #[serde(default)]
    pub panel: Option<String>,
}

impl PhotodiodeColumn {
    fn as_column(&self) -> Column {
        Column {
            column: self.column.clone(),
            columns: self.columns.clone(),
            unit: self.unit.clone(),
            counts: self.counts.clone(),
            sentinels: self.sentinels.clone(),
        }
    }
}

/// One temperature column: its conversion, and whose temperature it is (exactly one of
/// `photodiode` and `panel`). It becomes telemetry.csv's `temp_pdNN_C` or `temp_<panel>_C`.
// Column's fields are repeated, as in PhotodiodeColumn, because serde cannot combine
// `flatten` with `deny_unknown_fields`, and a misspelt key must stay an error.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TemperatureColumnMap {
    /// As [`Column::column`].
    #[serde(default)]
    pub column: Option<String>,
    /// As [`Column::columns`].
    #[serde(default)]
    pub columns: Option<Vec<(String, f64)>>,
    /// As [`Column::unit`] (`C`, `K`).
    #[serde(default)]
    pub unit: Option<String>,
    /// As [`Column::counts`].
    #[serde(default)]
    pub counts: Option<Counts>,
    /// As [`Column::sentinels`].
    #[serde(default)]
    pub sentinels: Vec<Sentinel>,
    /// The photodiode it measures, 1-based as in `pdNN_V` (the map's photodiode order).
    #[serde(default)]
    pub photodiode: Option<usize>,
    /// The panel it measures: every photodiode whose map entry names this panel.
    #[serde(default)]
    pub panel: Option<String>,
}

impl TemperatureColumnMap {
    fn as_column(&self) -> Column {
        Column {
            column: self.column.clone(),
            columns: self.columns.clone(),
            unit: self.unit.clone(),
            counts: self.counts.clone(),
            sentinels: self.sentinels.clone(),
        }
    }
}

/// One current column: its conversion (`A`, `mA` or counts) and the channel's name, which
/// becomes telemetry.csv's `cur_<name>_A`.
// Column's fields are repeated, as in PhotodiodeColumn (see TemperatureColumnMap).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CurrentColumnMap {
    /// The channel's name: ASCII `a-z`, `0-9`, `_` (`px`, `battery`, `torquer_z`).
    pub name: String,
    /// As [`Column::column`].
    #[serde(default)]
    pub column: Option<String>,
    /// As [`Column::columns`].
    #[serde(default)]
    pub columns: Option<Vec<(String, f64)>>,
    /// As [`Column::unit`] (`A`, `mA`).
    #[serde(default)]
    pub unit: Option<String>,
    /// As [`Column::counts`].
    #[serde(default)]
    pub counts: Option<Counts>,
    /// As [`Column::sentinels`].
    #[serde(default)]
    pub sentinels: Vec<Sentinel>,
}

impl CurrentColumnMap {
    fn as_column(&self) -> Column {
        Column {
            column: self.column.clone(),
            columns: self.columns.clone(),
            unit: self.unit.clone(),
            counts: self.counts.clone(),
            sentinels: self.sentinels.clone(),
        }
    }
}

/// Where the orbit comes from.
// One per map, read once: boxing the columns would only make the RON types harder to read.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum OrbitMap {
    /// A two-line element set, copied to dataset.ron.
    Tle {
        /// Line 1.
        line1: String,
        /// Line 2.
        line2: String,
    },
    /// Position columns, converted to GCRF km (`r_*_km`).
    Positions {
        /// x component.
        x: Column,
        /// y component.
        y: Column,
        /// z component.
        z: Column,
        /// The frame the columns are in.
        frame: PositionFrame,
    },
}

/// The inertial frame of position columns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
pub enum PositionFrame {
    /// GCRF, written as is.
    Gcrf,
    /// J2000 (EME2000), written as is: it differs from GCRF by the frame bias, 23 mas, under
    /// 1 m at LEO radius (dataset-format.md: "J2000 is close enough").
    J2000,
    /// TEME (SGP4's output frame), rotated to GCRF per row with
    /// `pdcal_ephem::frames::teme_to_gcrf`.
    Teme,
}

/// A map read and checked on its own (units, conversions, mounting, TLE); the columns are
/// checked against an export by [`crate::convert`].
#[derive(Clone, Debug)]
pub struct ImportMap {
    /// The map's content.
    pub spec: MapSpec,
    pub(crate) file: PathBuf,
    pub(crate) text: String,
    pub(crate) names: HashMap<String, usize>,
    /// Byte offsets of the map text's line ends, for [`ImportMap::line_of`].
    newlines: Vec<usize>,
    pub(crate) time: TimeReader,
}

/// Parses and checks the bytes of a map file; `file` names it in errors.
pub fn parse_map(file: &Path, bytes: &[u8]) -> Result<ImportMap, ImportError> {
    let text = text_of(file, bytes.to_vec())?;
    let spec: MapSpec = from_ron(file, &text)?;
    let names = column_names(&text);
    let map = Locator {
        file,
        text: &text,
        names: &names,
    };
    if spec.format_version != MAP_FORMAT_VERSION {
        return Err(map
            .key_error(
                "format_version",
                0,
                FileFaultKind::UnsupportedVersion {
                    found: spec.format_version,
                    known: MAP_FORMAT_VERSION,
                }
                .into(),
            )
            .named("format_version"));
    }
    let time = TimeReader::new(&spec.time.form).map_err(|reason| {
        let value = match &spec.time.form {
            TimeForm::Seconds { epoch_utc } => epoch_utc.clone(),
            _ => String::new(),
        };
        map.key_error(
            "epoch_utc",
            0,
            FileFaultKind::BadEpoch { value, reason }.into(),
        )
        .named("time.form.epoch_utc")
    })?;
    if spec.time.column.trim().is_empty() {
        return Err(map
            .key_error("time", 0, ErrorKind::EmptyColumnName)
            .named("time.column"));
    }
    check_sentinels(&map, &spec.sentinels, "sentinels", None)?;
    check_sentinels(&map, &spec.time.sentinels, "time.sentinels", None)?;
    for (path, column, quantity) in columns(&spec) {
        check_column(&map, &path, &column, quantity)?;
    }
    check_temperatures(&map, &spec)?;
    check_currents(&map, &spec)?;
    check_shared_columns(&map, &spec)?;
    check_as_dataset(&map, &spec)?;
    if let OrbitMap::Tle { line1, line2 } = &spec.orbit
        && let Err(e) = pdcal_ephem::TleOrbit::from_lines(line1, line2)
    {
        let kind = ErrorKind::Tle {
            message: clip(&e.to_string()),
        };
        return Err(map.key_error("line1", 0, kind).named("orbit"));
    }
    Ok(ImportMap {
        spec,
        file: file.to_path_buf(),
        newlines: text.match_indices('\n').map(|(i, _)| i).collect(),
        text,
        names,
        time,
    })
}

impl ImportMap {
    /// The map's file as given.
    pub fn file(&self) -> &Path {
        &self.file
    }

    /// The 1-based line of byte offset `offset` of the map text (a binary search, where
    /// `line_col` counts from the start: every column of a long map is placed in time
    /// linear in its length).
    pub(crate) fn line_of(&self, offset: usize) -> usize {
        1 + self.newlines.partition_point(|&n| n < offset)
    }

    pub(crate) fn locator(&self) -> Locator<'_> {
        Locator {
            file: &self.file,
            text: &self.text,
            names: &self.names,
        }
    }
}

/// Entries that stand for different data and read the same export data (a column copied
/// from the entry above and not renamed): two axes of the gyro or of the magnetometer, two
/// photodiodes (the second would be "calibrated" as a copy of the first), two currents.
/// Refused at the later entry; a combination is the same data whatever the order of its
/// terms.
fn check_shared_columns(map: &Locator<'_>, spec: &MapSpec) -> Result<(), ImportError> {
    let mut groups: Vec<(Vec<(String, Column)>, &'static str)> = Vec::new();
    for (name, sensor) in [("gyro", &spec.gyro), ("mag", &spec.mag)] {
        let Some(v) = sensor else { continue };
        let axes = [("x", &v.x), ("y", &v.y), ("z", &v.z)];
        let entries = axes.map(|(axis, c)| (format!("{name}.{axis}"), c.clone()));
        groups.push((
            entries.to_vec(),
            "two axes of one sensor never share a column",
        ));
    }
    let photodiodes = (spec.photodiodes.iter().enumerate())
        .map(|(i, p)| (format!("photodiodes[{i}]"), p.as_column()));
    groups.push((
        photodiodes.collect(),
        "two photodiodes never share a column (each is a sensor of its own)",
    ));
    let currents =
        (spec.currents.iter().enumerate()).map(|(i, c)| (format!("currents[{i}]"), c.as_column()));
    groups.push((currents.collect(), "two currents never share a column"));
    for (entries, never) in groups {
        let mut seen = HashMap::new();
        for (path, column) in entries {
            let Some(other) = seen.insert(same_data(&column), path.clone()) else {
                continue;
            };
            let place = map.key_path(&path).map(|o| line_col(map.text, o));
            let kind = ErrorKind::SharedColumn { other, never };
            return Err(ImportError::maybe_at(map.file, place, kind).named(path));
        }
    }
    Ok(())
}

/// The export data a column reads, as a key: its terms in name order, coefficients by bits.
fn same_data(column: &Column) -> Vec<(String, u64)> {
    let mut terms: Vec<(String, u64)> = (column.terms().into_iter())
        .map(|(name, c)| (name, c.to_bits()))
        .collect();
    terms.sort();
    terms
}

/// Every numeric column of the map: its field path, spec and quantity, in map order.
pub(crate) fn columns(spec: &MapSpec) -> Vec<(String, Column, Quantity)> {
    let mut out = Vec::new();
    let mut vector = |name: &str, v: &VectorColumns, q: Quantity| {
        for (axis, c) in [("x", &v.x), ("y", &v.y), ("z", &v.z)] {
            out.push((format!("{name}.{axis}"), c.clone(), q));
        }
    };
    if let Some(gyro) = &spec.gyro {
        vector("gyro", gyro, Quantity::AngularRate);
    }
    if let Some(mag) = &spec.mag {
        vector("mag", mag, Quantity::MagneticField);
    }
    if let OrbitMap::Positions { x, y, z, .. } = &spec.orbit {
        vector(
            "orbit",
            &VectorColumns {
                x: x.clone(),
                y: y.clone(),
                z: z.clone(),
            },
            Quantity::Length,
        );
    }
    for (i, pd) in spec.photodiodes.iter().enumerate() {
        out.push((
            format!("photodiodes[{i}]"),
            pd.as_column(),
            Quantity::Voltage,
        ));
    }
    for (i, t) in spec.temperatures.iter().enumerate() {
        out.push((
            format!("temperatures[{i}]"),
            t.as_column(),
            Quantity::Temperature,
        ));
    }
    for (i, c) in spec.currents.iter().enumerate() {
        out.push((format!("currents[{i}]"), c.as_column(), Quantity::Current));
    }
    out
}

/// The factor and offset taking a cell of `column` to the dataset unit:
/// `value = cell * scale + offset`. `None` when the unit is unknown (checked by
/// [`parse_map`]).
pub(crate) fn linear(column: &Column, quantity: Quantity) -> Option<(f64, f64)> {
    match (&column.unit, &column.counts) {
        (Some(unit), None) => (quantity.factor(unit)).map(|f| (f, quantity.zero(unit))),
        (None, Some(c)) => {
            (quantity.factor(&c.unit)).map(|f| (c.gain * f, c.offset * f + quantity.zero(&c.unit)))
        }
        _ => None,
    }
}

fn check_column(
    map: &Locator<'_>,
    path: &str,
    column: &Column,
    quantity: Quantity,
) -> Result<(), ImportError> {
    let at = column.first_name().and_then(|n| map.column(n));
    let here = || at.map(|o| line_col(map.text, o));
    match (&column.column, &column.columns) {
        (Some(name), None) if name.trim().is_empty() => {
            return Err(
                ImportError::maybe_at(map.file, here(), ErrorKind::EmptyColumnName)
                    .named(format!("{path}.column")),
            );
        }
        (Some(_), None) => {}
        (None, Some(terms)) => {
            let place = here().or_else(|| map.key_path(path).map(|o| line_col(map.text, o)));
            check_terms(map, path, terms, place)?;
        }
        _ => {
            let place = here().or_else(|| map.key_path(path).map(|o| line_col(map.text, o)));
            return Err(
                ImportError::maybe_at(map.file, place, ErrorKind::ColumnOrColumns).named(path),
            );
        }
    }
    // Where this spec's parts are: after its column name in the text.
    let near = |needle: &str| {
        at.and_then(|o| map.literal_after(o, needle))
            .or(at)
            .map(|o| line_col(map.text, o))
    };
    let unit_error = |unit: &str, field: &str| {
        let kind = ErrorKind::UnknownUnit {
            unit: unit.to_owned(),
            quantity: quantity.name(),
            allowed: quantity.allowed(),
        };
        Err(ImportError::maybe_at(map.file, near(unit), kind).named(format!("{path}.{field}")))
    };
    match (&column.unit, &column.counts) {
        (Some(unit), None) => {
            if quantity.factor(unit).is_none() {
                return unit_error(unit, "unit");
            }
        }
        (None, Some(counts)) => {
            if quantity.factor(&counts.unit).is_none() {
                return unit_error(&counts.unit, "counts.unit");
            }
            let bad = |value: f64, field: &str, rule| {
                let kind = ErrorKind::BadMapNumber {
                    value: format!("{value:?}"),
                    rule,
                };
                Err(ImportError::maybe_at(map.file, near(field), kind)
                    .named(format!("{path}.counts.{field}")))
            };
            if !counts.gain.is_finite() || counts.gain == 0.0 {
                return bad(counts.gain, "gain", "a gain must be finite and nonzero");
            }
            if !counts.offset.is_finite() {
                return bad(counts.offset, "offset", "an offset must be finite");
            }
        }
        _ => {
            return Err(
                ImportError::maybe_at(map.file, here(), ErrorKind::UnitOrCounts).named(path),
            );
        }
    }
    check_sentinels(map, &column.sentinels, &format!("{path}.sentinels"), at)
}

/// A combination's terms: at least one, names not blank and not repeated, coefficients
/// finite and nonzero.
fn check_terms(
    map: &Locator<'_>,
    path: &str,
    terms: &[(String, f64)],
    place: Option<(usize, usize)>,
) -> Result<(), ImportError> {
    let fault = |reason: String| {
        Err(
            ImportError::maybe_at(map.file, place, ErrorKind::BadCombination { reason })
                .named(format!("{path}.columns")),
        )
    };
    if terms.is_empty() {
        return fault("the list is empty: give at least one (\"COLUMN\", coefficient)".into());
    }
    let mut seen = std::collections::HashSet::new();
    for (name, c) in terms {
        if name.trim().is_empty() {
            return fault("a column name is empty".into());
        }
        if !c.is_finite() || *c == 0.0 {
            return fault(format!(
                "the coefficient of {} is {}: it must be finite and nonzero",
                quote(name),
                number(*c)
            ));
        }
        if !seen.insert(name.as_str()) {
            return fault(format!(
                "column {} appears twice: give it once with the sum of its coefficients",
                quote(name)
            ));
        }
    }
    Ok(())
}

fn check_sentinels(
    map: &Locator<'_>,
    values: &[Sentinel],
    path: &str,
    near: Option<usize>,
) -> Result<(), ImportError> {
    let fault = values.iter().find_map(|v| match v {
        Sentinel::Number(x) if !x.is_finite() => Some((
            format!("{x:?}"),
            "a sentinel must be a finite number (an empty cell needs none; \"NaN\" as text)",
        )),
        Sentinel::Text(t) if t.trim().is_empty() => Some((
            format!("{t:?}"),
            "a text sentinel must not be blank (an empty cell needs none)",
        )),
        _ => None,
    });
    let Some((value, rule)) = fault else {
        return Ok(());
    };
    let kind = ErrorKind::BadMapNumber { value, rule };
    let place = near
        .or_else(|| match path.split_once('.') {
            Some((outer, _)) => map
                .key(outer, 0)
                .and_then(|o| map.key_after(o, "sentinels")),
            None => map.top_level_key(path),
        })
        .map(|o| line_col(map.text, o));
    Err(ImportError::maybe_at(map.file, place, kind).named(path))
}

/// Each current column's name is a valid channel name, and no two are the same (they would
/// be one telemetry.csv column).
fn check_currents(map: &Locator<'_>, spec: &MapSpec) -> Result<(), ImportError> {
    let mut names = std::collections::HashSet::new();
    for (i, c) in spec.currents.iter().enumerate() {
        let reason = if !pdcal_dataset::is_current_name(&c.name) {
            format!(
                "{} is not a channel name (1 to 64 of a-z, 0-9, _): it becomes the column \
                 cur_<name>_A",
                quote(&c.name)
            )
        } else if !names.insert(c.name.as_str()) {
            format!("a second current named {}", quote(&c.name))
        } else {
            continue;
        };
        let at = c.as_column().first_name().and_then(|n| map.column(n));
        let place = at
            .and_then(|o| map.key_after(o, "name").or(Some(o)))
            .map(|o| line_col(map.text, o));
        let kind = ErrorKind::BadCurrentName { reason };
        return Err(
            ImportError::maybe_at(map.file, place, kind).named(format!("currents[{i}].name"))
        );
    }
    Ok(())
}

/// Each temperature column names exactly one photodiode of the map or one panel some
/// photodiode names, and no two name the same one (they would be one telemetry.csv column).
fn check_temperatures(map: &Locator<'_>, spec: &MapSpec) -> Result<(), ImportError> {
    let panels: std::collections::HashSet<&str> = (spec.photodiodes.iter())
        .filter_map(|p| p.panel.as_deref())
        .collect();
    let mut headers = std::collections::HashSet::new();
    for (i, t) in spec.temperatures.iter().enumerate() {
        let path = format!("temperatures[{i}]");
        let at = t.as_column().first_name().and_then(|n| map.column(n));
        let fault = |field: &str, reason: String| {
            let place = at
                .and_then(|o| map.key_after(o, field).or(Some(o)))
                .map(|o| line_col(map.text, o));
            let kind = ErrorKind::BadTemperatureTarget { reason };
            Err(ImportError::maybe_at(map.file, place, kind).named(format!("{path}.{field}")))
        };
        let header = match (t.photodiode, &t.panel) {
            (Some(k), None) if (1..=spec.photodiodes.len()).contains(&k) => {
                pdcal_dataset::photodiode_temperature_column(k)
            }
            (Some(k), None) => {
                let n = spec.photodiodes.len();
                return fault(
                    "photodiode",
                    format!("photodiode {k} is not one of the map's photodiodes 1 ..= {n}"),
                );
            }
            (None, Some(panel)) if panels.contains(panel.as_str()) => {
                pdcal_dataset::panel_temperature_column(panel)
            }
            (None, Some(panel)) => {
                return fault(
                    "panel",
                    format!("no photodiode of the map names panel {}", quote(panel)),
                );
            }
            _ => {
                return fault(
                    "column",
                    "give exactly one of `photodiode: N` and `panel: \"NAME\"`".to_owned(),
                );
            }
        };
        if headers.contains(&header) {
            return fault(
                "column",
                format!("a second column for {header}: one temperature per photodiode or panel"),
            );
        }
        headers.insert(header);
    }
    Ok(())
}

/// The map's mounting, TLE and noise hints through the dataset reader's own rules (a
/// dataset.ron made of them, parsed), so the import refuses exactly what the dataset format
/// refuses, placed in the map: the field paths are the same in both files.
fn check_as_dataset(map: &Locator<'_>, spec: &MapSpec) -> Result<(), ImportError> {
    let epoch = EpochUtc::parse("2000-01-01T00:00:00Z").map_err(|e| {
        ImportError::whole_file(
            map.file,
            ErrorKind::Dataset {
                message: e.to_string(),
            },
        )
    })?;
    let meta = DatasetMeta {
        format_version: pdcal_dataset::FORMAT_VERSION,
        name: "map check".into(),
        epoch_utc: epoch,
        orbit: orbit_spec(&spec.orbit),
        photodiodes: mounts(spec),
        noise: spec.noise,
        inertia_kg_m2: spec.inertia_kg_m2,
    };
    let text = ron::to_string(&meta).map_err(|e| {
        ImportError::whole_file(
            map.file,
            ErrorKind::Dataset {
                message: clip(&e.to_string()),
            },
        )
    })?;
    let Err(e) = pdcal_dataset::meta_from_str(&text) else {
        return Ok(());
    };
    let field = e.field().unwrap_or("").to_owned();
    let message = e.kind().to_string();
    // `photodiodes[3].elevation_deg` -> the 4th `elevation_deg:`; `orbit.line2 inclination,
    // columns 9-16` -> `line2:`; `noise.mag_nT` -> `mag_nT:`.
    let head = field.split(' ').next().unwrap_or("");
    let key = head.rsplit('.').next().unwrap_or(head);
    let nth = head
        .strip_prefix("photodiodes[")
        .and_then(|rest| rest.split(']').next())
        .and_then(|i| i.parse::<usize>().ok())
        .filter(|_| key != "panel")
        .unwrap_or(0);
    let err = map.key_error(key, nth, ErrorKind::Dataset { message });
    Err(if field.is_empty() {
        err
    } else {
        err.named(field)
    })
}

/// dataset.ron's orbit for a map's.
pub(crate) fn orbit_spec(orbit: &OrbitMap) -> OrbitSpec {
    match orbit {
        OrbitMap::Tle { line1, line2 } => OrbitSpec::Tle {
            line1: line1.clone(),
            line2: line2.clone(),
        },
        OrbitMap::Positions { .. } => OrbitSpec::PositionColumns,
    }
}

/// dataset.ron's photodiodes for a map's.
pub(crate) fn mounts(spec: &MapSpec) -> Vec<NominalMount> {
    (spec.photodiodes.iter())
        .map(|p| NominalMount {
            azimuth_deg: p.azimuth_deg,
            elevation_deg: p.elevation_deg,
            panel: p.panel.clone(),
            fov_deg: None,
        })
        .collect()
}

/// Positions in the map text, for errors found after parsing (serde keeps none).
#[derive(Clone, Copy)]
pub(crate) struct Locator<'a> {
    pub(crate) file: &'a Path,
    pub(crate) text: &'a str,
    /// Byte offset of each column name's first literal after `column:` or `columns: [(`.
    pub(crate) names: &'a HashMap<String, usize>,
}

/// Each column name of the map text with the byte offset of its first string literal after
/// a `column:` key or as the first name of a `columns:` list, found in one pass so that
/// placing every column of a map is linear in its length (a name written with escapes is
/// left out).
pub(crate) fn column_names(text: &str) -> HashMap<String, usize> {
    let mut out = HashMap::new();
    let is_ident = |c: char| c.is_alphanumeric() || c == '_';
    for (i, _) in text.match_indices("column") {
        if text[..i].chars().next_back().is_some_and(is_ident) {
            continue;
        }
        let rest = &text[i + "column".len()..];
        let (list, rest) = match rest.strip_prefix('s') {
            Some(r) => (true, r),
            None => (false, rest),
        };
        let Some(mut value) = rest.trim_start().strip_prefix(':') else {
            continue;
        };
        value = value.trim_start();
        if !list {
            insert_literal(&mut out, text, value);
            continue;
        }
        // Every name of a `[("A", 1.0), ("B", -1.0)]` list.
        let Some(mut rest) = value.strip_prefix('[') else {
            continue;
        };
        while let Some(entry) = rest.trim_start().strip_prefix('(') {
            let entry = entry.trim_start();
            insert_literal(&mut out, text, entry);
            let Some(close) = entry.find(')') else {
                break;
            };
            rest = entry[close + 1..].trim_start();
            rest = rest.strip_prefix(',').unwrap_or(rest);
        }
    }
    out
}

/// Records the string literal that `value` (a suffix of `text`) starts with, if any and if
/// written without escapes, at its offset in `text`, unless the name is known already.
fn insert_literal(out: &mut HashMap<String, usize>, text: &str, value: &str) {
    let Some(literal) = value.strip_prefix('"') else {
        return;
    };
    let Some(end) = literal.find('"') else {
        return;
    };
    let name = &literal[..end];
    if name.contains('\\') {
        return;
    }
    let at = text.len() - value.len();
    out.entry(name.to_owned()).or_insert(at);
}

impl Locator<'_> {
    /// Byte offset of the `nth` (0-based) `key:` that is not part of a longer identifier.
    pub(crate) fn key(&self, key: &str, nth: usize) -> Option<usize> {
        if key.is_empty() {
            return None;
        }
        let text = self.text;
        let is_ident = |c: char| c.is_alphanumeric() || c == '_';
        text.match_indices(key)
            .filter(|&(i, _)| {
                let before_ok = !text[..i].chars().next_back().is_some_and(is_ident);
                let after = text[i + key.len()..].trim_start();
                before_ok && after.starts_with(':')
            })
            .nth(nth)
            .map(|(i, _)| i)
    }

    /// An error at the `nth` `key:`, or about the whole map when it is not found.
    pub(crate) fn key_error(&self, key: &str, nth: usize, kind: ErrorKind) -> ImportError {
        let place = self.key(key, nth).map(|o| line_col(self.text, o));
        ImportError::maybe_at(self.file, place, kind)
    }

    /// Byte offset of the string literal `"name"` that follows a `column:` key (or opens a
    /// `columns:` list). A name written with escapes is not found, and the error then names
    /// its field path only.
    pub(crate) fn column(&self, name: &str) -> Option<usize> {
        self.names.get(name).copied()
    }

    /// Byte offset of the literal `"name"` of the column at field path `path`
    /// (`currents[2]`, `gyro.x`): the first after the map's top-level key of its section
    /// (`currents:`), so that a column an earlier section also reads is placed in its own;
    /// else the first anywhere ([`Self::column`]).
    pub(crate) fn column_of(&self, path: &str, name: &str) -> Option<usize> {
        let section = path.split(['[', '.']).next().unwrap_or(path);
        let quoted = format!("\"{name}\"");
        self.top_level_key(section)
            .and_then(|from| Some(from + self.text.get(from..)?.find(&quoted)?))
            .or_else(|| self.column(name))
    }

    /// Byte offset of a column spec given by its field path (`photodiodes[3]`: its
    /// `azimuth_deg:`; `currents[1]`: its `name:`; `gyro.x`: the `x:` after `gyro:`), for a
    /// spec that names no column or whose column another spec names first.
    fn key_path(&self, path: &str) -> Option<usize> {
        if let Some(i) = (path.strip_prefix("photodiodes["))
            .and_then(|r| r.strip_suffix(']'))
            .and_then(|i| i.parse::<usize>().ok())
        {
            return self.key("azimuth_deg", i);
        }
        if let Some(i) = (path.strip_prefix("currents["))
            .and_then(|r| r.strip_suffix(']'))
            .and_then(|i| i.parse::<usize>().ok())
        {
            let from = self.top_level_key("currents")?;
            return (0..)
                .map_while(|n| self.key("name", n))
                .filter(|&at| at > from)
                .nth(i);
        }
        let (outer, axis) = path.split_once('.')?;
        self.key_after(self.key(outer, 0)?, axis)
    }

    /// Byte offset of the `key:` of the map's outermost struct (not one inside a column).
    fn top_level_key(&self, key: &str) -> Option<usize> {
        (0..)
            .map_while(|n| self.key(key, n))
            .find(|&at| nesting(&self.text[..at]) == 1)
    }

    /// Byte offset of the first `key:` at or after `from`.
    fn key_after(&self, from: usize, key: &str) -> Option<usize> {
        let rest = self.text.get(from..)?;
        let i = rest.find(&format!("{key}:"))?;
        Some(from + i)
    }

    /// Byte offset of the first `"needle"` literal (or bare token, for numbers' keys) at or
    /// after `from`.
    fn literal_after(&self, from: usize, needle: &str) -> Option<usize> {
        let rest = self.text.get(from..)?;
        let quoted = format!("\"{needle}\"");
        rest.find(&quoted)
            .or_else(|| rest.find(needle))
            .map(|i| from + i)
    }
}

/// How many brackets are open at the end of `text` (outside strings and `//` comments).
fn nesting(text: &str) -> usize {
    let mut depth = 0usize;
    for line in text.lines() {
        let mut in_string = false;
        let mut escaped = false;
        let mut prev = ' ';
        for c in line.chars() {
            if in_string {
                in_string = escaped || c != '"';
                escaped = !escaped && c == '\\';
                continue;
            }
            match c {
                '"' => in_string = true,
                '/' if prev == '/' => break,
                '(' | '[' => depth += 1,
                ')' | ']' => depth = depth.saturating_sub(1),
                _ => {}
            }
            prev = c;
        }
    }
    depth
}

/// Deserialises the map with the dataset reader's RON options and error mapping.
fn from_ron<T: serde::de::DeserializeOwned>(file: &Path, text: &str) -> Result<T, ImportError> {
    pdcal_dataset::parse_ron(text)
        .map_err(|f| ImportError::at(file, f.line, Some(f.column), f.kind.into()))
}
