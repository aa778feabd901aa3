//! The sink of a streaming calibration ([`pdcal_filter::calibrate_streaming`]): writes
//! `estimates.csv`, `residuals.csv` and `estimates_smoothed.csv` into the staging directory
//! as the rows are produced, and keeps only what the summary and the figures need: the
//! residual statistics over every row and the estimates and residuals of every
//! `stride`-th row for the figures. The attitude per row for the Sun-vector metrics goes
//! to a spill file in the staging directory (40 bytes a row on disk, [`AttitudeSpill`]),
//! read back once the calibration is final.
//!
//! The smoothed rows arrive in segments, last segment first: each is appended to a spill
//! file in the staging directory with its byte range, and [`StreamSink::finish`] copies
//! the ranges in row order into `estimates_smoothed.csv`, shortening the spill behind each
//! range it copied (the last range appended is the first in row order), and removes it.

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use pdcal_attitude::Quat;
use pdcal_filter::{
    Consistency, ConsistencyAccumulator, ResidualRecord, RunSink, Sensor, SensorSigmas,
    StepEstimate,
};

use crate::output::OutputDir;
use crate::rows::{RESIDUAL_COLUMNS, estimate_header, estimate_row, residual_row};
use crate::schema::ResidualSummary;

/// Asked every [`pdcal_filter::CANCEL_POLL_ROWS`] rows of a calibration whether to stop
/// (an interactive session's interrupt); the run then fails with
/// [`pdcal_filter::FilterError::Cancelled`] and publishes nothing.
pub type CancelCheck = Box<dyn FnMut() -> bool>;

/// Largest number of points a figure's time series keeps.
pub const FIGURE_POINTS: usize = 4000;

/// Every `stride`-th row keeps at most [`FIGURE_POINTS`] of `rows`.
pub fn stride_for(rows: usize) -> usize {
    rows.div_ceil(FIGURE_POINTS).max(1)
}

/// What a finished [`StreamSink`] keeps.
pub struct Streamed {
    /// The attitude per row (smoothed when the smoother ran), on disk.
    pub attitudes: AttitudeSpill,
    /// Photodiode residual statistics over every row.
    pub residual_summary: ResidualSummary,
    /// Every `stride`-th forward estimate.
    pub forward_sample: Vec<StepEstimate>,
    /// The residuals of those rows.
    pub residual_sample: Vec<ResidualRecord>,
    /// Photodiode residual statistics per data set of a joint calibration
    /// ([`StreamSink::with_sets`]; one entry otherwise).
    pub set_residuals: Vec<ResidualSummary>,
    /// The consistency verdict over every row.
    pub consistency: Consistency,
    /// The consistency verdict per data set (one entry without sets).
    pub set_consistency: Vec<Consistency>,
}

/// Sums of the photodiode residuals of one data set: squares, inside 3 sigma, count.
#[derive(Debug, Clone, Copy, Default)]
struct ResidualSums {
    sum_sq: f64,
    inside: usize,
    count: usize,
}

/// Streams the per-row outputs of a calibration into the staging directory.
pub struct StreamSink {
    m: usize,
    stride: usize,
    smoother: bool,
    estimates: csv::Writer<BufWriter<File>>,
    estimates_header: bool,
    residuals: csv::Writer<BufWriter<File>>,
    spill: csv::Writer<BufWriter<File>>,
    spill_path: PathBuf,
    smoothed_path: PathBuf,
    smoothed_header: Option<Vec<String>>,
    /// Byte ranges of the smoothed segments in the spill, in arrival order.
    segments: Vec<(u64, u64)>,
    /// Attitudes for the Sun-vector metrics: forward, or smoothed in arrival order.
    attitudes: AttitudeSpill,
    forward_sample: Vec<StepEstimate>,
    residual_sample: Vec<ResidualRecord>,
    pd_count: usize,
    pd_sum_sq: f64,
    pd_inside: usize,
    /// First row of each data set, and its residual sums.
    set_starts: Vec<usize>,
    set_sums: Vec<ResidualSums>,
    consistency: ConsistencyAccumulator,
    set_consistency: Vec<ConsistencyAccumulator>,
    error: Option<anyhow::Error>,
    cancel: Option<CancelCheck>,
    estimates_path: PathBuf,
    residuals_path: PathBuf,
}

/// `cannot write PATH` for an error writing `path` (a full disk says which file).
fn writing(path: &Path) -> impl Fn() -> String + '_ {
    move || format!("cannot write {}", pdcal_text::path(path))
}

fn create(path: &Path) -> Result<csv::Writer<BufWriter<File>>> {
    let file =
        File::create(path).with_context(|| format!("cannot create {}", pdcal_text::path(path)))?;
    Ok(csv::Writer::from_writer(BufWriter::new(file)))
}

impl StreamSink {
    /// Files in `dir` for `m` photodiodes over at most `rows` rows; `sigmas` are the sensor
    /// noises the run uses (the consistency verdict's yardstick).
    pub fn new(
        dir: &OutputDir,
        m: usize,
        rows: usize,
        smoother: bool,
        sigmas: &SensorSigmas,
    ) -> Result<Self> {
        let consistency = ConsistencyAccumulator::new(m, sigmas.photodiode_v, sigmas.mag_nt);
        let spill_path = dir.file(".estimates_smoothed.spill");
        let residuals_path = dir.file("residuals.csv");
        let estimates_path = dir.file("estimates.csv");
        let mut residuals = create(&residuals_path)?;
        residuals
            .write_record(RESIDUAL_COLUMNS)
            .with_context(writing(&residuals_path))?;
        Ok(StreamSink {
            m,
            stride: stride_for(rows),
            smoother,
            estimates: create(&estimates_path)?,
            estimates_header: false,
            residuals,
            spill: create(&spill_path)?,
            spill_path,
            smoothed_path: dir.file("estimates_smoothed.csv"),
            smoothed_header: None,
            segments: Vec::new(),
            attitudes: AttitudeSpill::create(dir.file(".attitudes.spill"), smoother)?,
            forward_sample: Vec::new(),
            residual_sample: Vec::new(),
            pd_count: 0,
            pd_sum_sq: 0.0,
            pd_inside: 0,
            set_starts: vec![0],
            set_sums: vec![ResidualSums::default()],
            set_consistency: vec![consistency.clone()],
            consistency,
            error: None,
            cancel: None,
            estimates_path,
            residuals_path,
        })
    }

    /// Keeps the residual statistics per data set too, the sets starting at the rows
    /// `starts` (increasing, the first 0).
    pub fn with_sets(mut self, starts: &[usize]) -> Self {
        if !starts.is_empty() {
            self.set_starts = starts.to_vec();
            self.set_sums = vec![ResidualSums::default(); starts.len()];
            self.set_consistency = vec![self.consistency.clone(); starts.len()];
        }
        self
    }

    /// Lets `cancel` stop the run ([`RunSink::cancelled`]); `None` never stops it.
    pub fn with_cancel(mut self, cancel: Option<CancelCheck>) -> Self {
        self.cancel = cancel;
        self
    }

    fn keep(&mut self, result: Result<()>) {
        if let (Err(e), None) = (result, &self.error) {
            self.error = Some(e);
        }
    }

    fn header(&self, e: &StepEstimate) -> Vec<String> {
        let names: Vec<String> = e
            .calibration
            .parameters
            .iter()
            .map(|p| p.name.clone())
            .collect();
        estimate_header(self.m, &names)
    }

    fn write_forward(&mut self, e: &StepEstimate, residuals: &[ResidualRecord]) -> Result<()> {
        if !self.estimates_header {
            let header = self.header(e);
            self.estimates
                .write_record(&header)
                .with_context(writing(&self.estimates_path))?;
            self.smoothed_header = Some(header);
            self.estimates_header = true;
        }
        self.estimates
            .write_record(estimate_row(e))
            .with_context(writing(&self.estimates_path))?;
        for r in residuals {
            self.residuals
                .write_record(residual_row(r))
                .with_context(writing(&self.residuals_path))?;
        }
        Ok(())
    }

    fn write_segment(&mut self, segment: &[StepEstimate]) -> Result<()> {
        let path = self.spill_path.clone();
        self.write_segment_to_spill(segment)
            .with_context(writing(&path))
    }

    fn write_segment_to_spill(&mut self, segment: &[StepEstimate]) -> Result<()> {
        self.spill.flush()?;
        let mut file: &File = self.spill.get_ref().get_ref();
        let start = file.stream_position()?;
        for e in segment {
            self.spill.write_record(estimate_row(e))?;
        }
        self.spill.flush()?;
        let mut file: &File = self.spill.get_ref().get_ref();
        let end = file.stream_position()?;
        self.segments.push((start, end));
        Ok(())
    }

    /// Closes the files (`estimates_smoothed.csv` assembled in row order when the smoother
    /// ran); the first write error, if any. Returns the attitude per row (smoothed when
    /// available) and the photodiode residual statistics.
    pub fn finish(mut self) -> Result<Streamed> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        self.estimates
            .flush()
            .with_context(writing(&self.estimates_path))?;
        self.residuals
            .flush()
            .with_context(writing(&self.residuals_path))?;
        self.spill.flush().with_context(writing(&self.spill_path))?;
        drop(self.spill);
        if self.smoother {
            let mut out = create(&self.smoothed_path)?;
            if let Some(header) = &self.smoothed_header {
                out.write_record(header)
                    .with_context(writing(&self.smoothed_path))?;
            }
            out.flush().with_context(writing(&self.smoothed_path))?;
            let mut out = out
                .into_inner()
                .map_err(|e| anyhow::anyhow!("{}: {e}", pdcal_text::path(&self.smoothed_path)))?;
            let mut spill = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .open(&self.spill_path)
                .with_context(|| format!("cannot read {}", pdcal_text::path(&self.spill_path)))?;
            // Row order is the reverse of arrival, so each block copied is the spill's last:
            // cut off once copied, the spill and the CSV together never hold much more than
            // the smoothed rows once.
            for &(start, end) in self.segments.iter().rev() {
                spill.seek(SeekFrom::Start(start)).with_context(|| {
                    format!("cannot read {}", pdcal_text::path(&self.spill_path))
                })?;
                std::io::copy(&mut (&mut spill).take(end - start), &mut out).with_context(
                    || format!("cannot write {}", pdcal_text::path(&self.smoothed_path)),
                )?;
                spill.set_len(start).with_context(|| {
                    format!("cannot shorten {}", pdcal_text::path(&self.spill_path))
                })?;
            }
            out.flush().with_context(writing(&self.smoothed_path))?;
        }
        std::fs::remove_file(&self.spill_path)
            .with_context(|| format!("cannot remove {}", pdcal_text::path(&self.spill_path)))?;
        let mut attitudes = self.attitudes;
        attitudes.close()?;
        let summary = ResidualSummary::from_sums(self.pd_sum_sq, self.pd_inside, self.pd_count);
        Ok(Streamed {
            attitudes,
            residual_summary: summary,
            forward_sample: self.forward_sample,
            residual_sample: self.residual_sample,
            set_residuals: self
                .set_sums
                .iter()
                .map(|s| ResidualSummary::from_sums(s.sum_sq, s.inside, s.count))
                .collect(),
            consistency: self.consistency.finish(),
            set_consistency: self.set_consistency.iter().map(|c| c.finish()).collect(),
        })
    }
}

impl RunSink for StreamSink {
    fn forward(&mut self, estimate: &StepEstimate, residuals: &[ResidualRecord]) {
        if self.error.is_some() {
            return;
        }
        let result = self.write_forward(estimate, residuals);
        self.keep(result);
        for r in residuals {
            let set = self.set_starts.partition_point(|&s| s <= r.index).max(1) - 1;
            self.consistency.push(r);
            self.set_consistency[set].push(r);
            if matches!(r.sensor, Sensor::Photodiode(_)) {
                let inside = usize::from(r.residual.abs() <= r.bound_3sigma);
                self.pd_count += 1;
                self.pd_sum_sq += r.residual * r.residual;
                self.pd_inside += inside;
                let sums = &mut self.set_sums[set];
                sums.count += 1;
                sums.sum_sq += r.residual * r.residual;
                sums.inside += inside;
            }
        }
        if !self.smoother {
            let result = self.attitudes.append(std::slice::from_ref(estimate));
            self.keep(result);
        }
        if estimate.index.is_multiple_of(self.stride) {
            self.forward_sample.push(estimate.clone());
            self.residual_sample.extend_from_slice(residuals);
        }
    }

    fn smoothed(&mut self, segment: &[StepEstimate]) {
        if self.error.is_some() {
            return;
        }
        let result = self.write_segment(segment);
        self.keep(result);
        let result = self.attitudes.append(segment);
        self.keep(result);
    }

    fn cancelled(&mut self) -> bool {
        self.cancel.as_mut().is_some_and(|check| check())
    }
}

/// Bytes of one attitude record: the row (`u64`) and `x, y, z, w` (`f64`), little-endian.
const ATTITUDE_RECORD_BYTES: usize = 40;

/// The attitude per row of a streamed run, kept in a file of the staging directory instead
/// of memory: written as the estimates arrive (forward in row order, or the smoother's
/// blocks last first), read back in row order ([`AttitudeSpill::rows`]) exactly as written.
/// In memory: one byte range per appended block of rows.
pub struct AttitudeSpill {
    path: PathBuf,
    out: Option<BufWriter<File>>,
    written: u64,
    /// Byte ranges of the appended blocks, in arrival order.
    blocks: Vec<(u64, u64)>,
    /// Whether the blocks arrive last first (the smoother's backward pass).
    backward: bool,
}

impl AttitudeSpill {
    /// `backward`: the blocks will arrive last first.
    fn create(path: PathBuf, backward: bool) -> Result<Self> {
        let file = File::create(&path)
            .with_context(|| format!("cannot create {}", pdcal_text::path(&path)))?;
        Ok(AttitudeSpill {
            path,
            out: Some(BufWriter::new(file)),
            written: 0,
            blocks: Vec::new(),
            backward,
        })
    }

    /// Appends the attitudes of `rows` (consecutive, increasing) as one block.
    fn append(&mut self, rows: &[StepEstimate]) -> Result<()> {
        let Some(out) = self.out.as_mut() else {
            anyhow::bail!("{} is closed", pdcal_text::path(&self.path));
        };
        let start = self.written;
        for e in rows {
            let mut record = [0u8; ATTITUDE_RECORD_BYTES];
            record[..8].copy_from_slice(&(e.index as u64).to_le_bytes());
            for (cell, v) in record[8..]
                .chunks_exact_mut(8)
                .zip([e.q.x, e.q.y, e.q.z, e.q.w])
            {
                cell.copy_from_slice(&v.to_le_bytes());
            }
            out.write_all(&record).with_context(writing(&self.path))?;
            self.written += ATTITUDE_RECORD_BYTES as u64;
        }
        match self.blocks.last_mut() {
            // Forward rows arrive in row order: one growing block.
            Some(last) if !self.backward => last.1 = self.written,
            _ => self.blocks.push((start, self.written)),
        }
        Ok(())
    }

    fn close(&mut self) -> Result<()> {
        if let Some(mut out) = self.out.take() {
            out.flush().with_context(writing(&self.path))?;
        }
        Ok(())
    }

    /// The attitudes `(row, attitude)` in increasing rows.
    pub fn rows(&self) -> Result<impl Iterator<Item = Result<(usize, Quat)>> + '_> {
        let file = File::open(&self.path)
            .with_context(|| format!("cannot read {}", pdcal_text::path(&self.path)))?;
        let mut file = BufReader::new(file);
        let order: Box<dyn Iterator<Item = &(u64, u64)>> = if self.backward {
            Box::new(self.blocks.iter().rev())
        } else {
            Box::new(self.blocks.iter())
        };
        let path = &self.path;
        let reading = move || format!("cannot read {}", pdcal_text::path(path));
        Ok(order
            .flat_map(|&(start, end)| {
                let n = (end - start) / ATTITUDE_RECORD_BYTES as u64;
                (0..n).map(move |i| start + i * ATTITUDE_RECORD_BYTES as u64)
            })
            .scan(u64::MAX, move |at, offset| {
                let mut record = [0u8; ATTITUDE_RECORD_BYTES];
                let read = (|| -> std::io::Result<()> {
                    if *at != offset {
                        file.seek(SeekFrom::Start(offset))?;
                    }
                    file.read_exact(&mut record)
                })();
                *at = offset + ATTITUDE_RECORD_BYTES as u64;
                Some(read.with_context(reading).map(|()| decode(&record)))
            }))
    }

    /// Removes the file (before the staging directory is published).
    pub fn remove(mut self) -> Result<()> {
        self.close()?;
        std::fs::remove_file(&self.path)
            .with_context(|| format!("cannot remove {}", pdcal_text::path(&self.path)))
    }
}

fn decode(record: &[u8; ATTITUDE_RECORD_BYTES]) -> (usize, Quat) {
    let word = |i: usize| {
        let mut b = [0u8; 8];
        b.copy_from_slice(&record[8 * i..8 * i + 8]);
        b
    };
    let f = |i: usize| f64::from_le_bytes(word(i));
    let index = u64::from_le_bytes(word(0)) as usize;
    (
        index,
        Quat {
            x: f(1),
            y: f(2),
            z: f(3),
            w: f(4),
        },
    )
}
