//! A dataset written row by row (an import of an export of any length in constant memory):
//! telemetry.csv streamed into the staging directory of a [`DatasetWriter`], then dataset.ron,
//! then the whole staged telemetry.csv read back through the reader's checks, keeping no row,
//! before the directory is published. What is published is what [`crate::read_dataset`]
//! accepts, as with [`DatasetWriter::write`].

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::PathBuf;

use crate::error::io_error;
use crate::error::{DatasetError, ErrorKind};
use crate::files::{DatasetWriter, write_synced};
use crate::meta::{DatasetMeta, OrbitSpec, meta_from_str, render_meta};
use crate::table::CsvRows;
use crate::telemetry::{TelemetryRow, check_rows, header, push_telemetry_row};
use crate::{DATASET_RON, TELEMETRY_CSV};

/// The columns of a streamed telemetry.csv.
#[derive(Clone, Debug, PartialEq)]
pub struct TelemetryLayout {
    /// Number of photodiodes (`pd01_V` ..).
    pub photodiodes: usize,
    /// Whether there are `mag_*_nT` columns.
    pub magnetometer: bool,
    /// Whether there are `r_*_km` columns (`orbit: PositionColumns`).
    pub positions: bool,
    /// The `temp_*_C` headers, in column order.
    pub temperatures: Vec<String>,
    /// The `cur_<name>_A` headers, in column order.
    pub currents: Vec<String>,
}

/// telemetry.csv being written into a staging directory, one row at a time.
#[derive(Debug)]
pub struct TelemetryStream {
    out: BufWriter<File>,
    file: PathBuf,
    layout: TelemetryLayout,
    line: String,
    rows: usize,
}

impl TelemetryStream {
    /// Appends one row; its photodiode, temperature and current counts must be the layout's.
    pub fn push(&mut self, row: &TelemetryRow) -> Result<(), DatasetError> {
        let lay = &self.layout;
        if row.pd_v.len() != lay.photodiodes
            || row.temperature_c.len() != lay.temperatures.len()
            || row.current_a.len() != lay.currents.len()
        {
            let kind = ErrorKind::WrongLength {
                expected: lay.photodiodes + lay.temperatures.len() + lay.currents.len(),
                found: row.pd_v.len() + row.temperature_c.len() + row.current_a.len(),
            };
            return Err(DatasetError::whole_file(&self.file, kind).named("row"));
        }
        self.line.clear();
        push_telemetry_row(&mut self.line, row, lay.magnetometer, lay.positions);
        self.out
            .write_all(self.line.as_bytes())
            .map_err(|e| io_error(&self.file, "cannot write", e))?;
        self.rows += 1;
        Ok(())
    }

    /// Rows written so far.
    pub fn rows(&self) -> usize {
        self.rows
    }
}

impl DatasetWriter {
    /// Starts telemetry.csv in the staging directory: its header is written now, the rows by
    /// [`TelemetryStream::push`]; [`DatasetWriter::finish_stream`] completes the dataset.
    pub fn telemetry_stream(
        &self,
        layout: TelemetryLayout,
    ) -> Result<TelemetryStream, DatasetError> {
        let file = self.staging().join(TELEMETRY_CSV);
        let created = File::create(&file).map_err(|e| io_error(&file, "cannot create", e))?;
        let mut out = BufWriter::with_capacity(1 << 16, created);
        let mut text = header(
            layout.magnetometer,
            layout.photodiodes,
            layout.positions,
            &layout.temperatures,
            &layout.currents,
        );
        text.push('\n');
        out.write_all(text.as_bytes())
            .map_err(|e| io_error(&file, "cannot write", e))?;
        Ok(TelemetryStream {
            out,
            file,
            layout,
            line: String::new(),
            rows: 0,
        })
    }

    /// Writes dataset.ron for `meta`, checks the dataset as the reader would (dataset.ron
    /// and every row of the staged telemetry.csv, streamed), and publishes it in one step;
    /// on any failure an existing directory is kept as it was.
    pub fn finish_stream(
        self,
        meta: &DatasetMeta,
        stream: TelemetryStream,
    ) -> Result<(), DatasetError> {
        let TelemetryStream {
            out, file, layout, ..
        } = stream;
        let synced = out
            .into_inner()
            .map_err(|e| e.into_error())
            .and_then(|f| f.sync_all());
        synced.map_err(|e| io_error(&file, "cannot write", e))?;
        let positions = matches!(meta.orbit, OrbitSpec::PositionColumns);
        if layout.photodiodes != meta.photodiodes.len() || layout.positions != positions {
            let message = format!(
                "the streamed telemetry has {} photodiodes and {} positions, dataset.ron {} and {}",
                layout.photodiodes,
                if layout.positions { "" } else { "no" },
                meta.photodiodes.len(),
                if positions { "positions" } else { "a TLE" },
            );
            return Err(DatasetError::whole_file(
                &file,
                ErrorKind::Output { message },
            ));
        }
        let meta_text = render_meta(meta)?;
        let checked = meta_from_str(&meta_text)?;
        write_synced(&self.staging().join(DATASET_RON), &meta_text)?;
        let source = File::open(&file).map_err(|e| io_error(&file, "cannot read", e))?;
        let reader = std::io::BufReader::with_capacity(1 << 16, source);
        check_rows(CsvRows::from_reader(&file, reader)?, &checked)?;
        self.publish_staged()
    }
}
