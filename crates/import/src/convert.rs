//! The export through a checked map: columns found, cells converted, rows kept or dropped,
//! the dataset built.

use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

use csv::StringRecord;
use hifitime::Epoch;
use nalgebra::Vector3;
use pdcal_dataset::{
    Dataset, DatasetMeta, EpochUtc, FileFaultKind, Telemetry, TelemetryLayout, TelemetryRow,
};
use pdcal_ephem::{frames, time};

use crate::error::{ErrorKind, ImportError, clip, line_col, quote};
use crate::map::{
    Delimiter, DuplicateTimes, ImportMap, MapSpec, OrbitMap, PositionFrame, Sentinels, columns,
    linear, mounts, orbit_spec,
};
use crate::source::Records;
use crate::timeform::TimeFault;
use crate::units::Quantity;

/// A dataset made from an export, and what was done to the rows.
#[derive(Clone, Debug)]
pub struct Imported {
    /// The dataset, accepted by the dataset reader (no truth).
    pub dataset: Dataset,
    /// Counts of dropped rows and blanked cells.
    pub report: ImportReport,
}

/// What the import dropped or blanked, for the user to judge the export by.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ImportReport {
    /// Data rows in the export.
    pub rows_read: usize,
    /// Rows in the dataset.
    pub rows_kept: usize,
    /// Rows dropped because their time cell was empty.
    pub dropped_blank_time: usize,
    /// Rows dropped because their time cell held a sentinel.
    pub dropped_sentinel_time: usize,
    /// Per map column (field path, header): cells that held a sentinel and became empty.
    pub sentinel_cells: Vec<(String, String, usize)>,
    /// Per vector sensor (`gyro`, `mag`, `orbit`): rows where some but not all components
    /// were present; the dataset samples a vector whole or not at all, so these are empty.
    pub partial_vectors: Vec<(String, usize)>,
    /// The dataset's epoch: the first kept row's time, ISO 8601 UTC.
    pub epoch_utc: String,
    /// Time from the first to the last kept row, s.
    pub span_s: f64,
    /// The delimiter read with, and whether it was detected from the header (not given).
    pub delimiter: Option<(Delimiter, bool)>,
    /// The map's rule for rows of one time.
    pub duplicate_times: DuplicateTimes,
    /// Rows whose time equals the previous kept row's: dropped (`KeepFirst`) or averaged
    /// into it (`Average`).
    pub duplicate_rows: usize,
}

/// One map column resolved against the export's header.
struct Channel {
    /// Map field path (`photodiodes[2]`).
    path: String,
    /// How the output names it: the header, or the combination written out.
    label: String,
    /// 0-based cell index and coefficient of each term (one term of coefficient 1 for a
    /// plain column).
    terms: Vec<(usize, f64)>,
    scale: f64,
    offset: f64,
    quantity: Quantity,
    sentinels: Sentinels,
    /// Where the map names it, for cell messages (`map.ron:31`).
    map_line: Option<usize>,
    sentinel_hits: usize,
}

/// The dataset made by a [`convert_stream`]: its dataset.ron, and what was done to the rows.
#[derive(Clone, Debug)]
pub struct Converted {
    /// dataset.ron of the rows handed to the sink.
    pub meta: DatasetMeta,
    /// Counts of dropped rows and blanked cells.
    pub report: ImportReport,
}

/// The telemetry.csv columns an import with `map` writes.
pub fn layout(map: &ImportMap) -> TelemetryLayout {
    let spec = &map.spec;
    TelemetryLayout {
        photodiodes: spec.photodiodes.len(),
        magnetometer: spec.mag.is_some(),
        positions: matches!(spec.orbit, OrbitMap::Positions { .. }),
        temperatures: temperature_names(spec),
        currents: (spec.currents.iter())
            .map(|c| pdcal_dataset::current_column(&c.name))
            .collect(),
    }
}

/// Converts the export `bytes` (named `csv_file` in errors) with `map`, in memory: every
/// column the map names must be in the header; every cell of those columns must be empty,
/// a number (a time in the map's form) or a sentinel. Rows with an empty or sentinel time are
/// dropped; the kept rows must be in time order (rows of one time as the map's
/// `duplicate_times` says). The result has been through the dataset reader. An export too
/// long to hold goes through [`convert_stream`].
pub fn convert(map: &ImportMap, csv_file: &Path, bytes: &[u8]) -> Result<Imported, ImportError> {
    let lay = layout(map);
    let mut telemetry = Telemetry {
        pd_v: vec![Default::default(); lay.photodiodes],
        mag_nt: lay.magnetometer.then(Default::default),
        r_gcrf_km: lay.positions.then(Default::default),
        temperature_c: (lay.temperatures.iter())
            .map(|name| pdcal_dataset::TemperatureColumn {
                name: name.clone(),
                values: Vec::new(),
            })
            .collect(),
        current_a: (lay.currents.iter())
            .map(|name| pdcal_dataset::CurrentColumn {
                name: name.clone(),
                values: Vec::new(),
            })
            .collect(),
        ..Telemetry::default()
    };
    let converted = convert_stream(map, csv_file, bytes, |row| {
        let tm = &mut telemetry;
        tm.t_s.push(row.t_s);
        tm.gyro_rad_s.push(row.gyro_rad_s);
        if let Some(mag) = tm.mag_nt.as_mut() {
            mag.push(row.mag_nt);
        }
        for (pd, value) in tm.pd_v.iter_mut().zip(&row.pd_v) {
            pd.push(*value);
        }
        if let Some(r) = tm.r_gcrf_km.as_mut() {
            r.push(row.r_gcrf_km);
        }
        for (column, value) in tm.temperature_c.iter_mut().zip(&row.temperature_c) {
            column.values.push(*value);
        }
        for (column, value) in tm.current_a.iter_mut().zip(&row.current_a) {
            column.values.push(*value);
        }
        Ok(())
    })?;
    let dataset = Dataset {
        meta: converted.meta,
        telemetry,
        truth: None,
    };
    pdcal_dataset::render_dataset(&dataset)?;
    Ok(Imported {
        dataset,
        report: converted.report,
    })
}

/// [`convert`] reading the export from `source` as it goes and handing each dataset row to
/// `sink` (a [`pdcal_dataset::TelemetryStream`], say), holding no more than one row and the
/// header: memory does not grow with the export's length. The sink's rows are in order and
/// complete only when this returns `Ok`.
pub fn convert_stream<R: Read>(
    map: &ImportMap,
    csv_file: &Path,
    source: R,
    mut sink: impl FnMut(&TelemetryRow) -> Result<(), ImportError>,
) -> Result<Converted, ImportError> {
    let spec = &map.spec;
    let mut records = Records::open(csv_file, source, spec.delimiter)?;
    let mut header = StringRecord::new();
    let header_line = match records.next(&mut header)? {
        Some(line) => line,
        None => {
            return Err(ImportError::whole_file(
                csv_file,
                FileFaultKind::Empty.into(),
            ));
        }
    };
    if header.iter().all(str::is_empty) {
        // A header line of blanks: blank throughout is an empty file, else a missing header.
        let mut rest = StringRecord::new();
        while records.next(&mut rest)?.is_some() {}
        if records.blank_so_far() {
            return Err(ImportError::whole_file(
                csv_file,
                FileFaultKind::Empty.into(),
            ));
        }
    }
    let mut index: HashMap<&str, (usize, Option<usize>)> = HashMap::new();
    for (i, name) in header.iter().enumerate() {
        index
            .entry(name)
            .and_modify(|e| {
                e.1.get_or_insert(i);
            })
            .or_insert((i, None));
    }
    let locate = map.locator();
    let find = |field: &str, name: &str| -> Result<usize, ImportError> {
        match index.get(name) {
            None => {
                let place = locate.column(name).map(|o| line_col(&map.text, o));
                let kind = ErrorKind::UnknownColumn {
                    name: name.to_owned(),
                    csv: file_name(csv_file),
                    header_line,
                    available: listing(&header),
                };
                Err(ImportError::maybe_at(&map.file, place, kind).named(field))
            }
            Some(&(first, Some(second))) => {
                let kind = ErrorKind::AmbiguousColumn {
                    name: name.to_owned(),
                    first: first + 1,
                    second: second + 1,
                };
                Err(
                    ImportError::at(csv_file, header_line, Some(second + 1), kind)
                        .named(name.to_owned()),
                )
            }
            Some(&(first, None)) => Ok(first),
        }
    };
    let time_index = find("time.column", &spec.time.column)?;
    let time_map_line = locate.column(&spec.time.column).map(|o| map.line_of(o));
    let mut channels = Vec::new();
    for (path, column, quantity) in columns(spec) {
        let field = match column.columns {
            Some(_) => format!("{path}.columns"),
            None => format!("{path}.column"),
        };
        let mut terms = Vec::new();
        for (name, coefficient) in column.terms() {
            terms.push((find(&field, &name)?, coefficient));
        }
        // parse_map has checked every unit.
        let (scale, offset) = linear(&column, quantity).unwrap_or((f64::NAN, f64::NAN));
        let sentinels = Sentinels::of(&[&column.sentinels, &spec.sentinels]);
        channels.push(Channel {
            map_line: (column.first_name())
                .and_then(|n| locate.column_of(&path, n))
                .map(|o| map.line_of(o)),
            label: column.label(),
            path,
            terms,
            scale,
            offset,
            quantity,
            sentinels,
            sentinel_hits: 0,
        });
    }
    let time_sentinels = Sentinels::of(&[&spec.time.sentinels, &spec.sentinels]);

    let n_pd = spec.photodiodes.len();
    // Channel order of `columns`: gyro xyz, mag xyz, orbit xyz (each when mapped),
    // photodiodes, temperatures, currents.
    let mut next = 0;
    let mut slot = |present: bool| {
        present.then(|| {
            next += 3;
            next - 3
        })
    };
    let gyro_slot = slot(spec.gyro.is_some());
    let mag_slot = slot(spec.mag.is_some());
    let r_slot = slot(matches!(spec.orbit, OrbitMap::Positions { .. }));
    let slots = Slots {
        gyro: gyro_slot,
        mag: mag_slot,
        r: r_slot,
        pd: next,
        n_pd,
        n_temp: spec.temperatures.len(),
        n_cur: spec.currents.len(),
    };

    let mut report = ImportReport {
        delimiter: Some((records.delimiter, records.detected)),
        duplicate_times: spec.duplicate_times,
        ..ImportReport::default()
    };
    let mut partial = [0usize; 3];
    let mut values = vec![None; channels.len()];
    let mut group: Option<Group> = None;
    let mut first: Option<(Epoch, EpochUtc, usize)> = None;
    let mut last_epoch = None;
    let mut out_row = TelemetryRow {
        pd_v: vec![None; n_pd],
        temperature_c: vec![None; spec.temperatures.len()],
        current_a: vec![None; spec.currents.len()],
        ..TelemetryRow::default()
    };
    let mut emit = |g: &Group,
                    first: &mut Option<(Epoch, EpochUtc, usize)>,
                    rows_kept: &mut usize|
     -> Result<(), ImportError> {
        let epoch_utc = match first {
            Some((_, utc, _)) => utc.clone(),
            None => {
                let utc = dataset_epoch(g.epoch, csv_file, g.line, time_index)?;
                *first = Some((g.epoch, utc.clone(), g.line));
                utc
            }
        };
        out_row.t_s = time::seconds_between(epoch_utc.epoch(), g.epoch);
        g.fill(&slots, &mut out_row);
        if let (
            Some(r),
            OrbitMap::Positions {
                frame: PositionFrame::Teme,
                ..
            },
        ) = (out_row.r_gcrf_km, &spec.orbit)
        {
            out_row.r_gcrf_km = Some(frames::teme_to_gcrf(g.epoch) * r);
        }
        *rows_kept += 1;
        sink(&out_row)
    };
    let mut record = StringRecord::new();
    while let Some(line) = records.next(&mut record)? {
        report.rows_read += 1;
        if record.len() != header.len() {
            let kind = FileFaultKind::WrongCellCount {
                expected: header.len(),
                found: record.len(),
            };
            return Err(ImportError::at(csv_file, line, None, kind.into()));
        }
        let names = &header;
        let cell_error = |index: usize, kind: ErrorKind| {
            ImportError::at(csv_file, line, Some(index + 1), kind)
                .named(names.get(index).unwrap_or("").to_owned())
        };
        let context = |what: &str, map_line: Option<usize>| match map_line {
            Some(l) => format!(" ({what} of {}:{l})", file_name(&map.file)),
            None => format!(" ({what} of {})", file_name(&map.file)),
        };
        // The time: a row without one cannot be placed and is dropped.
        let cell = record.get(time_index).unwrap_or("");
        if cell.is_empty() {
            report.dropped_blank_time += 1;
            continue;
        }
        if time_sentinels.text(cell) {
            report.dropped_sentinel_time += 1;
            continue;
        }
        let form = &spec.time.form;
        let bad_time = |reason: String| {
            cell_error(
                time_index,
                ErrorKind::BadTime {
                    value: cell.to_owned(),
                    form: form.describe(),
                    reason,
                },
            )
        };
        let epoch = if form.is_numeric() {
            let value = number(cell, || {
                context(&format!("time, {}", form.describe()), time_map_line)
            })
            .map_err(|k| cell_error(time_index, k))?;
            if time_sentinels.number(value) {
                report.dropped_sentinel_time += 1;
                continue;
            }
            map.time
                .read_number(value)
                .map_err(|TimeFault(w)| bad_time(w))?
        } else {
            map.time
                .read_text(cell)
                .map_err(|TimeFault(w)| bad_time(w))?
        };
        let same_time = match (&group, last_epoch) {
            (Some(g), Some(previous)) if epoch == previous => {
                match spec.duplicate_times {
                    DuplicateTimes::Refuse => {
                        let kind = ErrorKind::DuplicateTime {
                            value: time::format_utc(epoch),
                            previous_line: g.line,
                        };
                        return Err(cell_error(time_index, kind));
                    }
                    DuplicateTimes::KeepFirst | DuplicateTimes::Average => {}
                }
                true
            }
            (Some(g), Some(previous)) if epoch < previous => {
                let kind = ErrorKind::TimeNotIncreasing {
                    value: time::format_utc(epoch),
                    previous: time::format_utc(previous),
                    previous_line: g.line,
                };
                return Err(cell_error(time_index, kind));
            }
            _ => false,
        };
        for (channel, value) in channels.iter_mut().zip(values.iter_mut()) {
            *value = channel
                .read(&record, context)
                .map_err(|(i, k)| cell_error(i, k))?;
        }
        let vector = |at: usize, count: &mut usize| match values[at..at + 3] {
            [Some(x), Some(y), Some(z)] => Some(Vector3::new(x, y, z)),
            [None, None, None] => None,
            _ => {
                *count += 1;
                None
            }
        };
        let gyro = slots.gyro.and_then(|at| vector(at, &mut partial[0]));
        let mag = slots.mag.and_then(|at| vector(at, &mut partial[1]));
        let r = slots.r.and_then(|at| vector(at, &mut partial[2]));
        if same_time {
            report.duplicate_rows += 1;
            if let (DuplicateTimes::Average, Some(g)) = (spec.duplicate_times, group.as_mut()) {
                g.add(gyro, mag, r, &values[slots.pd..]);
            }
            continue;
        }
        if let Some(g) = group.take() {
            emit(&g, &mut first, &mut report.rows_kept)?;
        }
        let mut g = Group::new(epoch, line, &slots);
        g.add(gyro, mag, r, &values[slots.pd..]);
        group = Some(g);
        last_epoch = Some(epoch);
    }
    if let Some(g) = group.take() {
        emit(&g, &mut first, &mut report.rows_kept)?;
    }
    let (Some((first_epoch, epoch_utc, _)), Some(last)) = (first, last_epoch) else {
        let dropped = report.dropped_blank_time + report.dropped_sentinel_time;
        return Err(ImportError::whole_file(
            csv_file,
            ErrorKind::NoRows { dropped },
        ));
    };
    report.epoch_utc = epoch_utc.as_str().to_owned();
    report.span_s = time::seconds_between(first_epoch, last);
    report.sentinel_cells = (channels.iter())
        .filter(|c| c.sentinel_hits > 0)
        .map(|c| (c.path.clone(), c.label.clone(), c.sentinel_hits))
        .collect();
    report.partial_vectors = ["gyro", "mag", "orbit"]
        .iter()
        .zip(partial)
        .filter(|(_, n)| *n > 0)
        .map(|(s, n)| ((*s).to_owned(), n))
        .collect();
    let name = spec.name.clone().unwrap_or_else(|| {
        csv_file.file_stem().map_or_else(
            || "imported".to_owned(),
            |s| s.to_string_lossy().into_owned(),
        )
    });
    let meta = DatasetMeta {
        format_version: pdcal_dataset::FORMAT_VERSION,
        name,
        epoch_utc,
        orbit: orbit_spec(&spec.orbit),
        photodiodes: mounts(spec),
        noise: spec.noise,
        inertia_kg_m2: spec.inertia_kg_m2,
    };
    Ok(Converted { meta, report })
}

/// Where each sensor's values are among the channels' (the order of `columns`).
struct Slots {
    gyro: Option<usize>,
    mag: Option<usize>,
    r: Option<usize>,
    pd: usize,
    n_pd: usize,
    n_temp: usize,
    /// Current channels (after the temperatures).
    n_cur: usize,
}

/// The rows of one time: the first row's values, or under `Average` the running means of
/// the non-empty ones.
struct Group {
    epoch: Epoch,
    line: usize,
    gyro: Mean3,
    mag: Mean3,
    r: Mean3,
    /// Photodiodes, then temperatures, then currents.
    scalars: Vec<Mean>,
}

#[derive(Clone, Copy, Default)]
struct Mean {
    value: f64,
    n: u32,
}

impl Mean {
    /// A running mean (not a sum divided at the end: no overflow, and one value, or several
    /// equal ones, come out bit for bit).
    fn add(&mut self, x: Option<f64>) {
        if let Some(x) = x {
            self.n = self.n.saturating_add(1);
            self.value += (x - self.value) / f64::from(self.n);
        }
    }

    fn get(self) -> Option<f64> {
        (self.n > 0).then_some(self.value)
    }
}

#[derive(Clone, Copy, Default)]
struct Mean3 {
    value: Vector3<f64>,
    n: u32,
}

impl Mean3 {
    fn add(&mut self, v: Option<Vector3<f64>>) {
        if let Some(v) = v {
            self.n = self.n.saturating_add(1);
            self.value += (v - self.value) / f64::from(self.n);
        }
    }

    fn get(self) -> Option<Vector3<f64>> {
        (self.n > 0).then_some(self.value)
    }
}

impl Group {
    fn new(epoch: Epoch, line: usize, slots: &Slots) -> Self {
        Group {
            epoch,
            line,
            gyro: Mean3::default(),
            mag: Mean3::default(),
            r: Mean3::default(),
            scalars: vec![Mean::default(); slots.n_pd + slots.n_temp + slots.n_cur],
        }
    }

    fn add(
        &mut self,
        gyro: Option<Vector3<f64>>,
        mag: Option<Vector3<f64>>,
        r: Option<Vector3<f64>>,
        scalars: &[Option<f64>],
    ) {
        self.gyro.add(gyro);
        self.mag.add(mag);
        self.r.add(r);
        for (mean, x) in self.scalars.iter_mut().zip(scalars) {
            mean.add(*x);
        }
    }

    fn fill(&self, slots: &Slots, row: &mut TelemetryRow) {
        row.gyro_rad_s = slots.gyro.and(self.gyro.get());
        row.mag_nt = slots.mag.and(self.mag.get());
        row.r_gcrf_km = slots.r.and(self.r.get());
        let (pd, rest) = self.scalars.split_at(slots.n_pd);
        let (temp, cur) = rest.split_at(slots.n_temp.min(rest.len()));
        for (out, mean) in row.pd_v.iter_mut().zip(pd) {
            *out = mean.get();
        }
        for (out, mean) in row.temperature_c.iter_mut().zip(temp) {
            *out = mean.get();
        }
        for (out, mean) in row.current_a.iter_mut().zip(cur) {
            *out = mean.get();
        }
    }
}

/// The dataset's epoch for the first kept row's time, as dataset.ron will hold it
/// (microseconds, none when whole), so that t_s counts from exactly the instant the file
/// names.
fn dataset_epoch(
    epoch: Epoch,
    csv_file: &Path,
    line: usize,
    time_index: usize,
) -> Result<EpochUtc, ImportError> {
    let full = time::format_utc(epoch);
    let epoch_text = match full.strip_suffix(".000000Z") {
        Some(whole) => format!("{whole}Z"),
        None => full,
    };
    EpochUtc::parse(&epoch_text).map_err(|kind| {
        let kind = ErrorKind::BadTime {
            value: epoch_text.clone(),
            form: "a dataset epoch",
            reason: clip(&kind.to_string()),
        };
        ImportError::at(csv_file, line, Some(time_index + 1), kind)
    })
}

/// The header's names for a message: quoted, escaped, as many as fit in about
/// [`pdcal_text::QUOTE_MAX_CHARS`] characters, then how many there are.
fn listing(header: &StringRecord) -> String {
    let mut out = String::new();
    for (i, name) in header.iter().enumerate() {
        if out.chars().count() > pdcal_text::QUOTE_MAX_CHARS {
            return format!("{out}, ... ({} columns)", header.len());
        }
        if i > 0 {
            out.push_str(", ");
        }
        out.push_str(&quote(name));
    }
    out
}

impl Channel {
    /// The channel's value on `record` in the dataset's unit: `None` when a term's cell is
    /// empty or a sentinel (counted when a sentinel), else the converted combination, or the
    /// error with the cell it is about (`context` says what the map reads it as, given this
    /// channel's field path and map line).
    fn read(
        &mut self,
        record: &StringRecord,
        context: impl Fn(&str, Option<usize>) -> String,
    ) -> Result<Option<f64>, (usize, ErrorKind)> {
        let what = || context(&self.path, self.map_line);
        let mut sum = 0.0;
        let mut blank = false;
        let mut hit = false;
        for &(index, coefficient) in &self.terms {
            let cell = record.get(index).unwrap_or("");
            if cell.is_empty() {
                blank = true;
                continue;
            }
            if self.sentinels.text(cell) {
                hit = true;
                continue;
            }
            let raw = number(cell, what).map_err(|k| (index, k))?;
            if self.sentinels.number(raw) {
                hit = true;
                continue;
            }
            sum += coefficient * raw;
        }
        if hit {
            self.sentinel_hits += 1;
        }
        if hit || blank {
            return Ok(None);
        }
        let at = self.terms.first().map_or(0, |t| t.0);
        let cell = record.get(at).unwrap_or("");
        let value = sum * self.scale + self.offset;
        if !value.is_finite() {
            return Err((
                at,
                ErrorKind::NotFinite {
                    value: cell.to_owned(),
                    context: format!(
                        "{}: it overflows when converted to the dataset's unit",
                        what()
                    ),
                },
            ));
        }
        let (low, high) = pdcal_dataset::TEMPERATURE_RANGE_C;
        if self.quantity == Quantity::Temperature && !(low..=high).contains(&value) {
            return Err((
                at,
                ErrorKind::ImplausibleTemperature {
                    value: cell.to_owned(),
                    celsius: value,
                    low,
                    high,
                    context: what(),
                },
            ));
        }
        let (low, high) = pdcal_dataset::CURRENT_RANGE_A;
        if self.quantity == Quantity::Current && !(low..=high).contains(&value) {
            return Err((
                at,
                ErrorKind::ImplausibleCurrent {
                    value: cell.to_owned(),
                    amperes: value,
                    low,
                    high,
                    context: what(),
                },
            ));
        }
        Ok(Some(value))
    }
}

/// telemetry.csv's temperature column names of the map's entries, in map order.
fn temperature_names(spec: &MapSpec) -> Vec<String> {
    (spec.temperatures.iter())
        .map(|t| match (t.photodiode, &t.panel) {
            // parse_map has checked that exactly one of the two is given.
            (Some(k), _) => pdcal_dataset::photodiode_temperature_column(k),
            (None, panel) => {
                pdcal_dataset::panel_temperature_column(panel.as_deref().unwrap_or(""))
            }
        })
        .collect()
}

/// A finite number, or the error for the cell (with `context`, what the map reads it as).
fn number(cell: &str, context: impl Fn() -> String) -> Result<f64, ErrorKind> {
    match cell.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(ErrorKind::NotFinite {
            value: cell.to_owned(),
            context: context(),
        }),
        Err(_) => Err(ErrorKind::NotANumber {
            value: cell.to_owned(),
            context: context(),
        }),
    }
}

fn file_name(path: &Path) -> String {
    path.file_name()
        .map_or_else(|| pdcal_text::path(path), pdcal_text::path)
}
