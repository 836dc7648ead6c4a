//! Fuzz the recorded-scan CSV reader: any bytes must give scans or clear errors, never a panic,
//! with both row policies; every returned scan has one range per beam.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quarry_core::ScanGeometry;
use quarry_data::scans_csv::{RowPolicy, ScanCsvOptions, ScanCsvReader};

fuzz_target!(|data: &[u8]| {
    let g = ScanGeometry {
        n_beams: 4,
        angle_min: -1.0,
        angle_increment: 0.5,
        range_min: 0.02,
        range_max: 12.0,
        scan_period: 0.1,
    };
    for policy in [RowPolicy::Error, RowPolicy::Skip] {
        let opts = ScanCsvOptions {
            bad_rows: policy,
            backwards: policy,
            ..Default::default()
        };
        if let Ok(rdr) = ScanCsvReader::new(data, g, opts) {
            for s in rdr.take(10_000) {
                if let Ok(s) = s {
                    assert_eq!(s.ranges_mm.len(), 4);
                }
            }
        }
    }
    let _ = quarry_data::scans_csv::parse_scan_meta(&String::from_utf8_lossy(data), "a");
});
