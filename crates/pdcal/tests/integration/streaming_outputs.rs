//! `pdcal calibrate` streams its CSVs (the smoother by segments): the files equal, byte for
//! byte, those written from the in-memory run of the same data set.

use pdcal_sim::Scenario;

#[test]
fn streamed_files_equal_the_in_memory_files() {
    streamed_equals_in_memory(true, false);
}

/// The photodiode, gyro and magnetometer columns kept in files of the staging directory
/// (as a long set's are, `calibrate::FILE_TELEMETRY_BYTES`) give the same files, and leave
/// none of theirs. The set is longer than two of the files' blocks of 4096 rows,
/// so rows are read back from the files.
#[test]
fn telemetry_kept_in_files_gives_the_in_memory_files() {
    streamed_equals_in_memory(true, true);
}

/// Without the smoother the attitudes of the Sun-vector metrics are the forward ones,
/// spilled in row order.
#[test]
fn streamed_forward_only_run_equals_the_in_memory_run() {
    streamed_equals_in_memory(false, false);
}

fn streamed_equals_in_memory(smoother: bool, kept_in_files: bool) {
    let tmp = tempfile::tempdir().unwrap();
    let (dataset, streamed, memory) = (
        tmp.path().join("set"),
        tmp.path().join("streamed"),
        tmp.path().join("memory"),
    );
    let mut scenario = Scenario::rax2_like().unwrap();
    // 3901 rows (9001 kept in files), the filter starting in sunlight near row 1440: more
    // than two smoother segments of 1024 rows, so the backward pass crosses segment
    // boundaries.
    scenario.duration_s = if kept_in_files { 9000.0 } else { 3900.0 };
    pdcal::simulate::run_to_dir(&scenario, 4, &dataset).unwrap();
    let mut config = pdcal::calibrate::RunConfig::default();
    config.filter.smoother = smoother;
    let file_bytes = if kept_in_files { 0 } else { u64::MAX };
    let read = pdcal::joint::read_kept(
        std::slice::from_ref(&dataset),
        Some((tmp.path(), file_bytes)),
    );
    let read = read.unwrap();
    let telemetry = &read[0].2;
    assert!(
        telemetry
            .pd_v
            .iter()
            .all(|pd| pd.is_in_file() == kept_in_files)
    );
    assert_eq!(telemetry.gyro_rad_s.is_in_file(), kept_in_files);
    let mag = telemetry.mag_nt.as_ref().unwrap();
    assert_eq!(mag.is_in_file(), kept_in_files);
    drop(read);
    pdcal::calibrate::run_dirs_kept(
        std::slice::from_ref(&dataset),
        &streamed,
        &config,
        false,
        file_bytes,
    )
    .unwrap();

    let meta = pdcal_dataset::read_meta(&dataset).unwrap();
    let telemetry = pdcal_dataset::read_telemetry(&dataset, &meta).unwrap();
    let albedo = pdcal::calibrate::albedo_model().unwrap();
    let outcome = pdcal::calibrate::run(&meta, &telemetry, &config, &albedo).unwrap();
    assert!(outcome.run.forward.len() > 2 * pdcal_filter::SMOOTHER_BLOCK_ROWS);
    let dir = pdcal::output::OutputDir::create(&memory, "calibrate").unwrap();
    pdcal::files::write_calibration_outputs(dir, &meta, &telemetry, &outcome, None).unwrap();

    let smoothed = smoother.then_some("estimates_smoothed.csv");
    for name in ["estimates.csv", "residuals.csv", "calibration.ron"]
        .into_iter()
        .chain(smoothed)
    {
        let (a, b) = (
            std::fs::read(streamed.join(name)).unwrap(),
            std::fs::read(memory.join(name)).unwrap(),
        );
        assert!(a == b, "{name} differs ({} vs {} bytes)", a.len(), b.len());
    }
    let summary = |dir: &std::path::Path| {
        let mut v: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join("summary.json")).unwrap()).unwrap();
        v.as_object_mut().unwrap().remove("runtime_s");
        v
    };
    assert_eq!(summary(&streamed), summary(&memory));
    assert!(!streamed.join(".estimates_smoothed.spill").exists());
    assert!(!streamed.join(".attitudes.spill").exists());
    let left: Vec<_> = std::fs::read_dir(&streamed)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|name| name.ends_with(".spill"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}
