//! The export through a checked map: columns found, cells converted, rows kept or dropped,
//! the dataset built.

use std::path::Path;

use hifitime::Epoch;
use nalgebra::Vector3;
use pdcal_dataset::{Dataset, DatasetMeta, EpochUtc, Telemetry};
use pdcal_ephem::{frames, time};

use crate::error::{ErrorKind, ImportError, clip, line_col, text_of};
use crate::map::{
    ImportMap, MapSpec, OrbitMap, PositionFrame, Sentinels, columns, linear, mounts, orbit_spec,
};
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
}

/// One map column resolved against the export's header.
struct Channel {
    /// Map field path (`photodiodes[2]`).
    path: String,
    /// 0-based cell index.
    index: usize,
    scale: f64,
    offset: f64,
    quantity: Quantity,
    sentinels: Sentinels,
    /// Where the map names it, for cell messages (`map.ron:31`).
    map_line: Option<usize>,
    sentinel_hits: usize,
}

/// Converts the export `bytes` (named `csv_file` in errors) with `map`: every column the map
/// names must be in the header; every cell of those columns must be empty, a number (a time
/// in the map's form) or a sentinel. Rows with an empty or sentinel time are dropped; the
/// kept rows must be in strictly increasing time order. The result has been through the
/// dataset reader.
pub fn convert(map: &ImportMap, csv_file: &Path, bytes: &[u8]) -> Result<Imported, ImportError> {
    let text = text_of(csv_file, bytes.to_vec())?;
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let mut records = reader.records();
    let header = match records.next() {
        Some(Ok(h)) => h,
        Some(Err(e)) => return Err(csv_error(csv_file, &e)),
        None => return Err(ImportError::whole_file(csv_file, ErrorKind::Empty)),
    };
    let header_line = header.position().map_or(1, |p| p.line() as usize);
    let names: Vec<String> = header.iter().map(str::to_owned).collect();
    let locate = map.locator();
    let spec = &map.spec;
    let find = |path: &str, name: &str| -> Result<usize, ImportError> {
        let place = locate.column(name).map(|o| line_col(&map.text, o));
        let mut hits = names.iter().enumerate().filter(|(_, h)| *h == name);
        let Some((first, _)) = hits.next() else {
            let listed: Vec<String> = names.iter().map(|n| format!("{n:?}")).collect();
            let kind = ErrorKind::UnknownColumn {
                name: name.to_owned(),
                csv: file_name(csv_file),
                header_line,
                available: clip(&listed.join(", ")),
            };
            return Err(
                ImportError::maybe_at(&map.file, place, kind).named(format!("{path}.column"))
            );
        };
        if let Some((second, _)) = hits.next() {
            let kind = ErrorKind::AmbiguousColumn {
                name: name.to_owned(),
                first: first + 1,
                second: second + 1,
            };
            return Err(
                ImportError::at(csv_file, header_line, Some(second + 1), kind)
                    .named(name.to_owned()),
            );
        }
        Ok(first)
    };
    let time_index = find("time", &spec.time.column)?;
    let time_map_line = locate
        .column(&spec.time.column)
        .map(|o| line_col(&map.text, o).0);
    let mut channels = Vec::new();
    for (path, column, quantity) in columns(spec) {
        let index = find(&path, &column.column)?;
        // parse_map has checked every unit.
        let (scale, offset) = linear(&column, quantity).unwrap_or((f64::NAN, f64::NAN));
        let sentinels = Sentinels::of(&[&column.sentinels, &spec.sentinels]);
        channels.push(Channel {
            map_line: locate
                .column(&column.column)
                .map(|o| line_col(&map.text, o).0),
            path,
            index,
            scale,
            offset,
            quantity,
            sentinels,
            sentinel_hits: 0,
        });
    }
    let time_sentinels = Sentinels::of(&[&spec.time.sentinels, &spec.sentinels]);

    let n_pd = spec.photodiodes.len();
    let has_mag = spec.mag.is_some();
    let has_r = matches!(spec.orbit, OrbitMap::Positions { .. });
    // Channel order of `columns`: gyro xyz, mag xyz, orbit xyz, photodiodes, temperatures.
    let gyro_at = 0;
    let mag_at = 3;
    let r_at = if has_mag { 6 } else { 3 };
    let pd_at = r_at + if has_r { 3 } else { 0 };
    let temp_at = pd_at + n_pd;

    let mut report = ImportReport::default();
    let mut epochs: Vec<Epoch> = Vec::new();
    let mut lines: Vec<usize> = Vec::new();
    let mut gyro = Vec::new();
    let mut mag = Vec::new();
    let mut r = Vec::new();
    let mut pd: Vec<Vec<Option<f64>>> = vec![Vec::new(); n_pd];
    let mut temperature: Vec<Vec<Option<f64>>> = vec![Vec::new(); spec.temperatures.len()];
    let mut partial = [0usize; 3];
    let mut values = vec![None; channels.len()];
    for record in records {
        let record = record.map_err(|e| csv_error(csv_file, &e))?;
        let line = record.position().map_or(0, |p| p.line() as usize);
        report.rows_read += 1;
        if record.len() != names.len() {
            let kind = ErrorKind::WrongCellCount {
                expected: names.len(),
                found: record.len(),
            };
            return Err(ImportError::at(csv_file, line, None, kind));
        }
        let cell_error = |index: usize, kind: ErrorKind| {
            ImportError::at(csv_file, line, Some(index + 1), kind).named(names[index].clone())
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
        if let (Some(&previous), Some(&previous_line)) = (epochs.last(), lines.last())
            && epoch <= previous
        {
            let kind = ErrorKind::TimeNotIncreasing {
                value: time::format_utc(epoch),
                previous: time::format_utc(previous),
                previous_line,
            };
            return Err(cell_error(time_index, kind));
        }
        for (channel, value) in channels.iter_mut().zip(values.iter_mut()) {
            let cell = record.get(channel.index).unwrap_or("");
            *value = channel
                .read(cell, context)
                .map_err(|k| cell_error(channel.index, k))?;
        }
        let vector = |at: usize, count: &mut usize| match values[at..at + 3] {
            [Some(x), Some(y), Some(z)] => Some(Vector3::new(x, y, z)),
            [None, None, None] => None,
            _ => {
                *count += 1;
                None
            }
        };
        gyro.push(vector(gyro_at, &mut partial[0]));
        if has_mag {
            mag.push(vector(mag_at, &mut partial[1]));
        }
        if has_r {
            r.push(vector(r_at, &mut partial[2]));
        }
        for (i, series) in pd.iter_mut().enumerate() {
            series.push(values[pd_at + i]);
        }
        for (i, series) in temperature.iter_mut().enumerate() {
            series.push(values[temp_at + i]);
        }
        epochs.push(epoch);
        lines.push(line);
    }
    let (Some(&first), Some(&last)) = (epochs.first(), epochs.last()) else {
        let dropped = report.dropped_blank_time + report.dropped_sentinel_time;
        return Err(ImportError::whole_file(
            csv_file,
            ErrorKind::NoRows { dropped },
        ));
    };
    // The epoch as dataset.ron will hold it (microseconds, none when whole), so that t_s
    // counts from exactly the instant the file names.
    let full = time::format_utc(first);
    let epoch_text = match full.strip_suffix(".000000Z") {
        Some(whole) => format!("{whole}Z"),
        None => full,
    };
    let epoch_utc = EpochUtc::parse(&epoch_text).map_err(|kind| {
        let kind = ErrorKind::BadTime {
            value: epoch_text.clone(),
            form: "a dataset epoch",
            reason: clip(&kind.to_string()),
        };
        ImportError::at(csv_file, lines[0], Some(time_index + 1), kind)
    })?;
    let t_s: Vec<f64> = (epochs.iter())
        .map(|&e| time::seconds_between(epoch_utc.epoch(), e))
        .collect();
    let r_gcrf_km = match &spec.orbit {
        OrbitMap::Positions {
            frame: PositionFrame::Teme,
            ..
        } => Some(
            r.iter()
                .zip(&epochs)
                .map(|(v, &e)| v.map(|v| frames::teme_to_gcrf(e) * v))
                .collect(),
        ),
        OrbitMap::Positions { .. } => Some(r),
        OrbitMap::Tle { .. } => None,
    };
    report.rows_kept = t_s.len();
    report.epoch_utc = epoch_text;
    report.span_s = time::seconds_between(first, last);
    report.sentinel_cells = (channels.iter())
        .filter(|c| c.sentinel_hits > 0)
        .map(|c| (c.path.clone(), names[c.index].clone(), c.sentinel_hits))
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
    let dataset = Dataset {
        meta: DatasetMeta {
            format_version: pdcal_dataset::FORMAT_VERSION,
            name,
            epoch_utc,
            orbit: orbit_spec(&spec.orbit),
            photodiodes: mounts(spec),
            noise: spec.noise,
        },
        telemetry: Telemetry {
            t_s,
            gyro_rad_s: gyro,
            mag_nt: has_mag.then_some(mag),
            pd_v: pd.into_iter().map(|c| c.into_iter().collect()).collect(),
            r_gcrf_km,
            temperature_c: temperature_columns(spec, temperature),
        },
        truth: None,
    };
    pdcal_dataset::render_dataset(&dataset)?;
    Ok(Imported { dataset, report })
}

impl Channel {
    /// A cell in the dataset's unit: `None` when empty or a sentinel (counted), else the
    /// converted number, or the error for the cell (`context` says what the map reads it as,
    /// given this channel's field path and map line).
    fn read(
        &mut self,
        cell: &str,
        context: impl Fn(&str, Option<usize>) -> String,
    ) -> Result<Option<f64>, ErrorKind> {
        let value = self.convert(cell, || context(&self.path, self.map_line))?;
        if value.is_none() && !cell.is_empty() {
            self.sentinel_hits += 1;
        }
        Ok(value)
    }

    /// [`Channel::read`] without the count: `None` for an empty or sentinel cell.
    fn convert(&self, cell: &str, context: impl Fn() -> String) -> Result<Option<f64>, ErrorKind> {
        if cell.is_empty() || self.sentinels.text(cell) {
            return Ok(None);
        }
        let raw = number(cell, &context)?;
        if self.sentinels.number(raw) {
            return Ok(None);
        }
        let value = raw * self.scale + self.offset;
        if !value.is_finite() {
            return Err(ErrorKind::NotFinite {
                value: cell.to_owned(),
                context: format!(
                    "{}: it overflows when converted to the dataset's unit",
                    context()
                ),
            });
        }
        let (low, high) = pdcal_dataset::TEMPERATURE_RANGE_C;
        if self.quantity == Quantity::Temperature && !(low..=high).contains(&value) {
            return Err(ErrorKind::ImplausibleTemperature {
                value: cell.to_owned(),
                celsius: value,
                low,
                high,
                context: context(),
            });
        }
        Ok(Some(value))
    }
}

/// telemetry.csv's temperature columns of the map's entries, in map order.
fn temperature_columns(
    spec: &MapSpec,
    series: Vec<Vec<Option<f64>>>,
) -> Vec<pdcal_dataset::TemperatureColumn> {
    (spec.temperatures.iter())
        .zip(series)
        .map(|(t, values)| pdcal_dataset::TemperatureColumn {
            // parse_map has checked that exactly one of the two is given.
            name: match (t.photodiode, &t.panel) {
                (Some(k), _) => pdcal_dataset::photodiode_temperature_column(k),
                (None, panel) => {
                    pdcal_dataset::panel_temperature_column(panel.as_deref().unwrap_or(""))
                }
            },
            values,
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

fn csv_error(file: &Path, e: &csv::Error) -> ImportError {
    let kind = ErrorKind::Csv {
        message: clip(&e.to_string()),
    };
    match e.position() {
        Some(p) => ImportError::at(file, p.line() as usize, None, kind),
        None => ImportError::whole_file(file, kind),
    }
}

fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}
