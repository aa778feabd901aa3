//! telemetry.csv: the measured time series, held column-wise.

use std::io::Read;
use std::path::Path;

use nalgebra::Vector3;

use crate::column::{Cell, Column, Samples, Vectors};
use crate::current::{CURRENT_RANGE_A, CurrentColumn, current_key};
use crate::error::{DatasetError, ErrorKind};
use crate::meta::{DatasetMeta, OrbitSpec};
use crate::table::{CsvRows, find, push_row, require, require3};
use crate::temperature::{
    HeldTemperatures, TEMPERATURE_RANGE_C, TemperatureColumn, TemperatureKey,
    panel_temperature_column, photodiode_temperature_column, temperature_key,
};

/// Column names of telemetry.csv (and, for `t_s` and `r_*_km`, of truth.csv).
pub mod columns {
    /// Seconds since `epoch_utc`.
    pub const T_S: &str = "t_s";
    /// Gyro rate, body frame, rad/s.
    pub const GYRO: [&str; 3] = ["gyro_x_rad_s", "gyro_y_rad_s", "gyro_z_rad_s"];
    /// Magnetometer, body frame, nT.
    pub const MAG: [&str; 3] = ["mag_x_nT", "mag_y_nT", "mag_z_nT"];
    /// Position, GCRF, km.
    pub const R: [&str; 3] = ["r_x_km", "r_y_km", "r_z_km"];
}

/// The header of photodiode `index` (1-based): `pd01_V` ... `pd99_V`, `pd100_V`; the index is
/// zero-padded to two digits and takes three from 100 on.
pub fn photodiode_column(index: usize) -> String {
    format!("pd{index:02}_V")
}

/// The measured time series, one `Vec` per column, all of the same length.
///
/// `None` is an empty cell: the sensor was not sampled at that time. A vector sensor is
/// sampled whole or not at all.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Telemetry {
    /// Sample times, s since `epoch_utc`, strictly increasing.
    pub t_s: Vec<f64>,
    /// Gyro rate, body frame, rad/s.
    pub gyro_rad_s: Vectors,
    /// Magnetometer, body frame, nT; `None` when the file has no `mag_*` columns
    /// (photodiode-only mode).
    pub mag_nt: Option<Vectors>,
    /// Photodiode outputs, V: `pd_v[i].get(k)` is photodiode `i + 1` at sample `k`.
    pub pd_v: Vec<Samples>,
    /// Position, GCRF, km; present exactly when the orbit is `PositionColumns`.
    pub r_gcrf_km: Option<Vectors>,
    /// The `temp_*_C` columns in file order, degrees Celsius; empty when there are none.
    /// [`Telemetry::photodiode_temperatures`] says which photodiode reads which.
    pub temperature_c: Vec<TemperatureColumn>,
    /// The `cur_<name>_A` columns in file order, amperes; empty when there are none.
    pub current_a: Vec<CurrentColumn>,
}

impl Telemetry {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }

    /// The first failure to read or write a photodiode column kept in a file
    /// ([`TelemetryStorage::Files`]), if any: the rows it concerns read as blank, so a
    /// result computed from this telemetry stands only when this is `None`.
    pub fn storage_error(&self) -> Option<String> {
        (self.pd_v.iter().find_map(Samples::storage_error))
            .or_else(|| self.gyro_rad_s.storage_error())
            .or_else(|| self.mag_nt.as_ref().and_then(Vectors::storage_error))
            .or_else(|| self.r_gcrf_km.as_ref().and_then(Vectors::storage_error))
    }

    /// The rows `k` for which `keep(k)` holds, in order (a pass-by-pass downlink cut from
    /// a continuous set, in tests and validation runs).
    pub fn select_rows(&self, keep: impl Fn(usize) -> bool) -> Telemetry {
        let rows: Vec<usize> = (0..self.len()).filter(|&k| keep(k)).collect();
        let pick = |column: &Samples| rows.iter().map(|&k| column.get(k)).collect();
        let pick3 = |column: &Vectors| rows.iter().map(|&k| column.get(k)).collect::<Vectors>();
        Telemetry {
            t_s: rows.iter().map(|&k| self.t_s[k]).collect(),
            gyro_rad_s: pick3(&self.gyro_rad_s),
            mag_nt: self.mag_nt.as_ref().map(pick3),
            pd_v: self.pd_v.iter().map(pick).collect(),
            r_gcrf_km: self.r_gcrf_km.as_ref().map(pick3),
            temperature_c: self
                .temperature_c
                .iter()
                .map(|c| TemperatureColumn {
                    name: c.name.clone(),
                    values: rows.iter().map(|&k| c.values[k]).collect(),
                })
                .collect(),
            current_a: self
                .current_a
                .iter()
                .map(|c| CurrentColumn {
                    name: c.name.clone(),
                    values: rows.iter().map(|&k| c.values[k]).collect(),
                })
                .collect(),
        }
    }
}

impl Telemetry {
    /// The index into [`Telemetry::temperature_c`] of the column named `name`.
    pub fn temperature_column(&self, name: &str) -> Option<usize> {
        self.temperature_c.iter().position(|c| c.name == name)
    }

    /// For each photodiode of `meta`, in `pdNN` order, the index into
    /// [`Telemetry::temperature_c`] of its temperature: its own `temp_pdNN_C` if present,
    /// else its panel's `temp_<panel>_C`, else `None` (no temperature for it).
    pub fn photodiode_temperatures(&self, meta: &DatasetMeta) -> Vec<Option<usize>> {
        meta.photodiodes
            .iter()
            .enumerate()
            .map(|(i, mount)| {
                self.temperature_column(&photodiode_temperature_column(i + 1))
                    .or_else(|| {
                        let panel = mount.panel.as_deref()?;
                        self.temperature_column(&panel_temperature_column(panel))
                    })
            })
            .collect()
    }

    /// Per-photodiode temperatures held from the last sample, for reading row by row
    /// ([`HeldTemperatures::at`]).
    pub fn held_temperatures(&self, meta: &DatasetMeta) -> HeldTemperatures<'_> {
        let of_photodiode = if self.temperature_c.is_empty() {
            Vec::new()
        } else {
            self.photodiode_temperatures(meta)
        };
        HeldTemperatures::new(&self.temperature_c, of_photodiode, meta.photodiodes.len())
    }
}

/// Column indices of one telemetry.csv header.
struct Layout {
    t: usize,
    gyro: Option<[usize; 3]>,
    mag: Option<[usize; 3]>,
    pd: Vec<usize>,
    r: Option<[usize; 3]>,
    temperature: Vec<usize>,
    current: Vec<usize>,
}

/// The photodiode index of a `pd<digits>_V` header, if it has that shape.
fn pd_index(name: &str) -> Option<usize> {
    let digits = name.strip_prefix("pd")?.strip_suffix("_V")?;
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok().or(Some(usize::MAX))
}

fn layout<R: Read>(rows: &CsvRows<'_, R>, meta: &DatasetMeta) -> Result<Layout, DatasetError> {
    let n = meta.photodiodes.len();
    let positions = matches!(meta.orbit, OrbitSpec::PositionColumns);
    let known = |h: &str| {
        h == columns::T_S
            || columns::GYRO.contains(&h)
            || columns::MAG.contains(&h)
            || columns::R.contains(&h)
    };
    let pd_hint = match n {
        0 => "; dataset.ron lists no photodiodes".to_owned(),
        1 => "; the photodiode column is pd01_V".to_owned(),
        _ => format!(
            "; photodiode columns are pd01_V .. {}",
            photodiode_column(n)
        ),
    };
    // A repeated header is its own fault, found before anything counts columns (two
    // `pd01_V` would otherwise read as a photodiode count that does not match).
    let mut seen = std::collections::HashMap::new();
    if let Some(col) =
        (rows.header.iter().enumerate()).position(|(i, h)| seen.insert(h.as_str(), i).is_some())
    {
        let kind = ErrorKind::DuplicateColumn {
            name: rows.header[col].clone(),
        };
        return Err(rows.header_error(col, kind));
    }
    let mut pd_count = 0;
    let mut temperature = Vec::new();
    let mut current = Vec::new();
    for (col, h) in rows.header.iter().enumerate() {
        if pd_index(h).is_some() {
            pd_count += 1;
        } else if let Some(key) = temperature_key(h) {
            check_temperature_header(rows, meta, col, h, key)?;
            temperature.push(col);
        } else if let Some(key) = current_key(h) {
            if key.is_err() {
                let kind = ErrorKind::UnknownColumn {
                    name: h.clone(),
                    hint: "; current columns are cur_<name>_A (<name>: 1 to 64 of a-z, 0-9, _; amperes)"
                        .to_owned(),
                };
                return Err(rows.header_error(col, kind));
            }
            current.push(col);
        } else if !known(h) {
            let hint = match h.is_empty() {
                true => "; the header has an empty name here: a delimiter at the end of the \
                         header line, or two in a row"
                    .to_owned(),
                false => String::new(),
            };
            let kind = ErrorKind::UnknownColumn {
                name: h.clone(),
                hint,
            };
            return Err(rows.header_error(col, kind));
        } else if columns::R.contains(&h.as_str()) && !positions {
            let kind = ErrorKind::UnexpectedPositionColumn { name: h.clone() };
            return Err(rows.header_error(col, kind));
        }
    }
    if pd_count != n {
        return Err(rows.header_row_error(ErrorKind::PhotodiodeCountMismatch {
            in_meta: n,
            what: "the header's pdNN_V columns number".into(),
            found: pd_count,
        }));
    }
    for (col, h) in rows.header.iter().enumerate() {
        if let Some(i) = pd_index(h)
            && (i == 0 || i > n || *h != photodiode_column(i))
        {
            let kind = ErrorKind::UnknownColumn {
                name: h.clone(),
                hint: pd_hint.clone(),
            };
            return Err(rows.header_error(col, kind));
        }
    }
    // Absent columns mean no such sensor, as empty cells in every row do.
    let gyro = match columns::GYRO.map(|name| find(rows, name)) {
        [Ok(None), Ok(None), Ok(None)] => None,
        _ => Some(require3(rows, columns::GYRO)?),
    };
    let mag = match columns::MAG.map(|name| find(rows, name)) {
        [Ok(None), Ok(None), Ok(None)] => None,
        _ => Some(require3(rows, columns::MAG)?),
    };
    let r = if positions {
        let hint = "; orbit: PositionColumns needs r_x_km, r_y_km, r_z_km";
        Some([
            require(rows, columns::R[0], hint)?,
            require(rows, columns::R[1], hint)?,
            require(rows, columns::R[2], hint)?,
        ])
    } else {
        None
    };
    Ok(Layout {
        t: require(rows, columns::T_S, "")?,
        gyro,
        mag,
        // Looked up in the header's map, not scanned for: linear in the photodiode count.
        pd: (1..=n)
            .map(|i| {
                let name = photodiode_column(i);
                seen.get(name.as_str()).copied().ok_or_else(|| {
                    rows.header_row_error(ErrorKind::MissingColumn {
                        name,
                        hint: String::new(),
                    })
                })
            })
            .collect::<Result<_, _>>()?,
        r,
        temperature,
        current,
    })
}

/// Checks a `temp_*_C` header against dataset.ron: a per-photodiode column needs its
/// photodiode, a panel column a photodiode on that panel (a panel nobody refers to is
/// almost surely a misspelling, and its data would be silently unused).
fn check_temperature_header<R: Read>(
    rows: &CsvRows<'_, R>,
    meta: &DatasetMeta,
    col: usize,
    h: &str,
    key: TemperatureKey<'_>,
) -> Result<(), DatasetError> {
    let n = meta.photodiodes.len();
    let unknown = |hint: String| {
        let kind = ErrorKind::UnknownColumn {
            name: h.to_owned(),
            hint,
        };
        rows.header_error(col, kind)
    };
    match key {
        TemperatureKey::Photodiode(i)
            if i >= 1 && i <= n && h == photodiode_temperature_column(i) => {}
        TemperatureKey::Photodiode(_) => {
            return Err(unknown(match n {
                0 => "; dataset.ron lists no photodiodes".to_owned(),
                1 => "; the photodiode temperature column is temp_pd01_C".to_owned(),
                _ => format!(
                    "; photodiode temperature columns are temp_pd01_C .. {}",
                    photodiode_temperature_column(n)
                ),
            }));
        }
        TemperatureKey::Panel(panel) => {
            let referred = (meta.photodiodes.iter()).any(|m| m.panel.as_deref() == Some(panel));
            if !referred {
                let kind = ErrorKind::UnreferencedPanel {
                    panel: panel.to_owned(),
                };
                return Err(rows.header_error(col, kind));
            }
        }
        TemperatureKey::Malformed => {
            return Err(unknown(
                "; temperature columns are temp_pdNN_C (one photodiode) or temp_<panel>_C \
                 (<panel>: a-z, 0-9, _ as in dataset.ron)"
                    .to_owned(),
            ));
        }
    }
    // A repeated header is reported at its second occurrence.
    find(rows, h).map(|_| ())
}

/// The telemetry of named columns a program holds (headers as in telemetry.csv, one value
/// per row, NaN for an empty cell), checked by the one reader: the columns are rendered as
/// telemetry.csv text in the order given and read back against `meta`, so whatever they
/// hold, the result and the errors (line, column, header, value) are those of that file.
pub fn telemetry_from_columns(
    columns: &[(String, Vec<f64>)],
    meta: &DatasetMeta,
) -> Result<Telemetry, DatasetError> {
    let file = Path::new(crate::TELEMETRY_CSV);
    let rows = columns.first().map_or(0, |(_, c)| c.len());
    if let Some((name, column)) = columns.iter().find(|(_, c)| c.len() != rows) {
        let kind = ErrorKind::WrongLength {
            expected: rows,
            found: column.len(),
        };
        return Err(DatasetError::whole_file(file, kind).named(name.clone()));
    }
    // The csv writer quotes a header that needs it, as a CSV library would write it.
    let mut header = csv::Writer::from_writer(Vec::new());
    let written = header.write_record(columns.iter().map(|(name, _)| name));
    let mut text = written
        .ok()
        .and_then(|()| header.into_inner().ok())
        .and_then(|bytes| String::from_utf8(bytes).ok())
        .unwrap_or_default();
    for k in 0..rows {
        push_row(
            &mut text,
            columns
                .iter()
                .map(|(_, c)| Some(c[k]).filter(|x| !x.is_nan())),
        );
    }
    telemetry_from_str(&text, meta)
}

/// Parses and validates telemetry.csv text against its dataset.ron (file name
/// `telemetry.csv` in errors).
pub fn telemetry_from_str(text: &str, meta: &DatasetMeta) -> Result<Telemetry, DatasetError> {
    parse_telemetry(Path::new(crate::TELEMETRY_CSV), text, meta)
}

pub(crate) fn parse_telemetry(
    file: &Path,
    text: &str,
    meta: &DatasetMeta,
) -> Result<Telemetry, DatasetError> {
    telemetry_from_rows(CsvRows::open(file, text)?, meta)
}

/// Where the telemetry's columns are kept while a program reads them.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum TelemetryStorage {
    /// In memory (`Vec`s).
    #[default]
    Memory,
    /// The photodiode, gyro, magnetometer and position columns in files of this
    /// directory, read through a small cache of blocks ([`Column::in_file`]); the times,
    /// temperatures and currents in memory. The files are unlinked when made, so nothing is
    /// left in the directory.
    Files(std::path::PathBuf),
}

impl TelemetryStorage {
    fn column<T: Cell>(&self) -> std::io::Result<Column<T>> {
        match self {
            TelemetryStorage::Memory => Ok(Column::new()),
            TelemetryStorage::Files(dir) => Column::in_file(dir),
        }
    }

    /// The file an error of this storage names: its directory.
    fn path(&self) -> &Path {
        match self {
            TelemetryStorage::Memory => Path::new(""),
            TelemetryStorage::Files(dir) => dir,
        }
    }
}

/// The telemetry of `rows` (from text in memory, or streamed from the file so that a large
/// file is never held whole as text).
pub(crate) fn telemetry_from_rows<R: Read>(
    rows: CsvRows<'_, R>,
    meta: &DatasetMeta,
) -> Result<Telemetry, DatasetError> {
    telemetry_from_rows_in(rows, meta, &TelemetryStorage::Memory)
}

/// [`telemetry_from_rows`] into the columns of `storage`.
pub(crate) fn telemetry_from_rows_in<R: Read>(
    mut rows: CsvRows<'_, R>,
    meta: &DatasetMeta,
    storage: &TelemetryStorage,
) -> Result<Telemetry, DatasetError> {
    let lay = layout(&rows, meta)?;
    let spill_error = |e| crate::error::io_error(storage.path(), "cannot keep telemetry in", e);
    let mut tm = empty_telemetry(&rows, &lay, storage).map_err(spill_error)?;
    let mut failed = None;
    visit_rows(&mut rows, &lay, |row| {
        if failed.is_none() {
            failed = push_telemetry(&mut tm, row).err();
        }
    })?;
    if let Some(e) = failed {
        return Err(spill_error(e));
    }
    if tm.is_empty() {
        return Err(rows.no_rows());
    }
    Ok(tm)
}

/// The columns of `lay`, empty, the photodiodes' in `storage`.
fn empty_telemetry<R: Read>(
    rows: &CsvRows<'_, R>,
    lay: &Layout,
    storage: &TelemetryStorage,
) -> std::io::Result<Telemetry> {
    Ok(Telemetry {
        pd_v: (0..lay.pd.len())
            .map(|_| storage.column())
            .collect::<Result<_, _>>()?,
        gyro_rad_s: storage.column()?,
        mag_nt: lay.mag.map(|_| storage.column()).transpose()?,
        r_gcrf_km: lay.r.map(|_| storage.column()).transpose()?,
        temperature_c: (lay.temperature.iter())
            .map(|&col| TemperatureColumn {
                name: rows.header[col].clone(),
                values: Vec::new(),
            })
            .collect(),
        current_a: (lay.current.iter())
            .map(|&col| CurrentColumn {
                name: rows.header[col].clone(),
                values: Vec::new(),
            })
            .collect(),
        ..Telemetry::default()
    })
}

/// Appends one row to every column of `tm`.
fn push_telemetry(tm: &mut Telemetry, row: &TelemetryRow) -> std::io::Result<()> {
    tm.t_s.push(row.t_s);
    tm.gyro_rad_s.try_push(row.gyro_rad_s)?;
    if let Some(mag) = tm.mag_nt.as_mut() {
        mag.try_push(row.mag_nt)?;
    }
    for (value, pd) in row.pd_v.iter().zip(tm.pd_v.iter_mut()) {
        pd.try_push(*value)?;
    }
    if let Some(r) = tm.r_gcrf_km.as_mut() {
        r.try_push(row.r_gcrf_km)?;
    }
    for (value, temp) in row.temperature_c.iter().zip(tm.temperature_c.iter_mut()) {
        temp.values.push(*value);
    }
    for (value, cur) in row.current_a.iter().zip(tm.current_a.iter_mut()) {
        cur.values.push(*value);
    }
    Ok(())
}

/// Checks every row of `rows` as [`telemetry_from_rows`] does, keeping none of them (a file
/// of any length in constant memory); the number of rows.
pub(crate) fn check_rows<R: Read>(
    mut rows: CsvRows<'_, R>,
    meta: &DatasetMeta,
) -> Result<usize, DatasetError> {
    let lay = layout(&rows, meta)?;
    let mut n = 0;
    visit_rows(&mut rows, &lay, |_| n += 1)?;
    if n == 0 {
        return Err(rows.no_rows());
    }
    Ok(n)
}

/// Reads and checks each data row of `rows` into one reused [`TelemetryRow`] and hands it
/// to `each`.
fn visit_rows<R: Read>(
    rows: &mut CsvRows<'_, R>,
    lay: &Layout,
    mut each: impl FnMut(&TelemetryRow),
) -> Result<(), DatasetError> {
    let mut row = TelemetryRow {
        pd_v: vec![None; lay.pd.len()],
        temperature_c: vec![None; lay.temperature.len()],
        current_a: vec![None; lay.current.len()],
        ..TelemetryRow::default()
    };
    let mut previous = None;
    while let Some(line) = rows.next_row()? {
        let t = rows.req(line, lay.t)?;
        rows.increasing(line, lay.t, previous, t)?;
        previous = Some(t);
        row.t_s = t;
        row.gyro_rad_s = match lay.gyro {
            Some(cols) => rows.vec3(line, cols)?,
            None => None,
        };
        row.mag_nt = match lay.mag {
            Some(cols) => rows.vec3(line, cols)?,
            None => None,
        };
        for (&col, pd) in lay.pd.iter().zip(row.pd_v.iter_mut()) {
            *pd = rows.opt(line, col)?;
        }
        row.r_gcrf_km = match lay.r {
            Some(cols) => rows.vec3(line, cols)?,
            None => None,
        };
        for (&col, temp) in lay.temperature.iter().zip(row.temperature_c.iter_mut()) {
            let value = rows.opt(line, col)?;
            if let Some(v) = value
                && !(TEMPERATURE_RANGE_C.0..=TEMPERATURE_RANGE_C.1).contains(&v)
            {
                let kind = ErrorKind::OutOfRange {
                    value: v,
                    rule: format!(
                        "a temperature must lie within {} .. {} C",
                        TEMPERATURE_RANGE_C.0, TEMPERATURE_RANGE_C.1
                    ),
                };
                return Err(rows.cell_error(line, col, kind));
            }
            *temp = value;
        }
        for (&col, cur) in lay.current.iter().zip(row.current_a.iter_mut()) {
            let value = rows.opt(line, col)?;
            if let Some(v) = value
                && !(CURRENT_RANGE_A.0..=CURRENT_RANGE_A.1).contains(&v)
            {
                let kind = ErrorKind::OutOfRange {
                    value: v,
                    rule: format!(
                        "a current must lie within {} .. {} A (milliamperes or counts: convert them \
                         with pdcal import's units)",
                        CURRENT_RANGE_A.0, CURRENT_RANGE_A.1
                    ),
                };
                return Err(rows.cell_error(line, col, kind));
            }
            *cur = value;
        }
        each(&row);
    }
    Ok(())
}

/// One row of telemetry.csv, in the dataset's units (the unit of a streamed writer or
/// reader: [`crate::TelemetryStream`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TelemetryRow {
    /// Seconds since `epoch_utc`.
    pub t_s: f64,
    /// Gyro rate, body frame, rad/s; `None` when not sampled.
    pub gyro_rad_s: Option<Vector3<f64>>,
    /// Magnetometer, body frame, nT; `None` when not sampled or absent.
    pub mag_nt: Option<Vector3<f64>>,
    /// Photodiode outputs, V, one per photodiode.
    pub pd_v: Vec<Option<f64>>,
    /// Position, GCRF, km; `None` when not sampled or absent.
    pub r_gcrf_km: Option<Vector3<f64>>,
    /// The temperature columns' values, degrees Celsius, in column order.
    pub temperature_c: Vec<Option<f64>>,
    /// The current columns' values, amperes, in column order.
    pub current_a: Vec<Option<f64>>,
}

/// telemetry.csv's header: `t_s`, gyro, magnetometer (if any), `pd01_V`.., position (if
/// any), the temperature columns in their order, the current columns in theirs.
pub(crate) fn header(
    mag: bool,
    photodiodes: usize,
    r: bool,
    temperatures: &[String],
    currents: &[String],
) -> String {
    let mut header: Vec<String> = vec![columns::T_S.into()];
    header.extend(columns::GYRO.map(String::from));
    if mag {
        header.extend(columns::MAG.map(String::from));
    }
    header.extend((1..=photodiodes).map(photodiode_column));
    if r {
        header.extend(columns::R.map(String::from));
    }
    header.extend(temperatures.iter().cloned());
    header.extend(currents.iter().cloned());
    header.join(",")
}

/// Appends `row` as one telemetry.csv line (the cells of `header`'s columns).
pub(crate) fn push_telemetry_row(out: &mut String, row: &TelemetryRow, mag: bool, r: bool) {
    let split = |v: Option<Vector3<f64>>| [v.map(|v| v.x), v.map(|v| v.y), v.map(|v| v.z)];
    let mut cells = vec![Some(row.t_s)];
    cells.extend(split(row.gyro_rad_s));
    if mag {
        cells.extend(split(row.mag_nt));
    }
    cells.extend(row.pd_v.iter().copied());
    if r {
        cells.extend(split(row.r_gcrf_km));
    }
    cells.extend(row.temperature_c.iter().copied());
    cells.extend(row.current_a.iter().copied());
    push_row(out, cells);
}

/// Checks that every column has one entry per row and the photodiode and position columns
/// match dataset.ron, so that rendering cannot index out of bounds.
pub(crate) fn check_shape(tm: &Telemetry, meta: &DatasetMeta) -> Result<(), DatasetError> {
    let file = Path::new(crate::TELEMETRY_CSV);
    let n = meta.photodiodes.len();
    if tm.pd_v.len() != n {
        return Err(DatasetError::whole_file(
            file,
            ErrorKind::PhotodiodeCountMismatch {
                in_meta: n,
                what: "the telemetry's photodiode series number".into(),
                found: tm.pd_v.len(),
            },
        ));
    }
    let positions = matches!(meta.orbit, OrbitSpec::PositionColumns);
    if tm.r_gcrf_km.is_some() != positions {
        let name = columns::R[0].to_owned();
        let kind = if positions {
            ErrorKind::MissingColumn {
                name,
                hint: "; orbit: PositionColumns needs positions".into(),
            }
        } else {
            ErrorKind::UnexpectedPositionColumn { name }
        };
        return Err(DatasetError::whole_file(file, kind));
    }
    let mut lengths = vec![("gyro_rad_s".to_owned(), tm.gyro_rad_s.len())];
    lengths.extend(tm.mag_nt.as_ref().map(|m| ("mag_nt".to_owned(), m.len())));
    lengths.extend(
        tm.r_gcrf_km
            .as_ref()
            .map(|r| ("r_gcrf_km".to_owned(), r.len())),
    );
    for (i, pd) in tm.pd_v.iter().enumerate() {
        lengths.push((format!("pd_v[{i}]"), pd.len()));
    }
    for column in &tm.temperature_c {
        lengths.push((column.name.clone(), column.values.len()));
    }
    for column in &tm.current_a {
        lengths.push((column.name.clone(), column.values.len()));
    }
    for (name, len) in lengths {
        if len != tm.len() {
            let kind = ErrorKind::WrongLength {
                expected: tm.len(),
                found: len,
            };
            return Err(DatasetError::whole_file(file, kind).named(name));
        }
    }
    Ok(())
}

/// telemetry.csv text: [`header`], then one line per row.
/// Call [`check_shape`] first.
pub(crate) fn render_telemetry(tm: &Telemetry) -> String {
    let names: Vec<String> = tm.temperature_c.iter().map(|c| c.name.clone()).collect();
    let currents: Vec<String> = tm.current_a.iter().map(|c| c.name.clone()).collect();
    let (mag, r) = (tm.mag_nt.is_some(), tm.r_gcrf_km.is_some());
    let mut out = header(mag, tm.pd_v.len(), r, &names, &currents);
    out.push('\n');
    let mut row = TelemetryRow::default();
    for k in 0..tm.len() {
        row.t_s = tm.t_s[k];
        row.gyro_rad_s = tm.gyro_rad_s.get(k);
        row.mag_nt = (tm.mag_nt.as_ref()).and_then(|c| c.get(k));
        row.pd_v.clear();
        row.pd_v.extend(tm.pd_v.iter().map(|pd| pd.get(k)));
        row.r_gcrf_km = (tm.r_gcrf_km.as_ref()).and_then(|c| c.get(k));
        row.temperature_c.clear();
        row.temperature_c.extend(
            tm.temperature_c
                .iter()
                .map(|c| c.values.get(k).copied().flatten()),
        );
        row.current_a.clear();
        row.current_a.extend(
            tm.current_a
                .iter()
                .map(|c| c.values.get(k).copied().flatten()),
        );
        push_telemetry_row(&mut out, &row, mag, r);
    }
    out
}
