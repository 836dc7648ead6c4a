//! Recorded-scan CSV reader (the input of `quarry lidar --scans FILE.csv`).
//!
//! # Format
//! One header line `stamp_s,r0,r1,...,r{N-1}`, then one row per scan: `stamp_s` is the capture
//! time in seconds (any epoch, e.g. UNIX time; converted to integer microseconds), `r_i` the range
//! of beam `i` in metres. Beam `i` points at `angle_min + i·angle_increment` (x forward, y left,
//! counter-clockwise) — the ROS `LaserScan` convention used by the leg-tracker recordings in
//! `shared/data/leg-tracker`. The geometry (beam count, angles, valid range, period) comes with
//! the file, e.g. from a `scan_meta.json` entry ([`parse_scan_meta`]); any beam count, field of
//! view and resolution is accepted. The header must have exactly `N + 1` columns.
//!
//! # What is done with bad data
//! - `nan`, `inf`, negative, out-of-`[range_min, range_max]` ranges (and values above 65.534 m)
//!   become invalid beams (range code 0) and are counted in [`ScanCsvStats::invalid_beams`].
//! - A row with the wrong number of columns, an unparseable cell or a non-finite stamp is a
//!   *bad row*: by default an error naming the line ([`RowPolicy::Error`]); with
//!   [`RowPolicy::Skip`] it is skipped and counted in [`ScanCsvStats::skipped_bad_rows`].
//! - A stamp earlier than the previous accepted row's is an error by default; with
//!   [`RowPolicy::Skip`] the row is skipped and counted in [`ScanCsvStats::skipped_backwards`].
//! - A stamp equal to the previous accepted row's (a repeated or duplicated row: a scanner
//!   does not capture two scans at one instant) is treated the same way and counted in
//!   [`ScanCsvStats::skipped_repeated`]. Accepting them made one recording give 291-316 tracks
//!   instead of 47: the background model and the tracker saw time stand still.
//!
//! Nothing here panics on any input (fuzzed: `fuzz/fuzz_targets/scan_csv.rs`).

use std::io::Read;

use quarry_core::{CoreError, PolarScan, ScanGeometry, SensorId, TimeUs};
use serde::Deserialize;

use crate::error::{DataError, Result};
use quarry_cloud::scan::metres_to_mm;

/// What to do with a row that cannot be used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RowPolicy {
    /// Stop with [`DataError::Csv`] naming the line (default).
    #[default]
    Error,
    /// Skip the row and count it.
    Skip,
}

/// Reader options.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ScanCsvOptions {
    /// Sensor id given to the scans.
    pub sensor: SensorId,
    /// Rows with the wrong column count, unparseable cells or a bad stamp.
    pub bad_rows: RowPolicy,
    /// Rows whose stamp goes backwards or repeats the previous one.
    pub backwards: RowPolicy,
}

/// Counters of a read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ScanCsvStats {
    /// Data rows seen (excluding the header).
    pub rows: u64,
    /// Scans returned.
    pub scans: u64,
    /// Rows skipped as malformed.
    pub skipped_bad_rows: u64,
    /// Rows skipped because their stamp went backwards.
    pub skipped_backwards: u64,
    /// Rows skipped because their stamp repeated the previous row's.
    pub skipped_repeated: u64,
    /// Beams marked invalid (NaN, inf, out of range) in the returned scans.
    pub invalid_beams: u64,
}

/// Streams [`PolarScan`]s from a scan CSV.
pub struct ScanCsvReader<R: Read> {
    records: csv::StringRecordsIntoIter<R>,
    geometry: ScanGeometry,
    opts: ScanCsvOptions,
    stats: ScanCsvStats,
    last_t: Option<TimeUs>,
    failed: bool,
}

impl<R: Read> std::fmt::Debug for ScanCsvReader<R> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ScanCsvReader")
            .field("geometry", &self.geometry)
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}

fn csv_err(line: u64, reason: impl Into<String>) -> DataError {
    DataError::Csv {
        line,
        reason: reason.into(),
    }
}

impl<R: Read> ScanCsvReader<R> {
    /// Opens a reader and checks the header against `geometry`.
    pub fn new(input: R, geometry: ScanGeometry, opts: ScanCsvOptions) -> Result<Self> {
        geometry.validate()?;
        let mut rdr = csv::ReaderBuilder::new()
            .has_headers(true)
            .flexible(true)
            .trim(csv::Trim::All)
            .from_reader(input);
        let header = rdr
            .headers()
            .map_err(|e| csv_err(1, format!("cannot read header: {e}")))?;
        let n = geometry.n_beams as usize;
        if header.len() != n + 1 {
            return Err(csv_err(
                1,
                format!(
                    "header has {} columns, the geometry needs {} (stamp_s + {} beams)",
                    header.len(),
                    n + 1,
                    n
                ),
            ));
        }
        if header.get(0) != Some("stamp_s") {
            return Err(csv_err(1, "first column must be stamp_s"));
        }
        Ok(Self {
            records: rdr.into_records(),
            geometry,
            opts,
            stats: ScanCsvStats::default(),
            last_t: None,
            failed: false,
        })
    }

    /// Counters so far.
    pub fn stats(&self) -> ScanCsvStats {
        self.stats
    }

    fn parse_row(&self, rec: &csv::StringRecord, line: u64) -> Result<(TimeUs, Vec<u16>, u64)> {
        let n = self.geometry.n_beams as usize;
        if rec.len() != n + 1 {
            return Err(csv_err(
                line,
                format!("expected {} columns, got {}", n + 1, rec.len()),
            ));
        }
        let stamp: f64 = rec
            .get(0)
            .unwrap_or("")
            .parse()
            .map_err(|_| csv_err(line, "stamp_s is not a number"))?;
        if !stamp.is_finite() || stamp.abs() > 9.0e12 {
            return Err(csv_err(line, "stamp_s is not finite (or beyond ±9e12 s)"));
        }
        let mut invalid = 0;
        let mut ranges = Vec::with_capacity(n);
        for (i, cell) in rec.iter().skip(1).enumerate() {
            let r: f64 = cell
                .parse()
                .map_err(|_| csv_err(line, format!("r{i} = {cell:?} is not a number")))?;
            if let Some(mm) = metres_to_mm(r, &self.geometry) {
                ranges.push(mm);
            } else {
                invalid += 1;
                ranges.push(0);
            }
        }
        Ok((TimeUs((stamp * 1e6).round() as i64), ranges, invalid))
    }
}

impl<R: Read> Iterator for ScanCsvReader<R> {
    type Item = Result<PolarScan>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        loop {
            let rec = match self.records.next()? {
                Ok(r) => r,
                Err(e) => {
                    // a csv-level error (e.g. invalid UTF-8) is a bad row
                    let line = e.position().map_or(0, csv::Position::line);
                    self.stats.rows += 1;
                    if self.opts.bad_rows == RowPolicy::Skip {
                        self.stats.skipped_bad_rows += 1;
                        continue;
                    }
                    self.failed = true;
                    return Some(Err(csv_err(line, e.to_string())));
                }
            };
            self.stats.rows += 1;
            let line = rec.position().map_or(0, csv::Position::line);
            let (t, ranges, invalid) = match self.parse_row(&rec, line) {
                Ok(x) => x,
                Err(e) => {
                    if self.opts.bad_rows == RowPolicy::Skip {
                        self.stats.skipped_bad_rows += 1;
                        continue;
                    }
                    self.failed = true;
                    return Some(Err(e));
                }
            };
            if let Some(last) = self.last_t
                && t <= last
            {
                if self.opts.backwards == RowPolicy::Skip {
                    if t == last {
                        self.stats.skipped_repeated += 1;
                    } else {
                        self.stats.skipped_backwards += 1;
                    }
                    continue;
                }
                self.failed = true;
                let what = if t == last {
                    format!(
                        "stamp {} us repeats the previous row's (a duplicated row?)",
                        t.0
                    )
                } else {
                    format!("stamp goes backwards ({} us after {} us)", t.0, last.0)
                };
                return Some(Err(csv_err(line, what)));
            }
            self.last_t = Some(t);
            self.stats.invalid_beams += invalid;
            let seq = self.stats.scans as u32;
            self.stats.scans += 1;
            return Some(
                PolarScan::try_new(self.opts.sensor, seq, t, ranges, self.geometry)
                    .map_err(DataError::from),
            );
        }
    }
}

/// Reads a whole scan CSV file.
pub fn read_scans(
    path: impl AsRef<std::path::Path>,
    geometry: ScanGeometry,
    opts: ScanCsvOptions,
) -> Result<(Vec<PolarScan>, ScanCsvStats)> {
    let f = std::fs::File::open(path.as_ref()).map_err(|e| DataError::Io {
        path: path.as_ref().display().to_string(),
        reason: e.to_string(),
    })?;
    let mut rdr = ScanCsvReader::new(std::io::BufReader::new(f), geometry, opts)?;
    let mut scans = Vec::new();
    for s in rdr.by_ref() {
        scans.push(s?);
    }
    Ok((scans, rdr.stats()))
}

#[derive(Deserialize)]
struct MetaEntry {
    angle_min: f64,
    angle_increment: f64,
    n_beams: u32,
    range_min: f64,
    range_max: f64,
    scan_time: f64,
}

/// The geometry of entry `key` of a `scan_meta.json` (an object of objects with `angle_min`,
/// `angle_increment`, `n_beams`, `range_min`, `range_max`, `scan_time`; other fields ignored).
pub fn parse_scan_meta(json: &str, key: &str) -> Result<ScanGeometry> {
    let all: std::collections::BTreeMap<String, serde_json::Value> =
        serde_json::from_str(json).map_err(|e| csv_err(0, format!("scan meta: {e}")))?;
    let v = all
        .get(key)
        .ok_or_else(|| csv_err(0, format!("scan meta has no entry {key:?}")))?;
    let m: MetaEntry = serde_json::from_value(v.clone())
        .map_err(|e| csv_err(0, format!("scan meta entry {key:?}: {e}")))?;
    if !(m.scan_time.is_finite() && m.scan_time > 0.0) {
        return Err(CoreError::invalid("scan_time", "must be finite and positive").into());
    }
    let g = ScanGeometry {
        n_beams: m.n_beams,
        angle_min: m.angle_min,
        angle_increment: m.angle_increment,
        range_min: m.range_min,
        range_max: m.range_max,
        scan_period: m.scan_time,
    };
    g.validate()?;
    Ok(g)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn geom(n: u32) -> ScanGeometry {
        ScanGeometry {
            n_beams: n,
            angle_min: -1.0,
            angle_increment: 0.5,
            range_min: 0.03,
            range_max: 11.0,
            scan_period: 0.1,
        }
    }

    fn read(text: &str, opts: ScanCsvOptions) -> (Vec<Result<PolarScan>>, ScanCsvStats) {
        let mut r = ScanCsvReader::new(text.as_bytes(), geom(3), opts).unwrap();
        let v: Vec<_> = r.by_ref().collect();
        (v, r.stats())
    }

    #[test]
    fn parses_and_counts_invalid() {
        let (v, st) = read(
            "stamp_s,r0,r1,r2\n1.5,1.0,nan,inf\n1.6,0.0,12.0,-inf\n1.7, 2.5 ,0.03,11.0\n",
            ScanCsvOptions::default(),
        );
        assert_eq!(v.len(), 3);
        let s: Vec<PolarScan> = v.into_iter().map(Result::unwrap).collect();
        assert_eq!(s[0].ranges_mm, vec![1000, 0, 0]);
        assert_eq!(s[0].t, TimeUs(1_500_000));
        assert_eq!(s[1].ranges_mm, vec![0, 0, 0]);
        assert_eq!(s[2].ranges_mm, vec![2500, 30, 11000]);
        assert_eq!(s[2].seq, 2);
        assert_eq!(st.invalid_beams, 5);
        assert_eq!(st.scans, 3);
    }

    #[test]
    fn bad_rows_error_or_skip() {
        let text = "stamp_s,r0,r1,r2\n1.0,1,1,1\n1.1,1,1\n1.2,1,x,1\nnan,1,1,1\n1.3,1,1,1\n";
        let (v, _) = read(text, ScanCsvOptions::default());
        assert_eq!(v.len(), 2);
        assert!(
            matches!(&v[1], Err(DataError::Csv { line: 3, reason }) if reason.contains("expected 4 columns"))
        );
        let (v, st) = read(
            text,
            ScanCsvOptions {
                bad_rows: RowPolicy::Skip,
                ..Default::default()
            },
        );
        assert_eq!(v.len(), 2);
        assert!(v.iter().all(Result::is_ok));
        assert_eq!(st.skipped_bad_rows, 3);
    }

    #[test]
    fn backwards_error_or_skip() {
        let text = "stamp_s,r0,r1,r2\n2.0,1,1,1\n1.0,1,1,1\n2.5,1,1,1\n3.0,1,1,1\n";
        let (v, _) = read(text, ScanCsvOptions::default());
        assert!(matches!(&v[1], Err(DataError::Csv { line: 3, .. })));
        let (v, st) = read(
            text,
            ScanCsvOptions {
                backwards: RowPolicy::Skip,
                ..Default::default()
            },
        );
        assert_eq!(v.len(), 3);
        assert_eq!(st.skipped_backwards, 1);
    }

    #[test]
    fn a_repeated_stamp_is_an_error_or_a_counted_skip() {
        let text = "stamp_s,r0,r1,r2\n1.0,1,1,1\n1.0,1,1,1\n2.0,1,1,1\n2.0,3,3,3\n";
        let (v, _) = read(text, ScanCsvOptions::default());
        match &v[1] {
            Err(DataError::Csv { line: 3, reason }) => {
                assert!(reason.contains("repeats"), "{reason}");
            }
            other => panic!("{other:?}"),
        }
        let (v, st) = read(
            text,
            ScanCsvOptions {
                backwards: RowPolicy::Skip,
                ..Default::default()
            },
        );
        assert_eq!(v.len(), 2);
        assert_eq!((st.skipped_repeated, st.skipped_backwards), (2, 0));
    }

    #[test]
    fn header_must_match_geometry() {
        assert!(
            ScanCsvReader::new(
                "stamp_s,r0,r1\n".as_bytes(),
                geom(3),
                ScanCsvOptions::default()
            )
            .is_err()
        );
        assert!(
            ScanCsvReader::new(
                "t,r0,r1,r2\n".as_bytes(),
                geom(3),
                ScanCsvOptions::default()
            )
            .is_err()
        );
        assert!(ScanCsvReader::new("".as_bytes(), geom(3), ScanCsvOptions::default()).is_err());
    }

    #[test]
    fn meta_parses() {
        let j = r#"{"a": {"angle_min": -2.35, "angle_increment": 0.006, "n_beams": 768, "range_min": 0.03,
                    "range_max": 11.0, "scan_time": 0.133, "frame_id": "x"}}"#;
        let g = parse_scan_meta(j, "a").unwrap();
        assert_eq!(g.n_beams, 768);
        assert!(parse_scan_meta(j, "b").is_err());
        assert!(parse_scan_meta("{", "a").is_err());
    }

    #[test]
    fn real_leg_tracker_recording() {
        let dir = std::env::var_os("QUARRY_SHARED").map_or_else(
            || std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")),
            std::path::PathBuf::from,
        );
        let dir = dir.join("data/leg-tracker");
        let Ok(meta) = std::fs::read_to_string(dir.join("scan_meta.json")) else {
            eprintln!("skipping: no leg-tracker data at {}", dir.display());
            return;
        };
        let g = parse_scan_meta(&meta, "positive_2").unwrap();
        let (scans, st) = read_scans(
            dir.join("positive_2_scans.csv"),
            g,
            ScanCsvOptions::default(),
        )
        .unwrap();
        assert_eq!(scans.len(), 243);
        assert_eq!(st.skipped_bad_rows + st.skipped_backwards, 0);
        assert!(st.invalid_beams > 0);
        assert!(scans.windows(2).all(|w| w[1].t >= w[0].t));
        let dt = (scans[242].t.0 - scans[0].t.0) as f64 / 242.0 * 1e-6;
        assert!((dt - g.scan_period).abs() < 0.02, "mean period {dt}");
    }
}
