//! The labels of the leg-tracker recordings (`shared/data/leg-tracker/positive_k_legs.csv`):
//! one row per labelled leg centroid, averaged into one person position per scan.
//!
//! ```
//! use quarry_data::leg_labels::parse_legs_csv;
//! let csv = "stamp_s,leg_index,x_m,y_m,frame_id\n1.0,0,1.0,0.0,laser\n1.0,1,1.0,0.2,laser\n";
//! let people = parse_legs_csv(csv)?;
//! assert_eq!(people.len(), 1);
//! assert_eq!(people[0].legs, 2);
//! assert!((people[0].pos.y - 0.1).abs() < 1e-12);
//! # Ok::<(), quarry_data::DataError>(())
//! ```

use quarry_core::{Point2, TimeUs};

use crate::{DataError, Result};

/// A labelled person position: the mean of the leg centroids of one scan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LabelledPerson {
    /// Scan stamp.
    pub t: TimeUs,
    /// Position (laser frame), metres.
    pub pos: Point2,
    /// Number of leg centroids averaged.
    pub legs: usize,
}

/// Parses a `positive_k_legs.csv` (header `stamp_s,leg_index,x_m,y_m,frame_id`, one row per
/// leg) into one [`LabelledPerson`] per stamp (mean of its legs), in stamp order.
///
/// Errors name the line: a missing or different header, a wrong column count, an unparseable
/// or non-finite number.
pub fn parse_legs_csv(text: &str) -> Result<Vec<LabelledPerson>> {
    let bad = |line: usize, why: &str| DataError::Csv {
        line: line as u64,
        reason: format!("legs csv: {why}"),
    };
    let mut lines = text.lines().enumerate();
    let header = lines
        .next()
        .map(|(_, h)| h.trim().to_string())
        .unwrap_or_default();
    let cols: Vec<&str> = header.split(',').map(str::trim).collect();
    if cols.len() < 4 || cols[..4] != ["stamp_s", "leg_index", "x_m", "y_m"] {
        return Err(bad(1, "header must start with stamp_s,leg_index,x_m,y_m"));
    }
    let mut acc: std::collections::BTreeMap<i64, (f64, f64, usize)> =
        std::collections::BTreeMap::new();
    for (i, line) in lines {
        let line_no = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != cols.len() {
            return Err(bad(
                line_no,
                &format!("{} columns, the header has {}", f.len(), cols.len()),
            ));
        }
        let num = |j: usize| -> Result<f64> {
            let v: f64 = f[j]
                .parse()
                .map_err(|_| bad(line_no, &format!("column {} is not a number", cols[j])))?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(bad(line_no, &format!("column {} is not finite", cols[j])))
            }
        };
        let stamp = num(0)?;
        let (x, y) = (num(2)?, num(3)?);
        let e = acc
            .entry((stamp * 1e6).round() as i64)
            .or_insert((0.0, 0.0, 0));
        e.0 += x;
        e.1 += y;
        e.2 += 1;
    }
    Ok(acc
        .into_iter()
        .map(|(t, (x, y, n))| LabelledPerson {
            t: TimeUs(t),
            pos: Point2::new(x / n as f64, y / n as f64),
            legs: n,
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legs_csv_parses_and_rejects() {
        let l = parse_legs_csv(
            "stamp_s,leg_index,x_m,y_m,frame_id\n1.0,0,1.0,0.0,laser\n1.0,1,1.0,0.2,laser\n2.0,0,3,3,laser\n",
        )
        .unwrap();
        assert_eq!(l.len(), 2);
        assert_eq!(l[0].legs, 2);
        assert!((l[0].pos.y - 0.1).abs() < 1e-12);
        assert!(parse_legs_csv("x,y\n").is_err());
        assert!(parse_legs_csv("stamp_s,leg_index,x_m,y_m,frame_id\n1,0,nan,0,l\n").is_err());
        assert!(parse_legs_csv("stamp_s,leg_index,x_m,y_m,frame_id\n1,0,1\n").is_err());
        assert!(parse_legs_csv("").is_err());
    }
}
