//! A dataset a program holds as fields and named columns becomes the dataset the files
//! would give, bit for bit, and bad values get the reader's errors at the places of the
//! files the writer would write.

use crate::common;

use pdcal_dataset::{
    DatasetMeta, MetaFields, Telemetry, columns, meta_from_fields, meta_from_str,
    photodiode_column, render_dataset, telemetry_from_columns,
};

fn fields(meta: &DatasetMeta) -> MetaFields {
    MetaFields {
        name: meta.name.clone(),
        epoch_utc: meta.epoch_utc.as_str().to_owned(),
        orbit: meta.orbit.clone(),
        photodiodes: meta.photodiodes.clone(),
        noise: meta.noise,
        inertia_kg_m2: meta.inertia_kg_m2,
    }
}

/// The telemetry as named columns in the writer's order, NaN for a blank.
fn named_columns(tm: &Telemetry) -> Vec<(String, Vec<f64>)> {
    let mut out = vec![(columns::T_S.to_owned(), tm.t_s.clone())];
    for (a, name) in columns::GYRO.iter().enumerate() {
        let values = tm.gyro_rad_s.iter().map(|v| v.map_or(f64::NAN, |v| v[a]));
        out.push(((*name).to_owned(), values.collect()));
    }
    for (a, name) in columns::MAG.iter().enumerate() {
        let mag = tm.mag_nt.as_ref().unwrap();
        let values = mag.iter().map(|v| v.map_or(f64::NAN, |v| v[a]));
        out.push(((*name).to_owned(), values.collect()));
    }
    for (i, pd) in tm.pd_v.iter().enumerate() {
        let values = pd.iter().map(|v| v.unwrap_or(f64::NAN));
        out.push((photodiode_column(i + 1), values.collect()));
    }
    out
}

#[test]
fn fields_and_columns_give_what_the_files_give() {
    let ds = common::full_dataset(40);
    let meta = meta_from_fields(&fields(&ds.meta)).unwrap();
    assert_eq!(meta, ds.meta);
    let tm = telemetry_from_columns(&named_columns(&ds.telemetry), &meta).unwrap();
    assert_eq!(tm, ds.telemetry);
    let files = render_dataset(&ds).unwrap();
    assert_eq!(meta_from_str(&files[0].1).unwrap(), meta);
}

#[test]
fn bad_values_get_the_readers_error_at_the_written_place() {
    let ds = common::full_dataset(40);
    let mut f = fields(&ds.meta);
    f.photodiodes[2].elevation_deg = 1000.0;
    let e = meta_from_fields(&f).unwrap_err();
    assert_eq!(e.field(), Some("photodiodes[2].elevation_deg"), "{e}");
    let mut f = fields(&ds.meta);
    f.epoch_utc = "2011-13-04T18:29:45Z".into();
    let e = meta_from_fields(&f).unwrap_err();
    let text = pdcal_dataset::render_dataset(&ds).unwrap()[0].1.clone();
    let line = text.lines().position(|l| l.contains("epoch_utc")).unwrap() + 1;
    assert_eq!(
        (e.line(), e.field()),
        (Some(line), Some("epoch_utc")),
        "{e}"
    );
    let mut cols = named_columns(&ds.telemetry);
    cols[1].1[6] = f64::NAN;
    cols[2].1[6] = 0.5;
    let e = telemetry_from_columns(&cols, &ds.meta).unwrap_err();
    // Row 6 is line 8 (the header is line 1); gyro_x_rad_s is column 2.
    assert_eq!((e.line(), e.column()), (Some(8), Some(2)), "{e}");
    cols = named_columns(&ds.telemetry);
    cols[8].1.pop();
    let e = telemetry_from_columns(&cols, &ds.meta).unwrap_err();
    assert_eq!(e.field(), Some(cols[8].0.as_str()), "{e}");
}
