//! The MOTChallenge text format: one object per line,
//! `frame,id,left,top,width,height,conf,x,y,z` (comma-separated, frames 1-based, boxes in pixels).
//!
//! Lines with 6 to 10 columns are accepted; the meaning of columns 7-10 depends on the file:
//! - results (all 2D MOT tasks): `conf, x, y, z` (world coordinates, -1 when unused);
//! - ground truth, 2D MOT 2015 style (10 columns): `flag, x, y, z`;
//! - ground truth, MOT16/17/20 style (9 columns): `flag (consider 0|1), class, visibility`.
//!
//! Blank lines and lines starting with `#` are skipped; fields may be padded with spaces.
//! A malformed line is an [`EvalError::Parse`] naming its 1-based line number; nothing here
//! panics on any input (the `motchallenge_reader` fuzz target checks that).
//!
//! [`to_frames`] turns ground truth and results into [`Frame`]s for [`crate::mot`], dropping
//! ignored ground truth the MOTChallenge way (spec 004 §5.4).
//!
//! ```
//! use quarry_eval::motchallenge::{read_gt, read_results, to_frames, write_results, GtStyle};
//! let gt = read_gt("1,1,10,20,30,60,1,1,1.0\n2,1,12,20,30,60,1,1,0.8\n", GtStyle::Auto)?;
//! let res = read_results("1,5,11,20,30,60,0.9,-1,-1,-1\n2,5,12,21,30,60,0.9,-1,-1,-1\n")?;
//! assert_eq!(gt[1].visibility, Some(0.8));
//! let frames = to_frames(&gt, &res, 0.5)?;
//! assert_eq!(frames.len(), 2);
//! let mut out = Vec::new();
//! write_results(&mut out, &res)?;
//! assert!(String::from_utf8(out).unwrap().starts_with("1,5,11,20,30,60,0.9,-1,-1,-1"));
//! # Ok::<(), quarry_eval::EvalError>(())
//! ```

use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;

use crate::EvalError;
use crate::lsap::linear_sum_assignment;
use crate::mot::Frame;
use crate::similarity::{Ltwh, iou_ltwh};

/// One line of a MOTChallenge file, columns as numbers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotRow {
    /// 1-based frame number.
    pub frame: u64,
    /// Object or track id (-1 for untracked detections).
    pub id: i64,
    /// `[left, top, width, height]`, pixels.
    pub bbox: Ltwh,
    /// Column 7 (confidence in results, flag in ground truth); 1 when absent.
    pub conf: f64,
    /// Columns 8-10 where present (world x, y, z, or class and visibility in MOT16+ GT).
    pub extra: [Option<f64>; 3],
}

/// A ground-truth line, interpreted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GtRow {
    /// 1-based frame number.
    pub frame: u64,
    /// Object id.
    pub id: i64,
    /// `[left, top, width, height]`, pixels.
    pub bbox: Ltwh,
    /// The flag column: `false` (flag 0) means "ignore this object".
    pub consider: bool,
    /// MOT16+ class (1 = pedestrian); `None` in MOT15-style files.
    pub class: Option<i64>,
    /// MOT16+ visibility ratio in `[0, 1]`; `None` in MOT15-style files.
    pub visibility: Option<f64>,
    /// World coordinates `(x, y)` (columns 8-9) of MOT15-style files that have them.
    pub world_xy: Option<[f64; 2]>,
}

/// Which ground-truth layout a file uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GtStyle {
    /// 9 columns mean MOT16+, anything else MOT15 (flag, then world coordinates).
    #[default]
    Auto,
    /// `flag, x, y, z` after the box.
    Mot15,
    /// `flag, class, visibility` after the box.
    Mot16,
}

/// MOT16/17/20 classes whose matched results are dropped rather than counted as false
/// positives (TrackEval's distractor classes: person on vehicle, static person, distractor,
/// reflection, non-MOT vehicle).
pub const DISTRACTOR_CLASSES: [i64; 5] = [2, 6, 7, 8, 12];

fn parse_num(field: &str, line: usize, col: usize) -> Result<f64, EvalError> {
    let t = field.trim();
    let v: f64 = t
        .parse()
        .map_err(|_| EvalError::parse(line, format!("column {col}: {t:?} is not a number")))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(EvalError::parse(
            line,
            format!("column {col}: {t:?} is not finite"),
        ))
    }
}

fn parse_int(field: &str, line: usize, col: usize, name: &str) -> Result<i64, EvalError> {
    let v = parse_num(field, line, col)?;
    if v.fract() != 0.0 || v.abs() > 9.0e15 {
        return Err(EvalError::parse(
            line,
            format!(
                "column {col} ({name}): {:?} is not an integer",
                field.trim()
            ),
        ));
    }
    Ok(v as i64)
}

/// Parses MOTChallenge text into raw rows (6 to 10 columns per line).
pub fn parse_rows(text: &str) -> Result<Vec<MotRow>, EvalError> {
    let mut rows = Vec::new();
    for (k, raw) in text.lines().enumerate() {
        let line = k + 1;
        let l = raw.trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = l.split(',').collect();
        let n = fields.len();
        if !(6..=10).contains(&n) {
            return Err(EvalError::parse(
                line,
                format!("expected 6 to 10 comma-separated columns, found {n}"),
            ));
        }
        let frame = parse_int(fields[0], line, 1, "frame")?;
        if frame < 1 {
            return Err(EvalError::parse(
                line,
                format!("column 1 (frame): frames are 1-based, got {frame}"),
            ));
        }
        let id = parse_int(fields[1], line, 2, "id")?;
        let mut bbox = [0.0; 4];
        for (c, b) in bbox.iter_mut().enumerate() {
            *b = parse_num(fields[2 + c], line, 3 + c)?;
        }
        if bbox[2] < 0.0 || bbox[3] < 0.0 {
            return Err(EvalError::parse(
                line,
                format!("negative box size {} x {}", bbox[2], bbox[3]),
            ));
        }
        let conf = if n > 6 {
            parse_num(fields[6], line, 7)?
        } else {
            1.0
        };
        let mut extra = [None; 3];
        for (c, e) in extra.iter_mut().enumerate() {
            if n > 7 + c {
                *e = Some(parse_num(fields[7 + c], line, 8 + c)?);
            }
        }
        rows.push(MotRow {
            frame: frame as u64,
            id,
            bbox,
            conf,
            extra,
        });
    }
    Ok(rows)
}

/// Parses raw bytes (must be UTF-8) into rows; the entry point the fuzz target exercises.
pub fn parse_bytes(bytes: &[u8]) -> Result<Vec<MotRow>, EvalError> {
    let text = std::str::from_utf8(bytes).map_err(|e| {
        let line = String::from_utf8_lossy(&bytes[..e.valid_up_to()])
            .matches('\n')
            .count()
            + 1;
        EvalError::parse(line, "not valid UTF-8 text")
    })?;
    parse_rows(text)
}

/// Reads a tracker result file's text (`frame,id,l,t,w,h,conf[,x,y,z]`).
pub fn read_results(text: &str) -> Result<Vec<MotRow>, EvalError> {
    parse_rows(text)
}

/// Reads ground-truth text in the given style.
pub fn read_gt(text: &str, style: GtStyle) -> Result<Vec<GtRow>, EvalError> {
    let mut out = Vec::new();
    let mut line_of_row = Vec::new();
    // keep line numbers for error messages about the interpreted columns
    for (k, raw) in text.lines().enumerate() {
        let l = raw.trim();
        if !(l.is_empty() || l.starts_with('#')) {
            line_of_row.push((k + 1, l.split(',').count()));
        }
    }
    let rows = parse_rows(text)?;
    for (row, &(line, ncols)) in rows.iter().zip(&line_of_row) {
        let mot16 = match style {
            GtStyle::Auto => ncols == 9,
            GtStyle::Mot15 => false,
            GtStyle::Mot16 => true,
        };
        let (class, visibility) = if mot16 {
            let class = match row.extra[0] {
                Some(c) if c.fract() == 0.0 => Some(c as i64),
                Some(c) => {
                    return Err(EvalError::parse(
                        line,
                        format!("column 8 (class): {c} is not an integer"),
                    ));
                }
                None => None,
            };
            if let Some(v) = row.extra[1]
                && !(0.0..=1.0).contains(&v)
            {
                return Err(EvalError::parse(
                    line,
                    format!("column 9 (visibility): {v} is outside [0, 1]"),
                ));
            }
            (class, row.extra[1])
        } else {
            (None, None)
        };
        let world_xy = match (mot16, row.extra[0], row.extra[1]) {
            (false, Some(x), Some(y)) => world(x, y),
            _ => None,
        };
        out.push(GtRow {
            frame: row.frame,
            id: row.id,
            bbox: row.bbox,
            consider: row.conf != 0.0,
            class,
            visibility,
            world_xy,
        });
    }
    Ok(out)
}

/// The largest MOTChallenge file the readers accept (512 MiB: MOT20's largest ground truth is a
/// few tens of MiB). A longer input, an endless one such as `/dev/zero` among them, is an error
/// after reading one byte more than this, never an unbounded allocation.
pub const MAX_FILE_BYTES: u64 = 512 << 20;

fn read_file(path: &Path) -> Result<String, EvalError> {
    read_file_limited(path, MAX_FILE_BYTES)
}

fn read_file_limited(path: &Path, limit: u64) -> Result<String, EvalError> {
    use std::io::Read as _;
    let io = |source| EvalError::Io {
        path: path.display().to_string(),
        source,
    };
    let f = std::fs::File::open(path).map_err(io)?;
    let mut b = Vec::new();
    f.take(limit + 1).read_to_end(&mut b).map_err(io)?;
    if b.len() as u64 > limit {
        return Err(io(std::io::Error::other(format!(
            "larger than {limit} bytes, the limit for a MOTChallenge file"
        ))));
    }
    String::from_utf8(b).map_err(|_| EvalError::parse(1, "file is not UTF-8 text"))
}

/// Reads a ground-truth file.
pub fn read_gt_file(path: impl AsRef<Path>, style: GtStyle) -> Result<Vec<GtRow>, EvalError> {
    read_gt(&read_file(path.as_ref())?, style)
}

/// Reads a result file.
pub fn read_results_file(path: impl AsRef<Path>) -> Result<Vec<MotRow>, EvalError> {
    read_results(&read_file(path.as_ref())?)
}

/// Writes rows as MOTChallenge results: always 10 columns, missing world coordinates as -1.
pub fn write_results<W: Write>(mut w: W, rows: &[MotRow]) -> Result<(), EvalError> {
    let io = |source| EvalError::Io {
        path: "<writer>".into(),
        source,
    };
    for r in rows {
        let [l, t, bw, bh] = r.bbox;
        let x = r.extra.map(|e| e.unwrap_or(-1.0));
        writeln!(
            w,
            "{},{},{},{},{},{},{},{},{},{}",
            r.frame, r.id, l, t, bw, bh, r.conf, x[0], x[1], x[2]
        )
        .map_err(io)?;
    }
    w.flush().map_err(io)
}

/// Builds per-frame [`Frame`]s (boxes) from ground truth and results, ordered by frame number
/// over every frame that appears in either file.
///
/// Ignored ground truth is handled as spec 004 §5.4 (after TrackEval's MOTChallenge
/// preprocessing) resolves it: a ground-truth row is *ignored* when its flag is 0 or its class
/// is one of [`DISTRACTOR_CLASSES`]. In each frame the results are matched to all ground truth
/// (optimal assignment maximising IoU among pairs with IoU >= `iou_threshold`); results matched
/// to an ignored row are dropped (neither TP nor FP), and ignored rows are removed. Rows of any
/// other non-pedestrian class are removed from the ground truth (results on them count as FP),
/// as TrackEval does. MOT15-style files have no class, so only the flag applies.
pub fn to_frames(
    gt: &[GtRow],
    res: &[MotRow],
    iou_threshold: f64,
) -> Result<Vec<Frame<Ltwh>>, EvalError> {
    Ok(select(gt, res, iou_threshold)?
        .into_iter()
        .map(|(g, r)| Frame {
            gt: g.iter().map(|g| (g.id, g.bbox)).collect(),
            hyp: r.iter().map(|r| (r.id, r.bbox)).collect(),
        })
        .collect())
}

/// World coordinates of columns 8-9, or `None` for MOTChallenge's "unused" marker `-1, -1`
/// (MOT15 writes -1 in every world column of most sequences; taking it as a position would
/// match every box to every other at distance 0).
fn world(x: f64, y: f64) -> Option<[f64; 2]> {
    (!(x == -1.0 && y == -1.0)).then_some([x, y])
}

/// Like [`to_frames`], but each object is the world position `(x, y)` of columns 8-9 (for
/// ground-plane evaluation with [`crate::Euclidean`]). Ignored rows are removed as in
/// [`to_frames`] (by box overlap); a kept row without world coordinates (a MOT16-style ground
/// truth, fewer than 9 columns, or the "unused" marker `-1, -1`) is an error.
pub fn to_point_frames(
    gt: &[GtRow],
    res: &[MotRow],
    iou_threshold: f64,
) -> Result<Vec<Frame<[f64; 2]>>, EvalError> {
    let missing = |which: &str, frame: u64, id: i64| {
        EvalError::from(quarry_core::CoreError::invalid(
            "world coordinates",
            format!("{which} row (frame {frame}, id {id}) has no world x, y (columns 8-9)"),
        ))
    };
    select(gt, res, iou_threshold)?
        .into_iter()
        .map(|(g, r)| {
            Ok(Frame {
                gt: g
                    .iter()
                    .map(|g| {
                        g.world_xy
                            .map(|w| (g.id, w))
                            .ok_or_else(|| missing("ground-truth", g.frame, g.id))
                    })
                    .collect::<Result<_, _>>()?,
                hyp: r
                    .iter()
                    .map(|r| match (r.extra[0], r.extra[1]) {
                        (Some(x), Some(y)) => world(x, y)
                            .map(|w| (r.id, w))
                            .ok_or_else(|| missing("result", r.frame, r.id)),
                        _ => Err(missing("result", r.frame, r.id)),
                    })
                    .collect::<Result<_, _>>()?,
            })
        })
        .collect()
}

/// The ground-truth and result rows kept in one frame.
type KeptRows<'a> = (Vec<&'a GtRow>, Vec<&'a MotRow>);

/// The rows kept in each frame (see [`to_frames`]).
fn select<'a>(
    gt: &'a [GtRow],
    res: &'a [MotRow],
    iou_threshold: f64,
) -> Result<Vec<KeptRows<'a>>, EvalError> {
    if !(iou_threshold > 0.0 && iou_threshold <= 1.0) {
        return Err(quarry_core::CoreError::invalid(
            "iou_threshold",
            format!("must lie in (0, 1], got {iou_threshold}"),
        )
        .into());
    }
    let mut by_frame: BTreeMap<u64, (Vec<&GtRow>, Vec<&MotRow>)> = BTreeMap::new();
    for g in gt {
        by_frame.entry(g.frame).or_default().0.push(g);
    }
    for r in res {
        by_frame.entry(r.frame).or_default().1.push(r);
    }
    let mut frames = Vec::with_capacity(by_frame.len());
    for (frame, (gts, rs)) in by_frame {
        let mut seen = std::collections::HashSet::new();
        for g in &gts {
            if !seen.insert(g.id) {
                return Err(EvalError::DuplicateId {
                    which: "ground truth",
                    frame,
                    id: g.id,
                });
            }
        }
        seen.clear();
        for r in &rs {
            if !seen.insert(r.id) {
                return Err(EvalError::DuplicateId {
                    which: "hypothesis",
                    frame,
                    id: r.id,
                });
            }
        }
        let ignored: Vec<bool> = gts
            .iter()
            .map(|g| !g.consider || g.class.is_some_and(|c| DISTRACTOR_CLASSES.contains(&c)))
            .collect();
        let mut drop_res = vec![false; rs.len()];
        if ignored.iter().any(|&x| x) && !rs.is_empty() {
            let (no, nh) = (gts.len(), rs.len());
            let mut score = vec![0.0; no * nh];
            for i in 0..no {
                for j in 0..nh {
                    let s = iou_ltwh(&gts[i].bbox, &rs[j].bbox);
                    score[i * nh + j] = if s < iou_threshold - f64::EPSILON {
                        0.0
                    } else {
                        -s
                    };
                }
            }
            for (i, j) in linear_sum_assignment(&score, no, nh)? {
                if -score[i * nh + j] > f64::EPSILON && ignored[i] {
                    drop_res[j] = true;
                }
            }
        }
        let g: Vec<&GtRow> = gts
            .iter()
            .zip(&ignored)
            .filter(|(g, ign)| !**ign && g.class.is_none_or(|c| c == 1))
            .map(|(g, _)| *g)
            .collect();
        let r: Vec<&MotRow> = rs
            .iter()
            .zip(&drop_res)
            .filter(|(_, d)| !**d)
            .map(|(r, _)| *r)
            .collect();
        frames.push((g, r));
    }
    Ok(frames)
}

#[cfg(test)]
mod tests {
    #[test]
    fn endless_or_oversized_files_are_refused() {
        let p = std::env::temp_dir().join(format!("quarry-eval-big-{}.txt", std::process::id()));
        std::fs::write(&p, "1,1,0,0,10,10,1,-1,-1,-1\n".repeat(10)).unwrap();
        assert!(read_file_limited(&p, 1 << 20).is_ok());
        let e = read_file_limited(&p, 100).unwrap_err();
        assert!(e.to_string().contains("larger than 100 bytes"), "{e}");
        std::fs::remove_file(&p).ok();
        let zero = Path::new("/dev/zero");
        if zero.exists() {
            assert!(read_file_limited(zero, 4096).is_err());
        }
    }

    #[test]
    fn unused_world_columns_are_not_positions() {
        // MOT15 ground truth and results with -1 world columns: --dist must refuse them, not
        // match every box at distance 0 (which scored MOTA 1.0 for boxes 500 px apart)
        let gt = read_gt("1,1,10,10,20,20,1,-1,-1,-1\n", GtStyle::Auto).unwrap();
        assert_eq!(gt[0].world_xy, None);
        let res = read_results("1,1,510,510,20,20,1,-1,-1,-1\n").unwrap();
        let e = to_point_frames(&gt, &res, 0.5).unwrap_err();
        assert!(e.to_string().contains("no world x, y"), "{e}");
        // a real position is kept, also one with a single -1 coordinate
        let gt = read_gt("1,1,10,10,20,20,1,-1,2.5,0\n", GtStyle::Auto).unwrap();
        assert_eq!(gt[0].world_xy, Some([-1.0, 2.5]));
    }

    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        /// Arbitrary bytes, and valid lines with random bytes spliced in, never panic anywhere
        /// from parsing to scoring (the same path as the `motchallenge_reader` fuzz target).
        #[test]
        fn never_panics(noise in proptest::collection::vec(any::<u8>(), 0..64), at in 0usize..200) {
            let mut data = b"1,1,10,20,30,60,1,1,0.5\n1,2,15,20,30,60,0,7,1\n2,1,11,20,30,60,1,-1,-1,-1\n".to_vec();
            let at = at.min(data.len());
            data.splice(at..at, noise.iter().copied());
            for bytes in [&noise[..], &data[..]] {
                if let (Ok(rows), Ok(text)) = (parse_bytes(bytes), std::str::from_utf8(bytes)) {
                    for style in [GtStyle::Auto, GtStyle::Mot15, GtStyle::Mot16] {
                        if let Ok(gt) = read_gt(text, style)
                            && let Ok(frames) = to_frames(&gt, &rows, 0.5)
                            && let Ok(ev) = crate::MotEvaluation::new(&frames, &crate::Iou::default())
                        {
                            let s = ev.summary().unwrap();
                            prop_assert!(s.clear.num_objects <= gt.len());
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn errors_name_the_line() {
        let e = parse_rows("1,1,0,0,1,1\n\n2,x,0,0,1,1\n").unwrap_err();
        assert_eq!(e.to_string(), "line 3: column 2: \"x\" is not a number");
        let e = parse_rows("1,1,0,0,1\n").unwrap_err();
        assert!(e.to_string().starts_with("line 1: expected 6 to 10"));
        let e = parse_rows("0,1,0,0,1,1\n").unwrap_err();
        assert!(e.to_string().contains("1-based"));
        let e = parse_rows("1,1,0,0,-1,1\n").unwrap_err();
        assert!(e.to_string().contains("negative box size"));
        let e = parse_rows("1,1.5,0,0,1,1\n").unwrap_err();
        assert!(e.to_string().contains("not an integer"));
        let e = parse_rows("1,1,0,0,nan,1\n").unwrap_err();
        assert!(e.to_string().contains("not finite"));
        assert_eq!(
            parse_bytes(b"1,1,0,0,1,1\n\xff").unwrap_err().to_string(),
            "line 2: not valid UTF-8 text"
        );
        assert!(read_gt("1,1,0,0,1,1,1,1,1.5\n", GtStyle::Auto).is_err());
    }

    #[test]
    fn columns_and_styles() {
        let r = parse_rows(" 3 , 7 , 1.5, 2, 3, 4 \n# c\n4,7,1,2,3,4,0.5,9\n").unwrap();
        assert_eq!(r.len(), 2);
        assert_eq!(r[0].frame, 3);
        assert_eq!(r[0].bbox, [1.5, 2.0, 3.0, 4.0]);
        assert_eq!(r[0].conf, 1.0);
        assert_eq!(r[1].extra, [Some(9.0), None, None]);
        let g = read_gt("1,1,0,0,1,1,0,-1,-1,-1\n", GtStyle::Auto).unwrap();
        assert!(!g[0].consider);
        assert_eq!(g[0].class, None);
        let g = read_gt("1,1,0,0,1,1,1,7,0.25\n", GtStyle::Auto).unwrap();
        assert_eq!((g[0].class, g[0].visibility), (Some(7), Some(0.25)));
    }

    #[test]
    fn ignored_gt_drops_matched_results() {
        // object 2 is flagged 0: the result on it vanishes, the result elsewhere stays an FP
        let gt = read_gt(
            "1,1,0,0,10,10,1,1,1\n1,2,50,0,10,10,0,1,1\n1,3,100,0,10,10,1,3,1\n",
            GtStyle::Auto,
        )
        .unwrap();
        let res = read_results("1,7,0,0,10,10,1\n1,8,51,0,10,10,1\n1,9,200,0,10,10,1\n").unwrap();
        let f = to_frames(&gt, &res, 0.5).unwrap();
        assert_eq!(f.len(), 1);
        assert_eq!(f[0].gt.iter().map(|p| p.0).collect::<Vec<_>>(), vec![1]);
        assert_eq!(f[0].hyp.iter().map(|p| p.0).collect::<Vec<_>>(), vec![7, 9]);
    }

    #[test]
    fn world_points_need_world_columns() {
        let gt = read_gt("1,1,0,0,10,10,1,2.5,3.5,0\n", GtStyle::Auto).unwrap();
        assert_eq!(gt[0].world_xy, Some([2.5, 3.5]));
        let res = read_results("1,4,0,0,10,10,1,2.0,3.0,-1\n").unwrap();
        let f = to_point_frames(&gt, &res, 0.5).unwrap();
        assert_eq!(f[0].gt, vec![(1, [2.5, 3.5])]);
        assert_eq!(f[0].hyp, vec![(4, [2.0, 3.0])]);
        let res6 = read_results("1,4,0,0,10,10\n").unwrap();
        let e = to_point_frames(&gt, &res6, 0.5).unwrap_err();
        assert!(e.to_string().contains("frame 1, id 4"), "{e}");
        let gt16 = read_gt("1,1,0,0,10,10,1,1,1\n", GtStyle::Auto).unwrap();
        assert!(to_point_frames(&gt16, &res, 0.5).is_err());
        assert!(to_frames(&gt, &res, 0.0).is_err());
        let dup = read_results("7,4,0,0,10,10\n7,4,5,5,10,10\n").unwrap();
        let e = to_frames(&gt, &dup, 0.5).unwrap_err();
        assert_eq!(e.to_string(), "duplicate id 4 in frame 7 of the hypothesis");
    }

    #[test]
    fn write_then_read_round_trips() {
        let rows =
            parse_rows("1,2,1.25,2.5,30,40,0.75,-1,-1,-1\n5,3,0,0,1,1,1,-1,-1,-1\n").unwrap();
        let mut buf = Vec::new();
        write_results(&mut buf, &rows).unwrap();
        assert_eq!(parse_bytes(&buf).unwrap(), rows);
    }
}
