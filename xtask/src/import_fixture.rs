//! The generator of `fixtures/import/`: a ground-segment-style export of a simulated set and
//! its column maps (`cargo xtask make-import-fixture`), and the direct dataset with the same
//! rows cut and cells blanked, which the import test compares the imported one against.
//!
//! The export differs from a pdcal dataset in every way `pdcal import` handles: 12-bit ADC
//! counts for the photodiodes (channels in another order than pdNN), Unix timestamps,
//! magnetometer in mG, gyro in deg/s, TEME positions in metres, extra columns, a sentinel
//! (65535) in some cells, rows with a sentinel (-1) or an empty time, a few rows missing and
//! one 90 s gap. Seeded: the same build gives byte-identical files.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result, ensure};
use pdcal_dataset::{Dataset, Telemetry};
use pdcal_ephem::{frames, time};
use pdcal_sim::{Scenario, SimOutput};

/// The simulator seed of the fixture.
pub const SEED: u64 = 3;
/// Length of the simulated set, s (the rax2-like orbit starts in eclipse for ~24 min).
pub const DURATION_S: f64 = 3600.0;
/// ADC gain of the photodiode channels, V/count: a 12-bit converter over 5 V.
pub const ADC_GAIN_V: f64 = 5.0 / 4096.0;
/// ADC offset, V (the voltage at count 0): the front end is biased so that the noise of a
/// dark sensor around 0 V stays above count 0.
pub const ADC_OFFSET_V: f64 = -0.25;
/// Largest count of the 12-bit converter.
pub const ADC_MAX: f64 = 4095.0;
/// The sentinel of a cell without a value.
pub const SENTINEL: u32 = 65535;
/// The time column's sentinel: the ground segment could not time-tag the frame.
pub const TIME_SENTINEL: i32 = -1;
/// The rows (sample times, s) of the one gap: none of them is in the export.
pub const GAP_S: (f64, f64) = (2400.0, 2490.0);
/// Rows missing from the export besides the gap (frames never downlinked).
pub const MISSING_S: [f64; 4] = [777.0, 1234.0, 2001.0, 3003.0];
/// Rows whose time is the sentinel (dropped by the import).
pub const SENTINEL_TIME_S: [f64; 3] = [100.0, 2222.0, 3333.0];
/// Rows whose time cell is empty (dropped by the import).
pub const BLANK_TIME_S: [f64; 1] = [1800.0];

/// The ADC channel of photodiode `i` (0-based): the harness wires them in another order.
pub fn adc_channel(i: usize) -> usize {
    (i * 5) % 17
}

/// Whether photodiode `i`'s cell of row `k` holds the sentinel.
fn pd_sentinel(k: usize, i: usize) -> bool {
    k % 97 == 13 && i == k % 17
}

/// Whether the magnetometer x cell of row `k` holds the sentinel.
fn mag_sentinel(k: usize) -> bool {
    k % 211 == 50
}

/// The export, the maps, and the direct dataset cut the same way.
pub struct Fixture {
    /// `export.csv`.
    pub export_csv: String,
    /// `map.ron`: TLE orbit.
    pub map_ron: String,
    /// `map-positions.ron`: the TEME position columns instead of the TLE.
    pub map_positions_ron: String,
    /// The simulator's dataset with the export's rows cut and its sentinel cells blanked, with
    /// its truth (all rows).
    pub direct: Dataset,
    /// The simulation.
    pub sim: SimOutput,
}

/// The fixture's scenario: the built-in rax2-like, [`DURATION_S`] long.
pub fn scenario() -> Result<Scenario> {
    let mut scenario = Scenario::builtin("rax2-like")?;
    scenario.duration_s = DURATION_S;
    scenario.name = "rax2-like-import-fixture".into();
    Ok(scenario)
}

/// Simulates and builds the fixture in memory.
pub fn build() -> Result<Fixture> {
    let sim = pdcal_sim::simulate(&scenario()?, SEED).context("simulating the fixture")?;
    let tm = &sim.telemetry;
    let truth = &sim.truth;
    ensure!(
        truth.t_s == tm.t_s,
        "the simulator's truth and telemetry rows differ"
    );
    let epoch = sim.meta.epoch_utc.epoch();
    let unix0 = 1_320_431_385.0; // 2011-11-04T18:29:45Z, the scenario's epoch
    ensure!(
        time::format_utc(epoch) == "2011-11-04T18:29:45.000000Z",
        "the rax2-like epoch changed; update the Unix time of the fixture"
    );
    let n_pd = tm.pd_v.len();
    let cut = |t: f64| {
        (t >= GAP_S.0 && t < GAP_S.1)
            || MISSING_S.contains(&t)
            || SENTINEL_TIME_S.contains(&t)
            || BLANK_TIME_S.contains(&t)
    };

    let mut header = vec!["frame_counter".to_owned()];
    header.extend((9..17).map(|c| format!("adc_ch{c:02}")));
    header.push("time_unix".into());
    header.extend(["mag_y_mG", "mag_x_mG", "mag_z_mG"].map(String::from));
    header.extend((0..9).map(|c| format!("adc_ch{c:02}")));
    header.extend(["gyro_z_dps", "gyro_x_dps", "gyro_y_dps"].map(String::from));
    header.extend(["pos_teme_x_m", "pos_teme_y_m", "pos_teme_z_m", "mode"].map(String::from));
    let mut csv = header.join(",");
    csv.push('\n');

    let mut direct = Telemetry {
        pd_v: vec![pdcal_dataset::Samples::new(); n_pd],
        mag_nt: tm.mag_nt.as_ref().map(|_| Default::default()),
        ..Telemetry::default()
    };
    for k in 0..tm.len() {
        let t = tm.t_s[k];
        let skipped = (t >= GAP_S.0 && t < GAP_S.1) || MISSING_S.contains(&t);
        if skipped {
            continue;
        }
        let time_cell = if SENTINEL_TIME_S.contains(&t) {
            TIME_SENTINEL.to_string()
        } else if BLANK_TIME_S.contains(&t) {
            String::new()
        } else {
            format!("{:.3}", unix0 + t)
        };
        // Counts by channel, so the export's channel columns can be written in order.
        let mut channel_cells = vec![String::new(); 17];
        let mut direct_pd = vec![None; n_pd];
        for i in 0..n_pd {
            let Some(v) = tm.pd_v[i].get(k) else { continue };
            let count = ((v - ADC_OFFSET_V) / ADC_GAIN_V).round();
            ensure!(
                (0.0..=ADC_MAX).contains(&count),
                "pd{:02} at t = {t} s reads {v} V, outside the ADC's range",
                i + 1
            );
            channel_cells[adc_channel(i)] = if pd_sentinel(k, i) {
                SENTINEL.to_string()
            } else {
                direct_pd[i] = Some(v);
                format!("{count}")
            };
        }
        let mag = tm.mag_nt.as_ref().and_then(|m| m.get(k));
        let mag_cells = match mag {
            Some(b) => {
                let x = if mag_sentinel(k) {
                    SENTINEL.to_string()
                } else {
                    format!("{:.2}", b.x / 100.0)
                };
                [
                    format!("{:.2}", b.y / 100.0),
                    x,
                    format!("{:.2}", b.z / 100.0),
                ]
            }
            None => Default::default(),
        };
        let gyro_cells = match tm.gyro_rad_s.get(k) {
            Some(w) => [w.z, w.x, w.y].map(|v| format!("{:.5}", v.to_degrees())),
            None => Default::default(),
        };
        let at = time::offset(epoch, t)?;
        let r_teme_m = frames::teme_to_gcrf(at).transpose() * truth.r_gcrf_km[k] * 1000.0;
        let mut row = vec![format!("{}", 40_000 + k)];
        row.extend(channel_cells[9..17].iter().cloned());
        row.push(time_cell);
        row.extend(mag_cells);
        row.extend(channel_cells[0..9].iter().cloned());
        row.extend(gyro_cells);
        row.extend([r_teme_m.x, r_teme_m.y, r_teme_m.z].map(|v| format!("{v:.3}")));
        row.push(if k % 600 < 300 { "SCI" } else { "NOM" }.into());
        writeln!(csv, "{}", row.join(","))?;

        if cut(t) {
            continue;
        }
        direct.t_s.push(t);
        direct.gyro_rad_s.push(tm.gyro_rad_s.get(k));
        if let Some(m) = direct.mag_nt.as_mut() {
            m.push(mag.filter(|_| !mag_sentinel(k)));
        }
        for (series, v) in direct.pd_v.iter_mut().zip(direct_pd) {
            series.push(v);
        }
    }
    let direct = Dataset {
        meta: sim.meta.clone(),
        telemetry: direct,
        truth: Some((sim.truth.clone(), sim.constants.clone())),
    };
    Ok(Fixture {
        export_csv: csv,
        map_ron: map_ron(&sim, false)?,
        map_positions_ron: map_ron(&sim, true)?,
        direct,
        sim,
    })
}

fn map_ron(sim: &SimOutput, positions: bool) -> Result<String> {
    let mut m = String::new();
    let name = if positions {
        "rax2-like-import-positions"
    } else {
        "rax2-like-import"
    };
    writeln!(
        m,
        "// Column map of fixtures/import/export.csv (made by `cargo xtask make-import-fixture`);\n\
         // the format is docs/import.md.\n\
         (\n    format_version: 1,\n    name: \"{name}\",\n    \
         time: (column: \"time_unix\", form: Unix, sentinels: [{TIME_SENTINEL}]),\n    \
         sentinels: [{SENTINEL}],\n    \
         gyro: (\n        x: (column: \"gyro_x_dps\", unit: \"deg/s\"),\n        \
         y: (column: \"gyro_y_dps\", unit: \"deg/s\"),\n        \
         z: (column: \"gyro_z_dps\", unit: \"deg/s\"),\n    ),\n    \
         mag: (\n        x: (column: \"mag_x_mG\", unit: \"mG\"),\n        \
         y: (column: \"mag_y_mG\", unit: \"mG\"),\n        \
         z: (column: \"mag_z_mG\", unit: \"mG\"),\n    ),\n    \
         // 12-bit ADC over 5 V, biased by -0.25 V: V = {ADC_GAIN_V} * count - 0.25\n    \
         photodiodes: ["
    )?;
    for (i, mount) in sim.meta.photodiodes.iter().enumerate() {
        writeln!(
            m,
            "        (column: \"adc_ch{:02}\", counts: (gain: {ADC_GAIN_V:?}, offset: {ADC_OFFSET_V:?}, unit: \"V\"), \
             azimuth_deg: {:?}, elevation_deg: {:?}),",
            adc_channel(i),
            mount.azimuth_deg,
            mount.elevation_deg
        )?;
    }
    m.push_str("    ],\n");
    if positions {
        m.push_str(
            "    orbit: Positions(\n        x: (column: \"pos_teme_x_m\", unit: \"m\"),\n        \
             y: (column: \"pos_teme_y_m\", unit: \"m\"),\n        \
             z: (column: \"pos_teme_z_m\", unit: \"m\"),\n        frame: Teme,\n    ),\n",
        );
    } else {
        let pdcal_dataset::OrbitSpec::Tle { line1, line2 } = &sim.meta.orbit else {
            anyhow::bail!("the rax2-like scenario has no TLE");
        };
        writeln!(
            m,
            "    orbit: Tle(\n        line1: \"{line1}\",\n        line2: \"{line2}\",\n    ),"
        )?;
    }
    if let Some(noise) = &sim.meta.noise {
        let field = |name: &str, v: Option<f64>| v.map(|v| format!("{name}: {v:?}"));
        let fields: Vec<String> = [
            field("gyro_rad_s", noise.gyro_rad_s),
            field("mag_nT", noise.mag_nt),
            field("photodiode_V", noise.photodiode_v),
        ]
        .into_iter()
        .flatten()
        .collect();
        writeln!(m, "    noise: ({}),", fields.join(", "))?;
    }
    m.push_str(")\n");
    Ok(m)
}

/// Writes `export.csv`, `map.ron` and `map-positions.ron` into `dir` (the README there is
/// hand-written).
pub fn write(dir: &Path) -> Result<Fixture> {
    let fixture = build()?;
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    for (name, text) in [
        ("export.csv", &fixture.export_csv),
        ("map.ron", &fixture.map_ron),
        ("map-positions.ron", &fixture.map_positions_ron),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, text).with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(fixture)
}
