//! The generator of `fixtures/`: small deterministic multi-axis gyro logs and the bank
//! of bad inputs. See `fixtures/README.md`; regenerate with
//! `cargo test --test suite -- --ignored fixtures::regenerate_fixtures`.

use std::path::Path;
use std::sync::Arc;

use arrow_array::{ArrayRef, Float64Array, RecordBatch};
use arrow_schema::{DataType, Field, Schema};
use parquet::arrow::ArrowWriter;
use parquet::basic::{Compression, ZstdLevel};
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// Rows and rate of the multi-axis fixture.
pub const ROWS: usize = 4000;
pub const RATE_HZ: f64 = 10.0;

/// The multi-axis log: time_s and four channels (deg/s and degC).
pub struct MultiAxis {
    pub time_s: Vec<f64>,
    pub gyro_x: Vec<f64>,
    pub gyro_y: Vec<f64>,
    pub gyro_z: Vec<f64>,
    pub temp_c: Vec<f64>,
}

/// Rounds to 9 significant decimals so the CSV stays short (values are then exactly
/// what the CSV says; the Parquet file holds the same f64s).
fn r9(x: f64) -> f64 {
    format!("{x:.9e}").parse().unwrap()
}

pub fn multiaxis() -> MultiAxis {
    let mut rng = ChaCha8Rng::seed_from_u64(20261122);
    let mut n = || -> f64 { StandardNormal.sample(&mut rng) };
    let dt = 1.0 / RATE_HZ;
    let mut m = MultiAxis {
        time_s: Vec::with_capacity(ROWS),
        gyro_x: Vec::with_capacity(ROWS),
        gyro_y: Vec::with_capacity(ROWS),
        gyro_z: Vec::with_capacity(ROWS),
        temp_c: Vec::with_capacity(ROWS),
    };
    // gyro_x: FARMA(2,1,1) drift, f1(z) = 0.3 + 0.4 exp(-z^2), f2(z) = -0.2 + 0.1 tanh(z),
    // b1 = -0.5, in units of 0.01 deg/s, on a 0.02 deg/s bias.
    let (mut x1, mut x2, mut e1) = (0.0f64, 0.0f64, 0.0f64);
    // gyro_y: ARMA(2,1) (0.5, -0.3; 0.4) + 0.004 deg/s/degC temperature sensitivity.
    let (mut y1, mut y2, mut u1) = (0.0f64, 0.0f64, 0.0f64);
    // gyro_z: white noise + rate random walk, quantized to 0.001 deg/s.
    let mut walk = 0.0f64;
    for k in 0..ROWS {
        let t = k as f64 * dt;
        let temp = 25.0 + 5.0 * (1.0 - (-t / 120.0).exp()) + 0.02 * n();
        let e = n();
        let x = (0.3 + 0.4 * (-x1 * x1).exp()) * x1 + (-0.2 + 0.1 * x1.tanh()) * x2 + e - 0.5 * e1;
        (x2, x1, e1) = (x1, x, e);
        let u = n();
        let y = 0.5 * y1 - 0.3 * y2 + u + 0.4 * u1;
        (y2, y1, u1) = (y1, y, u);
        walk += 0.0005 * n();
        let z = ((0.01 * n() + walk - 0.01) / 0.001).round() * 0.001;
        m.time_s.push(r9(t));
        m.gyro_x.push(r9(0.02 + 0.01 * x));
        m.gyro_y
            .push(r9(-0.015 + 0.005 * y + 0.004 * (temp - 25.0)));
        m.gyro_z.push(r9(z));
        m.temp_c.push(r9(temp));
    }
    m
}

pub fn multiaxis_csv(m: &MultiAxis) -> String {
    let mut s = String::from(
        "# farma fixture: 3 gyro axes (deg/s) and temperature (degC) at 10 Hz; see fixtures/README.md\n",
    );
    s.push_str("time_s,gyro_x,gyro_y,gyro_z,temp_c\n");
    for k in 0..m.time_s.len() {
        s.push_str(&format!(
            "{},{},{},{},{}\n",
            m.time_s[k], m.gyro_x[k], m.gyro_y[k], m.gyro_z[k], m.temp_c[k]
        ));
    }
    s
}

/// The same channels as Parquet without a time column; the rate is in the metadata.
pub fn write_multiaxis_parquet(m: &MultiAxis, path: &Path) {
    let names = ["gyro_x", "gyro_y", "gyro_z", "temp_c"];
    let cols = [&m.gyro_x, &m.gyro_y, &m.gyro_z, &m.temp_c];
    let schema = Arc::new(Schema::new(
        names
            .iter()
            .map(|n| Field::new(*n, DataType::Float64, false))
            .collect::<Vec<_>>(),
    ));
    let arrays: Vec<ArrayRef> = cols
        .iter()
        .map(|c| Arc::new(Float64Array::from((*c).clone())) as ArrayRef)
        .collect();
    let batch = RecordBatch::try_new(schema.clone(), arrays).unwrap();
    let props = WriterProperties::builder()
        .set_compression(Compression::ZSTD(ZstdLevel::default()))
        .set_key_value_metadata(Some(vec![KeyValue::new(
            "sample_rate_hz".into(),
            "10".to_string(),
        )]))
        .build();
    let file = std::fs::File::create(path).unwrap();
    let mut w = ArrowWriter::try_new(file, schema, Some(props)).unwrap();
    w.write(&batch).unwrap();
    w.close().unwrap();
}

/// The bad-input bank: (file name, contents). Each has a test in `tests/suite/bad_input.rs`.
pub fn bad_csv_files() -> Vec<(&'static str, String)> {
    let good_rows = |n: usize| -> String {
        (0..n)
            .map(|i| format!("{},{},{}\n", i as f64 * 0.1, 0.01 * i as f64, 25.0))
            .collect()
    };
    let header = "time,gyro_x,temp\n";
    vec![
        ("empty.csv", String::new()),
        ("comments_only.csv", "# nothing but a comment\n\n".into()),
        ("header_only.csv", header.into()),
        (
            "wrong_field_count.csv",
            format!("{header}{}0.5,0.05\n{}", good_rows(5), "0.6,0.06,25\n"),
        ),
        ("truncated.csv", format!("{header}{}0.5,0.0", good_rows(5))),
        (
            "non_numeric.csv",
            format!("{header}{}0.5,abc,25\n", good_rows(5)),
        ),
        (
            "nan_inf.csv",
            format!(
                "{header}{}0.5,NaN,25\n0.6,inf,25\n0.7,,25\n0.8,0.08,25\n",
                good_rows(5)
            ),
        ),
        (
            "non_monotonic_time.csv",
            format!("{header}0,0,25\n0.1,0,25\n0.3,0,25\n0.2,0,25\n0.4,0,25\n"),
        ),
        (
            "duplicate_time.csv",
            format!("{header}0,0,25\n0.1,0,25\n0.2,0,25\n0.2,0,25\n0.3,0,25\n"),
        ),
        (
            "gap.csv",
            format!("{header}0,0,25\n0.1,1,25\n0.2,2,25\n0.6,6,25\n0.7,7,25\n0.8,8,25\n"),
        ),
        (
            "irregular.csv",
            format!("{header}0,0,25\n0.1,1,25\n0.23,2,25\n0.3,3,25\n0.4,4,25\n"),
        ),
        ("no_time_base.csv", "gyro_x,temp\n0.1,25\n0.2,25\n".into()),
        (
            "duplicate_column.csv",
            "time,gyro_x,gyro_x\n0,1,2\n0.1,1,2\n".into(),
        ),
        (
            "empty_column_name.csv",
            "time,,temp\n0,1,2\n0.1,1,2\n".into(),
        ),
        ("no_header.csv", "0,1,2\n0.1,1,2\n".into()),
        ("one_row.csv", format!("{header}0,0.01,25\n")),
        (
            "nan_time.csv",
            format!("{header}0,0,25\nNaN,0,25\n0.2,0,25\n"),
        ),
    ]
}

/// Writes the multi-axis fixtures and the bad-input bank into `dir`.
pub fn write_all(dir: &Path) {
    std::fs::create_dir_all(dir.join("bad")).unwrap();
    let m = multiaxis();
    std::fs::write(dir.join("multiaxis.csv"), multiaxis_csv(&m)).unwrap();
    write_multiaxis_parquet(&m, &dir.join("multiaxis.parquet"));
    for (name, text) in bad_csv_files() {
        std::fs::write(dir.join("bad").join(name), text).unwrap();
    }
    // A Parquet file cut in half, and one with a text column.
    let full = std::fs::read(dir.join("multiaxis.parquet")).unwrap();
    std::fs::write(
        dir.join("bad").join("truncated.parquet"),
        &full[..full.len() / 2],
    )
    .unwrap();
    write_text_column_parquet(&dir.join("bad").join("text_column.parquet"));
    std::fs::write(
        dir.join("bad").join("not_a_log.arrow"),
        b"ARROW1 but not really an arrow file\n",
    )
    .unwrap();
}

fn write_text_column_parquet(path: &Path) {
    let schema = Arc::new(Schema::new(vec![
        Field::new("gyro_x", DataType::Float64, false),
        Field::new("label", DataType::Utf8, false),
    ]));
    let batch = RecordBatch::try_new(
        schema.clone(),
        vec![
            Arc::new(Float64Array::from(vec![0.1, 0.2])),
            Arc::new(arrow_array::StringArray::from(vec!["a", "b"])),
        ],
    )
    .unwrap();
    let props = WriterProperties::builder()
        .set_key_value_metadata(Some(vec![KeyValue::new(
            "sample_rate_hz".into(),
            "10".to_string(),
        )]))
        .build();
    let mut w =
        ArrowWriter::try_new(std::fs::File::create(path).unwrap(), schema, Some(props)).unwrap();
    w.write(&batch).unwrap();
    w.close().unwrap();
}
