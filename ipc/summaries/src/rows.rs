//! The run folder's CSV files as serde rows, written and read by their header's names with the
//! `csv` crate (quoted where a field needs it): `trace.csv` ([`TraceRow`]: the simulator writes
//! it; the lap-trace picture and the experiments' takeover time read it) and `progress.csv`
//! ([`ProgressRow`]: `mta up` writes it; `model_error.png` and `mta experiment` read it).

use std::borrow::Cow;

use anyhow::{Context, bail};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

/// A row type of a run-folder CSV file.
pub trait Row: DeserializeOwned + Serialize {
    /// The columns, in the order they are written.
    const COLUMNS: &'static [&'static str];
}

/// One row: the step, its episode, the car's position (m), its signed distance from the line
/// (m, + left) and who decided the command (`CommandSource::name`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TraceRow {
    pub step: u64,
    pub episode: u32,
    pub x: f64,
    pub y: f64,
    pub lateral_m: f64,
    /// Borrowed when written (a source's name is static): no allocation per row on the
    /// simulator's 50 Hz path.
    pub source: Cow<'static, str>,
}

impl Row for TraceRow {
    const COLUMNS: &'static [&'static str] = &["step", "episode", "x", "y", "lateral_m", "source"];
}

/// One row a second of `mta up`'s `progress.csv`, from the newest observation and command; an
/// empty field is not known yet (no command, no model).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProgressRow {
    pub wall_s: f64,
    pub step: u64,
    pub sim_s: f64,
    pub laps: u32,
    /// Who decided the newest command (`CommandSource::name`); empty before the first.
    pub driver: String,
    pub model_over_copy_last: Option<f64>,
    pub probe: Option<f64>,
    pub predictor_ms: Option<f64>,
}

impl Row for ProgressRow {
    const COLUMNS: &'static [&'static str] = &[
        "wall_s",
        "step",
        "sim_s",
        "laps",
        "driver",
        "model_over_copy_last",
        "probe",
        "predictor_ms",
    ];
}

impl TraceRow {
    /// Rounded to 0.1 mm: the file stays small and a picture needs no more.
    pub fn new(
        step: u64,
        episode: u32,
        x: f64,
        y: f64,
        lateral_m: f64,
        source: &'static str,
    ) -> Self {
        Self {
            step,
            episode,
            x: round_to(x, 4),
            y: round_to(y, 4),
            lateral_m: round_to(lateral_m, 4),
            source: Cow::Borrowed(source),
        }
    }
}

/// `v` rounded to `decimals` places: what a row's reader needs, and no longer a line.
pub fn round_to(v: f64, decimals: i32) -> f64 {
    let scale = 10f64.powi(decimals);
    (v * scale).round() / scale
}

/// The rows of a file, read by the header's names. A bad last line is left out (a writer killed
/// or still writing mid-row); a missing column or any other bad line is an error naming it.
pub fn parse<R: Row>(text: &str) -> anyhow::Result<Vec<R>> {
    let mut r = csv::ReaderBuilder::new()
        .flexible(true)
        .from_reader(text.as_bytes());
    let header = r.headers().context("reading the header")?.clone();
    if let Some(missing) = R::COLUMNS.iter().find(|c| !header.iter().any(|h| h == **c)) {
        bail!("no column {missing} in the header {header:?}");
    }
    let records: Vec<_> = r.deserialize::<R>().collect();
    let last = records.len().saturating_sub(1);
    let mut rows = Vec::with_capacity(records.len());
    for (i, rec) in records.into_iter().enumerate() {
        match rec {
            Ok(row) => rows.push(row),
            Err(_) if i == last => break,
            Err(e) => bail!("line {}: {e}", i + 2),
        }
    }
    Ok(rows)
}

/// A writer of `R` rows: the header at once (a run that ends before its first row still leaves a
/// readable file), then a row per [`csv::Writer::serialize`].
pub fn writer<R: Row, W: std::io::Write>(out: W) -> csv::Result<csv::Writer<W>> {
    let mut w = csv::WriterBuilder::new()
        .has_headers(false)
        .from_writer(out);
    w.write_record(R::COLUMNS)?;
    Ok(w)
}

/// A file's rows; an error names the file.
pub fn read<R: Row>(path: &std::path::Path) -> anyhow::Result<Vec<R>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    parse(&text).with_context(|| format!("reading {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_round_trip_by_name_and_a_torn_last_line_is_left_out() {
        let mut w = writer::<TraceRow, _>(Vec::new()).unwrap();
        let rows = [
            TraceRow::new(0, 0, 0.123456, -0.5, 0.00123, "reactive"),
            TraceRow::new(5, 1, 1.0, 2.0, -0.01, "active_inference"),
        ];
        for r in &rows {
            w.serialize(r).unwrap();
        }
        let mut text = String::from_utf8(w.into_inner().unwrap()).unwrap();
        assert!(text.starts_with(&TraceRow::COLUMNS.join(",")), "{text}");
        assert_eq!(parse::<TraceRow>(&text).unwrap(), rows);
        assert_eq!(rows[0].x, 0.1235);
        text.push_str("10,1,0.5");
        assert_eq!(parse::<TraceRow>(&text).unwrap(), rows, "torn last line");
        // Columns in another order are read by name.
        let swapped = "source,step,episode,x,y,lateral_m\nreactive,3,0,1,2,0\n";
        assert_eq!(parse::<TraceRow>(swapped).unwrap()[0].step, 3);
        // Empty fields are values not known yet.
        let progress = "wall_s,step,sim_s,laps,driver,model_over_copy_last,probe,predictor_ms\n\
                        1.0,50,1.00,0,,,,\n2.0,100,2.00,0,reactive,0.9,0.75,1.5\n";
        let p = parse::<ProgressRow>(progress).unwrap();
        assert_eq!(
            (p[0].probe, p[1].probe, p[1].driver.as_str()),
            (None, Some(0.75), "reactive")
        );
    }

    #[test]
    fn a_missing_column_or_a_bad_line_is_an_error() {
        let e = parse::<TraceRow>("step,episode\n0,0\n").unwrap_err();
        assert!(format!("{e:#}").contains("no column x"), "{e:#}");
        let text = "step,episode,x,y,lateral_m,source\nx,0,0,0,0,reactive\n1,0,0,0,0,reactive\n";
        let e = parse::<TraceRow>(text).unwrap_err();
        assert!(format!("{e:#}").contains("line 2"), "{e:#}");
    }
}
