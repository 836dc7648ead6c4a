//! The labels of the leg-tracker recordings (`shared/data/leg-tracker/positive_k_legs.csv`):
//! one row per labelled leg centroid. [`parse_legs_csv`] averages a scan's legs into one
//! person position (the recordings' own definition); [`parse_leg_scans_csv`] keeps the legs,
//! and [`LabelledScan::groups`] splits them into the people they belong to when a scan's
//! labels hold more than one (the recordings label every leg-sized cluster in a wedge, so a
//! second walker in it is labelled too).
//!
//! ```
//! use quarry_data::leg_labels::{parse_leg_scans_csv, parse_legs_csv};
//! let csv = "stamp_s,leg_index,x_m,y_m,frame_id\n1.0,0,1.0,0.0,laser\n1.0,1,1.0,0.2,laser\n";
//! let people = parse_legs_csv(csv)?;
//! assert_eq!(people.len(), 1);
//! assert_eq!(people[0].legs, 2);
//! assert!((people[0].pos.y - 0.1).abs() < 1e-12);
//!
//! // Two legs 0.2 m apart and a third 3 m away: two people.
//! let csv = "stamp_s,leg_index,x_m,y_m,frame_id\n\
//!            1.0,0,1.0,0.0,laser\n1.0,1,1.0,0.2,laser\n1.0,2,4.0,0.0,laser\n";
//! let scans = parse_leg_scans_csv(csv)?;
//! let groups = scans[0].groups(0.8)?;
//! assert_eq!(groups.len(), 2);
//! assert_eq!((groups[0].legs, groups[1].legs), (2, 1));
//! # Ok::<(), quarry_data::DataError>(())
//! ```

use quarry_core::{CoreError, Point2, TimeUs};

use crate::{DataError, Result};

/// The most leg centroids one scan may label. A leg is at least three returns, so a scan of
/// 1080 beams (the largest in common use) has at most 360; a file with more at one stamp is
/// not a leg-label file, and the limit keeps [`LabelledScan::groups`] (quadratic in the legs)
/// bounded.
pub const MAX_LEGS_PER_SCAN: usize = 1024;

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

/// The labelled leg centroids of one scan, in file order.
#[derive(Debug, Clone, PartialEq)]
pub struct LabelledScan {
    /// Scan stamp.
    pub t: TimeUs,
    /// Leg centroids (laser frame), metres; at least one.
    pub legs: Vec<Point2>,
}

impl LabelledScan {
    /// The recordings' person: the mean of every labelled leg of the scan.
    #[must_use]
    pub fn person(&self) -> LabelledPerson {
        mean_person(self.t, self.legs.iter().copied())
    }

    /// The scan's legs split into people: single-linkage groups, two legs in one group when a
    /// chain of legs each at most `link_m` from the next joins them. Each group's position is
    /// the mean of its legs. Groups are ordered by their first leg in the file.
    ///
    /// `link_m` is the distance within which two legs may belong to one person: leg_tracker's
    /// `max_leg_pairing_dist` (0.8 m) is the natural value.
    ///
    /// # Errors
    /// `link_m` not finite or not positive.
    pub fn groups(&self, link_m: f64) -> Result<Vec<LabelledPerson>> {
        if !(link_m.is_finite() && link_m > 0.0) {
            return Err(CoreError::invalid("link_m", "must be finite and > 0").into());
        }
        let n = self.legs.len();
        // Union-find over the legs; n <= MAX_LEGS_PER_SCAN (the parser's limit; a hand-built
        // scan may hold more, at quadratic cost).
        let mut parent: Vec<usize> = (0..n).collect();
        fn root(parent: &mut [usize], mut i: usize) -> usize {
            while parent[i] != i {
                parent[i] = parent[parent[i]];
                i = parent[i];
            }
            i
        }
        for i in 0..n {
            for j in i + 1..n {
                let (a, b) = (self.legs[i], self.legs[j]);
                if (a.x - b.x).hypot(a.y - b.y) <= link_m {
                    let (ri, rj) = (root(&mut parent, i), root(&mut parent, j));
                    if ri != rj {
                        // the smaller index stays the root: groups keep file order
                        parent[ri.max(rj)] = ri.min(rj);
                    }
                }
            }
        }
        let mut order: Vec<usize> = Vec::new();
        let mut members: Vec<Vec<Point2>> = Vec::new();
        for i in 0..n {
            let r = root(&mut parent, i);
            if let Some(k) = order.iter().position(|&o| o == r) {
                members[k].push(self.legs[i]);
            } else {
                order.push(r);
                members.push(vec![self.legs[i]]);
            }
        }
        Ok(members
            .into_iter()
            .map(|m| mean_person(self.t, m.into_iter()))
            .collect())
    }
}

fn mean_person(t: TimeUs, legs: impl Iterator<Item = Point2>) -> LabelledPerson {
    let (mut x, mut y, mut n) = (0.0, 0.0, 0usize);
    for p in legs {
        x += p.x;
        y += p.y;
        n += 1;
    }
    LabelledPerson {
        t,
        pos: Point2::new(x / n as f64, y / n as f64),
        legs: n,
    }
}

/// Parses a `positive_k_legs.csv` (header `stamp_s,leg_index,x_m,y_m,frame_id`, one row per
/// leg) into one [`LabelledPerson`] per stamp (mean of its legs), in stamp order: the
/// recordings' own definition of the person.
///
/// # Errors
/// As [`parse_leg_scans_csv`].
pub fn parse_legs_csv(text: &str) -> Result<Vec<LabelledPerson>> {
    Ok(parse_leg_scans_csv(text)?
        .iter()
        .map(LabelledScan::person)
        .collect())
}

/// Parses a `positive_k_legs.csv` into one [`LabelledScan`] per stamp (its legs in file order),
/// in stamp order.
///
/// # Errors
/// Naming the line: a missing or different header, a wrong column count, an unparseable or
/// non-finite number, more than [`MAX_LEGS_PER_SCAN`] legs at one stamp.
pub fn parse_leg_scans_csv(text: &str) -> Result<Vec<LabelledScan>> {
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
    let mut acc: std::collections::BTreeMap<i64, Vec<Point2>> = std::collections::BTreeMap::new();
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
        let e = acc.entry((stamp * 1e6).round() as i64).or_default();
        if e.len() == MAX_LEGS_PER_SCAN {
            return Err(bad(
                line_no,
                &format!("more than {MAX_LEGS_PER_SCAN} legs at stamp {stamp}"),
            ));
        }
        e.push(Point2::new(x, y));
    }
    Ok(acc
        .into_iter()
        .map(|(t, legs)| LabelledScan { t: TimeUs(t), legs })
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

    fn scan(legs: &[(f64, f64)]) -> LabelledScan {
        LabelledScan {
            t: TimeUs(0),
            legs: legs.iter().map(|&(x, y)| Point2::new(x, y)).collect(),
        }
    }

    #[test]
    fn groups_link_chains_and_keep_file_order() {
        // a chain 0.5 m per step is one group; 1.0 m gaps split
        let s = scan(&[(5.0, 0.0), (0.0, 0.0), (0.5, 0.0), (1.0, 0.0), (5.6, 0.0)]);
        let g = s.groups(0.8).unwrap();
        assert_eq!(g.len(), 2);
        assert_eq!((g[0].legs, g[1].legs), (2, 3));
        assert!((g[0].pos.x - 5.3).abs() < 1e-12);
        assert!((g[1].pos.x - 0.5).abs() < 1e-12);
        // a link shorter than every gap: each leg its own person
        assert_eq!(s.groups(0.1).unwrap().len(), 5);
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(s.groups(bad).is_err(), "link {bad}");
        }
        // the mean of every leg is the recordings' person
        assert!((s.person().pos.x - 12.1 / 5.0).abs() < 1e-12);
    }

    #[test]
    fn too_many_legs_at_one_stamp_is_an_error_naming_the_line() {
        let mut csv = String::from("stamp_s,leg_index,x_m,y_m,frame_id\n");
        for i in 0..=MAX_LEGS_PER_SCAN {
            use std::fmt::Write as _;
            let _ = writeln!(csv, "1.0,{i},1.0,0.0,laser");
        }
        let e = parse_leg_scans_csv(&csv).unwrap_err().to_string();
        assert!(
            e.contains(&format!("line {}", MAX_LEGS_PER_SCAN + 2)),
            "{e}"
        );
        assert!(e.contains("legs at stamp"), "{e}");
    }

    proptest::proptest! {
        /// Groups partition the legs, legs of different groups are farther apart than the link,
        /// and each group's position is the mean of its legs (the means weighted by group size
        /// give the scan's person).
        #[test]
        fn groups_partition_the_legs(
            pts in proptest::collection::vec((-5.0f64..5.0, -5.0f64..5.0), 1..40),
            link in 0.05f64..3.0,
        ) {
            let s = scan(&pts);
            let g = s.groups(link).unwrap();
            proptest::prop_assert_eq!(g.iter().map(|p| p.legs).sum::<usize>(), pts.len());
            let (mut x, mut y) = (0.0, 0.0);
            for p in &g {
                x += p.pos.x * p.legs as f64;
                y += p.pos.y * p.legs as f64;
            }
            let all = s.person();
            proptest::prop_assert!((x / pts.len() as f64 - all.pos.x).abs() < 1e-9);
            proptest::prop_assert!((y / pts.len() as f64 - all.pos.y).abs() < 1e-9);
            // the single-linkage components by flood fill, numbered by their first leg
            let mut member = vec![usize::MAX; pts.len()];
            let mut next = 0;
            for i in 0..pts.len() {
                if member[i] != usize::MAX {
                    continue;
                }
                let mut stack = vec![i];
                member[i] = next;
                while let Some(a) = stack.pop() {
                    for b in 0..pts.len() {
                        let d = (pts[a].0 - pts[b].0).hypot(pts[a].1 - pts[b].1);
                        if member[b] == usize::MAX && d <= link {
                            member[b] = next;
                            stack.push(b);
                        }
                    }
                }
                next += 1;
            }
            proptest::prop_assert_eq!(next, g.len());
            for (k, group) in g.iter().enumerate() {
                let legs: Vec<usize> = (0..pts.len()).filter(|&i| member[i] == k).collect();
                proptest::prop_assert_eq!(legs.len(), group.legs);
                let mx = legs.iter().map(|&i| pts[i].0).sum::<f64>() / legs.len() as f64;
                proptest::prop_assert!((mx - group.pos.x).abs() < 1e-9);
            }
        }
    }
}
